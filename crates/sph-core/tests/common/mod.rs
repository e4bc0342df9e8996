//! Helpers shared by the solver tests. Each test crate compiles this
//! module and uses part of it.

#[allow(dead_code)]
/// The least-squares slope of y over x for the points (x, y).
pub fn slope(points: impl Iterator<Item = (f64, f64)> + Clone) -> f64 {
    let n = points.clone().count() as f64;
    let (mx, my) = points
        .clone()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = points.fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    sxy / sxx
}

#[allow(dead_code)]
/// The least-squares slope of the pressures `ps` over the heights `ys`.
pub fn pressure_slope(ys: &[f32], ps: &[f32]) -> f64 {
    slope(
        ys.iter()
            .zip(ps)
            .map(|(&y, &p)| (f64::from(y), f64::from(p))),
    )
}
