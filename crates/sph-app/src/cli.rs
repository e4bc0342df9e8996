//! Command-line arguments (clap).

use std::path::PathBuf;

use clap::{Parser, ValueEnum};

/// Real-time SPH fluid with surfel extraction and point-splat rendering
/// (Vesterlund 2004). Without a display (or with --headless) it renders frames
/// to PNG files.
#[derive(Debug, Parser)]
#[command(version, about)]
pub struct Args {
    /// A built-in scene name (see --list-scenes) or a scene file (.toml).
    /// The default, `drop` (5,500 particles), is the largest built-in scene
    /// that PBF simulates and extracts in real time on two cores.
    #[arg(long, default_value = crate::scenes::DEFAULT)]
    pub scene: String,

    /// The solver, overriding the scene's choice: `pbf` (position-based
    /// fluids, real time; the built-in scenes' and a scene file's default),
    /// `dfsph` (divergence-free SPH, accurate) or `wcsph` (the thesis's
    /// weakly compressible SPH, the reference).
    #[arg(long, value_parser = parse_solver)]
    pub solver: Option<sph_core::SolverKind>,

    /// Play particle files instead of simulating: a file or a glob such as
    /// 'sim/particles_*.bgeo' (quoted, so that the shell leaves it alone),
    /// read one file per frame in natural order (`_2` before `_10`). Legacy
    /// VTK, VTU, PLY, XYZ (binary f32 triples), BGEO and splashsurf's JSON,
    /// from any simulator. A frame's time is the file's where it records one
    /// (this project's exports), else its index over --fps. Headless, every
    /// file is one frame (--frames or --seconds take fewer, or loop); the
    /// window loops. Needs --particle-radius.
    #[arg(long, value_name = "PATTERN", conflicts_with_all = ["scene", "solver", "gpu_sim"], requires = "particle_radius")]
    pub input: Option<String>,

    /// The radius r (m) of the particles read with --input: each stands for
    /// a cube 2r wide.
    #[arg(long, value_name = "R", value_parser = parse_length, requires = "input")]
    pub particle_radius: Option<f32>,

    /// The smoothing length of --input's particles in multiples of
    /// --particle-radius, as splashsurf takes it: the extraction's kernel
    /// support h is twice it, 2 × 2 × r = 4r by default (h = 2 particle
    /// diameters, as the built-in scenes have). h must span from one to
    /// ten particle diameters.
    #[arg(long, value_name = "L", default_value_t = 2.0, value_parser = parse_length, requires = "input")]
    pub smoothing_length: f32,

    /// The iso value of the surface the surfels lie on, c = k_iso (thesis
    /// eq. 34), in (0, 1): lower values give a fuller surface. Default 0.5.
    /// For any run; with --input it sets the surface around other
    /// simulators' particles as splashsurf's --surface-threshold does.
    #[arg(long, value_name = "K", default_value_t = 0.5, value_parser = parse_iso)]
    pub iso: f32,

    /// Print the built-in scenes and exit.
    #[arg(long)]
    pub list_scenes: bool,

    /// Render frames to PNG files instead of opening a window (automatic
    /// when no display is available).
    #[arg(long)]
    pub headless: bool,

    /// Number of frames to render headless (default: 1 s of simulated time).
    #[arg(long, conflicts_with = "seconds", value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: Option<u32>,

    /// Simulated duration to render headless, in seconds (alternative to --frames).
    #[arg(long, value_parser = parse_seconds)]
    pub seconds: Option<f64>,

    /// Frames per second of simulated time (headless), 1 to 1000: how
    /// often a frame is rendered and exported. The scene's
    /// `time_step.frame_dt` still sets the solvers' steps (PBF's substep
    /// length); a frame longer than it takes more of them.
    #[arg(long, default_value_t = 30.0, value_parser = parse_fps)]
    pub fps: f64,

    /// Output folder for headless frames, frames.csv and exports.
    #[arg(long, default_value = "frames")]
    pub out: PathBuf,

    /// Also write the frames as an animated GIF at PATH (looping, one frame
    /// per --fps of simulated time, shown at --fps on average in GIF's whole
    /// hundredths of a second, so --fps at most 50, above which browsers
    /// slow frames down; headless, needs a GPU adapter). The file
    /// is created before the run starts, so a path that cannot be written is
    /// an error at once.
    #[arg(long, value_name = "PATH")]
    pub gif: Option<PathBuf>,

