//! Hole closing (beyond the thesis): the thesis's initial guess can miss parts of
//! the surface, and refinement cannot grow into them. Surfels probe six points
//! just beyond their rim in their tangent plane; a probe no surfel covers is
//! projected onto the iso-surface by Newton-Raphson steps and, if still
//! uncovered, becomes a new surfel. New surfels probe in the next round, so a
//! hole is closed from its edge inwards. Probes that land on covered surface cost
//! no field evaluation, so a hole-free surface costs only the lookups: one
//! neighbour query per probing surfel against a grid over the surfel centres
//! (and one against the few surfels added in earlier rounds).
//!
//! The extractor runs it once, on the surfels of the first iteration before
//! they split: the surfels it adds are split and refined like the others, and
//! the children inherit the closed surface.

use std::collections::HashMap;

use glam::Vec3;
use std::cell::RefCell;

use sph_core::region;
use sph_core::{Error, NeighbourGrid, Result};

use crate::field::{ColourField, Surface};
use crate::thesis::{front_facing, newton_step};
use crate::{ExtractParams, Surfel, tangent_basis};

/// How far from a disc's plane (× h) a point counts as on the disc when
/// hole closing asks whether one of its probes, projected onto the
/// iso-surface, is covered, on `surface` (before the projection, [`LOOSE`]
/// times that).
///
/// On the thesis's field, a quarter of h. The anisotropic field's thin
/// kernels make sharper saddles and crevices in a splash, where discs of a
/// nearby, differently turned part lie within a quarter of h of a probe
/// that no disc of its own part covers: at that thickness the splashing
/// dam-break frame of `tests/reference_render.rs`
/// (`gpu_splats_close_the_anisotropic_surface`) kept 1.3–1.5 % of its
/// surface pixels uncovered, at 0.075 h (about the sag of a final disc's
/// rim on a surface curved at radius h) 0.02 %, for 8 % more surfels. On
/// the thesis's field that value costs issue 4's efficiency (0.63 surfels
/// per evaluation against 0.77, where its test asks for 0.75) and is not
/// used (docs/benchmark-notes.md, "Holes in a splash, closed").
pub fn thickness(surface: Surface) -> f32 {
    match surface {
        Surface::Isotropic => 0.25,
        Surface::Anisotropic(_) => 0.075,
    }
}
/// Probe distance from a surfel's centre, in units of its radius.
const PROBE: f32 = 1.2;
/// Thickness of the coverage test before a probe is projected, in units of
/// the usual thickness: the probe lies in its surfel's tangent plane, off a
/// surface that curves away.
pub const LOOSE: f32 = 2.0;
/// Probes per surfel, evenly spaced around its rim.
const PROBES: usize = 6;
/// (cos, sin) of the probe directions, 60° apart.
const RIM: [(f32, f32); PROBES] = {
    const S: f32 = 0.866_025_4; // √3/2
    [
        (1.0, 0.0),
        (0.5, S),
        (-0.5, S),
        (-1.0, 0.0),
        (-0.5, -S),
        (0.5, -S),
    ]
};

/// Whether `q` lies on the disc of `s`: within `thickness` of its plane and within
/// its radius of its centre in the plane.
#[inline]
pub fn disc_covers(s: &Surfel, q: Vec3, thickness: f32) -> bool {
    let d = q - s.position;
    let along = d.dot(s.normal);
    along.abs() <= thickness && (d - along * s.normal).length_squared() <= s.radius * s.radius
}

/// Surfels in a neighbour grid over their centres, for "is this point covered?"
/// queries and for gathering the surfels around a probing surfel.
#[derive(Debug)]
pub struct SurfelIndex {
    /// Over the surfel centres; its h reaches every disc that can cover a probe
    /// of a surfel from that surfel's centre.
    grid: Option<NeighbourGrid>,
    thickness: f32,
}

impl SurfelIndex {
    /// An index over all of `surfels` for discs `thickness` thick. Errors for
    /// a radius or thickness that is not finite and ≥ 0, non-finite surfel
    /// positions, and positions too far out for the grid's cells.
    pub fn build(surfels: &[Surfel], thickness: f32) -> Result<Self> {
        let bad = |v: f32| !(v.is_finite() && v >= 0.0);
        if let Some(s) = surfels.iter().find(|s| bad(s.radius)) {
            return Err(Error::InvalidParameter {
                name: "surfel radius",
                value: s.radius.to_string(),
                reason: "must be finite and >= 0",
            });
        }
        if bad(thickness) {
            return Err(Error::InvalidParameter {
                name: "thickness",
                value: thickness.to_string(),
                reason: "must be finite and >= 0",
            });
        }
        let max_radius = surfels.iter().map(|s| s.radius).fold(0.0, f32::max);
        // A disc covering a probe of surfel s (loosely) has its centre within
        // √(r_max² + (LOOSE thickness)²) of the probe, which lies PROBE r_s
        // from s.
        let reach = PROBE * max_radius + max_radius.hypot(LOOSE * thickness);
        let grid = if surfels.is_empty() || reach.is_nan() || reach <= 0.0 {
            None
        } else {
            let centres: Vec<Vec3> = surfels.iter().map(|s| s.position).collect();
            Some(NeighbourGrid::build(&centres, reach)?)
        };
        Ok(Self { grid, thickness })
    }

