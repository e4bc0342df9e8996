//! # splat-render
//!
//! Will draw any set of surfels with wgpu by two-pass point splatting: a visibility
//! pass, an additive attribute pass with the thesis's alpha mask, then per-pixel
//! normalisation and deferred shading in a compute pass (Vesterlund 2004, 3.2.2,
//! 3.2.3 and 4.2.2), with a headless backend for tests.
//!
//! Not yet implemented: this crate is an empty placeholder in the workspace until
//! the renderer issue lands. It knows nothing of SPH.
