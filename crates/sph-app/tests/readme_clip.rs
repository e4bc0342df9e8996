//! The README's clip (`docs/drop.gif`) is what the command written under it
//! makes: the command is read from the README, run in a scratch directory
//! with the built `sph-app`, and its GIF compared with the committed one
//! frame by frame: the same frames and delays, each within a FLIP mean of
//! 0.025. Lavapipe makes the same bytes on one machine; a sub-pixel change
//! of the rendering moves the GIF's palettes, up to 0.015 a frame (the
//! clip made before splats were planar quads, which looked the same),
//! while physics 10 % apart (XSPH 0.011 for 0.01) differs by 0.04–0.06
//! from the fourth frame on. The clip decodes, lasts a few seconds and
//! stays under 5 MB.

use std::path::{Path, PathBuf};
use std::process::Command;

use image::{AnimationDecoder, RgbaImage};

mod common;
use common::flip;

const README: &str = include_str!("../../../README.md");
const CLIP: &str = "docs/drop.gif";

/// The README's command for the clip, after `cargo run --release --`.
fn readme_args() -> Vec<String> {
    let end = README
        .find(&format!("--gif {CLIP}`"))
        .expect("the README gives the clip's command");
    let start = README[..end]
        .rfind("`cargo run --release --")
        .expect("the clip's command is a `cargo run --release --`");
    let command = &README[start + "`cargo run --release --".len()..end];
    let mut args: Vec<String> = command.split_whitespace().map(String::from).collect();
    args.extend(["--gif".into(), CLIP.into()]);
    args
}

/// Each frame of a GIF with its delay (ms).
fn frames(path: &Path) -> Vec<(RgbaImage, u32)> {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    image::codecs::gif::GifDecoder::new(file)
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap()
        .into_iter()
        .map(|f| {
            let (n, d) = f.delay().numer_denom_ms();
            (f.into_buffer(), n / d.max(1))
        })
        .collect()
}

#[test]
fn readme_clip_is_what_its_command_makes() {
    let committed = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(CLIP);
    let bytes = std::fs::metadata(&committed).unwrap().len();
    assert!(bytes < 5 << 20, "{bytes} bytes");
    let expected = frames(&committed);
    let ms: u32 = expected.iter().map(|(_, ms)| ms).sum();
    assert!(expected.len() >= 30, "{} frames", expected.len());
    assert!((2_000..=10_000).contains(&ms), "{ms} ms");

    let args = readme_args();
    println!("sph-app {}", args.join(" "));
    // Its own folder: a debug and a release run may go at once.
    let scratch = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("readme-clip-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    std::fs::create_dir_all(scratch.join("docs")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_sph-app"))
        .args(&args)
        .current_dir(&scratch)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    // Without an adapter the run fails before it writes: a skip, unless
    // `SPH_REQUIRE_GPU=1` (CI) makes it a failure.
    if !out.status.success()
        && stderr.contains("no GPU adapter")
        && std::env::var("SPH_REQUIRE_GPU").as_deref() != Ok("1")
    {
        eprintln!("skipped: no GPU adapter");
        return;
    }
    assert!(out.status.success(), "{stderr}");
    let made = frames(&scratch.join(CLIP));
    assert_eq!(made.len(), expected.len(), "frames");
    let mut worst = 0.0f32;
    for (k, ((a, a_ms), (b, b_ms))) in made.iter().zip(&expected).enumerate() {
        assert_eq!(a.dimensions(), b.dimensions(), "frame {k}");
        assert_eq!(a_ms, b_ms, "frame {k}'s delay");
        let mean = flip(b, a);
        worst = worst.max(mean);
        if mean > 0.025 {
            a.save(scratch.join(format!("frame-{k}-made.png"))).unwrap();
            b.save(scratch.join(format!("frame-{k}-committed.png")))
                .unwrap();
        }
        assert!(
            mean <= 0.025,
            "frame {k}: FLIP mean {mean} against {CLIP} (both frames in {}); \
             remake it with the README's command",
            scratch.display()
        );
    }
    println!(
        "{} frames, FLIP mean at most {worst:.4} against {CLIP}",
        made.len()
    );
    std::fs::remove_dir_all(&scratch).unwrap();
}
