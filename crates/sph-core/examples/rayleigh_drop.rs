//! A free drop in zero gravity, pulled round by surface tension, against
//! Rayleigh (1879): a drop of radius R disturbed in its mode l oscillates at
//! ω² = l(l − 1)(l + 2) σ / (ρ R³), damped at Lamb's rate (l − 1)(2l + 1) ν / R².
//!
//! The drop (water's σ, μ = 0.01 Pa·s, at rest) starts as one of:
//! - `box` (the default): a box elongated 2:1:1 along x of the volume of a
//!   sphere of 16³ particles, mostly l = 2 at large amplitude (1.61 × 2R
//!   along x);
//! - `ellipsoid`: the lattice points of a sphere of that volume, stretched
//!   by 1 + `--eps` (default 0.1) along x and shrunk by its square root
//!   across: l = 2 at small amplitude, where Rayleigh's linear theory holds;
//! - `cube`: a cube of 16³ particles, mostly l = 4 at large amplitude
//!   (a sphere's lattice points perturbed by l = 4's cubic harmonic were
//!   tried for small amplitudes, but the cubic lattice carries an l = 4
//!   signal of its own that swamps them);
//! - `l4`: l = 4 at small amplitude: the lattice points of that sphere
//!   moved by Rayleigh's own l = 4 flow, the gradient of the harmonic
//!   r⁴ P₄(cos θ) (divergence-free, so the density stays uniform), so that
//!   the surface moves out by `--eps` × R × P₄(cos θ). The axis lies in the
//!   xy-plane at ½ asin √0.8 = 31.7° from x, where the cubic harmonic
//!   x⁴ + y⁴ + z⁴ − 3/5 vanishes: the cubic lattice's own l = 4 signal
//!   does not project on the axisymmetric P₄ about it.
//!
//! Printed for the solver given (WCSPH by default): the extent along x
//! against time (2√5 times the rms offset along x: 2R for a sphere; for
//! the cube, the l = 4 signal instead: the fourth-moment extent
//! ⟨(x·n)⁴⟩^¼ along the faces' normals over that along the body diagonals,
//! 1 for a sphere, 0.912 for a cube; for `l4`, the amplitude
//! 3⟨r⁴ P₄(cos θ)⟩/R⁴ about its axis, 0 for a sphere and `--eps` at the
//! start), the
//! particles escaped beyond 3R, the period from the extent's extrema against
//! Rayleigh's and that of the damped sinusoid fitting every sample (with
//! the undamped period, 2π/√(ω² + β²); the solver tests read periods so),
//! the swing's decay rate from turn to turn against Lamb's, and
//! the mean pressure of the particles within R/2 of the
//! centre over every step of the last second (weighted by the step: DFSPH's
//! pressure pulses with its unequal steps) against Laplace's 2σ/R: the stored
//! pressure, that plus the surface tension forces' virial, and under PBF
//! and DFSPH the virial of both the pressure forces and those forces (the
//! consistent reading on a lattice; see the surface tension module).
//!
//! ```text
//! cargo run --release -p sph-core --example rayleigh_drop [-- SOLVER [SECONDS] \
//!     [--shape box|ellipsoid|cube|l4] [--eps E] [--profile] [--spacing S] [--across N] [--sigma N_PER_M] \
//!     [--model colour-field|akinci] [--mu PA_S] [--kick M_PER_S] [--akinci GAMMA] \
//!     [--solver-toml 'viscosity = "implicit"']]
//! ```
//!
//! `--profile` (PBF and DFSPH) adds the same steps' radial profile in
//! shells R/8 thick: the pressure forces' and Akinci's pair virials, their
//! sum, the stored pressure and the density, and the check that both
//! virials over the whole drop add to zero.
//!
//! `--model colour-field|akinci` picks the force that applies σ (each
//! solver's own by default; WCSPH takes either).
//!
//! `--solver-toml` is the solver's own table (`[solver.pbf]` or
//! `[solver.dfsph]`); `--spacing` sets the resolution (5 mm by default, h =
//! 2 spacings) and `--across N` the drop's volume, N³ particles (16 by
//! default: the shapes above are for 16); `--mu` the viscosity (0.01 Pa·s by default). WCSPH applies
//! σ by the thesis's colour-field force, PBF and DFSPH by Akinci et al.'s
//! forces (`sph_core::solver::surface_tension`).
//!
//! `--kick K` adds to every particle's velocity, after each step, a random
//! vector uniform in a cube of side K √(Δt / 5 ms) (m/s; a hash of the
//! particle and the step, the same for any thread count): particle-scale
//! noise put in by hand, for `docs/benchmark-notes.md`, "The slow swing at
//! water's viscosity is the noise's".
//!
//! `--akinci GAMMA` adds a prototype of Akinci et al. 2013's cohesion and
//! curvature forces with coefficient γ (the cohesion term weighted by
//! `surface_tension::COHESION_WEIGHT`) in place of the solver's own σ
//! (after PBF's `viscosity` station, or DFSPH's `forces`), and prints the inner
//! pressure with those forces' virial added (the mechanical pressure), for
//! the measurements of
//! `docs/benchmark-notes.md`, "Surface tension for PBF and DFSPH": not a
//! solver feature, and γ is not σ.

