//! The extractor of thesis 4.2.1: initial guess from the particles, then
//! Newton-Raphson refinement with splitting.

use std::time::Instant;

use glam::{DMat3, Vec3};
use rayon::prelude::*;
use sph_core::Result;

use crate::field::ColourField;
use crate::{AllAround, ExtractParams, Mode, Stats, Surfel, Surfels, fill, tangent_basis};

/// What one particle contributes to the initial guess.
enum Guess {
    /// Deep inside (or never reaching the iso value): nothing.
    Interior,
    /// One surfel from the particle's own Newton-Raphson step (maybe split).
    Surface(Vec<Surfel>),
    /// Surface on several sides: six or eight surfels around it (eq. 35–36).
    AllAround(Vec<Surfel>),
    /// No neighbour: the analytic iso-sphere, final as it is.
    Lone(Vec<Surfel>),
}

/// The 6 box-face and 8 box-corner directions.
fn box_directions(which: AllAround) -> &'static [Vec3] {
    const S: f32 = 0.577_350_26; // 1/√3
    const FACES: [Vec3; 6] = [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ];
    const CORNERS: [Vec3; 8] = [
        Vec3::new(S, S, S),
        Vec3::new(-S, S, S),
        Vec3::new(S, -S, S),
        Vec3::new(-S, -S, S),
        Vec3::new(S, S, -S),
        Vec3::new(-S, S, -S),
        Vec3::new(S, -S, -S),
        Vec3::new(-S, -S, -S),
    ];
    match which {
        AllAround::Six => &FACES,
        AllAround::Eight => &CORNERS,
    }
}

/// Whether a surfel faces the camera (always, without one).
pub(crate) fn front_facing(p: &ExtractParams, s: &Surfel) -> bool {
    p.camera
        .is_none_or(|eye| (eye - s.position).dot(s.normal) > 0.0)
}

/// Four surfels covering `s` in its tangent plane (figure 6).
fn split(s: &Surfel) -> [Surfel; 4] {
    let (t1, t2) = tangent_basis(s.normal);
    let a = 0.5 * s.radius;
    [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)].map(|(u, v)| Surfel {
        position: s.position + a * (u * t1 + v * t2),
        normal: s.normal,
        // Covers the parent disc: its farthest points are r/√2 from a child.
        radius: s.radius * std::f32::consts::FRAC_1_SQRT_2 * 1.05,
    })
}

/// One Newton-Raphson step (eq. 33) from `x`: the new position and the outward
/// normal −∇c/|∇c| there, or `None` when the step is longer than `max_step` or
/// the gradient vanishes.
pub(crate) fn newton_step(
    field: &ColourField,
    iso: f32,
    x: Vec3,
    max_step: f32,
) -> Option<(Vec3, Vec3)> {
    let s = field.sample(x);
    let g2 = s.gradient.length_squared();
    if g2.is_nan() || g2 <= 1e-12 / (field.h() * field.h()) {
        return None;
    }
    let step = -(s.c - iso) * s.gradient / g2;
    if step.is_nan() || step.length() > max_step {
        return None;
    }
    Some((x + step, -s.gradient / g2.sqrt()))
}

fn initial_guess(field: &ColourField, p: &ExtractParams, i: usize) -> Guess {
    let h = p.h;
    let x = field.positions()[i];
    let r0 = p.radius * h;
    // Covariance of the neighbours about the particle (eq. 35), in f64.
    let mut cov = DMat3::ZERO;
    let mut neighbours = 0usize;
    field.grid().for_each_neighbour(i, |j, r, _| {
        if j != i {
            let d = r.as_dvec3();
            cov += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
            neighbours += 1;
        }
    });
    if neighbours == 0 {
        let Some(radius) = field.lone_iso_radius(field.volumes()[i], p.iso) else {
            return Guess::Interior;
        };
        // Face and corner directions together leave no gap wider than 35.3°.
        let surfels = box_directions(AllAround::Six)
            .iter()
            .chain(box_directions(AllAround::Eight))
            .map(|&d| Surfel {
                position: x + radius * d,
                normal: d,
                radius: 0.8 * radius,
            })
            .filter(|s| front_facing(p, s))
            .collect();
        return Guess::Lone(surfels);
    }
    let trace = cov.x_axis.x + cov.y_axis.y + cov.z_axis.z;
    let shape = if trace > 0.0 {
        cov.determinant() / (trace / 3.0).powi(3)
    } else {
        0.0 // coincident particles
    };
    if shape < p.covariance_threshold as f64 {
        let surfels = box_directions(p.all_around)
            .iter()
            .map(|&d| Surfel {
                position: x + 0.5 * h * d,
                normal: d,
                radius: r0,
            })
            .filter(|s| front_facing(p, s))
            .collect();
        return Guess::AllAround(surfels);
    }
    let s = field.sample(x);
    let g = s.gradient.length();
    if g.is_nan() || g <= 1e-6 / h {
        return Guess::Interior;
    }
    let normal = -s.gradient / g;
    let step = (s.c - p.iso) / g; // along the normal
    if step.abs() > p.interior_step * h {
        return Guess::Interior;
    }
    let surfel = Surfel {
        position: x + normal * step.clamp(-0.5 * h, 0.5 * h),
        normal,
        radius: r0,
    };
    let surfels = if s.laplacian.abs() * h * h > p.split_laplacian {
        split(&surfel).to_vec()
    } else {
        vec![surfel]
    };
    Guess::Surface(surfels.into_iter().filter(|s| front_facing(p, s)).collect())
}

pub(crate) fn run(field: &ColourField, p: &ExtractParams) -> Result<Surfels> {
    let mut stats = Stats {
        particles: field.len(),
        ..Default::default()
    };
    let start = Instant::now();
    let e0 = field.evaluations();
    let guesses: Vec<Guess> = (0..field.len())
        .into_par_iter()
        .map(|i| initial_guess(field, p, i))
        .collect();
    let mut work = Vec::new();
    let mut done = Vec::new();
    for g in guesses {
        match g {
            Guess::Interior => {}
            Guess::Surface(s) => {
                stats.surface_particles += 1;
                work.extend(s);
            }
            Guess::AllAround(s) => {
                stats.all_around += 1;
                work.extend(s);
            }
            Guess::Lone(s) => {
                stats.lone += 1;
                done.extend(s);
            }
        }
    }
    stats.initial = work.len() + done.len();
    stats.particle_evaluations = field.evaluations() - e0;
    stats.initial_time = start.elapsed();

    let start = Instant::now();
    let e1 = field.evaluations();
    let max_step = p.discard_step * p.h;
    for it in 0..p.iterations {
        let last = it + 1 == p.iterations;
        let stepped: Vec<Option<Surfel>> = work
            .par_iter()
            .map(|s| {
                let (position, normal) = newton_step(field, p.iso, s.position, max_step)?;
                Some(Surfel {
                    position,
                    normal,
                    radius: s.radius,
                })
            })
            .collect();
        stats.discarded += stepped.iter().filter(|s| s.is_none()).count();
        let kept = stepped.into_iter().flatten().filter(|s| front_facing(p, s));
        if last {
            done.extend(kept);
            work = Vec::new();
        } else {
            work = kept.flat_map(|s| split(&s)).collect();
        }
    }
    stats.refine_time = start.elapsed();

    if p.mode == Mode::Covered {
        let start = Instant::now();
        stats.filled = fill::close_holes(field, p, &mut done);
        stats.fill_time = start.elapsed();
    }
    stats.evaluations = field.evaluations() - e1;
    stats.surfels = done.len();
    Ok(Surfels {
        surfels: done,
        stats,
    })
}
