// Semi-implicit Euler (v += a dt, x += v dt), then the boundary (resolve.wgsl):
// sph-core's Integrate and Boundaries processors.
// Expects solver_params.wgsl (struct Params, binding 0 `f`), walls.wgsl and
// resolve.wgsl prepended.

@group(0) @binding(1) var<storage, read_write> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> velocities: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> accelerations: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> obstacles: array<Obstacle>;
// Only `dt` is read: the step chosen by timestep.wgsl (StepState's layout).
struct Step {
    v_max: u32,
    a_max: u32,
    dt: f32,
};
@group(0) @binding(5) var<storage, read> chosen: Step;

@compute @workgroup_size(64)
fn integrate(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let dt = chosen.dt;
    if dt <= 0.0 {
        return;
    }
    let p = positions[i];
    let v = velocities[i].xyz + accelerations[i].xyz * dt;
    let xv = resolve(p.xyz + v * dt, v, f.restitution);
    positions[i] = vec4<f32>(xv[0], p.w);
    velocities[i] = vec4<f32>(xv[1], 0.0);
}
