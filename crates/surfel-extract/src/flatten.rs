//! Parallel flat-map into a reused vector. rayon's `flat_map_iter(..).collect()`
//! gathers an unknown number of items per piece of work into fresh vectors and
//! copies them together: on a 100k-particle frame, page faults and copies were
//! a tenth of the extraction. Here every item's output count is known up front
//! (the expansion is run twice, so it must be cheap and give the same items each
//! time), and each chunk of input writes straight to its place in the output.

use std::mem::MaybeUninit;
use std::ops::Range;

use sph_core::region::{self, Blocks};

/// Inputs per parallel chunk.
const CHUNK: usize = 1024;

/// Appends `expand(0)`, `expand(1)`, …, `expand(n − 1)` to `out`, in that
/// order, computing them in parallel. `counts` is scratch space, reused too.
///
/// `expand` must be deterministic: it is called twice per index, once to count.
pub(crate) fn par_extend_flat<T, I>(
    out: &mut Vec<T>,
    n: usize,
    counts: &mut Vec<usize>,
    expand: impl Fn(usize) -> I + Sync,
) where
    T: Copy + Send + Sync,
    I: Iterator<Item = T>,
{
    counts.clear();
    counts.resize(n.div_ceil(CHUNK), 0);
    let per_chunk = Blocks::new(counts);
    let count = |chunk: Range<usize>, c: usize| {
        // SAFETY: each chunk writes its own count; nothing reads them.
        unsafe { per_chunk.block(c..c + 1)[0] = chunk.map(|i| expand(i).count()).sum() };
    };
    region::run_by(n, CHUNK, &[&count]);
    let total: usize = counts.iter().sum();
    out.reserve(total);
    let old_len = out.len();
    // One destination slice per chunk, in order.
    let mut rest: &mut [MaybeUninit<T>] = &mut out.spare_capacity_mut()[..total];
    let mut slices = Vec::with_capacity(counts.len());
    for &count in counts.iter() {
        let (head, tail) = rest.split_at_mut(count);
        slices.push(head);
        rest = tail;
    }
    let slices = Blocks::new(&mut slices);
    let write = |chunk: Range<usize>, c: usize| {
        // SAFETY: each chunk takes its own slice; nothing reads them.
        let dst = unsafe { &mut slices.block(c..c + 1)[0] };
        let mut items = chunk.flat_map(&expand);
        for slot in dst.iter_mut() {
            slot.write(
                items
                    .next()
                    .expect("`expand` gave fewer items than counted"),
            );
        }
        assert!(
            items.next().is_none(),
            "`expand` gave more items than counted"
        );
    };
    region::run_by(n, CHUNK, &[&write]);
    // SAFETY: every one of the `total` slots after `old_len` was written above
    // (a chunk that could not fill its slice panicked before this line).
    unsafe { out.set_len(old_len + total) };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_a_sequential_flat_map_and_appends() {
        let expand = |i: usize| (0..i % 7).map(move |k| (i * 10 + k) as u32);
        for n in [0, 1, CHUNK - 1, CHUNK, 3 * CHUNK + 17] {
            let mut out = vec![7u32, 8];
            let mut counts = Vec::new();
            par_extend_flat(&mut out, n, &mut counts, expand);
            let expected: Vec<u32> = [7, 8].into_iter().chain((0..n).flat_map(expand)).collect();
            assert_eq!(out, expected, "n = {n}");
        }
    }

    #[test]
    #[should_panic(expected = "than counted")]
    fn an_expansion_that_changes_is_caught() {
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let mut out: Vec<u8> = Vec::new();
        par_extend_flat(&mut out, 1, &mut Vec::new(), |_| {
            // One item when counted, none when written.
            let first = calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed) == 0;
            std::iter::repeat_n(1u8, usize::from(first))
        });
    }
}