    /// Also write each frame's particles (PLY or VTK).
    #[arg(long, value_enum)]
    pub export_particles: Option<ExportFormat>,

    /// Also write each frame's surfels (PLY or VTK).
    #[arg(long, value_enum)]
    pub export_surfels: Option<ExportFormat>,

    /// Worker threads for simulation and extraction (default: all cores).
    /// The simulation steps on at most max(8, particles / 3000) of them,
    /// the most it gains from (`sph_core::useful_threads`).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,

    /// The surface field the surfels lie on: Yu & Turk's anisotropic
    /// kernels (the default), which make smooth water, or the thesis's
    /// isotropic colour field, bumpy at the particle scale and about 3.5
    /// times cheaper to extract (`drop`: 10–11 ms a frame against 3–3.6 ms
    /// on two cores, where its simulation takes 6–7 ms). --gpu-extract
    /// extracts either, the anisotropic one by default as well.
    #[arg(long, value_enum)]
    pub surface: Option<SurfaceField>,

    /// Draw the fluid alone before the thesis's screen-space background,
    /// without the scene's tank, obstacles and ground.
    #[arg(long)]
    pub no_scenery: bool,

    /// Surfel refinement iterations (thesis: 1–3).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=3))]
    pub iterations: u32,

    /// Image width in pixels.
    #[arg(long, default_value_t = 960, value_parser = clap::value_parser!(u32).range(16..=8192))]
    pub width: u32,

    /// Image height in pixels.
    #[arg(long, default_value_t = 540, value_parser = clap::value_parser!(u32).range(16..=8192))]
    pub height: u32,

    /// Window: take a screenshot (as the S key does) into --out after this many
    /// drawn frames, then quit. For smoke tests under Xvfb.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..), conflicts_with = "headless")]
    pub screenshot_after: Option<u64>,

    /// Run the scene's solver on the GPU (wgpu compute, `sph-gpu`) instead of
    /// the CPU: PBF (a frame per submission) or WCSPH; DFSPH stays on the CPU.
    /// Extraction stays on the CPU unless --gpu-extract. Needs a GPU adapter
    /// (lavapipe will do); scenes with emitters are not supported on this path.
    #[arg(long)]
    pub gpu_sim: bool,

    /// Run the simulation and the extraction on the CPU. Without it (and
    /// without --gpu-sim or --gpu-extract), a hardware GPU adapter runs the
    /// whole GPU path: the scene's solver where it runs there (PBF, WCSPH;
    /// DFSPH and emitters stay on the CPU) and the extraction. A software
    /// adapter (lavapipe, llvmpipe) runs the CPU path.
    #[arg(long, conflicts_with_all = ["gpu_sim", "gpu_extract"])]
    pub cpu: bool,

    /// Extract the surfels on the GPU (wgpu compute, `sph-gpu`; the same
    /// field, hole closing and splits as the CPU path) and draw
    /// them without a round trip to the CPU. With --gpu-sim it reads the GPU
    /// solver's buffers.
    #[arg(long)]
    pub gpu_extract: bool,

    /// How the splats are drawn: by the raster hardware, or by compute
    /// shaders that bin them to screen tiles, past the raster hardware's
    /// blending rate. Both draw the same images. `auto` takes the faster one
    /// on the adapter: compute on a GPU, raster on a software adapter.
    #[arg(long, value_enum, default_value_t = SplatsArg::Auto)]
    pub splats: SplatsArg,

    /// Extract only the surfels facing the camera (thesis 4.2.1), about half
    /// of them; the window re-extracts as the camera turns, and surfel exports
    /// then hold only those.
    #[arg(long)]
    pub cull: bool,

    /// More log output (-v info, -vv debug, -vvv trace); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count)]
    pub verbose: u8,
}

impl Args {
    /// Whether the run chooses where it runs (no --cpu, --gpu-sim or
    /// --gpu-extract): the whole GPU path on a hardware adapter.
    pub fn gpu_by_default(&self) -> bool {
        !(self.cpu || self.gpu_sim || self.gpu_extract)
    }

