//! Water at rest, per solver: issue 41's pool (0.6 × 0.2 × 0.6 m at 2 cm,
//! h = 4 cm, 9,000 particles, still from the start) after 2 s of 60 Hz
//! frames, and the same pool 25 layers (0.5 m) deep. Printed: the rms speed
//! of every particle (and of those within 2h of the top and of the floor),
//! and, away from the side walls (more than 2h), the first layer's mean
//! height above the floor against half a spacing and the free surface (the
//! mean over columns h square of their highest particle plus half a
//! spacing) against the filled height.
//!
//! ```text
//! cargo run --release -p sph-core --example pool_at_rest [-- SOLVER... \
//!     [--depth D] [--seconds T] [--clearance C] [--gravity G] [--every T] [--bands] [--walls] \
//!     [--solver-toml 'pbf = { xsph = 0.1 }']]
//! ```
//!
//! - `--clearance C`: the scene's `clearance` (m; half the spacing when
//!   left out).
//! - `--gravity G`: gravity's magnitude (m/s², 9.81 by default).
//! - `--every T`: every T seconds (rounded to whole 60 Hz frames, at least
//!   one), the rms speed split into the mean
//!   velocity of cells 2h wide and the motion about it (particle-scale
//!   jitter).
//! - `--walls`: at the end, the rms vertical speed by distance from the
//!   nearest side wall, in whole spacings (the last row all beyond).
//! - `--bands`: at the end, per 2 cm band above the floor, the particles,
//!   their rms horizontal and vertical speeds, their mean vertical velocity
//!   and mean density.
//! - `--solver-toml`: the body of a scene's `[solver]` table (without
//!   `kind`), to try parameters.

use std::collections::HashMap;

use sph_core::glam::{DVec3, Vec3};
use sph_core::scene::SolverSpec;
use sph_core::{Particles, Scene, SolverKind};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (side, s) = (0.6f32, 0.02f32);
    let mut kinds = Vec::new();
    let (mut depths, mut seconds, mut clearance) = (vec![0.2f32, 0.5], 2.0f32, None);
    let (mut every, mut bands, mut extra) = (0.0f32, false, String::new());
    let mut walls = false;
    let mut gravity = 9.81f32;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--depth" => depths = vec![value("--depth")?.parse()?],
            "--seconds" => seconds = value("--seconds")?.parse()?,
            "--clearance" => clearance = Some(value("--clearance")?.parse()?),
            "--every" => every = value("--every")?.parse()?,
            "--bands" => bands = true,
            "--walls" => walls = true,
            "--gravity" => gravity = value("--gravity")?.parse()?,
            "--solver-toml" => extra = value("--solver-toml")?,
            kind => kinds.push(SolverKind::from_name(kind).ok_or("solvers: wcsph, pbf, dfsph")?),
        }
    }
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(format!("--seconds {seconds}: must be finite and > 0").into());
    }
    if !(every.is_finite() && every >= 0.0) {
        return Err(format!("--every {every}: must be finite and ≥ 0 (0: no reports)").into());
    }
    if !(gravity.is_finite() && gravity >= 0.0) {
        return Err(format!("--gravity {gravity}: must be finite and ≥ 0 (m/s²)").into());
    }
    if kinds.is_empty() {
        kinds = vec![SolverKind::Dfsph, SolverKind::Pbf, SolverKind::Wcsph];
    }
    println!(
        "depth  solver  rms speed (mm/s): all  top 2h  bottom 2h  first layer (mm, ½ spacing = {:.0})  free surface (m)",
        500.0 * s
    );
    for &depth in &depths {
        for &kind in &kinds {
            let mut scene = Scene::dam_break(0.15, side, s);
            let spec: SolverSpec = toml::from_str(&extra)?;
            scene.solver = SolverSpec { kind, ..spec };
            scene.clearance = clearance;
            scene.fluid.gravity = [0.0, -gravity, 0.0];
            scene.domain.min = [0.0; 3];
            scene.domain.max = [side, depth + 0.2, side];
            scene.blocks[0].min = [0.0; 3];
            scene.blocks[0].max = [side, depth, side];
            let h = scene.fluid.h;
            let mut world = scene.build_world()?;
            let frames = (seconds * 60.0).round().max(1.0) as usize;
            let report_every = (every * 60.0).round().max(1.0) as usize;
            for frame in 1..=frames {
                world.advance(1.0 / 60.0)?;
                if every > 0.0 && frame % report_every == 0 {
                    let (all, coarse, fine) = split_rms(&world.particles, 2.0 * h);
                    println!(
                        "  t = {:5.2} s  rms {all:7.2} mm/s: cells 2h wide {coarse:7.2}, about them {fine:7.2}",
                        frame as f32 / 60.0
                    );
                }
            }
            let p = &world.particles;
            let rms = |band: &dyn Fn(f32) -> bool| {
                let (sum, n) = (p.positions().iter().zip(p.velocities()))
                    .filter(|(x, _)| band(x.y))
                    .fold((0.0f64, 0usize), |(s, n), (_, v)| {
                        (s + f64::from(v.length_squared()), n + 1)
                    });
                1e3 * (sum / n.max(1) as f64).sqrt()
            };
            let inside = |c: f32| c > 2.0 * h && c < side - 2.0 * h;
            let (mut first, mut count) = (0.0f64, 0usize);
            let mut tops: HashMap<(i32, i32), f32> = HashMap::new();
            for x in p.positions().iter().filter(|x| inside(x.x) && inside(x.z)) {
                if x.y < s {
                    first += f64::from(x.y);
                    count += 1;
                }
                let cell = ((x.x / h) as i32, (x.z / h) as i32);
                let top = tops.entry(cell).or_insert(f32::MIN);
                *top = top.max(x.y);
            }
            let surface =
                tops.values().map(|&y| f64::from(y + 0.5 * s)).sum::<f64>() / tops.len() as f64;
            println!(
                "{depth:5.2}  {kind:6}  {:22.1}  {:6.1}  {:9.1}  {:>33.2}  {surface:.4} ({:+.2} %)",
                rms(&|_| true),
                rms(&|y| y > depth - 2.0 * h),
                rms(&|y| y < 2.0 * h),
                1e3 * first / count.max(1) as f64,
                100.0 * (surface / f64::from(depth) - 1.0)
            );
            if walls {
                print_walls(p, side, s);
            }
            if bands {
                print_bands(p, s);
            }
        }
    }
    Ok(())
}

