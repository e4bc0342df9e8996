//! Water at rest (issue 41): a pool filled on the lattice from the floor,
//! still from the start, under each solver.

use sph_core::scene::SolverSpec;
use sph_core::{DfsphParams, PbfParams, PbfSolve, Scene, SolverKind, World};

/// Spacing (m); h = 2 spacings.
const S: f32 = 0.02;

/// A pool `side` square and `depth` deep, particle centres kept `clearance`
/// from the walls (`None`: the scene's default, half a spacing), run by
/// `kind` for `seconds` of 60 Hz frames.
fn settled(kind: SolverKind, side: f32, depth: f32, clearance: Option<f32>, seconds: f32) -> World {
    let spec = SolverSpec {
        kind,
        ..SolverSpec::default()
    };
    let mut world = pool(spec, side, depth, clearance);
    for _ in 0..(seconds * 60.0).round() as usize {
        world.advance(1.0 / 60.0).unwrap();
    }
    world
}

/// That pool, not yet run, by the solver and parameters of `spec`.
fn pool(spec: SolverSpec, side: f32, depth: f32, clearance: Option<f32>) -> World {
    let mut scene = Scene::dam_break(0.15, side, S);
    scene.solver = spec;
    scene.domain.min = [0.0; 3];
    scene.domain.max = [side, depth + 0.1, side];
    scene.blocks[0].min = [0.0; 3];
    scene.blocks[0].max = [side, depth, side];
    scene.clearance = clearance;
    scene.build_world().unwrap()
}

/// The mean height (m) of the particles below one spacing, more than 2h
/// from the side walls.
fn first_layer(world: &World, side: f32) -> f32 {
    let inside = |c: f32| c > 4.0 * S && c < side - 4.0 * S;
    let heights: Vec<f32> = (world.particles.positions().iter())
        .filter(|x| x.y < S && inside(x.x) && inside(x.z))
        .map(|x| x.y)
        .collect();
    assert!(!heights.is_empty());
    heights.iter().sum::<f32>() / heights.len() as f32
}

/// With the scenes' default clearance (half a spacing), the first layer of
/// every solver rests within 10 % of half a spacing above the floor, where
/// the lattice put it. (Without one it sinks to 1–4 mm of its 10: `cargo
/// run --release -p sph-core --example pool_at_rest -- SOLVER --clearance
/// 0`.)
#[test]
fn the_first_layer_rests_half_a_spacing_above_the_floor() {
    for kind in SolverKind::ALL {
        let (side, depth) = (0.3, 0.2);
        let world = settled(kind, side, depth, None, 1.0);
        let layer = first_layer(&world, side);
        eprintln!("{kind}: first layer {:.2} mm", 1e3 * layer);
        assert!(
            (layer / (0.5 * S) - 1.0).abs() <= 0.1,
            "{kind}: first layer at {:.2} mm, half a spacing is {:.0} mm",
            1e3 * layer,
            500.0 * S
        );
    }
}

/// Without gravity, a pool filled on the lattice to its walls is already at
/// rest density everywhere: the walls continue the lattice layer by layer
/// (`WallKernel::lattice_layers`), so PBF's one-sided constraints and
/// DFSPH's solves find nothing to correct, and the pool stays still. After
/// 1 s: rms speed below 0.01 mm/s and the free surface within 0.01 % of the
/// lattice's. Measured: PBF 0.0020 mm/s and +0.0027 %, DFSPH 0.0009 mm/s
/// and +0.0010 %. With layers V^⅓
/// apart and V^⅓ thick (the walls before, which started poly6's first
/// layer 0.40 % over ρ0), PBF's pool moved at 11.5 mm/s after 1 s and had
/// swollen by 12.7 % (`cargo run --release -p sph-core --example
/// pool_at_rest -- pbf --depth 0.2 --seconds 1 --gravity 0`).
#[test]
fn a_pool_without_gravity_stays_still() {
    for kind in [SolverKind::Pbf, SolverKind::Dfsph] {
        let (side, depth) = (0.3, 0.2);
        let spec = SolverSpec {
            kind,
            ..SolverSpec::default()
        };
        let mut scene = Scene::dam_break(0.15, side, S);
        scene.solver = spec;
        scene.fluid.gravity = [0.0; 3];
        scene.domain.min = [0.0; 3];
        scene.domain.max = [side, depth + 0.1, side];
        scene.blocks[0].min = [0.0; 3];
        scene.blocks[0].max = [side, depth, side];
        let mut world = scene.build_world().unwrap();
        for _ in 0..60 {
            world.advance(1.0 / 60.0).unwrap();
        }
        let rms = rms_speed(&world);
        let top = (world.particles.positions().iter())
            .map(|x| x.y)
            .fold(f32::MIN, f32::max);
        let surface = top + 0.5 * S;
        eprintln!(
            "{kind}: rms speed {:.4} mm/s, free surface {:+.4} %",
            1e3 * rms,
            100.0 * (surface / depth - 1.0)
        );
        assert!(rms < 1e-5, "{kind}: rms speed {rms} m/s");
        assert!(
            (surface / depth - 1.0).abs() < 1e-4,
            "{kind}: surface {surface} m"
        );
    }
}

