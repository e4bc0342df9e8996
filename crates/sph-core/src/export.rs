//! Point-cloud export: binary PLY and legacy binary VTK, each frame stamped with
//! its simulated time, and a [`FrameWriter`] that writes numbered frames plus a CSV
//! index (`{prefix}_index.csv`: frame, time, points, file).
//!
//! Both formats are read by ParaView, Blender (PLY) and splashsurf (PLY, VTK):
//! - PLY: `binary_little_endian 1.0`, one `vertex` element with `float`
//!   properties `x y z`, then three floats per vector attribute (`vx vy vz` for
//!   `velocity`; `nx ny nz` for `normal`, the names Blender and splashsurf
//!   expect) and one per scalar; the time is in a `comment time <seconds>` line.
//! - VTK: legacy `DATASET UNSTRUCTURED_GRID`, big-endian (as the format
//!   requires), `POINTS`, one vertex cell per point, `POINT_DATA` with `VECTORS` and
//!   `SCALARS`; the time is in the title line (and in the frame index CSV):
//!   no dataset `FIELD` block, which splashsurf's reader rejects.
//!
//! [`read_ply`] and [`read_vtk`] read back what these writers write (not arbitrary
//! files), for tests and tools.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::error::{Error, Result};
use crate::particles::Particles;

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

/// Writes `cloud` as binary little-endian PLY with `comment time <time>`.
pub fn write_ply(w: impl Write, cloud: &PointCloud, time: f64) -> Result<()> {
    cloud.check()?;
    let mut w = BufWriter::new(w);
    let mut write = || -> std::io::Result<()> {
        writeln!(w, "ply\nformat binary_little_endian 1.0")?;
        writeln!(w, "comment written by sph-core")?;
        writeln!(w, "comment time {time:?}")?;
        writeln!(w, "element vertex {}", cloud.len())?;
        for a in ["x", "y", "z"] {
            writeln!(w, "property float {a}")?;
        }
        for (name, _) in &cloud.vectors {
            for c in components(name) {
                writeln!(w, "property float {c}")?;
            }
        }
        for (name, _) in &cloud.scalars {
            writeln!(w, "property float {name}")?;
        }
        writeln!(w, "end_header")?;
        let mut row = Vec::with_capacity(4 * (3 + 3 * cloud.vectors.len() + cloud.scalars.len()));
        for i in 0..cloud.len() {
            row.clear();
            let vectors = cloud.vectors.iter().map(|(_, v)| v[i]);
            for v in std::iter::once(cloud.positions[i]).chain(vectors) {
                for c in v.to_array() {
                    row.extend_from_slice(&c.to_le_bytes());
                }
            }
            for (_, s) in &cloud.scalars {
                row.extend_from_slice(&s[i].to_le_bytes());
            }
            w.write_all(&row)?;
        }
        w.flush()
    };
    write().map_err(|e| io_err("PLY output", e))
}

/// The legacy VTK cell type of a single point.
const VTK_VERTEX: i32 = 1;

/// The start of a VTK file's title line, the frame time following it.
const VTK_TITLE: &str = "sph-core frame, time ";

/// Writes `cloud` as a legacy binary VTK unstructured grid of vertex cells,
/// the frame time in the title line (`sph-core frame, time 0.25`).
///
/// No dataset `FIELD` block: splashsurf's reader (vtkio) rejects one before
/// the points ("Parse error: Tag"); the frame time is also in the
/// [`FrameWriter`]'s index CSV.
pub fn write_vtk(w: impl Write, cloud: &PointCloud, time: f64) -> Result<()> {
    cloud.check()?;
    let n = cloud.len();
    // Legacy VTK numbers the points of a cell list with 32-bit integers.
    if n > i32::MAX as usize / 2 {
        return Err(bad(
            "VTK output",
            format!(
                "{n} points: legacy VTK's 32-bit cell list holds at most {}",
                i32::MAX / 2
            ),
        ));
    }
    let mut w = BufWriter::new(w);
    let mut write = || -> std::io::Result<()> {
        let be3 = |w: &mut BufWriter<_>, v: Vec3| -> std::io::Result<()> {
            for c in v.to_array() {
                w.write_all(&c.to_be_bytes())?;
            }
            Ok(())
        };
        writeln!(w, "# vtk DataFile Version 3.0")?;
        writeln!(w, "{VTK_TITLE}{time:?}")?;
        writeln!(w, "BINARY\nDATASET UNSTRUCTURED_GRID")?;
        writeln!(w, "POINTS {n} float")?;
        for &x in cloud.positions {
            be3(&mut w, x)?;
        }
        writeln!(w, "\nCELLS {n} {}", 2 * n)?;
        for i in 0..n as i32 {
            w.write_all(&1i32.to_be_bytes())?;
            w.write_all(&i.to_be_bytes())?;
        }
        writeln!(w, "\nCELL_TYPES {n}")?;
        for _ in 0..n {
            w.write_all(&VTK_VERTEX.to_be_bytes())?;
        }
        writeln!(w, "\nPOINT_DATA {n}")?;
        for (name, v) in &cloud.vectors {
            writeln!(w, "VECTORS {name} float")?;
            for &x in v.iter() {
                be3(&mut w, x)?;
            }
            writeln!(w)?;
        }
        for (name, s) in &cloud.scalars {
            writeln!(w, "SCALARS {name} float 1\nLOOKUP_TABLE default")?;
            for &x in s.iter() {
                w.write_all(&x.to_be_bytes())?;
            }
            writeln!(w)?;
        }
        w.flush()
    };
    write().map_err(|e| io_err("VTK output", e))
}

