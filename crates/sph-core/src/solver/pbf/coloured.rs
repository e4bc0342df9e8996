//! [`PbfSolve::GaussSeidel`](super::PbfSolve::GaussSeidel): the density
//! constraints solved one after another, in parallel where they share no
//! particle.
//!
//! Constraint i reads and moves particle i and its neighbours (those within
//! h on the predicted positions, [`NeighbourLists`]), so two constraints
//! more than 2h apart touch disjoint particles. The particles are cut into
//! columns along gravity, 2h wide (a little over) across it, and the
//! columns coloured by the parities of their two coordinates: two columns
//! of one colour are a column apart, so their particles are more than 2h
//! apart, and a colour's columns relax in parallel, each on one thread.
//! A column goes from the bottom up, in blocks 2h high, each block's
//! particles in index order, so that one sweep carries the support of the
//! floor up a whole column, as a weight must be carried. A sweep runs the
//! four colours in turn; odd sweeps run them, and each column, backwards
//! (a symmetric Gauss–Seidel). What a column does depends only on the
//! positions the colours before it left, never on the threads: results are
//! bitwise the same for any number.
//!
//! The argument needs lists of the fluid's h on the positions the sweeps
//! start from, which a custom program need not give: [`check_lists`]
//! checks every pair first, and refuses other lists.

use std::marker::PhantomData;
use std::ops::Range;

use glam::Vec3;

use super::Model;
use crate::NeighbourLists;
use crate::error::{Error, Result};
use crate::simd::{F32x8, LaneFn, Lanes};
use crate::solver::lane_map::{LaneMap, par_map};
use crate::solver::lanes::{DensitySums, LANES, Near};

/// Block edge over h: a little over 2, so that f32 rounding in the lists'
/// distances cannot make a particle within h of two columns of one colour.
const BLOCK_OVER_H: f64 = 2.0 * (1.0 + 1e-4);

/// The particles grouped into blocks, the blocks into columns along
/// gravity and the columns by colour, rebuilt each substep from the
/// predicted positions.
#[derive(Debug, Clone, Default)]
pub(super) struct Colouring {
    /// Particle indices, column after column; within a column, block
    /// after block from the bottom up, and within a block ascending.
    order: Vec<u32>,
    /// Column t's particles are `order[columns[t]..columns[t + 1]]`.
    columns: Vec<u32>,
    /// Colour c's columns are `colours[c]..colours[c + 1]`.
    colours: [usize; 5],
    /// Scratch: each particle's block coordinates, the up axis first.
    cells: Vec<[i32; 3]>,
    /// Scratch: particles per block of the dense box, then its first place.
    counts: Vec<u32>,
}

/// A column's colour: the parities of its two coordinates across gravity.
fn colour(cell: [i32; 3]) -> usize {
    ((cell[1] & 1) | (cell[2] & 1) << 1) as usize
}

impl Colouring {
    /// Groups the particles at `rows` (x, y, z, m) into blocks of edge
    /// [`BLOCK_OVER_H`] h, stacked into columns along the axis of
    /// `gravity`'s largest component (y without gravity), each column's
    /// blocks from the bottom up. Every position must be finite (the grid's
    /// build, before this, refuses others).
    pub(super) fn build(&mut self, rows: &[[f32; 4]], h: f32, gravity: Vec3) {
        let n = rows.len();
        let inv = 1.0 / (BLOCK_OVER_H * f64::from(h));
        let g = gravity.abs();
        let up = if g.x > g.y && g.x >= g.z {
            0
        } else if g.z > g.y && g.z > g.x {
            2
        } else {
            1
        };
        // Towards the sky: against gravity along the up axis.
        let sign = if gravity[up] > 0.0 { -1.0 } else { 1.0 };
        let axes = [up, (up + 1) % 3, (up + 2) % 3];
        self.cells.clear();
        let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
        for row in rows {
            let cell = [0, 1, 2].map(|k| {
                let x = f64::from(row[axes[k]]) * if k == 0 { sign } else { 1.0 };
                (x * inv).floor() as i32
            });
            for a in 0..3 {
                lo[a] = lo[a].min(cell[a]);
                hi[a] = hi[a].max(cell[a]);
            }
            self.cells.push(cell);
        }
        self.order.clear();
        self.columns.clear();
        self.colours = [0; 5];
        if n == 0 {
            return;
        }
        let dims = [0, 1, 2].map(|a| (i64::from(hi[a]) - i64::from(lo[a]) + 1) as u64);
        let boxed = dims[0].saturating_mul(dims[1]).saturating_mul(dims[2]);
        if boxed <= 8 * n as u64 + 4096 {
            self.dense(lo, dims);
        } else {
            self.sparse();
        }
    }

