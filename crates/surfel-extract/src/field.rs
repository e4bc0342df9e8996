//! The colour field c(x) = Σ_j V_j W_poly6(x − x_j) (thesis eq. 18, V_j = m_j/ρ_j)
//! and the iso function f = c − k_iso (eq. 34), evaluated anywhere through
//! `sph-core`'s neighbour grid, with every evaluation counted.
//!
//! The field is the thesis's isotropic one ([`Surface::Isotropic`]) or Yu &
//! Turk's anisotropic one ([`Surface::Anisotropic`], [`crate::anisotropy`]):
//! c(x) = Σ_j V_j det(G_j) W_poly6(|G_j (x − x̄_j)|) about smoothed centres
//! x̄_j. Both are evaluated through the same grid (built over the centres)
//! and give c, ∇c and ∇²c, so everything downstream works on either.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use sph_core::region;
use sph_core::{Error, NeighbourGrid, Neighbourhood, Particles, Poly6, Poly6Sums, Result};

use crate::anisotropy::{self, Anisotropy, Ellipsoid};
use crate::ellipsoid_sums::{SlotKernel, ellipsoid_sums, slot_kernel};

/// Which surface field the particles make.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Surface {
    /// The thesis's colour field: one isotropic poly6 kernel per particle,
    /// at the particle (eq. 18).
    #[default]
    Isotropic,
    /// Yu & Turk's (2013): kernels stretched along each neighbourhood's
    /// principal directions, about smoothed centres.
    Anisotropic(Anisotropy),
}

impl Surface {
    /// The anisotropic field with Yu & Turk's parameters.
    pub fn anisotropic() -> Self {
        Self::Anisotropic(Anisotropy::default())
    }

    /// Checks the anisotropy's parameters; the error names the field.
    pub fn validate(&self) -> Result<()> {
        match self {
            Self::Isotropic => Ok(()),
            Self::Anisotropic(a) => a.validate(),
        }
    }
}

/// c, ∇c and ∇²c at a point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// c(x).
    pub c: f32,
    /// ∇c(x).
    pub gradient: Vec3,
    /// ∇²c(x).
    pub laplacian: f32,
}

impl From<Poly6Sums> for Sample {
    /// c = Σ V_j W, ∇c = Σ V_j ∇W, ∇²c = Σ V_j ∇²W from sums weighted by volume.
    fn from(s: Poly6Sums) -> Self {
        Self {
            c: s.value,
            gradient: s.gradient,
            laplacian: s.laplacian,
        }
    }
}

/// The field at a particle and the shape of its neighbourhood.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ParticleSample {
    /// c, ∇c, ∇²c at the particle.
    pub sample: Sample,
    /// Σ (x_j − x)(x_j − x)ᵀ over the neighbours within h (eq. 35), as
    /// [xx, xy, xz, yy, yz, zz].
    pub covariance: [f32; 6],
    /// Other particles within h.
    pub neighbours: u32,
}

impl ParticleSample {
    /// P = det C / (tr C / 3)³ (eq. 36): 1 for an isotropic neighbourhood, near 0
    /// where it is flat or thin; 0 for coincident neighbours (C = 0).
    pub fn shape(&self) -> f64 {
        let [xx, xy, xz, yy, yz, zz] = self.covariance.map(f64::from);
        let trace = xx + yy + zz;
        if trace.is_nan() || trace <= 0.0 {
            return 0.0;
        }
        let det = xx * (yy * zz - yz * yz) - xy * (xy * zz - yz * xz) + xz * (xy * yz - yy * xz);
        det / (trace / 3.0).powi(3)
    }
}

/// A particle set's colour field, ready to evaluate at any point.
#[derive(Debug)]
pub struct ColourField {
    grid: NeighbourGrid,
    /// The kernels' centres: the particles' positions, or their smoothed
    /// centres for the anisotropic field.
    positions: Vec<Vec3>,
    /// Per particle (index order), its kernel's shape; empty for the
    /// isotropic field.
    shapes: Vec<Ellipsoid>,
    /// The anisotropic kernels' pass: its grid over the particles (radius
    /// `Anisotropy::radius` × h) and its output, kept between refills.
    wide: Option<NeighbourGrid>,
    kernels: Vec<(Vec3, Ellipsoid)>,
    /// Per slot of the grid, its particle's kernel as the anisotropic sums
    /// read it, in memory order.
    slot_kernels: Vec<SlotKernel>,
    surface: Surface,
    volumes: Vec<f32>,
    /// `volumes` in the grid's slot order, as its vectorised sums read them.
    slot_volumes: Vec<f32>,
    poly6: Poly6,
    evaluations: Counter,
}

