//! Passes over the particles in parallel regions, and the team of threads
//! that keeps one region open for a whole step.
//!
//! A PBF substep is a dozen passes of a few hundred microseconds each. Run
//! as one `par_iter` per pass, every pass forks, splits, joins, and wakes
//! the threads that went to sleep in the gap before it; on many cores that
//! costs more than the pass gains (issue 45's 16-core table). [`run`]
//! instead hands a whole sequence of passes to the threads at once. The
//! particles are cut into fixed [`BLOCK`]s; each pass's blocks are claimed
//! a few at a time from a counter shared by the whole sequence, and a claim
//! of pass p starts only when every claim of the passes before it is done:
//! the barrier between passes is a count of finished claims, not of
//! arrived threads.
//!
//! [`team`] goes one step further: it starts the pool's threads once for
//! everything its closure does (a [`crate::World::advance`]: every station
//! of every substep; surfel-extract's extraction: every stage of a frame),
//! and they wait, spinning, for the [`run`]s the closure's thread posts.
//! Between two stations nobody goes to sleep and nothing forks; a thread
//! that has had no job for 2 ms goes back to the pool, and the next
//! [`run`] calls it again. Work that
//! uses rayon itself (a station that declares no
//! [`crate::Processor::runs_in_region`], the grid build of a large scene)
//! runs inside [`released`], which sends the team's threads back to the
//! pool for it and calls them again after. A region started inside a pass
//! runs on that pass's thread.
//!
//! A thread that never arrives (busy elsewhere in the pool) holds nobody
//! up: whoever is in the region does all the work, and the calling thread
//! alone finishes it if it must. A thread waiting for the last blocks of a
//! pass spins briefly, then yields, instead of going to sleep.
//!
//! Each block's values depend only on the block, never on which thread ran
//! it or in what order: a pass gathers into its own block, and whatever
//! must be reduced is written per block and reduced after the region in
//! block order. So results are bitwise the same for any number of threads,
//! with or without a team.

use std::cell::{Cell, UnsafeCell};
use std::marker::PhantomData;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicUsize, Ordering};

/// Particles per block: small enough that 10,000 particles make 157
/// blocks, so that 16 threads share a pass evenly; large enough that a
/// block's claim (one atomic add) is noise against its work.
pub const BLOCK: usize = 64;

/// Claims per thread and pass that [`run`] aims at.
const CLAIMS_PER_THREAD: usize = 16;

/// How long a team's thread waits for a job before it leaves the team and
/// goes back to its pool, where it sleeps; the next [`run`] calls it
/// again. Longer than the serial stretches between a step's passes (the
/// contacts, the sums of per-block counts: each well under 1 ms at 10k
/// particles on a slow 2-core VM), so that within a step nobody leaves.
const IDLE: std::time::Duration = std::time::Duration::from_millis(2);

/// The number of blocks `n` particles make.
pub fn blocks(n: usize) -> usize {
    n.div_ceil(BLOCK)
}

/// A pass: called once per block with the block's particles and its index.
pub type Pass<'a> = &'a (dyn Fn(Range<usize>, usize) + Sync);

/// A pass built at run time (one per iteration of a solve).
pub type OwnedPass<'a> = Box<dyn Fn(Range<usize>, usize) + Sync + 'a>;