    /// A counting sort over the blocks of the particles' bounding box: for
    /// a fluid, whose blocks fill their box.
    fn dense(&mut self, lo: [i32; 3], dims: [u64; 3]) {
        // Box order: up fastest, so that a column's blocks follow each
        // other from the bottom up.
        let at = |c: &[i32; 3]| {
            let d = [0, 1, 2].map(|a| (c[a] - lo[a]) as u64);
            (d[0] + dims[0] * (d[1] + dims[1] * d[2])) as usize
        };
        self.counts.clear();
        self.counts
            .resize((dims[0] * dims[1] * dims[2]) as usize, 0);
        for c in &self.cells {
            self.counts[at(c)] += 1;
        }
        // The occupied blocks, colour by colour, each in box order, and
        // whether each starts a column.
        let mut by_colour: [Vec<(u32, bool)>; 4] = Default::default();
        let mut last = [None; 4];
        for (b, &count) in self.counts.iter().enumerate() {
            if count > 0 {
                let b64 = b as u64;
                let d = [
                    b64 % dims[0],
                    b64 / dims[0] % dims[1],
                    b64 / (dims[0] * dims[1]),
                ];
                let cell = [0, 1, 2].map(|a| lo[a] + d[a] as i32);
                let c = colour(cell);
                let column = Some([cell[1], cell[2]]);
                by_colour[c].push((b as u32, last[c] != column));
                last[c] = column;
            }
        }
        // Each block's first place in `order`, kept in `counts` while the
        // particles are dealt out in index order; each column's, in
        // `columns`.
        let mut start = 0;
        for (c, blocks) in by_colour.iter().enumerate() {
            self.colours[c] = self.columns.len();
            for &(b, new_column) in blocks {
                if new_column {
                    self.columns.push(start);
                }
                let count = self.counts[b as usize];
                self.counts[b as usize] = start;
                start += count;
            }
        }
        self.colours[4] = self.columns.len();
        self.columns.push(start);
        self.order.resize(self.cells.len(), 0);
        for (i, c) in self.cells.iter().enumerate() {
            let slot = &mut self.counts[at(c)];
            self.order[*slot as usize] = i as u32;
            *slot += 1;
        }
    }

    /// A sort by (colour, column, height, index): for particles spread over
    /// a box their blocks would not fill (spray far apart).
    fn sparse(&mut self) {
        let mut keys: Vec<(usize, [i32; 3], u32)> = (self.cells.iter())
            .enumerate()
            .map(|(i, &c)| (colour(c), [c[2], c[1], c[0]], i as u32))
            .collect();
        keys.sort_unstable();
        let mut before: Option<(usize, [i32; 3])> = None;
        for (k, &(c, cell, i)) in keys.iter().enumerate() {
            // A new column where the colour or the coordinates across
            // gravity change.
            if before.is_none_or(|(bc, bcell)| (bc, &bcell[..2]) != (c, &cell[..2])) {
                for later in before.map_or(0, |(bc, _)| bc + 1)..=c {
                    self.colours[later] = self.columns.len();
                }
                self.columns.push(k as u32);
            }
            before = Some((c, cell));
            self.order.push(i);
        }
        for later in before.map_or(0, |(c, _)| c + 1)..=4 {
            self.colours[later] = self.columns.len();
        }
        self.columns.push(keys.len() as u32);
    }