/// Where a refilled field's particle volumes come from.
#[derive(Debug, Clone, Copy)]
enum Volumes<'a> {
    /// Shepard volumes 1/Σ_k W(x_j − x_k).
    Shepard,
    /// m/ρ with ρ = Σ m W recomputed from these masses.
    Density(&'a [f32]),
    /// Already in the field's `volumes`, one per particle.
    Kept,
}

impl ColourField {
    /// An empty field of the kind `surface` says, to fill with
    /// [`ColourField::refill_from_particles`] or
    /// [`ColourField::refill_from_positions`].
    ///
    /// # Errors
    /// Anisotropy parameters that do not validate.
    pub fn new(surface: Surface) -> Result<Self> {
        let mut field = Self::empty();
        field.set_surface(surface)?;
        Ok(field)
    }

    /// The field of particles with known volumes m/ρ.
    pub fn with_volumes(positions: &[Vec3], volumes: &[f32], h: f32) -> Result<Self> {
        let mut field = Self::empty();
        field.refill_with_volumes(positions, volumes, h)?;
        Ok(field)
    }

    /// The field of bare positions (any point set): each particle gets the Shepard
    /// volume 1/Σ_k W(x_j − x_k), so c ≈ 1 inside a uniform cloud and a lone point
    /// reaches c = 1 at its centre.
    pub fn from_positions(positions: &[Vec3], h: f32) -> Result<Self> {
        Self::empty().refilled(positions, h, Volumes::Shepard)
    }

    /// The field of simulated particles, V = m/ρ with the solver's densities.
    /// If any density is not finite and positive (not computed yet, or a
    /// particle added since the last step), every density is recomputed as
    /// ρ = Σ m W, without the solver's wall terms, so the whole field changes
    /// slightly, not that particle's alone.
    pub fn from_particles(particles: &Particles, h: f32) -> Result<Self> {
        let mut field = Self::empty();
        field.refill_from_particles(particles, h)?;
        Ok(field)
    }

    /// [`ColourField::from_particles`] in place, reusing this field's memory:
    /// what a loop over frames does. On error the field is left empty.
    pub fn refill_from_particles(&mut self, particles: &Particles, h: f32) -> Result<()> {
        let (x, m, rho) = (
            particles.positions(),
            particles.masses(),
            particles.densities(),
        );
        if rho.iter().all(|r| r.is_finite() && *r > 0.0) {
            self.volumes.clear();
            self.volumes.extend(m.iter().zip(rho).map(|(m, r)| m / r));
            return self.refill(x, h, Volumes::Kept);
        }
        self.refill(x, h, Volumes::Density(m))
    }

    /// [`ColourField::with_volumes`] in place, reusing this field's memory.
    /// On error the field is left empty.
    pub fn refill_with_volumes(
        &mut self,
        positions: &[Vec3],
        volumes: &[f32],
        h: f32,
    ) -> Result<()> {
        self.volumes.clear();
        self.volumes.extend_from_slice(volumes);
        self.refill(positions, h, Volumes::Kept)
    }

    /// [`ColourField::from_positions`] in place, reusing this field's memory. On
    /// error the field is left empty.
    pub fn refill_from_positions(&mut self, positions: &[Vec3], h: f32) -> Result<()> {
        self.refill(positions, h, Volumes::Shepard)
    }

    /// An empty field, to refill (its h is a placeholder until then).
    pub(crate) fn empty() -> Self {
        let h = 1.0;
        Self {
            grid: NeighbourGrid::build(&[], h).expect("an empty grid of h = 1 builds"),
            positions: Vec::new(),
            shapes: Vec::new(),
            slot_kernels: Vec::new(),
            wide: None,
            kernels: Vec::new(),
            surface: Surface::Isotropic,
            volumes: Vec::new(),
            slot_volumes: Vec::new(),
            poly6: Poly6::new(h).expect("h = 1 is a valid kernel radius"),
            evaluations: Counter::default(),
        }
    }

