//! Particle and point files, one module per format, beside the frame writer:
//! [`PointCloud`]s written as binary PLY ([`write_ply`]) or legacy binary VTK
//! ([`write_vtk`]), each frame stamped with its simulated time, read back by
//! [`read_ply`] and [`read_vtk`] (what these writers write, not arbitrary
//! files: for tests and tools), and a [`FrameWriter`] that writes numbered
//! frames plus a CSV index (`{prefix}_index.csv`: frame, time, points, file).
//! [`read_particles`] reads any particle file by its extension, other
//! simulators' with the `readers` feature (splashsurf_lib's readers), and
//! [`write_particles`] writes one (XYZ; VTU and BGEO with that feature).
//!
//! Both formats are read by ParaView, Blender (PLY) and splashsurf (PLY,
//! VTK). Every writer flushes and reports a failed write as [`Error::Io`]
//! ([`FrameWriter`]'s naming the file).

use std::io::{BufRead, Read, Write};

use glam::Vec3;

use crate::error::{Error, Result};
use crate::particles::Particles;

mod bgeo;
mod frames;
mod ply;
mod read;
mod vtk;
mod vtu;
mod write;
mod xyz;

pub use frames::FrameWriter;
pub use ply::{read_ply, write_ply};
pub use read::{PARTICLE_EXTENSIONS, ParticleFile, read_particles};
pub use vtk::{read_vtk, write_vtk};
pub use write::{WRITE_EXTENSIONS, write_particles};

/// A set of points with named per-point attributes, borrowed from their owner.
#[derive(Debug, Clone, Default)]
pub struct PointCloud<'a> {
    /// Positions.
    pub positions: &'a [Vec3],
    /// Named 3-vectors per point (e.g. `velocity`, `normal`).
    pub vectors: Vec<(&'a str, &'a [Vec3])>,
    /// Named scalars per point (e.g. `density`, `radius`).
    pub scalars: Vec<(&'a str, &'a [f32])>,
}

impl<'a> PointCloud<'a> {
    /// Particles with velocity, density and pressure.
    pub fn from_particles(p: &'a Particles) -> Self {
        Self {
            positions: p.positions(),
            vectors: vec![("velocity", p.velocities())],
            scalars: vec![("density", p.densities()), ("pressure", p.pressures())],
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Every attribute has one value per point and every name is a plain word.
    fn check(&self) -> Result<()> {
        let n = self.positions.len();
        let names = self.vectors.iter().map(|(s, v)| (*s, v.len()));
        let names = names.chain(self.scalars.iter().map(|(s, v)| (*s, v.len())));
        for (name, len) in names {
            if len != n {
                return Err(Error::InvalidParameter {
                    name: "point attribute",
                    value: format!("{name} ({len} values for {n} points)"),
                    reason: "needs one value per point",
                });
            }
            if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                return Err(Error::InvalidParameter {
                    name: "attribute name",
                    value: name.to_string(),
                    reason: "must be a non-empty word of ASCII letters, digits and _",
                });
            }
        }
        Ok(())
    }
}

/// File format of an exported frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Binary little-endian PLY.
    Ply,
    /// Legacy binary VTK unstructured grid of vertex cells.
    Vtk,
}

impl Format {
    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Ply => "ply",
            Format::Vtk => "vtk",
        }
    }

    /// Writes `cloud` at simulated `time` in this format.
    pub fn write(self, w: impl Write, cloud: &PointCloud, time: f64) -> Result<()> {
        match self {
            Format::Ply => write_ply(w, cloud, time),
            Format::Vtk => write_vtk(w, cloud, time),
        }
    }
}

impl std::str::FromStr for Format {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "ply" => Ok(Format::Ply),
            "vtk" => Ok(Format::Vtk),
            _ => Err(Error::InvalidParameter {
                name: "format",
                value: s.to_string(),
                reason: "must be `ply` or `vtk`",
            }),
        }
    }
}

/// `path`'s extension in lower case, when it is one of `known`.
fn known_extension(path: &std::path::Path, known: &[&str]) -> Option<String> {
    (path.extension().and_then(|e| e.to_str()))
        .map(str::to_ascii_lowercase)
        .filter(|e| known.contains(&e.as_str()))
}

fn io_err(path: &str, e: std::io::Error) -> Error {
    Error::Io {
        path: path.to_string(),
        reason: e.to_string(),
    }
}

/// The per-vector component names: `normal` → `nx ny nz` and `velocity` →
/// `vx vy vz` as Blender and splashsurf expect, else `name_x name_y name_z`.
fn components(name: &str) -> [String; 3] {
    let prefix = match name {
        "normal" => "n".to_string(),
        "velocity" => "v".to_string(),
        _ => format!("{name}_"),
    };
    ["x", "y", "z"].map(|a| format!("{prefix}{a}"))
}

/// A point cloud read back from a file: owned attributes and the frame time.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadedCloud {
    /// The simulated time the file records: this project's frames carry
    /// it, other programs' files may not (`None`, not 0).
    pub time: Option<f64>,
    /// Positions.
    pub positions: Vec<Vec3>,
    /// Named vectors, in file order.
    pub vectors: Vec<(String, Vec<Vec3>)>,
    /// Named scalars, in file order.
    pub scalars: Vec<(String, Vec<f32>)>,
}