    /// The number of columns.
    pub(super) fn columns(&self) -> usize {
        self.colours[4]
    }

    /// The columns of colour `c`.
    pub(super) fn colour(&self, c: usize) -> Range<usize> {
        self.colours[c]..self.colours[c + 1]
    }

    /// Column `t`'s particles, block after block from the bottom up.
    pub(super) fn particles(&self, t: usize) -> &[u32] {
        &self.order[self.columns[t] as usize..self.columns[t + 1] as usize]
    }

    /// The most columns any colour has.
    pub(super) fn widest(&self) -> usize {
        (0..4).map(|c| self.colour(c).len()).max().unwrap_or(0)
    }
}

/// Memory that the columns of one colour write in parallel, each at the
/// particles its colour gives it alone ([`Colouring`]): element by element,
/// never as a slice, so that no thread holds a reference over elements
/// another writes.
#[derive(Clone, Copy)]
pub(super) struct Shared<'a, T> {
    ptr: *mut T,
    len: usize,
    borrowed: PhantomData<&'a mut [T]>,
}

// SAFETY: `Shared` hands out its elements only through its unsafe methods,
// whose callers keep different threads on different elements.
unsafe impl<T: Send> Send for Shared<'_, T> {}
unsafe impl<T: Send> Sync for Shared<'_, T> {}

impl<'a, T: Copy> Shared<'a, T> {
    pub(super) fn new(values: &'a mut [T]) -> Self {
        Self {
            ptr: values.as_mut_ptr(),
            len: values.len(),
            borrowed: PhantomData,
        }
    }

    /// Element `i`.
    ///
    /// # Safety
    /// No other thread writes element `i` meanwhile.
    #[inline(always)]
    pub(super) unsafe fn get(&self, i: usize) -> T {
        assert!(i < self.len);
        unsafe { self.ptr.add(i).read() }
    }

    /// Sets element `i`.
    ///
    /// # Safety
    /// No other thread reads or writes element `i` meanwhile.
    #[inline(always)]
    pub(super) unsafe fn set(&self, i: usize, value: T) {
        assert!(i < self.len);
        unsafe { self.ptr.add(i).write(value) }
    }
}

/// The farthest neighbour's |r|² of each particle: what
/// [`check_lists`] compares with h².
struct Farthest<'a> {
    rows: &'a [[f32; 4]],
    lists: &'a NeighbourLists,
}

impl LaneMap for Farthest<'_> {
    type Out = f32;
    #[inline(always)]
    fn particle<S: F32x8>(&self, i: usize) -> f32 {
        let mut far = S::splat(0.0);
        for (_, slots, count) in self.lists.lanes(i) {
            let c = Near::<S>::gather(self.rows[i], self.rows, slots, count);
            far = far.max(c.r2() * S::first(count));
        }
        far.to_array().into_iter().fold(0.0, f32::max)
    }
}

/// Checks that every pair of `lists` is within h (to a thousandth) at
/// `rows`, as the colouring's proof that a colour's columns share no
/// particle needs: lists found for another radius, or before the
/// particles moved, would let two threads write one particle.
///
/// # Errors
/// [`Error::Pipeline`] naming the density station.
pub(super) fn check_lists(
    rows: &[[f32; 4]],
    lists: &NeighbourLists,
    h: f32,
    farthest: &mut Vec<f32>,
) -> Result<()> {
    par_map(&Farthest { rows, lists }, rows.len(), farthest);
    let far = farthest.iter().copied().fold(0.0, f32::max);
    if far <= h * h * (1.0 + 1e-3) {
        return Ok(());
    }
    Err(Error::Pipeline {
        processor: "density",
        reason: "solve = \"gauss-seidel\" needs the neighbour lists of this fluid's h, found on \
                 the positions it starts from: put `grid` and `neighbours` (of the fluid's h) \
                 right before it",
    })
}

