//! The built-in scenes: the thesis's dam breaks, a drop into a pool, honey
//! and two weightless drops, by name ([`BUILT_IN`], [`Scene::built_in`]).

use glam::Vec3;

use super::{
    BlockSpec, BoxSpec, FluidSpec, ObstacleSpec, RenderSpec, Scene, SolverSpec, TimeStepSpec,
    default_max_particles,
};
use crate::solver::SolverKind;

impl Scene {
    /// Common parameters of the built-in scenes: h = 2 × spacing, run by
    /// the thesis's WCSPH (the constructors build the thesis's scenes;
    /// [`Scene::with_solver`] picks another, as the demo picks PBF).
    pub(super) fn base(name: &str, domain: Vec3, spacing: f32) -> Self {
        let h = 2.0 * spacing;
        Scene {
            name: name.into(),
            domain: BoxSpec {
                min: [0.0; 3],
                max: domain.to_array(),
            },
            fluid: FluidSpec {
                h,
                rest_density: 1000.0,
                viscosity: None,
                surface_tension: 0.0,
                surface_tension_model: None,
                gravity: [0.0, -9.81, 0.0],
            },
            spacing,
            blocks: Vec::new(),
            obstacles: Vec::new(),
            clearance: None,
            emitters: Vec::new(),
            time_step: TimeStepSpec {
                frame_dt: 1.0 / 60.0,
            },
            max_particles: default_max_particles(),
            solver: SolverSpec {
                kind: SolverKind::Wcsph,
                ..SolverSpec::default()
            },
            render: RenderSpec::framing(Vec3::ZERO, domain, 45.0),
        }
    }

    /// The dam break: a water column of width `a` and height 2a at the left of a
    /// tank 4a long and 2.5a high, `depth` deep (a thin slab when depth is a few
    /// spacings, full 3D when depth ≈ a); lengths in metres, particles on a
    /// lattice of `spacing`, h = 2 × spacing.
    pub fn dam_break(a: f32, depth: f32, spacing: f32) -> Self {
        let mut s = Self::base("dam break", Vec3::new(4.0 * a, 2.5 * a, depth), spacing);
        s.blocks.push(BlockSpec {
            min: [0.0; 3],
            max: [a, 2.0 * a, depth],
            velocity: [0.0; 3],
        });
        s
    }

    /// Two columns released from both ends of the tank.
    pub fn double_dam_break(a: f32, depth: f32, spacing: f32) -> Self {
        let mut s = Self::base(
            "double dam break",
            Vec3::new(5.0 * a, 2.5 * a, depth),
            spacing,
        );
        for x0 in [0.0, 4.0 * a] {
            s.blocks.push(BlockSpec {
                min: [x0, 0.0, 0.0],
                max: [x0 + a, 2.0 * a, depth],
                velocity: [0.0; 3],
            });
        }
        s
    }

    /// A cube of honey (side `a`, ρ0 = 1,400 kg/m³, μ = 50 Pa·s: 50,000 ×
    /// water) let go a/2 above the floor of a tank 4a wide: it slumps and
    /// spreads slowly, run by DFSPH (whose viscosity is implicit); run by
    /// PBF, its `[solver.pbf]` solves the same μ implicitly
    /// ([`PbfViscosity::Implicit`](crate::PbfViscosity::Implicit)) instead of XSPH.
    pub fn honey(a: f32, spacing: f32) -> Self {
        let w = 4.0 * a;
        let mut s = Self::base("honey", Vec3::new(w, 2.5 * a, w), spacing);
        s.fluid.rest_density = 1400.0;
        s.blocks.push(BlockSpec {
            min: [1.5 * a, 0.5 * a, 1.5 * a],
            max: [2.5 * a, 1.5 * a, 2.5 * a],
            velocity: [0.0; 3],
        });
        s.solver.kind = SolverKind::Dfsph;
        s.with_viscosity(50.0)
    }

