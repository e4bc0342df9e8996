//! The extractor of thesis 4.2.1: initial guess from the particles, then
//! Newton-Raphson refinement with splitting.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use glam::Vec3;
use sph_core::Result;
use sph_core::region;

use crate::field::{ColourField, ParticleSample, Surface};
use crate::flatten::par_extend_flat;
use crate::{AllAround, ExtractParams, Mode, Split, Stats, Surfel, fill, tangent_basis};

/// What one particle contributes to the initial guess.
#[derive(Debug, Clone, Copy)]
enum Guess {
    /// Deep inside (or never reaching the iso value): nothing.
    Interior,
    /// One surfel from the particle's own Newton-Raphson step, split in four
    /// where the laplacian is large (figure 6).
    Surface { surfel: Surfel, split: bool },
    /// Surface on several sides: six or eight surfels around it (eq. 35–36).
    AllAround,
    /// The same on the anisotropic field, each surfel where c crosses the
    /// iso value along its direction (NaN: no crossing within reach, no
    /// surfel): a thin sheet's or filament's kernels are thin, and surfels
    /// half an h out, as the thesis places them, were mostly discarded.
    AllAroundAt { distances: [f32; 8] },
    /// No neighbour: its analytic iso-sphere of this radius, final as it is.
    Lone { radius: f32 },
    /// A particle of a droplet too small for anisotropic kernels (its own
    /// an isolated sphere): [`DROPLET_SEEDS`] surfels on the sphere of its
    /// lone iso radius, refined (and split) like the others.
    Droplet { radius: f32 },
}

/// Surfels on a lone particle's sphere in the anisotropic field, final as
/// they are: with 14 (the thesis's box directions) a droplet rendered as a
/// cut gem (silhouette IoU 0.62 and a median normal error of 19.7° against
/// the ray caster), with 162 its outline still bulged (IoU 0.94), with 400
/// 0.973 and 3.2° (`tests/reference_render.rs`, case `droplet`).
const DROPLET_DIRECTIONS: usize = 400;

/// Surfels on the sphere of a particle of a small droplet, before the
/// refinement splits each into 9, then 4 per iteration.
const DROPLET_SEEDS: usize = 100;

/// `k` directions spread evenly over the sphere (a Fibonacci lattice).
fn sphere_directions(k: usize) -> impl Iterator<Item = Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5.0f32.sqrt());
    (0..k).map(move |i| {
        let z = 1.0 - (2 * i + 1) as f32 / k as f32;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * i as f32;
        Vec3::new(r * phi.cos(), z, r * phi.sin())
    })
}

/// The surfels on a sphere of `radius` about `x` from `k` directions, each
/// disc wide enough that they overlap (1.3 × the radius of the cap each
/// direction owns, 4π radius²/k in area) and its plane sunk by a quarter
/// of its rim's rise ρ²/2R above the sphere, so that the discs' outline
/// matches the sphere's on average rather than bulging beyond it.
fn sphere_surfels(x: Vec3, radius: f32, k: usize) -> impl Iterator<Item = Surfel> {
    let disc = 1.3 * radius * (4.0 / k as f32).sqrt();
    let sunk = radius - 0.125 * disc * disc / radius;
    sphere_directions(k).map(move |d| Surfel {
        position: x + sunk * d,
        normal: d,
        radius: disc,
    })
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

/// The surfels covering `s` in its tangent plane (figure 6): the disc's
/// bounding square cut into `grid`'s cells, one surfel per cell, each wide
/// enough to cover its cell's corners (5 % over).
fn split(s: &Surfel, grid: Split) -> impl Iterator<Item = Surfel> + use<> {
    let (t1, t2) = tangent_basis(s.normal);
    let n = cells(grid);
    let (centre, normal, r) = (s.position, s.normal, s.radius);
    // Cell centres at (n − 1 − 2k)/n of the radius: ±1/2 for 2×2, 0 and
    // ±2/3 for 3×3.
    let offset = move |k: u32| (n as f32 - 1.0 - 2.0 * k as f32) / n as f32;
    (0..n * n).map(move |k| Surfel {
        position: centre + r * (offset(k % n) * t1 + offset(k / n) * t2),
        normal,
        // Half a cell's diagonal, √2 r/n.
        radius: r * (std::f32::consts::SQRT_2 / n as f32) * 1.05,
    })
}

/// Cells along each side of a split.
fn cells(grid: Split) -> u32 {
    match grid {
        Split::TwoByTwo => 2,
        Split::ThreeByThree => 3,
    }
}

/// How far the corner children of a split of a surfel of `radius` lie from
/// its centre: √2 (n − 1)/n of the radius.
fn corner_distance(grid: Split, radius: f32) -> f32 {
    let n = cells(grid) as f32;
    std::f32::consts::SQRT_2 * (n - 1.0) / n * radius
}

/// Where one Newton-Raphson step (eq. 33) went.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Step {
    /// The point the step reaches.
    pub position: Vec3,
    /// The outward normal −∇c/|∇c| where the step started.
    pub normal: Vec3,
    /// |∇²c|/|∇c| where the step started (1/m). On the iso-surface, where the
    /// colour field's second derivative along the normal vanishes (the middle
    /// of its smooth step from 1 to 0), ∇²c = −(κ₁ + κ₂)|∇c|: the summed
    /// principal curvatures.
    pub bend: f32,
}