/// A chunk's own lanes, for gathers from its copied rows.
const LOCAL: [u32; LANES] = [0, 1, 2, 3, 4, 5, 6, 7];

/// Chunks of neighbours whose kernel gradients a constraint keeps between
/// its density sum and its pushes: 64 neighbours, about twice a particle's
/// at h = 2 spacings.
const KEPT: usize = 8;

/// What a column's relaxation reads and writes.
pub(super) struct Sweep<'a> {
    pub(super) model: &'a Model,
    pub(super) lists: &'a NeighbourLists,
    pub(super) dt: f32,
    /// Whether the solve is warm-started ([`PbfParams::warm_start`](super::PbfParams::warm_start)): each
    /// constraint's λ then accumulates from the warm share in `pressures`
    /// and is clamped as a sum, where without it each sweep's λ_i is
    /// clamped on its own and the first sweep starts the pressures afresh.
    pub(super) warm: bool,
    /// Each particle's density target over ρ0
    /// ([`PbfParams::surface_target`](super::PbfParams::surface_target));
    /// empty for ρ0 everywhere.
    pub(super) targets: &'a [f32],
    /// (x, m) per particle, moved in place.
    pub(super) rows: Shared<'a, [f32; 4]>,
    pub(super) velocities: Shared<'a, Vec3>,
    pub(super) pressures: Shared<'a, f32>,
    /// Each particle's density when its constraint was last taken.
    pub(super) densities: Shared<'a, f32>,
}

/// One column of one sweep, for [`Lanes::run`].
struct Column<'s, 'a> {
    sweep: &'s Sweep<'a>,
    particles: &'s [u32],
    /// The sweep's index: the first starts the pressures afresh (or from
    /// the warm start's share), odd ones run backwards.
    k: usize,
}

impl LaneFn for Column<'_, '_> {
    /// The column's largest density.
    type Out = f32;
    #[inline(always)]
    fn call<S: F32x8>(self) -> f32 {
        // Loops, not a closure: see `LaneFn`.
        let (sweep, k, mut densest) = (self.sweep, self.k, 0.0f32);
        if k % 2 == 0 {
            for &i in self.particles {
                densest = densest.max(sweep.relax::<S>(i as usize, k));
            }
        } else {
            for &i in self.particles.iter().rev() {
                densest = densest.max(sweep.relax::<S>(i as usize, k));
            }
        }
        densest
    }
}

