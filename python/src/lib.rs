//! `sph_splat`: sph-splat from Python (PyO3 + maturin, abi3). Worlds from a
//! built-in scene, a TOML scene file or numpy arrays; stepping with the GIL
//! released; positions, velocities, densities and pressures as numpy
//! arrays; particle files of any format sph-core reads
//! (`sph_core::io::read_particles`) in and PLY/VTK out; surfels as arrays;
//! a frame drawn headless as an image array.
//!
//! Arrays of points are `(N, 3)` `float32`; any other shape, type or a
//! non-finite value is a `ValueError` naming the argument, as every
//! parameter error of the library is (its message names the field). A file
//! that cannot be read or written is an `OSError`.

use std::path::PathBuf;

use glam::Vec3;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sph_core::io::PointCloud;
use sph_core::{Particles, Scene, Solver, SolverKind, World};
use splat_render::{Camera, Environment, GpuContext, Shading, Splat, SplatRenderer};
use surfel_extract::{ExtractParams, Extractor, Surface};

/// A library error as the Python exception a caller expects.
fn error(e: sph_core::Error) -> PyErr {
    match e {
        sph_core::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        e => PyValueError::new_err(e.to_string()),
    }
}

/// An `(N, 3)` float32 array as points, every one finite.
fn points(name: &str, array: &PyReadonlyArray2<'_, f32>) -> PyResult<Vec<Vec3>> {
    let shape = array.shape();
    if shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected an (N, 3) float32 array, got shape {shape:?}"
        )));
    }
    let view = array.as_array();
    let mut out = Vec::with_capacity(shape[0]);
    for (i, row) in view.rows().into_iter().enumerate() {
        let x = Vec3::new(row[0], row[1], row[2]);
        if !x.is_finite() {
            return Err(PyValueError::new_err(format!(
                "{name}: row {i} is {x}, not finite"
            )));
        }
        out.push(x);
    }
    Ok(out)
}

/// Points as an `(N, 3)` float32 array (one copy).
fn array3<'py>(py: Python<'py>, points: &[Vec3]) -> Bound<'py, PyArray2<f32>> {
    let flat: Vec<f32> = points.iter().flat_map(|x| x.to_array()).collect();
    Array2::from_shape_vec((points.len(), 3), flat)
        .expect("N × 3 values")
        .into_pyarray(py)
}

fn solver_kind(name: &str) -> PyResult<SolverKind> {
    SolverKind::from_name(name).ok_or_else(|| {
        PyValueError::new_err(format!("solver: `{name}` is not one of wcsph, pbf, dfsph"))
    })
}

/// An SPH simulation: particles, a solver and walls, stepped in frames.
///
/// `World(scene, solver=None)`: a built-in scene by name (`scenes()` lists
/// them) or a TOML scene file's path, run by its own solver or `solver`
/// (`"pbf"`, `"dfsph"`, `"wcsph"`).
#[pyclass(name = "World", module = "sph_splat", unsendable)]
struct PyWorld {
    world: World,
    /// Where `render` looks from.
    view: sph_core::scene::RenderSpec,
    /// The scene's frame (`time_step.frame_dt`, s): what `advance` steps
    /// by unless given another.
    frame_dt: f32,
}

#[pymethods]
impl PyWorld {
    #[new]
    #[pyo3(signature = (scene, solver = None))]
    fn new(py: Python<'_>, scene: &str, solver: Option<&str>) -> PyResult<Self> {
        let mut scene = match Scene::built_in(scene) {
            Some(s) => s,
            None => {
                let path = PathBuf::from(scene);
                if !path.exists() {
                    let names: Vec<&str> = sph_core::scene::BUILT_IN.iter().map(|b| b.0).collect();
                    return Err(PyValueError::new_err(format!(
                        "scene: `{scene}` is neither a built-in scene ({}) nor a file",
                        names.join(", ")
                    )));
                }
                Scene::load(&path).map_err(error)?
            }
        };
        if let Some(name) = solver {
            // What the new solver would refuse gives way to its own, each
            // with a `UserWarning` (`Scene::switch_solver`'s notes).
            let warning = py.get_type::<pyo3::exceptions::PyUserWarning>();
            for note in scene.switch_solver(solver_kind(name)?) {
                let note = std::ffi::CString::new(note)
                    .map_err(|e| PyValueError::new_err(e.to_string()))?;
                PyErr::warn(py, &warning, &note, 1)?;
            }
        }
        Ok(Self {
            world: scene.build_world().map_err(error)?,
            view: scene.render,
            frame_dt: scene.time_step.frame_dt,
        })
    }

