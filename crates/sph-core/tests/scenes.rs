//! Scene files: every file in `assets/scenes/` loads and runs, and each kind of
//! malformed scene is rejected with a message naming the field and the reason.

use sph_core::scene::{BlockSpec, BoxSpec, ObstacleSpec};
use sph_core::{Error, Scene};

const SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/scenes");

#[test]
fn every_scene_file_loads_and_runs_10_steps() {
    let mut seen = 0;
    for entry in std::fs::read_dir(SCENES).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let mut world = scene.build_world().unwrap();
            let n0 = world.particles.len();
            for _ in 0..10 {
                world
                    .step()
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            }
            assert!(world.particles.len() >= n0, "{}", path.display());
            assert!(
                world
                    .particles
                    .positions()
                    .iter()
                    .all(|x| scene.boundary().admits(*x))
            );
            seen += 1;
        }
    }
    assert!(seen >= 4, "only {seen} scene files");
}

#[test]
fn built_in_scenes_round_trip_through_toml() {
    let mut wcsph = Scene::dam_break(0.25, 0.08, 0.02);
    wcsph.solver.wcsph = Some(sph_core::scene::WcsphSpec {
        stiffness: 5000.0,
        surface_threshold: Some(3.0),
        ..Default::default()
    });
    wcsph.fluid.viscosity = Some(0.1);
    let built_in = sph_core::scene::BUILT_IN.iter().map(|(_, _, make)| make());
    for s in built_in.chain([
        Scene::dam_break(0.25, 0.25, 0.02),
        Scene::double_dam_break(0.2, 0.2, 0.02),
        wcsph,
    ]) {
        assert_eq!(Scene::from_toml(&s.to_toml()).unwrap(), s, "{}", s.name);
    }
}

/// Switching solver gives way, with a note, where the scene has what the
/// new solver would refuse; otherwise it only switches.
#[test]
fn switching_solver_gives_way_with_a_note() {
    use sph_core::{PbfViscosity, SolverKind};
    // Water's dam break gives μ, which PBF's XSPH would refuse.
    let mut water = Scene::built_in("dam-break-water").unwrap();
    water.solver.pbf = None;
    assert!(
        water
            .clone()
            .with_solver(SolverKind::Pbf)
            .validate()
            .is_err()
    );
    let notes = water.switch_solver(SolverKind::Pbf);
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].contains("implicitly"), "{notes:?}");
    assert_eq!(water.pbf_params().viscosity, PbfViscosity::Implicit);
    water.validate().unwrap();
    // An XSPH blend the implicit viscosity would not read goes back to its
    // default, and the note names it.
    let mut blended = Scene::built_in("dam-break-water").unwrap();
    blended.solver.kind = SolverKind::Dfsph;
    blended.solver.pbf = Some(sph_core::PbfParams {
        xsph: 0.1,
        ..sph_core::PbfParams::default()
    });
    let notes = blended.switch_solver(SolverKind::Pbf);
    assert!(
        notes.len() == 1 && notes[0].contains("XSPH blend of 0.1"),
        "{notes:?}"
    );
    assert_eq!(
        blended.pbf_params().xsph,
        sph_core::PbfParams::default().xsph
    );
    blended.validate().unwrap();
    // The colour field is WCSPH's.
    let mut colour = Scene::dam_break(0.25, 0.08, 0.02);
    colour.fluid.surface_tension = 0.07;
    colour.fluid.surface_tension_model = Some(sph_core::SurfaceTensionModel::ColourField);
    let notes = colour.switch_solver(SolverKind::Dfsph);
    assert!(notes.len() == 1 && notes[0].contains("Akinci"), "{notes:?}");
    assert_eq!(colour.fluid.surface_tension_model, None);
    colour.validate().unwrap();
    // Nothing to give way: only the kind changes.
    let plain = Scene::built_in("dam-break").unwrap();
    let mut switched = plain.clone();
    assert!(switched.switch_solver(SolverKind::Wcsph).is_empty());
    assert_eq!(switched, plain.with_solver(SolverKind::Wcsph));
}

/// The slab dam break as TOML with one line replaced.
fn with(find: &str, replace: &str) -> String {
    let text = std::fs::read_to_string(format!("{SCENES}/dam_break_slab.toml")).unwrap();
    assert!(text.contains(find), "{find}");
    text.replacen(find, replace, 1)
}

