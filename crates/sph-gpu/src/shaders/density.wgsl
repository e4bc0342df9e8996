// Density by poly6 summation (eq. 4) plus the walls' half-space integral, and
// pressure by the equation of state p = k(rho - rho0) (eq. 16): the same
// equations as sph-core's DensityPressure processor.

struct Fluid {
    h: f32,
    inv_h: f32,
    n: u32,
    table: u32,
    rest_density: f32,
    stiffness: f32,
    suction: f32,   // negative pressures are scaled by this
    poly6: f32,     // 315 / (64 pi h^9)
    domain_min: vec4<f32>,
    domain_max: vec4<f32>,
};

@group(0) @binding(0) var<uniform> f: Fluid;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read> starts: array<u32>;
@group(0) @binding(4) var<storage, read> sorted: array<u32>;
@group(0) @binding(5) var<storage, read_write> densities: array<f32>;
@group(0) @binding(6) var<storage, read_write> pressures: array<f32>;

// Integral of W_poly6 over the half-space beyond a plane at distance d, in
// units of s = d/h: 315/256 (G(1) - G(s)), G(s) = s (1 - 4s^2/3 + 6s^4/5 - 4s^6/7 + s^8/9).
fn wall_volume_fraction(d: f32) -> f32 {
    let s = clamp(d * f.inv_h, 0.0, 1.0);
    let s2 = s * s;
    let g = s * (1.0 + s2 * (-4.0 / 3.0 + s2 * (6.0 / 5.0 + s2 * (-4.0 / 7.0 + s2 / 9.0))));
    let g1 = 1.0 - 4.0 / 3.0 + 6.0 / 5.0 - 4.0 / 7.0 + 1.0 / 9.0;
    return 315.0 / 256.0 * (g1 - g);
}

@compute @workgroup_size(64)
fn density(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let x = positions[i].xyz;
    let c = cell_at(x, f.inv_h);
    let h2 = f.h * f.h;
    var rho = 0.0;
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let cell = c + vec3<i32>(dx, dy, dz);
                let b = bucket_of(cell, f.table);
                let s = starts[b];
                for (var k = 0u; k < counts[b]; k++) {
                    let y = positions[sorted[s + k]];
                    if any(cell_at(y.xyz, f.inv_h) != cell) {
                        continue;
                    }
                    let d = x - y.xyz;
                    let r2 = dot(d, d);
                    if r2 <= h2 {
                        let q = h2 - r2;
                        rho += y.w * f.poly6 * q * q * q;
                    }
                }
            }
        }
    }
    for (var a = 0; a < 3; a++) {
        let lo = x[a] - f.domain_min[a];
        if lo < f.h {
            rho += f.rest_density * wall_volume_fraction(max(lo, 0.0));
        }
        let hi = f.domain_max[a] - x[a];
        if hi < f.h {
            rho += f.rest_density * wall_volume_fraction(max(hi, 0.0));
        }
    }
    densities[i] = rho;
    let eos = f.stiffness * (rho - f.rest_density);
    pressures[i] = select(eos, f.suction * eos, eos < 0.0);
}