/// Runs `passes` in order over `n` particles, each over every block, in one
/// parallel region: on the team this thread leads ([`team`]), else on the
/// threads of the current rayon pool, started for this call.
///
/// A pass must not use rayon itself: a thread waiting in a `join` inside it
/// could pick up a helper of this region (or of another) and spin there
/// for a pass that the suspended block below it on the same stack holds
/// back.
///
/// # Panics
/// Where a pass panics; the other threads finish the claims of that pass
/// they hold or can still take, and stop before the next pass.
pub fn run(n: usize, passes: &[Pass<'_>]) {
    run_by(n, BLOCK, passes);
}

/// [`run`] with blocks of `block` particles instead of [`BLOCK`]: for
/// passes whose per-block buffers are sized to their own blocks.
pub fn run_by(n: usize, block: usize, passes: &[Pass<'_>]) {
    let leading = LEADING.with(Cell::get);
    let threads = if leading.is_null() {
        rayon::current_num_threads()
    } else {
        // SAFETY: `team` clears `LEADING` before its team goes.
        unsafe { (*leading).threads }
    };
    let job = Job::new(n, block, passes, threads);
    // A region inside a pass (a pass that maps over a grid, say) runs on
    // the pass's thread: posting it would overwrite the job in flight, and
    // forking could leave this thread waiting on a claim below it.
    if job.threads <= 1 || IN_PASS.with(Cell::get) {
        for pass in passes {
            (0..job.per_pass).for_each(|b| pass(job.range(b), b));
        }
        return;
    }
    if !leading.is_null() {
        // SAFETY: as above.
        let team = unsafe { &*leading };
        // Called once per generation, and again if everyone called has
        // left (idle for `IDLE`).
        if !team.called.swap(true, Ordering::Relaxed) || team.pending.load(Ordering::SeqCst) == 0 {
            // SAFETY: `team` sets `call` before this thread leads the team,
            // and the closure it points to outlives the leading.
            unsafe { ((*team.call.load(Ordering::Relaxed)).0)() };
        }
        return team.run(job);
    }
    let claims = Claims::default();
    rayon::scope(|s| {
        for _ in 1..job.threads {
            s.spawn(|_| claims.work(&job));
        }
        claims.work(&job);
    });
}

/// Sets each `out[i]` by `f(i, &mut out[i])`, in one parallel pass
/// ([`run`]).
pub fn for_each<T: Send + Sync>(out: &mut [T], f: impl Fn(usize, &mut T) + Sync) {
    let n = out.len();
    let out = Blocks::new(out);
    let pass = |range: Range<usize>, _| {
        let first = range.start;
        // SAFETY: each block writes its own elements; nothing reads them.
        let block = unsafe { out.block(range) };
        (block.iter_mut().enumerate()).for_each(|(k, value)| f(first + k, value));
    };
    run(n, &[&pass]);
}

/// `f` of each block of `n` particles, in block order, computed in one
/// parallel pass ([`run`]): what a reduction adds or compares in block
/// order after it, the same for any number of threads.
pub fn map_blocks<T: Send + Sync + Copy + Default>(
    n: usize,
    f: impl Fn(Range<usize>) -> T + Sync,
) -> Vec<T> {
    let mut values = vec![T::default(); blocks(n)];
    let out = Blocks::new(&mut values);
    // SAFETY: each block writes its own value; nothing reads them.
    let pass = |range: Range<usize>, b: usize| unsafe { out.block(b..b + 1)[0] = f(range) };
    run(n, &[&pass]);
    values
}

/// Runs `f` with a team of the current rayon pool's threads kept in one
/// region for all of it: every [`run`] that `f` makes on this thread goes
/// to the team instead of forking. Inside a team already (or on a pool of
/// one thread) it just runs `f`.
///
/// `f` must do its parallel work through [`run`]: a `par_iter` inside it
/// finds the team's threads spinning and runs on this thread alone; put
/// such work inside [`released`].
pub fn team<R>(f: impl FnOnce() -> R) -> R {
    let threads = rayon::current_num_threads();
    if threads <= 1 || !LEADING.with(Cell::get).is_null() {
        return f();
    }
    let team = Team::new(threads);
    rayon::in_place_scope(|scope| {
        let call = || {
            let generation = team.generation.load(Ordering::Acquire);
            team.pending.fetch_add(threads - 1, Ordering::SeqCst);
            for _ in 1..threads {
                let team = &team;
                scope.spawn(move |_| team.serve(generation));
            }
        };
        let calls = Calls(&call);
        // Sends the team home however `f` ends, before `scope` waits for
        // it, and stops this thread leading it.
        let _home = Home(&team);
        LEADS.with(|l| l.set(l.get() + 1));
        LEADING.with(|l| l.set(&team));
        team.call.store(
            &calls as *const Calls<'_> as *mut Calls<'static>,
            Ordering::Relaxed,
        );
        f()
    })
}

/// Whether this thread leads a team ([`team`], outside [`released`]): where
/// a parallel helper runs its work as a region pass instead of through
/// rayon.
pub fn leading() -> bool {
    !LEADING.with(Cell::get).is_null()
}

/// Whether this thread is inside a pass of a region, where a [`run`]
/// runs its passes on this thread alone: a helper sizing its parts by the
/// threads would only add work there.
pub(crate) fn in_pass() -> bool {
    IN_PASS.with(Cell::get)
}

/// Runs `f` with the team this thread leads (if any) sent back to the
/// pool, so that rayon work inside `f` has the pool's threads; the next
/// [`run`] after it calls the team again.
pub fn released<R>(f: impl FnOnce() -> R) -> R {
    let leading = LEADING.with(Cell::get);
    if leading.is_null() {
        return f();
    }
    // SAFETY: `team` clears `LEADING` before its team goes.
    let team = unsafe { &*leading };
    if team.called.swap(false, Ordering::Relaxed) {
        team.generation.fetch_add(1, Ordering::AcqRel);
    }
    LEADING.with(|l| l.set(std::ptr::null()));
    // Leads the team again however `f` ends.
    struct Again(*const Team);
    impl Drop for Again {
        fn drop(&mut self) {
            LEADING.with(|l| l.set(self.0));
        }
    }
    let _again = Again(leading);
    f()
}

thread_local! {
    /// The team this thread leads: set by [`team`] for its closure, unset
    /// inside [`released`].
    static LEADING: Cell<*const Team> = const { Cell::new(std::ptr::null()) };
    /// How many teams this thread leads, [`released`] or not.
    static LEADS: Cell<usize> = const { Cell::new(0) };
    /// Whether this thread is running a pass of a region.
    static IN_PASS: Cell<bool> = const { Cell::new(false) };
}

/// [`team`]'s closure that spawns the team's threads.
struct Calls<'a>(&'a (dyn Fn() + 'a));

/// Clears this thread's team and sends its threads home.
struct Home<'a>(&'a Team);

impl Drop for Home<'_> {
    fn drop(&mut self) {
        LEADING.with(|l| l.set(std::ptr::null()));
        LEADS.with(|l| l.set(l.get() - 1));
        self.0.generation.fetch_add(1, Ordering::AcqRel);
    }
}

/// A sequence of passes over `n` particles, cut into claims.
struct Job<'a> {
    passes: &'a [Pass<'a>],
    n: usize,
    /// Particles per block.
    block: usize,
    per_pass: usize,
    /// Blocks per claim.
    grain: usize,
    /// Claims per pass.
    claims: usize,
    threads: usize,
}

