//! The error type of `sph-core`.

/// Everything that can go wrong in `sph-core`, each with a message that names the
/// offending value and the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A parameter is out of its valid range or not finite.
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// A particle position is NaN or infinite.
    #[error("particle {index} has a non-finite position {position:?}")]
    NonFinitePosition {
        /// Index of the particle in the input slice.
        index: usize,
        /// The offending position.
        position: [f32; 3],
    },
    /// A particle's mass is not finite and positive, its velocity is not
    /// finite, or its position lies where the boundary admits no fluid.
    #[error("particle {index} has {what} {value}: {reason}")]
    InvalidParticle {
        /// Index of the particle.
        index: usize,
        /// What is wrong with it: "mass", "velocity" or "position".
        what: &'static str,
        /// The offending value, formatted.
        value: String,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// A particle lies so far from the origin, relative to the cell size, that its
    /// cell coordinate does not fit the grid's 32-bit cell coordinates.
    #[error(
        "particle {index} at {position:?} is too far from the origin for cell size h = {h} \
         (|x/h| must stay below 2^30); use a larger h or recentre the scene"
    )]
    OutOfGridRange {
        /// Index of the particle in the input slice.
        index: usize,
        /// The offending position.
        position: [f32; 3],
        /// The grid's cell size.
        h: f32,
    },
    /// More particles than the 32-bit indices of the neighbour grid can address.
    #[error("{count} particles exceed the neighbour grid's limit of {limit}")]
    TooManyParticles {
        /// The number of particles given.
        count: usize,
        /// The largest number supported.
        limit: usize,
    },
    /// More neighbour pairs than the 32-bit offsets of the neighbour lists
    /// can address.
    #[error(
        "{pairs} neighbour pairs exceed the neighbour lists' limit of 2³² − 1: \
         fewer particles, or a smaller h over the spacing"
    )]
    TooManyPairs {
        /// The pairs counted when the limit was passed.
        pairs: u64,
    },
    /// A named particle attribute does not exist.
    #[error("particle attribute `{0}` does not exist")]
    MissingAttribute(String),
    /// A named particle attribute exists with another element type.
    #[error("particle attribute `{name}` holds `{actual}`, not `{requested}`")]
    AttributeType {
        /// The attribute's name.
        name: String,
        /// The element type it holds.
        actual: &'static str,
        /// The element type that was asked for.
        requested: &'static str,
    },
    /// An attribute with this name already exists (or is a built-in field).
    #[error("particle attribute `{0}` already exists")]
    DuplicateAttribute(String),
    /// A processor ran without what it needs from earlier processors.
    #[error("processor `{processor}` {reason}")]
    Pipeline {
        /// The processor's name.
        processor: &'static str,
        /// What it lacked.
        reason: &'static str,
    },
    /// The simulation became unstable and was stopped.
    #[error("simulation stopped at step {step} (t = {time:.4} s): {what}; {hint}")]
    Unstable {
        /// The step at which it was detected.
        step: u64,
        /// Simulated time (s).
        time: f64,
        /// What went wrong.
        what: String,
        /// Which parameters to change.
        hint: String,
    },
    /// A scene file is not valid TOML or does not match the scene format (unknown
    /// or missing field, wrong type); the message names the field and line.
    #[error("scene file: {0}")]
    SceneSyntax(String),
    /// A scene value is out of range.
    #[error("scene field `{field}`: {reason}")]
    Scene {
        /// The field, e.g. `fluid.h` or `blocks[1]`.
        field: String,
        /// Why it is rejected.
        reason: String,
    },
    /// Reading or writing a file failed.
    #[error("{path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's reason.
        reason: String,
    },
    /// Arrays that must have the same length do not.
    #[error("length mismatch: `{what}` has {actual} elements, expected {expected}")]
    LengthMismatch {
        /// What was measured.
        what: &'static str,
        /// Its length.
        actual: usize,
        /// The expected length.
        expected: usize,
    },
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Checks that `h` is a usable smoothing length: finite and positive.
pub(crate) fn check_h(h: f32) -> Result<()> {
    if h.is_finite() && h > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name: "h",
            value: h.to_string(),
            reason: "the smoothing length must be finite and > 0",
        })
    }
}

