//! Quality metrics for a surfel set against the field it came from: iso-surface
//! samples found independently of any extractor (bisection along axis-aligned
//! rays), the fraction of them that some surfel covers, and the residual
//! |c(x_s) − k_iso| and normal error at the surfels.

use glam::UVec3;
use glam::Vec3;
use rayon::prelude::*;
use sph_core::{Error, Result};

use crate::Surfel;
use crate::field::ColourField;
use crate::fill::SurfelIndex;
use crate::ldc::lattice_size;

/// Points on c = `iso`: along rays parallel to x, y and z through a square
/// lattice of `spacing` over the particles' bounding box (grown by h), every sign
/// change of c − iso found by marching in steps of `spacing` and located by 40
/// bisections. Errors for an `iso` outside (0, 1) ([`crate::check_iso`]),
/// and a `spacing` that is not finite and positive or that gives more than
/// [`crate::ldc::MAX_GRID_POINTS`] lattice points.
pub fn iso_points(field: &ColourField, iso: f32, spacing: f32) -> Result<Vec<Vec3>> {
    crate::check_iso(iso)?;
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(Error::InvalidParameter {
            name: "spacing",
            value: spacing.to_string(),
            reason: "must be finite and > 0",
        });
    }
    let Some((lo, hi)) = field.support_bounds() else {
        return Ok(Vec::new());
    };
    let n = lattice_size(lo, hi, spacing)?;
    let n = UVec3::new(n[0] as u32, n[1] as u32, n[2] as u32);
    let f = |x: Vec3| field.sample(x).c - iso;
    let mut rays = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for i in 0..n[u] {
            for j in 0..n[v] {
                let mut o = lo;
                o[u] += i as f32 * spacing;
                o[v] += j as f32 * spacing;
                rays.push((axis, o));
            }
        }
    }
    let points = rays
        .par_iter()
        .flat_map_iter(|&(axis, o)| {
            let mut dir = Vec3::ZERO;
            dir[axis] = spacing;
            let mut out = Vec::new();
            let mut prev = f(o);
            for k in 1..n[axis] {
                let (a, b) = (o + (k - 1) as f32 * dir, o + k as f32 * dir);
                let cur = f(b);
                if (prev > 0.0) != (cur > 0.0) {
                    let (mut a, mut b, mut fa) = (a, b, prev);
                    for _ in 0..40 {
                        let m = 0.5 * (a + b);
                        let fm = f(m);
                        if (fm > 0.0) == (fa > 0.0) {
                            (a, fa) = (m, fm);
                        } else {
                            b = m;
                        }
                    }
                    out.push(0.5 * (a + b));
                }
                prev = cur;
            }
            out
        })
        .collect();
    Ok(points)
}

/// The fraction of `points` lying on some surfel's disc (within `thickness` of
/// its plane). Errors for no points (a fraction of nothing would read as
/// full coverage of a surface that was never found), for surfels with
/// non-finite positions, and for normals that are not unit vectors (a zero
/// normal would make its disc a ball, covering whatever lies near it).
pub fn covered_fraction(surfels: &[Surfel], points: &[Vec3], thickness: f32) -> Result<f64> {
    if points.is_empty() {
        return Err(Error::InvalidParameter {
            name: "points",
            value: "[]".into(),
            reason: "no points to cover: the fraction of none is undefined",
        });
    }
    if let Some(s) = surfels.iter().find(|s| !s.normal.is_normalized()) {
        return Err(Error::InvalidParameter {
            name: "surfel normal",
            value: s.normal.to_string(),
            reason: "must be a unit vector",
        });
    }
    let index = SurfelIndex::build(surfels, thickness)?;
    let covered = points
        .par_iter()
        .filter(|&&q| index.covered(surfels, q))
        .count();
    Ok(covered as f64 / points.len() as f64)
}