impl Step {
    /// How far the surface curves away from the tangent plane at distance `d`
    /// from the step's end, bend·d²/2: exact for a cylinder, twice a sphere's.
    pub fn sag(&self, d: f32) -> f32 {
        0.5 * self.bend * d * d
    }
}

/// One Newton-Raphson step (eq. 33) from `x`, or `None` when the step is
/// longer than `max_step` or the gradient vanishes.
pub(crate) fn newton_step(field: &ColourField, iso: f32, x: Vec3, max_step: f32) -> Option<Step> {
    let s = field.sample(x);
    let g2 = s.gradient.length_squared();
    if g2.is_nan() || g2 <= 1e-12 / (field.h() * field.h()) {
        return None;
    }
    let mut step = -(s.c - iso) * s.gradient / g2;
    if step.is_nan() {
        return None;
    }
    let g = g2.sqrt();
    if step.length() > max_step {
        // The anisotropic field's thin kernels leave c flat far from them,
        // where a Newton step overshoots: its crossing along the normal
        // within the step limit is kept instead (safeguarded Newton). The
        // thesis's field discards the surfel.
        let Surface::Anisotropic(_) = field.surface() else {
            return None;
        };
        let n = -s.gradient / g;
        step = n * crossing(field, iso, x, s.c, n, max_step, 0.0)?;
    }
    Some(Step {
        position: x + step,
        normal: -s.gradient / g,
        bend: s.laplacian.abs() / g,
    })
}

/// Classifies particle `i` from its field sample and neighbourhood shape.
fn initial_guess(field: &ColourField, p: &ExtractParams, i: usize, at: &ParticleSample) -> Guess {
    let h = p.h;
    if at.neighbours == 0 {
        return match field.lone_radius(i, p.iso) {
            Some(radius) => Guess::Lone { radius },
            None => Guess::Interior,
        };
    }
    if let Some(radius) = field.droplet_radius(i, p.iso) {
        return Guess::Droplet { radius };
    }
    if at.shape() < p.covariance_threshold as f64 {
        return match field.surface() {
            Surface::Isotropic => Guess::AllAround,
            Surface::Anisotropic(_) => {
                let x = field.positions()[i];
                let mut distances = [f32::NAN; 8];
                for (t, &d) in distances.iter_mut().zip(box_directions(p.all_around)) {
                    if let Some(found) = crossing(
                        field,
                        p.iso,
                        x,
                        at.sample.c,
                        d,
                        p.interior_step * h,
                        GUESS_TOLERANCE,
                    ) && found > 0.0
                    {
                        *t = found;
                    }
                }
                Guess::AllAroundAt { distances }
            }
        };
    }
    let s = at.sample;
    let g = s.gradient.length();
    if g.is_nan() || g <= 1e-6 / h {
        return Guess::Interior;
    }
    let normal = -s.gradient / g;
    let x = field.positions()[i];
    let step = match field.surface() {
        // The thesis's one Newton-Raphson step (eq. 33).
        Surface::Isotropic => (s.c - p.iso) / g, // along the normal
        // The anisotropic field's thin kernels make c peak near a surface
        // particle and fall steeply beyond it, so that a Newton step from
        // the particle overshoots (or, near the peak, calls a surface
        // particle interior): the crossing is bracketed along the normal.
        Surface::Anisotropic(_) => {
            match crossing(
                field,
                p.iso,
                x,
                s.c,
                normal,
                p.interior_step * h,
                GUESS_TOLERANCE,
            ) {
                Some(t) => t,
                None => return Guess::Interior,
            }
        }
    };
    if step.abs() > p.interior_step * h {
        return Guess::Interior;
    }
    Guess::Surface {
        surfel: Surfel {
            position: x + normal * step.clamp(-0.5 * h, 0.5 * h),
            normal,
            radius: p.radius * h,
        },
        split: s.laplacian.abs() * h * h > p.split_laplacian,
    }
}

