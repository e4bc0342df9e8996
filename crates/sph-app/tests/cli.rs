//! End-to-end tests of the `sph-app` binary: headless frames, CSV, exports, and
//! one-line errors with a non-zero exit.

use std::path::Path;
use std::process::{Command, Output};

use glam::Vec2;
use sph_core::io::{read_ply, read_vtk};
use splat_render::textures::{procedural_background, sample_bilinear};

mod common;

use common::{app, scratch, stderr};

/// Whether a `--gpu-*` run failed for want of an adapter: a skip, unless
/// `SPH_REQUIRE_GPU=1` (CI) makes it a failure.
fn skipped_without_adapter(o: &Output) -> bool {
    if o.status.success() || !stderr(o).contains("needs a GPU adapter") {
        return false;
    }
    assert!(
        std::env::var("SPH_REQUIRE_GPU").as_deref() != Ok("1"),
        "{}",
        stderr(o)
    );
    eprintln!("skipped: no GPU adapter");
    true
}

#[test]
fn headless_frames_csv_and_exports() {
    let out = scratch("headless");
    let o = app(&[
        "--headless",
        "--scene",
        "dam-break",
        "--frames",
        "3",
        "--fps",
        "30",
        "--width",
        "160",
        "--height",
        "120",
        "--out",
        out.to_str().unwrap(),
        "--export-particles",
        "ply",
        "--export-surfels",
        "vtk",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));

    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(
        csv.lines().next().unwrap(),
        "frame,time,particles,surfels,evaluations,step_ms,extract_ms,render_ms,render_gpu_ms,\
         solver,substeps,iterations,density_error_avg,density_error_max,clamped,\
         divergence_iterations,viscosity_iterations,unconverged"
    );
    assert_eq!(rows.len(), 3, "{csv}");
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row[0], i.to_string());
        let time: f64 = row[1].parse().unwrap();
        assert!((time - (i + 1) as f64 / 30.0).abs() < 1e-4, "time {time}");
        let particles: usize = row[2].parse().unwrap();
        let surfels: usize = row[3].parse().unwrap();
        assert!(particles > 1000 && surfels > 100, "{row:?}");
        // The built-in scenes run PBF: 3 substeps of 3 iterations per
        // 60 Hz frame, none longer: 6 per 1/30 s frame here.
        assert_eq!(&row[9..12], ["pbf", "6", "18"], "{row:?}");
        let (avg, max): (f32, f32) = (row[12].parse().unwrap(), row[13].parse().unwrap());
        assert!(
            (0.0..0.05).contains(&avg) && avg <= max && max < 0.5,
            "{row:?}"
        );
        assert_eq!(row[14], "0", "no particle clamped: {row:?}");
        assert_eq!(
            &row[15..17],
            ["0", "0"],
            "no divergence solve in PBF: {row:?}"
        );
        // The render passes' GPU time (lavapipe has timestamp queries): more
        // than nothing, less than the frame's render with its read-back.
        if let Ok(gpu_ms) = row[8].parse::<f64>() {
            let render_ms: f64 = row[7].parse().unwrap();
            assert!(gpu_ms > 0.0 && gpu_ms <= render_ms, "{row:?}");
        } else {
            // Empty only without an adapter or its timestamps; CI's lavapipe
            // has both.
            assert!(
                row[8].is_empty() && std::env::var("SPH_REQUIRE_GPU").as_deref() != Ok("1"),
                "{row:?}"
            );
        }
        let p = read_ply(std::fs::File::open(out.join(format!("particles_{i:05}.ply"))).unwrap())
            .unwrap();
        assert_eq!(p.positions.len(), particles);
        assert!(p.vector("velocity").is_some() && p.scalar("density").is_some());
        let s = read_vtk(std::fs::File::open(out.join(format!("surfels_{i:05}.vtk"))).unwrap())
            .unwrap();
        assert_eq!(s.positions.len(), surfels);
        assert!(s.vector("normal").is_some() && s.scalar("radius").is_some());
    }

    let png = out.join("frame_00002.png");
    if !png.exists() {
        assert!(
            std::env::var("SPH_REQUIRE_GPU").as_deref() != Ok("1"),
            "no PNG: {}",
            stderr(&o)
        );
        assert!(stderr(&o).contains("mesa-vulkan-drivers"), "{}", stderr(&o));
        eprintln!("skipped image checks: no GPU adapter");
        return;
    }
    for i in 0..3 {
        let img = image::open(out.join(format!("frame_{i:05}.png")))
            .unwrap()
            .into_rgba8();
        assert_eq!(img.dimensions(), (160, 120));
        // The fluid is visible: pixels differ from the plain background.
        let back = procedural_background(1024, 1024);
        let differing = img
            .enumerate_pixels()
            .filter(|(x, y, p)| {
                let uv = Vec2::new((*x as f32 + 0.5) / 160.0, (*y as f32 + 0.5) / 120.0);
                let b = sample_bilinear(&back, uv, false) * 255.0;
                (0..3).any(|c| (f32::from(p.0[c]) - b[c]).abs() > 12.0)
            })
            .count();
        assert!(
            differing > 160 * 120 / 50,
            "frame {i}: only {differing} pixels show fluid"
        );
    }
}