/// DFSPH's solves know the clearance's projection ("Contacts" in
/// `solver::dfsph`): with the default clearance of half a spacing, no layer of a
/// pool 0.5 m deep takes the compression the first layer cannot, and the
/// pool comes to rest. After 1 s, each 2 cm band's mean density (more
/// than 2h from the side walls, below the top 4 cm) within 0.2 % of ρ0
/// and the rms speed below 30 mm/s. Measured: at most 0.081 % and
/// 18.3 mm/s; with the contacts switched off (a throwaway edit) a band
/// was 4.45 % compressed and the pool moved at 63.5 mm/s.
#[test]
fn dfsph_with_a_clearance_compresses_no_layer() {
    let (side, depth) = (0.3, 0.5);
    let world = settled(SolverKind::Dfsph, side, depth, None, 1.0);
    let p = &world.particles;
    let inside = |c: f32| c > 4.0 * S && c < side - 4.0 * S;
    let mut bands = vec![(0.0f64, 0usize); (depth / 0.02).round() as usize];
    for (x, &rho) in p.positions().iter().zip(p.densities()) {
        let band = (x.y / 0.02) as usize;
        if inside(x.x) && inside(x.z) && band < bands.len() - 2 {
            bands[band].0 += f64::from(rho);
            bands[band].1 += 1;
        }
    }
    let worst = (bands.iter())
        .filter(|b| b.1 > 0)
        .map(|b| (b.0 / b.1 as f64 / 1000.0 - 1.0).abs())
        .fold(0.0, f64::max);
    let rms = rms_speed(&world);
    eprintln!(
        "largest band density off ρ0: {:.3} %; rms speed {:.1} mm/s",
        100.0 * worst,
        1e3 * rms
    );
    assert!(worst <= 0.002, "a band {:.2} % off ρ0", 100.0 * worst);
    assert!(rms < 0.03, "rms speed {rms} m/s");
}

/// The free surface against the filled `depth`: the mean over columns h
/// square, more than 2h from the side walls, of their highest particle
/// plus half a spacing, over `depth`, minus 1 (as `pool_at_rest` prints
/// it).
fn free_surface(world: &World, side: f32, depth: f32) -> f64 {
    let h = 2.0 * S;
    let inside = |c: f32| c > 2.0 * h && c < side - 2.0 * h;
    let mut tops = std::collections::HashMap::new();
    for x in (world.particles.positions().iter()).filter(|x| inside(x.x) && inside(x.z)) {
        let top = tops
            .entry(((x.x / h) as i32, (x.z / h) as i32))
            .or_insert(f32::MIN);
        *top = top.max(x.y);
    }
    let mean = tops.values().map(|&y| f64::from(y + 0.5 * S)).sum::<f64>() / tops.len() as f64;
    mean / f64::from(depth) - 1.0
}

/// Runs `world` 2 s at 60 Hz; returns the most any particle moved over the
/// last 0.1 s (m).
fn two_seconds(world: &mut World) -> f32 {
    let mut at = std::collections::HashMap::new();
    for frame in 1..=120 {
        world.advance(1.0 / 60.0).unwrap();
        if frame == 114 {
            let p = &world.particles;
            at = (p.ids().iter().copied())
                .zip(p.positions().iter().copied())
                .collect();
        }
    }
    let p = &world.particles;
    (p.ids().iter().zip(p.positions()))
        .map(|(id, x)| (*x - at[id]).length())
        .fold(0.0f32, f32::max)
}

/// The rms speed of every particle (m/s).
fn rms_speed(world: &World) -> f64 {
    let p = &world.particles;
    let sum = (p.velocities().iter())
        .map(|v| f64::from(v.length_squared()))
        .sum::<f64>();
    (sum / p.len() as f64).sqrt()
}