impl<'a> Job<'a> {
    fn new(n: usize, block: usize, passes: &'a [Pass<'a>], threads: usize) -> Self {
        let per_pass = n.div_ceil(block);
        let threads = threads.min(per_pass);
        // A claim takes a few blocks at once: about sixteen claims per
        // thread and pass, so that the shared counters are touched a few
        // hundred times a pass (a thousand at 100k particles on 16 threads)
        // and the threads even out. With four, the 157 blocks of 10k
        // particles made 53 claims of 3 for 16 threads: 4 rounds of claims
        // where 3.3 would do, 81 % of the threads' time at best; with
        // sixteen, 157 claims of one, 98 %.
        let grain = per_pass.div_ceil(CLAIMS_PER_THREAD * threads.max(1)).max(1);
        Self {
            passes,
            n,
            block,
            per_pass,
            grain,
            claims: per_pass.div_ceil(grain),
            threads,
        }
    }

    fn range(&self, b: usize) -> Range<usize> {
        b * self.block..((b + 1) * self.block).min(self.n)
    }
}

/// The counters a job's threads share.
#[derive(Default)]
struct Claims {
    claimed: Padded,
    done: Padded,
    failed: AtomicBool,
}

impl Claims {
    /// Takes claims of `job` until there are none left.
    fn work(&self, job: &Job<'_>) {
        let total = job.claims * job.passes.len();
        let stop = Stop(&self.failed);
        loop {
            let c = self.claimed.fetch_add(1, Ordering::Relaxed);
            if c >= total {
                break;
            }
            let (p, first) = (c / job.claims, c % job.claims * job.grain);
            if !wait_for(&self.done, p * job.claims, &self.failed) {
                break;
            }
            let _in_pass = InPass::enter();
            (first..(first + job.grain).min(job.per_pass))
                .for_each(|b| job.passes[p](job.range(b), b));
            self.done.fetch_add(1, Ordering::Release);
        }
        std::mem::forget(stop);
    }
}