    /// The surface field to extract: `--surface`, else the anisotropic one
    /// (on either path).
    pub fn surface_field(&self) -> SurfaceField {
        self.surface.unwrap_or(SurfaceField::Anisotropic)
    }
}

/// The surface field (`--surface`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SurfaceField {
    /// The thesis's colour field: one isotropic kernel per particle.
    Isotropic,
    /// Anisotropic kernels (Yu & Turk 2013) about smoothed centres.
    Anisotropic,
}

impl From<SurfaceField> for surfel_extract::Surface {
    fn from(f: SurfaceField) -> Self {
        match f {
            SurfaceField::Isotropic => Self::Isotropic,
            SurfaceField::Anisotropic => Self::anisotropic(),
        }
    }
}

/// How splats are drawn (`--splats`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SplatsArg {
    /// The adapter's faster path (`SplatPath::for_device`).
    Auto,
    /// The raster hardware: each splat a quad, blended.
    Raster,
    /// Compute shaders over screen tiles.
    Compute,
}

impl SplatsArg {
    /// The path forced on the renderer, none for `auto`.
    pub fn forced(self) -> Option<splat_render::SplatPath> {
        match self {
            SplatsArg::Auto => None,
            SplatsArg::Raster => Some(splat_render::SplatPath::Raster),
            SplatsArg::Compute => Some(splat_render::SplatPath::Compute),
        }
    }
}

/// File format of exported particles or surfels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExportFormat {
    /// Binary little-endian PLY.
    Ply,
    /// Legacy binary VTK (unstructured grid of vertices).
    Vtk,
}

impl From<ExportFormat> for sph_core::io::Format {
    fn from(f: ExportFormat) -> Self {
        match f {
            ExportFormat::Ply => Self::Ply,
            ExportFormat::Vtk => Self::Vtk,
        }
    }
}

/// A number in (0, max], or in [min, max] where `min` is given.
fn parse_in_range(s: &str, what: &str, min: Option<f64>, max: f64) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    let above = min.map_or(v > 0.0, |min| v >= min);
    match (v.is_finite() && above && v <= max, min) {
        (true, _) => Ok(v),
        (false, Some(min)) => Err(format!("{what} must lie in [{min}, {max}]")),
        (false, None) => Err(format!("{what} must be > 0 and at most {max}")),
    }
}

fn parse_solver(s: &str) -> Result<sph_core::SolverKind, String> {
    sph_core::SolverKind::from_name(s).ok_or_else(|| {
        let names: Vec<_> = sph_core::SolverKind::ALL.iter().map(|k| k.name()).collect();
        format!("unknown solver `{s}`: one of {}", names.join(", "))
    })
}

/// A length (or a multiple of one): finite and > 0, at most 1e6.
fn parse_length(s: &str) -> Result<f32, String> {
    parse_in_range(s, "the value", None, 1e6).map(|v| v as f32)
}

/// An iso value strictly between 0 and 1.
fn parse_iso(s: &str) -> Result<f32, String> {
    let v: f32 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    if v.is_finite() && v > 0.0 && v < 1.0 {
        Ok(v)
    } else {
        Err("the iso value must lie in (0, 1)".to_string())
    }
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    parse_in_range(s, "seconds", None, 3600.0)
}

/// At least one frame per simulated second: a frame is at most the 1 s a
/// scene's `frame_dt` may be.
fn parse_fps(s: &str) -> Result<f64, String> {
    parse_in_range(s, "fps", Some(1.0), 1000.0)
}

impl Args {
    /// Checks what one flag's parser cannot: --seconds makes whole frames
    /// at --fps (the run renders whole frames, and rounding 0.05 s at 30
    /// fps to 2 frames would simulate 0.067 s without a word), and --gif's
    /// --fps is at most 50 (a GIF frame lasts whole hundredths of a
    /// second, and browsers show a frame shorter than 2/100 s for 1/10 s).
    pub fn check(&self) -> Result<(), String> {
        if self.gif.is_some() && self.fps > 50.0 {
            return Err(format!(
                "--gif at --fps {}: a GIF frame lasts whole hundredths of a second, and browsers \
                 show one shorter than 2/100 s for 1/10 s, so a clip plays right at most at 50 fps",
                self.fps
            ));
        }
        let Some(s) = self.seconds.filter(|_| self.frames.is_none()) else {
            return Ok(());
        };
        let frames = s * self.fps;
        if frames < 0.999 || (frames - frames.round()).abs() > 1e-3 {
            return Err(format!(
                "--seconds {s} at --fps {} is {frames:.3} frames: give a duration of whole frames (or --frames)",
                self.fps
            ));
        }
        Ok(())
    }

