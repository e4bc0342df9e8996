//! Fixed neighbour lists: each particle's neighbours found once, then reused
//! while the particles move a little (position-based solvers iterate on
//! them within a step, Macklin & Müller 2013).

use rayon::prelude::*;

use super::NeighbourGrid;

/// Particles per parallel task when building lists: a fixed size, so the
/// result does not depend on the number of threads.
const CHUNK: usize = 512;

/// For each particle, the particles within h of it (itself excluded) when the
/// lists were built, in the grid's fixed query order: compressed rows, one
/// per particle.
///
/// ```
/// use sph_core::{NeighbourGrid, NeighbourLists, glam::Vec3};
/// let positions = [Vec3::ZERO, Vec3::new(0.5, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)];
/// let grid = NeighbourGrid::build(&positions, 1.0).unwrap();
/// let lists = NeighbourLists::build(&grid);
/// assert_eq!(lists.of(0), [1]);
/// assert_eq!(lists.of(2), [] as [u32; 0]);
/// assert_eq!(lists.pairs(), 2);
/// ```
#[derive(Debug, Clone, Default)]
pub struct NeighbourLists {
    /// Row `i` is `neighbours[start[i]..start[i + 1]]`.
    start: Vec<u32>,
    neighbours: Vec<u32>,
}

impl NeighbourLists {
    /// The lists of every particle of `grid`.
    pub fn build(grid: &NeighbourGrid) -> Self {
        let mut lists = Self::default();
        lists.rebuild(grid);
        lists
    }

    /// Rebuilds the lists for `grid` in this memory.
    ///
    /// # Panics
    /// If the grid holds 2³² neighbour pairs or more (about 10⁸ particles
    /// at usual neighbour counts); the indices are 32-bit.
    pub fn rebuild(&mut self, grid: &NeighbourGrid) {
        let n = grid.len();
        let chunks: Vec<(Vec<u32>, Vec<u32>)> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let range = c * CHUNK..((c + 1) * CHUNK).min(n);
                let mut counts = Vec::with_capacity(range.len());
                let mut found = Vec::new();
                for i in range {
                    let before = found.len();
                    grid.for_each_neighbour(i, |j, _, _| {
                        if j != i {
                            found.push(j as u32);
                        }
                    });
                    counts.push((found.len() - before) as u32);
                }
                (counts, found)
            })
            .collect();
        self.start.clear();
        self.neighbours.clear();
        self.start.reserve(n + 1);
        self.start.push(0);
        let mut total = 0u64;
        for (counts, found) in &chunks {
            for &c in counts {
                total += u64::from(c);
                let end = u32::try_from(total).expect("fewer than 2³² neighbour pairs");
                self.start.push(end);
            }
            self.neighbours.extend_from_slice(found);
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The neighbours of particle `i`.
    ///
    /// # Panics
    /// If `i >= self.len()`.
    #[inline]
    pub fn of(&self, i: usize) -> &[u32] {
        &self.neighbours[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// Where each row starts in the concatenation of all rows, and, last,
    /// [`NeighbourLists::pairs`]: `of(i)` is rows `row_starts()[i]..row_starts()[i + 1]`.
    /// Per-pair data laid out the same way can then be split by particle.
    pub fn row_starts(&self) -> &[u32] {
        &self.start
    }

    /// Number of (ordered) neighbour pairs: the sum of every list's length.
    pub fn pairs(&self) -> usize {
        self.neighbours.len()
    }
}
