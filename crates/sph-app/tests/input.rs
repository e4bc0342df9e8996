//! `sph-app --input`: other simulators' particle files (splashsurf's test
//! data, MIT, in `tests/data/splashsurf/`) and this project's own
//! exports, played back through extraction and rendering.

use std::path::{Path, PathBuf};

mod common;

use common::{app, stderr};

/// A fresh, empty folder `name` under the tests' scratch folder.
fn scratch(name: &str) -> PathBuf {
    let dir = common::scratch(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn data(name: &str) -> String {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/splashsurf");
    dir.join(name).to_str().unwrap().to_string()
}

/// `frames.csv`'s rows of `out`, split at the commas.
fn rows(out: &Path) -> Vec<Vec<String>> {
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    (csv.lines().skip(1))
        .map(|l| l.split(',').map(String::from).collect())
        .collect()
}

/// Plays `input` headless at 30 fps into `out`, checking it succeeded.
fn play(input: &str, radius: &str, out: &Path, extra: &[&str]) -> Vec<Vec<String>> {
    let out_arg = out.to_str().unwrap();
    let mut args = vec![
        "--headless",
        "--input",
        input,
        "--particle-radius",
        radius,
        "--width",
        "96",
        "--height",
        "64",
        "--out",
        out_arg,
    ];
    args.extend(extra);
    let o = app(&args);
    assert!(o.status.success(), "{input}: {}", stderr(&o));
    rows(out)
}

/// SPlisHSPlasH's double dam break (two legacy VTK files, a glob), a BGEO
/// frame and a VTU file: one frame per file in order, every particle, a
/// surface, the frame times 1/30 s apart (the files record none).
#[test]
fn other_simulators_files_play_frame_by_frame() {
    let cases = [
        (
            "double_dam_break_frame_*_4732_particles.vtk",
            2,
            4732,
            0.025,
        ),
        ("dam_break_frame_9_6859_particles.bgeo", 1, 6859, 0.025),
        ("fluid_encoded_250_particles.vtu", 1, 250, 0.07),
    ];
    for (k, (pattern, files, particles, radius)) in cases.into_iter().enumerate() {
        let out = scratch(&format!("input-{k}"));
        let rows = play(&data(pattern), &radius.to_string(), &out, &[]);
        assert_eq!(rows.len(), files, "{pattern}");
        for (i, row) in rows.iter().enumerate() {
            let time: f64 = row[1].parse().unwrap();
            assert!((time - i as f64 / 30.0).abs() < 1e-6, "{pattern}: {row:?}");
            assert_eq!(row[2], particles.to_string(), "{pattern}: {row:?}");
            let surfels: usize = row[3].parse().unwrap();
            assert!(surfels >= particles / 10, "{pattern}: {row:?}");
            assert_eq!(row[9], "input", "{pattern}: {row:?}");
            assert_eq!(&row[12..14], ["", ""], "no solver, no density error");
            assert!(out.join(format!("frame_{i:05}.png")).exists() || row[8].is_empty());
        }
    }
    // The double dam break's files sort as 01 then 26: the columns stand at
    // first (a few surfels per particle), then the flow has spread thin.
    let out = scratch("input-order");
    let rows = play(
        &data("double_dam_break_frame_*_4732_particles.vtk"),
        "0.025",
        &out,
        &[],
    );
    let surfels: Vec<usize> = rows.iter().map(|r| r[3].parse().unwrap()).collect();
    assert!(surfels[1] > 3 * surfels[0], "{surfels:?}");
}

/// This project's own exports play back at the times they record, in
/// frame order.
#[test]
fn own_exports_play_back_at_their_times() {
    let sim = scratch("input-own-sim");
    let o = app(&[
        "--headless",
        "--scene",
        "dam-break",
        "--frames",
        "4",
        "--fps",
        "20",
        "--width",
        "64",
        "--height",
        "48",
        "--export-particles",
        "vtk",
        "--out",
        sim.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let simulated = rows(&sim);
    let pattern = sim.join("particles_*.vtk");
    let out = scratch("input-own-play");
    let played = play(pattern.to_str().unwrap(), "0.01", &out, &[]);
    assert_eq!(played.len(), 4);
    for (i, row) in played.iter().enumerate() {
        let source = &simulated[i];
        assert_eq!((&row[1], &row[2]), (&source[1], &source[2]), "frame {i}");
    }
    // A lost file is reported, and the rest play (three files: --frames
    // no longer given, each plays once).
    std::fs::remove_file(sim.join("particles_00001.vtk")).unwrap();
    let o = app(&[
        "--headless",
        "--input",
        pattern.to_str().unwrap(),
        "--particle-radius",
        "0.01",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("frames missing from the sequence between 0 and 2"),
        "{}",
        stderr(&o)
    );
    assert_eq!(rows(&out).len(), 3);
}

/// Each format's files cut to a quarter (inside the positions), emptied or with a wrong first bytes
/// are one-line errors naming the file, never a panic.
#[test]
fn truncated_empty_and_wrong_magic_files_are_errors() {
    let dir = scratch("input-broken");
    // This project's PLY, beside splashsurf's VTK, VTU and BGEO.
    let sim = scratch("input-broken-sim");
    let o = app(&[
        "--headless",
        "--scene",
        "dam-break",
        "--frames",
        "1",
        "--width",
        "64",
        "--height",
        "48",
        "--export-particles",
        "ply",
        "--out",
        sim.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sources = [
        sim.join("particles_00000.ply"),
        PathBuf::from(data("double_dam_break_frame_01_4732_particles.vtk")),
        PathBuf::from(data("fluid_encoded_250_particles.vtu")),
        PathBuf::from(data("dam_break_frame_9_6859_particles.bgeo")),
    ];
    for source in sources {
        let bytes = std::fs::read(&source).unwrap();
        let extension = source.extension().unwrap().to_str().unwrap();
        let mut wrong = bytes.clone();
        wrong[..4].copy_from_slice(b"XXXX");
        let broken = [
            ("truncated", bytes[..bytes.len() / 4].to_vec()),
            ("empty", Vec::new()),
            ("wrong_magic", wrong),
        ];
        for (what, content) in broken {
            let path = dir.join(format!("{what}.{extension}"));
            std::fs::write(&path, content).unwrap();
            let o = app(&[
                "--headless",
                "--input",
                path.to_str().unwrap(),
                "--particle-radius",
                "0.01",
            ]);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(1), "{}: {err}", path.display());
            assert!(err.contains(&format!("{what}.{extension}")), "{err}");
            assert!(!err.contains("panicked"), "{err}");
            assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
        }
    }
}

#[test]
fn bad_inputs_are_clear_errors() {
    let dir = scratch("input-bad");
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();
    std::fs::write(dir.join("garbage.bgeo"), b"not a bgeo file at all").unwrap();
    std::fs::write(dir.join("empty.xyz"), b"").unwrap();
    std::fs::write(dir.join("short.xyz"), [0u8; 7]).unwrap();
    std::fs::write(dir.join("points.txt"), b"0 0 0\n").unwrap();
    let nan: Vec<u8> = [0.0f32, f32::NAN, 0.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    std::fs::write(dir.join("nan.xyz"), nan).unwrap();
    // NaN positions in this project's PLY and VTK (its writers do not check).
    let nan_points = [sph_core::glam::Vec3::new(0.0, f32::NAN, 0.0); 3];
    let cloud = sph_core::io::PointCloud {
        positions: &nan_points,
        ..Default::default()
    };
    for format in [sph_core::io::Format::Ply, sph_core::io::Format::Vtk] {
        let file = std::fs::File::create(dir.join(format!("nan.{}", format.extension()))).unwrap();
        format.write(file, &cloud, 0.0).unwrap();
    }
    // A NaN in a BGEO file: one written with a marker value, the marker's
    // big-endian bytes then replaced by a NaN's.
    let marked = [
        sph_core::glam::Vec3::ZERO,
        sph_core::glam::Vec3::new(0.5, 1234.5, 0.5),
    ];
    let bgeo = dir.join("nan.bgeo");
    sph_core::io::write_particles(
        &bgeo,
        &sph_core::io::PointCloud {
            positions: &marked,
            ..Default::default()
        },
        None,
    )
    .unwrap();
    let mut bytes = std::fs::read(&bgeo).unwrap();
    let marker = 1234.5f32.to_be_bytes();
    let at = (bytes.windows(4))
        .position(|w| w == marker)
        .expect("the marker in the BGEO file");
    bytes[at..at + 4].copy_from_slice(&f32::NAN.to_be_bytes());
    std::fs::write(&bgeo, bytes).unwrap();
    // And in a VTU file, written as ASCII.
    std::fs::write(
        dir.join("nan.vtu"),
        r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="2" NumberOfCells="2">
      <Points>
        <DataArray type="Float32" NumberOfComponents="3" format="ascii">0 0 0 0.5 nan 0.5</DataArray>
      </Points>
      <Cells>
        <DataArray type="UInt64" Name="connectivity" format="ascii">0 1</DataArray>
        <DataArray type="UInt64" Name="offsets" format="ascii">1 2</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">1 1</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"#,
    )
    .unwrap();
    let cases: [(String, &str, &str); 11] = [
        (path("nan.ply"), "0.01", "not finite"),
        (path("nan.vtk"), "0.01", "not finite"),
        (path("nan.bgeo"), "0.01", "not finite"),
        (path("nan.vtu"), "0.01", "not finite"),
        (path("missing_*.vtk"), "0.01", "no file matches"),
        (path("garbage.bgeo"), "0.01", "garbage.bgeo"),
        (path("empty.xyz"), "0.01", "holds no particle"),
        (path("short.xyz"), "0.01", "short.xyz"),
        (path("points.txt"), "0.01", "not a particle file"),
        (path("nan.xyz"), "0.01", "not finite"),
        (path("[bad"), "0.01", "not a valid pattern"),
    ];
    for (input, radius, expected) in cases {
        let o = app(&["--headless", "--input", &input, "--particle-radius", radius]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{input}: {err}");
        assert!(err.contains(expected), "{input}: {err}");
        assert!(err.contains("--input"), "{input}: {err}");
        assert!(!err.contains("panicked"), "{input}: {err}");
    }
    // A smoothing length that gives thousands of neighbours.
    let o = app(&[
        "--headless",
        "--input",
        &data("fluid_encoded_250_particles.vtu"),
        "--particle-radius",
        "0.025",
        "--smoothing-length",
        "30",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("thousands of neighbours"),
        "{err}"
    );
    // One under which no particle reaches its neighbours.
    let o = app(&[
        "--headless",
        "--input",
        &data("fluid_encoded_250_particles.vtu"),
        "--particle-radius",
        "0.025",
        "--smoothing-length",
        "0.3",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("less than 1"), "{err}");
}

/// XYZ files (binary f32 triples, as splashsurf reads them) play too.
#[test]
fn xyz_files_play() {
    let dir = scratch("input-xyz");
    let mut bytes = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            for k in 0..6 {
                for v in [i, j, k] {
                    bytes.extend((0.02 * v as f32).to_le_bytes());
                }
            }
        }
    }
    std::fs::write(dir.join("block.xyz"), bytes).unwrap();
    let out = dir.join("out");
    let rows = play(dir.join("block.xyz").to_str().unwrap(), "0.01", &out, &[]);
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0][2], "216");
    let surfels: usize = rows[0][3].parse().unwrap();
    assert!(surfels > 100, "{:?}", rows[0]);
}

/// Another program's PLY files, which record no time, play 1/--fps apart
/// (they played at t = 0 each: the reader took the missing time for 0).
#[test]
fn ply_files_without_a_time_play_at_the_frame_rate() {
    let dir = scratch("input-ply");
    std::fs::create_dir_all(&dir).unwrap();
    for f in 0..3 {
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 216\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
        for i in 0..6 {
            for j in 0..6 {
                for k in 0..6 {
                    for v in [i, j + f, k] {
                        bytes.extend((0.02 * v as f32).to_le_bytes());
                    }
                }
            }
        }
        std::fs::write(dir.join(format!("cloud_{f}.ply")), bytes).unwrap();
    }
    let glob = dir.join("cloud_*.ply");
    let rows = play(
        glob.to_str().unwrap(),
        "0.01",
        &dir.join("out"),
        &["--fps", "10"],
    );
    let times: Vec<&str> = rows.iter().map(|r| r[1].as_str()).collect();
    assert_eq!(times, ["0.000000", "0.100000", "0.200000"]);
}

/// `--iso` reaches the extraction: the BGEO dam break's surface at
/// k = 0.3 is another surface than at the default 0.5 (18,389 surfels
/// against 26,671 measured).
#[test]
fn the_iso_flag_sets_the_surface() {
    let bgeo = data("dam_break_frame_9_6859_particles.bgeo");
    let surfels = |extra: &[&str], name: &str| -> usize {
        let out = scratch(name);
        play(&bgeo, "0.025", &out, extra)[0][3].parse().unwrap()
    };
    let (default, low) = (
        surfels(&[], "input-iso-5"),
        surfels(&["--iso", "0.3"], "input-iso-3"),
    );
    assert!(low < default * 9 / 10, "{low} at 0.3, {default} at 0.5");
}
