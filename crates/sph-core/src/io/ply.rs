//! Binary PLY: `binary_little_endian 1.0`, one `vertex` element with
//! `float` properties `x y z`, then three floats per vector attribute (`vx
//! vy vz` for `velocity`; `nx ny nz` for `normal`, the names Blender and
//! splashsurf expect) and one per scalar; the time is in a `comment time
//! <seconds>` line.

use std::io::{BufReader, BufWriter, Read, Write};

use glam::Vec3;

use super::{LoadedCloud, PointCloud, bad, components, floats, header_line, io_err, times};
use crate::error::Result;

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

/// Reads a PLY file written by [`write_ply`].
pub fn read_ply(r: impl Read) -> Result<LoadedCloud> {
    let what = "PLY input";
    let mut r = BufReader::new(r);
    if header_line(&mut r, what)? != "ply" {
        return Err(bad(what, "missing `ply` magic"));
    }
    let (mut n, mut props, mut time) = (None, Vec::new(), None);
    loop {
        let line = header_line(&mut r, what)?;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", "binary_little_endian", "1.0"] => {}
            ["format", ..] => return Err(bad(what, format!("unsupported `{line}`"))),
            ["comment", "time", t] => {
                let finite = t.parse::<f64>().ok().filter(|t| t.is_finite());
                time = Some(finite.ok_or_else(|| bad(what, format!("bad time `{t}`")))?);
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