fn message(text: &str) -> String {
    Scene::from_toml(text).unwrap_err().to_string()
}

/// Every solver applies a scene's surface tension: WCSPH by the thesis's
/// colour-field force inside its force sums, or with `surface_tension_model
/// = "akinci"` by a `surface tension` station (Akinci et al.'s forces), as
/// PBF and DFSPH always do; a scene without σ has no station. The colour
/// field under PBF or DFSPH is refused, naming the field and the solvers.
#[test]
fn every_solver_applies_surface_tension() {
    for sigma in ["0.0", "0.0728"] {
        for model in ["", "surface_tension_model = \"akinci\"\n"] {
            let text = with(
                "surface_tension = 0.0\n",
                &format!("surface_tension = {sigma}\n{model}"),
            );
            for kind in ["wcsph", "pbf", "dfsph"] {
                let scene = text.replacen("kind = \"pbf\"", &format!("kind = \"{kind}\""), 1);
                if sigma == "0.0" && !model.is_empty() {
                    // A model without σ is read by no solver.
                    let err = message(&scene);
                    assert!(
                        err.contains("fluid.surface_tension_model") && err.contains("> 0"),
                        "{err}"
                    );
                    continue;
                }
                let mut world = Scene::from_toml(&scene).unwrap().build_world().unwrap();
                world.advance(1.0 / 60.0).unwrap();
                let names: Vec<_> = world.program_mut().names().collect();
                assert_eq!(
                    names.contains(&"surface tension"),
                    sigma != "0.0" && (kind != "wcsph" || !model.is_empty()),
                    "{kind}, σ = {sigma}, {model}: {names:?}"
                );
            }
        }
    }
    let colour = with(
        "surface_tension = 0.0\n",
        "surface_tension = 0.0728\nsurface_tension_model = \"colour-field\"\n",
    );
    let wcsph = colour.replacen("kind = \"pbf\"", "kind = \"wcsph\"", 1);
    assert!(Scene::from_toml(&wcsph).unwrap().build_world().is_ok());
    // The colour field's threshold, where Akinci et al.'s forces run instead.
    let threshold = |model: &str| {
        let text = with(
            "surface_tension = 0.0\n",
            &format!("surface_tension = 0.0728\nsurface_tension_model = \"{model}\"\n"),
        );
        let text = text.replacen("kind = \"pbf\"", "kind = \"wcsph\"", 1);
        text.replacen("cfl = 0.4\n", "cfl = 0.4\nsurface_threshold = 2.5\n", 1)
    };
    assert!(Scene::from_toml(&threshold("colour-field")).is_ok());
    let err = message(&threshold("akinci"));
    assert!(
        err.contains("solver.wcsph.surface_threshold") && err.contains("colour-field force only"),
        "{err}"
    );
    for kind in ["pbf", "dfsph"] {
        let scene = colour.replacen("kind = \"pbf\"", &format!("kind = \"{kind}\""), 1);
        let err = message(&scene);
        assert!(
            err.contains("fluid.surface_tension_model") && err.contains("PBF and DFSPH"),
            "{err}"
        );
    }
    let typo = with(
        "surface_tension = 0.0\n",
        "surface_tension = 0.0\nsurface_tension_model = \"csf\"\n",
    );
    let err = message(&typo);
    assert!(err.contains("surface_tension_model"), "{err}");
}