    /// A world of particles at `positions` ((N, 3) float32, m) with
    /// optional `velocities`, on a lattice `spacing` apart (their mass: the
    /// fluid of rest density 1000 kg/m³ filling it, h = 2 spacings), in the
    /// box `domain_min`–`domain_max`, under gravity 9.81 m/s² down, run by
    /// `solver`.
    #[staticmethod]
    #[pyo3(signature = (positions, spacing, domain_min, domain_max, velocities = None, solver = "pbf"))]
    fn from_arrays(
        positions: PyReadonlyArray2<'_, f32>,
        spacing: f32,
        domain_min: [f32; 3],
        domain_max: [f32; 3],
        velocities: Option<PyReadonlyArray2<'_, f32>>,
        solver: &str,
    ) -> PyResult<Self> {
        let x = points("positions", &positions)?;
        let v = match velocities {
            Some(v) => points("velocities", &v)?,
            None => vec![Vec3::ZERO; x.len()],
        };
        if v.len() != x.len() {
            return Err(PyValueError::new_err(format!(
                "velocities: {} rows for {} positions",
                v.len(),
                x.len()
            )));
        }
        let (min, max) = (Vec3::from(domain_min), Vec3::from(domain_max));
        if !(min.is_finite() && max.is_finite() && min.cmplt(max).all()) {
            return Err(PyValueError::new_err(format!(
                "domain_min: {min} must be finite and below domain_max: {max} on every axis"
            )));
        }
        let scene = Scene::empty("arrays", min, max, spacing).with_solver(solver_kind(solver)?);
        let params = scene.fluid_params();
        let solver: Solver = scene.solver();
        let mass = solver.particle_mass(&params, spacing).map_err(error)?;
        let mut particles = Particles::new();
        for (x, v) in x.iter().zip(&v) {
            particles.push(*x, *v, mass);
        }
        let stepping = sph_core::TimeStepping::default();
        let world = World::with_solver(particles, params, scene.boundary(), stepping, solver)
            .map_err(error)?;
        Ok(Self {
            world,
            view: scene.render,
            frame_dt: scene.time_step.frame_dt,
        })
    }

