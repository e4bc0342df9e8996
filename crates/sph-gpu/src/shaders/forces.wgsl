// Accelerations: symmetric pressure force (eq. 15, poly6 or spiky gradient),
// viscosity (eq. 17), surface tension from the colour field (eq. 18-20, where
// |n| > threshold), gravity, and the walls' pressure push — the equations of
// sph-core's Forces processor — and the demo's push near a ray, if any.
// Expects solver_params.wgsl (struct Params, binding 0 `f`), walls.wgsl and
// push.wgsl prepended.

@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read> starts: array<u32>;
@group(0) @binding(4) var<storage, read> sorted: array<u32>;
@group(0) @binding(5) var<storage, read> densities: array<f32>;
@group(0) @binding(6) var<storage, read> pressures: array<f32>;
@group(0) @binding(7) var<storage, read> velocities: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> accelerations: array<vec4<f32>>;

@group(0) @binding(9) var<storage, read> obstacles: array<Obstacle>;

@compute @workgroup_size(64)
fn forces(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let x = positions[i].xyz;
    let vi = velocities[i].xyz;
    let rho_i = densities[i];
    let pi = pressures[i] / (rho_i * rho_i);
    let c = cell_at(x, f.inv_h);
    let h2 = f.h * f.h;
    var a_p = vec3<f32>(0.0);
    var a_v = vec3<f32>(0.0);
    var n = vec3<f32>(0.0);
    var lap_c = 0.0;
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let cell = c + vec3<i32>(dx, dy, dz);
                let b = bucket_of(cell, f.table);
                let s = starts[b];
                for (var k = 0u; k < counts[b]; k++) {
                    let j = sorted[s + k];
                    let y = positions[j];
                    if any(cell_at(y.xyz, f.inv_h) != cell) {
                        continue;
                    }
                    let r = x - y.xyz;
                    let r2 = dot(r, r);
                    if r2 > h2 {
                        continue;
                    }
                    let rho_j = densities[j];
                    let vol = y.w / rho_j;
                    let q = h2 - r2;
                    let grad6 = -f.poly6_grad * q * q * r;
                    n += vol * grad6;
                    lap_c += vol * f.poly6_grad * q * (7.0 * r2 - 3.0 * h2);
                    if j == i {
                        continue;
                    }
                    let len = sqrt(r2);
                    var grad = grad6;
                    if f.spiky_pressure == 1u {
                        // Zero for coincident particles, as on the CPU (r/len
                        // would be 0/0).
                        let e = f.h - len;
                        grad = select(vec3<f32>(0.0), -f.spiky_grad * e * e * r / len, len > 0.0);
                    }
                    a_p -= y.w * (pi + pressures[j] / (rho_j * rho_j)) * grad;
                    a_v += vol * f.visc_lap * (f.h - len) * (velocities[j].xyz - vi);
                }
            }
        }
    }
    for (var k = 0u; k < wall_count(); k++) {
        let w = wall(k, x);
        if w.w < f.h {
            let d = max(w.w, 0.0);
            let slope = wall_term(d, vec2<f32>(0.0, plane_density(d))).y;
            a_p += pi * f.rest_density * slope * w.xyz;
        }
    }
    var a = a_p + (f.viscosity / rho_i) * a_v + f.gravity.xyz;
    let n_len = length(n);
    if f.surface_tension > 0.0 && n_len > f.surface_threshold {
        a -= f.surface_tension * lap_c * n / (n_len * rho_i);
    }
    // After the forces, as the demo's push processor is.
    a += push_acceleration(x);
    accelerations[i] = vec4<f32>(a, 0.0);
}
