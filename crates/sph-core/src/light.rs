//! How the neighbour grid's dense build (the usual one: a fluid filling
//! its bounding box; a scattered set's sort splits as before) and a
//! particle reordering split: passes doing a few nanoseconds of work per
//! particle. Below [`SERIAL_BELOW`] particles, outside a step's team, such
//! a pass runs on the calling thread alone, in one piece whatever its length: waking a second
//! thread after the gap since the last station's pass costs tens of
//! microseconds on a VM, more than the pass. Rebuilding the grid of a
//! lattice of 10,648 particles after a 50 µs gap took 0.143 ms on one
//! thread and 0.159–0.178 ms on two, of 19,683 0.271 against 0.318–0.321
//! ms, of 39,304 0.533 against 0.476–0.488 ms (the median of 400 rebuilds
//! each, 2-core VM, 2026-11-27; `cargo run --release -p sph-core --example
//! grid_rebuild_threads`). Pieces of at least 16k particles above it took
//! 0.56 ms at 39k and 1.10 against 1.01 ms at 97k on two threads, so larger
//! passes split as rayon sees fit. (Interpolated, one and two threads
//! break even near 29k.) The results are the same either way.
//!
//! Inside a step's team (`crate::region::team`) the other threads no
//! longer sleep between passes, and the grid's dense build splits among
//! them below [`SERIAL_BELOW`] too, as region passes (one part per thread,
//! `grid/layout.rs`): the grid station of `dam-break-fine` (10k particles,
//! 2 threads) took 0.35–0.44 ms a substep against 0.47–0.66 before, a
//! median ratio of 0.70 over four alternated pairs of `pbf_stations`
//! (2026-11-29), and the same on one thread. Split through rayon with the
//! team released instead (a throwaway build with `SERIAL_BELOW` = 0), it
//! had taken 0.83–0.85 ms against 0.68–0.81 on one (2026-11-27): the fork
//! cost more than the work. The solvers' own light passes (integration, a
//! density copy, a maximum) and, below [`SERIAL_BELOW`], the particles'
//! reordering after each build run as region passes in the team too: the
//! reordering gathers every column in one pass, and with it the 10k grid station took 0.18–0.19 ms
//! against 0.23–0.24 on two threads (`pbf_stations`, 2026-11-29).

/// The particle count from which a light pass splits.
pub(crate) const SERIAL_BELOW: usize = 1 << 15;

/// The fewest items of a parallel piece of a light pass over `n`
/// particles (`with_min_len(min_piece(n))`): one piece below
/// [`SERIAL_BELOW`] (even over more items than particles, such as the
/// cells of their box), else rayon's choice.
pub(crate) fn min_piece(n: usize) -> usize {
    if n < SERIAL_BELOW { usize::MAX } else { 1 }
}

/// How many parts a light pass over `n` particles written as region passes
/// (`crate::region::run_by`) splits into: one per thread from
/// [`SERIAL_BELOW`] particles or in a step's team, whose threads are
/// waiting; else one, on the calling thread; and one inside a region's
/// pass, which runs a region on its own thread anyway.
pub(crate) fn parts(n: usize) -> usize {
    if crate::region::in_pass() {
        1
    } else if n >= SERIAL_BELOW || crate::region::leading() {
        rayon::current_num_threads().max(1)
    } else {
        1
    }
}

/// Runs `f`, a light pass over `n` particles that uses rayon, with the
/// calling thread's team released (`crate::region::released`) where it
/// splits (from [`SERIAL_BELOW`]); below, on this thread as it is.
pub(crate) fn released_if_heavy<R>(n: usize, f: impl FnOnce() -> R) -> R {
    if n >= SERIAL_BELOW {
        crate::region::released(f)
    } else {
        f()
    }
}
