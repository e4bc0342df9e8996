// Yu & Turk's (2013) anisotropic kernels as one compute pass, as
// surfel-extract's `anisotropy::kernels` computes them (see its module docs
// for the three choices that differ from the paper): per particle, over its
// neighbours within r (the grid's cell size), with weights
// w = 1 − (|x_j − x_i|/r)³, the weighted mean and covariance, the
// covariance's principal axes (Eberly's closed form, in f32 on a matrix
// scaled to entries of at most 1), the kernel G² = R diag(σ₁/max(σₖ, σ₁/k_r)) Rᵀ
// with det G, an isolated sphere below N_ε neighbours, and the smoothed
// centre. Expects hash.wgsl prepended.

struct Aniso {
    r: f32,               // the neighbourhoods' radius (the grid's cell size)
    inv_r: f32,
    n: u32,
    table: u32,
    smoothing: f32,       // λ
    max_ratio: f32,       // k_r
    min_neighbours: u32,  // N_ε
    isolated_scale: f32,  // k_n
    inv_tau: f32,         // 1 / (thickness h): the layer's half-thickness
    layer: u32,           // 1: Centres::Layer, 0: Centres::Mean
    pad0: u32,
    pad1: u32,
};

// One particle's kernel: G² as xx, xy, xz, yy in `a` and yz, zz in `b.xy`,
// det G in `b.z`, 1 in `b.w` for an isolated particle's sphere.
struct Kernel {
    a: vec4<f32>,
    b: vec4<f32>,
};

@group(0) @binding(0) var<uniform> p: Aniso;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read> starts: array<u32>;
@group(0) @binding(4) var<storage, read> sorted: array<u32>;
@group(0) @binding(5) var<storage, read_write> centres: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> kernels: array<Kernel>;

// A symmetric matrix's eigenvalues, largest first, their unit axes (columns),
// and whether it had any (a zero or non-finite matrix has none).
struct Principal {
    variances: vec3<f32>,
    axes: mat3x3<f32>,
    ok: bool,
};

// The unit eigenvector of symmetric m for its simple eigenvalue `value`: the
// longest cross product of two rows of m − value I.
fn eigenvector_of_simple(m: mat3x3<f32>, value: f32) -> vec3<f32> {
    let r0 = m[0] - vec3<f32>(value, 0.0, 0.0);
    let r1 = m[1] - vec3<f32>(0.0, value, 0.0);
    let r2 = m[2] - vec3<f32>(0.0, 0.0, value);
    let c0 = cross(r0, r1);
    let c1 = cross(r0, r2);
    let c2 = cross(r1, r2);
    var best = c0;
    if dot(c1, c1) > dot(best, best) {
        best = c1;
    }
    if dot(c2, c2) > dot(best, best) {
        best = c2;
    }
    let len = length(best);
    if !(len > 0.0) {
        return vec3<f32>(1.0, 0.0, 0.0);
    }
    return best / len;
}

// The unit eigenvector of symmetric m for `value` orthogonal to its unit
// eigenvector w: the null vector of m − value I in w's orthogonal complement.
fn eigenvector_in_complement(m: mat3x3<f32>, w: vec3<f32>, value: f32) -> vec3<f32> {
    var u: vec3<f32>;
    if abs(w.x) > abs(w.y) {
        u = vec3<f32>(-w.z, 0.0, w.x) / sqrt(w.x * w.x + w.z * w.z);
    } else {
        u = vec3<f32>(0.0, w.z, -w.y) / sqrt(w.y * w.y + w.z * w.z);
    }
    let v = cross(w, u);
    let mu = m * u;
    let mv = m * v;
    let m00 = dot(u, mu) - value;
    let m01 = dot(u, mv);
    let m11 = dot(v, mv) - value;
    var d = m11;
    var across = -1.0;
    if abs(m00) >= abs(m11) {
        d = m00;
        across = 1.0;
    }
    if max(abs(d), abs(m01)) == 0.0 {
        return u;
    }
    var s: f32;
    var c: f32;
    if abs(d) >= abs(m01) {
        let t = m01 / d;
        c = 1.0 / sqrt(1.0 + t * t);
        s = t * c;
    } else {
        let t = d / m01;
        s = 1.0 / sqrt(1.0 + t * t);
        c = t * s;
    }
    if across > 0.0 {
        return s * u - c * v;
    }
    return c * u - s * v;
}

// Eberly's non-iterative solver for a symmetric 3 × 3 matrix (surfel-extract's
// `Principal::of`, there in f64).
fn principal(c: mat3x3<f32>) -> Principal {
    var none: Principal;
    none.ok = false;
    let scale = max(max(max(abs(c[0].x), abs(c[1].x)), max(abs(c[2].x), abs(c[1].y))),
                    max(abs(c[2].y), abs(c[2].z)));
    if !(scale > 0.0 && scale < 3.0e38) {
        return none;
    }
    let m = c * (1.0 / scale);
    let a00 = m[0].x;
    let a01 = m[1].x;
    let a02 = m[2].x;
    let a11 = m[1].y;
    let a12 = m[2].y;
    let a22 = m[2].z;
    let q = (a00 + a11 + a22) / 3.0;
    let b00 = a00 - q;
    let b11 = a11 - q;
    let b22 = a22 - q;
    let off = a01 * a01 + a02 * a02 + a12 * a12;
    let pp = sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * off) / 6.0);
    var values = vec3<f32>(q);
    var axes = mat3x3<f32>(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0),
                           vec3<f32>(0.0, 0.0, 1.0));
    if pp > 0.0 {
        let c00 = b11 * b22 - a12 * a12;
        let c01 = a01 * b22 - a12 * a02;
        let c02 = a01 * a12 - b11 * a02;
        let det = (b00 * c00 - a01 * c01 + a02 * c02) / (pp * pp * pp);
        let half_det = clamp(0.5 * det, -1.0, 1.0);
        let angle = acos(half_det) / 3.0;
        let beta2 = 2.0 * cos(angle);
        let beta0 = 2.0 * cos(angle + 2.0943951);
        let beta1 = -(beta0 + beta2);
        values = vec3<f32>(q + pp * beta0, q + pp * beta1, q + pp * beta2);
        if half_det >= 0.0 {
            let e2 = eigenvector_of_simple(m, values.z);
            let e1 = eigenvector_in_complement(m, e2, values.y);
            axes = mat3x3<f32>(cross(e1, e2), e1, e2);
        } else {
            let e0 = eigenvector_of_simple(m, values.x);
            let e1 = eigenvector_in_complement(m, e0, values.y);
            axes = mat3x3<f32>(e0, e1, cross(e0, e1));
        }
    }
    var out: Principal;
    out.variances = values.zyx * scale;
    out.axes = mat3x3<f32>(axes[2], axes[1], axes[0]);
    out.ok = out.variances.x > 0.0 && out.variances.x < 3.0e38;
    return out;
}

