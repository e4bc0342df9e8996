//! Particle files for anyone, by extension: this project's PLY and VTK
//! frames with their attributes and simulated time ([`super::write_ply`],
//! [`super::write_vtk`]), and positions in the formats other tools read
//! (what [`super::read_particles`] reads back): XYZ (`xyz.rs`), and with
//! the `readers` feature VTU (`vtu.rs`) and BGEO (`bgeo.rs`).
//!
//! A file is written in memory by the format's writer, then to disk in one
//! checked write and flush: a full disk or an unwritable path is an error
//! naming the file, never a short file without a word.

use std::io::Write;
use std::path::Path;

use super::{PointCloud, known_extension, write_ply, write_vtk};
use crate::error::{Error, Result};

/// The extensions [`write_particles`] takes (lower case, without the dot).
pub const WRITE_EXTENSIONS: [&str; 5] = ["ply", "vtk", "xyz", "vtu", "bgeo"];

/// Writes `cloud` to the file at `path`, its format from its extension (any
/// of [`WRITE_EXTENSIONS`], in any case): PLY and VTK with every attribute
/// and the simulated `time` (0 when `None`), XYZ, VTU and BGEO with the
/// positions alone.
///
/// # Errors
/// [`Error::InvalidParameter`] naming the file: an extension not among
/// those (`format`), attributes for a format that holds positions only,
/// rather than dropping them (`format`), a non-finite position
/// (`positions`) or attribute value (the attribute's name), a non-finite
/// `time`, or a time for a format that holds none (`time`); [`Error::Io`]
/// naming the file: a format that needs the
/// `readers` feature without it, or a write that failed.
pub fn write_particles(
    path: impl AsRef<Path>,
    cloud: &PointCloud,
    time: Option<f64>,
) -> Result<()> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let fail = |reason: String| Error::Io {
        path: name.clone(),
        reason,
    };
    let extension =
        known_extension(path, &WRITE_EXTENSIONS).ok_or_else(|| Error::InvalidParameter {
            name: "format",
            value: name.clone(),
            reason: "the file name must end in .ply, .vtk, .xyz, .vtu or .bgeo",
        })?;
    if let Some(i) = cloud.positions.iter().position(|x| !x.is_finite()) {
        return Err(Error::InvalidParameter {
            name: "positions",
            value: format!("{} at row {i} for {name}", cloud.positions[i]),
            reason: "every position must be finite",
        });
    }
    let vectors = cloud.vectors.iter().map(|(n, v)| {
        let bad = v.iter().position(|x| !x.is_finite());
        (*n, bad.map(|i| (i, v[i].to_string())))
    });
    let scalars = cloud.scalars.iter().map(|(n, s)| {
        let bad = s.iter().position(|x| !x.is_finite());
        (*n, bad.map(|i| (i, s[i].to_string())))
    });
    for (attribute, bad) in vectors.chain(scalars) {
        if let Some((i, value)) = bad {
            return Err(Error::InvalidParameter {
                name: "point attribute",
                value: format!("{attribute} {value} at row {i} for {name}"),
                reason: "every value must be finite",
            });
        }
    }
    let positions_only = !matches!(extension.as_str(), "ply" | "vtk");
    let bad_time = |t: f64, reason| Error::InvalidParameter {
        name: "time",
        value: format!("{t} for {name}"),
        reason,
    };
    match time {
        Some(t) if !t.is_finite() => return Err(bad_time(t, "must be finite")),
        Some(t) if positions_only => {
            return Err(bad_time(
                t,
                "a .xyz, .vtu or .bgeo file records no time: write it to .ply or .vtk",
            ));
        }
        _ => {}
    }
    let time = time.unwrap_or(0.0);
    if positions_only && !(cloud.vectors.is_empty() && cloud.scalars.is_empty()) {
        let names: Vec<&str> = (cloud.vectors.iter().map(|(n, _)| *n))
            .chain(cloud.scalars.iter().map(|(n, _)| *n))
            .collect();
        return Err(Error::InvalidParameter {
            name: "format",
            value: format!("{name} with {}", names.join(", ")),
            reason: "a .xyz, .vtu or .bgeo file holds positions only: write attributes to .ply or .vtk",
        });
    }
    let mut bytes = Vec::new();
    match extension.as_str() {
        "ply" => write_ply(&mut bytes, cloud, time)?,
        "vtk" => write_vtk(&mut bytes, cloud, time)?,
        "xyz" => super::xyz::write_xyz(&mut bytes, cloud.positions),
        "vtu" => super::vtu::write_vtu(&mut bytes, cloud.positions).map_err(fail)?,
        "bgeo" => super::bgeo::write_bgeo(&mut bytes, cloud.positions).map_err(fail)?,
        _ => unreachable!("an extension of WRITE_EXTENSIONS"),
    }
    let mut file = std::fs::File::create(path).map_err(|e| fail(e.to_string()))?;
    file.write_all(&bytes)
        .and_then(|()| file.flush())
        .map_err(|e| fail(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("sph-core-write-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    /// Every format's file reads back as the positions written (and PLY and
    /// VTK with their time).
    #[test]
    fn every_format_reads_back() {
        let positions: Vec<Vec3> = (0..50)
            .map(|i| {
                Vec3::new(
                    i as f32 * 0.01,
                    (i % 7) as f32 * -0.3,
                    1e-3 * (i * i) as f32,
                )
            })
            .collect();
        let cloud = PointCloud {
            positions: &positions,
            ..Default::default()
        };
        let formats: &[&str] = if cfg!(feature = "readers") {
            &WRITE_EXTENSIONS
        } else {
            &["ply", "vtk"]
        };
        for ext in formats {
            let path = scratch(&format!("round.{ext}"));
            write_particles(&path, &cloud, matches!(*ext, "ply" | "vtk").then_some(0.25)).unwrap();
            let back = super::super::read_particles(&path).unwrap();
            assert_eq!(back.positions, positions, "{ext}");
            let time = matches!(*ext, "ply" | "vtk").then_some(0.25);
            assert_eq!(back.time, time, "{ext}");
        }
    }

    /// Attributes a format cannot hold, NaN and unknown extensions are
    /// errors naming the file; so is a write to a full device.
    #[test]
    fn bad_writes_are_errors_naming_the_file() {
        let positions = vec![Vec3::ONE; 3];
        let velocities = vec![Vec3::X; 3];
        let mut cloud = PointCloud {
            positions: &positions,
            ..Default::default()
        };
        cloud.vectors.push(("velocity", &velocities));
        let e = write_particles(scratch("v.xyz"), &cloud, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("v.xyz") && e.contains("velocity") && e.contains("positions only"),
            "{e}"
        );
        let e = write_particles(scratch("v.obj"), &cloud, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("v.obj") && e.contains(".ply"), "{e}");
        let nan = vec![Vec3::new(0.0, f32::NAN, 0.0)];
        let e = write_particles(
            scratch("nan.ply"),
            &PointCloud {
                positions: &nan,
                ..Default::default()
            },
            None,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("nan.ply") && e.contains("finite"), "{e}");
        // NaN in an attribute or the time, as in a position.
        let nan_density = vec![1000.0, f32::NAN, 1000.0];
        let mut dense = PointCloud {
            positions: &positions,
            ..Default::default()
        };
        dense.scalars.push(("density", &nan_density));
        let e = write_particles(scratch("d.ply"), &dense, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("density") && e.contains("row 1") && e.contains("finite"),
            "{e}"
        );
        let plain = PointCloud {
            positions: &positions,
            ..Default::default()
        };
        let e = write_particles(scratch("t.ply"), &plain, Some(f64::NAN))
            .unwrap_err()
            .to_string();
        assert!(e.contains("time") && e.contains("finite"), "{e}");
        let e = write_particles(scratch("t.xyz"), &plain, Some(0.5))
            .unwrap_err()
            .to_string();
        assert!(e.contains("time") && e.contains("records no time"), "{e}");
        if std::path::Path::new("/dev/full").exists() {
            // /dev/full takes no extension: a link to it that has one.
            let link = scratch("full.xyz");
            let _ = std::fs::remove_file(&link);
            std::os::unix::fs::symlink("/dev/full", &link).unwrap();
            let plain = PointCloud {
                positions: &positions,
                ..Default::default()
            };
            let e = write_particles(&link, &plain, None)
                .unwrap_err()
                .to_string();
            assert!(e.contains("full.xyz"), "{e}");
        }
    }
}
