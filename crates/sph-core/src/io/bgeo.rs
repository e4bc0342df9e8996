//! BGEO: Houdini's geometry format, uncompressed, positions only, written
//! by splashsurf_lib (which reads it back). Needs the `readers` feature.

use glam::Vec3;

/// Appends the BGEO file of `positions`.
#[cfg(feature = "readers")]
pub(super) fn write_bgeo(bytes: &mut Vec<u8>, positions: &[Vec3]) -> Result<(), String> {
    use splashsurf_lib::io::bgeo_format::{
        AttributeStorage, BgeoFile, BgeoHeader, write_bgeo_file,
    };
    let n = positions.len();
    let num_points =
        i32::try_from(n).map_err(|_| format!("{n} particles are more than BGEO's {}", i32::MAX))?;
    let bgeo = BgeoFile {
        header: BgeoHeader {
            magic_bytes: *b"Bgeo",
            version_char: b'V',
            version: 5,
            num_points,
            num_prims: 0,
            num_point_groups: 0,
            num_prim_groups: 0,
            num_point_attrib: 0,
            num_vertex_attrib: 0,
            num_prim_attrib: 0,
            num_attrib: 0,
        },
        positions: AttributeStorage::Vector(
            3,
            positions.iter().flat_map(|p| p.to_array()).collect(),
        ),
        weights: AttributeStorage::Float(vec![1.0; n]),
        attribute_definitions: Vec::new(),
        attribute_data: Vec::new(),
    };
    write_bgeo_file(&bgeo, bytes, false).map_err(|e| format!("{e:#}"))
}

/// Whether the points a BGEO file's header claims fit in its bytes
/// (`bytes`, unzipped). splashsurf_lib's parser allocates every attribute
/// for the claimed count before reading a point, so a header of 2³¹ − 1
/// points in a 69-byte file aborted the process (no panic to catch). Each
/// point holds its position and weight (four f32) and each named
/// attribute's `size` values of four bytes. A file that is not BGEO 5 as
/// far as this reads is left to splashsurf_lib to refuse.
#[cfg(feature = "readers")]
pub(super) fn check_bgeo_counts(bytes: &[u8]) -> Result<(), String> {
    let i32_at = |at: usize| -> Option<i32> {
        Some(i32::from_be_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
    };
    let u16_at = |at: usize| -> Option<usize> {
        Some(u16::from_be_bytes(bytes.get(at..at + 2)?.try_into().ok()?).into())
    };
    if !bytes.starts_with(b"Bgeo") || i32_at(5) != Some(5) {
        return Ok(());
    }
    let (Some(points), Some(attributes)) = (i32_at(9), i32_at(25)) else {
        return Ok(());
    };
    if points < 0 || attributes < 0 {
        return Err(format!(
            "its header claims {points} points and {attributes} point attributes"
        ));
    }
    // The attribute definitions: a name, a size, a type and `size` defaults.
    let (mut at, mut record) = (41usize, 16u64);
    for _ in 0..attributes {
        let Some(name) = u16_at(at) else {
            return Ok(());
        };
        let Some(size) = u16_at(at + 2 + name) else {
            return Ok(());
        };
        at += 2 + name + 2 + 4 + 4 * size;
        record += 4 * size as u64;
    }
    let body = bytes.len().saturating_sub(at) as u64;
    let claimed = points as u64 * record;
    if claimed > body {
        return Err(format!(
            "its header claims {points} points of {record} bytes, {claimed} bytes, but {body} follow"
        ));
    }
    Ok(())
}

#[cfg(not(feature = "readers"))]
pub(super) fn write_bgeo(_: &mut Vec<u8>, _: &[Vec3]) -> Result<(), String> {
    Err(".bgeo files need sph-core's `readers` feature".into())
}