/// Particle sleeping brings issue 41's pool (0.6 m square, 0.2 m deep)
/// and a pool 25 layers deep to rest: rms speed at most 1 mm/s after 2 s,
/// and no particle moved more than 10 µm over the last 0.1 s. The shallow
/// pools fall asleep before their top layers pack, and keep their free
/// surface within issue 41's 0.5 % of the filled height (measured: PBF
/// −0.32 %, DFSPH −0.06 %; PBF's deep pool −2.77 % here, −2.57 % at 0.6 m
/// square: `cargo run --release
/// -p sph-core --example pool_at_rest -- SOLVER --depth D --solver-toml
/// '...'`).
/// - PBF (`PbfParams::sleep_speed`, 2 cm/s) once damping (XSPH 0.1) and an
///   even iteration count (4; 6 for the deep pool) have brought its jitter
///   below the threshold. Without sleeping the same settings leave the
///   shallow pool jittering above 5 mm/s, and the defaults at about
///   80 mm/s (`cargo run --release -p sph-core --example pool_at_rest --
///   pbf`).
/// - DFSPH (`DfsphParams::sleep_speed`, 1.5 cm/s) at its defaults, which
///   leave about 8 mm/s at 2 s without sleeping (the shallow pool only
///   here; the deep one, 0.6 m square, is still from 2 s too: `cargo run
///   --release -p sph-core --example pool_at_rest -- dfsph --depth 0.5
///   --solver-toml 'dfsph = { sleep_speed = 0.015 }'`). At 1 cm/s the
///   shallow pool stayed awake at 12.3 mm/s: the particles next to the
///   walls' clearance planes keep moving above it for longer.
///
/// PBF's deep pool is 0.3 m square here, to keep the test short.
#[test]
fn pools_fall_asleep() {
    let damped = |iterations, sleep_speed| SolverSpec {
        kind: SolverKind::Pbf,
        pbf: Some(PbfParams {
            iterations,
            xsph: 0.1,
            sleep_speed,
            ..PbfParams::default()
        }),
        ..SolverSpec::default()
    };
    let dfsph = |sleep_speed| SolverSpec {
        kind: SolverKind::Dfsph,
        dfsph: Some(DfsphParams {
            sleep_speed,
            ..DfsphParams::default()
        }),
        ..SolverSpec::default()
    };
    for (spec, side, depth, asleep) in [
        (damped(4, 0.02), 0.6, 0.2, true),
        (damped(6, 0.02), 0.3, 0.5, true),
        (damped(4, 0.0), 0.6, 0.2, false),
        (dfsph(0.015), 0.6, 0.2, true),
    ] {
        let kind = spec.kind;
        let mut world = pool(spec, side, depth, None);
        let moved = two_seconds(&mut world);
        let rms = rms_speed(&world);
        let surface = free_surface(&world, side, depth);
        eprintln!(
            "{kind}, {side} m square, {depth} m deep, sleeping {asleep}: rms speed {:.2} mm/s, \
             the most any particle moved over the last 0.1 s {:.4} mm, free surface {:+.2} %",
            1e3 * rms,
            1e3 * moved,
            100.0 * surface
        );
        if asleep {
            assert!(rms <= 1e-3, "{kind}: rms speed {:.2} mm/s", 1e3 * rms);
            assert!(moved <= 1e-5, "{kind}: a particle moved {moved} m");
            // Asleep before the top layers pack: issue 41's 0.5 % holds
            // for the shallow pools (not for PBF's deep one, −2.8 %).
            if depth == 0.2 {
                assert!(surface.abs() <= 5e-3, "{kind}: free surface {surface:+}");
            }
        } else {
            assert!(
                rms > 5e-3,
                "without sleeping, rms speed {:.2} mm/s",
                1e3 * rms
            );
        }
    }
}

/// PBF's Gauss–Seidel solve (`PbfSolve::GaussSeidel`) quiets issue 41's
/// pool (0.6 m square, 0.2 m deep) at the other defaults: rms speed
/// 21.6 mm/s after 2 s against Jacobi's 81.7 (`cargo run --release -p
/// sph-core --example pool_at_rest -- pbf --solver-toml 'pbf = { solve =
/// "gauss-seidel" }'`), with its first layer held at half a spacing.
/// Asserted: at most 30 mm/s, and at most 0.4 of Jacobi's. Not issue 41's
/// 1 mm/s: what is left is the lattice settling sideways, as under DFSPH
/// (`docs/benchmark-notes.md`, "Coloured Gauss–Seidel on the cubic
/// spline").
#[test]
fn gauss_seidel_quiets_a_pbf_pool() {
    let (side, depth) = (0.6, 0.2);
    let run = |solve| {
        let spec = SolverSpec {
            kind: SolverKind::Pbf,
            pbf: Some(PbfParams {
                solve,
                ..PbfParams::default()
            }),
            ..SolverSpec::default()
        };
        let mut world = pool(spec, side, depth, None);
        for _ in 0..120 {
            world.advance(1.0 / 60.0).unwrap();
        }
        (rms_speed(&world), first_layer(&world, side))
    };
    let (jacobi, _) = run(PbfSolve::Jacobi);
    let (rms, layer) = run(PbfSolve::GaussSeidel);
    eprintln!(
        "rms speed at 2 s: Gauss–Seidel {:.2} mm/s, Jacobi {:.2} mm/s; first layer {:.2} mm",
        1e3 * rms,
        1e3 * jacobi,
        1e3 * layer
    );
    assert!(rms <= 0.03, "rms speed {:.2} mm/s", 1e3 * rms);
    assert!(rms <= 0.4 * jacobi, "{rms} against Jacobi's {jacobi} m/s");
    assert!(
        (layer / (0.5 * S) - 1.0).abs() <= 0.1,
        "first layer {layer} m"
    );
}