    /// Advances by `seconds` of simulated time in equal frames of at most
    /// `frame_dt` (the GIL released); returns the last frame's report as a
    /// dict (solver, substeps, iterations, density_error_avg,
    /// density_error_max, clamped: the particles PBF's displacement guard
    /// slowed, time).
    /// `frame_dt` defaults to the scene's `time_step.frame_dt` (1/60 s for
    /// the built-in scenes and `from_arrays`).
    #[pyo3(signature = (seconds, frame_dt = None))]
    fn advance<'py>(
        &mut self,
        py: Python<'py>,
        seconds: f64,
        frame_dt: Option<f32>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let frame_dt = frame_dt.unwrap_or(self.frame_dt);
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "seconds: {seconds} must be finite and ≥ 0"
            )));
        }
        if !(frame_dt.is_finite() && frame_dt > 0.0) {
            return Err(PyValueError::new_err(format!(
                "frame_dt: {frame_dt} must be finite and > 0"
            )));
        }
        // Equal frames, as many as frames of `frame_dt` would take: a last
        // short remainder (a sliver below `min_dt` where `seconds` is not a
        // multiple of `frame_dt` in f32) would be refused by the world. A
        // hair under, as `PbfParams::substeps_for`, so that a whole number
        // of frames despite rounding takes that number. Each frame shares
        // what is left, so the last lands on the end; a duration of a
        // nanosecond or less takes none, as before.
        let frames = if seconds > 1e-9 {
            (seconds / f64::from(frame_dt) * (1.0 - 1e-6))
                .ceil()
                .max(1.0) as u64
        } else {
            0
        };
        let world = &mut self.world;
        let report = py
            .detach(|| {
                let end = world.time() + seconds;
                let mut last = None;
                for k in 0..frames {
                    let dt = ((end - world.time()) / (frames - k) as f64) as f32;
                    last = Some(world.advance(dt)?);
                }
                Ok::<_, sph_core::Error>(last)
            })
            .map_err(error)?;
        let dict = PyDict::new(py);
        dict.set_item("time", self.world.time())?;
        if let Some(r) = report {
            dict.set_item("solver", r.solver.name())?;
            dict.set_item("substeps", r.substeps)?;
            dict.set_item("iterations", r.iterations)?;
            dict.set_item("density_error_avg", r.density_error_avg)?;
            dict.set_item("density_error_max", r.density_error_max)?;
            dict.set_item("clamped", r.clamped)?;
        }
        Ok(dict)
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.world.time()
    }

    /// The solver's name.
    #[getter]
    fn solver(&self) -> &'static str {
        self.world.solver().kind().name()
    }

    fn __len__(&self) -> usize {
        self.world.particles.len()
    }

    /// Positions, (N, 3) float32 (a copy).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        array3(py, self.world.particles.positions())
    }

    #[setter]
    fn set_positions(&mut self, positions: PyReadonlyArray2<'_, f32>) -> PyResult<()> {
        let x = points("positions", &positions)?;
        if let Some(i) = x.iter().position(|&x| !self.world.boundary().admits(x)) {
            return Err(PyValueError::new_err(format!(
                "positions: row {i} ({}) lies outside the domain or inside an obstacle",
                x[i]
            )));
        }
        self.set("positions", &x, |p| p.positions_mut())
    }

    /// Velocities, (N, 3) float32 (a copy).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        array3(py, self.world.particles.velocities())
    }

    #[setter]
    fn set_velocities(&mut self, velocities: PyReadonlyArray2<'_, f32>) -> PyResult<()> {
        let v = points("velocities", &velocities)?;
        self.set("velocities", &v, |p| p.velocities_mut())
    }

    /// Densities, (N,) float32 (kg/m³, a copy).
    #[getter]
    fn densities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        Array1::from_vec(self.world.particles.densities().to_vec()).into_pyarray(py)
    }

    /// Pressures, (N,) float32 (Pa, a copy).
    #[getter]
    fn pressures<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        Array1::from_vec(self.world.particles.pressures().to_vec()).into_pyarray(py)
    }

    /// The fluid drawn headless (`width` × `height`, the scene's camera, the
    /// demo's water before the thesis's screen-space background, no tank): a
    /// dict of `image`, an
    /// (H, W, 4) uint8 array, and `covered`, the fraction of pixels the
    /// fluid's splats cover. Needs a GPU adapter (Mesa's lavapipe will do).
    #[pyo3(signature = (width = 480, height = 270, surface = "anisotropic"))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        surface: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        if !((16..=8192).contains(&width) && (16..=8192).contains(&height)) {
            return Err(PyValueError::new_err(format!(
                "width, height: {width} × {height} must each lie in 16..=8192"
            )));
        }
        let h = self.world.params().h;
        let params = extract_params(h, surface, 2)?;
        let (particles, view) = (&self.world.particles, self.view);
        let drawn = py.detach(|| -> Result<_, String> {
            let mut extractor = Extractor::new();
            let surfels = extractor
                .extract(particles, &params)
                .map_err(|e| e.to_string())?;
            let splats: Vec<Splat> = (surfels.surfels.iter())
                .map(|s| Splat::new(s.position, s.normal, s.radius))
                .collect();
            let ctx = GpuContext::headless().map_err(|e| e.to_string())?;
            let env = Environment::procedural();
            let mut renderer =
                SplatRenderer::new(&ctx, width, height, &env).map_err(|e| e.to_string())?;
            renderer.upload(&ctx, &splats).map_err(|e| e.to_string())?;
            let camera = Camera {
                fov_y: view.fov_y.to_radians(),
                ..Camera::looking_at(Vec3::from(view.camera), Vec3::from(view.look_at))
            }
            .with_planes_for_distance();
            (renderer.render(&ctx, &camera, &Shading::water(h))).map_err(|e| e.to_string())?;
            let image = renderer.read_image(&ctx).map_err(|e| e.to_string())?;
            let weights = renderer
                .read_accumulation(&ctx)
                .map_err(|e| e.to_string())?;
            let covered = (0..height)
                .flat_map(|y| (0..width).map(move |x| (x, y)))
                .filter(|&(x, y)| weights.weight(x, y) > 0.0)
                .count();
            Ok((image, covered))
        });
        let (image, covered) = drawn.map_err(PyRuntimeError::new_err)?;
        let pixels = Array3::from_shape_vec((height as usize, width as usize, 4), image.into_raw())
            .expect("H × W × 4 bytes");
        let dict = PyDict::new(py);
        dict.set_item("image", pixels.into_pyarray(py))?;
        dict.set_item("covered", covered as f64 / f64::from(width * height))?;
        Ok(dict)
    }

    /// The surfels of the particles (see `extract`).
    #[pyo3(signature = (surface = "anisotropic", iterations = 2))]
    fn extract<'py>(
        &self,
        py: Python<'py>,
        surface: &str,
        iterations: u32,
    ) -> PyResult<Bound<'py, PyDict>> {
        let params = extract_params(self.world.params().h, surface, iterations)?;
        let particles = &self.world.particles;
        let mut extractor = Extractor::new();
        let surfels = py
            .detach(|| {
                extractor
                    .extract(particles, &params)
                    .map(|s| s.surfels.clone())
            })
            .map_err(error)?;
        surfel_dict(py, &surfels)
    }
}

impl PyWorld {
    /// Replaces one field of every particle, the count unchanged.
    fn set(
        &mut self,
        name: &str,
        values: &[Vec3],
        field: impl Fn(&mut Particles) -> &mut [Vec3],
    ) -> PyResult<()> {
        let n = self.world.particles.len();
        if values.len() != n {
            return Err(PyValueError::new_err(format!(
                "{name}: {} rows for a world of {n} particles",
                values.len()
            )));
        }
        field(&mut self.world.particles).copy_from_slice(values);
        Ok(())
    }
}