    fn refilled(mut self, positions: &[Vec3], h: f32, volumes: Volumes<'_>) -> Result<Self> {
        self.refill(positions, h, volumes)?;
        Ok(self)
    }

    /// Rebuilds the field for new particles, reusing its memory; on error the
    /// field is left empty (its h the former one, or the new one when the
    /// error came after the grid was rebuilt).
    fn refill(&mut self, positions: &[Vec3], h: f32, volumes: Volumes<'_>) -> Result<()> {
        let result = self.try_refill(positions, h, volumes);
        if result.is_err() {
            self.positions.clear();
            self.shapes.clear();
            self.slot_kernels.clear();
            self.volumes.clear();
            self.slot_volumes.clear();
            self.evaluations = Counter::default();
            // Empty, its memory kept (an empty set is always in range).
            let _ = self.grid.rebuild(&[]);
        }
        result
    }

    fn try_refill(&mut self, positions: &[Vec3], h: f32, volumes: Volumes<'_>) -> Result<()> {
        let (what, given) = match volumes {
            Volumes::Density(m) => ("masses", m.len()),
            Volumes::Kept => ("volumes", self.volumes.len()),
            Volumes::Shepard => ("positions", positions.len()),
        };
        if given != positions.len() {
            return Err(Error::LengthMismatch {
                what,
                actual: given,
                expected: positions.len(),
            });
        }
        // The kernel and the grid change together, or not at all.
        let poly6 = Poly6::new(h)?;
        sph_core::error::check_precise(positions, h)?;
        // The anisotropic field with its volumes given and a wider
        // neighbourhood for its kernels needs the grid at h only over the
        // kernel centres, built below.
        let centres_only = matches!(volumes, Volumes::Kept)
            && matches!(self.surface, Surface::Anisotropic(a) if a.radius != 1.0);
        if self.grid.h() == h {
            if !centres_only {
                self.grid.rebuild(positions)?;
            }
        } else {
            self.grid = NeighbourGrid::build(if centres_only { &[] } else { positions }, h)?;
        }
        self.poly6 = poly6;
        self.positions.clear();
        self.positions.extend_from_slice(positions);
        self.evaluations = Counter::default();
        match volumes {
            Volumes::Kept => {}
            Volumes::Shepard => self.grid.par_map_into(
                |_, nb| {
                    let mut sum = 0.0f32;
                    nb.for_each(|_, _, r2| sum += poly6.value_r2(r2));
                    1.0 / sum
                },
                &mut self.volumes,
            ),
            Volumes::Density(m) => self.grid.par_map_into(
                |i, nb| {
                    let mut rho = 0.0f32;
                    nb.for_each(|j, _, r2| rho += m[j] * poly6.value_r2(r2));
                    m[i] / rho
                },
                &mut self.volumes,
            ),
        }
        if let Some(i) = self
            .volumes
            .iter()
            .position(|v| !(v.is_finite() && *v > 0.0))
        {
            return Err(Error::InvalidParameter {
                name: "volume",
                value: format!("{} (particle {i})", self.volumes[i]),
                reason: "particle volumes m/ρ must be finite and positive",
            });
        }
        self.shapes.clear();
        if let Surface::Anisotropic(a) = self.surface {
            // The kernels from the particles' neighbourhoods; then the grid
            // over their centres, through which the field is evaluated.
            let grid = if a.radius == 1.0 {
                &self.grid
            } else {
                let r = a.radius * h;
                match &mut self.wide {
                    Some(wide) if wide.h() == r => wide.rebuild(positions)?,
                    wide => *wide = Some(NeighbourGrid::build(positions, r)?),
                }
                self.wide.as_ref().expect("built above")
            };
            anisotropy::kernels(grid, positions, &a, &mut self.kernels);
            self.positions.clear();
            self.positions.extend(self.kernels.iter().map(|k| k.0));
            self.shapes.extend(self.kernels.iter().map(|k| k.1));
            self.grid.rebuild(&self.positions)?;
        }
        let order = self.grid.order();
        let volumes = &self.volumes;
        self.slot_volumes.resize(order.len(), 0.0);
        region::for_each(&mut self.slot_volumes, |s, v| {
            *v = volumes[order[s] as usize]
        });
        self.slot_kernels.clear();
        if !self.shapes.is_empty() {
            // W_poly6 = k (h² − r²)³.
            let k = poly6.value_r2(0.0) / (h * h).powi(3);
            let shapes = &self.shapes;
            self.slot_kernels.resize(order.len(), [0.0; 8]);
            region::for_each(&mut self.slot_kernels, |s, out| {
                let i = order[s] as usize;
                let e = &shapes[i];
                *out = slot_kernel(e, volumes[i] * e.det * k);
            });
        }
        Ok(())
    }