    /// A cube of water of side `a` falling into a pool of depth a/2 in a tank 3a
    /// wide and deep.
    pub fn drop_into_pool(a: f32, spacing: f32) -> Self {
        let w = 3.0 * a;
        let mut s = Self::base("drop into pool", Vec3::new(w, 3.0 * a, w), spacing);
        s.blocks.push(BlockSpec {
            min: [0.0; 3],
            max: [w, 0.5 * a, w],
            velocity: [0.0; 3],
        });
        s.blocks.push(BlockSpec {
            min: [a, 1.6 * a, a],
            max: [2.0 * a, 2.6 * a, 2.0 * a],
            velocity: [0.0, -1.0, 0.0],
        });
        s
    }
}

impl Scene {
    /// Two weightless cubes of water (side 13 spacings, 6.5 cm at 5 mm)
    /// drifting towards each other at 5 cm/s each, a third of a side off
    /// centre, in a box 0.36 × 0.2 × 0.2 m: surface tension (water's σ =
    /// 0.0728 N/m) rounds each into a drop, and the drops merge into one
    /// that spins and wobbles. Without σ nothing pulls them round or holds
    /// them together. h = 2 × spacing, as the other scenes. No μ is given:
    /// PBF, which runs it (on the GPU too), damps by its XSPH blend, and
    /// the other solvers take [`FluidSpec::DEFAULT_VISCOSITY`].
    pub fn weightless_drops(spacing: f32) -> Self {
        let (w, d) = (0.36, 0.2);
        let mut s = Self::base("weightless drops", Vec3::new(w, d, d), spacing);
        s.fluid.gravity = [0.0; 3];
        s.fluid.surface_tension = 0.0728;
        // 13 lattice points a side. The extent is a quarter spacing over
        // 13 from when the lattice rounded 12.999998 spacings (13 × 0.005
        // in f32) down to 12; it is kept so the scene's particles stay
        // where its measurements put them.
        let side = 13.25 * spacing;
        let offset = side / 3.0;
        for (cx, cy, vx) in [
            (0.3 * w, 0.5 * d + 0.5 * offset, 0.05),
            (0.7 * w, 0.5 * d - 0.5 * offset, -0.05),
        ] {
            s.blocks.push(BlockSpec {
                min: [cx - 0.5 * side, cy - 0.5 * side, 0.5 * d - 0.5 * side],
                max: [cx + 0.5 * side, cy + 0.5 * side, 0.5 * d + 0.5 * side],
                velocity: [vx, 0.0, 0.0],
            });
        }
        s.render = RenderSpec {
            camera: [0.5 * w, 0.6 * d, 0.5 * d + 0.32],
            look_at: [0.5 * w, 0.5 * d, 0.5 * d],
            fov_y: 45.0,
        };
        s
    }
}

/// A built-in scene: name, description, constructor.
pub type BuiltIn = (&'static str, &'static str, fn() -> Scene);

/// The demo's built-in scenes (`sph-app --scene NAME`, keys 1–8 in its
/// window; `sph_splat.World(NAME)` in Python), in key order: name,
/// description, constructor ([`Scene::built_in`]). The first five run PBF, the
/// real-time solver, with the parameters `Scene::pbf_params` derives (3
/// iterations, and 3 substeps per 60 Hz frame, 5 for `dam-break-fine`, so
/// that a fall through the fluid's height moves at most 0.6 h per substep);
/// the next two DFSPH, the accurate one, with physical viscosities: water
/// (1e-3 Pa·s) and honey (50 Pa·s); `drops`, water's surface tension in
/// zero gravity, PBF again (with no μ: run by another solver it takes
/// [`FluidSpec::DEFAULT_VISCOSITY`]). `--solver` runs any with another.
pub const BUILT_IN: [BuiltIn; 8] = [
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
            Scene::dam_break(0.25, 0.08, 0.02)
                .with_solver(SolverKind::Dfsph)
                .with_viscosity(1e-3)
        },
    ),
    (
        "honey",
        "a cube of honey (μ = 50 Pa·s) slumping, DFSPH",
        || Scene::honey(0.2, 0.02),
    ),
    (
        "drops",
        "two weightless cubes of water rounded and merged by surface tension",
        || Scene::weightless_drops(0.005).with_solver(SolverKind::Pbf),
    ),
];

impl Scene {
    /// The built-in scene called `name` ([`BUILT_IN`]), or `None`.
    pub fn built_in(name: &str) -> Option<Scene> {
        (BUILT_IN.iter())
            .find(|(n, _, _)| *n == name)
            .map(|(_, _, make)| make())
    }
}