/// How close to `iso` the initial guess's [`crossing`]s stop: |c − iso| ≤
/// 10⁻³, about 10⁻³ h along the normal where |∇c| h is about 1. The Newton
/// steps that refine a guess take it from there (each squares the error).
/// Stopping at the first such point, not after all six steps, cut the
/// initial guess's evaluations by 14 % at 100k particles and 23 % on the
/// demo's `drop` (`cargo run --release -p surfel-extract --example
/// stage_times -- 100k anisotropic`). The refinement's safeguarded steps,
/// whose crossing can be a surfel's final position, take all six.
const GUESS_TOLERANCE: f32 = 1e-3;

/// Where c crosses `iso` along the line x + t n, |t| ≤ `reach`, on the side
/// c(x) = `c0` says (t > 0 when c0 > iso: outwards), or `None` if c is
/// still on c0's side at `reach`. Regula falsi (Illinois) from the bracket
/// [0, ±reach], until c is within `tolerance` of `iso`: 1 + at most 6
/// evaluations.
fn crossing(
    field: &ColourField,
    iso: f32,
    x: Vec3,
    c0: f32,
    n: Vec3,
    reach: f32,
    tolerance: f32,
) -> Option<f32> {
    let side = if c0 >= iso { 1.0 } else { -1.0 };
    let (mut a, mut fa) = (0.0f32, c0 - iso);
    let mut b = side * reach;
    let mut fb = field.sample(x + b * n).c - iso;
    if fb * fa > 0.0 {
        return None;
    }
    let mut last = 0;
    for _ in 0..6 {
        let t = if fa != fb {
            b - fb * (b - a) / (fb - fa)
        } else {
            0.5 * (a + b)
        };
        let ft = field.sample(x + t * n).c - iso;
        if ft.abs() <= tolerance {
            return Some(t);
        }
        if (ft > 0.0) == (fa > 0.0) {
            (a, fa) = (t, ft);
            if last == -1 {
                fb *= 0.5;
            }
            last = -1;
        } else {
            (b, fb) = (t, ft);
            if last == 1 {
                fa *= 0.5;
            }
            last = 1;
        }
    }
    Some(if fa.abs() < fb.abs() { a } else { b })
}

/// The front-facing surfels of a non-lone guess at particle position `x`,
/// computed as they are read (nothing is copied around for a guess without
/// any).
fn guess_surfels(p: &ExtractParams, x: Vec3, guess: Guess) -> impl Iterator<Item = Surfel> {
    let (split_up, whole, around) = match guess {
        Guess::Surface {
            surfel,
            split: true,
        } => (Some(surfel), None, None),
        Guess::Surface { surfel, .. } => (None, Some(surfel), None),
        Guess::AllAround => (None, None, Some(box_directions(p.all_around))),
        Guess::AllAroundAt { .. } => (None, None, None),
        Guess::Interior | Guess::Lone { .. } | Guess::Droplet { .. } => (None, None, None),
    };
    let droplet = match guess {
        Guess::Droplet { radius } => Some(sphere_surfels(x, radius, DROPLET_SEEDS)),
        _ => None,
    };
    let at = match guess {
        Guess::AllAroundAt { distances } => Some(
            box_directions(p.all_around)
                .iter()
                .zip(distances)
                .filter(|(_, t)| t.is_finite())
                .map(move |(&d, t)| Surfel {
                    position: x + t * d,
                    normal: d,
                    radius: p.radius * p.h,
                }),
        ),
        _ => None,
    };
    let (h, radius) = (p.h, p.radius * p.h);
    split_up
        .into_iter()
        .flat_map(|s| split(&s, Split::TwoByTwo))
        .chain(whole)
        .chain(around.into_iter().flatten().map(move |&d| Surfel {
            position: x + 0.5 * h * d,
            normal: d,
            radius,
        }))
        .chain(droplet.into_iter().flatten())
        .chain(at.into_iter().flatten())
        .filter(move |s| front_facing(p, s))
}