/// Threads of a rayon pool kept in one region ([`team`]).
struct Team {
    /// The pool's threads, this one included.
    threads: usize,
    /// Odd while a job is posted; bumped to post and to retract it.
    epoch: Padded,
    /// Bumped to send the threads serving the team home.
    generation: AtomicUsize,
    /// Whether threads of the current generation were called (by the first
    /// [`run`] since the team started or was [`released`]). Only the
    /// leading thread touches it.
    called: AtomicBool,
    /// Threads called and not yet gone home (queued, serving, or leaving):
    /// when it is zero, every thread called has left after [`IDLE`], and
    /// the next [`run`] calls them again.
    pending: AtomicUsize,
    /// How the leading thread calls the team's threads ([`team`]'s spawns).
    call: AtomicPtr<Calls<'static>>,
    /// Threads inside the posted job.
    active: Padded,
    claims: Claims,
    /// The posted job, its lifetime erased: valid while `epoch` is odd and
    /// for the threads counted in `active`.
    job: UnsafeCell<Option<Job<'static>>>,
}

// SAFETY: `job` is written by the leading thread only while no other
// thread reads it (no job posted and `active` zero), and read only by
// threads counted in `active` while it is posted.
unsafe impl Sync for Team {}

impl Team {
    fn new(threads: usize) -> Self {
        Self {
            threads,
            epoch: Padded::default(),
            generation: AtomicUsize::new(0),
            called: AtomicBool::new(false),
            pending: AtomicUsize::new(0),
            call: AtomicPtr::new(std::ptr::null_mut()),
            active: Padded::default(),
            claims: Claims::default(),
            job: UnsafeCell::new(None),
        }
    }

    /// Posts `job`, works on it with the team, and returns when it is done
    /// and nobody holds it any more.
    fn run(&self, job: Job<'_>) {
        // SAFETY: no job is posted and no thread is inside one (the last
        // `run` retracted its job and waited for `active` to reach zero; a
        // thread that counts itself in `active` after that finds the epoch
        // moved on and leaves without reading `job` or the counters), and
        // this is not inside a pass (`run_by` runs those on their thread).
        unsafe {
            *self.job.get() = Some(std::mem::transmute::<Job<'_>, Job<'static>>(job));
        }
        self.claims.claimed.store(0, Ordering::Relaxed);
        self.claims.done.store(0, Ordering::Relaxed);
        self.epoch.fetch_add(1, Ordering::SeqCst);
        // Retracts the job however this ends (a pass of this thread may
        // panic): the passes it borrows must outlive every thread in it.
        let _retract = Retract(self);
        // SAFETY: posted above; cleared only by `Retract`.
        let job = unsafe { (*self.job.get()).as_ref().expect("posted") };
        self.claims.work(job);
        let total = job.claims * job.passes.len();
        if !wait_for(&self.claims.done, total, &self.claims.failed) {
            panic!("a pass of a parallel region panicked on another thread");
        }
    }

    /// Serves the team's jobs until its generation moves on, or until it
    /// has waited [`IDLE`] for one.
    ///
    /// The idle limit also keeps a thread from spinning here for good
    /// where the work below it on its stack is what the leading thread
    /// waits for: a thread waiting in a `join` can pick up this call, and
    /// a leading thread in a rayon pass that is not [`released`] (a grid
    /// build below `light::SERIAL_BELOW` with a scattered layout) waits
    /// for the other half of its `join`. That hung a test once
    /// (`docs/benchmark-notes.md`, "A team's thread that never left").
    fn serve(&self, generation: usize) {
        let _gone = Leave(&self.pending);
        // A thread that leads a team (inside its `released` too) and waits
        // in rayon can pick up a call of its own team or of another: it
        // must not spin there, for its own team or another that waits for
        // it, so it leaves the call to the pool's other threads.
        if LEADS.with(Cell::get) > 0 {
            return;
        }
        let mut last = 0;
        let mut spins = 0u32;
        let mut idle_since: Option<std::time::Instant> = None;
        while self.generation.load(Ordering::Acquire) == generation {
            let epoch = self.epoch.load(Ordering::Acquire);
            if epoch % 2 == 1 && epoch != last {
                last = epoch;
                self.active.fetch_add(1, Ordering::SeqCst);
                let _leave = Leave(&self.active);
                if self.epoch.load(Ordering::SeqCst) == epoch {
                    // SAFETY: posted (`epoch` is odd) and kept until this
                    // thread leaves `active`.
                    let job = unsafe { (*self.job.get()).as_ref().expect("posted") };
                    self.claims.work(job);
                }
                spins = 0;
                idle_since = None;
            } else {
                back_off(&mut spins);
                if spins >= SPINS {
                    let since = *idle_since.get_or_insert_with(std::time::Instant::now);
                    if since.elapsed() >= IDLE {
                        return;
                    }
                }
            }
        }
    }
}

