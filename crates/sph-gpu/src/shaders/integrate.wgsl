// Semi-implicit Euler (v += a dt, x += v dt), then the box walls: clamp into
// the domain and reflect the normal velocity with the restitution — sph-core's
// Integrate and Boundaries processors (no obstacles yet).
// Expects solver_params.wgsl (struct Params, binding 0 `f`) prepended.

@group(0) @binding(1) var<storage, read_write> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> velocities: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> accelerations: array<vec4<f32>>;

@compute @workgroup_size(64)
fn integrate(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let p = positions[i];
    var v = velocities[i].xyz + accelerations[i].xyz * f.dt;
    var x = p.xyz + v * f.dt;
    for (var a = 0; a < 3; a++) {
        if x[a] < f.domain_min[a] {
            x[a] = f.domain_min[a];
            if v[a] < 0.0 {
                v[a] -= (1.0 + f.restitution) * v[a];
            }
        } else if x[a] > f.domain_max[a] {
            x[a] = f.domain_max[a];
            if v[a] > 0.0 {
                v[a] -= (1.0 + f.restitution) * v[a];
            }
        }
    }
    positions[i] = vec4<f32>(x, p.w);
    velocities[i] = vec4<f32>(v, 0.0);
}
