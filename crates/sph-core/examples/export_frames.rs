//! Writing particle frames for ParaView, Blender or splashsurf.
//!
//! `cargo run --release -p sph-core --example export_frames -- OUT_DIR [ply|vtk] [FRAMES]`
//!
//! Runs the built-in thin dam break at 30 frames per simulated second and writes
//! `OUT_DIR/particles_00000.ply`, … with `particles_index.csv` beside them (frame,
//! simulated time, particle count, file). Each file also carries its time.

use sph_core::io::{Format, FrameWriter, PointCloud};
use sph_core::{Result, Scene};

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: export_frames OUT_DIR [ply|vtk] [FRAMES]";
    let Some(dir) = args.next() else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    let format: Format = args.next().as_deref().unwrap_or("ply").parse()?;
    let frames: u32 = match args.next().map(|s| s.parse()) {
        None => 30,
        Some(Ok(n)) => n,
        Some(Err(_)) => {
            eprintln!("{usage}");
            std::process::exit(2);
        }
    };
    let mut world = Scene::dam_break(0.2, 0.05, 0.01).build_world()?;
    let mut writer = FrameWriter::new(&dir, "particles", format)?;
    for _ in 0..frames {
        writer.write(&PointCloud::from_particles(&world.particles), world.time())?;
        world.advance(1.0 / 30.0)?;
    }
    println!(
        "wrote {} {} frames of {} particles to {dir}",
        writer.frames(),
        format.extension(),
        world.particles.len()
    );
    Ok(())
}