    /// Which field this is; set it before a refill with
    /// [`ColourField::set_surface`].
    pub fn surface(&self) -> Surface {
        self.surface
    }

    /// Makes the next refill build `surface`'s field (the current particles'
    /// field is unchanged until then).
    ///
    /// # Errors
    /// Anisotropy parameters that do not validate.
    pub fn set_surface(&mut self, surface: Surface) -> Result<()> {
        surface.validate()?;
        self.surface = surface;
        Ok(())
    }

    /// The anisotropic kernels' shapes, one per particle in index order;
    /// empty for the isotropic field.
    pub fn shapes(&self) -> &[Ellipsoid] {
        &self.shapes
    }

    /// c, ∇c, ∇²c and the neighbours within h, with the second moment of
    /// their offsets when `SECOND`, from the anisotropic kernels about `x`.
    #[inline]
    fn anisotropic_sums<const SECOND: bool>(
        &self,
        nb: Neighbourhood<'_>,
    ) -> (Sample, [f32; 6], u32) {
        let h2 = self.h() * self.h();
        let sums = ellipsoid_sums::<SECOND>(nb, &self.slot_kernels, self.grid.len(), h2);
        let [c, gx, gy, gz, laplacian] = sums.value;
        let sample = Sample {
            c,
            gradient: Vec3::new(gx, gy, gz),
            laplacian,
        };
        (sample, sums.second, sums.count)
    }

    /// The smoothing length.
    pub fn h(&self) -> f32 {
        self.grid.h()
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The particle positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// The particles' bounding box grown by h, outside which c = 0; `None` when
    /// there are no particles.
    pub fn support_bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        let (lo, hi) = self
            .positions
            .iter()
            .fold((first, first), |(lo, hi), &x| (lo.min(x), hi.max(x)));
        let h = Vec3::splat(self.h());
        Some((lo - h, hi + h))
    }

    /// The particle volumes m/ρ.
    pub fn volumes(&self) -> &[f32] {
        &self.volumes
    }

    /// The neighbour grid over the particles.
    pub fn grid(&self) -> &NeighbourGrid {
        &self.grid
    }

    /// c, ∇c, ∇²c at `x` (one counted evaluation). Zero far from every particle and
    /// at non-finite points.
    #[inline]
    pub fn sample(&self, x: Vec3) -> Sample {
        self.evaluations.add();
        let nb = self.grid.neighbourhood_of_point(x);
        if self.shapes.is_empty() {
            nb.poly6_sums(&self.poly6, &self.slot_volumes).into()
        } else {
            self.anisotropic_sums::<false>(nb).0
        }
    }

    /// c, ∇c, ∇²c at particle `i` and the covariance of its neighbourhood about it
    /// (thesis eq. 35), from one scan (one counted evaluation).
    ///
    /// # Panics
    /// If `i` is not below [`ColourField::len`].
    pub fn sample_particle(&self, i: usize) -> ParticleSample {
        self.sample_neighbourhood(self.grid.neighbourhood(i))
    }

