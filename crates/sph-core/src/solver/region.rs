//! A station's passes over the particles in one parallel region.
//!
//! A PBF substep is a dozen passes of a few hundred microseconds each. Run
//! as one `par_iter` per pass, every pass forks, splits, joins, and wakes
//! the threads that went to sleep in the gap before it; on many cores that
//! costs more than the pass gains (issue 45's 16-core table). [`run`]
//! instead starts the threads once for a whole sequence of passes. The
//! particles are cut into fixed [`BLOCK`]s; each pass's blocks are claimed
//! a few at a time from a counter shared by the whole sequence, and a claim
//! of pass p starts only when every claim of the passes before it is done:
//! the barrier between passes is a count of finished claims, not of
//! arrived threads.
//!
//! So a thread that never arrives (busy elsewhere in the pool) holds nobody
//! up: whoever is in the region does all the work, and the calling thread
//! alone finishes it if it must. A thread waiting for the last blocks of a
//! pass spins briefly, then yields, instead of going to sleep.
//!
//! Each block's values depend only on the block, never on which thread ran
//! it or in what order: a pass gathers into its own block, and whatever
//! must be reduced is written per block and reduced after the region in
//! block order. So results are bitwise the same for any number of threads.

use std::marker::PhantomData;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Particles per block: small enough that 10,000 particles make 157
/// blocks, so that 16 threads share a pass evenly; large enough that a
/// block's claim (one atomic add) is noise against its work.
pub(super) const BLOCK: usize = 64;

/// The number of blocks `n` particles make.
pub(super) fn blocks(n: usize) -> usize {
    n.div_ceil(BLOCK)
}

/// A pass: called once per block with the block's particles and its index.
pub(super) type Pass<'a> = &'a (dyn Fn(Range<usize>, usize) + Sync);

/// A pass built at run time (one per iteration of a solve).
pub(super) type OwnedPass<'a> = Box<dyn Fn(Range<usize>, usize) + Sync + 'a>;

/// Runs `passes` in order over `n` particles, each over every block, in one
/// parallel region of the current rayon pool.
///
/// A pass must not use rayon itself: a thread waiting in a `join` inside it
/// could pick up a helper of this region (or of another) and spin there
/// for a pass that the suspended block below it on the same stack holds
/// back.
///
/// # Panics
/// Where a pass panics; the other threads finish the claims of that pass
/// they hold or can still take, and stop before the next pass.
pub(super) fn run(n: usize, passes: &[Pass<'_>]) {
    let per_pass = blocks(n);
    let range = |b: usize| b * BLOCK..((b + 1) * BLOCK).min(n);
    let threads = rayon::current_num_threads().min(per_pass);
    if threads <= 1 {
        for pass in passes {
            (0..per_pass).for_each(|b| pass(range(b), b));
        }
        return;
    }
    // A claim takes a few blocks at once: about four claims per thread and
    // pass, so that the shared counters are touched a few hundred times a
    // pass at most and the threads still even out.
    let grain = per_pass.div_ceil(4 * threads);
    let claims = per_pass.div_ceil(grain);
    let total = claims * passes.len();
    let claimed = Padded(AtomicUsize::new(0));
    let done = Padded(AtomicUsize::new(0));
    let failed = AtomicBool::new(false);
    let work = || {
        let stop = Stop(&failed);
        loop {
            let c = claimed.fetch_add(1, Ordering::Relaxed);
            if c >= total {
                break;
            }
            let (p, first) = (c / claims, c % claims * grain);
            if !wait_for(&done, p * claims, &failed) {
                break;
            }
            (first..(first + grain).min(per_pass)).for_each(|b| passes[p](range(b), b));
            done.fetch_add(1, Ordering::Release);
        }
        std::mem::forget(stop);
    };
    rayon::scope(|s| {
        for _ in 1..threads {
            s.spawn(|_| work());
        }
        work();
    });
}

/// A counter on a cache line of its own: the threads bump one and spin
/// on the other.
#[repr(align(128))]
struct Padded(AtomicUsize);

impl std::ops::Deref for Padded {
    type Target = AtomicUsize;
    fn deref(&self) -> &AtomicUsize {
        &self.0
    }
}

/// Marks the region failed if a pass unwinds, so that nobody waits for the
/// block it never finishes.
struct Stop<'a>(&'a AtomicBool);