/// A point cloud read back from a file: owned attributes and the frame time.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadedCloud {
    /// Simulated time of the frame.
    pub time: f64,
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

/// Reads a PLY file written by [`write_ply`].
pub fn read_ply(r: impl Read) -> Result<LoadedCloud> {
    let what = "PLY input";
    let mut r = BufReader::new(r);
    if header_line(&mut r, what)? != "ply" {
        return Err(bad(what, "missing `ply` magic"));
    }
    let (mut n, mut props, mut time) = (None, Vec::new(), 0.0);
    loop {
        let line = header_line(&mut r, what)?;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", "binary_little_endian", "1.0"] => {}
            ["format", ..] => return Err(bad(what, format!("unsupported `{line}`"))),
            ["comment", "time", t] => {
                time = t
                    .parse()
                    .map_err(|_| bad(what, format!("bad time `{t}`")))?
            }
            ["comment", ..] => {}
            ["element", "vertex", c] => {
                n = Some(
                    c.parse::<usize>()
                        .map_err(|_| bad(what, "bad vertex count"))?,
                )
            }
            ["property", "float", name] => props.push(name.to_string()),
            ["end_header"] => break,
            _ => return Err(bad(what, format!("unsupported header line `{line}`"))),
        }
    }
    let n = n.ok_or_else(|| bad(what, "no vertex element"))?;
    if props.len() < 3 || props[..3] != ["x", "y", "z"] {
        return Err(bad(what, "the first properties must be x y z"));
    }
    let stride = props.len();
    let data = floats(&mut r, times(n, stride, what)?, false, what)?;
    let column = |k: usize| -> Vec<f32> { (0..n).map(|i| data[i * stride + k]).collect() };
    let vec_at = |k: usize| -> Vec<Vec3> {
        (0..n)
            .map(|i| Vec3::from_slice(&data[i * stride + k..i * stride + k + 3]))
            .collect()
    };
    let mut cloud = LoadedCloud {
        time,
        positions: vec_at(0),
        ..Default::default()
    };
    let mut k = 3;
    while k < stride {
        // A vector is three consecutive properties named as `components` names them.
        let vector_name = ["normal", "velocity"]
            .into_iter()
            .map(String::from)
            .chain(props[k].strip_suffix("_x").map(String::from))
            .find(|name| k + 3 <= stride && props[k..k + 3] == components(name));
        match vector_name {
            Some(name) => {
                cloud.vectors.push((name, vec_at(k)));
                k += 3;
            }
            None => {
                cloud.scalars.push((props[k].clone(), column(k)));
                k += 1;
            }
        }
    }
    Ok(cloud)
}

