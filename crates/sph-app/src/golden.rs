//! Image goldens for the demo's tests: NVIDIA's FLIP against a PNG under
//! `tests/golden/`, which `SPH_UPDATE_GOLDEN=1` rewrites; a failing
//! comparison leaves the image and its error map in `target/tmp/`.

use std::path::PathBuf;

use image::RgbaImage;

/// NVIDIA's FLIP between two images: the mean and the error map.
pub fn flip(reference: &RgbaImage, test: &RgbaImage) -> (f32, RgbaImage) {
    let rgb = |i: &RgbaImage| {
        let rgb = image::DynamicImage::ImageRgba8(i.clone()).to_rgb8();
        nv_flip::FlipImageRgb8::with_data(rgb.width(), rgb.height(), &rgb)
    };
    let error = nv_flip::flip(
        rgb(reference),
        rgb(test),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    let mean = nv_flip::FlipPool::from_image(&error).mean();
    let map = error.apply_color_lut(&nv_flip::magma_lut()).to_vec();
    let map = image::DynamicImage::ImageRgb8(
        image::RgbImage::from_raw(reference.width(), reference.height(), map)
            .expect("FLIP map size"),
    );
    (mean, map.to_rgba8())
}

/// The FLIP mean of `image` against the golden `name.png` (written first
/// with `SPH_UPDATE_GOLDEN=1`); the image and, above `limit`, its error
/// map are saved in `target/tmp/` to look at.
pub fn against(name: &str, image: &RgbaImage, limit: f32) -> f32 {
    let golden = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/tmp");
    std::fs::create_dir_all(&out).unwrap();
    image.save(out.join(format!("{name}.png"))).unwrap();
    let path = golden.join(format!("{name}.png"));
    if std::env::var("SPH_UPDATE_GOLDEN").is_ok_and(|v| v == "1") {
        image.save(&path).unwrap();
    }
    let expected = image::open(&path)
        .unwrap_or_else(|e| panic!("{}: {e}; SPH_UPDATE_GOLDEN=1 writes it", path.display()))
        .to_rgba8();
    let (mean, map) = flip(&expected, image);
    if mean > limit {
        map.save(out.join(format!("{name}-difference.png")))
            .unwrap();
    }
    mean
}
