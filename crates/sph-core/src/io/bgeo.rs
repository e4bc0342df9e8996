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

#[cfg(not(feature = "readers"))]
pub(super) fn write_bgeo(_: &mut Vec<u8>, _: &[Vec3]) -> Result<(), String> {
    Err(".bgeo files need sph-core's `readers` feature".into())
}
