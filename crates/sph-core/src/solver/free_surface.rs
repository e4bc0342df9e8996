//! The density a particle at a free surface is held to, for the
//! incompressible solvers' density constraints (PBF's
//! [`PbfParams::surface_target`](super::pbf::PbfParams::surface_target),
//! DFSPH's [`DfsphParams::surface_target`](super::dfsph::DfsphParams::surface_target)).
//!
//! A summed density misses the share of the kernel that lies in the air,
//! so a particle at a free surface reads below ρ0 at its rest spacing: the
//! top layer of a cubic lattice at h = 2 spacings reads 0.85 ρ0 with the
//! cubic spline. A one-sided constraint (ρ ≤ ρ0) leaves such a particle
//! free until it reads ρ0, so under gravity the surface layers pack: in a
//! pool 0.2 m deep under DFSPH the top layer holds 1.2 times the bulk's
//! particles per area after 2 s, and the free surface stands 1.7 % low
//! (`docs/benchmark-notes.md`, "The free surface's packed top layer").
//! Schechter & Bridson 2012 ("Ghost SPH for animating water") fill the
//! missing share with ghost air particles; this module does the cheaper
//! thing of lowering the target instead.
//!
//! The constraint's gradient ∇_i(ρ_i/ρ0) = Σ_j (m_j/ρ0) ∇W_ij (with the
//! walls' term, which fills their side) vanishes in a full neighbourhood
//! and grows where the neighbourhood is cut off. Its length, averaged over
//! the neighbourhood with the density's weights ([`SmoothedLengths`], so
//! that one particle's disorder does not move its own target), says how
//! far a particle lies below a free surface. The target follows what the
//! layers of a cubic lattice with a flat top read, piecewise linearly in
//! that length: the top layer's density at the top layer's length and
//! beyond (edges and corners, which miss more, pack a little), each deeper
//! layer's at its own (at h = 2 spacings only the top layer misses a
//! share), and ρ0 from the first full layer's length or a quarter of the
//! top layer's, whichever is larger (the bulk's disorder), down. Thin
//! sheets and spray, whose gradients cancel, keep ρ0, as before.

use super::lane_map::LaneMap;
use super::lanes::{LaneKernels, Near};
use crate::NeighbourLists;
use crate::boundary::WallKernel;
use crate::simd::F32x8;

/// The averaged |∇C|, over the top layer's, below which the target stays
/// ρ0: the bulk's disorder.
const DEAD_ZONE: f32 = 0.25;

/// The most points of the target: every layer that misses a share of its
/// kernel (fewer than h over the spacing, at most
/// [`MAX_H_OVER_SPACING`](crate::solver::MAX_H_OVER_SPACING)) and the end
/// of the ramp.
const POINTS: usize = 12;

/// The target ρ/ρ0 as a function of the constraint gradient's length
/// |∇C| averaged over the neighbourhood (1/m, [`SmoothedLengths`]),
/// calibrated on a cubic lattice with a flat top: piecewise linear through
/// its layers' (averaged |∇C|, density) from the top down to the first
/// full layer, or to the bulk's disorder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SurfaceTarget {
    /// (averaged |∇C|, ρ/ρ_bulk), the |∇C| falling: the top layer's, the
    /// other layers that miss a share, and last the |∇C| at which the
    /// target reaches 1.
    points: [(f32, f32); POINTS],
    len: usize,
}

/// One layer of a lattice with a flat top ([`lattice_layers`]).
#[derive(Debug, Clone, Copy)]
struct Layer {
    /// Its summed density over ρ0 (m/ρ0 times the kernel sum).
    density: f32,
    /// |∇C|.
    length: f32,
    /// |∇C| averaged over the neighbourhood with the density's weights.
    smoothed: f32,
}