/// Reads a VTK file written by [`write_vtk`].
pub fn read_vtk(r: impl Read) -> Result<LoadedCloud> {
    let what = "VTK input";
    let mut r = BufReader::new(r);
    if !header_line(&mut r, what)?.starts_with("# vtk DataFile") {
        return Err(bad(what, "missing `# vtk DataFile` magic"));
    }
    let title = header_line(&mut r, what)?;
    if header_line(&mut r, what)? != "BINARY" {
        return Err(bad(what, "only BINARY files are supported"));
    }
    let mut cloud = LoadedCloud::default();
    // The frame time, from the title `write_vtk` writes (files of earlier
    // versions carry a TIME field as well, read below).
    if let Some(t) = title.strip_prefix(VTK_TITLE) {
        cloud.time = t
            .trim()
            .parse()
            .map_err(|_| bad(what, format!("bad time in the title `{title}`")))?;
    }
    // The point count, once POINTS has been read: the attributes need it.
    let mut points = None;
    let need_points = |points: Option<usize>, line: &str| {
        points.ok_or_else(|| bad(what, format!("`{line}` before POINTS")))
    };
    while let Some(line) = next_line(&mut r, what)? {
        let words: Vec<&str> = line.split_whitespace().collect();
        let count = |s: &str| {
            s.parse::<usize>()
                .map_err(|_| bad(what, format!("bad count in `{line}`")))
        };
        match words.as_slice() {
            []
            | ["DATASET", "UNSTRUCTURED_GRID"]
            | ["FIELD", "FieldData", "1"]
            | ["LOOKUP_TABLE", _] => {}
            ["TIME", "1", "1", "double"] => {
                let mut b = [0u8; 8];
                r.read_exact(&mut b).map_err(|e| io_err(what, e))?;
                cloud.time = f64::from_be_bytes(b);
            }
            ["POINTS", c, "float"] => {
                if points.is_some() {
                    return Err(bad(what, "a second POINTS section"));
                }
                let n = count(c)?;
                let values = times(n, 3, what)?;
                cloud.positions = to_vec3(&floats(&mut r, values, true, what)?);
                points = Some(n);
            }
            ["CELLS", c, _] | ["CELL_TYPES", c] => {
                let bytes = if words[0] == "CELLS" { 8 } else { 4 };
                let skip = times(count(c)?, bytes, what)?;
                let skipped = std::io::copy(&mut (&mut r).take(skip as u64), &mut std::io::sink())
                    .map_err(|e| io_err(what, e))?;
                if skipped != skip as u64 {
                    return Err(bad(what, format!("truncated data in `{line}`")));
                }
            }
            ["POINT_DATA", c] => {
                if count(c)? != need_points(points, &line)? {
                    return Err(bad(what, "POINT_DATA count differs from POINTS"));
                }
            }
            ["VECTORS", name, "float"] => {
                let n = need_points(points, &line)?;
                let v = to_vec3(&floats(&mut r, 3 * n, true, what)?);
                cloud.vectors.push((name.to_string(), v));
            }
            ["SCALARS", name, "float", "1"] => {
                let table = header_line(&mut r, what)?;
                if !table.starts_with("LOOKUP_TABLE") {
                    return Err(bad(what, "SCALARS without LOOKUP_TABLE"));
                }
                let n = need_points(points, &line)?;
                cloud
                    .scalars
                    .push((name.to_string(), floats(&mut r, n, true, what)?));
            }
            _ => return Err(bad(what, format!("unsupported line `{line}`"))),
        }
    }
    Ok(cloud)
}

/// Writes numbered frames `{prefix}_{frame:05}.{ext}` into a folder and keeps
/// `{prefix}_index.csv` (frame, time, points, file) up to date after each frame.
#[derive(Debug)]
pub struct FrameWriter {
    dir: PathBuf,
    prefix: String,
    format: Format,
    index: BufWriter<File>,
    frames: u64,
}

impl FrameWriter {
    /// Creates `dir` if needed and starts a fresh index there.
    pub fn new(dir: impl AsRef<Path>, prefix: &str, format: Format) -> Result<Self> {
        let dir = dir.as_ref().to_path_buf();
        let path_str = dir.display().to_string();
        std::fs::create_dir_all(&dir).map_err(|e| io_err(&path_str, e))?;
        let index_path = dir.join(format!("{prefix}_index.csv"));
        let index_str = index_path.display().to_string();
        let file = File::create(&index_path).map_err(|e| io_err(&index_str, e))?;
        let mut index = BufWriter::new(file);
        writeln!(index, "frame,time,points,file").map_err(|e| io_err(&index_str, e))?;
        Ok(Self {
            dir,
            prefix: prefix.to_string(),
            format,
            index,
            frames: 0,
        })
    }

    /// Writes the next frame; returns its path.
    pub fn write(&mut self, cloud: &PointCloud, time: f64) -> Result<PathBuf> {
        let name = format!(
            "{}_{:05}.{}",
            self.prefix,
            self.frames,
            self.format.extension()
        );
        let path = self.dir.join(&name);
        let path_str = path.display().to_string();
        let file = File::create(&path).map_err(|e| io_err(&path_str, e))?;
        self.format.write(file, cloud, time).map_err(|e| match e {
            Error::Io { reason, .. } => io_err(&path_str, std::io::Error::other(reason)),
            other => other,
        })?;
        let index = &mut self.index;
        writeln!(index, "{},{time:?},{},{name}", self.frames, cloud.len())
            .and_then(|_| index.flush())
            .map_err(|e| io_err(&self.dir.display().to_string(), e))?;
        self.frames += 1;
        Ok(path)
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }
}

#[cfg(test)]
mod tests {
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
            assert_eq!(back.time, 0.125);
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
        assert_eq!(back.time, 1.0 / 30.0);
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