#[test]
fn list_scenes_names_the_built_ins() {
    let o = app(&["--list-scenes"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    for name in ["dam-break", "dam-break-3d", "double-dam-break", "drop"] {
        assert!(text.contains(name), "{text}");
    }
    // The counts are the scenes' own, not written by hand.
    let slab = sph_core::Scene::dam_break(0.25, 0.08, 0.02)
        .particles()
        .unwrap();
    assert!(
        text.contains(&format!("slab dam break, {} particles", slab.len())),
        "{text}"
    );
    // Each with its solver, the default marked.
    assert_eq!(text.matches(" particles, pbf").count(), 6, "{text}");
    assert!(
        text.contains("5500 particles, pbf (the default)\n"),
        "{text}"
    );
}

/// Runs a failing command: non-zero exit, a message containing `expected`, no panic.
fn fails_with(args: &[&str], expected: &str) {
    let o = app(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} succeeded");
    assert!(err.contains(expected), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
}

#[test]
fn bad_input_is_a_clear_error_and_a_failure() {
    let dir = scratch("errors");
    std::fs::create_dir_all(&dir).unwrap();
    fails_with(
        &["--headless", "--scene", "atlantis"],
        "unknown scene `atlantis`",
    );
    fails_with(&["--iterations", "7"], "--iterations");
    fails_with(&["--fps", "0"], "fps must lie in [1, 1000]");
    fails_with(&["--fps", "0.0001"], "fps must lie in [1, 1000]");

    let syntax = dir.join("broken.toml");
    std::fs::write(&syntax, "name = \"x\"\nspacing = = 0.02\n").unwrap();
    fails_with(
        &["--headless", "--scene", syntax.to_str().unwrap()],
        "line 2",
    );

    let unknown = dir.join("unknown.toml");
    let mut text = sph_core::Scene::dam_break(0.1, 0.04, 0.02).to_toml();
    text.push_str("\n[wibble]\nx = 1\n");
    std::fs::write(&unknown, text).unwrap();
    fails_with(
        &["--headless", "--scene", unknown.to_str().unwrap()],
        "wibble",
    );

    let bad_h = dir.join("bad_h.toml");
    let text = sph_core::Scene::dam_break(0.1, 0.04, 0.02)
        .to_toml()
        .replace("h = 0.04", "h = -1.0");
    std::fs::write(&bad_h, text).unwrap();
    fails_with(
        &["--headless", "--scene", bad_h.to_str().unwrap()],
        "fluid.h",
    );

    // A folder below a regular file cannot be created, even by root.
    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    let out = file.join("frames");
    fails_with(
        &[
            "--headless",
            "--frames",
            "1",
            "--out",
            out.to_str().unwrap(),
        ],
        "cannot write to",
    );
}

#[test]
fn without_an_adapter_it_still_simulates_extracts_and_exports() {
    let out = scratch("no-adapter");
    // No Metal backend exists on Linux: wgpu finds no adapter at all.
    let o = Command::new(env!("CARGO_BIN_EXE_sph-app"))
        .args([
            "--headless",
            "--frames",
            "2",
            "--export-particles",
            "vtk",
            "--out",
        ])
        .arg(&out)
        .env("WGPU_BACKEND", "metal")
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("mesa-vulkan-drivers"), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
    assert!(out.join("particles_00001.vtk").exists());
    assert!(!out.join("frame_00000.png").exists());
}

/// Mean position and mean speed of an exported particle frame.
fn bulk(path: &Path) -> (glam::Vec3, f32) {
    let p = read_ply(std::fs::File::open(path).unwrap()).unwrap();
    let n = p.positions.len() as f32;
    let mean = p.positions.iter().copied().sum::<glam::Vec3>() / n;
    let v = p.vector("velocity").unwrap();
    (mean, v.iter().map(|v| v.length()).sum::<f32>() / n)
}

/// `--gpu-sim` runs the scene's solver on the GPU, and its particles and
/// frame statistics follow the CPU's: WCSPH and PBF.
#[test]
fn gpu_sim_follows_the_cpu_solver() {
    let run = |name: &str, solver: &str, gpu: bool| {
        let out = scratch(&format!("{name}-{solver}"));
        let mut args = vec![
            "--headless",
            "--scene",
            "dam-break",
            "--frames",
            "3",
            "--width",
            "64",
            "--height",
            "48",
            "--export-particles",
            "ply",
            "--solver",
            solver,
            "--out",
            out.to_str().unwrap(),
        ];
        if gpu {
            args.push("--gpu-sim");
        }
        (app(&args), out)
    };
    for solver in ["wcsph", "pbf"] {
        let (o, gpu) = run("gpu-sim", solver, true);
        if skipped_without_adapter(&o) {
            return;
        }
        assert!(o.status.success(), "{}", stderr(&o));
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(
            stdout.contains(&format!("solver {solver} (SPH step on the GPU)")),
            "{stdout}"
        );
        let (o, cpu) = run("cpu-sim", solver, false);
        assert!(o.status.success(), "{}", stderr(&o));
        // 0.1 s of collapse, the same substeps on both paths (WCSPH: the
        // GPU chooses its step as World::advance does): the bulk motion
        // agrees. Measured on lavapipe: WCSPH (2026-11-22) mean positions
        // within 9.3e-7 m, mean speeds within 1.3e-4 of each other
        // (relative); PBF (2026-11-26) 1.6e-7 m, mean speeds equal to
        // five digits. Bounds 10× and 8× WCSPH's.
        for i in 0..3 {
            let file = format!("particles_{i:05}.ply");
            let ((xg, vg), (xc, vc)) = (bulk(&gpu.join(&file)), bulk(&cpu.join(&file)));
            eprintln!(
                "{solver} frame {i}: |Δ mean x| = {:.3e} m, mean speed {vg:.5} vs {vc:.5} m/s",
                (xg - xc).length()
            );
            assert!((xg - xc).length() < 1e-5, "frame {i}: mean {xg} vs {xc}");
            assert!(
                (vg - vc).abs() < 1e-3 * vc.max(1e-3),
                "frame {i}: speed {vg} vs {vc}"
            );
        }
        // Each frame's row: the same substeps and iterations; PBF's density
        // errors (back from the GPU a frame late) close to the CPU's, WCSPH
        // on the GPU reports none.
        let rows = |dir: &Path| -> Vec<Vec<String>> {
            let csv = std::fs::read_to_string(dir.join("frames.csv")).unwrap();
            (csv.lines().skip(1))
                .map(|l| l.split(',').map(str::to_owned).collect())
                .collect()
        };
        let (g, c) = (rows(&gpu), rows(&cpu));
        assert_eq!(g.len(), 3, "three rows");
        for (i, (g, c)) in g.iter().zip(&c).enumerate() {
            assert_eq!(g[0], i.to_string(), "rows in frame order");
            assert_eq!(
                g[9..12],
                c[9..12],
                "frame {i}: solver, substeps, iterations"
            );
            if solver == "pbf" {
                let (eg, ec): (f32, f32) = (g[12].parse().unwrap(), c[12].parse().unwrap());
                eprintln!("pbf frame {i}: density error avg {eg} on the GPU, {ec} on the CPU");
                assert!(
                    (eg - ec).abs() <= 0.02 * ec + 1e-5,
                    "frame {i}: {eg} vs {ec}"
                );
            } else {
                assert_eq!(
                    g[12], "",
                    "frame {i}: WCSPH on the GPU has no density error"
                );
            }
        }
    }
}

#[test]
fn gpu_paths_without_an_adapter_are_a_clear_error() {
    for flag in ["--gpu-sim", "--gpu-extract"] {
        let o = Command::new(env!("CARGO_BIN_EXE_sph-app"))
            .args(["--headless", "--frames", "1", flag, "--out"])
            .arg(scratch(&format!(
                "{}-no-adapter",
                flag.trim_start_matches('-')
            )))
            .env("WGPU_BACKEND", "metal")
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap();
        assert!(!o.status.success());
        let expected = format!("{flag} needs a GPU adapter");
        assert!(stderr(&o).contains(&expected), "{}", stderr(&o));
    }
}

#[test]
fn gpu_extract_draws_and_exports_the_gpu_surfels() {
    for (name, extra) in [
        ("gpu-extract", None),
        (
            "gpu-sim-and-extract",
            Some(["--gpu-sim", "--solver", "wcsph"]),
        ),
    ] {
        let out = scratch(name);
        let mut args = vec![
            "--headless",
            "--scene",
            "dam-break",
            "--frames",
            "2",
            "--width",
            "64",
            "--height",
            "48",
            "--export-surfels",
            "ply",
            "--gpu-extract",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra.into_iter().flatten());
        let o = app(&args);
        if skipped_without_adapter(&o) {
            return;
        }
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(stdout.contains("surfels extracted on the GPU"), "{stdout}");
        let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
        assert_eq!(
            csv.lines().count(),
            3,
            "{name}: a header and 2 frames\n{csv}"
        );
        for (i, line) in csv.lines().skip(1).enumerate() {
            let surfels: usize = line.split(',').nth(3).unwrap().parse().unwrap();
            let file = out.join(format!("surfels_{i:05}.ply"));
            let cloud = read_ply(std::fs::File::open(&file).unwrap()).unwrap();
            eprintln!("{name} frame {i}: {surfels} surfels");
            assert!(surfels > 100, "{name}: {line}");
            assert_eq!(cloud.positions.len(), surfels, "{name}: {line}");
            assert!(out.join(format!("frame_{i:05}.png")).exists());
        }
    }
}

#[test]
fn gpu_sim_refuses_a_scene_with_emitters() {
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/scenes/drop_into_pool.toml"
    );
    let out = scratch("gpu-sim-emitters");
    let o = app(&[
        "--headless",
        "--frames",
        "1",
        "--scene",
        scene,
        "--gpu-sim",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    if skipped_without_adapter(&o) {
        return;
    }
    let err = stderr(&o);
    assert!(err.contains("emitters are not on the GPU path"), "{err}");
}

/// `--cull` keeps only the surfels facing the scene's camera: fewer surfels
/// in `frames.csv` than the same frame without it.
#[test]
fn cull_extracts_only_front_facing_surfels() {
    let surfels = |cull: bool| {
        let out = scratch(if cull { "cull" } else { "no-cull" });
        let mut args = vec![
            "--headless",
            "--frames",
            "2",
            "--width",
            "32",
            "--height",
            "32",
            "--out",
            out.to_str().unwrap(),
        ];
        if cull {
            args.push("--cull");
        }
        let o = app(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
        let last = csv.lines().last().unwrap().to_owned();
        last.split(',').nth(3).unwrap().parse::<usize>().unwrap()
    };
    let (all, front) = (surfels(false), surfels(true));
    assert!(0 < front && front < 3 * all / 4, "{front} of {all} surfels");
}

/// The GPU path runs PBF and WCSPH: `--gpu-sim` on a DFSPH scene is refused
/// with the way out, not switched silently; the scene's own PBF runs.
#[test]
fn gpu_sim_refuses_dfsph_and_says_which_solvers_it_runs() {
    let out = scratch("gpu-sim-dfsph");
    let args = [
        "--headless",
        "--scene",
        "dam-break",
        "--frames",
        "1",
        "--width",
        "64",
        "--height",
        "48",
        "--gpu-sim",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = app(&[&args[..], &["--solver", "dfsph"]].concat());
    assert!(!o.status.success());
    if skipped_without_adapter(&o) {
        return;
    }
    let err = stderr(&o);
    assert!(
        err.contains("the GPU path runs PBF and the thesis's WCSPH, and this scene runs dfsph")
            && err.contains("--solver pbf"),
        "{err}"
    );
    let o = app(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("solver pbf (SPH step on the GPU)"),
        "{stdout}"
    );
}

/// `--solver` overrides the scene's choice, and a wrong name lists the
/// solvers.
#[test]
fn solver_flag_chooses_and_bad_names_are_errors() {
    let out = scratch("solver-flag");
    let o = app(&[
        "--headless",
        "--frames",
        "1",
        "--width",
        "32",
        "--height",
        "32",
        "--solver",
        "wcsph",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    assert_eq!(row[9], "wcsph", "{csv}");
    assert_eq!(row[11], "0", "WCSPH has no iterations: {csv}");
    assert!(
        row[10].parse::<u32>().unwrap() > 10,
        "WCSPH's small steps: {csv}"
    );
    // DFSPH: steps by the flow's speed, both solves' iterations, all
    // converged; the collapsing column shears from the first frame, so
    // the implicit viscosity iterates (the `drop` scene's pool is still).
    let o = app(&[
        "--headless",
        "--scene",
        "dam-break",
        "--frames",
        "2",
        "--width",
        "32",
        "--height",
        "32",
        "--solver",
        "dfsph",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    for line in csv.lines().skip(1) {
        let row: Vec<&str> = line.split(',').collect();
        assert_eq!(row[9], "dfsph", "{csv}");
        let number = |k: usize| row[k].parse::<u32>().unwrap();
        assert!(number(10) >= 1 && number(11) >= 2 * number(10), "{csv}");
        assert!(number(15) >= number(10), "{csv}");
        assert!(number(16) >= 1, "implicit viscosity: {csv}");
        assert_eq!(row[17], "0", "unconverged: {csv}");
        let max: f32 = row[13].parse().unwrap();
        assert!(max < 0.02, "{csv}");
    }
    let o = app(&["--headless", "--solver", "flip"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("one of wcsph, pbf, dfsph"),
        "{}",
        stderr(&o)
    );
    // A DFSPH scene with a μ run by PBF: its XSPH blend gives way to the
    // implicit viscosity, with a note, rather than the scene being refused.
    let slab = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/scenes/dam_break_slab.toml"
    );
    let text = std::fs::read_to_string(slab).unwrap();
    let water = (text.replacen(
        "rest_density = 1000.0\n",
        "rest_density = 1000.0\nviscosity = 0.001\n",
        1,
    ))
    .replacen("kind = \"pbf\"", "kind = \"dfsph\"", 1);
    let file = out.join("water.toml");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(&file, water).unwrap();
    let o = app(&[
        "--headless",
        "--scene",
        file.to_str().unwrap(),
        "--frames",
        "1",
        "--width",
        "32",
        "--height",
        "32",
        "--solver",
        "pbf",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("solves the scene's μ"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert_eq!(
        csv.lines().nth(1).unwrap().split(',').nth(9),
        Some("pbf"),
        "{csv}"
    );
}

/// `--gif` writes the run as a looping animated GIF that decodes, one frame
/// per rendered frame; a GIF path that cannot be written stops the run
/// before anything is written.
#[test]
fn gif_clip_decodes_and_a_bad_path_fails_first() {
    use image::AnimationDecoder;
    let out = scratch("gif");
    let gif = out.join("clip.gif");
    std::fs::create_dir_all(&out).unwrap();
    let o = app(&[
        "--headless",
        "--scene",
        "dam-break",
        "--frames",
        "4",
        "--width",
        "80",
        "--height",
        "48",
        "--gif",
        gif.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    if skipped_without_adapter(&o) {
        return;
    }
    assert!(o.status.success(), "{}", stderr(&o));
    // Each frame's size and delay (ms).
    let decoded = |gif: &std::path::Path| {
        let file = std::io::BufReader::new(std::fs::File::open(gif).unwrap());
        let frames = image::codecs::gif::GifDecoder::new(file)
            .unwrap()
            .into_frames()
            .collect_frames()
            .unwrap();
        (frames.iter())
            .map(|f| {
                let (numer, denom) = f.delay().numer_denom_ms();
                (f.buffer().dimensions(), numer / denom)
            })
            .collect::<Vec<_>>()
    };
    // 30 fps in whole hundredths: each frame ends at its rounded time
    // (3.33, 6.67, 10, 13.33 cs), so the clip keeps 30 fps on average.
    let sizes = (80, 48);
    assert_eq!(
        decoded(&gif),
        [(sizes, 30), (sizes, 40), (sizes, 30), (sizes, 30)]
    );
    // 50 fps, the most: every frame 2/100 s.
    let o = app(&[
        "--headless",
        "--scene",
        "dam-break",
        "--frames",
        "3",
        "--fps",
        "50",
        "--width",
        "80",
        "--height",
        "48",
        "--gif",
        gif.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(decoded(&gif), [(sizes, 20); 3]);
    // Above 50 fps a GIF cannot show each frame for 1/fps s in a browser.
    for fps in ["60", "200"] {
        let o = app(&[
            "--headless",
            "--frames",
            "2",
            "--fps",
            fps,
            "--gif",
            gif.to_str().unwrap(),
        ]);
        assert!(!o.status.success());
        assert!(stderr(&o).contains("at most at 50 fps"), "{}", stderr(&o));
    }
    let bad = scratch("gif-bad");
    let o = app(&[
        "--headless",
        "--frames",
        "2",
        "--gif",
        "/nonexistent/folder/clip.gif",
        "--out",
        bad.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("cannot write to /nonexistent/folder/clip.gif"),
        "{}",
        stderr(&o)
    );
    assert!(!bad.exists(), "the run started before the GIF failed");
}

/// Every file the headless writer makes reports a failed write (a full
/// disk: the file is a link to `/dev/full`) as an error naming it, and the
/// run stops: the frame's PNG and the GIF (which fit their writers' buffers
/// until they are flushed), `frames.csv`, and the particle and surfel
/// exports in both formats.
#[test]
fn every_output_reports_a_full_disk() {
    let cases = [
        ("frame_00000.png", "ply"),
        ("clip.gif", "ply"),
        ("frames.csv", "ply"),
        ("particles_00000.ply", "ply"),
        ("surfels_00000.ply", "ply"),
        ("particles_00000.vtk", "vtk"),
        ("surfels_00000.vtk", "vtk"),
    ];
    for (name, format) in cases {
        let out = scratch(&format!("full-{name}"));
        std::fs::create_dir_all(&out).unwrap();
        let file = out.join(name);
        std::os::unix::fs::symlink("/dev/full", &file).unwrap();
        let mut args = vec![
            "--headless",
            "--scene",
            "dam-break",
            "--frames",
            "2",
            "--width",
            "64",
            "--height",
            "48",
            "--export-particles",
            format,
            "--export-surfels",
            format,
            "--out",
            out.to_str().unwrap(),
        ];
        let gif = file.to_str().unwrap();
        if name.ends_with(".gif") {
            args.extend(["--gif", gif]);
        }
        let o = app(&args);
        // Without an adapter no image is written (the PNG: nothing to fail;
        // the GIF: refused first).
        if (name.ends_with(".png") || name.ends_with(".gif"))
            && stderr(&o).contains("mesa-vulkan-drivers")
            && std::env::var("SPH_REQUIRE_GPU").as_deref() != Ok("1")
        {
            eprintln!("skipped {name}: no GPU adapter");
            continue;
        }
        assert!(
            !o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stdout)
        );
        let said = stderr(&o);
        assert!(
            said.contains(&file.display().to_string()) && said.contains("No space left"),
            "{name}: {said}"
        );
    }
}

/// On wgpu's GL backend (`WGPU_BACKEND=gl`), which cannot read depth
/// textures as the splat passes do, the headless run exits non-zero with
/// one line naming the backend and what it lacks (or, where there is no GL
/// adapter at all, simulates without images as without any adapter): no
/// panic from a pipeline that fails validation.
#[test]
fn the_gl_backend_is_declined_not_a_panic() {
    let out = scratch("gl-backend");
    let o = Command::new(env!("CARGO_BIN_EXE_sph-app"))
        .args(["--headless", "--scene", "dam-break", "--frames", "2"])
        .args(["--width", "64", "--height", "48", "--out"])
        .arg(&out)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .env("WGPU_BACKEND", "gl")
        .output()
        .expect("the binary runs");
    let said = stderr(&o);
    assert!(!said.contains("panicked"), "{said}");
    if said.contains("no GPU adapter") {
        // No GL driver on this machine.
        assert!(o.status.success(), "{said}");
        assert!(!out.join("frame_00000.png").exists());
        return;
    }
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert_eq!(said.trim_end().lines().count(), 1, "one line: {said}");
    assert!(
        said.contains("wgpu's GL backend") && said.contains("textureLoad"),
        "{said}"
    );
    assert!(!out.join("frame_00000.png").exists());
}

/// Where a run goes without a flag: the whole GPU path on a hardware
/// adapter, the CPU path on a software one (lavapipe here and in CI), and
/// `--cpu` keeps it on the CPU anywhere.
#[test]
fn a_software_adapter_runs_the_cpu_path_by_default() {
    let Some(ctx) = splat_render::GpuContext::headless_or_skip() else {
        return;
    };
    for extra in [&[][..], &["--cpu"][..]] {
        let out = scratch(&format!("default-path{}", extra.len()));
        let mut args = vec!["--headless", "--scene", "drop", "--frames", "2"];
        args.extend(["--width", "64", "--height", "48", "--out"]);
        args.push(out.to_str().unwrap());
        args.extend(extra);
        let o = app(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let stdout = String::from_utf8_lossy(&o.stdout);
        let on_gpu = stdout.contains("(SPH step on the GPU)")
            && stdout.contains("(surfels extracted on the GPU)");
        let expected = extra.is_empty() && !ctx.is_software();
        assert_eq!(
            on_gpu,
            expected,
            "{extra:?} on {}: {stdout}",
            ctx.adapter_summary()
        );
    }
}

/// `--splats compute` draws the frames `--splats raster` draws (FLIP ≤
/// 0.01), from the same CPU simulation and extraction, and from the GPU
/// extraction's buffers (splats that never leave the GPU).
#[test]
fn compute_splats_draw_the_raster_frames() {
    for extraction in ["--cpu", "--gpu-extract"] {
        compute_splats_draw_the_raster_frame(extraction);
    }
    let o = app(&["--headless", "--splats", "tiles"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("raster"), "{}", stderr(&o));
}

fn compute_splats_draw_the_raster_frame(extraction: &str) {
    let mut frames = Vec::new();
    for path in ["raster", "compute"] {
        let out = scratch(&format!("splats-{path}{extraction}"));
        let o = app(&[
            "--headless",
            "--scene",
            "drop",
            "--frames",
            "2",
            "--width",
            "160",
            "--height",
            "96",
            extraction,
            "--splats",
            path,
            "--out",
            out.to_str().unwrap(),
        ]);
        if skipped_without_adapter(&o) {
            return;
        }
        assert!(o.status.success(), "{path}: {}", stderr(&o));
        match image::open(out.join("frame_00001.png")) {
            Ok(image) => frames.push(image.to_rgba8()),
            // Without an adapter nothing is drawn (the run still succeeds).
            Err(_) if std::env::var("SPH_REQUIRE_GPU").as_deref() != Ok("1") => {
                eprintln!("skipped: no GPU adapter");
                return;
            }
            Err(e) => panic!("{path}: no frame: {e}"),
        }
    }
    let mean = common::flip(&frames[0], &frames[1]);
    eprintln!("{extraction}: FLIP mean compute vs raster {mean:e}");
    assert!(mean <= 0.01, "{extraction}: FLIP mean {mean}");
}

/// A scene whose camera stands 300 m out (with a field of view narrowed to
/// frame the same tank) draws the tank and its fluid, as the scene's own
/// 1.2 m camera does: the headless camera's clip planes scale with its
/// distance. Against the near frame (whose perspective and ground differ)
/// FLIP reads 0.223 with the scaled planes, and 0.400 with planes fixed at
/// 0.01–100 m, where the far frame held the background alone. Held: < 0.3.
#[test]
fn a_distant_camera_still_draws_the_fluid() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/scenes/dam_break_slab.toml"
    ))
    .unwrap();
    let (camera, look_at) = (
        glam::Vec3::new(0.5, 0.744, 1.112),
        glam::Vec3::new(0.5, 0.208, 0.04),
    );
    assert!(text.contains("camera = [0.5, 0.744, 1.112]") && text.contains("fov_y = 45.0"));
    let d = camera - look_at;
    let k = 300.0 / d.length();
    let far = look_at + d * k;
    let fov = 2.0 * ((22.5f32).to_radians().tan() / k).atan().to_degrees();
    let far_text = text
        .replace(
            "camera = [0.5, 0.744, 1.112]",
            &format!("camera = [{}, {}, {}]", far.x, far.y, far.z),
        )
        .replace("fov_y = 45.0", &format!("fov_y = {fov}"));
    let mut frames = Vec::new();
    for (name, scene) in [("near", text), ("far", far_text)] {
        let out = scratch(&format!("distant-{name}"));
        std::fs::create_dir_all(&out).unwrap();
        let path = out.join("scene.toml");
        std::fs::write(&path, scene).unwrap();
        let o = app(&[
            "--headless",
            "--scene",
            path.to_str().unwrap(),
            "--frames",
            "1",
            "--width",
            "96",
            "--height",
            "54",
            "--out",
            out.to_str().unwrap(),
        ]);
        if skipped_without_adapter(&o) {
            return;
        }
        assert!(o.status.success(), "{}", stderr(&o));
        frames.push(image::open(out.join("frame_00000.png")).unwrap().to_rgba8());
    }
    let error = common::flip(&frames[0], &frames[1]);
    println!("FLIP, far against near: {error:.3}");
    assert!(error < 0.3, "{error}");
}