/// The layers of a cubic lattice of `spacing` with its top layer at y = 0,
/// of particles of `volume`, from the top down to the first beyond `h`
/// from the surface (which reads the bulk).
fn lattice_layers(
    h: f32,
    spacing: f32,
    volume: f32,
    w: &dyn Fn(f32) -> f32,
    dw: &dyn Fn(f32) -> f32,
) -> Vec<Layer> {
    let reach = (h / spacing).ceil() as i32;
    let depths = reach as usize + 2;
    let v = f64::from(volume);
    // The neighbours of a particle of layer k: lattice points within
    // `reach` across, of layers 0..depths (beyond that, the bulk's).
    let around = |k: i32, f: &mut dyn FnMut(i32, f32, f32)| {
        for a in -reach..=reach {
            for b in -reach..=reach {
                let layer = k + b;
                if layer < 0 {
                    continue;
                }
                for c in -reach..=reach {
                    let (x, y, z) = (a as f32 * spacing, b as f32 * spacing, c as f32 * spacing);
                    let r = (x * x + y * y + z * z).sqrt();
                    f(layer, r, y);
                }
            }
        }
    };
    let mut layers: Vec<Layer> = (0..depths as i32)
        .map(|k| {
            let (mut rho, mut n) = (0.0f64, 0.0f64);
            around(k, &mut |_, r, y| {
                rho += f64::from(w(r));
                // ∇_i W(x_i − x_j) = W'(r) (x_i − x_j)/r, x_j − x_i = (., −y, .):
                // the neighbour b layers deeper is y = b spacings below.
                if r > 0.0 {
                    n += f64::from(dw(r)) * f64::from(y / r);
                }
            });
            Layer {
                density: (v * rho) as f32,
                length: (v * n).abs() as f32,
                smoothed: 0.0,
            }
        })
        .collect();
    for k in 0..depths {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        around(k as i32, &mut |layer, r, _| {
            let length = layers.get(layer as usize).map_or(0.0, |l| l.length);
            num += f64::from(w(r)) * f64::from(length);
            den += f64::from(w(r));
        });
        layers[k].smoothed = (num / den) as f32;
    }
    layers
}

/// A [`SurfaceTarget`] kept for the lightest particle's mass.
pub(crate) type TargetCache = Option<(f32, SurfaceTarget)>;

impl SurfaceTarget {
    /// The target for a cubic lattice of `spacing`, particles of volume
    /// m/ρ0 `volume`, and a density of kernel `w(r)` whose gradient is
    /// `dw(r)` = dW/dr (the solver's own pair: the cubic spline's for
    /// both solvers that read it; the unit tests also take poly6's density
    /// with spiky's gradient), both 0 beyond `h`.
    pub(crate) fn lattice(
        h: f32,
        spacing: f32,
        volume: f32,
        w: impl Fn(f32) -> f32,
        dw: impl Fn(f32) -> f32,
    ) -> Self {
        let read = lattice_layers(h, spacing, volume, &w, &dw);
        let bulk = read[read.len() - 1].density;
        let top = read[0].smoothed;
        // The ramp ends at the first layer that reads the bulk's density,
        // or at the bulk's disorder.
        let full = read
            .iter()
            .position(|layer| layer.density >= bulk * (1.0 - 1e-4));
        let end = full.map_or(0.0, |k| read[k].smoothed).max(DEAD_ZONE * top);
        let mut points = [(0.0, 1.0); POINTS];
        let mut len = 0;
        for layer in &read[..full.unwrap_or(read.len())] {
            if len + 1 < POINTS && layer.smoothed > end {
                points[len] = (layer.smoothed, layer.density / bulk);
                len += 1;
            }
        }
        points[len] = (end, 1.0);
        Self {
            points,
            len: len + 1,
        }
    }

    /// The target ρ/ρ0 of a particle whose averaged constraint gradient
    /// is `n` long (1/m): the top layer's density at its |∇C| and beyond,
    /// 1 from the end of the ramp down, linear between the layers'.
    #[inline(always)]
    pub(crate) fn at(&self, n: f32) -> f32 {
        let points = &self.points[..self.len];
        if n >= points[0].0 {
            return points[0].1;
        }
        for pair in points.windows(2) {
            let ((n0, s0), (n1, s1)) = (pair[0], pair[1]);
            if n >= n1 {
                return s1 + (s0 - s1) * (n - n1) / (n0 - n1);
            }
        }
        1.0
    }

    /// The target of the lattice of the lightest of `masses` at
    /// `rest_density` under the solver's `kernels`, whose spacing the
    /// walls' `kernel` finds ([`WallKernel::lattice_layers`]), kept in
    /// `cache` while that mass stays. Heavier particles of a fluid of
    /// several masses get the same (as the walls' layers do). None without
    /// a particle, or for one so light that h spans more than
    /// [`MAX_H_OVER_SPACING`](crate::solver::MAX_H_OVER_SPACING) of its
    /// lattice, which no world admits (a calibration would cost
    /// (h/spacing)⁴).
    pub(crate) fn lightest(
        kernel: &WallKernel,
        kernels: &LaneKernels,
        rest_density: f32,
        masses: &[f32],
        cache: &mut TargetCache,
    ) -> Option<Self> {
        let lightest = super::lanes::lightest(masses);
        if !lightest.is_finite() {
            return None;
        }
        match *cache {
            Some((m, target)) if m == lightest => Some(target),
            _ => {
                let h = kernel.h();
                let spacing = kernel.lattice_layers(lightest, rest_density).spacing;
                // Every mass a world admits (`FluidParams::check_masses`:
                // a side of h/10 to a per cent in volume) is calibrated.
                let within = h / spacing <= 1.02 * crate::solver::MAX_H_OVER_SPACING;
                if !within {
                    return None;
                }
                let target = kernels.surface_target(h, spacing, lightest / rest_density);
                *cache = Some((lightest, target));
                Some(target)
            }
        }
    }
}