impl LoadedCloud {
    /// The vector attribute called `name`.
    pub fn vector(&self, name: &str) -> Option<&[Vec3]> {
        let found = self.vectors.iter().find(|(n, _)| n == name);
        found.map(|(_, v)| v.as_slice())
    }

    /// The scalar attribute called `name`.
    pub fn scalar(&self, name: &str) -> Option<&[f32]> {
        let found = self.scalars.iter().find(|(n, _)| n == name);
        found.map(|(_, v)| v.as_slice())
    }
}

fn bad(what: &str, reason: impl Into<String>) -> Error {
    Error::Io {
        path: what.to_string(),
        reason: reason.into(),
    }
}

/// The next text line, `None` at the end of the input.
fn next_line(r: &mut impl BufRead, what: &str) -> Result<Option<String>> {
    let mut line = String::new();
    let n = r.read_line(&mut line).map_err(|e| io_err(what, e))?;
    Ok((n > 0).then(|| line.trim_end().to_string()))
}

fn header_line(r: &mut impl BufRead, what: &str) -> Result<String> {
    next_line(r, what)?.ok_or_else(|| bad(what, "unexpected end of header"))
}

/// Exactly `bytes` bytes of `r`, an error if the input ends first. Memory
/// grows with what is read, not with the count a header claims.
fn read_bytes(r: &mut impl Read, bytes: usize, what: &str) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let got = r
        .take(bytes as u64)
        .read_to_end(&mut out)
        .map_err(|e| io_err(what, e))?;
    if got != bytes {
        return Err(bad(
            what,
            format!("truncated data: the header promises {bytes} bytes, the input holds {got}"),
        ));
    }
    Ok(out)
}

/// `count` × `size` (bytes, or values per record): an error where a header's
/// count overflows.
fn times(count: usize, size: usize, what: &str) -> Result<usize> {
    count
        .checked_mul(size)
        .ok_or_else(|| bad(what, format!("count {count} is too large")))
}

fn floats(r: &mut impl Read, n: usize, big_endian: bool, what: &str) -> Result<Vec<f32>> {
    let bytes = read_bytes(r, times(n, 4, what)?, what)?;
    let conv = if big_endian {
        f32::from_be_bytes
    } else {
        f32::from_le_bytes
    };
    Ok(bytes
        .chunks_exact(4)
        .map(|c| conv(c.try_into().unwrap_or_default()))
        .collect())
}

fn to_vec3(f: &[f32]) -> Vec<Vec3> {
    f.chunks_exact(3).map(Vec3::from_slice).collect()
}

#[cfg(test)]
mod tests {
    use std::fs::File;

    use super::*;

