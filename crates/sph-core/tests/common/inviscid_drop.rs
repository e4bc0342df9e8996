//! An inviscid, axisymmetric, weightless drop at finite amplitude: the
//! reference for how Rayleigh's period lengthens as a drop starts further
//! from round (the solvers' drops in `tests/pbf.rs`, and
//! `docs/benchmark-notes.md`, "Large amplitudes").
//!
//! Units: the drop's volume radius, its density and its surface tension
//! are 1, so Rayleigh's linear frequencies are ω_l² = l(l − 1)(l + 2).
//!
//! Potential flow by spectral collocation. The surface r = F(θ) and the
//! surface potential Φ(θ) live at Gauss–Legendre nodes in cos θ. Inside,
//! φ = Σ a_n rⁿ P_n(cos θ), with the a_n fitted to Φ by least squares
//! (Householder QR) at every stage. The kinematic condition is
//! F_t = φ_r − φ_θ F_θ / F². Bernoulli's, followed along the node's ray, is
//! Φ_t = −|∇φ|²/2 − κ + φ_r F_t, with κ the exact mean curvature sum of the
//! axisymmetric surface. Time is classical Runge–Kutta, with an exponential
//! filter on the top Legendre modes of F and Φ after each step.
//!
//! The start is the l4 shape's: the unit sphere's points moved by ε times
//! Rayleigh's own flow of mode l, ∇(r^l P_l)/l, rescaled to the unit
//! sphere's volume, at rest. For l = 2 that flow is linear, so the start
//! is an ellipsoid stretched by 1 + ε along its axis and 1 − ε/2 across.
//! The signal for l = 4 is the amplitude (2l + 1)/3 ⟨r^l P_l⟩ over the
//! volume (`l4_amplitude`'s, ε at small ε), for l = 2 the extent
//! √(5⟨z²⟩) along the axis (`drop_period`'s, over 2R).

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_k from the
/// Chebyshev guesses).
fn gauss_legendre(k: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut nodes, mut weights) = (Vec::with_capacity(k), Vec::with_capacity(k));
    for i in 0..k {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (k as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (p, d) = legendre_and_slope(k, x);
            dp = d;
            let step = p / d;
            x -= step;
            if step.abs() < 1e-15 {
                break;
            }
        }
        nodes.push(x);
        weights.push(2.0 / ((1.0 - x * x) * dp * dp));
    }
    (nodes, weights)
}

/// P_n(x) and P_n'(x) by the three-term recurrence.
fn legendre_and_slope(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    if n == 0 {
        return (1.0, 0.0);
    }
    for m in 2..=n {
        let m = m as f64;
        (p0, p1) = (p1, ((2.0 * m - 1.0) * x * p1 - (m - 1.0) * p0) / m);
    }
    let n = n as f64;
    (p1, n * (x * p1 - p0) / (x * x - 1.0))
}

/// Least squares min |A a − b| for A of `rows` × `cols` (row-major), by
/// Householder QR.
fn least_squares(mut a: Vec<f64>, rows: usize, cols: usize, mut b: Vec<f64>) -> Vec<f64> {
    for j in 0..cols {
        let norm = (j..rows)
            .map(|i| a[i * cols + j].powi(2))
            .sum::<f64>()
            .sqrt();
        let alpha = if a[j * cols + j] > 0.0 { -norm } else { norm };
        let mut v: Vec<f64> = (j..rows).map(|i| a[i * cols + j]).collect();
        v[0] -= alpha;
        let vv: f64 = v.iter().map(|x| x * x).sum();
        if vv == 0.0 {
            continue;
        }
        for c in j..cols {
            let dot: f64 = (j..rows).map(|i| v[i - j] * a[i * cols + c]).sum();
            for i in j..rows {
                a[i * cols + c] -= 2.0 * dot / vv * v[i - j];
            }
        }
        let dot: f64 = (j..rows).map(|i| v[i - j] * b[i]).sum();
        for i in j..rows {
            b[i] -= 2.0 * dot / vv * v[i - j];
        }
    }
    let mut x = vec![0.0; cols];
    for j in (0..cols).rev() {
        let s: f64 = (j + 1..cols).map(|c| a[j * cols + c] * x[c]).sum();
        x[j] = (b[j] - s) / a[j * cols + j];
    }
    x
}

