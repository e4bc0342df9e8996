//! The extractor against the field it samples: placement residuals, normals,
//! coverage of independently found iso-surface points, degenerate inputs and
//! determinism.

use glam::Vec3;
use sph_core::{Error, Scene};
use surfel_extract::coverage::{covered_fraction, iso_points, residuals};
use surfel_extract::ldc::extract_ldc;
use surfel_extract::samples::jittered_lattice;
use surfel_extract::{
    ColourField, ExtractParams, Extractor, Mode, Surfel, extract_field, extract_points,
};

const SPACING: f32 = 0.01;
const H: f32 = 2.0 * SPACING;

/// The tests' jittered lattice of `SPACING` cut by `keep`.
fn lattice(n: i32, keep: impl Fn(Vec3) -> bool) -> Vec<Vec3> {
    jittered_lattice(n, SPACING, 0.3, 11, keep)
}

fn sphere() -> Vec<Vec3> {
    lattice(9, |x| x.length() <= 8.5 * SPACING)
}

fn block() -> Vec<Vec3> {
    lattice(6, |x| x.x < 5.5 * SPACING && x.z > -3.5 * SPACING)
}

/// A dam-break frame: the thin-slab scene after 0.4 s of collapse.
fn dam_break_frame() -> sph_core::Particles {
    let mut world = Scene::dam_break(0.2, 0.06, 0.02).build_world().unwrap();
    world.advance(0.4).unwrap();
    world.particles
}

struct Quality {
    surfels: usize,
    coverage: f64,
    efficiency: f64,
}

fn check(name: &str, field: &ColourField, params: &ExtractParams) -> Quality {
    let out = extract_field(field, params).unwrap();
    let r = residuals(field, params.iso, &out.surfels);
    let points = iso_points(field, params.iso, 0.25 * H).expect("iso points");
    let coverage = covered_fraction(&out.surfels, &points, 0.1 * H).unwrap();
    println!(
        "{name} {:?}: {} surfels from {} particles, residual median {:.2e} p95 {:.2e}, normal median {:.2}°, coverage {:.2} % of {} iso points, efficiency {:.2}, stats {:?}",
        params.mode,
        out.surfels.len(),
        field.len(),
        r.median,
        r.p95,
        r.median_angle_deg,
        100.0 * coverage,
        points.len(),
        out.stats.efficiency(),
        out.stats
    );
    assert!(r.median < 0.01, "{name}: median residual {}", r.median);
    assert!(r.p95 < 0.05, "{name}: p95 residual {}", r.p95);
    assert!(
        r.median_angle_deg < 5.0,
        "{name}: median angle {}",
        r.median_angle_deg
    );
    Quality {
        surfels: out.surfels.len(),
        coverage,
        efficiency: out.stats.efficiency(),
    }
}

fn compare_modes(name: &str, field: &ColourField) {
    let params = ExtractParams::new(H);
    let covered = check(name, field, &params);
    let thesis = check(name, field, &params.thesis());
    println!(
        "{name}: coverage {:.2} % covered mode ({} surfels, efficiency {:.2}) vs {:.2} % thesis mode ({} surfels, efficiency {:.2})",
        100.0 * covered.coverage,
        covered.surfels,
        covered.efficiency,
        100.0 * thesis.coverage,
        thesis.surfels,
        thesis.efficiency
    );
    assert!(
        covered.coverage >= 0.99,
        "{name}: coverage {}",
        covered.coverage
    );
    assert!(covered.coverage >= thesis.coverage);
}

#[test]
fn sphere_of_particles() {
    compare_modes(
        "sphere",
        &ColourField::from_positions(&sphere(), H).unwrap(),
    );
}

#[test]
fn block_of_particles() {
    compare_modes("block", &ColourField::from_positions(&block(), H).unwrap());
}