use std::sync::{Arc, Mutex};

// The solver tests' helpers: the l = 4 mode's flow and amplitude, and the
// damped-sinusoid fit they read periods with.
#[path = "../tests/common/mod.rs"]
mod common;

use sph_core::glam::Vec3;
use sph_core::processor::{Context, Processor};
use sph_core::solver::surface_tension::{SurfaceTension, Update};
use sph_core::{
    Aabb, Boundary, FluidParams, Particles, Solver, SolverKind, SurfaceTensionModel, TimeStepping,
    World,
};

/// PBF's surface tension station (Akinci et al. 2013's forces), its
/// virial pressure per particle copied out after each step for the
/// measurement.
struct Measured {
    inner: SurfaceTension,
    virial: Arc<Mutex<Vec<f32>>>,
}

impl Processor for Measured {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> sph_core::Result<()> {
        self.inner.process(particles, ctx)?;
        let mut virial = self.virial.lock().unwrap_or_else(|e| e.into_inner());
        virial.clear();
        virial.extend(self.inner.virial());
        Ok(())
    }
}

/// `--kick`'s noise: after each step, every velocity gains a random vector
/// uniform in a cube of side `speed` √(Δt / 5 ms), from a hash of the
/// particle's index and the step's count.
struct Kick {
    speed: f32,
    step: u64,
}