/// The collocation: nodes μ_k = cos θ_k, weights, and P_n, P_n', P_n''
/// there for n ≤ `modes`.
struct Drop {
    mu: Vec<f64>,
    w: Vec<f64>,
    sin: Vec<f64>,
    modes: usize,
    /// P_n(μ_k), P_n'(μ_k), P_n''(μ_k) at [k * (modes + 1) + n].
    p: Vec<f64>,
    dp: Vec<f64>,
    ddp: Vec<f64>,
    filter: Vec<f64>,
}

impl Drop {
    fn new(nodes: usize, modes: usize) -> Self {
        let (mu, w) = gauss_legendre(nodes);
        let sin = mu.iter().map(|m| (1.0 - m * m).sqrt()).collect();
        let (mut p, mut dp, mut ddp) = (Vec::new(), Vec::new(), Vec::new());
        for &x in &mu {
            for n in 0..=modes {
                let (v, d) = legendre_and_slope(n, x);
                let nn = (n * (n + 1)) as f64;
                p.push(v);
                dp.push(d);
                ddp.push((2.0 * x * d - nn * v) / (1.0 - x * x));
            }
        }
        let filter = (0..=modes)
            .map(|n| (-36.0 * (n as f64 / modes as f64).powi(16)).exp())
            .collect();
        Self {
            mu,
            w,
            sin,
            modes,
            p,
            dp,
            ddp,
            filter,
        }
    }

    fn at(&self, table: &[f64], k: usize, n: usize) -> f64 {
        table[k * (self.modes + 1) + n]
    }

    /// The Legendre coefficients of `f` at the nodes (Gauss quadrature).
    fn project(&self, f: &[f64]) -> Vec<f64> {
        (0..=self.modes)
            .map(|n| {
                let s: f64 = (0..f.len())
                    .map(|k| self.w[k] * self.at(&self.p, k, n) * f[k])
                    .sum();
                s * (2 * n + 1) as f64 / 2.0
            })
            .collect()
    }

    /// `f` with its top modes filtered.
    fn smooth(&self, f: &[f64]) -> Vec<f64> {
        let c = self.project(f);
        (0..f.len())
            .map(|k| {
                (0..=self.modes)
                    .map(|n| self.filter[n] * c[n] * self.at(&self.p, k, n))
                    .sum()
            })
            .collect()
    }

    /// (F_t, Φ_t) for the surface `f` and its potential `phi`.
    fn rates(&self, f: &[f64], phi: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (k, cols) = (f.len(), self.modes + 1);
        let mut a = Vec::with_capacity(k * cols);
        for (i, &r) in f.iter().enumerate() {
            for n in 0..cols {
                a.push(r.powi(n as i32) * self.at(&self.p, i, n));
            }
        }
        let coef = least_squares(a, k, cols, phi.to_vec());
        let c = self.project(f);
        let (mut df, mut dphi) = (vec![0.0; k], vec![0.0; k]);
        for i in 0..k {
            let (r, mu, s) = (f[i], self.mu[i], self.sin[i]);
            let (mut phi_r, mut phi_t) = (0.0, 0.0);
            for (n, a) in coef.iter().enumerate() {
                let rn = r.powi(n as i32);
                if n > 0 {
                    phi_r += a * n as f64 * rn / r * self.at(&self.p, i, n);
                }
                phi_t += a * rn * -s * self.at(&self.dp, i, n);
            }
            let (mut f_mu, mut f_mumu) = (0.0, 0.0);
            for (n, c) in c.iter().enumerate() {
                f_mu += c * self.at(&self.dp, i, n);
                f_mumu += c * self.at(&self.ddp, i, n);
            }
            let f_t = -s * f_mu;
            let f_tt = -mu * f_mu + s * s * f_mumu;
            let q = r * r + f_t * f_t;
            let kappa = (r * r + 2.0 * f_t * f_t - r * f_tt) / q.powf(1.5)
                + (r * s - f_t * mu) / (r * s * q.sqrt());
            df[i] = phi_r - phi_t * f_t / (r * r);
            dphi[i] = -0.5 * (phi_r * phi_r + (phi_t / r).powi(2)) - kappa + phi_r * df[i];
        }
        (df, dphi)
    }

    fn volume(&self, f: &[f64]) -> f64 {
        2.0 * std::f64::consts::PI / 3.0
            * f.iter()
                .zip(&self.w)
                .map(|(r, w)| w * r.powi(3))
                .sum::<f64>()
    }

