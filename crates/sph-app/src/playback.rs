//! Particle files played back instead of a simulation (`--input`): a
//! sequence of files from any simulator ([`sph_core::io::read_particles`]),
//! read one per frame in natural order (`p_2` before `p_10`), shown as the
//! demo shows its own particles.
//!
//! The particles get the volume of a cube one particle diameter wide (mass
//! ρ0 (2r)³ at rest density), and the extraction the smoothing length of
//! `--smoothing-length` times r, as splashsurf takes them: its compact
//! support 2 L r is this project's h, 4r by default, as the built-in scenes
//! have (h = 2 spacings).

use std::path::{Path, PathBuf};

use glam::Vec3;
use sph_core::io::{ParticleFile, read_particles};
use sph_core::{Particles, Scene};

use crate::error::AppError;

/// The rest density given to the particles read (kg/m³): water's. It sets
/// only their masses, which the extraction divides back out.
const REST_DENSITY: f32 = 1000.0;

/// The files of a playback, and where it is.
#[derive(Debug, Clone)]
pub struct Playback {
    files: Vec<PathBuf>,
    /// The next file's index.
    next: usize,
    mass: f32,
    /// Frame time (s) for files that record none.
    frame_dt: f64,
}

impl Playback {
    /// The files matching `pattern` (a path or a glob such as
    /// `sim/particles_*.bgeo`), with particles of radius `radius` (m) and
    /// the extraction's h = 2 `smoothing_length` `radius`; files without a
    /// time are `frame_dt` apart. Returns the playback, a scene for the
    /// pipeline (its domain and camera framing the first file's particles)
    /// and those particles.
    ///
    /// # Errors
    /// [`AppError::Input`]: a bad pattern, no file, a radius or smoothing
    /// length that is not positive and finite, or a first file that cannot
    /// be read or holds no particle.
    pub fn open(
        pattern: &str,
        radius: f32,
        smoothing_length: f32,
        frame_dt: f64,
    ) -> Result<(Self, Scene, Particles), AppError> {
        let bad = |reason: String| AppError::Input {
            input: pattern.to_string(),
            reason,
        };
        for (name, value) in [
            ("--particle-radius", radius),
            ("--smoothing-length", smoothing_length),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(bad(format!("{name} {value} must be a positive number")));
            }
        }
        let paths = glob::glob(pattern).map_err(|e| bad(format!("not a valid pattern: {e}")))?;
        let mut files = Vec::new();
        for path in paths {
            let path = path.map_err(|e| bad(e.to_string()))?;
            if path.is_file() {
                files.push(path);
            }
        }
        if files.is_empty() {
            return Err(bad("no file matches it".to_string()));
        }
        files.sort_by_key(|p| natural_key(p));
        let missing = gaps(&files);
        if !missing.is_empty() {
            let list: Vec<String> = (missing.iter().take(5))
                .map(|(a, b)| format!("between {a} and {b}"))
                .collect();
            let more = missing.len().saturating_sub(5);
            let message = format!(
                "warning: --input `{pattern}`: frames missing from the sequence {}{}",
                list.join(", "),
                if more > 0 {
                    format!(" and {more} more gaps")
                } else {
                    String::new()
                }
            );
            eprintln!("{message}");
            log::warn!("{message}");
        }
        let spacing = 2.0 * radius;
        let playback = Self {
            files,
            next: 0,
            mass: REST_DENSITY * spacing.powi(3),
            frame_dt,
        };
        let (first, particles) = playback.load(0)?;
        let h = 2.0 * smoothing_length * radius;
        let scene = scene_around(&first.positions, spacing, h, pattern)?;
        // The first frame plays the first file again: a headless run
        // advances before each frame it writes.
        Ok((playback, scene, particles))
    }

    /// The number of files.
    pub fn len(&self) -> usize {
        self.files.len()
    }

    /// Back to the first file.
    pub fn rewind(&mut self) {
        self.next = 0;
    }

    /// The next file's particles and its time (the file's own, else its
    /// index times the frame time); after the last file, the first again.
    ///
    /// # Errors
    /// [`AppError::Input`] for a file that cannot be read.
    pub fn next_frame(&mut self) -> Result<(Particles, f64), AppError> {
        let index = self.next;
        let (file, particles) = self.load(index)?;
        self.next = (index + 1) % self.files.len();
        Ok((particles, file.time.unwrap_or(index as f64 * self.frame_dt)))
    }

    /// File `index` and its particles: at rest, at rest density.
    fn load(&self, index: usize) -> Result<(ParticleFile, Particles), AppError> {
        let path = &self.files[index];
        let file = read_particles(path).map_err(|e| AppError::Input {
            input: path.display().to_string(),
            reason: e.to_string(),
        })?;
        if file.positions.is_empty() {
            return Err(AppError::Input {
                input: path.display().to_string(),
                reason: "holds no particle".to_string(),
            });
        }
        let mut particles = Particles::new();
        for &x in &file.positions {
            particles.push(x, Vec3::ZERO, self.mass);
        }
        particles.densities_mut().fill(REST_DENSITY);
        Ok((file, particles))
    }
}