impl Drop for Stop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// Waits until `done` reaches `target`: true, or false if the region failed.
fn wait_for(done: &AtomicUsize, target: usize, failed: &AtomicBool) -> bool {
    let mut spins = 0u32;
    while done.load(Ordering::Acquire) < target {
        if failed.load(Ordering::Acquire) {
            return false;
        }
        if spins < 1 << 12 {
            std::hint::spin_loop();
            spins += 1;
        } else {
            std::thread::yield_now();
        }
    }
    true
}

/// A slice that the passes of a region write block by block and read whole
/// in later passes.
pub(super) struct Blocks<'a, T> {
    ptr: *mut T,
    len: usize,
    _slice: PhantomData<&'a mut [T]>,
}

// SAFETY: `Blocks` hands out `&mut [T]` of disjoint ranges and `&[T]` when
// nothing writes, on any thread: as `&mut [T]` would be, it needs `T: Send`
// to be sent and `T: Send + Sync` to be shared.
unsafe impl<T: Send> Send for Blocks<'_, T> {}
unsafe impl<T: Send + Sync> Sync for Blocks<'_, T> {}

impl<'a, T> Blocks<'a, T> {
    /// Borrows `slice` for the region.
    pub(super) fn new(slice: &'a mut [T]) -> Self {
        Self {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _slice: PhantomData,
        }
    }

    /// The elements in `range`, to write.
    ///
    /// # Safety
    /// Only the pass that owns this slice's writes, for the block it was
    /// given, while no pass reads the slice ([`run`] gives each block of a
    /// pass to one call, and starts a pass after the last one finished).
    #[allow(clippy::mut_from_ref)]
    pub(super) unsafe fn block(&self, range: Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len);
        // SAFETY: in bounds (asserted); exclusive by the caller's promise.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }

    /// The whole slice, to read.
    ///
    /// # Safety
    /// Only in a pass that writes none of it.
    pub(super) unsafe fn all(&self) -> &[T] {
        // SAFETY: no writer, by the caller's promise.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of passes, each reading its neighbours' values from the last,
    /// gives the same values on one thread and on seven.
    #[test]
    fn passes_see_the_whole_of_the_pass_before() {
        // 17 blocks, the last one short: on 2 threads claims of 3 blocks,
        // the last of 2.
        let n = 1050;
        let chain = |threads: usize| {
            let mut a: Vec<u64> = (0..n as u64).collect();
            let mut b = vec![0u64; n];
            let mut sums = vec![0u64; blocks(n)];
            let (a_out, b_out, s_out) = (
                Blocks::new(&mut a),
                Blocks::new(&mut b),
                Blocks::new(&mut sums),
            );
            let neighbours = |v: &[u64], i: usize| v[(i + n - 1) % n] + 3 * v[(i + 1) % n];
            // SAFETY (every pass): each writes only its own block of the
            // slice it owns and reads only slices no pass writes meanwhile.
            let to_b = |r: Range<usize>, _| {
                let (a, b) = unsafe { (a_out.all(), b_out.block(r.clone())) };
                for (k, i) in r.enumerate() {
                    b[k] = neighbours(a, i) % 1_000_003;
                }
            };
            let to_a = |r: Range<usize>, blk| {
                let (b, a) = unsafe { (b_out.all(), a_out.block(r.clone())) };
                for (k, i) in r.enumerate() {
                    a[k] = neighbours(b, i) % 1_000_003;
                }
                unsafe { s_out.block(blk..blk + 1)[0] = a.iter().sum() };
            };
            let passes: Vec<Pass<'_>> = vec![&to_b, &to_a, &to_b, &to_a];
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| run(n, &passes));
            (a, sums)
        };
        let one = chain(1);
        assert!(one.1.iter().all(|&s| s > 0));
        assert_eq!(chain(2), one);
        assert_eq!(chain(7), one);
    }

    /// A pass that panics stops the region with its panic instead of
    /// leaving the others waiting.
    #[test]
    fn a_panicking_pass_stops_the_region() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let boom = |r: Range<usize>, _| assert!(!r.contains(&500), "a pass failed");
        let after = |_: Range<usize>, _| {};
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| run(1000, &[&boom, &after]))
        }));
        assert!(result.is_err());
    }
}