// The neighbourhood sums of particle i at x: Σw, Σw o, Σw o oᵀ (o = x_j − x),
// and how many within r (itself included).
struct Sums {
    w: f32,
    first: vec3<f32>,
    diagonal: vec3<f32>,  // xx, yy, zz
    off: vec3<f32>,       // xy, xz, yz
    count: u32,
};

fn sums(x: vec3<f32>) -> Sums {
    var s = Sums(0.0, vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), 0u);
    let c = cell_at(x, p.inv_r);
    let r2 = p.r * p.r;
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let cell = c + vec3<i32>(dx, dy, dz);
                let b = bucket_of(cell, p.table);
                let first = starts[b];
                for (var k = 0u; k < counts[b]; k++) {
                    let y = positions[sorted[first + k]].xyz;
                    if any(cell_at(y, p.inv_r) != cell) {
                        continue;
                    }
                    let o = y - x;
                    let d2 = dot(o, o);
                    if d2 <= r2 {
                        let q = sqrt(d2) * p.inv_r;
                        let w = 1.0 - q * q * q;
                        let wo = w * o;
                        s.w += w;
                        s.first += wo;
                        s.diagonal += wo * o;
                        s.off += wo.xxy * o.yzz;
                        s.count++;
                    }
                }
            }
        }
    }
    return s;
}

// The weighted mean height, along n, of the neighbours within the layer of
// half-thickness τ about x's plane (weights w (1 − (t/τ)²)²).
fn layer_height(x: vec3<f32>, n: vec3<f32>) -> f32 {
    var sw = 0.0;
    var sum = 0.0;
    let c = cell_at(x, p.inv_r);
    let r2 = p.r * p.r;
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let cell = c + vec3<i32>(dx, dy, dz);
                let b = bucket_of(cell, p.table);
                let first = starts[b];
                for (var k = 0u; k < counts[b]; k++) {
                    let y = positions[sorted[first + k]].xyz;
                    if any(cell_at(y, p.inv_r) != cell) {
                        continue;
                    }
                    let o = y - x;
                    let d2 = dot(o, o);
                    if d2 <= r2 {
                        let q = sqrt(d2) * p.inv_r;
                        let t = dot(o, n);
                        let u = t * p.inv_tau;
                        let a = max(1.0 - u * u, 0.0);
                        let wg = (1.0 - q * q * q) * a * a;
                        sw += wg;
                        sum += wg * t;
                    }
                }
            }
        }
    }
    return sum / sw;
}

// One thread per particle, in the grid's cell order (thread k takes
// sorted[k]): a warp's particles share their neighbourhoods, so its loads
// hit the same lines.
@compute @workgroup_size(64)
fn kernels_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= p.n {
        return;
    }
    let i = sorted[id.x];
    let x = positions[i].xyz;
    let s = sums(x);
    let inv = 1.0 / s.w;
    let mean = s.first * inv;
    let d = s.diagonal * inv;
    let o = s.off * inv;
    let c = mat3x3<f32>(
        vec3<f32>(d.x, o.x, o.y) - mean * mean.x,
        vec3<f32>(o.x, d.y, o.z) - mean * mean.y,
        vec3<f32>(o.y, o.z, d.z) - mean * mean.z,
    );
    var pr: Principal;
    pr.ok = false;
    if s.count - 1u >= p.min_neighbours {
        pr = principal(c);
    }
    var kernel: Kernel;
    if pr.ok {
        let largest = pr.variances.x;
        let floor = largest / p.max_ratio;
        var g2 = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
        var det = 1.0;
        for (var k = 0; k < 3; k++) {
            let g2k = largest / max(pr.variances[k], floor);
            det *= sqrt(g2k);
            let v = pr.axes[k];
            g2 += mat3x3<f32>(v * v.x, v * v.y, v * v.z) * g2k;
        }
        kernel = Kernel(vec4<f32>(g2[0].x, g2[1].x, g2[2].x, g2[1].y),
                        vec4<f32>(g2[2].y, g2[2].z, det, 0.0));
    } else {
        let a = 1.0 / (p.isolated_scale * p.isolated_scale);
        let det = a / p.isolated_scale;
        kernel = Kernel(vec4<f32>(a, 0.0, 0.0, a), vec4<f32>(0.0, a, det, 1.0));
    }
    var centre = x + p.smoothing * mean;
    if p.layer != 0u && pr.ok {
        let n = pr.axes[2];
        centre = x + p.smoothing * layer_height(x, n) * n;
    }
    kernels[i] = kernel;
    centres[i] = vec4<f32>(centre, positions[i].w);
}