/// Gauss–Seidel's warm start (`PbfParams::warm_start`) carries the weight
/// of a pool 25 layers deep from one substep to the next, where the cold
/// solve's three sweeps hold it by compressing the pool: at half the last
/// pressure the pool (0.3 m square here, to keep the test short) moves
/// less than half as fast after 2 s and stands higher (measured 26.4
/// against 138.3 mm/s, the free surface −1.75 % against −2.56 %; run this
/// test with `--nocapture`). At 0.6 m square:
/// 57.8 against 174.4 mm/s, the free surface −1.91 % against −2.36 %
/// (`cargo run --release -p sph-core --example pool_at_rest -- pbf --depth
/// 0.5 --solver-toml 'pbf = { solve = "gauss-seidel", warm_start = 0.5
/// }'`). Asserted: at most 0.3 of the cold rms speed, and the surface at
/// least 0.5 % of the depth higher (w = 0.3 gave 0.51 and +0.16 % at 0.6 m
/// square, so a weaker carry fails).
#[test]
fn a_warm_start_holds_a_deep_pbf_pool() {
    let (side, depth) = (0.3, 0.5);
    let run = |warm_start| {
        let spec = SolverSpec {
            kind: SolverKind::Pbf,
            pbf: Some(PbfParams {
                solve: PbfSolve::GaussSeidel,
                warm_start,
                ..PbfParams::default()
            }),
            ..SolverSpec::default()
        };
        let mut world = pool(spec, side, depth, None);
        for _ in 0..120 {
            world.advance(1.0 / 60.0).unwrap();
        }
        (rms_speed(&world), free_surface(&world, side, depth))
    };
    let (cold, cold_surface) = run(0.0);
    let (warm, warm_surface) = run(0.5);
    eprintln!(
        "rms speed at 2 s: warm {:.2} mm/s, cold {:.2} mm/s; free surface warm {:+.2} %, \
         cold {:+.2} %",
        1e3 * warm,
        1e3 * cold,
        100.0 * warm_surface,
        100.0 * cold_surface
    );
    assert!(warm <= 0.3 * cold, "{warm} against {cold} m/s");
    assert!(
        warm_surface >= cold_surface + 5e-3,
        "free surface {warm_surface:+} against {cold_surface:+}"
    );
}

/// The free surface's target (`DfsphParams::surface_target`,
/// `PbfParams::surface_target`) holds the top layer at the density a
/// lattice's top layer reads instead of letting it pack to ρ0, and keeps
/// the free surface within issue 41's 0.5 % of the filled height after
/// 2 s: under DFSPH in the 0.2 m pool and in one 25 layers deep (0.3 m
/// square here, to keep the test short), and under PBF's warm-started
/// Gauss–Seidel solve in the 0.2 m pool, each of which ends 1.1–2.2 % low
/// without it (here: DFSPH +0.19 % and −0.33 % against −1.71 % and
/// −1.11 %, PBF −0.18 % against −2.16 %). At 0.6 m square (`cargo run
/// --release -p sph-core --example pool_at_rest -- SOLVER --depth D
/// --solver-toml '...'`): DFSPH +0.19 % and −0.23 % against −1.71 % and
/// −0.99 %; PBF −0.18 % and, 0.5 m deep, −1.13 % (the bulk's compression,
/// which the warm start does not take away) against −2.16 % and −1.91 %.
#[test]
fn a_surface_target_keeps_the_free_surface_at_its_height() {
    let dfsph = |surface_target| SolverSpec {
        kind: SolverKind::Dfsph,
        dfsph: Some(DfsphParams {
            surface_target,
            ..DfsphParams::default()
        }),
        ..SolverSpec::default()
    };
    let pbf = |surface_target| SolverSpec {
        kind: SolverKind::Pbf,
        pbf: Some(PbfParams {
            solve: PbfSolve::GaussSeidel,
            warm_start: 0.5,
            surface_target,
            ..PbfParams::default()
        }),
        ..SolverSpec::default()
    };
    for (spec, plain, side, depth) in [
        (dfsph(true), dfsph(false), 0.6, 0.2),
        (dfsph(true), dfsph(false), 0.3, 0.5),
        (pbf(true), pbf(false), 0.6, 0.2),
    ] {
        let kind = spec.kind;
        let surface = |spec| {
            let mut world = pool(spec, side, depth, None);
            for _ in 0..120 {
                world.advance(1.0 / 60.0).unwrap();
            }
            free_surface(&world, side, depth)
        };
        let (held, sunk) = (surface(spec), surface(plain));
        eprintln!(
            "{kind}, {side} m square, {depth} m deep: free surface {:+.2} % with the target, \
             {:+.2} % without",
            100.0 * held,
            100.0 * sunk
        );
        assert!(held.abs() <= 5e-3, "{kind}: free surface {held:+}");
        assert!(sunk < -8e-3, "{kind}: without the target {sunk:+}");
    }
}