/// The volume where c > `iso` (m³), counted in cubes of side `step` over
/// the field's support (each cube inside when c at its centre is). Errors
/// for an `iso` outside (0, 1) ([`crate::check_iso`]), and a `step` that is
/// not finite and positive or that gives more than
/// [`crate::ldc::MAX_GRID_POINTS`] cubes.
pub fn enclosed_volume(field: &ColourField, iso: f32, step: f32) -> Result<f64> {
    crate::check_iso(iso)?;
    if !(step.is_finite() && step > 0.0) {
        return Err(Error::InvalidParameter {
            name: "step",
            value: step.to_string(),
            reason: "must be finite and > 0",
        });
    }
    let Some((lo, hi)) = field.support_bounds() else {
        return Ok(0.0);
    };
    let [nx, ny, nz] = lattice_size(lo, hi, step)?;
    let cubes = nx * ny * nz;
    let inside = (0..cubes)
        .into_par_iter()
        .filter(|&k| {
            let (i, j, l) = (k % nx, k / nx % ny, k / (nx * ny));
            let x = lo + (Vec3::new(i as f32, j as f32, l as f32) + 0.5) * step;
            field.sample(x).c > iso
        })
        .count();
    Ok(inside as f64 * f64::from(step).powi(3))
}

/// Distribution of the surfels' placement errors.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Residuals {
    /// Median |c(x_s) − iso|.
    pub median: f32,
    /// 95th percentile |c(x_s) − iso|.
    pub p95: f32,
    /// Median angle between the surfel normal and −∇c at its centre (degrees).
    pub median_angle_deg: f32,
}

fn percentile(mut v: Vec<f32>, q: f32) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    v[((v.len() - 1) as f32 * q).round() as usize]
}

/// Residuals of `surfels` on the field's iso-surface `iso`.
pub fn residuals(field: &ColourField, iso: f32, surfels: &[Surfel]) -> Residuals {
    let (res, angle): (Vec<f32>, Vec<f32>) = surfels
        .par_iter()
        .map(|s| {
            let x = field.sample(s.position);
            let n = -x.gradient.normalize_or_zero();
            let cos = n.dot(s.normal).clamp(-1.0, 1.0);
            ((x.c - iso).abs(), cos.acos().to_degrees())
        })
        .unzip();
    Residuals {
        median: percentile(res.clone(), 0.5),
        p95: percentile(res, 0.95),
        median_angle_deg: percentile(angle, 0.5),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lone particle's iso-sphere (radius from the field's own formula):
    /// the cubes inside it add up to its volume within 1 %.
    #[test]
    fn enclosed_volume_of_a_lone_particle() {
        let field = ColourField::with_volumes(&[Vec3::ZERO], &[5e-4], 0.1).unwrap();
        let r = field.lone_iso_radius(5e-4, 0.5).unwrap();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * f64::from(r).powi(3);
        let v = enclosed_volume(&field, 0.5, 0.002).unwrap();
        assert!((v / exact - 1.0).abs() < 0.01, "{v} vs {exact}");
    }

    #[test]
    fn bad_or_huge_lattices_are_errors() {
        let field = ColourField::from_positions(&[Vec3::ZERO, Vec3::X * 0.01], 0.04).unwrap();
        assert!(!iso_points(&field, 0.5, 0.01).unwrap().is_empty());
        for spacing in [0.0, -1.0, f32::NAN, f32::INFINITY, 1e-9] {
            assert!(iso_points(&field, 0.5, spacing).is_err(), "{spacing}");
            assert!(enclosed_volume(&field, 0.5, spacing).is_err(), "{spacing}");
        }
        // An iso outside (0, 1): below 0 the whole support box would count
        // as inside, NaN would find nothing.
        let iso_of = |e: Error| match e {
            Error::InvalidParameter { name, .. } => name,
            e => panic!("{e}"),
        };
        for iso in [-1.0, 0.0, 1.0, f32::NAN] {
            assert_eq!(iso_of(iso_points(&field, iso, 0.01).unwrap_err()), "iso");
            assert_eq!(
                iso_of(enclosed_volume(&field, iso, 0.01).unwrap_err()),
                "iso"
            );
        }
    }

    /// Surfels whose normals are not unit vectors are refused: a zero
    /// normal's disc would be a ball covering every point near it.
    #[test]
    fn covered_fraction_refuses_bad_normals() {
        let points = [Vec3::ZERO, Vec3::X];
        let surfel = |normal| Surfel {
            position: Vec3::ZERO,
            normal,
            radius: 0.1,
        };
        assert_eq!(
            covered_fraction(&[surfel(Vec3::Y)], &points, 0.01).unwrap(),
            0.5
        );
        for normal in [Vec3::ZERO, Vec3::NAN, 2.0 * Vec3::Y] {
            match covered_fraction(&[surfel(Vec3::Y), surfel(normal)], &points, 0.01) {
                Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "surfel normal"),
                other => panic!("{normal}: {other:?}"),
            }
        }
    }
}
