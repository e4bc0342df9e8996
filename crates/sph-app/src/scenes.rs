//! The built-in scenes (keys 1–8 in the window) and `--scene` resolution.

use std::path::Path;

use sph_core::Scene;
#[cfg(test)]
use sph_core::SolverKind;

use crate::error::AppError;

/// The scene the demo opens without `--scene`: the largest built-in scene
/// that PBF simulates and extracts in real time on two cores.
pub const DEFAULT: &str = "drop";

pub use sph_core::scene::BUILT_IN;

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
    let mut out = String::from("built-in scenes (--scene NAME, keys 1-8 in the window):\n");
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
        for (name, _, make) in BUILT_IN {
            let default = if ["dam-break-water", "honey"].contains(&name) {
                SolverKind::Dfsph
            } else {
                SolverKind::Pbf
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