    /// [`ColourField::sample_particle`] for a particle's neighbourhood.
    #[inline]
    pub(crate) fn sample_neighbourhood(&self, nb: Neighbourhood<'_>) -> ParticleSample {
        self.evaluations.add();
        if !self.shapes.is_empty() {
            let (sample, covariance, count) = self.anisotropic_sums::<true>(nb);
            return ParticleSample {
                sample,
                covariance,
                neighbours: count.saturating_sub(1),
            };
        }
        // Offsets are at most h, so f32 sums of a few dozen terms are exact
        // enough for the shape test.
        let (sums, covariance) = nb.poly6_sums_and_second_moment(&self.poly6, &self.slot_volumes);
        ParticleSample {
            sample: sums.into(),
            covariance,
            // The particle finds itself.
            neighbours: sums.count.saturating_sub(1),
        }
    }

    /// Evaluations made since the field was built or last refilled.
    pub fn evaluations(&self) -> u64 {
        self.evaluations.total()
    }

    /// The distance from particle `i`, if it were alone, at which its kernel
    /// reaches `iso`: [`ColourField::lone_iso_radius`] for its volume, for
    /// an anisotropic field scaled by its kernel (an isolated particle's is
    /// a sphere `isolated_scale` × h in radius).
    pub fn lone_radius(&self, i: usize, iso: f32) -> Option<f32> {
        let volume = self.volumes[i];
        match self.shapes.get(i) {
            None => self.lone_iso_radius(volume, iso),
            Some(e) => {
                // det G = 1/a³ for a sphere of radius a h: c(aρ) = (V/a³) W(ρ).
                let a = e.det.cbrt().recip();
                self.lone_iso_radius(volume * e.det, iso).map(|r| a * r)
            }
        }
    }

    /// For a particle whose anisotropic kernel is an isolated one's sphere
    /// (a droplet of fewer than N_ε particles), its [`ColourField::lone_radius`];
    /// `None` for every other particle and for the isotropic field.
    pub fn droplet_radius(&self, i: usize, iso: f32) -> Option<f32> {
        let shape = self.shapes.get(i)?;
        if shape.isolated {
            self.lone_radius(i, iso)
        } else {
            None
        }
    }

    /// The distance from a lone particle of volume `volume` at which its field
    /// c(r) = V W_poly6(r) equals `iso`, or `None` if it never reaches `iso`.
    pub fn lone_iso_radius(&self, volume: f32, iso: f32) -> Option<f32> {
        let h = self.h() as f64;
        // V · 315/(64π h⁹) (h² − r²)³ = iso.
        let w = 315.0 / (64.0 * std::f64::consts::PI * h.powi(9));
        let d3 = iso as f64 / (volume as f64 * w);
        let d = d3.cbrt();
        (iso > 0.0 && d < h * h).then(|| (h * h - d).sqrt() as f32)
    }
}

/// An event counter that threads increment on separate cache lines: one shared
/// atomic would bounce its line between cores on every evaluation.
#[derive(Debug, Default)]
struct Counter {
    shards: [Shard; SHARDS],
}

/// One cache-line pair's worth of counter.
#[derive(Debug, Default)]
#[repr(align(128))]
struct Shard(AtomicU64);

const SHARDS: usize = 16;

impl Counter {
    #[inline]
    fn add(&self) {
        let shard = rayon::current_thread_index().map_or(SHARDS - 1, |i| i % SHARDS);
        self.shards[shard].0.fetch_add(1, Ordering::Relaxed);
    }

