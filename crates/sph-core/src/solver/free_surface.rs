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
//! and grows where the neighbourhood is cut off. A particle whose gradient
//! is n0 long, that of a lattice's top layer under a flat surface, is held
//! to the density that layer reads, and the target ramps linearly in |∇C|
//! from ρ0 at a quarter of n0 (below which the bulk's disorder stays
//! untouched) to it, and stays there beyond (edges and corners, which miss
//! more, pack a little: twice the deficit there made the surfaces of
//! settled pools rougher). Thin sheets and spray, whose gradients cancel,
//! keep ρ0, as before.
//!
//! At h = 2 spacings only the top layer misses a share. With wider
//! kernels the next layer misses some too, which the ramp does not follow:
//! it is held to ρ0 against the 0.976 ρ0 it reads at h = 3 spacings, and so
//! packs a little.

use crate::boundary::WallKernel;

/// |∇C| over n0 below which the target stays ρ0: the bulk's disorder.
const DEAD_ZONE: f32 = 0.25;

/// The target ρ/ρ0 as a function of the constraint gradient's length
/// |∇C| (1/m), calibrated on a cubic lattice with a flat top.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SurfaceTarget {
    /// 1 − ρ_top/ρ_bulk: the share of its density a lattice's top layer
    /// misses.
    deficit: f32,
    /// That layer's |∇C| (1/m).
    n0: f32,
}

/// A [`SurfaceTarget`] kept for the lightest particle's mass.
pub(crate) type TargetCache = Option<(f32, SurfaceTarget)>;

impl SurfaceTarget {
    /// The target for a cubic lattice of `spacing`, particles of volume
    /// m/ρ0 `volume`, and a density of kernel `w(r)` whose gradient is
    /// `dw(r)` = dW/dr (the solver's own pair, which for PBF's Jacobi
    /// solve is poly6's density and spiky's gradient), both 0 beyond `h`.
    pub(crate) fn lattice(
        h: f32,
        spacing: f32,
        volume: f32,
        w: impl Fn(f32) -> f32,
        dw: impl Fn(f32) -> f32,
    ) -> Self {
        let reach = (h / spacing).ceil() as i32;
        let (mut bulk, mut top, mut n) = (0.0f64, 0.0f64, 0.0f64);
        for a in -reach..=reach {
            for b in -reach..=reach {
                for c in -reach..=reach {
                    let (x, y, z) = (a as f32 * spacing, b as f32 * spacing, c as f32 * spacing);
                    let r = (x * x + y * y + z * z).sqrt();
                    let weight = f64::from(w(r));
                    bulk += weight;
                    // The top layer at y = 0, the fluid at y ≤ 0: the
                    // gradient ∇_i W(x_i − x_j) = W'(r) (x_i − x_j)/r.
                    if b <= 0 {
                        top += weight;
                        if r > 0.0 {
                            n += f64::from(dw(r)) * f64::from(-y / r);
                        }
                    }
                }
            }
        }
        let v = f64::from(volume);
        Self {
            deficit: ((bulk - top) / bulk) as f32,
            n0: (v * n).abs() as f32,
        }
    }

    /// The target ρ/ρ0 of a particle whose constraint gradient is `n` long
    /// (1/m): 1 up to a quarter of n0, linear to 1 − deficit at n0, and
    /// that beyond.
    #[inline(always)]
    pub(crate) fn at(&self, n: f32) -> f32 {
        let dead = DEAD_ZONE * self.n0;
        let t = ((n - dead) / (self.n0 - dead)).clamp(0.0, 1.0);
        1.0 - self.deficit * t
    }

    /// The target of the lattice of the lightest of `masses` at
    /// `rest_density`, whose spacing the walls' `kernel` finds
    /// ([`WallKernel::lattice_layers`]), kept in `cache` while that mass
    /// stays; `of(spacing, volume)` calibrates it. None without a particle.
    pub(crate) fn lightest(
        kernel: &WallKernel,
        rest_density: f32,
        masses: &[f32],
        cache: &mut TargetCache,
        of: impl FnOnce(f32, f32) -> Self,
    ) -> Option<Self> {
        let lightest = super::lanes::lightest(masses);
        if !lightest.is_finite() {
            return None;
        }
        match *cache {
            Some((m, target)) if m == lightest => Some(target),
            _ => {
                let spacing = kernel.lattice_layers(lightest, rest_density).spacing;
                let target = of(spacing, lightest / rest_density);
                *cache = Some((lightest, target));
                Some(target)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::kernels::{CubicSpline, Poly6, Spiky};

    /// Each layer of a lattice with a flat top, summed particle by
    /// particle: its density over the bulk's and its gradient's length.
    fn layers(
        h: f32,
        s: f32,
        volume: f32,
        w: &dyn Fn(f32) -> f32,
        dw: &dyn Fn(f32) -> f32,
    ) -> Vec<(f32, f32)> {
        let reach = (h / s).ceil() as i32 + 1;
        let mut out = Vec::new();
        for depth in 0..reach + 1 {
            let xi = Vec3::new(0.0, -(depth as f32) * s, 0.0);
            let (mut rho, mut grad) = (0.0f32, Vec3::ZERO);
            for a in -reach..=reach {
                for b in -2 * reach..=0 {
                    for c in -reach..=reach {
                        let xj = Vec3::new(a as f32, b as f32, c as f32) * s;
                        let d = xi - xj;
                        let r = d.length();
                        rho += volume * w(r);
                        if r > 0.0 {
                            grad += volume * dw(r) * d / r;
                        }
                    }
                }
            }
            out.push((rho, grad.length()));
        }
        let bulk = out.last().unwrap().0;
        out.iter().map(|&(rho, n)| (rho / bulk, n)).collect()
    }

    /// A lattice at rest reads its target at every layer: the top layer
    /// (0.85 ρ0 with the cubic spline, 0.81 with poly6 and spiky, at h = 2
    /// spacings) its own density, the layers below ρ0.
    /// With wider kernels the layers below the top miss a share too,
    /// which the ramp does not follow: the top layer still reads its
    /// target, the second is held to ρ0 against its 0.996 at h = 2.5
    /// spacings, 0.976 at 3, and to 0.912 against 0.919 at 4.
    #[test]
    fn wider_kernels_hold_the_top_layer() {
        for (ratio, below) in [(2.5f32, 0.005), (3.0, 0.025), (4.0, 0.01)] {
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
            let (top, n) = read[0];
            assert!((top - target.at(n)).abs() < 1e-4, "h/s {ratio}: {top}");
            for &(rho, n) in &read[1..] {
                let off = (rho - target.at(n)).abs();
                assert!(
                    off <= below,
                    "h/s {ratio}: reads {rho}, target {}",
                    target.at(n)
                );
            }
        }
    }

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
                0.850,
            ),
            (&poly6_w, &spiky_dw, 0.81),
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
            assert!((read[0].0 - top).abs() < 0.01, "top layer {}", read[0].0);
            assert_eq!(target.at(0.0), 1.0);
            // Linear from a quarter of n0, the top layer's beyond.
            let deficit = 1.0 - read[0].0;
            assert_eq!(target.at(DEAD_ZONE * target.n0), 1.0);
            let half = 1.0 - deficit * (0.5 - DEAD_ZONE) / (1.0 - DEAD_ZONE);
            assert!((target.at(0.5 * target.n0) - half).abs() < 1e-4);
            assert!((target.at(1e9) - read[0].0).abs() < 1e-4);
        }
    }
}