#[test]
fn malformed_scenes_name_the_field_and_reason() {
    let cases: [(&str, &str, &[&str]); 41] = [
        (
            "spacing = 0.02\n",
            "spacing = 0.02\nclearance = -0.01\n",
            &["clearance", "≥ 0"],
        ),
        (
            "spacing = 0.02\n",
            "spacing = 0.02\nclearance = 0.03\n",
            &["clearance", "at most the spacing"],
        ),
        (
            "spacing = 0.02\n",
            "spacing = 0.02\nclearance = nan\n",
            &["clearance", "≥ 0"],
        ),
        ("h = 0.04", "h = 0.04 +", &["scene file", "line"]),
        (
            "h = 0.04",
            "h = 0.04\nbogus = 1",
            &["unknown field", "bogus"],
        ),
        ("spacing = 0.02\n", "", &["missing field", "spacing"]),
        ("h = 0.04", "h = -0.04", &["fluid.h", "> 0"]),
        ("h = 0.04", "h = nan", &["fluid.h", "finite"]),
        // A domain reaching 2.5e6 h from the origin, where f32 resolves
        // positions to worse than h/128.
        (
            "min = [0.0, 0.0, 0.0]",
            "min = [-1e5, 0.0, 0.0]",
            &["domain.min", "65,536 h"],
        ),
        // Numbers that f32 would read as 0 or infinity.
        (
            "surface_tension = 0.0",
            "surface_tension = 1e-50",
            &["fluid.surface_tension", "f32's range", "become 0"],
        ),
        (
            "rest_density = 1000.0",
            "rest_density = 1e39",
            &["fluid.rest_density", "f32's range", "become inf"],
        ),
        (
            "max = [0.25, 0.5, 0.08]",
            "max = [0.25, 0.5, -1e-46]",
            &["blocks[0].max[2]", "f32's range"],
        ),
        (
            "surface_tension = 0.0",
            "surface_tension = -0.07",
            &["fluid.surface_tension", ">= 0"],
        ),
        (
            "surface_tension = 0.0",
            "surface_tension = nan",
            &["fluid.surface_tension", "finite"],
        ),
        (
            "spacing = 0.02",
            "spacing = 0.05",
            &["spacing", "smaller than fluid.h"],
        ),
        (
            "rest_density = 1000.0",
            "rest_density = 0.0",
            &["fluid.rest_density", "> 0"],
        ),
        (
            "max = [0.25, 0.5, 0.08]",
            "max = [0.25, 5.0, 0.08]",
            &["blocks[0]", "outside the domain"],
        ),
        (
            "max_particles = 2000000",
            "max_particles = 100",
            &["max_particles", "more than"],
        ),
        // Would take (2·⌈h/spacing⌉ + 1)³ kernel sums to find the mass.
        (
            "spacing = 0.02",
            "spacing = 0.00002",
            &["spacing", "exceeds 10"],
        ),
        // The kernels' coefficients overflow f32 below h = 1e-4 m.
        ("h = 0.04", "h = 0.00005", &["h", "[1e-4, 1e3]"]),
        (
            "frame_dt = 0.016666668",
            "frame_dt = 10000.0",
            &["time_step.frame_dt", "longer than 1 s"],
        ),
        (
            "frame_dt = 0.016666668",
            "frame_dt = 1e-30",
            &["time_step.frame_dt", "shortest step"],
        ),
        (
            "max_dt = 0.002",
            "max_dt = 1e-9",
            &["solver.wcsph.max_dt", "at least min_dt"],
        ),
        // PBF's default XSPH viscosity has no μ to apply.
        (
            "rest_density = 1000.0\n",
            "rest_density = 1000.0\nviscosity = 1e-3\n",
            &["fluid.viscosity", "not applied by PBF", "implicit"],
        ),
        // WCSPH's own values are named where they live.
        (
            "stiffness = 2000.0",
            "stiffness = 0.0",
            &["solver.wcsph.stiffness", "> 0"],
        ),
        (
            "negative_pressure_scale = 0.0",
            "negative_pressure_scale = 2.0",
            &["solver.wcsph.negative_pressure_scale", "[0, 1]"],
        ),
        // A field unknown to PBF is not told it is WCSPH's.
        (
            "scorr_n = 4\n",
            "scorr_n = 4\ncfl = 0.4\n",
            &["unknown field `cfl`"],
        ),
        // WCSPH's parameters moved out of [fluid] and [time_step].
        (
            "rest_density = 1000.0\n",
            "rest_density = 1000.0\nstiffness = 2000.0\n",
            &["unknown field `stiffness`", "[solver.wcsph]"],
        ),
        (
            "frame_dt = 0.016666668",
            "frame_dt = 0.016666668\ncfl = 0.4",
            &["unknown field `cfl`", "[solver.wcsph]"],
        ),
        ("fov_y = 45.0", "fov_y = 0.0", &["render.fov_y", "degrees"]),
        ("fov_y = 45.0", "fov_y = nan", &["render.fov_y", "degrees"]),
        (
            "fov_y = 45.0",
            "fov_y = 179.995",
            &["render.fov_y", "0.011°"],
        ),
        (
            "look_at = [0.5, 0.208, 0.04]",
            "look_at = [0.5, 0.744, 1.112]",
            &["render.look_at", "differ"],
        ),
        (
            "look_at = [0.5, 0.208, 0.04]",
            "look_at = [0.5, 0.208, 1.112]",
            &["render.look_at", "vertical"],
        ),
        (
            "camera = [0.5, 0.744, 1.112]\nlook_at = [0.5, 0.208, 0.04]",
            "camera = [-3e38, 0.744, 1.112]\nlook_at = [3e38, 0.208, 0.04]",
            &["render.look_at", "overflows"],
        ),
        // A nozzle 100 particles wide is 2 m across in a 1 m domain.
        (
            "[time_step]",
            "[[emitters]]\ncentre = [0.5, 0.3, 0.04]\nvelocity = [1.0, 0.0, 0.0]\nwidth = 100\n\n[time_step]",
            &["emitters[0]", "nozzle", "outside the domain"],
        ),
        (
            "[time_step]",
            "[[emitters]]\ncentre = [0.5, 0.3, 0.04]\nvelocity = [1.0, 0.0, 0.0]\nwidth = 4294967295\n\n[time_step]",
            &["emitters[0]", "nozzle"],
        ),
        // A small sphere in the middle of a 3-wide nozzle, clear of its corners.
        (
            "[time_step]",
            "[[obstacles]]\nshape = \"sphere\"\ncentre = [0.5, 0.3, 0.04]\nradius = 0.01\n\n[[emitters]]\ncentre = [0.5, 0.3, 0.04]\nvelocity = [1.0, 0.0, 0.0]\nwidth = 3\n\n[time_step]",
            &["emitters[0]", "obstacle"],
        ),
        (
            "max_particles = 2000000",
            "max_particles = 5000000000",
            &["max_particles", "limit"],
        ),
        // Two particles on one lattice point would never separate.
        (
            "[time_step]",
            "[[blocks]]\nmin = [0.2, 0.4, 0.0]\nmax = [0.4, 0.6, 0.08]\nvelocity = [0.0, 0.0, 0.0]\n\n[time_step]",
            &["blocks[1]", "overlaps blocks[0]"],
        ),
        // A block thinner than a spacing would hold no particle.
        (
            "[time_step]",
            "[[blocks]]\nmin = [0.5, 0.0, 0.0]\nmax = [0.51, 0.1, 0.08]\nvelocity = [0.0, 0.0, 0.0]\n\n[time_step]",
            &["blocks[1]", "along x", "no particle"],
        ),
    ];
    for (find, replace, words) in cases {
        let msg = message(&with(find, replace));
        for w in words {
            assert!(
                msg.contains(w),
                "`{replace}` gave `{msg}`, which lacks `{w}`"
            );
        }
    }
    // The hint that a field moved to [solver.wcsph] only where it was.
    let pbf_cfl = message(&with("scorr_n = 4\n", "scorr_n = 4\ncfl = 0.4\n"));
    assert!(!pbf_cfl.contains("[solver.wcsph]"), "{pbf_cfl}");
    // Without [render], the camera frames the domain, wherever it lies.
    let text = with("[domain]", "[domain]");
    let start = text.find("[render]").unwrap();
    let end = start + text[start..].find("\n\n").unwrap();
    let far = format!("{}{}", &text[..start], &text[end..])
        .replace(
            "min = [0.0, 0.0, 0.0]\nmax = [1.0, 0.625, 0.08]",
            "min = [10.0, 0.0, 10.0]\nmax = [11.0, 0.625, 10.08]",
        )
        .replace(
            "min = [0.0, 0.0, 0.0]\nmax = [0.25, 0.5, 0.08]",
            "min = [10.0, 0.0, 10.0]\nmax = [10.25, 0.5, 10.08]",
        );
    let scene = Scene::from_toml(&far).unwrap();
    let framing = sph_core::scene::RenderSpec::framing(
        sph_core::glam::Vec3::new(10.0, 0.0, 10.0),
        sph_core::glam::Vec3::new(11.0, 0.625, 10.08),
        45.0,
    );
    assert_eq!(scene.render, framing);
    // A nozzle that fits and is inside no obstacle is accepted.
    let fits = "[[emitters]]\ncentre = [0.5, 0.3, 0.04]\nvelocity = [1.0, 0.0, 0.0]\nwidth = 3\n\n[time_step]";
    Scene::from_toml(&with("[time_step]", fits)).unwrap();
    // Blocks that touch without overlapping are accepted.
    let touching = "[[blocks]]\nmin = [0.25, 0.0, 0.0]\nmax = [0.4, 0.2, 0.08]\nvelocity = [0.0, 0.0, 0.0]\n\n[time_step]";
    Scene::from_toml(&with("[time_step]", touching)).unwrap();
    // A block a whole number of spacings wide holds that many lattice
    // points, though in f32 0.1 / 0.02 is 4.9999981.
    let round = "[[blocks]]\nmin = [0.6, 0.0, 0.0]\nmax = [0.7, 0.1, 0.08]\nvelocity = [0.0, 0.0, 0.0]\n\n[time_step]";
    let one = Scene::from_toml(&with("[time_step]", "[time_step]")).unwrap();
    let two = Scene::from_toml(&with("[time_step]", round)).unwrap();
    let count = |s: &Scene| s.particles().unwrap().len();
    assert_eq!(count(&two) - count(&one), 5 * 5 * 4);
    // A nozzle layer larger than the particle budget (checked before walking
    // its points, whose number is the layer's).
    let wide =
        with("[time_step]", fits).replacen("max_particles = 2000000", "max_particles = 8", 1);
    let msg = message(&wide);
    assert!(
        msg.contains("emitters[0].width") && msg.contains("max_particles"),
        "{msg}"
    );
    // The blocks' 1,200 particles leave no room for a layer of 9: an error,
    // where the emitter used to add nothing. Room for one layer and a
    // half: it adds one whole layer and stops.
    let budget = |max: usize| {
        with("[time_step]", fits).replacen(
            "max_particles = 2000000",
            &format!("max_particles = {max}"),
            1,
        )
    };
    let msg = message(&budget(1205));
    assert!(
        msg.contains("emitters[0].width") && msg.contains("1200"),
        "{msg}"
    );
    let mut world = Scene::from_toml(&budget(1213))
        .unwrap()
        .build_world()
        .unwrap();
    for _ in 0..6 {
        world.advance(1.0 / 60.0).unwrap();
    }
    assert_eq!(world.particles.len(), 1209);
    // A speed that carries layers beyond the far wall within one step: an
    // error, where they were pressed onto the wall on top of each other.
    let fast = with("[time_step]", fits).replacen(
        "velocity = [1.0, 0.0, 0.0]",
        "velocity = [1000.0, 0.0, 0.0]",
        1,
    );
    let mut world = Scene::from_toml(&fast).unwrap().build_world().unwrap();
    let e = world.advance(1.0 / 60.0).unwrap_err().to_string();
    assert!(
        e.contains("emitter.velocity") && e.contains("out of the domain"),
        "{e}"
    );
    // Obstacles over the whole block leave no fluid: an error, not an empty run.
    let buried = with(
        "[time_step]",
        "[[obstacles]]\nshape = \"box\"\nmin = [-0.1, -0.1, -0.1]\nmax = [0.3, 0.6, 0.1]\n\n[time_step]",
    );
    let e = Scene::from_toml(&buried)
        .unwrap()
        .build_world()
        .unwrap_err();
    assert!(e.to_string().contains("no fluid"), "{e}");
    // So does one block of two, named, while the other keeps its fluid.
    let two = Scene {
        blocks: vec![
            BlockSpec {
                min: [0.0, 0.0, 0.0],
                max: [0.6, 0.1, 0.6],
                velocity: [0.0; 3],
            },
            BlockSpec {
                min: [0.25, 0.3, 0.25],
                max: [0.35, 0.4, 0.35],
                velocity: [0.0; 3],
            },
        ],
        obstacles: vec![ObstacleSpec::Box {
            min: [0.2, 0.25, 0.2],
            max: [0.4, 0.45, 0.4],
        }],
        domain: BoxSpec {
            min: [0.0; 3],
            max: [0.6, 0.6, 0.6],
        },
        emitters: Vec::new(),
        ..Scene::built_in("dam-break").unwrap()
    };
    let e = two.build_world().unwrap_err().to_string();
    assert!(
        e.contains("blocks[1]") && e.contains("holds no fluid"),
        "{e}"
    );
    let one = Scene {
        blocks: two.blocks[..1].to_vec(),
        ..two.clone()
    };
    assert!(one.build_world().is_ok());
    // PBF's substeps derived from a fall (no `[solver.pbf]`) that would
    // need more than PBF takes: an error saying where they came from, not
    // a run with every particle slowed by the displacement guard.
    let mut heavy = Scene::built_in("dam-break").unwrap();
    assert!(heavy.solver.pbf.is_none());
    heavy.fluid.gravity = [0.0, -1e9, 0.0];
    let msg = heavy.validate().unwrap_err().to_string();
    for w in ["solver.pbf", "is not given", "fluid.gravity", "substeps"] {
        assert!(msg.contains(w), "`{msg}` lacks `{w}`");
    }
    // A frame shorter than the shortest step would not move the clock.
    let mut world = Scene::built_in("dam-break").unwrap().build_world().unwrap();
    let e = world.advance(1e-9).unwrap_err().to_string();
    assert!(e.contains("frame_dt") && e.contains("min_dt"), "{e}");
    let e = Scene::load("/nonexistent/scene.toml").unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
}

