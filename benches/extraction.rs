//! `cargo bench --bench extraction`: the thesis's Table 2 — surfel extraction with
//! 1, 2 and 3 refinement iterations and the LDC reference — on a 2,250-particle
//! dam-break frame (the thesis's size) and a 101k-particle one. Each timed run
//! includes building the colour field (grid and volumes) from the particles.
//! Runs go through one `Extractor` kept across runs, as a real-time loop keeps
//! it across frames; at 2 iterations the one-shot `extract` (fresh memory
//! every call) is timed beside it (`one-shot`).
//! Throughput is in surfels. Before timing, one untimed run per configuration
//! prints surfels, evaluations, efficiency (surfels per surfel evaluation) and
//! coverage of independently found iso-surface points, for the default and the
//! thesis-faithful mode. With 2 and 3 iterations the default mode also runs
//! with the thesis's 2×2 first split (`iterations-2x2`), the default before
//! the 3×3 one.
//! The anisotropic field (Yu & Turk 2013, `anisotropic`) at 2 iterations,
//! with its kernel pass timed alone (`anisotropic-kernels`: the field built
//! without extracting). In the same run, splashsurf's
//! `reconstruct_surface_inplace` (marching cubes, its output and workspace
//! kept across runs) on the same particles is the peer, bare and with its
//! CLI's smoothing (`splashsurf-smoothed`: 25 Laplacian iterations of the
//! mesh, β = 1, uniform weights, and 10 of the vertex normals).
//!
//! `real-data`: other simulators' frames (splashsurf's test data,
//! `tests/data/splashsurf/`: SPlisHSPlasH's BGEO dam break, 6,859 particles,
//! and its double dam break's frame 26, 4,732), as `sph-app --input` plays
//! them (r = 0.025 m, h = 4r, the anisotropic surface, 2 iterations), against
//! splashsurf reconstructing the same particles with its README's
//! recommended settings (the particle radius, smoothing length 2r: support
//! 4r, surface threshold 0.6, cubes of 0.5r), unsmoothed: `splashsurf_lib`
//! in memory, and, where the splashsurf CLI runs (`SPLASHSURF=path` or
//! `splashsurf` on the PATH; `cargo install splashsurf --version 0.14.1`),
//! the CLI as a user runs it on the file (`splashsurf-cli`: the whole
//! process, reading the file and writing the mesh).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use sph_core::{Particles, Scene};
use splashsurf_lib::nalgebra::Vector3;
use surfel_extract::coverage::{covered_fraction, iso_points};
use surfel_extract::ldc::extract_ldc;
use surfel_extract::{ColourField, ExtractParams, Extractor, Split, Surfel, extract};

/// The dam break `Scene::dam_break(a, depth, 0.01)` after `t` seconds.
fn frame(a: f32, depth: f32, t: f32) -> Particles {
    let mut world = Scene::dam_break(a, depth, 0.01)
        .build_world()
        .expect("built-in scene");
    world.advance(t).expect("stable");
    world.particles
}

