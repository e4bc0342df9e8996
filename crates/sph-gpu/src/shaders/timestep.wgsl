// The step length on the GPU: sph-core's `World::stable_dt` (acoustic CFL and
// force condition from the largest speed and acceleration) and `World::advance`'s
// landing on the frame time, without a readback. Expects solver_params.wgsl.

struct StepState {
    v_max: atomic<u32>,   // bits of the largest |v| (non-negative floats order as u32)
    a_max: atomic<u32>,   // bits of the largest |a| of the last forces pass
    dt: f32,              // this step's length (0: the frame is done)
    elapsed: f32,         // time advanced in this frame
    steps: u32,           // steps with dt > 0 in this frame
    unstable: u32,        // 1: the stable step fell below min_dt or is NaN
    pad0: u32,
    pad1: u32,
};

@group(0) @binding(1) var<storage, read> velocities: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> accelerations: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> state: StepState;
// The step's indirect workgroup counts (solver.rs, `GpuSolver::gate`): 4 live
// [x, y, z] triples, then the same 4 with the full counts.
@group(0) @binding(4) var<storage, read_write> gate: array<u32, 24>;

// The bits of |v| for an atomic max: non-negative floats order as u32. A
// non-finite length (NaN of either sign, inf) becomes +inf, so a blown-up
// particle makes the stable step 0 and the state unstable, whatever `min`
// does with NaN.
fn magnitude_bits(v: vec3<f32>) -> u32 {
    return min(bitcast<u32>(length(v)) & 0x7fffffffu, 0x7f800000u);
}

var<workgroup> v_bits: array<u32, 64>;
var<workgroup> a_bits: array<u32, 64>;

// The largest |v| and |a| of a workgroup's particles by a tree in workgroup
// memory, then one atomicMax per workgroup: an atomic per particle on the one
// address would serialise them. A max of bits is exact in any order.
@compute @workgroup_size(64)
fn reduce_max(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    var v = 0u;
    var a = 0u;
    if id.x < f.n {
        v = magnitude_bits(velocities[id.x].xyz);
        a = magnitude_bits(accelerations[id.x].xyz);
    }
    v_bits[lid] = v;
    a_bits[lid] = a;
    workgroupBarrier();
    for (var s = 32u; s > 0u; s = s >> 1u) {
        if lid < s {
            v_bits[lid] = max(v_bits[lid], v_bits[lid + s]);
            a_bits[lid] = max(a_bits[lid], a_bits[lid + s]);
        }
        workgroupBarrier();
    }
    if lid == 0u {
        atomicMax(&state.v_max, v_bits[0]);
        atomicMax(&state.a_max, a_bits[0]);
    }
}

@compute @workgroup_size(1)
fn choose_dt() {
    var dt = f.dt;
    if dt <= 0.0 {
        let v = bitcast<f32>(atomicLoad(&state.v_max));
        let a = bitcast<f32>(atomicLoad(&state.a_max));
        var stable = min(f.max_dt, f.cfl * f.h / (f.sound_speed + v));
        if a > 0.0 {
            stable = min(stable, f.force_factor * sqrt(f.h / a));
        }
        if !(stable >= f.min_dt) || state.unstable != 0u {
            state.unstable = 1u;
            stable = 0.0;
        }
        dt = stable;
        if f.frame_dt > 0.0 && dt > 0.0 {
            // Land on the frame time without a sliver step.
            let remaining = f.frame_dt - state.elapsed;
            if remaining <= 0.0 {
                dt = 0.0;
            } else if remaining <= stable {
                dt = remaining;
            } else if remaining < 2.0 * stable {
                dt = 0.5 * remaining;
            }
        }
    }
    atomicStore(&state.v_max, 0u);
    atomicStore(&state.a_max, 0u);
    state.dt = dt;
    // No step (the frame is done or unstable): the step's passes dispatch nothing.
    for (var i = 0u; i < 12u; i += 1u) {
        gate[i] = select(0u, gate[12u + i], dt > 0.0);
    }
    if dt > 0.0 {
        state.elapsed += dt;
        state.steps += 1u;
    }
}