#[test]
fn dam_break_frame_is_covered() {
    let p = dam_break_frame();
    let field = ColourField::from_particles(&p, 0.04).unwrap();
    let params = ExtractParams::new(0.04);
    let points = iso_points(&field, 0.5, 0.01).expect("iso points");
    for mode in [Mode::Covered, Mode::Thesis] {
        let params = match mode {
            Mode::Covered => params,
            Mode::Thesis => params.thesis(),
        };
        let out = extract_field(&field, &params).unwrap();
        let r = residuals(&field, 0.5, &out.surfels);
        let coverage = covered_fraction(&out.surfels, &points, 0.004).unwrap();
        println!(
            "dam break {mode:?}: {} surfels from {} particles, residual median {:.2e} p95 {:.2e}, normal {:.2}°, coverage {:.2} %, efficiency {:.2}",
            out.surfels.len(),
            p.len(),
            r.median,
            r.p95,
            r.median_angle_deg,
            100.0 * coverage,
            out.stats.efficiency()
        );
        assert!(
            r.median < 0.01 && r.p95 < 0.05 && r.median_angle_deg < 5.0,
            "{r:?}"
        );
        // The thesis mode leaves holes; closing them is the covered mode's job.
        if mode == Mode::Covered {
            assert!(coverage >= 0.99, "covered mode: coverage {coverage}");
        }
    }
}

/// Issue 4's efficiency target, at least 0.75 surfels per surfel evaluation in
/// the default mode, on the `extraction` bench's 2,250-particle dam break at
/// several frames and at 2 and 3 iterations. The 3×3 first split lifts it (the
/// thesis's 2×2 splits alone cannot cross 0.75, see `Split`).
///
/// Not on the 600-particle slab above: two to three particles thick, most
/// of it is surface, and its efficiency at 2 iterations ranges 0.72–0.81
/// from frame to frame (`cargo run --release -p surfel-extract --example
/// efficiency_over_frames`).
#[test]
fn efficiency_target_holds_on_the_bench_scene() {
    let mut world = Scene::dam_break(0.15, 0.05, 0.01).build_world().unwrap();
    for t in [0.2, 0.3, 0.4, 0.5] {
        world.advance(t - world.time() as f32).unwrap();
        let field = ColourField::from_particles(&world.particles, 0.02).unwrap();
        for iterations in [2, 3] {
            let params = ExtractParams {
                iterations,
                ..ExtractParams::new(0.02)
            };
            let stats = extract_field(&field, &params).unwrap().stats;
            println!(
                "t = {t} s, {iterations} iterations: {} surfels from {} evaluations, efficiency {:.3}",
                stats.surfels,
                stats.evaluations,
                stats.efficiency()
            );
            assert!(
                stats.efficiency() >= 0.75,
                "t = {t} s, {iterations} iterations: efficiency {}",
                stats.efficiency()
            );
        }
    }
}

#[test]
fn iterations_and_ldc_stay_on_the_surface() {
    let field = ColourField::from_positions(&sphere(), H).unwrap();
    for iterations in 1..=3 {
        let params = ExtractParams {
            iterations,
            ..ExtractParams::new(H)
        };
        let out = extract_field(&field, &params).unwrap();
        let r = residuals(&field, 0.5, &out.surfels);
        println!(
            "{iterations} iterations: {} surfels, {r:?}",
            out.surfels.len()
        );
        // Residuals of no surfels would pass.
        assert!(
            out.surfels.len() > 100,
            "{iterations} iterations: {} surfels",
            out.surfels.len()
        );
        assert!(r.p95 < 0.05, "{iterations} iterations: {r:?}");
    }
    let ldc = extract_ldc(&field, &ExtractParams::new(H), 0.25 * H).unwrap();
    let r = residuals(&field, 0.5, &ldc.surfels);
    let points = iso_points(&field, 0.5, 0.25 * H).expect("iso points");
    let coverage = covered_fraction(&ldc.surfels, &points, 0.1 * H).unwrap();
    println!(
        "LDC: {} surfels, {r:?}, coverage {coverage}",
        ldc.surfels.len()
    );
    assert!(r.median < 0.01 && r.median_angle_deg < 5.0, "{r:?}");
    assert!(coverage > 0.99, "LDC coverage {coverage}");
    // The LDC validates its parameters as the extractor does: an iso
    // outside (0, 1) or a camera at NaN found nothing before, as `Ok`.
    for bad in [
        ExtractParams {
            iso: f32::NAN,
            ..ExtractParams::new(H)
        },
        ExtractParams {
            iso: 5.0,
            ..ExtractParams::new(H)
        },
        ExtractParams {
            camera: Some(Vec3::NAN),
            ..ExtractParams::new(H)
        },
    ] {
        assert!(extract_ldc(&field, &bad, 0.25 * H).is_err(), "{bad:?}");
    }
}