/// A lone particle's iso-sphere, its front-facing surfels into `done`: in
/// the isotropic field the thesis's face and corner directions together,
/// which leave no gap wider than 35.3°; in the anisotropic field a
/// droplet's [`DROPLET_DIRECTIONS`].
fn lone_surfels(p: &ExtractParams, x: Vec3, radius: f32, surface: Surface, done: &mut Vec<Surfel>) {
    let keep = |s: &Surfel| front_facing(p, s);
    match surface {
        Surface::Isotropic => done.extend(
            (box_directions(AllAround::Six).iter())
                .chain(box_directions(AllAround::Eight))
                .map(|&d| Surfel {
                    position: x + radius * d,
                    normal: d,
                    radius: 0.8 * radius,
                })
                .filter(keep),
        ),
        Surface::Anisotropic(_) => {
            done.extend(sphere_surfels(x, radius, DROPLET_DIRECTIONS).filter(keep))
        }
    }
}

/// The extractor's buffers, kept from one frame to the next.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    /// Per particle, its guess.
    guesses: Vec<Guess>,
    /// The surfels an iteration refines, and those the next one will.
    work: Vec<Surfel>,
    next: Vec<Surfel>,
    /// Per surfel of `work`, where its Newton-Raphson step went (`None`:
    /// discarded or culled) and how it splits.
    steps: Vec<Option<(Surfel, Split)>>,
    /// [`par_extend_flat`]'s counts.
    counts: Vec<usize>,
}

