#!/usr/bin/env python3
"""An inviscid, axisymmetric drop in zero gravity, oscillating at finite
amplitude: the reference for how Rayleigh's period lengthens with the
amplitude of the drops in `sph-core`'s `rayleigh_drop` example and tests.

Units: the drop's volume radius R = 1, density 1, surface tension 1, so
Rayleigh's linear frequencies are w_l^2 = l (l - 1) (l + 2).

The method is spectral collocation of potential flow (as in Lundgren &
Mansour 1988's problem, here without boundary integrals): the surface
r = F(theta, t) and the surface potential Phi(theta, t) at K Gauss-Legendre
nodes in cos(theta); inside, phi = sum_n a_n r^n P_n(cos theta), its a_n
fitted to Phi by least squares each stage. Kinematic condition
F_t = phi_r - phi_theta F_theta / F^2, Bernoulli's
dPhi/dt = -|grad phi|^2 / 2 - kappa + phi_r F_t (kappa the mean curvature
sum), classical Runge-Kutta in time, and an exponential filter on the
highest Legendre modes of F and Phi each step against aliasing.

The start is the l4 shape's: the unit sphere's points moved by eps times
Rayleigh's own flow of mode l, grad(r^l P_l)/l, rescaled to the unit
sphere's volume, at rest. For l = 2 that flow is linear, so the start is an
ellipsoid stretched by 1 + eps along the axis and 1 - eps/2 across (the
example's ellipsoid takes 1 + eps and its inverse square root: compare
them at equal extent). The signal is the example's: for l = 2 the
extent along the axis over 2R, sqrt(5 <z^2>) over the volume; otherwise
the amplitude (2l + 1)/3 <r^l P_l> over the volume, which reads eps at
small eps.

    python3 -m venv /tmp/npv && /tmp/npv/bin/pip install numpy
    /tmp/npv/bin/python scripts/inviscid_drop.py --mode 4 --eps 0.05 0.1 0.2 -0.2
    /tmp/npv/bin/python scripts/inviscid_drop.py --mode 2 --eps 0.3 0.5 --nmax 24 --nodes 40 --dt 2e-3

Measured figures and what they say about the solvers: docs/benchmark-notes.md,
"Large amplitudes: an inviscid reference for the box and the cube".
"""

import argparse

import numpy as np
from numpy.polynomial import legendre as L


def legendre_matrices(mu, n_max):
    """P_n(mu), P_n'(mu), P_n''(mu) for n = 0..n_max at nodes mu."""
    k = len(mu)
    p, dp, ddp = (np.zeros((k, n_max + 1)) for _ in range(3))
    for n in range(n_max + 1):
        c = np.zeros(n + 1)
        c[n] = 1.0
        p[:, n] = L.legval(mu, c)
        dp[:, n] = L.legval(mu, L.legder(c))
        ddp[:, n] = L.legval(mu, L.legder(c, 2))
    return p, dp, ddp


class Drop:
    def __init__(self, nodes, n_max, filter_order=16):
        self.mu, self.w = L.leggauss(nodes)
        self.theta = np.arccos(self.mu)
        self.sin = np.sqrt(1.0 - self.mu**2)
        self.n_max = n_max
        self.p, self.dp, self.ddp = legendre_matrices(self.mu, n_max)
        # Projection onto Legendre coefficients by Gauss quadrature.
        norms = (2 * np.arange(n_max + 1) + 1) / 2.0
        self.project = (self.p * self.w[:, None]).T * norms[:, None]
        n = np.arange(n_max + 1)
        self.filter = np.exp(-36.0 * (n / n_max) ** filter_order)

    def smooth(self, f):
        return self.p @ (self.filter * (self.project @ f))

    def shape_derivatives(self, f):
        c = self.project @ f
        mu, s = self.mu, self.sin
        f_mu, f_mumu = self.dp @ c, self.ddp @ c
        f_t = -s * f_mu
        f_tt = -mu * f_mu + s * s * f_mumu
        return f_t, f_tt

    def curvature(self, f):
        f_t, f_tt = self.shape_derivatives(f)
        q = f * f + f_t * f_t
        meridional = (f * f + 2 * f_t * f_t - f * f_tt) / q**1.5
        azimuthal = (f * self.sin - f_t * self.mu) / (f * self.sin * np.sqrt(q))
        return meridional + azimuthal, f_t

    def rates(self, f, phi_s):
        n = np.arange(self.n_max + 1)
        a_mat = f[:, None] ** n[None, :] * self.p
        a, *_ = np.linalg.lstsq(a_mat, phi_s, rcond=None)
        rn1 = f[:, None] ** np.maximum(n - 1, 0)[None, :]
        phi_r = (rn1 * n[None, :] * self.p) @ a
        phi_th = (f[:, None] ** n[None, :] * (-self.sin[:, None] * self.dp)) @ a
        kappa, f_t = self.curvature(f)
        df = phi_r - phi_th * f_t / (f * f)
        grad2 = phi_r**2 + (phi_th / f) ** 2
        dphi = -0.5 * grad2 - kappa + phi_r * df
        return df, dphi

    def volume(self, f):
        return 2 * np.pi / 3 * np.sum(self.w * f**3)

    def amplitude(self, f, l):
        """(2l + 1)/3 <r^l P_l> over the volume: eps for r = 1 + eps P_l
        at small eps (the example's 3 <r^4 P_4> for l = 4)."""
        moment = 2 * np.pi * np.sum(self.w * self.p[:, l] * f ** (l + 3)) / (l + 3)
        return moment / self.volume(f) * (2 * l + 1) / 3

    def extent(self, f):
        """The example's extent along the axis over 2R: sqrt(5 <z^2>) over
        the volume (1 for the sphere)."""
        z2 = 2 * np.pi * np.sum(self.w * self.mu**2 * f**5) / 5
        return np.sqrt(5 * z2 / self.volume(f))

    def start(self, l, eps, samples=20001):
        t0 = np.linspace(0, np.pi, samples)
        c = np.zeros(l + 1)
        c[l] = 1.0
        pl = L.legval(np.cos(t0), c)
        dpl = -np.sin(t0) * L.legval(np.cos(t0), L.legder(c))
        er = np.stack([np.sin(t0), np.cos(t0)])
        et = np.stack([np.cos(t0), -np.sin(t0)])
        x = er * (1 + eps * pl) + et * (eps / l) * dpl
        r = np.hypot(x[0], x[1])
        th = np.arctan2(x[0], x[1])
        order = np.argsort(th)
        f = np.interp(self.theta, th[order], r[order])
        f *= (4 * np.pi / 3 / self.volume(f)) ** (1 / 3)
        return f


