//! The README's clip (`docs/drop.gif`, made by the command written under it)
//! exists, decodes as an animated GIF of a few seconds and stays under 5 MB.

use image::AnimationDecoder;

#[test]
fn readme_clip_decodes() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/drop.gif");
    let bytes = std::fs::metadata(path).unwrap().len();
    assert!(bytes < 5 << 20, "{bytes} bytes");
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let frames = image::codecs::gif::GifDecoder::new(file)
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap();
    let ms: u32 = frames
        .iter()
        .map(|f| {
            let (n, d) = f.delay().numer_denom_ms();
            n / d.max(1)
        })
        .sum();
    assert!(frames.len() >= 30, "{} frames", frames.len());
    assert!((2_000..=10_000).contains(&ms), "{ms} ms");
    let readme = include_str!("../README.md");
    assert!(readme.contains("docs/drop.gif") && readme.contains("--gif docs/drop.gif"));
}
