//! Particle files from anywhere, by extension: this project's PLY and VTK
//! frames with their simulated time ([`super::read_ply`],
//! [`super::read_vtk`]), and, with the `readers` feature, what other
//! simulators write (SPlisHSPlasH, DualSPHysics, Houdini, splashsurf's test
//! data): legacy VTK and VTU, PLY, XYZ (binary f32 triples), BGEO and
//! splashsurf's JSON, read by splashsurf_lib's readers. Only positions are
//! read from those; they carry no time.

use std::path::Path;

use glam::Vec3;

use super::{LoadedCloud, known_extension, read_ply, read_vtk};
use crate::error::{Error, Result};

/// The particles of one file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParticleFile {
    /// Positions.
    pub positions: Vec<Vec3>,
    /// The simulated time the file records (this project's frames), if any.
    pub time: Option<f64>,
}

/// The extensions [`read_particles`] takes (lower case, without the dot).
pub const PARTICLE_EXTENSIONS: [&str; 6] = ["ply", "vtk", "vtu", "xyz", "bgeo", "json"];

/// Reads the particle positions of the file at `path`, its format from its
/// extension (any of [`PARTICLE_EXTENSIONS`], in any case).
///
/// # Errors
/// [`Error::Io`] naming the file: it cannot be read, its extension is not
/// one of those, it is not a particle file of that format, or a position is
/// not finite; other simulators' formats without the `readers` feature.
pub fn read_particles(path: impl AsRef<Path>) -> Result<ParticleFile> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let fail = |reason: String| Error::Io {
        path: name.clone(),
        reason,
    };
    let extension = known_extension(path, &PARTICLE_EXTENSIONS).ok_or_else(|| {
        fail(format!(
            "not a particle file: the name must end in .{}",
            PARTICLE_EXTENSIONS.join(", .")
        ))
    })?;
    // This project's own frames first (they carry the time), then anyone's.
    let own: Option<fn(std::io::BufReader<std::fs::File>) -> Result<LoadedCloud>> =
        match extension.as_str() {
            "ply" => Some(read_ply),
            "vtk" => Some(read_vtk),
            _ => None,
        };
    let own_error = match own {
        Some(read) => {
            let file = std::fs::File::open(path).map_err(|e| fail(e.to_string()))?;
            match read(std::io::BufReader::new(file)) {
                Ok(cloud) => {
                    return finite(ParticleFile {
                        positions: cloud.positions,
                        time: cloud.time,
                    })
                    .map_err(fail);
                }
                Err(e) => Some(e.to_string()),
            }
        }
        None => None,
    };
    let positions = foreign(path, &extension).map_err(|reason| match &own_error {
        Some(own) => fail(format!(
            "{reason}; as this project's own {extension}: {own}"
        )),
        None => fail(reason),
    })?;
    finite(ParticleFile {
        positions,
        time: None,
    })
    .map_err(fail)
}

/// Every position is finite.
fn finite(file: ParticleFile) -> std::result::Result<ParticleFile, String> {
    match file.positions.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(format!(
            "particle {i} is at {}, not finite",
            file.positions[i]
        )),
        None => Ok(file),
    }
}