impl Kick {
    /// A number in [−½, ½) from particle `i`, axis `axis` and the step.
    fn unit(&self, i: u64, axis: u64) -> f32 {
        // SplitMix64's finaliser over the three inputs.
        let mut z = i.wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ self.step.wrapping_mul(0xBF58_476D_1CE4_E5B9)
            ^ axis.wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        z = z.wrapping_mul(0xD6E8_FEB8_6659_FD93);
        z ^= z >> 29;
        (z >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    }
}

impl Processor for Kick {
    fn name(&self) -> &str {
        "kick"
    }
    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> sph_core::Result<()> {
        let side = self.speed * (ctx.dt / 0.005).sqrt();
        for (i, v) in particles.fields_mut().velocities.iter_mut().enumerate() {
            let i = i as u64;
            *v += side * Vec3::new(self.unit(i, 1), self.unit(i, 2), self.unit(i, 3));
        }
        self.step += 1;
        Ok(())
    }
}

/// The mean pressures of the particles within `within` of the drop's
/// centre (Pa): the stored pressure, that plus the Akinci forces' virial
/// (`virial`, empty under WCSPH's colour field), both forces' pair virial
/// (PBF and DFSPH; NaN under WCSPH) and the particles' kinetic part.
fn inner_readings(
    p: &Particles,
    kind: SolverKind,
    params: &FluidParams,
    virial: &[f32],
    within: f64,
) -> [f64; 4] {
    let c = p.positions().iter().sum::<Vec3>() / p.len() as f32;
    let inner: Vec<(f64, f64)> = (p.positions().iter().zip(p.pressures()))
        .enumerate()
        .filter(|(_, (x, _))| f64::from((**x - c).length()) < within)
        .map(|(i, (_, &p))| (f64::from(p), virial.get(i).map_or(0.0, |&w| f64::from(w))))
        .collect();
    let count = inner.len().max(1) as f64;
    let pressure = inner.iter().map(|q| q.0).sum::<f64>() / count;
    let mechanical = inner.iter().map(|q| q.0 + q.1).sum::<f64>() / count;
    // Under DFSPH and PBF, the pressure forces' own virial in place of the
    // stored pressure (`common::inner_pair_virial`).
    let pair_virial = if kind == SolverKind::Wcsph {
        f64::NAN
    } else {
        common::inner_pair_virial(p, kind, params, virial, c, within)
    };
    let kinetic = common::inner_kinetic_pressure(p, c, within);
    [pressure, mechanical, pair_virial, kinetic]
}

/// Shells R/8 thick from the centre, to 1.25 R, in [`shell_sums`].
const SHELLS: usize = 10;

/// Per shell, in five figures each (`SHELLS` × 5): the particles and the
/// sums over them of the pressure forces' pair virial, the Akinci forces'
/// virial, the stored pressure and the density; then, over all particles,
/// Σ V_i times each of the two virials and Σ V_i (V_i = m_i/ρ_i). A drop at
/// rest has Σ V (both virials) = 0 (the virial theorem), so how the pressure
/// virial is spread between the surface shell and the interior sets the
/// inner pressure (PBF and DFSPH).
fn shell_sums(
    p: &Particles,
    kind: SolverKind,
    params: &FluidParams,
    virial: &[f32],
    radius: f64,
) -> [f64; SHELLS * 5 + 3] {
    let x = p.positions();
    let c = x.iter().sum::<Vec3>() / p.len() as f32;
    let all: Vec<usize> = (0..p.len()).collect();
    let pressure = common::pair_virial_pressures(p, kind, params, &[], &all);
    let mut out = [0.0f64; SHELLS * 5 + 3];
    for (i, &pv) in pressure.iter().enumerate() {
        let akinci = virial.get(i).map_or(0.0, |&w| f64::from(w));
        let rho = f64::from(p.densities()[i]);
        let volume = f64::from(p.masses()[i]) / rho;
        let shell = (f64::from((x[i] - c).length()) / radius * 8.0) as usize;
        if shell < SHELLS {
            let row = &mut out[shell * 5..][..5];
            row[0] += 1.0;
            row[1] += pv;
            row[2] += akinci;
            row[3] += f64::from(p.pressures()[i]);
            row[4] += rho;
        }
        out[SHELLS * 5] += volume * pv;
        out[SHELLS * 5 + 1] += volume * akinci;
        out[SHELLS * 5 + 2] += volume;
    }
    out
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut kind = SolverKind::Wcsph;
    let (mut seconds, mut shape, mut eps) = (4.0f64, "box".to_string(), 0.1f32);
    let (mut spacing, mut sigma, mut table) = (0.005f32, 0.0728f32, String::new());
    let (mut across, mut profile) = (16u32, false);
    let (mut mu, mut akinci, mut model) = (0.01f32, None, None);
    let mut kick = 0.0f32;
    let mut args = std::env::args().skip(1);
    let mut positional = 0;
    while let Some(arg) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--shape" => {
                shape = value("--shape")?;
                if !["box", "ellipsoid", "cube", "l4"].contains(&shape.as_str()) {
                    return Err(format!("unknown shape `{shape}`: box, ellipsoid, cube, l4").into());
                }
            }
            "--eps" => eps = value("--eps")?.parse()?,
            "--profile" => profile = true,
            "--spacing" => spacing = value("--spacing")?.parse()?,
            "--across" => across = value("--across")?.parse()?,
            "--sigma" => sigma = value("--sigma")?.parse()?,
            "--solver-toml" => table = value("--solver-toml")?,
            "--mu" => mu = value("--mu")?.parse()?,
            "--kick" => kick = value("--kick")?.parse()?,
            "--akinci" => akinci = Some(value("--akinci")?.parse::<f32>()?),
            "--model" => {
                model = Some(match value("--model")?.as_str() {
                    "colour-field" => SurfaceTensionModel::ColourField,
                    "akinci" => SurfaceTensionModel::Akinci,
                    other => {
                        return Err(format!("unknown model `{other}`: colour-field, akinci").into());
                    }
                })
            }
            _ if positional == 0 => {
                kind = SolverKind::from_name(&arg).ok_or(format!("unknown solver `{arg}`"))?;
                positional += 1;
            }
            _ => seconds = arg.parse()?,
        }
    }
    if !(sigma.is_finite() && sigma > 0.0) {
        return Err(format!(
            "--sigma {sigma}: must be positive (N/m); the drop is read against Rayleigh's period \
             and Laplace's pressure, which both need σ"
        )
        .into());
    }
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(format!("seconds {seconds}: must be finite and > 0").into());
    }
    if !(kick.is_finite() && kick >= 0.0) {
        return Err(format!("--kick {kick}: must be a speed ≥ 0 (m/s)").into());
    }
    let params = FluidParams {
        gravity: Vec3::ZERO,
        // `--akinci` replaces PBF's and DFSPH's own σ.
        surface_tension: match (kind, akinci) {
            (SolverKind::Wcsph, _) | (_, None) => sigma,
            _ => 0.0,
        },
        surface_tension_model: model,
        viscosity: mu,
        ..FluidParams::water(2.0 * spacing)
    };
    let solver = match kind {
        SolverKind::Wcsph => Solver::Wcsph,
        SolverKind::Pbf => Solver::Pbf(toml::from_str(&table)?),
        SolverKind::Dfsph => Solver::Dfsph(toml::from_str(&table)?),
    };
    let mass = solver.particle_mass(&params, spacing)?;
    // The volume of `across`³ particles: 4/3 π R³.
    let volume = (across as f32 * spacing).powi(3);
    let mut particles = Particles::new();
    let cube = shape == "cube";
    let l4 = shape == "l4";
    if shape == "ellipsoid" || l4 {
        let r = (3.0 * volume / (4.0 * std::f32::consts::PI)).cbrt();
        let n = (r / spacing).ceil() as i32 + 1;
        let stretch = Vec3::new(1.0 + eps, (1.0 + eps).powf(-0.5), (1.0 + eps).powf(-0.5));
        for k in -n..n {
            for j in -n..n {
                for i in -n..n {
                    let x = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * spacing;
                    if x.length() <= r {
                        let moved = if l4 {
                            x + eps * r * common::l4_flow(x / r)
                        } else {
                            x * stretch
                        };
                        particles.push(moved, Vec3::ZERO, mass);
                    }
                }
            }
        }
    } else {
        let b = (volume / 2.0).cbrt();
        let (nx, ny) = if cube {
            (across as i32, across as i32)
        } else {
            (
                (2.0 * b / spacing).round() as i32,
                (b / spacing).round() as i32,
            )
        };
        for k in 0..ny {
            for j in 0..ny {
                for i in 0..nx {
                    let x = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * spacing
                        - 0.5 * Vec3::new(nx as f32, ny as f32, ny as f32) * spacing;
                    particles.push(x, Vec3::ZERO, mass);
                }
            }
        }
    }
    let count = particles.len();
    let radius =
        (3.0 * count as f64 * f64::from(spacing).powi(3) / (4.0 * std::f64::consts::PI)).cbrt();
    let rho = f64::from(params.rest_density);
    let (l, nu) = (if cube || l4 { 4.0f64 } else { 2.0 }, f64::from(mu) / rho);
    let omega = (l * (l - 1.0) * (l + 2.0) * f64::from(sigma) / (rho * radius.powi(3))).sqrt();
    let rayleigh = 2.0 * std::f64::consts::PI / omega;
    let lamb = (l - 1.0) * (2.0 * l + 1.0) * nu / (radius * radius);
    let laplace = 2.0 * f64::from(sigma) / radius;
    let boundary = Boundary::new(Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)));
    let mut world =
        World::with_solver(particles, params, boundary, TimeStepping::default(), solver)?;
    if kick > 0.0 {
        world.program_mut().push(Kick {
            speed: kick,
            step: 0,
        });
    }
    if akinci.is_some() && kind == SolverKind::Wcsph {
        return Err(
            "--akinci needs PBF or DFSPH (their neighbour lists); WCSPH applies σ itself".into(),
        );
    }
    // The forces' virial, for the mechanical pressure: PBF's own station,
    // or Akinci's forces with `--akinci`'s γ, in a wrapper that copies it.
    let virial = Arc::new(Mutex::new(Vec::<f32>::new()));
    let (update, after) = match kind {
        SolverKind::Pbf => (Update::Velocities, "viscosity"),
        SolverKind::Dfsph => (Update::Accelerations, "forces"),
        SolverKind::Wcsph => (Update::Accelerations, "neighbours"),
    };
    let colour_field = kind == SolverKind::Wcsph && model != Some(SurfaceTensionModel::Akinci);
    let station = match (kind, akinci) {
        (_, Some(gamma)) => Some(SurfaceTension::with_gamma(&params, gamma, update)?),
        (_, None) if sigma > 0.0 && !colour_field => Some(SurfaceTension::new(&params, update)?),
        _ => None,
    };
    if let Some(inner) = station {
        let measured = Measured {
            inner,
            virial: virial.clone(),
        };
        let program = world.program_mut();
        program.remove("surface tension");
        if !program.insert_after(after, measured) {
            return Err(format!("no `{after}` station to put Akinci's forces after").into());
        }
    }
    println!(
        "{kind}: {count} particles at {spacing} m, R = {radius:.4} m, σ = {sigma} N/m ({}), μ = {mu} Pa·s; \
         Rayleigh's l = {l} period {rayleigh:.3} s, Lamb's damping {lamb:.3} 1/s, Laplace's 2σ/R {laplace:.2} Pa",
        match (kind, akinci) {
            (SolverKind::Wcsph, _) if colour_field =>
                "applied by WCSPH: the thesis's colour field".to_string(),
            (_, Some(gamma)) => format!("not applied; Akinci's forces with γ = {gamma}"),
            (_, None) => format!("applied by {kind}: Akinci's forces"),
        }
    );
    // The extent along x: twice the rms distance from the centre along x
    // over √(1/5), the ratio of a sphere's, so a sphere reads 2R; the
    // particles more than 3R from the centre (escaped spray); the mean
    // pressure within R/2 of the centre.
    let measure = |p: &Particles| {
        let c = p.positions().iter().sum::<Vec3>() / p.len() as f32;
        let var = (p.positions().iter())
            .map(|x| f64::from((x.x - c.x).powi(2)))
            .sum::<f64>()
            / p.len() as f64;
        let far = (p.positions().iter())
            .filter(|x| f64::from((**x - c).length()) > 3.0 * radius)
            .count();
        let signal = if l4 {
            common::l4_amplitude(p.positions(), c, radius)
        } else if cube {
            // The l = 4 signal: fourth-moment extents along the faces'
            // normals over those along the body diagonals.
            let extent = |n: Vec3| {
                let m4 = (p.positions().iter())
                    .map(|x| f64::from((*x - c).dot(n)).powi(4))
                    .sum::<f64>()
                    / p.len() as f64;
                m4.powf(0.25)
            };
            let faces = [Vec3::X, Vec3::Y, Vec3::Z].map(extent).iter().sum::<f64>();
            let diagonals = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)]
                .map(|(a, b)| extent(Vec3::new(1.0, a, b).normalize()))
                .iter()
                .sum::<f64>();
            (faces / 3.0) / (diagonals / 4.0)
        } else {
            2.0 * (5.0 * var).sqrt() / (2.0 * radius)
        };
        (signal, far)
    };
    // The inner pressures over every step of the last second, weighted by
    // the step (`common::StepAverage`: DFSPH's pressure pulses with its
    // unequal steps, 0.909 of 2σ/R after each frame against 0.805 over
    // every step on the 16-across drop over 8 s).
    let sums = Arc::new(Mutex::new(([0.0f64; 4], 0.0f64)));
    let shared = virial.clone();
    world.program_mut().push(common::StepAverage {
        read: move |p: &Particles| {
            let virial = shared.lock().unwrap_or_else(|e| e.into_inner());
            inner_readings(p, kind, &params, &virial, 0.5 * radius)
        },
        from: seconds - 1.0 + 1e-9,
        sums: sums.clone(),
    });
    // With `--profile`, the same steps' profile in shells.
    let shells = Arc::new(Mutex::new(([0.0f64; SHELLS * 5 + 3], 0.0f64)));
    if profile && kind != SolverKind::Wcsph {
        let shared = virial.clone();
        world.program_mut().push(common::StepAverage {
            read: move |p: &Particles| {
                let virial = shared.lock().unwrap_or_else(|e| e.into_inner());
                shell_sums(p, kind, &params, &virial, radius)
            },
            from: seconds - 1.0 + 1e-9,
            sums: shells.clone(),
        });
    }
    let frame = 1.0 / 60.0;
    let start = measure(&world.particles);
    let mut series = vec![(0.0f64, start.0)];
    let mut escaped = vec![0];
    while world.time() < seconds - 1e-9 {
        world.advance(frame)?;
        let (e, far) = measure(&world.particles);
        series.push((world.time(), e));
        escaped.push(far);
    }
    // Extrema of the extent (local maxima and minima), each a half period
    // apart: a turn counts when it is at least 1 % (of 2R) from the last one
    // (so a plateau's or a resting drop's wiggles do not).
    let mut extrema: Vec<(f64, f64)> = Vec::new();
    let mut last = start.0;
    for w in series.windows(3) {
        let (a, b, c) = (w[0].1, w[1].1, w[2].1);
        let turn = (b > a && b >= c) || (b < a && b <= c);
        if turn && (b - last).abs() > 0.01 {
            extrema.push(w[1]);
            last = b;
        }
    }
    for ((t, e), far) in series.iter().zip(&escaped).step_by(6) {
        println!(
            "  t = {t:5.2} s  {} {e:.3}, {far} particles beyond 3R",
            if l4 {
                "l = 4 amplitude"
            } else if cube {
                "faces' over diagonals' extent"
            } else {
                "extent along x over 2R"
            },
        );
    }
    println!("extrema (t, extent): {extrema:.3?}");
    if extrema.len() >= 3 {
        let half: Vec<f64> = extrema.windows(2).map(|w| w[1].0 - w[0].0).collect();
        let period = 2.0 * half.iter().sum::<f64>() / half.len() as f64;
        println!(
            "period {period:.3} s from {} half periods; Rayleigh {rayleigh:.3} s; ratio {:.3}",
            half.len(),
            period / rayleigh,
        );
    } else {
        println!("fewer than three extrema in {seconds} s: no period to measure");
    }
    // The damped sinusoid that fits every sample (as the tests read the
    // period): the swing's period, and the restoring force's alone,
    // 2π/√(ω² + β²).
    let omega_r = 2.0 * std::f64::consts::PI / rayleigh;
    match common::damped_fit(&series, omega_r) {
        Some((w, beta)) => println!(
            "fit: period {:.3} s, ratio {:.3}; undamped ratio {:.3}; β {beta:.2} 1/s",
            2.0 * std::f64::consts::PI / w,
            omega_r / w,
            omega_r / w.hypot(beta),
        ),
        None => println!("fit: no damped oscillation between ½ and 2 × Rayleigh's frequency"),
    }
    // The damping: the swings about the last second's mean, from the start
    // (itself a turn) through the extrema, each over the one before, as a
    // rate e^(−βt) against Lamb's.
    let last: Vec<f64> = (series.iter())
        .filter(|(t, _)| *t > seconds - 1.0)
        .map(|(_, e)| *e)
        .collect();
    let rest = last.iter().sum::<f64>() / last.len().max(1) as f64;
    let turns: Vec<(f64, f64)> = std::iter::once((0.0, start.0))
        .chain(extrema.iter().copied())
        .collect();
    let rates: Vec<f64> = (turns.windows(2))
        .map(|w| ((w[0].1 - rest).abs() / (w[1].1 - rest).abs()).ln() / (w[1].0 - w[0].0))
        .collect();
    // Over all the turns after the first half swing (the start's swing
    // includes the drop's settling from the lattice).
    let overall = match turns.get(1..).filter(|t| t.len() >= 2) {
        Some(t) => {
            let (a, b) = (t[0], t[t.len() - 1]);
            ((a.1 - rest).abs() / (b.1 - rest).abs()).ln() / (b.0 - a.0)
        }
        None => f64::NAN,
    };
    println!(
        "swing decay rates β (1/s) from turn to turn: {rates:.2?} about {rest:.3}; \
         from the first extremum to the last {overall:.2}; Lamb {lamb:.3} 1/s"
    );
    let means = common::step_means(&sums);
    let mean = |k: usize| means[k];
    let pressure = mean(0);
    println!(
        "pressure within R/2 over the last second {pressure:.3} Pa; Laplace {laplace:.3} Pa; ratio {:.3}",
        pressure / laplace
    );
    if !virial.lock().unwrap_or_else(|e| e.into_inner()).is_empty() {
        let mechanical = mean(1);
        println!(
            "with the Akinci forces' virial {mechanical:.3} Pa; ratio to Laplace {:.3}",
            mechanical / laplace
        );
        if kind != SolverKind::Wcsph {
            let pairs = mean(2);
            println!(
                "the pressure forces' and Akinci forces' virial {pairs:.3} Pa; ratio to Laplace {:.3}",
                pairs / laplace
            );
            let kinetic = mean(3);
            println!(
                "the particles' motion about the drop's ρ|v − v̄|²/3 {kinetic:.3} Pa \
                 (a pressure only at rest, --eps 0; else the swing's motion); \
                 with the pair virial {:.3} Pa, ratio to Laplace {:.3}",
                pairs + kinetic,
                (pairs + kinetic) / laplace
            );
        }
    }
    if profile && kind != SolverKind::Wcsph {
        // Over every step of the last second: the pair virials per shell
        // (their sum is the mechanical pressure), the stored pressure and
        // the density.
        let m = common::step_means(&shells);
        println!(
            "shell (r/R)   particles   pressure forces' virial   Akinci's virial   both (Pa)   stored (Pa)   ρ (kg/m³)"
        );
        for (shell, row) in m.chunks_exact(5).take(SHELLS).enumerate() {
            let (lo, hi) = (shell as f64 / 8.0, (shell + 1) as f64 / 8.0);
            let n = row[0].max(f64::MIN_POSITIVE);
            println!(
                "{lo:.3}–{hi:.3}   {:9.1}   {:23.3}   {:15.3}   {:9.3}   {:11.3}   {:9.2}",
                row[0],
                row[1] / n,
                row[2] / n,
                (row[1] + row[2]) / n,
                row[3] / n,
                row[4] / n,
            );
        }
        let (pressure, akinci, volume) = (m[SHELLS * 5], m[SHELLS * 5 + 1], m[SHELLS * 5 + 2]);
        println!(
            "over the drop's {volume:.4e} m³: Σ V × the pressure forces' virial {pressure:.4e} Pa·m³, \
             × Akinci's {akinci:.4e}; sum {:.4e} (0 at rest), {:.3} % of either",
            pressure + akinci,
            100.0 * (pressure + akinci) / pressure.abs().max(f64::MIN_POSITIVE),
        );
    }
    Ok(())
}