/// With the free surface's target and sleeping, both solvers bring issue
/// 41's pools to rest at their height, the one 25 layers deep too (0.3 m
/// square here, to keep the test short): rms speed at most 1 mm/s after
/// 2 s, and the free surface within 0.5 %.
/// - PBF: warm-started Gauss–Seidel (0.5), 4 substeps of 4 sweeps, XSPH
///   0.1, sleeping at 2 cm/s.
/// - DFSPH: its defaults, sleeping at 1.5 cm/s.
///
/// Here PBF's surfaces end at −0.07 % and −0.19 %, DFSPH's at −0.05 % and
/// −0.04 %. At 0.6 m square (`cargo run --release -p sph-core --example
/// pool_at_rest -- SOLVER --depth D --solver-toml '...'`) both are at
/// rest, PBF's surfaces at −0.07 % and −0.22 %, DFSPH's at −0.05 % and
/// +0.07 %. The shallow pools freeze flat (`flat_pool`'s top normals
/// 0.14° median and 1.42° at p99 under PBF, 0.00° and 1.30° under DFSPH),
/// the deep ones with the ripples they had when they fell asleep (3.94°
/// and 10.0° under PBF, 1.68° and 5.97° under DFSPH).
#[test]
fn held_surfaces_fall_asleep_at_their_height() {
    let pbf = SolverSpec {
        kind: SolverKind::Pbf,
        pbf: Some(PbfParams {
            solve: PbfSolve::GaussSeidel,
            warm_start: 0.5,
            surface_target: true,
            substeps: 4,
            iterations: 4,
            xsph: 0.1,
            sleep_speed: 0.02,
            ..PbfParams::default()
        }),
        ..SolverSpec::default()
    };
    let dfsph = SolverSpec {
        kind: SolverKind::Dfsph,
        dfsph: Some(DfsphParams {
            surface_target: true,
            sleep_speed: 0.015,
            ..DfsphParams::default()
        }),
        ..SolverSpec::default()
    };
    for (spec, side, depth) in [
        (pbf, 0.6, 0.2),
        (pbf, 0.3, 0.5),
        (dfsph, 0.6, 0.2),
        (dfsph, 0.3, 0.5),
    ] {
        let kind = spec.kind;
        let mut world = pool(spec, side, depth, None);
        let moved = two_seconds(&mut world);
        let (rms, surface) = (rms_speed(&world), free_surface(&world, side, depth));
        eprintln!(
            "{kind}, {side} m square, {depth} m deep: rms speed {:.2} mm/s, the most any \
             particle moved over the last 0.1 s {:.4} mm, free surface {:+.2} %",
            1e3 * rms,
            1e3 * moved,
            100.0 * surface
        );
        assert!(rms <= 1e-3, "{kind}: rms speed {:.2} mm/s", 1e3 * rms);
        // Asleep, the most any particle moves over 0.1 s is 12 µm here (a
        // particle at the edge of sleeping); awake, millimetres.
        assert!(moved <= 3e-5, "{kind}: a particle moved {moved} m");
        // At most 0.19 % off here; asleep without the target the shallow
        // pools read −0.35 % (PBF) and −0.06 % (DFSPH), the deep ones −1 to
        // −2.6 %.
        assert!(surface.abs() <= 3e-3, "{kind}: free surface {surface:+}");
    }
}
