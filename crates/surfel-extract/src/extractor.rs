//! [`Extractor`]: the extraction, its memory kept from one frame to the next.

use std::time::Instant;

use glam::Vec3;
use sph_core::{Particles, Result};

use crate::{ColourField, ExtractParams, Stats, Surfels, on_pool, thesis};

/// Extracts surfels frame after frame, keeping the colour field's neighbour
/// grid, the passes' buffers and the output between calls, where the
/// one-shot [`crate::extract`] pays for fresh memory, page faults included,
/// on every call. Hole closing still builds its index over the first
/// iteration's surfels per call (keeping it measured no faster).
///
/// The result is the same as `extract`'s, bit for bit.
///
/// ```
/// use surfel_extract::{ExtractParams, Extractor};
/// use sph_core::glam::Vec3;
///
/// let mut extractor = Extractor::new();
/// let params = ExtractParams::new(0.1);
/// for frame in 0..3 {
///     let points: Vec<Vec3> = (0..125)
///         .map(|i| Vec3::new((i % 5) as f32, (i / 5 % 5) as f32, (i / 25) as f32) * 0.05)
///         .map(|x| x + Vec3::X * 0.01 * frame as f32)
///         .collect();
///     let out = extractor.extract_points(&points, &params).unwrap();
///     assert!(!out.surfels.is_empty());
/// }
/// ```
#[derive(Debug, Default)]
pub struct Extractor {
    /// The last frame's field, refilled by the next.
    field: Option<ColourField>,
    scratch: thesis::Scratch,
    out: Surfels,
}

impl Extractor {
    /// An extractor with no memory yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Extracts surfels from simulated particles (volumes m/ρ, see
    /// [`ColourField::from_particles`]).
    ///
    /// # Errors
    /// Invalid `params` or particles; the output is then empty.
    pub fn extract(&mut self, particles: &Particles, params: &ExtractParams) -> Result<&Surfels> {
        self.extract_built(params, |field, h| field.refill_from_particles(particles, h))
    }

    /// Extracts surfels from bare points (Shepard volumes, see
    /// [`ColourField::from_positions`]).
    ///
    /// # Errors
    /// Invalid `params` or positions; the output is then empty.
    pub fn extract_points(
        &mut self,
        positions: &[Vec3],
        params: &ExtractParams,
    ) -> Result<&Surfels> {
        self.extract_built(params, |field, h| field.refill_from_positions(positions, h))
    }

    /// Extracts surfels from a prepared field (its h is used; `params.h` is
    /// ignored). [`Extractor::field`] is not changed.
    ///
    /// # Errors
    /// Invalid `params`; the output is then empty.
    pub fn extract_field(
        &mut self,
        field: &ColourField,
        params: &ExtractParams,
    ) -> Result<&Surfels> {
        self.clear();
        let params = ExtractParams {
            h: field.h(),
            ..*params
        };
        params.validate()?;
        let (scratch, out) = (&mut self.scratch, &mut self.out);
        let result = on_pool(|| thesis::run(field, &params, scratch, &mut out.surfels))
            .map(|stats| out.stats = stats);
        self.finish(result)
    }

    /// The last extraction's surfels and statistics (empty after an error).
    pub fn surfels(&self) -> &Surfels {
        &self.out
    }

    /// Forgets the last extraction's output, keeping its memory.
    pub fn clear(&mut self) {
        self.out.surfels.clear();
        self.out.stats = Stats::default();
    }

    /// Takes the last extraction's output, leaving an empty one: the next call
    /// allocates its output afresh.
    pub fn take(&mut self) -> Surfels {
        std::mem::take(&mut self.out)
    }

    /// The colour field the last [`Extractor::extract`] or
    /// [`Extractor::extract_points`] with valid parameters built: empty if
    /// building it failed, `None` before any.
    pub fn field(&self) -> Option<&ColourField> {
        self.field.as_ref()
    }

    /// Validates `params`, refills the field (timed as `field_time`) and
    /// extracts.
    fn extract_built(
        &mut self,
        params: &ExtractParams,
        refill: impl FnOnce(&mut ColourField, f32) -> Result<()> + Send,
    ) -> Result<&Surfels> {
        self.clear();
        params.validate()?;
        let Self {
            field,
            scratch,
            out,
        } = self;
        let result = on_pool(|| {
            let start = Instant::now();
            let field = match field {
                Some(field) => field,
                None => field.insert(ColourField::empty()),
            };
            field.set_surface(params.surface)?;
            refill(field, params.h)?;
            let field_time = start.elapsed();
            out.stats = thesis::run(field, params, scratch, &mut out.surfels)?;
            out.stats.field_time = field_time;
            Ok(())
        });
        self.finish(result)
    }

    /// The output, or the error with the output emptied: a pass that failed
    /// part way may have written some surfels.
    fn finish(&mut self, result: Result<()>) -> Result<&Surfels> {
        match result {
            Ok(()) => Ok(&self.out),
            Err(e) => {
                self.clear();
                Err(e)
            }
        }
    }
}