#[test]
fn lone_particle_gets_its_analytic_iso_sphere() {
    let centre = Vec3::new(0.3, -0.2, 0.1);
    let out = extract_points(&[centre], &ExtractParams::new(H)).unwrap();
    let radius = H * (1.0 - 0.5f32.cbrt()).sqrt();
    assert_eq!(out.stats.lone, 1);
    assert_eq!(out.surfels.len(), 14);
    for s in &out.surfels {
        let d = s.position - centre;
        assert!((d.length() - radius).abs() < 1e-4 * H, "{}", d.length());
        assert!((d.normalize() - s.normal).length() < 1e-5);
    }
    let points = iso_points(
        &ColourField::from_positions(&[centre], H).unwrap(),
        0.5,
        0.05 * H,
    )
    .expect("iso points");
    assert!(covered_fraction(&out.surfels, &points, 0.1 * H).unwrap() >= 0.99);
}

#[test]
fn degenerate_sets_give_surfels_on_the_surface() {
    let two = vec![Vec3::ZERO, Vec3::new(0.6 * H, 0.0, 0.0)];
    let line: Vec<Vec3> = (0..20)
        .map(|i| Vec3::new(i as f32 * SPACING, 0.0, 0.0))
        .collect();
    let plane: Vec<Vec3> = (0..400)
        .map(|i| Vec3::new((i % 20) as f32, 0.0, (i / 20) as f32) * SPACING)
        .collect();
    let coincident = vec![Vec3::splat(0.5); 200];
    for (name, set) in [
        ("two", two),
        ("line", line),
        ("plane", plane),
        ("coincident", coincident),
    ] {
        let field = ColourField::from_positions(&set, H).unwrap();
        let out = extract_field(&field, &ExtractParams::new(H)).unwrap();
        let r = residuals(&field, 0.5, &out.surfels);
        let points = iso_points(&field, 0.5, 0.25 * H).expect("iso points");
        let coverage = covered_fraction(&out.surfels, &points, 0.1 * H).unwrap();
        println!(
            "{name}: {} surfels, {r:?}, coverage {coverage:.4}",
            out.surfels.len()
        );
        assert!(!out.surfels.is_empty(), "{name}");
        assert!(r.median < 0.02 && r.p95 < 0.05, "{name}: {r:?}");
        assert!(coverage >= 0.95, "{name}: coverage {coverage}");
    }
    let empty = extract_points(&[], &ExtractParams::new(H)).unwrap();
    assert!(empty.surfels.is_empty());
}

