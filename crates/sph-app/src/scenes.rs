//! The built-in scenes (keys 1–7 in the window) and `--scene` resolution.

use std::path::Path;

use sph_core::scene::ObstacleSpec;
use sph_core::{Scene, SolverKind};

use crate::error::AppError;

/// The scene the demo opens without `--scene`: the largest built-in scene
/// that PBF simulates and extracts in real time on two cores.
pub const DEFAULT: &str = "drop";

/// A built-in scene: name, description, constructor.
pub type BuiltIn = (&'static str, &'static str, fn() -> Scene);

/// Built-in scenes, in key order (keys 1–7). The first five run PBF, the
/// real-time solver, with the parameters `Scene::pbf_params` derives (3
/// iterations, and 3 substeps per 60 Hz frame, 5 for `dam-break-fine`, so
/// that a fall through the fluid's height moves at most 0.6 h per substep);
/// the last two DFSPH, the accurate one, with physical viscosities: water
/// (1e-3 Pa·s) and honey (50 Pa·s). `--solver` runs any with another.
pub const BUILT_IN: [BuiltIn; 7] = [
    ("dam-break", "thin-slab dam break", || {
        Scene::dam_break(0.25, 0.08, 0.02).with_solver(SolverKind::Pbf)
    }),
    (
        "dam-break-3d",
        "full 3D dam break around a sphere and a low wall",
        || {
            // The obstacles of assets/scenes/dam_break_3d.toml.
            let mut scene = Scene::dam_break(0.25, 0.25, 0.02).with_solver(SolverKind::Pbf);
            scene.obstacles = vec![
                ObstacleSpec::Sphere {
                    centre: [0.6, 0.0, 0.125],
                    radius: 0.1,
                },
                ObstacleSpec::Box {
                    min: [0.85, 0.0, 0.0],
                    max: [0.9, 0.1, 0.25],
                },
            ];
            scene
        },
    ),
    (
        "double-dam-break",
        "two columns released from both ends",
        || Scene::double_dam_break(0.2, 0.08, 0.02).with_solver(SolverKind::Pbf),
    ),
    ("drop", "a cube of water falling into a pool", || {
        Scene::drop_into_pool(0.2, 0.02).with_solver(SolverKind::Pbf)
    }),
    (
        "dam-break-fine",
        "thin-slab dam break at 1 cm spacing",
        || Scene::dam_break(0.25, 0.08, 0.01).with_solver(SolverKind::Pbf),
    ),
    (
        "dam-break-water",
        "thin-slab dam break of water (μ = 1e-3 Pa·s), DFSPH",
        || {
            let mut scene = Scene::dam_break(0.25, 0.08, 0.02).with_solver(SolverKind::Dfsph);
            scene.fluid.viscosity = 1e-3;
            scene
        },
    ),
    (
        "honey",
        "a cube of honey (μ = 50 Pa·s) slumping, DFSPH",
        || Scene::honey(0.2, 0.02),
    ),
];

/// A built-in scene by name, or a scene file (`.toml`, or any existing path).
pub fn resolve(scene: &str) -> Result<(String, Scene), AppError> {
    if let Some((name, _, make)) = BUILT_IN.iter().find(|(n, _, _)| *n == scene) {
        return Ok((name.to_string(), make()));
    }
    let path = Path::new(scene);
    if path.extension().is_some_and(|e| e == "toml") || path.exists() {
        let loaded = Scene::load(path).map_err(|source| AppError::Scene {
            scene: scene.to_string(),
            source,
        })?;
        return Ok((scene.to_string(), loaded));
    }
    Err(AppError::UnknownScene(scene.to_string()))
}

/// The `--list-scenes` text, with each scene's particle count at the start.
pub fn listing() -> String {
    let mut out = String::from("built-in scenes (--scene NAME, keys 1-7 in the window):\n");
    for (i, (name, what, make)) in BUILT_IN.iter().enumerate() {
        let scene = make();
        let count = match scene.particles() {
            Ok(p) => format!("{} particles, {}", p.len(), scene.solver.kind),
            Err(e) => format!("invalid: {e}"),
        };
        let default = if *name == DEFAULT {
            " (the default)"
        } else {
            ""
        };
        out.push_str(&format!(
            "  {}  {name:<18} {what}, {count}{default}\n",
            i + 1
        ));
    }
    out.push_str("or a scene file: --scene assets/scenes/dam_break_3d.toml\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_ins_are_valid_and_names_resolve() {
        for (name, _, make) in BUILT_IN {
            make().validate().unwrap();
            assert_eq!(resolve(name).unwrap().0, name);
        }
        assert!(matches!(
            resolve("nonsense"),
            Err(AppError::UnknownScene(_))
        ));
    }

    /// Every built-in scene runs a frame with each solver; PBF by default,
    /// DFSPH for the two with physical viscosities.
    #[test]
    fn built_ins_run_with_every_solver() {
        for (k, (name, _, make)) in BUILT_IN.iter().enumerate() {
            let default = if k < 5 {
                SolverKind::Pbf
            } else {
                SolverKind::Dfsph
            };
            assert_eq!(make().solver.kind, default, "{name}");
            for kind in SolverKind::ALL {
                let mut world = make().with_solver(kind).build_world().unwrap();
                let r = world.advance(1.0 / 60.0).unwrap();
                assert_eq!(r.solver, kind, "{name}");
                assert!(r.density_error_avg.is_finite(), "{name} {kind}: {r:?}");
            }
        }
    }
}