/// Each particle's |∇C| averaged over its neighbourhood with the
/// density's weights m_j W_ij, its own included: what [`SurfaceTarget::at`]
/// reads. The average keeps one particle's disorder from moving its own
/// target: with |∇C| alone, the top of DFSPH's 0.2 m pool leaned 1.21°
/// median and 3.96° at p99 after 2 s, against 0.98° and 2.46° without a
/// target; averaged, 1.07° and 2.87° (`cargo run --release -p
/// surfel-extract --example flat_pool -- dfsph --solver-toml 'dfsph = {
/// surface_target = true }'`).
pub(super) struct SmoothedLengths<'a> {
    pub(super) kernels: &'a LaneKernels,
    /// (x, y, z, m) per particle.
    pub(super) rows: &'a [[f32; 4]],
    pub(super) lists: &'a NeighbourLists,
    /// |∇C| per particle.
    pub(super) lengths: &'a [f32],
    /// W(0).
    pub(super) w0: f32,
}

impl LaneMap for SmoothedLengths<'_> {
    type Out = f32;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> f32 {
        let xi = self.rows[i];
        let (mut num, mut den) = (S::splat(0.0), S::splat(0.0));
        for (_, slots, count) in self.lists.lanes(i) {
            let c = Near::<S>::gather(xi, self.rows, slots, count);
            let (w, _) = self.kernels.eval(c.r2());
            // No mass past the particle's own neighbours.
            let weight = c.m * w;
            num = num + weight * S::gather(self.lengths, &c.slots);
            den = den + weight;
        }
        let own = xi[3] * self.w0;
        (num.sum() + own * self.lengths[i]) / (den.sum() + own)
    }
}