/// Marks this thread as running a pass until dropped (however the pass
/// ends).
struct InPass(bool);

impl InPass {
    fn enter() -> Self {
        Self(IN_PASS.with(|f| f.replace(true)))
    }
}

impl Drop for InPass {
    fn drop(&mut self) {
        IN_PASS.with(|f| f.set(self.0));
    }
}

/// Retracts a team's job and waits until no thread is inside it.
struct Retract<'a>(&'a Team);

impl Drop for Retract<'_> {
    fn drop(&mut self) {
        let team = self.0;
        team.epoch.fetch_add(1, Ordering::SeqCst);
        let mut spins = 0;
        while team.active.load(Ordering::SeqCst) != 0 {
            back_off(&mut spins);
        }
        // SAFETY: retracted, and nobody is inside it.
        unsafe { *team.job.get() = None };
        if team.claims.failed.swap(false, Ordering::AcqRel) && !std::thread::panicking() {
            panic!("a pass of a parallel region panicked on another thread");
        }
    }
}

/// Leaves a job's count of threads, however the thread leaves it.
struct Leave<'a>(&'a AtomicUsize);

impl Drop for Leave<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Spins [`back_off`] makes before it yields.
const SPINS: u32 = 1 << 12;

/// Spins a while, then yields.
fn back_off(spins: &mut u32) {
    if *spins < SPINS {
        std::hint::spin_loop();
        *spins += 1;
    } else {
        std::thread::yield_now();
    }
}

/// A counter on a cache line of its own: the threads bump one and spin
/// on the other.
#[derive(Default)]
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
        back_off(&mut spins);
    }
    true
}