/// A scene for particles at `positions`: its domain their bounds grown by
/// h (downwards by a particle radius, so that the ground it draws is under
/// them), the camera framing them, no blocks.
fn scene_around(positions: &[Vec3], spacing: f32, h: f32, name: &str) -> Result<Scene, AppError> {
    let (min, max) = positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
    // The floor just under the lowest particle (the ground is drawn there),
    // h of room on every other side.
    let (min, max) = (min - Vec3::new(h, 0.5 * spacing, h), max + h);
    let mut scene = Scene::empty(name, min, max, spacing);
    scene.fluid.h = h;
    let ratio = h / spacing;
    if ratio < 1.0 {
        return Err(AppError::Input {
            input: name.to_string(),
            reason: format!(
                "--smoothing-length gives h = {ratio} particle diameters, less than 1: \
                 particles on their lattice would not reach their neighbours"
            ),
        });
    }
    if ratio > sph_core::solver::MAX_H_OVER_SPACING {
        return Err(AppError::Input {
            input: name.to_string(),
            reason: format!(
                "--smoothing-length gives h = {ratio} particle diameters, more than {}: \
                 each particle would have thousands of neighbours",
                sph_core::solver::MAX_H_OVER_SPACING
            ),
        });
    }
    Ok(scene)
}

/// The gaps in a sorted sequence of numbered files: neighbouring frame
/// numbers further apart than the sequence's usual step (its smallest), so
/// that every tenth frame exported is no gap but a lost file is. The frame
/// number is the first run of digits in the file names that differs
/// between them (`frame_01_4732_particles`: the 01).
fn gaps(files: &[PathBuf]) -> Vec<(u64, u64)> {
    let runs: Vec<Vec<u64>> = (files.iter())
        .map(|p| {
            let name = p.file_name().map(Path::new).unwrap_or(p);
            let key = natural_key(name);
            key[..key.len() - 1].iter().map(|&(_, n)| n).collect()
        })
        .collect();
    let count = runs[0].len();
    if runs.iter().any(|r| r.len() != count) {
        return Vec::new();
    }
    let Some(at) = (0..count).find(|&k| runs.iter().any(|r| r[k] != runs[0][k])) else {
        return Vec::new();
    };
    let numbers: Vec<u64> = runs.iter().map(|r| r[at]).collect();
    let steps = numbers.windows(2).map(|w| w[1].saturating_sub(w[0]));
    let Some(step) = steps.filter(|&d| d > 0).min() else {
        return Vec::new();
    };
    (numbers.windows(2))
        .filter(|w| w[1].saturating_sub(w[0]) > step)
        .map(|w| (w[0], w[1]))
        .collect()
}

/// The file name split into text and numbers, so that `p_2` sorts before
/// `p_10`.
fn natural_key(path: &Path) -> Vec<(String, u64)> {
    let name = path.to_string_lossy();
    let mut key = Vec::new();
    let (mut text, mut digits) = (String::new(), String::new());
    for c in name.chars() {
        if c.is_ascii_digit() {
            digits.push(c);
        } else {
            if !digits.is_empty() {
                key.push((
                    std::mem::take(&mut text),
                    digits.parse().unwrap_or(u64::MAX),
                ));
                digits.clear();
            }
            text.push(c);
        }
    }
    key.push((text, digits.parse().unwrap_or(0)));
    key
}

#[cfg(test)]
mod tests {
    use splat_render::{GpuContext, SplatRenderer};
    use surfel_extract::{ColourField, Surface, coverage};

    use super::*;
    use crate::pipeline::Pipeline;