    /// The flags among those `given` (clap's ids: given on the command
    /// line) that only a headless run reads: what a window would otherwise
    /// ignore. --fps counts only without --input, whose files a window
    /// plays 1/fps apart (a window steps by the scene's frame); --out is
    /// read by both (a window's screenshots).
    pub fn headless_only(&self, given: impl Fn(&str) -> bool) -> Vec<&'static str> {
        let mut flags = vec![
            ("frames", "frames"),
            ("seconds", "seconds"),
            ("gif", "gif"),
            ("export_particles", "export-particles"),
            ("export_surfels", "export-surfels"),
        ];
        if self.input.is_none() {
            flags.push(("fps", "fps"));
        }
        flags
            .into_iter()
            .filter(|(id, _)| given(id))
            .map(|(_, flag)| flag)
            .collect()
    }

    /// Frames to render headless; `files` where --input plays that many
    /// and neither --frames nor --seconds is given.
    pub fn frame_count(&self, files: Option<usize>) -> u32 {
        match (self.frames, self.seconds, files) {
            (Some(n), _, _) => n,
            (None, Some(s), _) => (s * self.fps).round().max(1.0) as u32,
            (None, None, Some(files)) => u32::try_from(files).unwrap_or(u32::MAX),
            (None, None, None) => self.fps.round().max(1.0) as u32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flags a window would ignore are named, as given on the command
    /// line (not their defaults); --fps only where no --input plays.
    #[test]
    fn headless_only_flags_are_named() {
        use clap::{CommandFactory, FromArgMatches};
        let named = |line: &[&str]| {
            let matches = Args::command().try_get_matches_from(line).unwrap();
            let args = Args::from_arg_matches(&matches).unwrap();
            args.headless_only(|id| {
                matches.value_source(id) == Some(clap::parser::ValueSource::CommandLine)
            })
        };
        assert!(named(&["sph-app"]).is_empty());
        assert!(named(&["sph-app", "--out", "shots", "--width", "640"]).is_empty());
        assert_eq!(
            named(&["sph-app", "--seconds", "2", "--fps", "10", "--gif", "a.gif"]),
            ["seconds", "gif", "fps"]
        );
        assert_eq!(
            named(&["sph-app", "--frames", "3", "--export-particles", "ply"]),
            ["frames", "export-particles"]
        );
        assert_eq!(
            named(&["sph-app", "--export-surfels", "vtk"]),
            ["export-surfels"]
        );
        let input = ["sph-app", "--input", "f_*.ply", "--particle-radius", "0.01"];
        assert!(named(&[&input[..], &["--fps", "24"]].concat()).is_empty());
    }

    #[test]
    fn arguments_parse_and_bad_ones_are_rejected() {
        let a = Args::try_parse_from(["sph-app", "--headless", "--seconds", "2", "--fps", "10"])
            .unwrap();
        assert_eq!(a.frame_count(None), 20);
        assert_eq!(a.frame_count(Some(7)), 20);
        assert!(Args::try_parse_from(["sph-app", "--iterations", "7"]).is_err());
        assert!(Args::try_parse_from(["sph-app", "--surface", "bumpy"]).is_err());
        let a = Args::try_parse_from(["sph-app"]).unwrap();
        assert_eq!(a.surface_field(), SurfaceField::Anisotropic);
        let a = Args::try_parse_from(["sph-app", "--surface", "isotropic"]).unwrap();
        assert_eq!(a.surface_field(), SurfaceField::Isotropic);
        // Where it runs: chosen (the GPU path on a hardware adapter) unless
        // a flag says; --cpu excludes the GPU flags.
        assert!(Args::try_parse_from(["sph-app"]).unwrap().gpu_by_default());
        for flag in ["--cpu", "--gpu-sim", "--gpu-extract"] {
            assert!(
                !Args::try_parse_from(["sph-app", flag])
                    .unwrap()
                    .gpu_by_default()
            );
        }
        assert!(Args::try_parse_from(["sph-app", "--cpu", "--gpu-sim"]).is_err());
        assert!(Args::try_parse_from(["sph-app", "--cpu", "--gpu-extract"]).is_err());
        // The GPU extracts the anisotropic field too: the default there as well.
        let a = Args::try_parse_from(["sph-app", "--gpu-extract"]).unwrap();
        assert_eq!(a.surface_field(), SurfaceField::Anisotropic);
        let a =
            Args::try_parse_from(["sph-app", "--gpu-extract", "--surface", "isotropic"]).unwrap();
        assert_eq!(a.surface_field(), SurfaceField::Isotropic);
        assert!(Args::try_parse_from(["sph-app", "--fps", "-1"]).is_err());
        // Frames of more than 1 s of simulation would run for hours.
        assert!(Args::try_parse_from(["sph-app", "--fps", "0.0001"]).is_err());
        assert!(Args::try_parse_from(["sph-app", "--fps", "1"]).is_ok());
        // Flags of another mode are refused, not ignored.
        for args in [
            &["sph-app", "--particle-radius", "0.01"][..],
            &["sph-app", "--smoothing-length", "3"],
            &["sph-app", "--headless", "--screenshot-after", "3"],
        ] {
            assert!(Args::try_parse_from(args).is_err(), "{args:?}");
        }
        // A duration of whole frames, or an error saying how many it is.
        let timed = |s: &str, fps: &str| {
            let args = ["sph-app", "--headless", "--seconds", s, "--fps", fps];
            Args::try_parse_from(args).unwrap().check()
        };
        assert_eq!(timed("3", "15"), Ok(()));
        assert_eq!(timed("0.1", "30"), Ok(()));
        let e = timed("0.05", "30").unwrap_err();
        assert!(e.contains("1.500 frames"), "{e}");
        assert!(timed("0.01", "30").is_err());
        let input = ["sph-app", "--input", "f.vtk", "--particle-radius", "0.01"];
        assert!(Args::try_parse_from(input).is_ok());
        assert!(Args::try_parse_from(["sph-app", "--frames", "3", "--seconds", "1"]).is_err());
        assert!(Args::try_parse_from(["sph-app", "--threads", "0"]).is_err());
        let a = Args::try_parse_from(["sph-app", "--solver", "wcsph"]).unwrap();
        assert_eq!(a.solver, Some(sph_core::SolverKind::Wcsph));
        let e = Args::try_parse_from(["sph-app", "--solver", "sph"]).unwrap_err();
        assert!(e.to_string().contains("one of wcsph, pbf"), "{e}");
        // --input: a radius, no scene or solver of its own.
        let a = Args::try_parse_from(["sph-app", "--input", "a.vtk", "--particle-radius", "0.01"])
            .unwrap();
        assert_eq!(a.frame_count(Some(7)), 7);
        assert!(Args::try_parse_from(["sph-app", "--input", "a.vtk"]).is_err());
        for conflict in [["--scene", "drop"], ["--solver", "pbf"]] {
            let mut line = vec!["sph-app", "--input", "a.vtk", "--particle-radius", "0.01"];
            line.extend(conflict);
            assert!(Args::try_parse_from(line).is_err(), "{conflict:?}");
        }
        for bad in ["0", "-1", "nan", "inf"] {
            let line = ["sph-app", "--input", "a.vtk", "--particle-radius", bad];
            assert!(Args::try_parse_from(line).is_err(), "{bad}");
        }
        assert_eq!(Args::try_parse_from(["sph-app"]).unwrap().iso, 0.5);
        assert_eq!(
            Args::try_parse_from(["sph-app", "--iso", "0.3"])
                .unwrap()
                .iso,
            0.3
        );
        for bad in ["0", "1", "-0.2", "nan", "x"] {
            assert!(
                Args::try_parse_from(["sph-app", "--iso", bad]).is_err(),
                "{bad}"
            );
        }
    }
}
