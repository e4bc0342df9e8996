//! Legacy binary VTK: `DATASET UNSTRUCTURED_GRID`, big-endian (as the
//! format requires), `POINTS`, one vertex cell per point, `POINT_DATA` with
//! `VECTORS` and `SCALARS`; the time is in the title line (and in the frame
//! index CSV): no dataset `FIELD` block, which splashsurf's reader rejects.

use std::io::{BufReader, BufWriter, Read, Write};

use glam::Vec3;

use super::{LoadedCloud, PointCloud, bad, floats, header_line, io_err, next_line, times, to_vec3};
use crate::error::Result;

/// The legacy VTK cell type of a single point.
const VTK_VERTEX: i32 = 1;

/// The start of a VTK file's title line, the frame time following it.
const VTK_TITLE: &str = "sph-core frame, time ";

/// Writes `cloud` as a legacy binary VTK unstructured grid of vertex cells,
/// the frame time in the title line (`sph-core frame, time 0.25`).
///
/// No dataset `FIELD` block: splashsurf's reader (vtkio) rejects one before
/// the points ("Parse error: Tag"); the frame time is also in the
/// [`super::FrameWriter`]'s index CSV.
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
        let finite = t.trim().parse::<f64>().ok().filter(|t| t.is_finite());
        let time = finite.ok_or_else(|| bad(what, format!("bad time in the title `{title}`")))?;
        cloud.time = Some(time);
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
                let time = f64::from_be_bytes(b);
                if !time.is_finite() {
                    return Err(bad(what, format!("TIME {time} is not finite")));
                }
                cloud.time = Some(time);
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
