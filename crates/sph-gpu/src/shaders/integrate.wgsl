// Semi-implicit Euler (v += a dt, x += v dt), then the box walls: clamp into
// the domain and reflect the normal velocity with the restitution — sph-core's
// Integrate and Boundaries processors (no obstacles yet).

struct Params {
    h: f32,
    inv_h: f32,
    n: u32,
    table: u32,
    rest_density: f32,
    viscosity: f32,
    surface_tension: f32,
    surface_threshold: f32,
    gravity: vec4<f32>,
    domain_min: vec4<f32>,
    domain_max: vec4<f32>,
    poly6_grad: f32,
    visc_lap: f32,
    spiky_grad: f32,
    spiky_pressure: u32,
    dt: f32,
    restitution: f32,
    pad0: f32,
    pad1: f32,
};

@group(0) @binding(0) var<uniform> f: Params;
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