    /// Whether some surfel of `surfels` (the indexed ones) covers `q`.
    ///
    /// # Panics
    /// If `surfels` is shorter than the slice the index was built over.
    pub fn covered(&self, surfels: &[Surfel], q: Vec3) -> bool {
        let Some(grid) = &self.grid else {
            return false;
        };
        let mut hit = false;
        grid.for_each_neighbour_of_point(q, |k, _, _| {
            hit = hit || disc_covers(&surfels[k], q, self.thickness);
        });
        hit
    }

    /// Appends to `out` the indexed surfels of `surfels` that can cover a
    /// probe of a surfel at `x` no larger than the largest indexed one.
    fn gather(&self, surfels: &[Surfel], x: Vec3, out: &mut Discs) {
        if let Some(grid) = &self.grid {
            grid.for_each_neighbour_of_point(x, |j, _, _| out.push(&surfels[j]));
        }
    }
}

/// The surfels during hole closing: those it started with, indexed once, and
/// those it added, indexed again each round (few, so rounds after the first
/// cost little).
struct Parts<'a> {
    old: (&'a SurfelIndex, &'a [Surfel]),
    new: (SurfelIndex, &'a [Surfel]),
}

impl Parts<'_> {
    /// The surfels that can cover a probe of a surfel at `x`, into `out`.
    fn gather(&self, x: Vec3, out: &mut Discs) {
        out.clear();
        self.old.0.gather(self.old.1, x, out);
        self.new.0.gather(self.new.1, x, out);
    }

    /// Whether a surfel covers `q`.
    fn covered(&self, q: Vec3) -> bool {
        self.old.0.covered(self.old.1, q) || self.new.0.covered(self.new.1, q)
    }
}

/// Discs as structure of arrays, so that testing a point against all of them
/// is one branch-free loop the compiler vectorises.
#[derive(Debug)]
struct Discs {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    nx: Vec<f32>,
    ny: Vec<f32>,
    nz: Vec<f32>,
    r2: Vec<f32>,
}

impl Discs {
    /// Room for a typical neighbourhood: rayon calls `map_init`'s init once per
    /// piece of work it splits off, so growing from empty would repeat often.
    fn new() -> Self {
        let v = || Vec::with_capacity(128);
        Self {
            x: v(),
            y: v(),
            z: v(),
            nx: v(),
            ny: v(),
            nz: v(),
            r2: v(),
        }
    }

    fn clear(&mut self) {
        for v in [
            &mut self.x,
            &mut self.y,
            &mut self.z,
            &mut self.nx,
            &mut self.ny,
            &mut self.nz,
            &mut self.r2,
        ] {
            v.clear();
        }
    }

    fn push(&mut self, s: &Surfel) {
        self.x.push(s.position.x);
        self.y.push(s.position.y);
        self.z.push(s.position.z);
        self.nx.push(s.normal.x);
        self.ny.push(s.normal.y);
        self.nz.push(s.normal.z);
        self.r2.push(s.radius * s.radius);
    }

    /// Whether one of the discs covers `q` ([`disc_covers`], the same float
    /// operations in the same order).
    fn cover(&self, q: Vec3, thickness: f32) -> bool {
        let n = self.x.len();
        let (x, y, z) = (&self.x[..n], &self.y[..n], &self.z[..n]);
        let (nx, ny, nz, r2) = (&self.nx[..n], &self.ny[..n], &self.nz[..n], &self.r2[..n]);
        let mut hit = false;
        for i in 0..n {
            let (dx, dy, dz) = (q.x - x[i], q.y - y[i], q.z - z[i]);
            let along = dx * nx[i] + dy * ny[i] + dz * nz[i];
            let (px, py, pz) = (dx - along * nx[i], dy - along * ny[i], dz - along * nz[i]);
            hit |= (along.abs() <= thickness) & (px * px + py * py + pz * pz <= r2[i]);
        }
        hit
    }
}