/// Positions by splashsurf_lib's readers. A reader that panics on a
/// malformed file (BGEO's parser on a truncated one, some readers' asserts)
/// is reported as an error, without the panic's message.
#[cfg(feature = "readers")]
fn foreign(path: &Path, extension: &str) -> std::result::Result<Vec<Vec3>, String> {
    sizes_fit(path, extension)?;
    let read = || splashsurf_lib::io::particles_from_file::<f32, _>(path);
    match quietly(read) {
        Ok(Ok(points)) => Ok(points.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect()),
        // One line: some readers' messages hold newlines and tabs.
        Ok(Err(e)) => Err(format!("{e:#}")
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")),
        Err(_) => Err("the reader failed on a malformed or truncated file".to_string()),
    }
}

/// What splashsurf_lib's readers would take on trust, checked first: an XYZ
/// file's length is a whole number of points (its reader stops silently at
/// the first short read, dropping a ragged tail), and a BGEO file's header
/// claims no more points than its bytes hold ([`super::bgeo`]).
#[cfg(feature = "readers")]
fn sizes_fit(path: &Path, extension: &str) -> std::result::Result<(), String> {
    use std::io::Read;
    match extension {
        "xyz" => {
            let len = std::fs::metadata(path).map_err(|e| e.to_string())?.len();
            if len % 12 != 0 {
                return Err(format!(
                    "{len} bytes are not whole points of three f32 (12 bytes each)"
                ));
            }
        }
        "bgeo" => {
            let mut bytes = std::fs::read(path).map_err(|e| e.to_string())?;
            if bytes.starts_with(&[0x1f, 0x8b]) {
                let mut unzipped = Vec::new();
                flate2::read::GzDecoder::new(&bytes[..])
                    .read_to_end(&mut unzipped)
                    .map_err(|e| format!("gzip: {e}"))?;
                bytes = unzipped;
            }
            super::bgeo::check_bgeo_counts(&bytes)?;
        }
        _ => {}
    }
    Ok(())
}

/// `f`, its panic caught and not printed. The panic hook is wrapped once,
/// per process: it stays silent on this thread while `f` runs and passes
/// every other panic to the hook it found.
#[cfg(feature = "readers")]
fn quietly<T>(f: impl FnOnce() -> T + std::panic::UnwindSafe) -> std::thread::Result<T> {
    use std::cell::Cell;
    thread_local! {
        static QUIET: Cell<bool> = const { Cell::new(false) };
    }
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(Cell::get) {
                previous(info);
            }
        }));
    });
    QUIET.with(|q| q.set(true));
    let result = std::panic::catch_unwind(f);
    QUIET.with(|q| q.set(false));
    result
}

#[cfg(not(feature = "readers"))]
fn foreign(_: &Path, _: &str) -> std::result::Result<Vec<Vec3>, String> {
    Err("other simulators' files need sph-core's `readers` feature".to_string())
}

#[cfg(all(test, feature = "readers"))]
mod tests {
    use super::*;
    use crate::io::{PointCloud, write_particles};

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("sph-core-read-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    fn refused(path: &Path, words: &[&str]) {
        let e = read_particles(path).unwrap_err().to_string();
        for w in words {
            assert!(e.contains(w), "`{e}` lacks `{w}`");
        }
    }

    /// A BGEO header claiming more points than its file holds (plain or
    /// gzipped, or a negative count) is an error, where splashsurf_lib's
    /// parser allocated the claim and aborted the process; an XYZ file of a
    /// ragged length is an error, where its reader dropped the tail.
    #[test]
    fn files_whose_sizes_lie_are_errors_not_aborts() {
        use std::io::Write;
        let positions = vec![Vec3::new(0.1, 0.2, 0.3); 3];
        let cloud = PointCloud {
            positions: &positions,
            ..Default::default()
        };
        let good = scratch("good.bgeo");
        write_particles(&good, &cloud, None).unwrap();
        assert_eq!(read_particles(&good).unwrap().positions, positions);
        let bytes = std::fs::read(&good).unwrap();
        assert_eq!(i32::from_be_bytes(bytes[9..13].try_into().unwrap()), 3);
        for (name, points) in [("huge.bgeo", i32::MAX), ("negative.bgeo", -1)] {
            let mut lying = bytes.clone();
            lying[9..13].copy_from_slice(&points.to_be_bytes());
            let path = scratch(name);
            std::fs::write(&path, &lying).unwrap();
            refused(&path, &[name, "claims", &points.to_string()]);
            let mut zipped = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            zipped.write_all(&lying).unwrap();
            let path = scratch(&format!("zipped-{name}"));
            std::fs::write(&path, zipped.finish().unwrap()).unwrap();
            refused(&path, &["claims"]);
        }
        let ragged = scratch("ragged.xyz");
        std::fs::write(&ragged, [0u8; 14]).unwrap();
        refused(&ragged, &["ragged.xyz", "14 bytes", "12 bytes"]);
        let whole = scratch("whole.xyz");
        std::fs::write(&whole, [0u8; 24]).unwrap();
        assert_eq!(
            read_particles(&whole).unwrap().positions,
            vec![Vec3::ZERO; 2]
        );
    }
}