#[test]
fn bad_input_is_an_error() {
    let params = ExtractParams::new(H);
    assert!(extract_points(&[Vec3::ZERO, Vec3::NAN], &params).is_err());
    assert!(extract_points(&[Vec3::ZERO], &ExtractParams::new(0.0)).is_err());
    assert!(extract_points(&[Vec3::ZERO], &ExtractParams::new(-1.0)).is_err());
    let err = extract_points(
        &[Vec3::ZERO],
        &ExtractParams {
            iterations: 7,
            ..params
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("iterations"), "{err}");
    // Particles 2^20 h from the origin, where an f32 ulp is h/8: the surface
    // came out with half its surfels, as Ok. Within 2^16 h it is extracted.
    for (offset, ok) in [(65_000.0 * H, true), (1_048_576.0 * H, false)] {
        let block: Vec<Vec3> = (0..27)
            .map(|i| {
                Vec3::new(offset, 0.0, 0.0)
                    + 0.5 * H * Vec3::new((i % 3) as f32, (i / 3 % 3) as f32, (i / 9) as f32)
            })
            .collect();
        match extract_points(&block, &params) {
            Ok(out) => assert!(ok && !out.surfels.is_empty(), "{offset}"),
            Err(e) => {
                assert!(!ok, "{offset}: {e}");
                assert!(matches!(e, Error::InvalidParticle { index: 0, .. }), "{e}");
                assert!(e.to_string().contains("65,536 h"), "{e}");
            }
        }
    }
    // A surfel radius r·h that overflows f32.
    let err = extract_points(
        &[Vec3::ZERO],
        &ExtractParams {
            radius: 4.0,
            ..ExtractParams::new(1e38)
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("radius · h"), "{err}");
    // Radii and hole-closing rounds that would multiply surfels without end.
    for (bad, field) in [
        (
            ExtractParams {
                radius: 0.01,
                ..params
            },
            "radius",
        ),
        (
            ExtractParams {
                radius: 5.0,
                ..params
            },
            "radius",
        ),
        (
            ExtractParams {
                fill_rounds: 65,
                ..params
            },
            "fill_rounds",
        ),
        // Steps so short that every surfel is discarded or every particle
        // interior: Ok with nothing, before STEP_RANGE.
        (
            ExtractParams {
                discard_step: 1e-30,
                ..params
            },
            "discard_step",
        ),
        (
            ExtractParams {
                interior_step: 1e-3,
                ..params
            },
            "interior_step",
        ),
        (
            ExtractParams {
                interior_step: 5.0,
                ..params
            },
            "interior_step",
        ),
    ] {
        let err = extract_points(&[Vec3::ZERO], &bad).unwrap_err().to_string();
        assert!(err.contains(field), "{err}");
    }
    let edge = ExtractParams {
        radius: 0.05,
        fill_rounds: 64,
        ..params
    };
    assert!(extract_points(&[Vec3::ZERO], &edge).is_ok());
    assert!(
        extract_ldc(
            &ColourField::from_positions(&[Vec3::ZERO], H).unwrap(),
            &params,
            0.0
        )
        .is_err()
    );
    // Coverage of surfels with a NaN radius, or for a NaN thickness: an
    // error, not an empty index that covers nothing.
    let disc = |radius| Surfel {
        position: Vec3::ZERO,
        normal: Vec3::Z,
        radius,
    };
    let q = [Vec3::ZERO];
    assert_eq!(covered_fraction(&[disc(0.1)], &q, 0.01).unwrap(), 1.0);
    assert!(covered_fraction(&[disc(f32::NAN)], &q, 0.01).is_err());
    assert!(covered_fraction(&[disc(0.1)], &q, f32::NAN).is_err());
    // No points: an error, not a full coverage of nothing.
    assert!(covered_fraction(&[disc(0.1)], &[], 0.01).is_err());
}

#[test]
fn identical_for_any_thread_count() {
    let points = sphere();
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| extract_points(&points, &ExtractParams::new(H)).unwrap())
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a.surfels, b.surfels);
    assert_eq!(a.stats.evaluations, b.stats.evaluations);
}

/// An `Extractor` kept across frames of different sizes, smoothing lengths,
/// modes and iteration counts, with a failed frame among them, gives every
/// frame bitwise what the one-shot functions give.
#[test]
fn extractor_reused_across_frames_matches_one_shot() {
    let frames = [
        (sphere(), ExtractParams::new(H)),
        (
            block(),
            ExtractParams {
                iterations: 3,
                ..ExtractParams::new(H)
            },
        ),
        (sphere(), ExtractParams::new(1.3 * H).thesis()),
        (
            sphere().into_iter().take(40).collect(),
            ExtractParams {
                iterations: 1,
                camera: Some(Vec3::new(0.0, 0.0, 1.0)),
                ..ExtractParams::new(H)
            },
        ),
        (Vec::new(), ExtractParams::new(H)),
        (sphere(), ExtractParams::new(H)),
    ];
    let mut extractor = Extractor::new();
    for (k, (points, params)) in frames.iter().enumerate() {
        let expected = extract_points(points, params).unwrap();
        let got = extractor.extract_points(points, params).unwrap();
        assert_eq!(got.surfels, expected.surfels, "frame {k}");
        assert_eq!(
            got.stats.evaluations, expected.stats.evaluations,
            "frame {k}"
        );
        assert_eq!(extractor.field().unwrap().len(), points.len());
        // A bad frame in between: an error, and an empty output.
        assert!(
            extractor
                .extract_points(&[Vec3::ZERO, Vec3::NAN], params)
                .is_err()
        );
        assert!(extractor.surfels().surfels.is_empty());
        assert_eq!(extractor.surfels().stats.surfels, 0);
    }
    // Simulated particles, and a prepared field, through the same extractor.
    let frame = dam_break_frame();
    let params = ExtractParams::new(0.02);
    let expected = surfel_extract::extract(&frame, &params).unwrap();
    assert_eq!(
        extractor.extract(&frame, &params).unwrap().surfels,
        expected.surfels
    );
    let field = ColourField::from_particles(&frame, 0.02).unwrap();
    assert_eq!(
        extractor.extract_field(&field, &params).unwrap().surfels,
        expected.surfels
    );
    assert_eq!(extractor.take().surfels, expected.surfels);
    assert!(extractor.surfels().surfels.is_empty());
}