/// The new surfel a probe `q` of `s` seeds, if the surface there is uncovered:
/// the probe projected onto the iso-surface by two Newton-Raphson steps. `near`
/// holds the surfels that can cover `q`.
fn probe(
    field: &ColourField,
    p: &ExtractParams,
    parts: &Parts<'_>,
    near: &Discs,
    s: &Surfel,
    q: Vec3,
) -> Option<Surfel> {
    // The probe lies in the tangent plane: where the surface curves away it
    // is off the surface, so before spending an evaluation it counts as
    // covered by a disc it lies over within twice the usual thickness.
    if near.cover(q, LOOSE * parts.old.0.thickness) {
        return None;
    }
    let max_step = p.discard_step * p.h;
    let q = newton_step(field, p.iso, q, max_step)?.position;
    if parts.covered(q) {
        return None;
    }
    let step = newton_step(field, p.iso, q, max_step)?;
    let new = Surfel {
        position: step.position,
        normal: step.normal,
        radius: s.radius,
    };
    (front_facing(p, &new) && !parts.covered(new.position)).then_some(new)
}

/// Closes holes in `surfels` (see the module docs), probing first around all of
/// them, then around each round's new surfels; returns how many were added.
pub fn close_holes(
    field: &ColourField,
    p: &ExtractParams,
    surfels: &mut Vec<Surfel>,
) -> Result<usize> {
    let thickness = thickness(field.surface()) * p.h;
    let first_new = surfels.len();
    let old_index = SurfelIndex::build(surfels, thickness)?;
    let mut probing: Vec<u32> = (0..first_new as u32).collect();
    for _ in 0..p.fill_rounds {
        if probing.is_empty() {
            break;
        }
        let all: &[Surfel] = surfels;
        let (old, new) = all.split_at(first_new);
        let parts = Parts {
            old: (&old_index, old),
            new: (SurfelIndex::build(new, thickness)?, new),
        };
        thread_local! {
            /// A probing surfel's neighbours, gathered once for its probes.
            static NEAR: RefCell<Discs> = RefCell::new(Discs::new());
        }
        let mut found = vec![[None; PROBES]; probing.len()];
        region::for_each(&mut found, |k, found| {
            let s = &all[probing[k] as usize];
            NEAR.with_borrow_mut(|near| {
                parts.gather(s.position, near);
                let (t1, t2) = tangent_basis(s.normal);
                for (slot, (cos, sin)) in found.iter_mut().zip(RIM) {
                    let q = s.position + PROBE * s.radius * (cos * t1 + sin * t2);
                    *slot = probe(field, p, &parts, near, s, q);
                }
            });
        });
        let candidates: Vec<Surfel> = (found.into_iter())
            .flat_map(|found| found.into_iter().flatten())
            .collect();
        // Keep a candidate only if none accepted before it covers it (sequential,
        // so the result does not depend on the thread count).
        let round_start = surfels.len();
        let mut fresh = Fresh::new(
            candidates.iter().map(|s| s.radius).fold(0.0, f32::max),
            thickness,
        );
        for c in candidates {
            if !fresh.covered(&surfels[round_start..], c.position) {
                fresh.insert((surfels.len() - round_start) as u32, c.position);
                surfels.push(c);
            }
        }
        probing = (round_start as u32..surfels.len() as u32).collect();
    }
    Ok(surfels.len() - first_new)
}

/// The surfels accepted in one round, hashed by cell as they arrive.
struct Fresh {
    inv_cell: f32,
    cells: HashMap<[i32; 3], Vec<u32>>,
    thickness: f32,
}

impl Fresh {
    fn new(max_radius: f32, thickness: f32) -> Self {
        Self {
            inv_cell: 1.0 / (max_radius + thickness).max(f32::MIN_POSITIVE),
            cells: HashMap::new(),
            thickness,
        }
    }

    fn cell(&self, x: Vec3) -> [i32; 3] {
        (x * self.inv_cell).floor().as_ivec3().to_array()
    }

    fn insert(&mut self, k: u32, x: Vec3) {
        self.cells.entry(self.cell(x)).or_default().push(k);
    }

    fn covered(&self, surfels: &[Surfel], q: Vec3) -> bool {
        let c = self.cell(q);
        (-1..=1).any(|dz| {
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    self.cells
                        .get(&[c[0] + dx, c[1] + dy, c[2] + dz])
                        .is_some_and(|list| {
                            list.iter()
                                .any(|&k| disc_covers(&surfels[k as usize], q, self.thickness))
                        })
                })
            })
        })
    }
}
