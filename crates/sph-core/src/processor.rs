//! The "conveyor belt" of thesis section 4.3.1: each time step, the particle
//! container passes through an ordered list of [`Processor`]s, each of which
//! modifies it (builds the neighbour grid, computes densities, adds forces,
//! integrates, adds or removes particles, ...). A [`Program`] is itself a
//! processor, so programs nest.
//!
//! ```
//! use sph_core::processor::{Context, Processor, Program};
//! use sph_core::{Particles, Result, glam::Vec3};
//!
//! /// Counts steps in a per-particle attribute.
//! struct Age;
//! impl Processor for Age {
//!     fn name(&self) -> &str { "age" }
//!     fn process(&mut self, particles: &mut Particles, _ctx: &mut Context) -> Result<()> {
//!         if !particles.has_attribute("age") {
//!             particles.add_attribute("age", 0u32)?;
//!         }
//!         particles.attribute_mut::<u32>("age")?.iter_mut().for_each(|a| *a += 1);
//!         Ok(())
//!     }
//! }
//!
//! let mut program = Program::new("mine");
//! program.push(Age);
//! let mut particles = Particles::new();
//! particles.push(Vec3::ZERO, Vec3::ZERO, 1.0);
//! let mut ctx = Context::new(0.01);
//! program.process(&mut particles, &mut ctx).unwrap();
//! program.process(&mut particles, &mut ctx).unwrap();
//! assert_eq!(particles.attribute::<u32>("age").unwrap(), &[2]);
//! ```

use crate::error::Result;
use crate::grid::{NeighbourGrid, NeighbourLists};
use crate::particles::Particles;

/// What a processor knows of the current step besides the particles.
#[derive(Debug)]
pub struct Context {
    /// The step's time increment (s).
    pub dt: f32,
    /// Simulated time at the start of the step (s).
    pub time: f64,
    /// Index of the step, from 0.
    pub step: u64,
    /// The neighbour grid over the current positions, once a grid processor has
    /// built it this step; `None` before, and after anything moved particles.
    pub grid: Option<NeighbourGrid>,
    /// Fixed neighbour lists of the step, found on the positions a grid was
    /// built over, once a neighbour-list processor made them
    /// ([`crate::solver::FindNeighbours`]). Unlike the grid they stay
    /// while a constraint projection moves particles within the step (as in
    /// Macklin & Müller 2013); a grid build drops them, and a processor that
    /// adds, removes or reorders particles after them must set this to `None`.
    pub neighbours: Option<NeighbourLists>,
    /// What the step's processors counted, summed into the frame's report.
    pub counters: StepCounters,
    /// An outdated grid whose memory the next grid build reuses.
    recycled: Option<NeighbourGrid>,
    /// Outdated neighbour lists whose memory the next build reuses.
    recycled_lists: Option<NeighbourLists>,
}

/// What the processors of one step count, for [`crate::solver::FrameReport`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StepCounters {
    /// Constraint-solver iterations taken (0 for a solver without any):
    /// PBF's density constraint, DFSPH's constant-density solve.
    pub iterations: u32,
    /// DFSPH's divergence-free solve's iterations (0 for other solvers).
    pub divergence_iterations: u32,
    /// The implicit viscosity solve's conjugate-gradient iterations (0
    /// without one).
    pub viscosity_iterations: u32,
    /// Solves that stopped at their iteration limit above their tolerance
    /// (DFSPH's; 0 for other solvers).
    pub unconverged: u32,
    /// Particles whose motion a guard limited (PBF's displacement guard).
    pub clamped: u64,
}

impl Context {
    /// A context for a step of length `dt` at time 0.
    pub fn new(dt: f32) -> Self {
        Self {
            dt,
            time: 0.0,
            step: 0,
            grid: None,
            neighbours: None,
            counters: StepCounters::default(),
            recycled: None,
            recycled_lists: None,
        }
    }

    /// Marks the grid outdated (particles moved, appeared or vanished), keeping
    /// its memory for the next build. Setting `grid = None` is equivalent but
    /// frees the memory.
    pub fn invalidate_grid(&mut self) {
        if let Some(grid) = self.grid.take() {
            self.recycled = Some(grid);
        }
    }

    /// Particles were added, removed or reordered: the grid and the
    /// neighbour lists are both out of date (their memory is kept for the
    /// next builds).
    pub fn invalidate_neighbours(&mut self) {
        self.invalidate_grid();
        if let Some(lists) = self.neighbours.take() {
            self.recycled_lists = Some(lists);
        }
    }

