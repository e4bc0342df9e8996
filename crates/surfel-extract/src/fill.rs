//! Hole closing (beyond the thesis): the thesis's initial guess can miss parts of
//! the surface, and refinement cannot grow into them. After refinement, every
//! surfel probes six points just beyond its rim in its tangent plane; a probe no
//! surfel covers is projected onto the iso-surface by Newton-Raphson steps and,
//! if still uncovered, becomes a new surfel. New surfels probe in the next round,
//! so a hole is closed from its edge inwards. Probes that land on covered surface
//! cost no field evaluation, so a hole-free surface costs only the lookups.

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;

use crate::field::ColourField;
use crate::thesis::{front_facing, newton_step};
use crate::{ExtractParams, Surfel, tangent_basis};

/// Whether `q` lies on the disc of `s`: within `thickness` of its plane and within
/// its radius of its centre in the plane.
pub fn disc_covers(s: &Surfel, q: Vec3, thickness: f32) -> bool {
    let d = q - s.position;
    let along = d.dot(s.normal);
    along.abs() <= thickness && (d - along * s.normal).length_squared() <= s.radius * s.radius
}

/// Surfels hashed by cell for "is this point covered?" queries.
#[derive(Debug, Clone)]
pub struct SurfelIndex {
    inv_cell: f32,
    cells: HashMap<[i32; 3], Vec<u32>>,
    thickness: f32,
}

impl SurfelIndex {
    /// An empty index for discs of radius up to `max_radius` and `thickness`.
    pub fn new(max_radius: f32, thickness: f32) -> Self {
        Self {
            inv_cell: 1.0 / (max_radius + thickness).max(f32::MIN_POSITIVE),
            cells: HashMap::new(),
            thickness,
        }
    }

    fn cell(&self, x: Vec3) -> [i32; 3] {
        (x * self.inv_cell).floor().as_ivec3().to_array()
    }

    /// Adds surfel number `k` centred at `x`.
    pub fn insert(&mut self, k: u32, x: Vec3) {
        self.cells.entry(self.cell(x)).or_default().push(k);
    }

    /// An index over all of `surfels`.
    pub fn build(surfels: &[Surfel], thickness: f32) -> Self {
        let max_radius = surfels.iter().map(|s| s.radius).fold(0.0, f32::max);
        let mut index = Self::new(max_radius, thickness);
        for (k, s) in surfels.iter().enumerate() {
            index.insert(k as u32, s.position);
        }
        index
    }

    /// Whether some surfel of `surfels` (the indexed ones) covers `q`.
    pub fn covered(&self, surfels: &[Surfel], q: Vec3) -> bool {
        if !q.is_finite() {
            return false;
        }
        let c = self.cell(q);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let key = [c[0] + dx, c[1] + dy, c[2] + dz];
                    if let Some(list) = self.cells.get(&key)
                        && list
                            .iter()
                            .any(|&k| disc_covers(&surfels[k as usize], q, self.thickness))
                    {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// Closes holes in `surfels` (see the module docs); returns how many were added.
pub fn close_holes(field: &ColourField, p: &ExtractParams, surfels: &mut Vec<Surfel>) -> usize {
    let thickness = 0.25 * p.h;
    let max_step = p.discard_step * p.h;
    let mut parents = 0..surfels.len();
    let mut added = 0;
    for _ in 0..p.fill_rounds {
        let index = SurfelIndex::build(surfels, thickness);
        let all: &[Surfel] = surfels;
        let candidates: Vec<Surfel> = all[parents.clone()]
            .par_iter()
            .flat_map_iter(|s| {
                let (t1, t2) = tangent_basis(s.normal);
                let index = &index;
                (0..6).filter_map(move |k| {
                    let a = k as f32 * std::f32::consts::FRAC_PI_3;
                    let q = s.position + 1.2 * s.radius * (a.cos() * t1 + a.sin() * t2);
                    if index.covered(all, q) {
                        return None;
                    }
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
                })
            })
            .collect();
        // Keep a candidate only if none accepted before it covers it (sequential,
        // so the result does not depend on the thread count).
        let first_new = surfels.len();
        let mut fresh = SurfelIndex::new(
            candidates.iter().map(|s| s.radius).fold(0.0, f32::max),
            thickness,
        );
        for c in candidates {
            if !fresh.covered(&surfels[first_new..], c.position) {
                fresh.insert((surfels.len() - first_new) as u32, c.position);
                surfels.push(c);
            }
        }
        parents = first_new..surfels.len();
        added += parents.len();
        if parents.is_empty() {
            break;
        }
    }
    added
}