/// The rms speed (mm/s) of all particles, of the mean velocities of cubic
/// cells `cell` wide (each particle counted with its cell's), and of the
/// particles' velocities about their cell's mean.
fn split_rms(p: &Particles, cell: f32) -> (f64, f64, f64) {
    let key = |x: Vec3| (x / cell).floor().as_ivec3().to_array();
    let mut cells: HashMap<[i32; 3], (DVec3, f64)> = HashMap::new();
    for (x, v) in p.positions().iter().zip(p.velocities()) {
        let c = cells.entry(key(*x)).or_default();
        (c.0, c.1) = (c.0 + v.as_dvec3(), c.1 + 1.0);
    }
    let (mut all, mut coarse, mut fine) = (0.0, 0.0, 0.0);
    for (x, v) in p.positions().iter().zip(p.velocities()) {
        let (sum, n) = cells[&key(*x)];
        let mean = sum / n;
        all += v.as_dvec3().length_squared();
        coarse += mean.length_squared();
        fine += (v.as_dvec3() - mean).length_squared();
    }
    let n = p.len().max(1) as f64;
    let mm = |sum: f64| 1e3 * (sum / n).sqrt();
    (mm(all), mm(coarse), mm(fine))
}

/// The rms vertical speed of the particles by their distance from the
/// nearest side wall of a pool `side` square, in whole spacings `s` (the
/// last row: 7 spacings and beyond).
fn print_walls(p: &Particles, side: f32, s: f32) {
    let mut rows = [(0.0f64, 0usize); 8];
    for (x, v) in p.positions().iter().zip(p.velocities()) {
        let d = x.x.min(side - x.x).min(x.z).min(side - x.z);
        let row = &mut rows[((d / s).max(0.0) as usize).min(7)];
        row.0 += f64::from(v.y * v.y);
        row.1 += 1;
    }
    println!("  from the side walls (spacings)  particles  rms vertical (mm/s)");
    for (k, &(sum, n)) in rows.iter().enumerate() {
        let rms = 1e3 * (sum / n.max(1) as f64).sqrt();
        println!(
            "  {k:>29}{}  {n:9}  {rms:19.2}",
            if k == 7 { "+" } else { " " }
        );
    }
}

/// Per band `s` thick above the floor: particles, rms horizontal and
/// vertical speed, mean vertical velocity, mean density.
fn print_bands(p: &Particles, s: f32) {
    let mut bands: Vec<(f64, f64, usize, f64, f64)> = Vec::new();
    for ((x, v), &rho) in (p.positions().iter().zip(p.velocities())).zip(p.densities()) {
        let k = (x.y / s).max(0.0) as usize;
        if bands.len() <= k {
            bands.resize(k + 1, (0.0, 0.0, 0, 0.0, 0.0));
        }
        let b = &mut bands[k];
        b.0 += f64::from(v.x * v.x + v.z * v.z);
        b.1 += f64::from(v.y * v.y);
        b.2 += 1;
        b.3 += f64::from(rho);
        b.4 += f64::from(v.y);
    }
    println!(
        "  band (cm)  particles  rms horizontal  vertical  mean vertical (mm/s)  density (kg/m³)"
    );
    for (k, &(horizontal, vertical, n, rho, mean)) in bands.iter().enumerate() {
        let count = n.max(1) as f64;
        println!(
            "  {:3.0}–{:<3.0}  {n:9}  {:14.2}  {:8.2}  {:20.2}  {:15.2}",
            100.0 * s * k as f32,
            100.0 * s * (k + 1) as f32,
            1e3 * (horizontal / count).sqrt(),
            1e3 * (vertical / count).sqrt(),
            1e3 * mean / count,
            rho / count
        );
    }
}