fn extraction(c: &mut Criterion) {
    let mut group = c.benchmark_group("extraction");
    group.sample_size(10);
    for (label, particles) in [
        ("2k", frame(0.15, 0.05, 0.3)),
        ("100k", frame(0.37, 0.37, 0.1)),
    ] {
        let h = 0.02;
        // Untimed: coverage of iso-surface points found by bisection (spacing
        // h/4, disc thickness h/10), and the thesis-faithful mode beside.
        let field = ColourField::from_particles(&particles, h).expect("field");
        let points = iso_points(&field, 0.5, 0.25 * h).expect("iso points");
        let mut extractor = Extractor::new();
        let mut run = |params: &ExtractParams| {
            extractor
                .extract(&particles, params)
                .expect("extraction")
                .stats
                .surfels
        };
        for iterations in 1..=3 {
            let params = ExtractParams {
                iterations,
                ..ExtractParams::new(h)
            };
            let out = extract(&particles, &params).expect("extraction");
            let thesis = extract(&particles, &params.thesis()).expect("extraction");
            let coverage = |s: &[Surfel]| {
                100.0
                    * covered_fraction(s, &points, 0.1 * h)
                        .expect("finite surfels and an iso-surface")
            };
            let s = out.stats;
            println!(
                "{label} ({} particles), {iterations} iterations: {} surfels, {} surfel + {} particle evaluations, efficiency {:.2}, coverage {:.2} % of {} iso points; thesis mode: {} surfels, efficiency {:.2}, coverage {:.2} %",
                particles.len(),
                s.surfels,
                s.evaluations,
                s.particle_evaluations,
                s.efficiency(),
                coverage(&out.surfels),
                points.len(),
                thesis.stats.surfels,
                thesis.stats.efficiency(),
                coverage(&thesis.surfels),
            );
            group.throughput(Throughput::Elements(s.surfels as u64));
            group.bench_function(
                BenchmarkId::new(format!("{label}/iterations"), iterations),
                |b| b.iter(|| black_box(run(&params))),
            );
            if iterations == 2 {
                group.bench_function(
                    BenchmarkId::new(format!("{label}/one-shot"), iterations),
                    |b| b.iter(|| black_box(extract(&particles, &params).expect("extraction"))),
                );
            }
            if iterations > 1 {
                let params = ExtractParams {
                    first_split: Split::TwoByTwo,
                    ..params
                };
                let out = extract(&particles, &params).expect("extraction");
                let s = out.stats;
                println!(
                    "{label}, {iterations} iterations, 2×2 first split: {} surfels, {} surfel evaluations, efficiency {:.2}, coverage {:.2} %",
                    s.surfels,
                    s.evaluations,
                    s.efficiency(),
                    coverage(&out.surfels),
                );
                group.throughput(Throughput::Elements(s.surfels as u64));
                group.bench_function(
                    BenchmarkId::new(format!("{label}/iterations-2x2"), iterations),
                    |b| b.iter(|| black_box(run(&params))),
                );
            }
        }
        // The anisotropic field at 2 iterations, and its field alone.
        let params = ExtractParams {
            iterations: 2,
            ..ExtractParams::new(h)
        }
        .anisotropic();
        let out = extract(&particles, &params).expect("extraction");
        let s = out.stats;
        let mut field = ColourField::new(params.surface).expect("valid");
        field.refill_from_particles(&particles, h).expect("field");
        let aniso_points = iso_points(&field, 0.5, 0.25 * h).expect("iso points");
        println!(
            "{label} anisotropic, 2 iterations: {} surfels, {} surfel + {} particle evaluations, coverage {:.2} % of {} iso points; stages (ms): field {:.1}, initial guess {:.1}, refinement {:.1}, hole closing {:.1}",
            s.surfels,
            s.evaluations,
            s.particle_evaluations,
            100.0
                * covered_fraction(&out.surfels, &aniso_points, 0.1 * h)
                    .expect("finite surfels and an iso-surface"),
            aniso_points.len(),
            s.field_time.as_secs_f64() * 1e3,
            s.initial_time.as_secs_f64() * 1e3,
            s.refine_time.as_secs_f64() * 1e3,
            s.fill_time.as_secs_f64() * 1e3,
        );
        group.throughput(Throughput::Elements(s.surfels as u64));
        group.bench_function(BenchmarkId::new(label, "anisotropic"), |b| {
            b.iter(|| black_box(run(&params)))
        });
        group.throughput(Throughput::Elements(particles.len() as u64));
        group.bench_function(BenchmarkId::new(label, "anisotropic-kernels"), |b| {
            b.iter(|| {
                field.refill_from_particles(&particles, h).expect("field");
                black_box(field.len())
            })
        });

        let params = ExtractParams::new(h);
        let ldc = |p: &Particles| {
            let field = ColourField::from_particles(p, h).expect("field");
            extract_ldc(&field, &params, 0.5 * h).expect("ldc")
        };
        let out = ldc(&particles);
        println!(
            "{label} LDC at h/2: {} surfels, {} evaluations, efficiency {:.2}",
            out.stats.surfels,
            out.stats.evaluations,
            out.stats.efficiency()
        );
        group.throughput(Throughput::Elements(out.stats.surfels as u64));
        group.bench_function(BenchmarkId::new(label, "ldc"), |b| {
            b.iter(|| black_box(ldc(&particles)))
        });

        // The peer: splashsurf's marching cubes on the same particles, kernel
        // support h (= 4 particle radii at spacing h/2) and cubes of one particle
        // radius (h/4), multi-threaded; throughput counts mesh vertices.
        let positions: Vec<Vector3<f32>> = particles
            .positions()
            .iter()
            .map(|x| Vector3::new(x.x, x.y, x.z))
            .collect();
        let mut sp = splashsurf_lib::Parameters::new(0.25 * h, h, 0.25 * h);
        sp.iso_surface_threshold = 0.6;
        let mut surface = splashsurf_lib::SurfaceReconstruction::<i64, f32>::default();
        let mut mc = |x: &[Vector3<f32>]| {
            splashsurf_lib::reconstruct_surface_inplace(x, &sp, &mut surface).expect("splashsurf");
            surface.mesh.vertices.len()
        };
        let vertices = mc(&positions);
        let mesh = splashsurf_lib::reconstruct_surface::<i64, f32>(&positions, &sp)
            .expect("splashsurf")
            .mesh;
        assert_eq!(mesh.vertices.len(), vertices);
        println!(
            "{label} splashsurf (cube h/4): {} vertices, {} triangles",
            mesh.vertices.len(),
            mesh.triangles.len()
        );
        group.throughput(Throughput::Elements(mesh.vertices.len() as u64));
        group.bench_function(BenchmarkId::new(label, "splashsurf"), |b| {
            b.iter(|| black_box(mc(&positions)))
        });
        let mut smoothed = |x: &[Vector3<f32>]| {
            use splashsurf_lib::mesh::Mesh3d;
            use splashsurf_lib::postprocessing::{
                par_laplacian_smoothing_inplace, par_laplacian_smoothing_normals_inplace,
            };
            splashsurf_lib::reconstruct_surface_inplace(x, &sp, &mut surface).expect("splashsurf");
            let mesh = &mut surface.mesh;
            let connectivity = mesh.vertex_vertex_connectivity();
            let weights = vec![1.0f32; mesh.vertices.len()];
            par_laplacian_smoothing_inplace(mesh, &connectivity, 25, 1.0, &weights);
            let mut normals: Vec<Vector3<f32>> = (mesh.par_vertex_normals().iter())
                .map(|n| n.into_inner())
                .collect();
            par_laplacian_smoothing_normals_inplace(&mut normals, &connectivity, 10);
            normals.len()
        };
        group.bench_function(BenchmarkId::new(label, "splashsurf-smoothed"), |b| {
            b.iter(|| black_box(smoothed(&positions)))
        });
    }
    group.finish();
}

