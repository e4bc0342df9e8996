//! `tests/huppert.rs`'s axisymmetric viscous current
//! (`common::HuppertCurrent`: a cylinder of radius 0.113 m and height 0.1 m
//! let go on a no-slip floor, DFSPH with its implicit viscosity) at any
//! spacing and wall clearance, against Huppert (1982)'s late-time radius
//! r(t) = 0.894 (ρ g V³ / 3μ)^{1/8} t^{1/8}: the radius
//! (`common::current_radius`) at √2 steps to `--seconds`, and over the last
//! three samples the exponent of log r against log t and the rate r⁸ grows
//! at against Huppert's (`common::huppert_fit`). The test runs 1 cm; finer
//! spacings tell a resolution's artefact from the method's.
//!
//! ```text
//! cargo run --release -p sph-core --example huppert_current -- \
//!     [--spacing 0.01] [--clearance C] [--mu 100] [--seconds 8]
//! ```

#[path = "../tests/common/mod.rs"]
mod common;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut spacing, mut clearance, mut mu, mut seconds) = (0.01f32, None, 100.0f32, 8.0f64);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--spacing" => spacing = value()?.parse()?,
            "--clearance" => clearance = Some(value()?.parse()?),
            "--mu" => mu = value()?.parse()?,
            "--seconds" => seconds = value()?.parse()?,
            other => return Err(format!("unknown argument `{other}`").into()),
        }
    }
    let mut current = common::HuppertCurrent::new(spacing, mu, clearance)?;
    println!(
        "{} particles at {spacing} m, clearance {} m, μ = {mu} Pa·s; t (s), r (m), Huppert (m)",
        current.particles,
        clearance.unwrap_or(0.5 * spacing)
    );
    // √2 steps down from `seconds` to 0.2 s, in order.
    let mut times: Vec<f64> = (0..)
        .map(|k| seconds / 2f64.sqrt().powi(k))
        .take_while(|&t| t >= 0.2 - 1e-9)
        .collect();
    times.reverse();
    let mut rows = Vec::new();
    let start = std::time::Instant::now();
    for &t in &times {
        let (r, theory) = current.run_to(t, |_| ())?;
        println!(
            "  {t:5.2} {r:.4} {theory:.4} ({:+.1} %)  [{:.0} s wall]",
            100.0 * (r / theory - 1.0),
            start.elapsed().as_secs_f64()
        );
        rows.push((t, r, theory));
    }
    if rows.len() >= 3 {
        let (exponent, rate) = common::huppert_fit(&rows[rows.len() - 3..]);
        println!(
            "last three samples: exponent {exponent:.4} (Huppert 0.125); r⁸ grows at {rate:.3} of Huppert's rate"
        );
    }
    Ok(())
}