/// A slice that the passes of a region write block by block and read whole
/// in later passes.
pub struct Blocks<'a, T> {
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
    pub fn new(slice: &'a mut [T]) -> Self {
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
    pub unsafe fn block(&self, range: Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len);
        // SAFETY: in bounds (asserted); exclusive by the caller's promise.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }

    /// The whole slice, to read.
    ///
    /// # Safety
    /// Only in a pass that writes none of it.
    pub unsafe fn all(&self) -> &[T] {
        // SAFETY: no writer, by the caller's promise.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of passes over `n` values, each reading its neighbours'
    /// values from the last, twice through [`run`]; between the two, with
    /// `team`, a `par_iter` sum inside [`released`] and a team of its own
    /// inside that. Returns the values and the per-block and rayon sums.
    fn chain(n: usize, pool: &rayon::ThreadPool, with_team: bool) -> (Vec<u64>, Vec<u64>, u64) {
        use rayon::prelude::*;
        let mut a: Vec<u64> = (0..n as u64).collect();
        let mut b = vec![0u64; n];
        let mut sums = vec![0u64; blocks(n)];
        let (a_out, b_out, s_out) = (
            Blocks::new(&mut a),
            Blocks::new(&mut b),
            Blocks::new(&mut sums),
        );
        let neighbours = |v: &[u64], i: usize| v[(i + n - 1) % n] + 3 * v[(i + 1) % n];
        // SAFETY (every pass): each writes only its own block of the slice
        // it owns and reads only slices no pass writes meanwhile.
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
        let steps = || {
            run(n, &passes);
            let total = released(|| {
                // SAFETY: no pass runs.
                let a = unsafe { a_out.all() };
                let inner = team(|| {
                    let mut c = vec![0u64; n];
                    let c_out = Blocks::new(&mut c);
                    let double = |r: Range<usize>, _| {
                        let c = unsafe { c_out.block(r.clone()) };
                        c.iter_mut().zip(&a[r]).for_each(|(c, &a)| *c = 2 * a);
                    };
                    run(n, &[&double]);
                    c.iter().sum::<u64>()
                });
                a.par_iter().sum::<u64>() + inner
            });
            run(n, &passes);
            total
        };
        let total = pool.install(|| if with_team { team(steps) } else { steps() });
        (a, sums, total)
    }

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    }

    /// Chains of passes give the same values on one thread and on two and
    /// seven, with and without a team, and a team's `released` work gets
    /// the pool.
    #[test]
    fn passes_see_the_whole_of_the_pass_before() {
        // 17 blocks, the last one short: on 2 threads claims of 3 blocks,
        // the last of 2.
        let n = 1050;
        let one = chain(n, &pool(1), false);
        assert!(one.1.iter().all(|&s| s > 0));
        assert!(one.2 > 0);
        for threads in [1, 2, 3, 7] {
            let pool = pool(threads);
            assert_eq!(chain(n, &pool, false), one, "{threads} threads");
            assert_eq!(chain(n, &pool, true), one, "{threads} threads, team");
        }
    }

    /// Teams on one pool, led from as many threads at once, each with
    /// rayon work released in between, all finish (none waits for a thread
    /// another holds) with the values of one thread.
    #[test]
    fn teams_side_by_side_on_one_pool_finish() {
        let one = chain(700, &pool(1), false);
        let shared = pool(3);
        let results: Vec<_> = std::thread::scope(|s| {
            let runs: Vec<_> = (0..6)
                .map(|_| {
                    s.spawn(|| {
                        (0..5)
                            .map(|_| chain(700, &shared, true))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            runs.into_iter().flat_map(|r| r.join().unwrap()).collect()
        });
        assert_eq!(results.len(), 30);
        assert!(results.iter().all(|r| *r == one));
    }

    /// A leading thread that forks with rayon without releasing its team
    /// (as a scattered grid's sort below `light::SERIAL_BELOW` does) and, while it
    /// waits in a `join`, runs a region in work it picked up: that calls
    /// the team, and the pool's other thread, itself waiting inside a
    /// `join` above work the leader waits for, can pick up the call and
    /// serve it. Without [`IDLE`] it served for good (a hang seen once in
    /// surfel-extract's `extractor_reused_across_frames_matches_one_shot`).
    /// A watchdog fails the test instead of hanging it.
    #[test]
    fn a_team_thread_holding_the_leaders_join_leaves() {
        fn busy(micros: u64) {
            let start = std::time::Instant::now();
            while start.elapsed() < std::time::Duration::from_micros(micros) {
                std::hint::spin_loop();
            }
        }
        fn fork(depth: u32, seed: u64) {
            if depth == 0 {
                if seed.is_multiple_of(3) {
                    run(512, &[&|_, _| busy(1)]);
                }
                busy(10 + seed % 17);
            } else {
                let seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                rayon::join(
                    || fork(depth - 1, seed >> 7),
                    || fork(depth - 1, seed >> 13),
                );
            }
        }
        let (done, finished) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            pool(2).install(|| {
                for round in 0..200 {
                    team(|| fork(6, round));
                }
            });
            done.send(()).unwrap();
        });
        let waited = finished.recv_timeout(std::time::Duration::from_secs(20));
        assert!(
            waited.is_ok(),
            "a team's rounds of joins did not finish in 20 s"
        );
    }

    /// A region inside a pass (on any thread, in a team or not) runs on
    /// the pass's thread and gives what it gives alone.
    #[test]
    fn a_region_inside_a_pass_runs_on_its_thread() {
        let n = 2000;
        let nested = |pool: &rayon::ThreadPool, with_team: bool| {
            let mut out = vec![0u64; n];
            let mut go = || {
                for_each(&mut out, |i, v| {
                    // Sums of blocks of a small inner range, per particle.
                    let inner = map_blocks(200 + i % 7, |r| r.map(|k| (k * i) as u64).sum::<u64>());
                    *v = inner.iter().sum();
                })
            };
            pool.install(|| if with_team { team(go) } else { go() });
            out
        };
        let one = nested(&pool(1), false);
        assert_eq!(one[3], (0..203u64).map(|k| k * 3).sum::<u64>());
        for threads in [2, 3] {
            let pool = pool(threads);
            assert_eq!(nested(&pool, false), one);
            assert_eq!(nested(&pool, true), one);
        }
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
        for with_team in [false, true] {
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                pool.install(|| {
                    if with_team {
                        team(|| run(1000, &[&boom, &after]))
                    } else {
                        run(1000, &[&boom, &after])
                    }
                })
            }));
            assert!(result.is_err(), "team: {with_team}");
        }
        // A pass that panics on a thread the team called, not on the one
        // leading it (whose blocks are slow, so that the others claim some).
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| {
                let leader = rayon::current_thread_index();
                let boom = |_: Range<usize>, _| {
                    if rayon::current_thread_index() == leader {
                        std::thread::sleep(std::time::Duration::from_millis(2));
                    } else {
                        panic!("a pass failed on another thread");
                    }
                };
                team(|| run(1000, &[&boom, &after]))
            })
        }));
        assert!(result.is_err());
        // The pool is whole after it.
        assert_eq!(pool.install(|| team(|| 7)), 7);
    }
}
