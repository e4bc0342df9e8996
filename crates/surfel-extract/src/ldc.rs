//! The layered-depth-cube reference extractor (end of thesis 4.2.1): the field on
//! a regular grid over the particles, three axis-aligned families of rays along
//! the grid lines, and one surfel per sign change of c − k_iso between
//! neighbouring grid points, placed by linear interpolation with the
//! interpolated gradient as its normal. Every grid point is evaluated once.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use sph_core::{Error, Result};

use crate::field::{ColourField, Sample};
use crate::{ExtractParams, Stats, Surfel, Surfels};

/// LDC grids and coverage lattices ([`crate::coverage::iso_points`]) of more
/// points than this are refused (memory and time).
pub const MAX_GRID_POINTS: u64 = 1 << 27;

/// Points per axis of a lattice of `spacing` from `lo` to past `hi`; an error
/// beyond [`MAX_GRID_POINTS`] in all (the product saturates, never wraps).
pub(crate) fn lattice_size(lo: Vec3, hi: Vec3, spacing: f32) -> Result<[usize; 3]> {
    let n = (((hi - lo) / spacing).ceil().as_dvec3() + 1.0).as_u64vec3();
    if n.x.saturating_mul(n.y).saturating_mul(n.z) > MAX_GRID_POINTS {
        return Err(Error::InvalidParameter {
            name: "spacing",
            value: spacing.to_string(),
            reason: "gives more than 2^27 lattice points: use a coarser spacing",
        });
    }
    Ok([n.x as usize, n.y as usize, n.z as usize])
}

/// LDC surfels at grid `spacing` (m); radius 0.75 × spacing so neighbouring
/// intersections overlap. `params` gives the iso value and the camera
/// (culling), and is validated as [`crate::extract_field`] validates it
/// (with the field's h).
pub fn extract_ldc(field: &ColourField, params: &ExtractParams, spacing: f32) -> Result<Surfels> {
    sph_core::error::positive("spacing", spacing)?;
    ExtractParams {
        h: field.h(),
        ..*params
    }
    .validate()?;
    let mut stats = Stats {
        particles: field.len(),
        ..Default::default()
    };
    let Some((lo, hi)) = field.support_bounds() else {
        return Ok(Surfels {
            surfels: Vec::new(),
            stats,
        });
    };
    let start = Instant::now();
    let [nx, ny, nz] = lattice_size(lo, hi, spacing)?;
    let at = |i: usize, j: usize, k: usize| lo + Vec3::new(i as f32, j as f32, k as f32) * spacing;
    let e0 = field.evaluations();
    let samples: Vec<Sample> = (0..nx * ny * nz)
        .into_par_iter()
        .map(|idx| field.sample(at(idx % nx, idx / nx % ny, idx / (nx * ny))))
        .collect();
    stats.evaluations = field.evaluations() - e0;
    let iso = params.iso;
    let samples = &samples;
    let surfels: Vec<Surfel> = (0..nx * ny * nz)
        .into_par_iter()
        .flat_map_iter(|idx| {
            let (i, j, k) = (idx % nx, idx / nx % ny, idx / (nx * ny));
            let a = samples[idx];
            let x = at(i, j, k);
            let next = [
                (i + 1 < nx).then(|| (idx + 1, Vec3::X)),
                (j + 1 < ny).then(|| (idx + nx, Vec3::Y)),
                (k + 1 < nz).then(|| (idx + nx * ny, Vec3::Z)),
            ];
            next.into_iter().flatten().filter_map(move |(b_idx, dir)| {
                let b = samples[b_idx];
                let (fa, fb) = (a.c - iso, b.c - iso);
                if (fa > 0.0) == (fb > 0.0) {
                    return None;
                }
                let t = fa / (fa - fb);
                let g = a.gradient.lerp(b.gradient, t);
                let normal = -g.try_normalize()?;
                let s = Surfel {
                    position: x + t * spacing * dir,
                    normal,
                    radius: 0.75 * spacing,
                };
                crate::thesis::front_facing(params, &s).then_some(s)
            })
        })
        .collect();
    stats.surfels = surfels.len();
    stats.initial_time = start.elapsed();
    Ok(Surfels { surfels, stats })
}