/// A degenerate obstacle (a box of zero size or turned inside out, a sphere
/// of zero radius, NaN anywhere) is an error naming its field, from the file
/// as from the library, before any particle or scenery is built.
#[test]
fn degenerate_obstacles_name_the_field() {
    let sphere = |centre: &str, radius: &str| {
        format!(
            "[[obstacles]]\nshape = \"sphere\"\ncentre = {centre}\nradius = {radius}\n\n[time_step]"
        )
    };
    let cuboid = |min: &str, max: &str| {
        format!("[[obstacles]]\nshape = \"box\"\nmin = {min}\nmax = {max}\n\n[time_step]")
    };
    let cases = [
        (sphere("[0.5, 0.3, 0.04]", "0.0"), "obstacles[0].radius"),
        (sphere("[0.5, 0.3, 0.04]", "-0.1"), "obstacles[0].radius"),
        (sphere("[0.5, 0.3, 0.04]", "nan"), "obstacles[0].radius"),
        (sphere("[0.5, nan, 0.04]", "0.1"), "obstacles[0].centre"),
        (
            cuboid("[0.6, 0.0, 0.0]", "[0.6, 0.2, 0.08]"),
            "obstacles[0]",
        ),
        (
            cuboid("[0.7, 0.0, 0.0]", "[0.6, 0.2, 0.08]"),
            "obstacles[0]",
        ),
        (
            cuboid("[0.6, 0.0, nan]", "[0.7, 0.2, 0.08]"),
            "obstacles[0].min",
        ),
        (
            cuboid("[0.6, 0.0, 0.0]", "[inf, 0.2, 0.08]"),
            "obstacles[0].max",
        ),
    ];
    for (obstacle, field) in cases {
        let msg = message(&with("[time_step]", &obstacle));
        assert!(
            msg.contains(field),
            "`{obstacle}` gave `{msg}`, which lacks `{field}`"
        );
    }
    // Obstacles that miss the domain (1 × 0.625 × 0.08 m) hold nothing back.
    for obstacle in [
        cuboid("[5.0, 0.0, 0.0]", "[6.0, 0.2, 0.08]"),
        sphere("[0.5, 0.3, 0.5]", "0.3"),
    ] {
        let msg = message(&with("[time_step]", &obstacle));
        assert!(
            msg.contains("obstacles[0]") && msg.contains("wholly outside"),
            "{msg}"
        );
    }
    // Ones that reach into it are accepted.
    Scene::from_toml(&with("[time_step]", &sphere("[0.5, 0.3, 0.5]", "0.5"))).unwrap();
    // The same box with room inside is accepted.
    Scene::from_toml(&with(
        "[time_step]",
        &cuboid("[0.6, 0.0, 0.0]", "[0.7, 0.2, 0.08]"),
    ))
    .unwrap();
}