/// Other simulators' frames: this project's extraction against splashsurf's
/// reconstruction with its README's settings.
fn real_data(c: &mut Criterion) {
    let mut group = c.benchmark_group("real-data");
    group.sample_size(10);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/splashsurf");
    let r = 0.025f32;
    let h = 4.0 * r;
    for (label, file) in [
        ("dam-break-bgeo", "dam_break_frame_9_6859_particles.bgeo"),
        (
            "double-dam-break-vtk",
            "double_dam_break_frame_26_4732_particles.vtk",
        ),
    ] {
        let positions: Vec<Vector3<f32>> =
            splashsurf_lib::io::particles_from_file(dir.join(file)).expect("splashsurf's data");
        let mut particles = Particles::new();
        let mass = 1000.0 * (2.0 * r).powi(3);
        for x in &positions {
            particles.push(
                sph_core::glam::Vec3::new(x.x, x.y, x.z),
                Default::default(),
                mass,
            );
        }
        particles.densities_mut().fill(1000.0);
        let params = ExtractParams {
            surface: surfel_extract::Surface::anisotropic(),
            ..ExtractParams::new(h)
        };
        let mut extractor = Extractor::new();
        let surfels = extractor
            .extract(&particles, &params)
            .expect("extraction")
            .stats
            .surfels;
        let mut sp = splashsurf_lib::Parameters::new(r, h, 0.5 * r);
        sp.iso_surface_threshold = 0.6;
        let mut surface = splashsurf_lib::SurfaceReconstruction::<i64, f32>::default();
        splashsurf_lib::reconstruct_surface_inplace(&positions, &sp, &mut surface)
            .expect("splashsurf");
        println!(
            "{label}: {} particles, {surfels} surfels; splashsurf (README settings): {} vertices, {} triangles",
            positions.len(),
            surface.mesh.vertices.len(),
            surface.mesh.triangles.len()
        );
        group.bench_function(BenchmarkId::new(label, "anisotropic"), |b| {
            b.iter(|| {
                black_box(
                    extractor
                        .extract(&particles, &params)
                        .expect("extraction")
                        .stats
                        .surfels,
                )
            })
        });
        // As `sph-app --input` takes a frame: the file read (by the same
        // reader), the particles built, the surfels extracted.
        group.bench_function(BenchmarkId::new(label, "anisotropic+read"), |b| {
            b.iter(|| {
                let read: Vec<Vector3<f32>> =
                    splashsurf_lib::io::particles_from_file(dir.join(file)).expect("read");
                let mut p = Particles::new();
                for x in &read {
                    p.push(
                        sph_core::glam::Vec3::new(x.x, x.y, x.z),
                        Default::default(),
                        mass,
                    );
                }
                p.densities_mut().fill(1000.0);
                black_box(
                    extractor
                        .extract(&p, &params)
                        .expect("extraction")
                        .stats
                        .surfels,
                )
            })
        });
        group.bench_function(BenchmarkId::new(label, "splashsurf"), |b| {
            b.iter(|| {
                splashsurf_lib::reconstruct_surface_inplace(&positions, &sp, &mut surface)
                    .expect("splashsurf");
                black_box(surface.mesh.vertices.len())
            })
        });
        // The CLI itself, where one is installed: the whole process, reading
        // the file and writing the mesh included.
        match splashsurf_cli() {
            Some(cli) => {
                let out = std::env::temp_dir().join(format!("real-data-{label}.vtk"));
                let run = || {
                    let status = std::process::Command::new(&cli)
                        .arg("reconstruct")
                        .arg(dir.join(file))
                        .args([
                            "-r", "0.025", "-l", "2.0", "-c", "0.5", "-t", "0.6", "-q", "-o",
                        ])
                        .arg(&out)
                        .status()
                        .expect("the splashsurf CLI runs");
                    assert!(status.success(), "splashsurf CLI: {status}");
                };
                run();
                group.bench_function(BenchmarkId::new(label, "splashsurf-cli"), |b| b.iter(run));
            }
            None => println!(
                "{label}: no splashsurf CLI (`cargo install splashsurf --version 0.14.1`, \
                 or SPLASHSURF=path): its row is skipped"
            ),
        }
    }
    group.finish();
}

/// The splashsurf CLI: `SPLASHSURF`, else `splashsurf` where it runs.
fn splashsurf_cli() -> Option<std::path::PathBuf> {
    let cli = std::env::var_os("SPLASHSURF").unwrap_or_else(|| "splashsurf".into());
    let runs = std::process::Command::new(&cli)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    runs.then(|| cli.into())
}

criterion_group!(benches, extraction, real_data);
criterion_main!(benches);