/// The surfels of the field's iso-surface into `done` (cleared first), and
/// the extraction's statistics but the field's build time.
pub(crate) fn run(
    field: &ColourField,
    p: &ExtractParams,
    scratch: &mut Scratch,
    done: &mut Vec<Surfel>,
) -> Result<Stats> {
    let Scratch {
        guesses,
        work,
        next,
        steps,
        counts,
    } = scratch;
    done.clear();
    let mut stats = Stats {
        particles: field.len(),
        ..Default::default()
    };
    let start = Instant::now();
    let e0 = field.evaluations();
    // One scan per particle gives its field and its neighbourhood's shape;
    // scheduled in cell order, stored by particle.
    field.grid().par_map_into(
        |i, nb| {
            let at = field.sample_neighbourhood(nb);
            initial_guess(field, p, i, &at)
        },
        guesses,
    );
    let positions = field.positions();
    work.clear();
    par_extend_flat(work, guesses.len(), counts, |i| {
        guess_surfels(p, positions[i], guesses[i])
    });
    for (&g, &x) in guesses.iter().zip(positions) {
        match g {
            Guess::Interior => {}
            Guess::Surface { .. } => stats.surface_particles += 1,
            Guess::AllAround | Guess::AllAroundAt { .. } => stats.all_around += 1,
            Guess::Droplet { .. } => stats.droplets += 1,
            Guess::Lone { radius } => {
                stats.lone += 1;
                lone_surfels(p, x, radius, field.surface(), done);
            }
        }
    }
    stats.initial = work.len() + done.len();
    stats.particle_evaluations = field.evaluations() - e0;
    stats.initial_time = start.elapsed();

    let start = Instant::now();
    let e1 = field.evaluations();
    let max_step = p.discard_step * p.h;
    let covered = p.mode == Mode::Covered;
    let mut fill_time = std::time::Duration::ZERO;
    // Each iteration is one parallel pass over `work` (the Newton-Raphson
    // step, the discard test, culling and the choice of split) into `steps`,
    // then, but in the last, the split into `next`.
    let discarded = AtomicUsize::new(0);
    let step = |s: &Surfel, grid: Split| match newton_step(field, p.iso, s.position, max_step) {
        None => {
            discarded.fetch_add(1, Ordering::Relaxed);
            None
        }
        Some(step) => {
            let new = Surfel {
                position: step.position,
                normal: step.normal,
                radius: s.radius,
            };
            // A 3×3 split's corner children start 0.94 r out in the tangent
            // plane: where the surface curves away from it there by more
            // than a step the refinement accepts, they would start too far
            // off it, and the split is 2×2.
            let grid = match grid {
                Split::ThreeByThree if step.sag(corner_distance(grid, s.radius)) > max_step => {
                    Split::TwoByTwo
                }
                grid => grid,
            };
            front_facing(p, &new).then_some((new, grid))
        }
    };
    for it in 0..p.iterations {
        let last = it + 1 == p.iterations;
        let grid = if it == 0 {
            p.first_split
        } else {
            Split::TwoByTwo
        };
        steps.resize(work.len(), None);
        region::for_each(steps, |k, out| *out = step(&work[k], grid));
        let kept = |k: usize| steps[k].map(|(s, _)| s).into_iter();
        let children = |k: usize| steps[k].into_iter().flat_map(|(s, grid)| split(&s, grid));
        next.clear();
        if covered && it == 0 {
            // Holes are closed once, on the first iteration's surfels: fill
            // surfels (after the others) are split 2×2 and refined like the
            // others, and children inherit the closed surface. With one
            // iteration that is the result, lone spheres included.
            let first = if last { &mut *done } else { &mut *next };
            par_extend_flat(first, steps.len(), counts, kept);
            let t = Instant::now();
            let filled = fill::close_holes(field, p, first)?;
            fill_time += t.elapsed();
            stats.filled += filled;
            if !last {
                // `next` holds the kept surfels then the fill; split them.
                let fill_start = next.len() - filled;
                work.clear();
                par_extend_flat(work, steps.len(), counts, children);
                let fills = &next[fill_start..];
                par_extend_flat(work, fills.len(), counts, |k| {
                    split(&fills[k], Split::TwoByTwo)
                });
            }
        } else if last {
            par_extend_flat(done, steps.len(), counts, kept);
        } else {
            par_extend_flat(next, steps.len(), counts, children);
            std::mem::swap(work, next);
        }
    }
    stats.discarded = discarded.into_inner();
    stats.refine_time = start.elapsed() - fill_time;
    stats.fill_time = fill_time;
    stats.evaluations = field.evaluations() - e1;
    stats.surfels = done.len();
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every point of a split surfel's disc lies on a child's disc, and the
    /// children lie in its plane: a split loses no surface and tilts nothing.
    #[test]
    fn split_children_cover_the_parent_disc() {
        let parent = Surfel {
            position: Vec3::new(0.3, -0.2, 0.5),
            normal: Vec3::new(1.0, 2.0, -0.5).normalize(),
            radius: 0.01,
        };
        let (t1, t2) = tangent_basis(parent.normal);
        for (grid, n, ratio) in [(Split::TwoByTwo, 4, 0.742), (Split::ThreeByThree, 9, 0.495)] {
            let children: Vec<Surfel> = split(&parent, grid).collect();
            assert_eq!(children.len(), n);
            for c in &children {
                assert_eq!(c.normal, parent.normal);
                assert!((c.position - parent.position).dot(parent.normal).abs() < 1e-6);
                assert!(
                    (c.radius / parent.radius - ratio).abs() < 1e-3,
                    "{grid:?}: {}",
                    c.radius
                );
            }
            // Polar samples out to the rim.
            for i in 0..=40 {
                for j in 0..64 {
                    let rho = parent.radius * i as f32 / 40.0;
                    let phi = std::f32::consts::TAU * j as f32 / 64.0;
                    let q = parent.position + rho * (phi.cos() * t1 + phi.sin() * t2);
                    let nearest = (children.iter())
                        .map(|c| (q - c.position).length() / c.radius)
                        .fold(f32::INFINITY, f32::min);
                    assert!(nearest <= 1.0, "{grid:?}: point {q} uncovered ({nearest})");
                }
            }
        }
    }
}