    fn sample() -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        let x: Vec<Vec3> = (0..5)
            .map(|i| Vec3::new(i as f32, -0.5, 1e-7 * i as f32))
            .collect();
        let v: Vec<Vec3> = (0..5).map(|i| Vec3::splat(i as f32 * 0.25)).collect();
        let s: Vec<f32> = (0..5).map(|i| 1000.0 + i as f32).collect();
        (x, v, s)
    }

    #[test]
    fn ply_and_vtk_round_trip_bit_exact() {
        let (x, v, s) = sample();
        let cloud = PointCloud {
            positions: &x,
            vectors: vec![("velocity", &v), ("normal", &v), ("spin", &v)],
            scalars: vec![("density", &s), ("radius", &s)],
        };
        for format in [Format::Ply, Format::Vtk] {
            let mut bytes = Vec::new();
            format.write(&mut bytes, &cloud, 0.125).unwrap();
            let back = match format {
                Format::Ply => read_ply(bytes.as_slice()),
                Format::Vtk => read_vtk(bytes.as_slice()),
            }
            .unwrap();
            assert_eq!(back.time, Some(0.125));
            assert_eq!(back.positions, x);
            let names: Vec<&str> = back.vectors.iter().map(|(n, _)| n.as_str()).collect();
            assert_eq!(names, ["velocity", "normal", "spin"], "{format:?}");
            assert_eq!(back.vector("spin").unwrap(), v);
            assert_eq!(back.scalar("radius").unwrap(), s);
        }
    }

    #[test]
    fn ply_header_is_standard() {
        let (x, v, s) = sample();
        let cloud = PointCloud {
            positions: &x,
            vectors: vec![("velocity", &v)],
            scalars: vec![("density", &s)],
        };
        let mut bytes = Vec::new();
        write_ply(&mut bytes, &cloud, 2.5).unwrap();
        let end = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        let header = std::str::from_utf8(&bytes[..end]).unwrap();
        assert!(header.contains("comment time 2.5\n"));
        assert!(header.contains("element vertex 5\n"));
        assert!(header.contains("property float vx\nproperty float vy\nproperty float vz\n"));
        assert_eq!(bytes.len() - end, 5 * 7 * 4, "7 floats per vertex");
        // First vertex (0, −0.5, 0), little-endian.
        assert_eq!(&bytes[end..end + 4], &0.0f32.to_le_bytes());
        assert_eq!(&bytes[end + 4..end + 8], &(-0.5f32).to_le_bytes());
        assert_eq!(&bytes[end + 8..end + 12], &0.0f32.to_le_bytes());
    }

    #[test]
    fn mismatched_or_badly_named_attributes_are_errors() {
        let (x, v, s) = sample();
        let short = &s[..3];
        let cloud = PointCloud {
            positions: &x,
            vectors: vec![("velocity", &v)],
            scalars: vec![("density", short)],
        };
        let err = write_ply(Vec::new(), &cloud, 0.0).unwrap_err().to_string();
        assert!(err.contains("density"), "{err}");
        let cloud = PointCloud {
            positions: &x,
            vectors: vec![("two words", &v)],
            scalars: vec![],
        };
        assert!(write_vtk(Vec::new(), &cloud, 0.0).is_err());
        assert!("obj".parse::<Format>().is_err());
        assert!(read_ply(&b"ply\nformat ascii 1.0\n"[..]).is_err());
        assert!(read_ply(&b"ply\nformat binary_little_endian 1.0\nelement vertex 9\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0"[..]).is_err());
    }

    /// Header counts that overflow, promise more data than there is, or come
    /// in the wrong order are errors, without allocating what they claim.
    #[test]
    fn malformed_headers_are_errors_not_panics() {
        let ply = |count: &str| {
            let mut b = format!("ply\nformat binary_little_endian 1.0\nelement vertex {count}\nproperty float x\nproperty float y\nproperty float z\nend_header\n").into_bytes();
            b.extend_from_slice(&[0u8; 24]);
            read_ply(b.as_slice()).map(|c| c.positions.len())
        };
        assert_eq!(ply("2").unwrap(), 2);
        // Another program's PLY records no time: none, not 0.
        let b = b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
        assert_eq!(read_ply(&b[..]).unwrap().time, None);
        // A time that is not a finite number.
        for t in ["nan", "inf", "-inf", "soon"] {
            let b = format!(
                "ply\nformat binary_little_endian 1.0\ncomment time {t}\nelement vertex 0\nend_header\n"
            );
            let e = read_ply(b.as_bytes()).unwrap_err().to_string();
            assert!(e.contains("bad time"), "{t}: {e}");
            let b = format!("# vtk DataFile Version 3.0\nsph-core frame, time {t}\nBINARY\n");
            let e = read_vtk(b.as_bytes()).unwrap_err().to_string();
            assert!(e.contains("bad time"), "{t}: {e}");
        }
        for count in ["4611686018427387904", "100000000000", "3", "-1"] {
            let e = ply(count).unwrap_err().to_string();
            assert!(
                ["too large", "truncated", "bad vertex count"]
                    .iter()
                    .any(|w| e.contains(w)),
                "{count}: {e}"
            );
        }
        let vtk = |body: &[u8]| {
            let mut b = b"# vtk DataFile Version 3.0\ntitle\nBINARY\n".to_vec();
            b.extend_from_slice(body);
            read_vtk(b.as_slice())
        };
        for (body, words) in [
            (&b"VECTORS v float\n"[..], "before POINTS"),
            (b"POINT_DATA 0\n", "before POINTS"),
            (b"POINTS 6148914691236517206 float\n", "too large"),
            (b"POINTS 1000000000 float\n\0\0\0\0", "truncated"),
            (
                b"POINTS 0 float\nCELLS 9223372036854775807 0\n",
                "too large",
            ),
            (b"POINTS 0 float\nCELL_TYPES 5\n\0\0", "truncated"),
            (b"POINTS 0 float\nPOINTS 0 float\n", "second POINTS"),
        ] {
            let e = vtk(body).unwrap_err().to_string();
            assert!(e.contains(words), "{}: {e}", String::from_utf8_lossy(body));
        }
        assert!(
            vtk(b"POINTS 0 float\nPOINT_DATA 0\n")
                .unwrap()
                .positions
                .is_empty()
        );
    }

    #[test]
    fn frame_writer_numbers_frames_and_keeps_an_index() {
        let dir = std::env::temp_dir().join(format!("sph-export-{}", std::process::id()));
        let (x, v, s) = sample();
        let cloud = PointCloud {
            positions: &x,
            vectors: vec![("velocity", &v)],
            scalars: vec![("density", &s)],
        };
        let mut w = FrameWriter::new(&dir, "particles", Format::Vtk).unwrap();
        w.write(&cloud, 0.0).unwrap();
        let second = w.write(&cloud, 1.0 / 30.0).unwrap();
        assert_eq!(second, dir.join("particles_00001.vtk"));
        let back = read_vtk(File::open(&second).unwrap()).unwrap();
        assert_eq!(back.time, Some(1.0 / 30.0));
        let index = std::fs::read_to_string(dir.join("particles_index.csv")).unwrap();
        let lines: Vec<&str> = index.lines().collect();
        assert_eq!(
            lines,
            [
                "frame,time,points,file",
                "0,0.0,5,particles_00000.vtk",
                &format!("1,{:?},5,particles_00001.vtk", 1.0 / 30.0),
            ]
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