    fn total(&self) -> u64 {
        self.shards
            .iter()
            .map(|s| s.0.load(Ordering::Relaxed))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_and_laplacian_match_finite_differences() {
        let mut x = Vec::new();
        for k in 0..4 {
            for j in 0..4 {
                for i in 0..4 {
                    x.push(
                        Vec3::new(i as f32, j as f32, k as f32) * 0.5
                            + Vec3::splat(0.01 * (i * j) as f32),
                    );
                }
            }
        }
        let field = ColourField::from_positions(&x, 1.0).unwrap();
        let e = 1e-3f32;
        for p in [
            Vec3::new(0.3, 0.7, 0.2),
            Vec3::new(1.9, 1.0, 1.6),
            Vec3::splat(-0.4),
        ] {
            let s = field.sample(p);
            let mut lap = 0.0;
            for a in 0..3 {
                let mut d = Vec3::ZERO;
                d[a] = e;
                let (cp, cm) = (field.sample(p + d).c, field.sample(p - d).c);
                let fd = (cp - cm) / (2.0 * e);
                assert!(
                    (fd - s.gradient[a]).abs() < 2e-3 * (1.0 + s.gradient.length()),
                    "{p} axis {a}: {fd} vs {}",
                    s.gradient[a]
                );
                // The second difference needs a wider step in f32.
                let e2 = 2e-2;
                let (cp2, cm2) = (
                    field.sample(p + d / e * e2).c,
                    field.sample(p - d / e * e2).c,
                );
                lap += (cp2 - 2.0 * s.c + cm2) / (e2 * e2);
            }
            assert!(
                (lap - s.laplacian).abs() < 0.02 * (1.0 + s.laplacian.abs()),
                "{p}: {lap} vs {}",
                s.laplacian
            );
        }
        assert_eq!(field.evaluations(), 3 * 13);
    }

    /// The anisotropic field's ∇c and ∇²c against finite differences of its
    /// c, on a jittered block whose faces flatten its kernels; each
    /// kernel's integral stays 1 (det G), so the field inside is about 1;
    /// a lone particle reaches the iso value at [`ColourField::lone_radius`].
    #[test]
    fn anisotropic_field_matches_finite_differences() {
        let s = 0.02f32;
        let mut x = Vec::new();
        for k in 0..10 {
            for j in 0..10 {
                for i in 0..10 {
                    let jitter = Vec3::new(
                        ((i * 7 + j * 3 + k) % 5) as f32,
                        ((i + j * 5 + k * 3) % 7) as f32,
                        ((i * 3 + j + k * 7) % 3) as f32,
                    ) * 0.0005;
                    x.push(Vec3::new(i as f32, j as f32, k as f32) * s + jitter);
                }
            }
        }
        let volumes = vec![s * s * s; x.len()];
        let mut field = ColourField::empty();
        field.set_surface(Surface::anisotropic()).unwrap();
        field.volumes.extend_from_slice(&volumes);
        field.refill(&x, 2.0 * s, Volumes::Kept).unwrap();
        assert_eq!(field.shapes().len(), x.len());
        let inside = field.sample(Vec3::splat(4.5 * s)).c;
        assert!((inside - 1.0).abs() < 0.1, "c inside {inside}");
        let e = 1e-4f32;
        for p in [
            Vec3::new(0.09, 0.182, 0.09),
            Vec3::new(-0.002, 0.05, 0.1),
            Vec3::new(0.181, 0.181, 0.09),
        ] {
            let smp = field.sample(p);
            assert!(smp.c > 0.02 && smp.c < 1.5, "{p}: c {}", smp.c);
            let mut lap = 0.0;
            for a in 0..3 {
                let mut d = Vec3::ZERO;
                d[a] = e;
                let fd = (field.sample(p + d).c - field.sample(p - d).c) / (2.0 * e);
                assert!(
                    (fd - smp.gradient[a]).abs() < 0.02 * smp.gradient.length(),
                    "{p} axis {a}: {fd} vs {}",
                    smp.gradient[a]
                );
                let e2 = 5e-4;
                let d2 = d / e * e2;
                lap += (field.sample(p + d2).c - 2.0 * smp.c + field.sample(p - d2).c) / (e2 * e2);
            }
            assert!(
                (lap - smp.laplacian).abs()
                    < 0.02 * smp.laplacian.abs() + 0.05 * smp.gradient.length() / s,
                "{p}: {lap} vs {}",
                smp.laplacian
            );
        }
        // A lone particle: an isotropic kernel of half h, 8 times as high, so
        // that it reaches the iso value where the thesis's (V W(0) = 0.2 at
        // h = 2 spacings) does not.
        let mut lone = ColourField::empty();
        lone.set_surface(Surface::anisotropic()).unwrap();
        lone.volumes.push(s * s * s);
        lone.refill(&[Vec3::ZERO], 2.0 * s, Volumes::Kept).unwrap();
        let r = lone.lone_radius(0, 0.5).unwrap();
        assert_eq!(lone.lone_iso_radius(s * s * s, 0.5), None);
        assert!(r > 0.0 && r < s, "{r}");
        assert!((lone.sample(Vec3::new(r, 0.0, 0.0)).c - 0.5).abs() < 1e-3);
    }

    #[test]
    fn particle_sample_matches_the_point_query_and_measures_shape() {
        let cube: Vec<Vec3> = (0..343)
            .map(|i| Vec3::new((i % 7) as f32, (i / 7 % 7) as f32, (i / 49) as f32) * 0.4)
            .collect();
        let field = ColourField::from_positions(&cube, 1.0).unwrap();
        for i in [0, 24, 171, 342] {
            let at = field.sample_particle(i);
            // The same rows in the same order: bitwise the same sums.
            assert_eq!(at.sample, field.sample(cube[i]));
        }
        // The centre of the cube: a symmetric, isotropic neighbourhood.
        let centre = field.sample_particle(171);
        let within = cube.iter().filter(|x| x.distance_squared(cube[171]) <= 1.0);
        assert_eq!(centre.neighbours as usize, within.count() - 1);
        assert_eq!(centre.neighbours, 80);
        assert!((centre.shape() - 1.0).abs() < 1e-6, "{}", centre.shape());
        // A plane of particles: one eigenvalue of C vanishes.
        let plane: Vec<Vec3> = (0..49)
            .map(|i| Vec3::new((i % 7) as f32, (i / 7) as f32, 0.0) * 0.4)
            .collect();
        let field = ColourField::from_positions(&plane, 1.0).unwrap();
        assert!(field.sample_particle(24).shape().abs() < 1e-9);
        // Coincident particles: C = 0.
        let field = ColourField::from_positions(&[Vec3::ONE; 3], 1.0).unwrap();
        assert_eq!(field.sample_particle(0).shape(), 0.0);
        assert_eq!(field.sample_particle(0).neighbours, 2);
    }

    #[test]
    fn lone_particle_reaches_iso_at_the_analytic_radius() {
        let field = ColourField::from_positions(&[Vec3::ZERO], 0.1).unwrap();
        let r = field.lone_iso_radius(field.volumes()[0], 0.5).unwrap();
        assert!((r / 0.1 - (1.0 - 0.5f32.cbrt()).sqrt()).abs() < 1e-5);
        assert!((field.sample(Vec3::new(0.0, r, 0.0)).c - 0.5).abs() < 1e-5);
        assert_eq!(field.lone_iso_radius(field.volumes()[0], 1.5), None);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(ColourField::from_positions(&[Vec3::NAN], 0.1).is_err());
        assert!(ColourField::from_positions(&[Vec3::ZERO], 0.0).is_err());
        assert!(ColourField::with_volumes(&[Vec3::ZERO], &[-1.0], 0.1).is_err());
        // The length is checked first, whatever h.
        for h in [0.1, 0.0] {
            assert!(matches!(
                ColourField::with_volumes(&[Vec3::ZERO], &[], h),
                Err(Error::LengthMismatch {
                    what: "volumes",
                    actual: 0,
                    expected: 1
                })
            ));
        }
        // A failed refill leaves the field empty, its kernel and grid agreeing.
        let mut field = ColourField::from_positions(&[Vec3::ZERO, Vec3::X], 0.1).unwrap();
        field.sample(Vec3::ZERO);
        assert!(field.refill_from_positions(&[Vec3::NAN], 0.2).is_err());
        assert!(field.is_empty() && field.volumes().is_empty());
        assert_eq!((field.h(), field.evaluations()), (0.1, 0));
        assert_eq!(field.sample(Vec3::ZERO), Sample::default());
        field.refill_from_positions(&[Vec3::ZERO], 0.2).unwrap();
        assert_eq!(field.h(), 0.2);
        assert_eq!(
            field.lone_iso_radius(field.volumes()[0], 0.5),
            ColourField::from_positions(&[Vec3::ZERO], 0.2)
                .unwrap()
                .lone_iso_radius(field.volumes()[0], 0.5)
        );
        let empty = ColourField::from_positions(&[], 0.1).unwrap();
        assert_eq!(empty.sample(Vec3::ZERO), Sample::default());
    }
}
