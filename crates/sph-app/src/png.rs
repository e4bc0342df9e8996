//! PNG files, written and checked: `image`'s `save` leaves the last part of a
//! file in a buffer that is flushed when dropped, where a failed write (a
//! full disk) is lost, so a small frame could vanish without an error.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use image::codecs::png::PngEncoder;
use image::{ImageEncoder, RgbaImage};

use crate::error::AppError;

/// Writes `image` to `path` as a PNG, flushing it and reporting any failed
/// write as an error naming the file.
pub fn save(image: &RgbaImage, path: &Path) -> Result<(), AppError> {
    let fail = |e: &dyn std::fmt::Display| AppError::output(path, e);
    let file = File::create(path).map_err(|e| fail(&e))?;
    let mut out = BufWriter::new(file);
    PngEncoder::new(&mut out)
        .write_image(
            image.as_raw(),
            image.width(),
            image.height(),
            image::ExtendedColorType::Rgba8,
        )
        .map_err(|e| fail(&e))?;
    out.into_inner().map_err(|e| fail(&e.into_error()))?;
    Ok(())
}