impl SmoothedLengths<'_> {
    /// Each particle's density target over ρ0 under `target`, into
    /// `targets`, from its averaged |∇C| (into `smoothed`).
    pub(super) fn targets(
        &self,
        target: SurfaceTarget,
        smoothed: &mut Vec<f32>,
        targets: &mut Vec<f32>,
    ) {
        let n = self.rows.len();
        super::lane_map::par_map(self, n, smoothed);
        targets.resize(n, 1.0);
        crate::region::for_each(targets, |i, t| *t = target.at(smoothed[i]));
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::kernels::{CubicSpline, Poly6, Spiky};

    /// Each layer of a lattice with a flat top, summed particle by
    /// particle: its density over the bulk's, and its |∇C| averaged over
    /// its neighbours' (as `SmoothedLengths` averages).
    fn layers(
        h: f32,
        s: f32,
        volume: f32,
        w: &dyn Fn(f32) -> f32,
        dw: &dyn Fn(f32) -> f32,
    ) -> Vec<(f32, f32)> {
        let reach = (h / s).ceil() as i32 + 1;
        // Every lattice point within `reach` across of the particle at
        // `depth`, with its depth.
        let near = |depth: i32| {
            let mut out = Vec::new();
            for a in -reach..=reach {
                for b in -2 * reach..=0 {
                    for c in -reach..=reach {
                        let xj = Vec3::new(a as f32, b as f32, c as f32) * s;
                        out.push((xj, -b));
                    }
                }
            }
            (Vec3::new(0.0, -(depth as f32) * s, 0.0), out)
        };
        let raw: Vec<(f32, f32)> = (0..=2 * reach)
            .map(|depth| {
                let (xi, around) = near(depth);
                let (mut rho, mut grad) = (0.0f32, Vec3::ZERO);
                for (xj, _) in around {
                    let d = xi - xj;
                    let r = d.length();
                    rho += volume * w(r);
                    if r > 0.0 {
                        grad += volume * dw(r) * d / r;
                    }
                }
                (rho, grad.length())
            })
            .collect();
        let bulk = raw[reach as usize + 1].0;
        (0..=reach as usize)
            .map(|depth| {
                let (xi, around) = near(depth as i32);
                let (mut num, mut den) = (0.0f32, 0.0f32);
                for (xj, dj) in around {
                    let weight = w((xi - xj).length());
                    num += weight * raw[dj as usize].1;
                    den += weight;
                }
                (raw[depth].0 / bulk, num / den)
            })
            .collect()
    }

    /// The lightest particle a world admits (`FluidParams::check_masses`,
    /// h/V^⅓ just over 10) gets a target, as do the built-in scenes'; none
    /// is switched off without a word.
    #[test]
    fn every_admitted_mass_is_calibrated() {
        let h = 0.04f32;
        let params = crate::solver::FluidParams::water(h);
        let rho0 = params.rest_density;
        let walls = WallKernel::cubic_spline(h);
        let kernels = LaneKernels::Cubic(super::super::lanes::LaneCubic::new(
            &CubicSpline::new(h).unwrap(),
        ));
        let lightest = 0.97 * rho0 * (h / crate::solver::MAX_H_OVER_SPACING).powi(3);
        for mass in [lightest, rho0 * (0.5 * h).powi(3)] {
            params.check_masses(&[mass]).unwrap();
            let mut cache = None;
            let target = SurfaceTarget::lightest(&walls, &kernels, rho0, &[mass], &mut cache);
            let target = target.unwrap_or_else(|| panic!("no target for {mass} kg"));
            assert!(target.at(f32::MAX) < 0.9, "{target:?}");
        }
        assert!(SurfaceTarget::lightest(&walls, &kernels, rho0, &[], &mut None).is_none());
    }

    /// With wider kernels the layers below the top miss a share too, and
    /// the target follows each.
    #[test]
    fn wider_kernels_hold_every_layer() {
        for ratio in [2.5f32, 3.0, 4.0] {
            let s = 0.02f32;
            let h = ratio * s;
            let cubic = CubicSpline::new(h).unwrap();
            let w = |r: f32| cubic.value_len(r);
            let dw = |r: f32| cubic.derivative_len(r);
            let reach = (h / s).ceil() as i32;
            let mut sum = 0.0;
            for a in -reach..=reach {
                for b in -reach..=reach {
                    for c in -reach..=reach {
                        sum += w((Vec3::new(a as f32, b as f32, c as f32) * s).length());
                    }
                }
            }
            let volume = 1.0 / sum;
            let target = SurfaceTarget::lattice(h, s, volume, w, dw);
            let read = layers(h, s, volume, &w, &dw);
            assert!(read[1].0 < 0.999, "h/s {ratio}: second layer {}", read[1].0);
            for &(rho, n) in &read {
                let off = (rho - target.at(n)).abs();
                assert!(
                    off <= 1e-4,
                    "h/s {ratio}: reads {rho}, target {}",
                    target.at(n)
                );
            }
        }
    }

    /// A lattice at rest reads its target at every layer: the top layer
    /// (0.85 ρ0 with the cubic spline, 0.81 with poly6 and spiky, at h = 2
    /// spacings) its own density, the layers below ρ0.
    #[test]
    fn a_lattice_at_rest_reads_its_target_at_every_layer() {
        let (h, s) = (0.04f32, 0.02f32);
        let cubic = CubicSpline::new(h).unwrap();
        let (poly6, spiky) = (Poly6::new(h).unwrap(), Spiky::new(h).unwrap());
        let cubic_w = |r: f32| cubic.value_len(r);
        let cubic_dw = |r: f32| cubic.derivative_len(r);
        let poly6_w = |r: f32| poly6.value_r2(r * r);
        let spiky_dw = |r: f32| spiky.gradient_len(Vec3::X * r, r).x;
        for (w, dw, top) in [
            (
                &cubic_w as &dyn Fn(f32) -> f32,
                &cubic_dw as &dyn Fn(f32) -> f32,
                0.8503,
            ),
            (&poly6_w, &spiky_dw, 0.809),
        ] {
            let volume = s * s * s;
            let target = SurfaceTarget::lattice(h, s, volume, w, dw);
            let read = layers(h, s, volume, w, dw);
            for (k, &(rho, n)) in read.iter().enumerate() {
                let expected = target.at(n);
                assert!(
                    (rho - expected).abs() < 1e-4,
                    "layer {k}: reads {rho} at |∇C| {n}, target {expected}"
                );
            }
            assert!((read[0].0 - top).abs() < 2e-3, "top layer {}", read[0].0);
            assert_eq!(target.at(0.0), 1.0);
            // Linear from the end of the ramp to the top layer's, that
            // beyond.
            let deficit = 1.0 - read[0].0;
            let (n0, end) = (target.points[0].0, target.points[target.len - 1].0);
            assert_eq!(target.len, 2);
            assert!(
                end >= read[1].1,
                "the ramp ends at the first full layer or below"
            );
            assert_eq!(target.at(end), 1.0);
            let middle = 0.5 * (end + n0);
            assert!((target.at(middle) - (1.0 - 0.5 * deficit)).abs() < 1e-4);
            assert!((target.at(1e9) - read[0].0).abs() < 1e-4);
        }
    }
}