/// The smallest and largest smoothing lengths the kernels accept (m): their
/// coefficients, up to 945/(32π h⁹), and powers up to h⁹ stay finite,
/// normal f32 values in between, and so does a density sum Σ m (h² − r²)³,
/// about 4 ρ0 h⁹ before its coefficient, for rest densities up to
/// [`crate::solver::MAX_REST_DENSITY`] (at h = 1e4 m and water's density it
/// overflowed).
pub const KERNEL_H_RANGE: (f32, f32) = (1e-4, 1e3);

/// Checks that `h` is a smoothing length the kernels can represent: within
/// [`KERNEL_H_RANGE`]. The GPU's passes, which compute the kernels'
/// coefficients themselves, check it too.
///
/// # Errors
/// [`Error::InvalidParameter`] naming `h`.
pub fn check_kernel_h(h: f32) -> Result<()> {
    check_h(h)?;
    let (lo, hi) = KERNEL_H_RANGE;
    if (lo..=hi).contains(&h) {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name: "h",
            value: h.to_string(),
            reason: "the kernels' smoothing length must lie in [1e-4, 1e3] m (their coefficients or sums overflow f32 outside); rescale the units",
        })
    }
}

/// How far from the origin, in units of h, a coordinate keeps f32's
/// resolution at h/128 or finer (an ulp of x is about |x| 2⁻²³): 2¹⁶.
/// Beyond, distances between neighbours carry errors of a percent of h and
/// more, and the densities, forces and surfaces built on them degrade
/// without failing (a surface extracted 2²⁰ h out lost half its surfels).
pub const MAX_PRECISE_EXTENT: f32 = 65536.0;

/// The index of the first of `points` farther than [`MAX_PRECISE_EXTENT`]
/// × `h` from the origin on some axis, if any. Non-finite points are left
/// to the checks that name them so.
pub fn first_imprecise(points: &[glam::Vec3], h: f32) -> Option<usize> {
    let reach = MAX_PRECISE_EXTENT * h;
    (points.iter()).position(|p| p.is_finite() && p.abs().max_element() > reach)
}

/// Why a point beyond [`MAX_PRECISE_EXTENT`] h is refused, for errors.
pub const IMPRECISE: &str = "lies more than 65,536 h from the origin, where f32 resolves \
    positions more coarsely than h/128: move the particles (and the scene) nearer the origin";

/// Refuses particle `positions` beyond [`MAX_PRECISE_EXTENT`] × `h` from
/// the origin: [`Error::InvalidParticle`] naming the first.
pub fn check_precise(positions: &[glam::Vec3], h: f32) -> Result<()> {
    match first_imprecise(positions, h) {
        Some(index) => Err(Error::InvalidParticle {
            index,
            what: "position",
            value: positions[index].to_string(),
            reason: IMPRECISE,
        }),
        None => Ok(()),
    }
}

/// `Ok` if `ok`, else [`Error::InvalidParameter`] naming `name`, its
/// `value` and `reason`: a parameter table's checks, one line each.
pub(crate) fn check_param(
    name: &'static str,
    value: f64,
    ok: bool,
    reason: &'static str,
) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name,
            value: value.to_string(),
            reason,
        })
    }
}

/// `Ok` if `v` is finite and > 0, else [`Error::InvalidParameter`] naming `name`.
pub fn positive(name: &'static str, v: f32) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name,
            value: v.to_string(),
            reason: "must be finite and > 0",
        })
    }
}

/// `Ok` if `v` is finite and ≥ 0, else [`Error::InvalidParameter`] naming `name`.
pub fn non_negative(name: &'static str, v: f32) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name,
            value: v.to_string(),
            reason: "must be finite and >= 0",
        })
    }
}