/// Every number in every scene file, replaced in turn by an awkward value
/// (zero, negative, tiny, huge, NaN, ±infinity, …): the scene is an error or
/// it builds and runs three steps (then, where the case changed `frame_dt`
/// to at most 0.02 s, one frame of it), each an error or a finite state.
/// Nothing panics.
#[test]
fn any_one_number_replaced_is_an_error_or_a_running_scene() {
    use std::panic::{AssertUnwindSafe, catch_unwind};
    const FLOATS: [&str; 11] = [
        "0.0", "-1.0", "1e-30", "1e-7", "0.5", "3.0e5", "1e30", "nan", "inf", "-inf", "-0.0",
    ];
    const INTS: [&str; 6] = ["0", "-1", "1", "7", "4294967296", "9223372036854775807"];
    let number = |c: char| c.is_ascii_digit() || "+-.eE".contains(c);
    let (mut cases, mut runs) = (0, 0);
    let mut panics = Vec::new();
    for entry in std::fs::read_dir(SCENES).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let frame_dt0 = Scene::from_toml(&text).unwrap().time_step.frame_dt;
        // The numbers' spans, outside comments and strings.
        let mut spans = Vec::new();
        let mut offset = 0;
        for line in text.split_inclusive('\n') {
            let code = line.split('#').next().unwrap();
            if !code.contains('"') {
                let bytes: Vec<char> = code.chars().collect();
                let mut i = 0;
                while i < bytes.len() {
                    let starts = bytes[i].is_ascii_digit()
                        || (bytes[i] == '-'
                            && bytes.get(i + 1).is_some_and(|c| c.is_ascii_digit()));
                    let after_name =
                        i > 0 && (bytes[i - 1].is_alphanumeric() || bytes[i - 1] == '_');
                    if starts && !after_name {
                        let j = (i..bytes.len())
                            .find(|&j| !number(bytes[j]))
                            .unwrap_or(bytes.len());
                        spans.push((offset + i, offset + j));
                        i = j;
                    } else {
                        i += 1;
                    }
                }
            }
            offset += line.len();
        }
        assert!(
            spans.len() > 15,
            "{}: {} numbers",
            path.display(),
            spans.len()
        );
        for &(a, b) in &spans {
            let values: &[&str] = if text[a..b].contains('.') || text[a..b].contains('e') {
                &FLOATS
            } else {
                &INTS
            };
            for value in values {
                let mutated = format!("{}{value}{}", &text[..a], &text[b..]);
                cases += 1;
                let outcome = catch_unwind(AssertUnwindSafe(|| {
                    let Ok(scene) = Scene::from_toml(&mutated) else {
                        return false;
                    };
                    let Ok(mut world) = scene.build_world() else {
                        return false;
                    };
                    let finite = |w: &sph_core::World| {
                        let p = &w.particles;
                        p.positions().iter().all(|x| x.is_finite())
                            && p.velocities().iter().all(|v| v.is_finite())
                    };
                    for _ in 0..3 {
                        if world.step().is_err() {
                            return true;
                        }
                        assert!(finite(&world), "a step returned Ok with a non-finite state");
                    }
                    // A frame as the app takes it, where this case changed
                    // frame_dt to one short enough to run here.
                    let frame_dt = scene.time_step.frame_dt;
                    if frame_dt != frame_dt0 && frame_dt <= 0.02 && world.advance(frame_dt).is_ok()
                    {
                        assert!(
                            finite(&world),
                            "a frame returned Ok with a non-finite state"
                        );
                    }
                    true
                }));
                match outcome {
                    Ok(ran) => runs += usize::from(ran),
                    Err(_) => panics.push(format!(
                        "{}: {} -> {value}",
                        path.file_name().unwrap().to_string_lossy(),
                        &text[a..b]
                    )),
                }
            }
        }
    }
    println!("{cases} mutated scenes: {runs} built and ran, the rest were errors");
    assert!(panics.is_empty(), "panicked: {panics:#?}");
    assert!(runs > 0 && runs < cases, "{runs} of {cases} ran");
}

