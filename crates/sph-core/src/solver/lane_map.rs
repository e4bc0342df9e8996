//! The solvers' per-particle passes over [`F32x8`] lanes: a [`LaneMap`]
//! gives a value per particle, a [`LaneRowMap`] also writes a value per
//! neighbour pair. [`par_map`], [`fill_block`] and [`par_map_rows`] run
//! them with the lanes [`with_lanes`] picks (every kind gives bitwise the
//! same values).

use std::ops::Range;

use crate::NeighbourLists;
use crate::region::{self, Blocks};
use crate::simd::{F32x8, LaneFn, Lanes, with_lanes};

/// A per-particle computation written over lanes of any kind.
pub(super) trait LaneMap: Sync {
    /// What it gives per particle.
    type Out: Send + Sync + Copy + Default;
    /// Particle `i`'s value, computed with lanes `S`. Implementations
    /// must be `#[inline(always)]` (see [`LaneFn`]).
    fn particle<S: F32x8>(&self, i: usize) -> Self::Out;
}

/// Particles per parallel task: a fixed size, so that nothing depends on the
/// number of threads.
const BLOCK: usize = 256;

/// Sets `out` to `map`'s value for each of `n` particles, in parallel, with
/// the lanes [`with_lanes`] picks.
pub(super) fn par_map<M: LaneMap>(map: &M, n: usize, out: &mut Vec<M::Out>) {
    // Every value is written below; the memory is only sized here.
    out.resize(n, M::Out::default());
    let blocks = Blocks::new(out);
    // SAFETY: each block writes its own values; nothing reads them.
    let fill =
        |range: Range<usize>, _| fill_block(map, range.start, unsafe { blocks.block(range) });
    region::run_by(n, BLOCK, &[&fill]);
}

/// Sets `block[k]` to `map`'s value for particle `first + k`, on this
/// thread, with the lanes [`with_lanes`] picks.
#[inline]
pub(super) fn fill_block<M: LaneMap>(map: &M, first: usize, block: &mut [M::Out]) {
    with_lanes(Fill { map, first, block });
}

/// [`fill_block`]'s work, for [`with_lanes`].
struct Fill<'a, M: LaneMap> {
    map: &'a M,
    first: usize,
    block: &'a mut [M::Out],
}

impl<M: LaneMap> LaneFn for Fill<'_, M> {
    type Out = ();
    #[inline(always)]
    fn call<S: F32x8>(self) {
        for (k, out) in self.block.iter_mut().enumerate() {
            *out = self.map.particle::<S>(self.first + k);
        }
    }
}

/// A per-particle computation over lanes of any kind that also writes a
/// value per neighbour pair, into the particle's row (laid out as
/// [`NeighbourLists::row`] lays them out).
pub(super) trait LaneRowMap: Sync {
    /// What it gives per particle.
    type Out: Send + Sync;
    /// What it writes per pair.
    type Pair: Send + Sync;
    /// Particle `i`'s value, computed with lanes `S`; `pairs` is its row.
    /// Implementations must be `#[inline(always)]` (see [`LaneFn`]).
    fn particle<S: F32x8>(&self, i: usize, pairs: &mut [Self::Pair]) -> Self::Out;
}

/// One particle of a [`LaneRowMap`], for [`with_lanes`].
struct Row<'a, M: LaneRowMap> {
    map: &'a M,
    i: usize,
    pairs: &'a mut [M::Pair],
}

impl<M: LaneRowMap> LaneFn for Row<'_, M> {
    type Out = M::Out;
    #[inline(always)]
    fn call<S: F32x8>(self) -> M::Out {
        self.map.particle::<S>(self.i, self.pairs)
    }
}

/// Sets `out[i]` and row i of `pairs` by `map` for every particle of
/// `lists`, in parallel ([`NeighbourLists::par_map_rows`]), with the lanes
/// [`with_lanes`] picks ([`Lanes::best`]).
///
/// # Panics
/// As [`NeighbourLists::par_map_rows`]: unless `out` holds a value per
/// particle and `pairs` one per pair.
pub(super) fn par_map_rows<M: LaneRowMap>(
    map: &M,
    lists: &NeighbourLists,
    out: &mut [M::Out],
    pairs: &mut [M::Pair],
) {
    let lanes = Lanes::best();
    lists.region_map_rows(out, pairs, |i, _, pairs| lanes.run(Row { map, i, pairs }));
}

/// `map`'s values for `n` particles with every kind of lanes this CPU
/// runs, the plain arrays first: what the solvers' tests compare.
#[cfg(test)]
pub(super) fn every_kind<M: LaneMap>(map: &M, n: usize) -> Vec<(&'static str, Vec<M::Out>)> {
    Lanes::every()
        .into_iter()
        .map(|lanes| {
            let mut block = vec![M::Out::default(); n];
            lanes.run(Fill {
                map,
                first: 0,
                block: &mut block,
            });
            (lanes.name(), block)
        })
        .collect()
}

/// One kind of lanes' run of a [`LaneRowMap`]: its name, the values per
/// particle and the rows of per-pair values.
#[cfg(test)]
pub(super) type KindRows<M> = (
    &'static str,
    Vec<<M as LaneRowMap>::Out>,
    Vec<<M as LaneRowMap>::Pair>,
);

/// `map`'s values and rows for every particle of `lists` with every kind
/// of lanes this CPU runs, the plain arrays first: what the solvers' tests
/// compare for the passes that write per-pair data.
#[cfg(test)]
pub(super) fn every_kind_rows<M: LaneRowMap>(map: &M, lists: &NeighbourLists) -> Vec<KindRows<M>>
where
    M::Pair: Clone + Default,
{
    Lanes::every()
        .into_iter()
        .map(|lanes| {
            let mut pairs = vec![M::Pair::default(); lists.pairs()];
            let mut out = Vec::with_capacity(lists.len());
            let mut rest = &mut pairs[..];
            for i in 0..lists.len() {
                let (row, tail) = std::mem::take(&mut rest).split_at_mut(lists.of(i).len());
                out.push(lanes.run(Row { map, i, pairs: row }));
                rest = tail;
            }
            (lanes.name(), out, pairs)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `par_map` fills every particle's value, whatever the block split.
    #[test]
    fn par_map_fills_every_particle() {
        struct Square;
        impl LaneMap for Square {
            type Out = f32;
            fn particle<S: F32x8>(&self, i: usize) -> f32 {
                (S::splat(i as f32) * S::splat(i as f32)).to_array()[3]
            }
        }
        let mut out = vec![7.0; 3];
        par_map(&Square, 1000, &mut out);
        assert_eq!(out.len(), 1000);
        assert!(out.iter().enumerate().all(|(i, &v)| v == (i * i) as f32));
    }
}