    fn signal(&self, f: &[f64], l: usize) -> f64 {
        let v = self.volume(f);
        if l == 2 {
            let z2: f64 = (0..f.len())
                .map(|k| self.w[k] * self.mu[k].powi(2) * f[k].powi(5))
                .sum::<f64>()
                * 2.0
                * std::f64::consts::PI
                / 5.0;
            (5.0 * z2 / v).sqrt()
        } else {
            let moment: f64 = (0..f.len())
                .map(|k| self.w[k] * self.at(&self.p, k, l) * f[k].powi(l as i32 + 3))
                .sum::<f64>()
                * 2.0
                * std::f64::consts::PI
                / (l + 3) as f64;
            moment / v * (2 * l + 1) as f64 / 3.0
        }
    }

    /// The start: the unit sphere moved by ε ∇(r^l P_l)/l, at the nodes'
    /// angles (interpolated from a fine sampling of the moved sphere), at
    /// the unit sphere's volume.
    fn start(&self, l: usize, eps: f64) -> Vec<f64> {
        let samples = 20_001;
        let mut moved: Vec<(f64, f64)> = (0..samples)
            .map(|i| {
                let t0 = std::f64::consts::PI * i as f64 / (samples - 1) as f64;
                let (p, d) = legendre_and_slope(l, t0.cos());
                let dp = -t0.sin() * d; // dP_l/dθ
                let (er, et) = ((t0.sin(), t0.cos()), (t0.cos(), -t0.sin()));
                let (a, b) = (1.0 + eps * p, eps / l as f64 * dp);
                let x = (a * er.0 + b * et.0, a * er.1 + b * et.1);
                (x.0.atan2(x.1), x.0.hypot(x.1))
            })
            .collect();
        moved.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut f: Vec<f64> = self
            .mu
            .iter()
            .map(|m| {
                let t = m.acos();
                let j = moved.partition_point(|s| s.0 < t).clamp(1, samples - 1);
                let (a, b) = (moved[j - 1], moved[j]);
                a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
            })
            .collect();
        let scale = (4.0 * std::f64::consts::PI / 3.0 / self.volume(&f)).cbrt();
        f.iter_mut().for_each(|r| *r *= scale);
        f
    }
}

/// The signal of an inviscid drop in mode `l` started at amplitude `eps`,
/// sampled every `dt` (in units of Rayleigh's period) for `periods`
/// periods: (t / Rayleigh's period, signal).
pub fn series(l: usize, eps: f64, periods: f64, dt: f64) -> Vec<(f64, f64)> {
    let ll = l as f64;
    let period = 2.0 * std::f64::consts::PI / (ll * (ll - 1.0) * (ll + 2.0)).sqrt();
    let drop = Drop::new(48, if l == 2 { 24 } else { 32 });
    let mut f = drop.start(l, eps);
    let mut phi = vec![0.0; f.len()];
    let h = dt * period;
    let steps = (periods / dt).round() as usize;
    let mut out = vec![(0.0, drop.signal(&f, l))];
    let axpy = |x: &[f64], a: f64, y: &[f64]| -> Vec<f64> {
        x.iter().zip(y).map(|(x, y)| x + a * y).collect()
    };
    for i in 0..steps {
        let k1 = drop.rates(&f, &phi);
        let k2 = drop.rates(&axpy(&f, 0.5 * h, &k1.0), &axpy(&phi, 0.5 * h, &k1.1));
        let k3 = drop.rates(&axpy(&f, 0.5 * h, &k2.0), &axpy(&phi, 0.5 * h, &k2.1));
        let k4 = drop.rates(&axpy(&f, h, &k3.0), &axpy(&phi, h, &k3.1));
        let step = |x: &[f64], k: [&[f64]; 4]| -> Vec<f64> {
            (0..x.len())
                .map(|j| x[j] + h / 6.0 * (k[0][j] + 2.0 * k[1][j] + 2.0 * k[2][j] + k[3][j]))
                .collect()
        };
        f = drop.smooth(&step(&f, [&k1.0, &k2.0, &k3.0, &k4.0]));
        phi = drop.smooth(&step(&phi, [&k1.1, &k2.1, &k3.1, &k4.1]));
        out.push(((i + 1) as f64 * dt, drop.signal(&f, l)));
    }
    out
}

/// The period of an inviscid drop in mode `l` started at amplitude `eps`,
/// over Rayleigh's, read from its turns over three periods as the solvers'
/// drops are read (the first half swing left out).
pub fn period(l: usize, eps: f64) -> f64 {
    super::turn_period(&series(l, eps, 3.0, 1.0 / 600.0), 0.0).expect("an inviscid drop turns")
}