/// The `drops` scene shows surface tension: with water's σ the two
/// weightless cubes merge into one round drop, whose radius of gyration
/// after 3 s is within 10 % of a sphere's of the same volume; without σ
/// they collide and splash apart, and it ends at least 1.5 times that.
/// Measured: 1.042 and 2.293.
#[test]
fn the_drops_scene_merges_by_surface_tension() {
    let gyration = |sigma: f32| {
        let mut scene = Scene::built_in("drops").unwrap();
        scene.fluid.surface_tension = sigma;
        let mut world = scene.build_world().unwrap();
        while world.time() < 3.0 - 1e-9 {
            world.advance(1.0 / 60.0).unwrap();
        }
        let p = &world.particles;
        let n = p.len() as f64;
        let c = p
            .positions()
            .iter()
            .map(|x| x.as_dvec3())
            .sum::<sph_core::glam::DVec3>()
            / n;
        let rg = (p.positions().iter())
            .map(|x| (x.as_dvec3() - c).length_squared())
            .sum::<f64>()
            / n;
        let radius =
            (3.0 * n * f64::from(scene.spacing).powi(3) / (4.0 * std::f64::consts::PI)).cbrt();
        rg.sqrt() / ((3.0f64 / 5.0).sqrt() * radius)
    };
    let (with, without) = (gyration(0.0728), gyration(0.0));
    println!("radius of gyration over a sphere's: {with:.3} with σ, {without:.3} without");
    assert!((with - 1.0).abs() <= 0.1, "{with}");
    assert!(without >= 1.5, "{without}");
}