fn extract_params(h: f32, surface: &str, iterations: u32) -> PyResult<ExtractParams> {
    let surface = match surface {
        "anisotropic" => Surface::anisotropic(),
        "isotropic" => Surface::Isotropic,
        other => {
            return Err(PyValueError::new_err(format!(
                "surface: `{other}` is not `anisotropic` or `isotropic`"
            )));
        }
    };
    if !(1..=3).contains(&iterations) {
        return Err(PyValueError::new_err(format!(
            "iterations: {iterations} must be 1, 2 or 3"
        )));
    }
    Ok(ExtractParams {
        surface,
        iterations,
        ..ExtractParams::new(h)
    })
}

fn surfel_dict<'py>(
    py: Python<'py>,
    surfels: &[surfel_extract::Surfel],
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    let positions: Vec<Vec3> = surfels.iter().map(|s| s.position).collect();
    let normals: Vec<Vec3> = surfels.iter().map(|s| s.normal).collect();
    let radii: Vec<f32> = surfels.iter().map(|s| s.radius).collect();
    dict.set_item("positions", array3(py, &positions))?;
    dict.set_item("normals", array3(py, &normals))?;
    dict.set_item("radii", Array1::from_vec(radii).into_pyarray(py))?;
    Ok(dict)
}

/// The surfels of particles at `positions` ((N, 3) float32) for kernel
/// support `h` (m): a dict of `positions` and `normals` ((M, 3)) and
/// `radii` ((M,)). Particle volumes come from the positions (Shepard), as
/// for other simulators' files.
#[pyfunction]
#[pyo3(signature = (positions, h, surface = "anisotropic", iterations = 2))]
fn extract<'py>(
    py: Python<'py>,
    positions: PyReadonlyArray2<'_, f32>,
    h: f32,
    surface: &str,
    iterations: u32,
) -> PyResult<Bound<'py, PyDict>> {
    let x = points("positions", &positions)?;
    let params = extract_params(h, surface, iterations)?;
    let mut extractor = Extractor::new();
    let surfels = py
        .detach(|| {
            extractor
                .extract_points(&x, &params)
                .map(|s| s.surfels.clone())
        })
        .map_err(error)?;
    surfel_dict(py, &surfels)
}

/// The particles of a file (legacy VTK, VTU, PLY, XYZ, BGEO or splashsurf's
/// JSON, by extension): `(positions, time)`, `time` being the simulated time
/// the file records (this project's exports) or None.
#[pyfunction]
fn read_particles<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, PyArray2<f32>>, Option<f64>)> {
    let file = sph_core::io::read_particles(&path).map_err(error)?;
    Ok((array3(py, &file.positions), file.time))
}

/// Writes points to `path`, its format by its extension: binary PLY or
/// legacy VTK at simulated `time` (0 when left out) with optional
/// `velocities` ((N, 3)) and `densities` ((N,)), or positions alone as XYZ,
/// VTU or BGEO (what `read_particles` reads back). Attributes or a time for
/// a positions-only format are a `ValueError`, not dropped.
#[pyfunction]
#[pyo3(signature = (path, positions, time = None, velocities = None, densities = None))]
fn write_particles(
    path: PathBuf,
    positions: PyReadonlyArray2<'_, f32>,
    time: Option<f64>,
    velocities: Option<PyReadonlyArray2<'_, f32>>,
    densities: Option<numpy::PyReadonlyArray1<'_, f32>>,
) -> PyResult<()> {
    let x = points("positions", &positions)?;
    let v = velocities.map(|v| points("velocities", &v)).transpose()?;
    let rho: Option<Vec<f32>> = densities.map(|d| d.as_array().to_vec());
    let mut cloud = PointCloud {
        positions: &x,
        ..Default::default()
    };
    if let Some(v) = &v {
        cloud.vectors.push(("velocity", v));
    }
    if let Some(rho) = &rho {
        cloud.scalars.push(("density", rho));
    }
    sph_core::io::write_particles(&path, &cloud, time).map_err(error)
}

/// The built-in scenes' names.
#[pyfunction]
fn scenes() -> Vec<&'static str> {
    sph_core::scene::BUILT_IN.iter().map(|b| b.0).collect()
}

#[pymodule]
fn sph_splat(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyWorld>()?;
    m.add_function(wrap_pyfunction!(extract, m)?)?;
    m.add_function(wrap_pyfunction!(read_particles, m)?)?;
    m.add_function(wrap_pyfunction!(write_particles, m)?)?;
    m.add_function(wrap_pyfunction!(scenes, m)?)?;
    Ok(())
}
