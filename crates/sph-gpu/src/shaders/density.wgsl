// Density by poly6 summation (eq. 4) plus the walls' half-space integrals (walls.wgsl), and
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
    layers: vec4<f32>,  // the walls' layers under a clearance: spacing, thickness (walls.wgsl)
};

@group(0) @binding(0) var<uniform> f: Fluid;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read> starts: array<u32>;
@group(0) @binding(4) var<storage, read> sorted: array<u32>;
@group(0) @binding(5) var<storage, read_write> densities: array<f32>;
@group(0) @binding(6) var<storage, read_write> pressures: array<f32>;

@group(0) @binding(7) var<storage, read> obstacles: array<Obstacle>;

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
    for (var k = 0u; k < wall_count(); k++) {
        let w = wall(k, x);
        if w.w < f.h {
            let d = max(w.w, 0.0);
            rho += f.rest_density * wall_term(d, vec2<f32>(wall_volume_fraction(d), 0.0)).x;
        }
    }
    densities[i] = rho;
    let eos = f.stiffness * (rho - f.rest_density);
    pressures[i] = select(eos, f.suction * eos, eos < 0.0);
}