/// A world rebuilt mid-run with `Scene::world_continuing` (the demo's
/// panel after a slider moved) runs on as if nothing had happened when
/// nothing changed: the same particles, bit for bit, the same clock, and
/// its emitter keeps its place in the stream. A fresh emitter would emit
/// a layer at once, within a spacing of the last. A changed fluid
/// parameter keeps the emitter's place too; a moved emitter starts afresh
/// where it now is; a scene the new parameters break leaves the old world
/// running untouched.
#[test]
fn a_world_continued_mid_run_keeps_its_emitter_and_clock() {
    let scene = Scene::load(format!("{SCENES}/drop_into_pool.toml")).unwrap();
    let mut straight = scene.build_world().unwrap();
    let mut rebuilt = scene.build_world().unwrap();
    let frame = 1.0 / 60.0;
    let both = |a: &mut sph_core::World, b: &mut sph_core::World, dt: f32, n: usize| {
        for _ in 0..n {
            a.advance(dt).unwrap();
            b.advance(dt).unwrap();
        }
    };
    both(&mut straight, &mut rebuilt, frame, 10);
    let mut rebuilt = scene.world_continuing(&mut rebuilt, &scene).unwrap();
    assert_eq!(rebuilt.time(), straight.time());
    assert_eq!(rebuilt.steps(), straight.steps());
    both(&mut straight, &mut rebuilt, frame, 5);
    assert_eq!(rebuilt.particles.len(), straight.particles.len());
    assert_eq!(
        rebuilt.particles.positions(),
        straight.particles.positions()
    );
    // Refused: the running world is untouched, still in step.
    let mut bad = scene.clone();
    bad.fluid.surface_tension = -1.0;
    assert!(bad.world_continuing(&mut rebuilt, &scene).is_err());
    both(&mut straight, &mut rebuilt, frame, 1);
    assert_eq!(
        rebuilt.particles.positions(),
        straight.particles.positions()
    );
    // Gravity changed (the emitters and the mass as they were): the stream
    // goes on where it was, so the count stays that of the straight run
    // (a fresh emitter would be a layer ahead).
    let mut lighter = scene.clone();
    lighter.fluid.gravity[1] = -9.0;
    let mut light = lighter.world_continuing(&mut rebuilt, &scene).unwrap();
    both(&mut straight, &mut light, frame, 5);
    assert_eq!(light.particles.len(), straight.particles.len());
    // As the demo once did it, with a fresh emitter: a layer at once.
    let layer = 16;
    let mut fresh = scene.world_with(straight.particles.clone()).unwrap();
    fresh.advance(1e-4).unwrap();
    straight.advance(1e-4).unwrap();
    assert_eq!(fresh.particles.len(), straight.particles.len() + layer);
    // A moved emitter starts afresh, at its new place.
    let mut moved = scene.clone();
    moved.emitters[0].centre[2] += 0.02;
    let newest = straight.particles.ids().iter().copied().max().unwrap();
    let mut moved_world = moved.world_continuing(&mut straight, &scene).unwrap();
    moved_world.advance(1e-4).unwrap();
    let p = &moved_world.particles;
    let new: Vec<_> = (p.ids().iter().zip(p.positions()))
        .filter(|&(&id, _)| id > newest)
        .map(|(_, x)| *x)
        .collect();
    assert_eq!(new.len(), layer);
    let z = new.iter().map(|x| x.z).sum::<f32>() / layer as f32;
    // A tenth of a spacing: the old place was a whole spacing away.
    assert!((z - moved.emitters[0].centre[2]).abs() < 2e-3, "{z}");
}
