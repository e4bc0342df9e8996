//! # surfel-extract
//!
//! Will place surfels (position, normal, radius) on the colour-field iso-surface
//! c(x) = 0.5 of a particle set by Newton-Raphson steps from surface particles
//! (Vesterlund 2004, sections 3.2.1 and 4.2.1), beside the layered-depth-cube
//! reference extractor.
//!
//! Not yet implemented: this crate is an empty placeholder in the workspace until
//! the extraction issue lands. It depends on `sph-core` for the neighbour grid and
//! kernels, and on nothing that renders.
