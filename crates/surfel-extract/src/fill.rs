//! Hole closing (beyond the thesis): the thesis's initial guess can miss parts of
//! the surface, and refinement cannot grow into them. Surfels probe six points
//! just beyond their rim in their tangent plane; a probe no surfel covers is
//! projected onto the iso-surface by Newton-Raphson steps and, if still
//! uncovered, becomes a new surfel. New surfels probe in the next round, so a
//! hole is closed from its edge inwards. Probes that land on covered surface cost
//! no field evaluation, so a hole-free surface costs only the lookups: one
//! neighbour query per probing surfel, against a grid over the surfel centres.
//!
//! The extractor runs it once, on the surfels of the first iteration before
//! they split: the surfels it adds are split and refined like the others, and
//! the children inherit the closed surface.

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;
use sph_core::{NeighbourGrid, Result};

use crate::field::ColourField;
use crate::thesis::{front_facing, newton_step};
use crate::{ExtractParams, Surfel, tangent_basis};

/// Probe distance from a surfel's centre, in units of its radius.
const PROBE: f32 = 1.2;
/// Thickness of the coverage test before a probe is projected, in units of
/// the usual thickness.
const LOOSE: f32 = 2.0;
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
    /// An index over all of `surfels` for discs `thickness` thick. Errors only
    /// for non-finite surfel positions.
    pub fn build(surfels: &[Surfel], thickness: f32) -> Result<Self> {
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

    /// The indexed surfels that can cover a probe of surfel `k`, into `out`.
    fn gather(&self, k: usize, out: &mut Vec<u32>) {
        out.clear();
        if let Some(grid) = &self.grid {
            grid.for_each_neighbour(k, |j, _, _| out.push(j as u32));
        }
    }
}

/// The new surfel a probe `q` of `s` seeds, if the surface there is uncovered:
/// the probe projected onto the iso-surface by two Newton-Raphson steps. `near`
/// holds the surfels that can cover `q`.
fn probe(
    field: &ColourField,
    p: &ExtractParams,
    index: &SurfelIndex,
    all: &[Surfel],
    near: &[u32],
    s: &Surfel,
    q: Vec3,
) -> Option<Surfel> {
    // The probe lies in the tangent plane: where the surface curves away it
    // is off the surface, so before spending an evaluation it counts as
    // covered by a disc it lies over within twice the usual thickness.
    let loose = LOOSE * index.thickness;
    if near
        .iter()
        .any(|&j| disc_covers(&all[j as usize], q, loose))
    {
        return None;
    }
    let max_step = p.discard_step * p.h;
    let (q, _) = newton_step(field, p.iso, q, max_step)?;
    if index.covered(all, q) {
        return None;
    }
    let (x, normal) = newton_step(field, p.iso, q, max_step)?;
    let new = Surfel {
        position: x,
        normal,
        radius: s.radius,
    };
    (front_facing(p, &new) && !index.covered(all, x)).then_some(new)
}

/// Closes holes in `surfels` (see the module docs), probing first around all of
/// them, then around each round's new surfels; returns how many were added.
pub fn close_holes(
    field: &ColourField,
    p: &ExtractParams,
    surfels: &mut Vec<Surfel>,
) -> Result<usize> {
    let thickness = 0.25 * p.h;
    let mut probing: Vec<u32> = (0..surfels.len() as u32).collect();
    let mut added = 0;
    for _ in 0..p.fill_rounds {
        if probing.is_empty() {
            break;
        }
        let index = SurfelIndex::build(surfels, thickness)?;
        let all: &[Surfel] = surfels;
        let candidates: Vec<Surfel> = probing
            .par_iter()
            .map_init(Vec::new, |near, &k| {
                let s = &all[k as usize];
                index.gather(k as usize, near);
                let (t1, t2) = tangent_basis(s.normal);
                let mut found = [None; PROBES];
                for (slot, (cos, sin)) in found.iter_mut().zip(RIM) {
                    let q = s.position + PROBE * s.radius * (cos * t1 + sin * t2);
                    *slot = probe(field, p, &index, all, near, s, q);
                }
                found
            })
            .flat_map_iter(|found| found.into_iter().flatten())
            .collect();
        // Keep a candidate only if none accepted before it covers it (sequential,
        // so the result does not depend on the thread count).
        let first_new = surfels.len();
        let mut fresh = Fresh::new(
            candidates.iter().map(|s| s.radius).fold(0.0, f32::max),
            thickness,
        );
        for c in candidates {
            if !fresh.covered(&surfels[first_new..], c.position) {
                fresh.insert((surfels.len() - first_new) as u32, c.position);
                surfels.push(c);
            }
        }
        probing = (first_new as u32..surfels.len() as u32).collect();
        added += probing.len();
    }
    Ok(added)
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
