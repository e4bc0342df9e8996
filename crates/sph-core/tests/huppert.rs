//! Viscous spreading against Huppert (1982), "The propagation of
//! two-dimensional and axisymmetric viscous gravity currents over a rigid
//! horizontal surface", J. Fluid Mech. 121: a fixed volume V of viscous
//! fluid spreading on a no-slip floor under gravity at low Reynolds number
//! reaches the radius r(t) = 0.894 (ρ g V³ / 3μ)^{1/8} t^{1/8} at late
//! times. DFSPH with its implicit viscosity.
//!
//! ```text
//! cargo test --release -p sph-core --test huppert -- --nocapture
//! ```

mod common;

/// Huppert's current (`common::HuppertCurrent`: V ≈ 0.004 m³, 3,960
/// particles at 1 cm) at viscosity `mu`: (t, r, Huppert's r) at each of
/// `times`.
fn spread(mu: f32, times: &[f64]) -> Vec<(f64, f64, f64)> {
    let mut current = common::HuppertCurrent::new(0.01, mu, None).unwrap();
    let mut rows = Vec::new();
    for &t in times {
        let unconverged = |r: &sph_core::FrameReport| {
            assert_eq!(r.unconverged, 0, "μ = {mu}: {r:?}");
        };
        let (r, theory) = current.run_to(t, unconverged).unwrap();
        rows.push((t, r, theory));
    }
    println!("μ = {mu} Pa·s: t (s), r (m), Huppert (m)");
    for &(t, r, theory) in &rows {
        println!(
            "  {t:5.2} {r:.4} {theory:.4} ({:+.1} %)",
            100.0 * (r / theory - 1.0)
        );
    }
    rows
}

/// The current at 100 Pa·s from 1 to 8 s, sampled at √2 steps, against
/// Huppert's similarity solution, and the current at 1,000 Pa·s against
/// the first by the law's own scaling. The radius is the front's median
/// over 32 sectors (`common::current_radius`).
///
/// At late times (4 to 8 s, r 1.7–1.9 times the cylinder's 0.113 m), with
/// the scenes' default clearance (half a spacing):
/// - the exponent of log r against log t (Huppert's is 1/8) measured
///   0.151: the cylinder starts below the similarity solution and reaches
///   it from below, so the exponent is above 1/8 and falls towards it.
///   Asserted in [0.125, 0.175]: a current that stopped spreading gives 0.
/// - r⁸ grows at 0.68 of Huppert's rate 0.894⁸ ρ g V³/3μ, asserted within
///   0.65–1.0 (r⁸ magnifies an error in the radius eightfold). That rate is
///   the similarity solution's whatever the virtual time origin, and a
///   current still approaching it, as the exponent says this one is,
///   grows r⁸ more slowly.
/// - the radius measured 7.1 and 6.3 % below Huppert's at 5.7 and 8 s,
///   asserted within 7.5 % (a current frozen at its 4 s radius is 14.8 %
///   short at 8 s).
///
/// The clearance costs this thin current (two layers deep at 8 s) speed:
/// with its first layer free to sink into the floor it read a rate of
/// 0.76 and 5.8 and 5.1 % short, and the bounds were 0.7 and 7 %
/// (`cargo run --release -p sph-core --example huppert_current --
/// --clearance 0`). The clearance holds the first layer where the lattice
/// put it, a quarter of the current's depth, against the no-slip floor
/// (the wall friction that gives Poiseuille's flow rate within 5 % in
/// `tests/viscosity.rs`); the sinking layer had made room for the layers
/// above. The gap shrinks with resolution (at 5 mm, with the older
/// square-cut current: 0.82 without and 0.75 with a clearance).
///
/// These are the method's, not the resolution's: at 5 mm (32,040
/// particles, `cargo run --release -p sph-core --example huppert_current --
/// --spacing 0.005`) the exponent is 0.151, the rate 0.78 and the radius
/// 5.3 and 4.6 % short. (This test once cut its cylinder from a block 0.2
/// m square, which kept the square's flat sides, and took the farthest
/// particle for the radius: 3,600 particles, read 0.91 of the rate and 3.0 %
/// short at 8 s.)
///
/// At low Reynolds number r depends on t and μ through t/μ alone (the
/// law's r ∝ (t/μ)^{1/8} is the late-time form of that), so the current
/// at 1,000 Pa·s at t is the current at 100 Pa·s at t/10: measured
/// within 1.94 %, asserted within 2.5 % from 2 to 8 s (where the currents
/// are still 12–15 % short of the similarity solution). A viscosity solve
/// that did nothing would let the 1,000 Pa·s current run far ahead.
#[test]
fn axisymmetric_current_spreads_as_huppert() {
    let late: Vec<f64> = (0..7).map(|k| 2f64.sqrt().powi(k)).collect();
    let early: Vec<f64> = late[2..].iter().map(|t| 0.1 * t).collect();
    let times: Vec<f64> = early.iter().chain(&late).copied().collect();
    let thin = spread(100.0, &times);
    let thick = spread(1000.0, &late[2..]);
    let tail = &thin[thin.len() - 3..];
    let (exponent, rate) = common::huppert_fit(tail);
    println!(
        "μ = 100 Pa·s, 4 to 8 s: exponent {exponent:.4}; r⁸ grows at {rate:.3} of Huppert's rate"
    );
    let mut worst = 0.0f64;
    for (&(t, r, _), &(t_early, r_early, _)) in thick.iter().zip(&thin) {
        let off = r / r_early - 1.0;
        println!(
            "  μ = 1000 at {t:.2} s: r {r:.4} m; μ = 100 at {t_early:.3} s: {r_early:.4} m ({:+.2} %)",
            100.0 * off
        );
        worst = worst.max(off.abs());
    }
    assert!(
        (0.125..=0.175).contains(&exponent),
        "exponent {exponent} over 4–8 s"
    );
    assert!((0.65..=1.0).contains(&rate), "r⁸ rate {rate} of Huppert's");
    for &(t, r, theory) in &tail[1..] {
        assert!(
            (r / theory - 1.0).abs() <= 0.075,
            "t = {t}: r {r} m, Huppert {theory} m"
        );
    }
    assert!(
        worst <= 0.025,
        "μ = 1000 against μ = 100 at a tenth of the time: {worst}"
    );
}