    /// splashsurf's test data (SPlisHSPlasH's frames, MIT): the double dam
    /// break's two VTK frames and a BGEO dam break, each played as the demo
    /// does (anisotropic surface, 2
    /// iterations). Each keeps every particle, extracts its measured surfel
    /// count (within 2 %), covers the field's iso-surface (rays 0.2 h apart,
    /// within 0.1 h of a disc: ≥ 99 %), and draws as its golden
    /// (`tests/golden/input-*.png`, 240×135, FLIP mean ≤ 0.02).
    #[test]
    fn splashsurf_data_extracts_covers_and_renders_as_its_goldens() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/splashsurf");
        let cases = [
            (
                "double_dam_break_frame_01_4732_particles.vtk",
                0.025,
                4732,
                15_252,
            ),
            (
                "double_dam_break_frame_26_4732_particles.vtk",
                0.025,
                4732,
                162_493,
            ),
            ("dam_break_frame_9_6859_particles.bgeo", 0.025, 6859, 26_671),
        ];
        let ctx = GpuContext::headless_or_skip();
        for (file, radius, particles, surfels) in cases {
            let path = dir.join(file);
            let (playback, scene, first) =
                Playback::open(path.to_str().unwrap(), radius, 2.0, 1.0 / 30.0).unwrap();
            let mut pipeline = Pipeline::playback(file.into(), scene, first, playback, 2).unwrap();
            pipeline.extract.surface = Surface::anisotropic();
            pipeline.extract_surfels().unwrap();
            let found = pipeline.surfels_on_cpu().unwrap().len();
            let h = pipeline.extract.h;
            let mut field = ColourField::new(pipeline.extract.surface).unwrap();
            field
                .refill_from_particles(&pipeline.world.particles, h)
                .unwrap();
            let points = coverage::iso_points(&field, pipeline.extract.iso, 0.2 * h).unwrap();
            let surfel_list = pipeline.surfels_on_cpu().unwrap();
            let covered = coverage::covered_fraction(&surfel_list, &points, 0.1 * h).unwrap();
            println!(
                "{file}: {} particles, {found} surfels, {:.2} % of {} iso points covered",
                pipeline.world.particles.len(),
                100.0 * covered,
                points.len()
            );
            assert_eq!(pipeline.world.particles.len(), particles, "{file}");
            let ratio = found as f64 / surfels as f64;
            assert!((ratio - 1.0).abs() <= 0.02, "{file}: {found} surfels");
            assert!(covered >= 0.99, "{file}: {covered}");
            let Some(ctx) = ctx else { continue };
            let mut renderer = SplatRenderer::new(ctx, 240, 135, &crate::environment()).unwrap();
            renderer
                .set_geometry(ctx, &pipeline.scenery().unwrap())
                .unwrap();
            pipeline.show_surfels(ctx, &mut renderer).unwrap();
            renderer
                .render(ctx, &pipeline.camera(), &pipeline.shading())
                .unwrap();
            let image = renderer.read_image(ctx).unwrap();
            let stem = file.split("_particles").next().unwrap_or(file);
            let name = format!("input-{}", stem.replace('_', "-"));
            let mean = crate::golden::against(&name, &image, 0.02);
            println!("{file}: FLIP mean vs golden {mean:.4}");
            assert!(mean <= 0.02, "{file}: FLIP mean {mean} against its golden");
        }
    }

    #[test]
    fn numbered_files_sort_by_their_numbers() {
        let mut names = ["p_10.bgeo", "p_2.bgeo", "p_1.bgeo", "q_0.bgeo"].map(PathBuf::from);
        names.sort_by_key(|p| natural_key(p));
        assert_eq!(
            names.map(|p| p.display().to_string()),
            ["p_1.bgeo", "p_2.bgeo", "p_10.bgeo", "q_0.bgeo"]
        );
    }

    #[test]
    fn lost_frames_are_gaps_and_a_stride_is_not() {
        let files = |names: &[&str]| names.iter().map(PathBuf::from).collect::<Vec<_>>();
        let sequence = files(&[
            "d/f_1_99.vtk",
            "d/f_2_99.vtk",
            "d/f_4_99.vtk",
            "d/f_5_99.vtk",
        ]);
        assert_eq!(gaps(&sequence), [(2, 4)]);
        let stride = files(&["f_0.vtk", "f_10.vtk", "f_20.vtk"]);
        assert!(gaps(&stride).is_empty());
        let lost = files(&["f_0.vtk", "f_10.vtk", "f_30.vtk", "f_40.vtk"]);
        assert_eq!(gaps(&lost), [(10, 30)]);
        assert!(gaps(&files(&["a.vtk"])).is_empty());
        assert!(gaps(&files(&["a.vtk", "b_1.vtk"])).is_empty());
    }
}
