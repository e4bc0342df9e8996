//! Whole runs are bitwise the same on every SIMD path (`SPH_SIMD`): each
//! solver over half a second of the demo's slab dam break (1,200
//! particles), and both surface fields' surfels of the result. The lane
//! passes are compared pass by pass inside `sph-core`; this compares what
//! a user gets at the end.
//!
//! The level is read once per process, so the test runs itself once per
//! level this CPU has (`SPH_SIMD=baseline`, `avx2`, `avx512`), each run
//! printing a fingerprint of its results, and compares them.
//!
//! ```text
//! cargo test --release --test simd_levels -- --nocapture
//! ```

use std::hash::{DefaultHasher, Hasher};
use std::process::Command;

use sph_core::glam::Vec3;
use sph_core::{PbfParams, PbfViscosity, Scene, Simd, SolverKind, simd_level};
use surfel_extract::{ExtractParams, Extractor, Surface};

/// Set in the runs this test starts: compute and print the fingerprint.
const CHILD: &str = "SPH_SIMD_LEVELS_CHILD";
const NAME: &str = "whole_runs_are_identical_on_every_simd_path";

fn hash_vec3s(hasher: &mut DefaultHasher, v: &[Vec3]) {
    for x in v {
        for c in x.to_array() {
            hasher.write_u32(c.to_bits());
        }
    }
}

/// One fingerprint per part: (name, hash, a count that shows it did work).
fn fingerprints() -> Vec<(String, u64, usize)> {
    let base = Scene::dam_break(0.25, 0.08, 0.02);
    let mut implicit = base.clone().with_solver(SolverKind::Pbf);
    implicit.solver.pbf = Some(PbfParams {
        viscosity: PbfViscosity::Implicit,
        ..implicit.pbf_params()
    });
    let runs = [
        ("wcsph", base.clone().with_solver(SolverKind::Wcsph)),
        ("pbf-xsph", base.clone().with_solver(SolverKind::Pbf)),
        ("pbf-implicit", implicit),
        ("dfsph", base.with_solver(SolverKind::Dfsph)),
    ];
    let mut out = Vec::new();
    for (name, scene) in runs {
        let mut world = scene.build_world().unwrap();
        let mut hasher = DefaultHasher::new();
        for _ in 0..30 {
            let r = world.advance(1.0 / 60.0).unwrap();
            hasher.write_u32(r.density_error_max.to_bits());
            hasher.write_u32(r.density_error_avg.to_bits());
            for count in [
                r.substeps,
                r.iterations,
                r.divergence_iterations,
                r.viscosity_iterations,
            ] {
                hasher.write_u32(count);
            }
        }
        let p = &world.particles;
        for id in p.ids() {
            hasher.write_u64(*id);
        }
        hash_vec3s(&mut hasher, p.positions());
        hash_vec3s(&mut hasher, p.velocities());
        for x in p.densities().iter().chain(p.pressures()) {
            hasher.write_u32(x.to_bits());
        }
        out.push((name.to_string(), hasher.finish(), p.len()));
        for surface in [Surface::Isotropic, Surface::anisotropic()] {
            let params = ExtractParams {
                surface,
                ..ExtractParams::new(scene.fluid.h)
            };
            let surfels = Extractor::new().extract(p, &params).unwrap().clone();
            let mut hasher = DefaultHasher::new();
            for s in &surfels.surfels {
                hash_vec3s(&mut hasher, &[s.position, s.normal]);
                hasher.write_u32(s.radius.to_bits());
            }
            let field = if surface == Surface::Isotropic {
                "isotropic"
            } else {
                "anisotropic"
            };
            out.push((
                format!("{name}-{field}-surfels"),
                hasher.finish(),
                surfels.surfels.len(),
            ));
        }
    }
    out
}

#[test]
fn whole_runs_are_identical_on_every_simd_path() {
    if std::env::var_os(CHILD).is_some() {
        println!("level {}", simd_level().name());
        for (name, hash, count) in fingerprints() {
            println!("fingerprint {name} {hash:016x} {count}");
        }
        return;
    }
    let levels: Vec<Simd> = [Simd::Baseline, Simd::Avx2, Simd::Avx512]
        .into_iter()
        .filter(|&l| l <= Simd::detect())
        .collect();
    let exe = std::env::current_exe().unwrap();
    let mut runs = Vec::new();
    for level in &levels {
        let out = Command::new(&exe)
            .args([NAME, "--exact", "--nocapture", "--test-threads", "1"])
            .env(CHILD, "1")
            .env("SPH_SIMD", level.name())
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "SPH_SIMD={}: {stdout}{}",
            level.name(),
            String::from_utf8_lossy(&out.stderr)
        );
        // The run took the path it was asked for.
        assert!(
            stdout.contains(&format!("level {}\n", level.name())),
            "SPH_SIMD={}: {stdout}",
            level.name()
        );
        let prints: Vec<&str> = (stdout.lines())
            .filter_map(|l| l.strip_prefix("fingerprint "))
            .collect();
        println!("{}: {prints:?}", level.name());
        // Every part ran on a real run: particles and surfels.
        assert_eq!(prints.len(), 12, "{stdout}");
        for line in &prints {
            let count: usize = line.rsplit(' ').next().unwrap().parse().unwrap();
            assert!(count > 500, "{line}");
        }
        runs.push((level.name(), prints.join("\n")));
    }
    // CI's machines have AVX2 at least: a comparison of one level with
    // itself would show nothing.
    assert!(
        runs.len() >= 2 || Simd::detect() == Simd::Baseline,
        "{runs:?}"
    );
    for (name, prints) in &runs[1..] {
        assert_eq!(&runs[0].1, prints, "{} and {name} differ", runs[0].0);
    }
}