/// Every parameter in turn set to an awkward value (zero, negative, tiny,
/// huge, NaN, ±infinity and the edges of the accepted ranges), in both modes:
/// the extraction is an error, or surfels with finite positions, unit
/// normals and finite radii > 0. Nothing panics.
#[test]
fn any_one_awkward_parameter_is_an_error_or_finite_surfels() {
    use std::panic::{AssertUnwindSafe, catch_unwind};
    let points = lattice(5, |x| x.length() < 0.045);
    let floats = [
        0.0,
        -0.0,
        -1.0,
        1e-30,
        1e-7,
        0.05,
        0.5,
        0.999,
        1.0,
        4.0,
        1e7,
        1e30,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ];
    type Set = fn(&mut ExtractParams, f32);
    let float_fields: [(&str, Set); 8] = [
        ("h", |p, v| p.h = v),
        ("iso", |p, v| p.iso = v),
        ("interior_step", |p, v| p.interior_step = v),
        ("discard_step", |p, v| p.discard_step = v),
        ("split_laplacian", |p, v| p.split_laplacian = v),
        ("covariance_threshold", |p, v| p.covariance_threshold = v),
        ("radius", |p, v| p.radius = v),
        ("camera", |p, v| p.camera = Some(Vec3::new(v, 0.1, 1.0))),
    ];
    let ints = [0, 1, 2, 3, 4, 64, 65, u32::MAX];
    type SetInt = fn(&mut ExtractParams, u32);
    let int_fields: [(&str, SetInt); 2] = [
        ("iterations", |p, v| p.iterations = v),
        ("fill_rounds", |p, v| p.fill_rounds = v),
    ];
    let mut cases: Vec<(String, ExtractParams)> = Vec::new();
    for base in [ExtractParams::new(H), ExtractParams::new(H).thesis()] {
        for (name, set) in float_fields {
            for v in floats {
                let mut p = base;
                set(&mut p, v);
                cases.push((format!("{:?} {name} = {v}", base.mode), p));
            }
        }
        for (name, set) in int_fields {
            for v in ints {
                let mut p = base;
                set(&mut p, v);
                cases.push((format!("{:?} {name} = {v}", base.mode), p));
            }
        }
    }
    let (mut ran, mut panics) = (0, Vec::new());
    for (case, p) in &cases {
        match catch_unwind(AssertUnwindSafe(|| extract_points(&points, p))) {
            Err(_) => panics.push(case.clone()),
            Ok(Err(_)) => {}
            Ok(Ok(out)) => {
                ran += 1;
                for s in &out.surfels {
                    assert!(s.position.is_finite(), "{case}: {s:?}");
                    assert!((s.normal.length() - 1.0).abs() < 1e-3, "{case}: {s:?}");
                    assert!(s.radius.is_finite() && s.radius > 0.0, "{case}: {s:?}");
                }
            }
        }
    }
    println!(
        "{} parameter sets on {} particles: {ran} extracted, the rest were errors",
        cases.len(),
        points.len()
    );
    assert!(panics.is_empty(), "panicked: {panics:#?}");
    assert!(ran > 0 && ran < cases.len(), "{ran} of {}", cases.len());
}