impl Sweep<'_> {
    /// Relaxes column `t` of `colouring` in sweep `k` with `lanes`;
    /// returns its largest density.
    ///
    /// # Safety
    /// No thread touches the particles of `t` or their neighbours
    /// meanwhile: the other columns running are of `t`'s colour.
    pub(super) unsafe fn column(
        &self,
        colouring: &Colouring,
        t: usize,
        k: usize,
        lanes: Lanes,
    ) -> f32 {
        lanes.run(Column {
            sweep: self,
            particles: colouring.particles(t),
            k,
        })
    }

    /// Particle i's constraint in sweep `k`: λ_i from the current
    /// positions of i and its neighbours, then i moved by
    /// λ_i (∇_i(ρ_wall/ρ0) + Σ_j G_ij) and each neighbour j by
    /// −λ_i (m_i/ρ0) ∇W_ij (with G_ij = (m_j/ρ0) ∇W_ij): the terms of
    /// Jacobi's Δp_i and Δp_j that constraint i gives, so that the masses'
    /// momentum Σ m Δx is the walls' push alone. Each move is projected out
    /// of the walls and adds its motion over Δt to the velocity. Returns ρ_i.
    #[inline(always)]
    fn relax<S: F32x8>(&self, i: usize, k: usize) -> f32 {
        let m = self.model;
        // SAFETY (the reads and writes below): particle i and its neighbours
        // are the caller's alone (`Sweep::column`, `check_lists`); a
        // chunk's lanes past i's own neighbours (`NeighbourLists::lanes`)
        // are not read.
        let xi = unsafe { self.rows.get(i) };
        let (rho_wall, wall) = m.walls_at(Vec3::new(xi[0], xi[1], xi[2]));
        let inv_rho0 = S::splat(m.inv_rho0);
        // The first chunks' ∇W_ij, kept for the pushes; longer lists
        // gather the rest again.
        let mut kept = [[S::splat(0.0); 3]; KEPT];
        let mut sums = DensitySums::new();
        for (q, (_, slots, count)) in self.lists.lanes(i).enumerate() {
            let near = self.near(slots, count);
            let c = Near::<S>::gather(xi, &near, &LOCAL, count);
            let (w, s) = m.lanes.eval(c.r2());
            sums.add(&c, w, s, inv_rho0);
            if q < KEPT {
                kept[q] = [c.d[0] * s, c.d[1] * s, c.d[2] * s];
            }
        }
        let (rho_sum, grad_sum, squares) = sums.finish();
        let rho = rho_wall + xi[3] * m.w0 + rho_sum;
        let grad_i = wall + grad_sum;
        let target = self.targets.get(i).copied().unwrap_or(1.0);
        let error = rho * m.inv_rho0 - target;
        let denominator = grad_i.length_squared() + squares + m.epsilon;
        let omega = m.pbf.over_relaxation;
        // The pressure the solve has applied so far, p = −ρ0 λ/Δt².
        // SAFETY: as above.
        let before = match (self.warm, k) {
            (false, 0) => 0.0,
            _ => unsafe { self.pressures.get(i) },
        };
        let (lambda, pressure) = if self.warm {
            // Clamped as a sum: the pushes so far may be taken back, no
            // further than none. The pressure is the sum's, exactly 0
            // where all is taken back.
            let so_far = -before * self.dt * self.dt * m.inv_rho0;
            let total = (so_far - omega * error / denominator).min(0.0);
            let pressure = -m.params.rest_density * total / (self.dt * self.dt);
            (total - so_far, pressure)
        } else {
            let lambda = -omega * error.max(0.0) / denominator;
            let applied = -m.params.rest_density * lambda / (self.dt * self.dt);
            (lambda, before + applied)
        };
        unsafe {
            self.densities.set(i, rho);
            self.pressures.set(i, pressure);
        }
        if lambda == 0.0 {
            return rho;
        }
        // The neighbours' pushes, −λ_i (m_i/ρ0) ∇W_ij.
        let f = S::splat(-lambda * xi[3] * m.inv_rho0);
        for (q, (_, slots, count)) in self.lists.lanes(i).enumerate() {
            let grad = if q < KEPT {
                kept[q]
            } else {
                let near = self.near(slots, count);
                let c = Near::<S>::gather(xi, &near, &LOCAL, count);
                let (_, s) = m.lanes.eval(c.r2());
                [c.d[0] * s, c.d[1] * s, c.d[2] * s]
            };
            let push = [
                (grad[0] * f).to_array(),
                (grad[1] * f).to_array(),
                (grad[2] * f).to_array(),
            ];
            for (lane, &j) in slots[..count].iter().enumerate() {
                let dx = Vec3::new(push[0][lane], push[1][lane], push[2][lane]);
                self.shift(j as usize, dx);
            }
        }
        self.shift(i, lambda * grad_i);
        rho
    }

    /// The rows of a chunk's first `count` neighbours, copied out one by
    /// one (see [`Shared`]); the lanes past them stay empty (no mass).
    #[inline(always)]
    fn near(&self, slots: &[u32; LANES], count: usize) -> [[f32; 4]; LANES] {
        let mut near = [[0.0; 4]; LANES];
        for (row, &j) in near.iter_mut().zip(&slots[..count]) {
            // SAFETY: as in `relax`.
            *row = unsafe { self.rows.get(j as usize) };
        }
        near
    }

    /// Moves particle `i` by `dx` and out of the walls, and its velocity
    /// by that motion over Δt.
    #[inline(always)]
    fn shift(&self, i: usize, dx: Vec3) {
        // SAFETY: as in `relax`.
        let row = unsafe { self.rows.get(i) };
        let free = Vec3::new(row[0], row[1], row[2]) + dx;
        let mut x = free;
        self.model.walls.boundary().project(&mut x);
        unsafe {
            self.rows.set(i, [x.x, x.y, x.z, row[3]]);
            let v = self.velocities.get(i);
            self.velocities.set(i, v + (dx + (x - free)) / self.dt);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Positions of a jittered block (the lanes' test block) stretched
    /// over a few columns, and the same with one particle far away.
    fn spread() -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let (x, m, _) = crate::solver::lanes::jittered_block();
        let rows: Vec<[f32; 4]> = (x.iter().zip(&m))
            .map(|(x, &m)| [3.0 * x.x, x.y, 2.0 * x.z, m])
            .collect();
        let mut far = rows.clone();
        far[17] = [1e3, -2e3, 5e2, m[17]];
        (rows, far)
    }

    /// Every particle in exactly one column; two particles in different
    /// columns of one colour more than 2h apart; each column's blocks from
    /// the bottom up, their particles in index order; the dense counting
    /// sort and the sparse sort (a particle far away) the same grouping.
    #[test]
    fn columns_of_a_colour_are_over_2h_apart() {
        let h = 0.04;
        let (rows, far) = spread();
        for (rows, gravity) in [
            (&rows, Vec3::new(0.0, -9.81, 0.0)),
            (&far, Vec3::new(0.0, -9.81, 0.0)),
            (&rows, Vec3::new(3.0, 0.0, 0.0)),
            (&rows, Vec3::ZERO),
        ] {
            let mut c = Colouring::default();
            c.build(rows, h, gravity);
            let mut seen = vec![0; rows.len()];
            let mut column_of = vec![usize::MAX; rows.len()];
            for t in 0..c.columns() {
                for &i in c.particles(t) {
                    seen[i as usize] += 1;
                    column_of[i as usize] = t;
                }
            }
            assert!(seen.iter().all(|&s| s == 1), "each particle once");
            let up = if gravity.x != 0.0 { 0 } else { 1 };
            let sign = if gravity[up] > 0.0 { -1.0 } else { 1.0 };
            let inv = 1.0 / (BLOCK_OVER_H * f64::from(h));
            for t in 0..c.columns() {
                let heights: Vec<i32> = (c.particles(t).iter())
                    .map(|&i| (f64::from(rows[i as usize][up]) * sign * inv).floor() as i32)
                    .collect();
                assert!(heights.is_sorted(), "column {t} goes up: {heights:?}");
            }
            for colour in 0..4 {
                let members: Vec<usize> = (c.colour(colour))
                    .flat_map(|t| c.particles(t).iter().map(|&i| i as usize))
                    .collect();
                for &i in &members {
                    for &j in &members {
                        if column_of[i] != column_of[j] {
                            let d = (0..3)
                                .map(|a| (rows[i][a] - rows[j][a]).powi(2))
                                .sum::<f32>();
                            assert!(d.sqrt() > 2.0 * h, "{i} and {j} {} apart", d.sqrt());
                        }
                    }
                }
            }
        }
        // The far particle takes the sparse path; without it, the dense
        // path groups the others as the sparse one does.
        let mut dense = Colouring::default();
        dense.build(&rows, h, Vec3::new(0.0, -9.81, 0.0));
        let mut sparse = dense.clone();
        sparse.order.clear();
        sparse.columns.clear();
        sparse.colours = [usize::MAX; 5];
        sparse.sparse();
        assert_eq!(dense.order, sparse.order);
        assert_eq!(dense.columns, sparse.columns);
        assert_eq!(dense.colours, sparse.colours);
        assert!(dense.widest() > 1, "{} columns", dense.columns());
    }
}
