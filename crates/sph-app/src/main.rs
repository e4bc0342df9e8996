//! The sph-splat demo: scene → simulate → extract → render, every frame.
//!
//! `cargo run --release` opens a window where a display exists and otherwise
//! renders a short clip headless; `--help` lists the options.

mod cli;
mod error;
#[cfg(test)]
mod golden;
mod gpu_extract;
mod gpu_sim;
mod headless;
mod orbit;
mod panel;
mod pipeline;
mod playback;
mod png;
mod scenery;
mod scenes;
mod window;

use std::path::Path;
use std::process::ExitCode;

use splat_render::Environment;

use crate::cli::Args;
use crate::error::AppError;
use crate::pipeline::Pipeline;
use crate::playback::Playback;

fn main() -> ExitCode {
    use clap::{CommandFactory, FromArgMatches};
    let matches = Args::command().get_matches();
    let args = Args::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let headless_flags = args.headless_only(|id| {
        matches.value_source(id) == Some(clap::parser::ValueSource::CommandLine)
    });
    if let Err(message) = args.check() {
        Args::command()
            .error(clap::error::ErrorKind::ValueValidation, message)
            .exit();
    }
    let level = match args.verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(level)).init();
    match run(&args, &headless_flags) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs the demo: a window where a display exists, else headless.
/// `headless_flags` are the flags given that only a headless run reads,
/// which a window refuses.
fn run(args: &Args, headless_flags: &[&'static str]) -> Result<(), AppError> {
    if args.list_scenes {
        print!("{}", scenes::listing());
        return Ok(());
    }
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(usize::from(n))
            .build_global()
            .map_err(|e| AppError::Threads(e.to_string()))?;
    }
    log::info!(
        "CPU neighbour search and sums on the {} path (SPH_SIMD lowers it)",
        sph_core::simd_level().name()
    );
    let mut pipeline = match (&args.input, args.particle_radius) {
        (Some(pattern), Some(radius)) => {
            let (playback, scene, particles) =
                Playback::open(pattern, radius, args.smoothing_length, 1.0 / args.fps)?;
            Pipeline::playback(pattern.clone(), scene, particles, playback, args.iterations)?
        }
        _ => {
            let (name, mut scene) = scenes::resolve(&args.scene)?;
            if let Some(kind) = args.solver {
                for note in scene.switch_solver(kind) {
                    println!("{note}");
                }
            }
            Pipeline::new(name, scene, args.iterations)?
        }
    };
    pipeline.extract.surface = args.surface_field().into();
    pipeline.extract.iso = args.iso;
    if args.headless {
        return headless::run(args, pipeline);
    }
    if !window::display_available() {
        println!("no display found (DISPLAY and WAYLAND_DISPLAY are unset): rendering headless");
        return headless::run(args, pipeline);
    }
    if let Some(flag) = headless_flags.first() {
        return Err(AppError::HeadlessOnly(flag));
    }
    window::run(args, pipeline)
}

/// The environment map and background from `assets/textures/`, or the same
/// images generated procedurally when the folder is not there.
pub fn environment() -> Environment {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/textures");
    Environment::load(&dir).unwrap_or_else(|e| {
        // Without the folder (an installed binary) the procedural images
        // are the plan; a folder whose images do not load is a mistake to
        // show.
        if dir.exists() {
            log::warn!("{e}; using the procedural environment");
        } else {
            log::info!("{e}; using the procedural environment");
        }
        Environment::procedural()
    })
}