def run(l, eps, t_end, dt, nodes, n_max):
    d = Drop(nodes, n_max)
    f = d.start(l, eps)
    np.seterr(over="raise", invalid="raise")
    phi = np.zeros_like(f)
    signal = (lambda f: d.extent(f)) if l == 2 else (lambda f: d.amplitude(f, l))
    times, amps = [0.0], [signal(f)]
    steps = int(round(t_end / dt))
    v0 = d.volume(f)
    for i in range(steps):
        k1 = d.rates(f, phi)
        k2 = d.rates(f + 0.5 * dt * k1[0], phi + 0.5 * dt * k1[1])
        k3 = d.rates(f + 0.5 * dt * k2[0], phi + 0.5 * dt * k2[1])
        k4 = d.rates(f + dt * k3[0], phi + dt * k3[1])
        f = f + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        phi = phi + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        f, phi = d.smooth(f), d.smooth(phi)
        times.append((i + 1) * dt)
        amps.append(signal(f))
    return np.array(times), np.array(amps), d.volume(f) / v0 - 1


def turns(t, a):
    """Extrema of a sampled signal, each refined by a parabola."""
    out = []
    for i in range(1, len(a) - 1):
        if (a[i] - a[i - 1]) * (a[i + 1] - a[i]) < 0:
            y0, y1, y2 = a[i - 1], a[i], a[i + 1]
            den = y0 - 2 * y1 + y2
            s = 0.5 * (y0 - y2) / den if den != 0 else 0.0
            out.append((t[i] + s * (t[1] - t[0]), y1 - 0.25 * (y0 - y2) * s))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mode", type=int, default=4)
    ap.add_argument("--eps", type=float, nargs="+", default=[0.05, 0.1, 0.2])
    ap.add_argument("--periods", type=float, default=3.0)
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--nodes", type=int, default=48)
    ap.add_argument("--nmax", type=int, default=32)
    args = ap.parse_args()
    l = args.mode
    w = np.sqrt(l * (l - 1) * (l + 2))
    period = 2 * np.pi / w
    print(f"l = {l}: Rayleigh's period 2 pi / sqrt({l * (l - 1) * (l + 2)}) = {period:.4f}")
    for eps in args.eps:
        try:
            t, a, dv = run(l, eps, args.periods * period, args.dt, args.nodes, args.nmax)
        except (np.linalg.LinAlgError, FloatingPointError) as e:
            print(f"eps {eps:+.3f}: the collocation broke down ({e}): too large for this method")
            continue
        tr = turns(t, a)
        half = np.diff([0.0] + [x[0] for x in tr])
        first = tr[0][0] / (period / 2)
        mean = 2 * (tr[-1][0] - tr[0][0]) / (len(tr) - 1) / period if len(tr) > 1 else float("nan")
        print(
            f"eps {eps:+.3f}: {'extent' if l == 2 else 'amplitude'} at start {a[0]:+.4f}; first half swing / Rayleigh's {first:.4f}; "
            f"period from the turns / Rayleigh's {mean:.4f}; half swings {np.round(half / (period / 2), 4).tolist()}; "
            f"extrema {[round(float(x[1]), 4) for x in tr]}; volume drift {dv:+.1e}",
            flush=True,
        )


if __name__ == "__main__":
    main()
