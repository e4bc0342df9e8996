//! Writes the procedural environment map and background to `assets/textures/`.
//!
//! `cargo run --release -p splat-render --example make_textures`

use std::path::Path;

use splat_render::Environment;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/textures");
    std::fs::create_dir_all(&dir)?;
    let env = Environment::procedural();
    env.environment.save(dir.join("environment.png"))?;
    env.background.save(dir.join("background.png"))?;
    println!("wrote {}", dir.display());
    Ok(())
}
