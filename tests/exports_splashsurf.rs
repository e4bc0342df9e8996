//! The particle exports open in another tool: PLY and VTK frames written by
//! `sph_core::io` are read back by `splashsurf_lib`'s own readers (the
//! library of the splashsurf CLI), positions and attributes equal.

use sph_core::glam::Vec3;
use sph_core::io::{Format, FrameWriter, PointCloud};
use splashsurf_lib::io::{ply_format, vtk_format};
use splashsurf_lib::mesh::AttributeData;

/// A small cloud with a vector and a scalar attribute.
fn cloud() -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
    let positions: Vec<Vec3> = (0..100)
        .map(|i| Vec3::new(i as f32 * 0.01, (i % 7) as f32 * 0.02, -(i as f32) * 1e-3))
        .collect();
    let velocities = positions.iter().map(|&x| x * 3.0 - Vec3::Y).collect();
    let densities = (0..100).map(|i| 1000.0 + i as f32 * 0.5).collect();
    (positions, velocities, densities)
}

fn write(format: Format, dir: &std::path::Path) -> std::path::PathBuf {
    let (positions, velocities, densities) = cloud();
    let cloud = PointCloud {
        positions: &positions,
        vectors: vec![("velocity", &velocities)],
        scalars: vec![("density", &densities)],
    };
    let _ = std::fs::remove_dir_all(dir);
    let mut writer = FrameWriter::new(dir, "particles", format).unwrap();
    writer.write(&cloud, 0.25).unwrap()
}

fn scratch(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name)
}

#[test]
fn vtk_frames_load_in_splashsurf_with_their_attributes() {
    let path = write(Format::Vtk, &scratch("splashsurf-vtk"));
    let (positions, velocities, densities) = cloud();
    let loaded: Vec<_> = vtk_format::particles_from_vtk::<f32, _>(&path)
        .unwrap_or_else(|e| panic!("splashsurf cannot read {}: {e:?}", path.display()));
    let as_vec3 = |v: &[f32]| Vec3::new(v[0], v[1], v[2]);
    assert_eq!(loaded.len(), positions.len());
    for (a, b) in loaded.iter().zip(&positions) {
        assert_eq!(as_vec3(a.as_slice()), *b);
    }
    let pieces = vtk_format::VtkFile::load_file(&path).unwrap().into_pieces();
    assert_eq!(pieces.len(), 1);
    let mut names = pieces[0].point_attribute_names();
    names.sort();
    assert_eq!(names, ["density", "velocity"]);
    let attributes = pieces[0]
        .load_point_attributes::<f32>(&["velocity".into(), "density".into()])
        .unwrap();
    match &attributes[0].data {
        AttributeData::Vector3Real(v) => {
            let v: Vec<Vec3> = v.iter().map(|v| as_vec3(v.as_slice())).collect();
            assert_eq!(v, velocities);
        }
        other => panic!("velocity read as {other:?}"),
    }
    match &attributes[1].data {
        AttributeData::ScalarReal(d) => assert_eq!(&d[..], &densities[..]),
        other => panic!("density read as {other:?}"),
    }
    // The frame time stays readable: in the title line, and our reader.
    let ours = sph_core::io::read_vtk(std::fs::File::open(&path).unwrap()).unwrap();
    assert_eq!(ours.time, Some(0.25));
    assert_eq!(ours.positions, positions);
}

#[test]
fn ply_frames_load_in_splashsurf() {
    let path = write(Format::Ply, &scratch("splashsurf-ply"));
    let (positions, _, _) = cloud();
    let loaded: Vec<_> = ply_format::particles_from_ply::<f32, _>(&path)
        .unwrap_or_else(|e| panic!("splashsurf cannot read {}: {e:?}", path.display()));
    assert_eq!(loaded.len(), positions.len());
    for (a, b) in loaded.iter().zip(&positions) {
        assert_eq!(Vec3::new(a[0], a[1], a[2]), *b);
    }
}