    /// The lists or outdated ones, to rebuild in place.
    pub(crate) fn take_lists_memory(&mut self) -> Option<NeighbourLists> {
        self.neighbours
            .take()
            .or_else(|| self.recycled_lists.take())
    }

    /// The grid or the outdated one, to rebuild in place.
    pub(crate) fn take_grid_memory(&mut self) -> Option<NeighbourGrid> {
        self.grid.take().or_else(|| self.recycled.take())
    }

    /// Hands an outdated grid's and neighbour lists' memory to this context
    /// (from a previous step).
    pub(crate) fn recycle(&mut self, grid: Option<NeighbourGrid>, lists: Option<NeighbourLists>) {
        self.recycled = grid;
        self.recycled_lists = lists;
    }
}

/// One station of the conveyor belt: modifies the particle container for one step.
pub trait Processor: Send {
    /// A short name, used to find and report it. Names may repeat (every
    /// [`crate::solver::Emitter`] is `emitter`): [`Program::insert_after`] and
    /// [`Program::insert_before`] find the first of a name, [`Program::remove`]
    /// removes all of it.
    fn name(&self) -> &str;
    /// Processes the particles for the step described by `ctx`.
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()>;
    /// Whether `process` does its parallel work only through sph-core's
    /// parallel regions, so that the team of threads a
    /// [`crate::World::advance`] keeps awake for the whole step may stay
    /// awake across it. The default, `false`, sends the team back to rayon's
    /// pool for this processor (one fork and join, as each `par_iter` pays
    /// anyway), which a processor that uses rayon, or no threads at all,
    /// needs: inside the team a `par_iter` finds the pool's threads busy and
    /// runs on one. sph-core's own stations answer `true` where it holds.
    fn runs_in_region(&self) -> bool {
        false
    }
}

/// A boxed processor is one: lists of `Box<dyn Processor>` can be wrapped
/// and pushed like any other.
impl<P: Processor + ?Sized> Processor for Box<P> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        (**self).process(particles, ctx)
    }
    fn runs_in_region(&self) -> bool {
        (**self).runs_in_region()
    }
}

/// An ordered list of processors, itself a processor.
pub struct Program {
    name: String,
    processors: Vec<Box<dyn Processor>>,
}

impl Program {
    /// An empty program.
    pub fn new(name: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            processors: Vec::new(),
        }
    }

    /// Appends a processor.
    pub fn push(&mut self, processor: impl Processor + 'static) -> &mut Self {
        self.processors.push(Box::new(processor));
        self
    }

    /// Puts a processor first.
    pub fn push_front(&mut self, processor: impl Processor + 'static) -> &mut Self {
        self.processors.insert(0, Box::new(processor));
        self
    }

    /// Inserts a processor right after the one named `after`; returns false (and
    /// inserts nothing) if there is none of that name.
    pub fn insert_after(&mut self, after: &str, processor: impl Processor + 'static) -> bool {
        match self.processors.iter().position(|p| p.name() == after) {
            Some(k) => {
                self.processors.insert(k + 1, Box::new(processor));
                true
            }
            None => false,
        }
    }

    /// Inserts a processor right before the one named `before`; returns false (and
    /// inserts nothing) if there is none of that name.
    pub fn insert_before(&mut self, before: &str, processor: impl Processor + 'static) -> bool {
        match self.processors.iter().position(|p| p.name() == before) {
            Some(k) => {
                self.processors.insert(k, Box::new(processor));
                true
            }
            None => false,
        }
    }

    /// Removes every processor named `name`; returns whether there was one.
    pub fn remove(&mut self, name: &str) -> bool {
        let before = self.processors.len();
        self.processors.retain(|p| p.name() != name);
        self.processors.len() != before
    }

    /// Removes every processor named `name` and returns them, in order
    /// (to move them, with their state, into another program).
    pub fn take(&mut self, name: &str) -> Vec<Box<dyn Processor>> {
        let (taken, kept) = std::mem::take(&mut self.processors)
            .into_iter()
            .partition(|p| p.name() == name);
        self.processors = kept;
        taken
    }

    /// The processors' names, in order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.processors.iter().map(|p| p.name())
    }
}

impl Processor for Program {
    fn name(&self) -> &str {
        &self.name
    }

    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        for p in &mut self.processors {
            if p.runs_in_region() {
                p.process(particles, ctx)?;
            } else {
                crate::region::released(|| p.process(particles, ctx))?;
            }
        }
        Ok(())
    }

    /// True: each of its processors is run as it declares.
    fn runs_in_region(&self) -> bool {
        true
    }
}

impl std::fmt::Debug for Program {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Program")
            .field("name", &self.name)
            .field("processors", &self.names().collect::<Vec<_>>())
            .finish()
    }
}
