// Position-based fluids (Macklin & Müller 2013) on the GPU: sph-core's
// `solver::pbf` station by station, one thread per particle. Each entry point
// is one dispatch; a substep is
//   predict → grid build (grid.wgsl) → gather → lists
//   → iterations × (lambda → correct → apply) → curl → confine
//   → (surface_normals → surface_tension, where σ > 0) → boundaries
//   → scatter → reduce,
// and a frame is its substeps recorded back to back, nothing read back.
//
// The particles keep their order in the `home_*` buffers (group 2), which the
// extractor and readbacks see. Inside a substep they work in the grid's cell
// order: `gather` copies them into the working buffers (group 0) sorted by
// cell, so that a cell's particles sit side by side, a warp's threads share
// neighbourhoods and a neighbour list's reads hit the same lines; `scatter`
// copies them home. Lists are neighbour-major (entry k of particle i at
// k n + i), so a warp reading its k-th neighbours reads one run of memory.
// Within a cell the working order is the home order, so every sum runs in the
// order it would over home indices.
//
// Expects hash.wgsl, walls.wgsl, resolve.wgsl and push.wgsl appended (they
// read `f` and `obstacles`).

struct Pbf {
    h: f32,
    inv_h: f32,
    n: u32,
    max_neighbours: u32,
    gravity: vec4<f32>,
    domain_min: vec4<f32>, // w: Boundary::clearance (resolve.wgsl)
    domain_max: vec4<f32>,
    rest_density: f32,
    inv_rho0: f32,
    dt: f32,                // the frame's substep (s)
    omega: f32,             // PbfParams::over_relaxation
    epsilon: f32,           // PbfParams::relaxation / h² (1/m²)
    scorr_k: f32,
    scorr_n: u32,
    inv_w_dq: f32,          // 1 / W_poly6(Δq h)
    vorticity: f32,         // ε of vorticity confinement (m/s)
    xsph: f32,              // XSPH's c
    max_speed: f32,         // PbfParams::max_displacement h / dt
    restitution: f32,
    poly6: f32,             // 315 / (64 π h⁹)
    spiky: f32,             // 45 / (π h⁶)
    w0: f32,                // W_poly6(0)
    max_error: f32,         // pbf::MAX_DENSITY_ERROR
    push_origin: vec4<f32>, // RayPush: a point on the ray, radius in w (0: none)
    push_dir: vec4<f32>,    // its unit direction
    push_accel: vec4<f32>,  // the acceleration on the ray (m/s²)
    table: u32,             // the grid's hash buckets (hash.wgsl)
    gamma: f32,             // Akinci et al.'s γ (0: no surface tension)
    cohesion: f32,          // their cohesion spline's 32 / (π h⁹) × COHESION_WEIGHT
    pad0: u32,
    layers: vec4<f32>,      // the walls' layers under a clearance: spacing, thickness (walls.wgsl)
};

// What a frame's substeps add up; cleared when a frame starts, read back
// after it.
struct Stats {
    error_sum: f32,             // Σ over substeps of the average max(ρ/ρ0 − 1, 0)
    substeps: u32,
    unstable: u32,              // 0; 1: a non-finite state; 2: a solve without headway; 3: a cut list
    unstable_substep: u32,      // the substep (of the frame) it happened in
    first_error: f32,           // the failed solve's largest error, first iteration
    last_error: f32,            // and last
    error_max: atomic<u32>,     // f32 bits of the largest ρ/ρ0 − 1 (≥ 0)
    clamped: atomic<u32>,       // particles the displacement guard slowed
    most_neighbours: atomic<u32>,
    nonfinite: atomic<u32>,
    first_max: atomic<u32>,     // f32 bits of this substep's largest ρ, first iteration
    last_max: atomic<u32>,      // and last
};

@group(0) @binding(0) var<uniform> f: Pbf;
@group(0) @binding(1) var<storage, read_write> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> velocities: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> lists: array<u32>;
@group(0) @binding(4) var<storage, read_write> list_len: array<u32>;
// Each particle's density constraint (pbf.rs `Constraint`): λ and
// D = 1/(Σ|∇C|² + ε), all a neighbour's correction reads of it.
@group(0) @binding(5) var<storage, read_write> lambdas: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read_write> corrections: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> pressures: array<f32>;
@group(0) @binding(8) var<storage, read_write> densities: array<f32>;
@group(0) @binding(9) var<storage, read_write> curls: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read_write> means: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> stats: Stats;
@group(0) @binding(12) var<storage, read> obstacles: array<Obstacle>;
@group(0) @binding(13) var<storage, read_write> partials: array<f32>;
// Each particle's position with m λ / ρ0 in w: the one value per neighbour
// the correction reads (without s_corr).
@group(0) @binding(14) var<storage, read_write> weighted: array<vec4<f32>>;

// The particles in their own order, and the grid built on them: cell order's
// home index of each working slot (`sorted`), each bucket's first slot and
// count. Bound by predict, gather, lists and scatter.
@group(2) @binding(0) var<storage, read_write> home_positions: array<vec4<f32>>;
@group(2) @binding(1) var<storage, read_write> home_velocities: array<vec4<f32>>;
@group(2) @binding(2) var<storage, read_write> home_densities: array<f32>;
@group(2) @binding(3) var<storage, read_write> home_pressures: array<f32>;
@group(2) @binding(4) var<storage, read> sorted: array<u32>;
@group(2) @binding(5) var<storage, read> starts: array<u32>;
@group(2) @binding(6) var<storage, read> counts: array<u32>;

// The gate: the workgroup counts of the frame's dispatches, as [x, y, z]
// triples of four kinds (the grid's hash buckets, particles in 256s, one
// workgroup, particles in 64s): the live ones, which every dispatch but
// `open_gate` and `reduce` reads indirectly, then the full ones. A failed
// substep zeroes the live ones, so the rest of the frame dispatches nothing
// (a blown-up state is not carried through more grid builds); `halted`
// keeps them zero for the solver's life.
@group(1) @binding(0) var<storage, read_write> gate: array<u32, 24>;
@group(1) @binding(1) var<storage, read_write> halted: u32;

// One thread, at a frame's start: the live counts from the full ones, or
// zeros once halted.
@compute @workgroup_size(1)
fn open_gate() {
    for (var k = 0u; k < 12u; k++) {
        gate[k] = select(gate[12u + k], 0u, halted != 0u);
    }
}

// Which iteration a `lambda` pipeline is: bit 0 the first, bit 1 the last
// (the solve's headway is their largest densities).
override HEADWAY: u32 = 0u;

const GROUP: u32 = 64u;

// Particle i's neighbours (itself excluded by the callers), as the lists hold
// them: at most max_neighbours (more are counted in `most_neighbours`).
fn neighbour_count(i: u32) -> u32 {
    return min(list_len[i], f.max_neighbours);
}

fn neighbour(i: u32, k: u32) -> u32 {
    return lists[k * f.n + i];
}

// The spiky gradient's factor s (∇W_ij = s (x_i − x_j)) from r², zero
// beyond h.
fn spiky_factor(r2: f32) -> f32 {
    let len = sqrt(r2);
    let t = max(f.h - len, 0.0);
    return -f.spiky * t * t / max(len, f.h * 1e-6);
}

// W_poly6 and the spiky gradient's factor from r²: pbf.rs
// `LaneKernels::eval`, zero beyond h.
fn kernels(r2: f32) -> vec2<f32> {
    let d = max(f.h * f.h - r2, 0.0);
    return vec2<f32>(f.poly6 * d * d * d, spiky_factor(r2));
}

// A wall's fraction of the poly6 volume beyond it and that fraction's slope,
// at distance d: `WallKernel::fraction_and_density` for poly6.
fn fraction_and_density(d: f32) -> vec2<f32> {
    let u = clamp(d / f.h, 0.0, 1.0);
    let u2 = u * u;
    let g = u * (1.0 + u2 * (-4.0 / 3.0 + u2 * (6.0 / 5.0 + u2 * (-4.0 / 7.0 + u2 / 9.0))));
    let g1 = 1.0 - 4.0 / 3.0 + 6.0 / 5.0 - 4.0 / 7.0 + 1.0 / 9.0;
    let c = 315.0 / 256.0;
    let w = 1.0 - u2;
    let w2 = w * w;
    return vec2<f32>(c * (g1 - g), c / f.h * w2 * w2);
}

// The walls' density over ρ0 at x (in `.w`) and its gradient (`.xyz`): the
// union of the half-spaces within h, 1 − Π_k (1 − f_k) (sph-core's
// `Walls::at`, or `Walls::at_layers` under a clearance; walls beyond the
// eighth are added, as there).
fn walls_at(x: vec3<f32>) -> vec4<f32> {
    var keep: array<f32, 8>;
    var grads: array<vec3<f32>, 8>;
    var count = 0u;
    var extra = vec4<f32>(0.0);
    for (var k = 0u; k < wall_count(); k++) {
        let w = wall(k, x);
        if w.w >= f.h {
            continue;
        }
        let d = max(w.w, 0.0);
        let fd = wall_term(d, fraction_and_density(d));
        let grad = -fd.y * w.xyz;
        if count < 8u {
            keep[count] = 1.0 - fd.x;
            grads[count] = grad;
            count++;
        } else {
            extra += vec4<f32>(grad, fd.x);
        }
    }
    var outside = 1.0;
    for (var k = 0u; k < count; k++) {
        outside *= keep[k];
    }
    var grad = extra.xyz;
    for (var k = 0u; k < count; k++) {
        var others = 1.0;
        for (var l = 0u; l < count; l++) {
            if l != k {
                others *= keep[l];
            }
        }
        grad += others * grads[k];
    }
    return vec4<f32>(grad, 1.0 - outside + extra.w);
}

// Lines 1–4, in home order: v ← v + Δt (g + a push), limited to the guard's
// speed, x* ← x + Δt v, projected out of walls with v following the push
// (pbf.rs `Predict`).
@compute @workgroup_size(64)
fn predict(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let dt = f.dt;
    let p = home_positions[i];
    let a = f.gravity.xyz + push_acceleration(p.xyz);
    var v = home_velocities[i].xyz + a * dt;
    let speed = length(v);
    if speed > f.max_speed {
        v *= f.max_speed / speed;
        atomicAdd(&stats.clamped, 1u);
    }
    let free = p.xyz + v * dt;
    let x = resolve(free, vec3<f32>(0.0), 0.0)[0];
    v += (x - free) / dt;
    home_positions[i] = vec4<f32>(x, p.w);
    home_velocities[i] = vec4<f32>(v, 0.0);
}

// The predicted particles into the working buffers in cell order (slot s
// holds particle sorted[s]). The pressure the solve will sum starts at 0.
@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) id: vec3<u32>) {
    let s = id.x;
    if s >= f.n {
        return;
    }
    let i = sorted[s];
    positions[s] = home_positions[i];
    velocities[s] = home_velocities[i];
    pressures[s] = 0.0;
}

// Every working slot j with |x_s − x_j|² ≤ h² (s included), bucket by bucket
// over the 27 cells around s, in slot order inside a bucket: up to
// max_neighbours kept (neighbour-major), the full count in list_len.
@compute @workgroup_size(64)
fn neighbour_lists(@builtin(global_invocation_id) id: vec3<u32>) {
    let s = id.x;
    if s >= f.n {
        return;
    }
    let x = positions[s].xyz;
    let c = cell_at(x, f.inv_h);
    let h2 = f.h * f.h;
    var len = 0u;
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let cell = c + vec3<i32>(dx, dy, dz);
                let b = bucket_of(cell, f.table);
                let first = starts[b];
                let end = first + counts[b];
                for (var j = first; j < end; j++) {
                    let y = positions[j].xyz;
                    // Buckets are shared by hash collisions: this cell's particles only.
                    if any(cell_at(y, f.inv_h) != cell) {
                        continue;
                    }
                    let d = x - y;
                    if dot(d, d) <= h2 {
                        if len < f.max_neighbours {
                            lists[len * f.n + s] = j;
                        }
                        len += 1u;
                    }
                }
            }
        }
    }
    list_len[s] = len;
}

// The substep's particles home: positions, velocities and the density and
// pressure the extractor and readbacks see.
@compute @workgroup_size(64)
fn scatter(@builtin(global_invocation_id) id: vec3<u32>) {
    let s = id.x;
    if s >= f.n {
        return;
    }
    let i = sorted[s];
    home_positions[i] = positions[s];
    home_velocities[i] = velocities[s];
    home_densities[i] = densities[s];
    home_pressures[i] = pressures[s];
}

// Lines 9–11: ρ_i (walls and the particle itself included), λ_i and D_i.
// Δp_i starts as its own λ's share, λ_i (∇(ρ_wall/ρ0) + (1/ρ0) Σ_j m_j ∇W_ij):
// the sum is ∇_i C_i, summed here already.
@compute @workgroup_size(64)
fn lambda(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let xi = positions[i];
    let walls = walls_at(xi.xyz);
    var rho = 0.0;
    var grad = vec3<f32>(0.0);
    var squares = 0.0;
    let count = neighbour_count(i);
    for (var k = 0u; k < count; k++) {
        let j = neighbour(i, k);
        if j == i {
            continue;
        }
        let y = positions[j];
        let d = xi.xyz - y.xyz;
        let ws = kernels(dot(d, d));
        let g = d * (ws.y * y.w * f.inv_rho0);
        rho += y.w * ws.x;
        grad += g;
        squares += dot(g, g);
    }
    rho = f.rest_density * walls.w + xi.w * f.w0 + rho;
    let grad_i = walls.xyz + grad;
    let error = rho * f.inv_rho0 - 1.0;
    let dd = 1.0 / (dot(grad_i, grad_i) + squares + f.epsilon);
    let lambda = -max(error, 0.0) * dd;
    lambdas[i] = vec2<f32>(lambda, dd);
    weighted[i] = vec4<f32>(xi.xyz, xi.w * f.inv_rho0 * lambda);
    corrections[i] = vec4<f32>(lambda * grad_i, 0.0);
    if (HEADWAY & 1u) != 0u {
        atomicMax(&stats.first_max, bitcast<u32>(max(rho, 0.0)));
        atomicMax(&stats.most_neighbours, list_len[i]);
    }
    if (HEADWAY & 2u) != 0u {
        atomicMax(&stats.last_max, bitcast<u32>(max(rho, 0.0)));
    }
}

// Lines 12–13: Δp_i = (1/ρ0) Σ_j m_j (λ_i + λ_j + s_corr) ∇W_ij plus the
// walls' λ_i ∇(ρ_wall/ρ0): the λ_i share came from `lambda`, this adds λ_j's
// (and s_corr's).
@compute @workgroup_size(64)
fn correct(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let xi = weighted[i].xyz;
    var acc = vec3<f32>(0.0);
    let count = neighbour_count(i);
    if f.scorr_k > 0.0 {
        let di = lambdas[i].y;
        for (var k = 0u; k < count; k++) {
            let j = neighbour(i, k);
            if j == i {
                continue;
            }
            let y = weighted[j];
            let d = xi - y.xyz;
            let ws = kernels(dot(d, d));
            let q = ws.x * f.inv_w_dq;
            var scorr = q;
            for (var e = 1u; e < f.scorr_n; e++) {
                scorr *= q;
            }
            let tensile = -f.scorr_k * scorr * 0.5 * (di + lambdas[j].y);
            acc += d * (ws.y * (y.w + positions[j].w * f.inv_rho0 * tensile));
        }
    } else {
        for (var k = 0u; k < count; k++) {
            let j = neighbour(i, k);
            if j == i {
                continue;
            }
            let y = weighted[j];
            let d = xi - y.xyz;
            acc += d * (spiky_factor(dot(d, d)) * y.w);
        }
    }
    corrections[i] = vec4<f32>(corrections[i].xyz + acc, 0.0);
}

// Moves each particle by ω Δp_i and back out of walls, its velocity by that
// motion over Δt (line 21 kept true), and sums the pressure the solve applied,
// p_i = −ω ρ0 Σ λ_i / Δt².
@compute @workgroup_size(64)
fn apply(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let p = positions[i];
    let dp = f.omega * corrections[i].xyz;
    let free = p.xyz + dp;
    let x = resolve(free, vec3<f32>(0.0), 0.0)[0];
    velocities[i] = vec4<f32>(velocities[i].xyz + (dp + (x - free)) / f.dt, 0.0);
    positions[i] = vec4<f32>(x, p.w);
    pressures[i] += -f.omega * f.rest_density / (f.dt * f.dt) * lambdas[i].x;
}

// Line 22, first pass: the density at the final positions (walls included),
// the curl ω_i = Σ_j (m_j/ρ0)(v_j − v_i) × ∇W_ij with |ω_i|, and XSPH's mean
// Σ_j (m_j/ρ0)(v_j − v_i) W_ij.
@compute @workgroup_size(64)
fn curl(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let xi = positions[i];
    let vi = velocities[i].xyz;
    var rho = 0.0;
    var curl = vec3<f32>(0.0);
    var mean = vec3<f32>(0.0);
    let count = neighbour_count(i);
    for (var k = 0u; k < count; k++) {
        let j = neighbour(i, k);
        if j == i {
            continue;
        }
        let y = positions[j];
        let d = xi.xyz - y.xyz;
        let ws = kernels(dot(d, d));
        let u = velocities[j].xyz - vi;
        let vol = y.w * f.inv_rho0;
        rho += y.w * ws.x;
        curl += cross(u, d * (ws.y * vol));
        mean += u * (vol * ws.x);
    }
    densities[i] = f.rest_density * walls_at(xi.xyz).w + xi.w * f.w0 + rho;
    curls[i] = vec4<f32>(curl, length(curl));
    means[i] = vec4<f32>(mean, 0.0);
}

// Line 22, second pass: η_i = Σ_j (m_j/ρ0)(|ω_j| − |ω_i|) ∇W_ij, then
// v_i += c mean_i + Δt ε (η_i/|η_i|) × ω_i.
@compute @workgroup_size(64)
fn confine(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let ci = curls[i];
    var dv = f.xsph * means[i].xyz;
    if f.vorticity > 0.0 {
        let xi = positions[i].xyz;
        var eta = vec3<f32>(0.0);
        let count = neighbour_count(i);
        for (var k = 0u; k < count; k++) {
            let j = neighbour(i, k);
            if j == i {
                continue;
            }
            let y = positions[j];
            let d = xi - y.xyz;
            let ws = kernels(dot(d, d));
            eta += d * (ws.y * y.w * f.inv_rho0 * (curls[j].w - ci.w));
        }
        let len = length(eta);
        if len > 0.0 && len < 3.0e38 {
            dv += f.dt * f.vorticity * cross(eta / len, ci.xyz);
        }
    }
    velocities[i] = vec4<f32>(velocities[i].xyz + dv, 0.0);
}

// Surface tension (Akinci et al. 2013, sph-core's `surface_tension`), first
// pass: n_i = h Σ_j (m_j/ρ_j) ∇W_poly6(x_i − x_j), with ρ_j the densities
// `curl` left, into `curls` as (n_i, ρ_i) (`confine` has read them).
@compute @workgroup_size(64)
fn surface_normals(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let xi = positions[i].xyz;
    let h2 = f.h * f.h;
    var n = vec3<f32>(0.0);
    let count = neighbour_count(i);
    for (var k = 0u; k < count; k++) {
        let j = neighbour(i, k);
        let y = positions[j];
        let d = xi - y.xyz;
        let t = max(h2 - dot(d, d), 0.0);
        n += d * (-6.0 * f.poly6 * t * t * y.w / densities[j]);
    }
    curls[i] = vec4<f32>(f.h * n, densities[i]);
}

// (h − x)⁺³ x³, the cohesion spline's outer part.
fn cohesion_outer(x: f32) -> f32 {
    let t = max(f.h - x, 0.0);
    return t * t * t * (x * x * x);
}

// Second pass: v_i += Δt a_i, a_i = −γ Σ_j K_ij (m_j C(r) r̂ + n_i − n_j)
// over the pairs within (0, h), K_ij = 2ρ0/(ρ_i + ρ_j), C Akinci's spline.
@compute @workgroup_size(64)
fn surface_tension(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let xi = positions[i].xyz;
    let ni = curls[i];
    let h2 = f.h * f.h;
    let half = 0.5 * f.h;
    let middle = cohesion_outer(half);
    var a = vec3<f32>(0.0);
    let count = neighbour_count(i);
    for (var k = 0u; k < count; k++) {
        let j = neighbour(i, k);
        let y = positions[j];
        let d = xi - y.xyz;
        let r2 = dot(d, d);
        if r2 <= 0.0 || r2 >= h2 {
            continue;
        }
        let r = sqrt(r2);
        let c = f.cohesion * (cohesion_outer(r) + cohesion_outer(min(r, half)) - middle);
        let nj = curls[j];
        let kij = 2.0 * f.rest_density / (ni.w + nj.w);
        a += kij * (d * (y.w * c / r) + ni.xyz - nj.xyz);
    }
    velocities[i] = vec4<f32>(velocities[i].xyz - f.dt * f.gamma * a, 0.0);
}

fn finite(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7f800000u) != 0x7f800000u;
}

var<workgroup> group_sums: array<f32, GROUP>;

// Line 23 and the substep's statistics: the boundary with restitution
// (sph-core's `Boundaries`), a non-finite state flagged, and each workgroup's
// sum of max(ρ/ρ0 − 1, 0) by a fixed tree into `partials`.
@compute @workgroup_size(64)
fn boundaries(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) t: u32,
    @builtin(workgroup_id) group: vec3<u32>,
) {
    let i = id.x;
    var error = 0.0;
    if i < f.n {
        let p = positions[i];
        let xv = resolve(p.xyz, velocities[i].xyz, f.restitution);
        positions[i] = vec4<f32>(xv[0], p.w);
        velocities[i] = vec4<f32>(xv[1], 0.0);
        let e = densities[i] * f.inv_rho0 - 1.0;
        let x = xv[0];
        let v = xv[1];
        if !(finite(x.x) && finite(x.y) && finite(x.z) && finite(v.x) && finite(v.y)
            && finite(v.z) && finite(e)) {
            atomicMax(&stats.nonfinite, 1u);
        }
        error = max(e, 0.0);
        atomicMax(&stats.error_max, bitcast<u32>(error));
    }
    group_sums[t] = error;
    for (var half = GROUP / 2u; half > 0u; half /= 2u) {
        workgroupBarrier();
        if t < half {
            group_sums[t] += group_sums[t + half];
        }
    }
    if t == 0u {
        partials[group.x] = group_sums[0];
    }
}

var<workgroup> reduce_sums: array<f32, 256>;

// The substep's end, one workgroup: its average error (the partials summed in
// a fixed order) added to the frame's, the solve's headway checked as
// `SolveDensity` does (a largest error above max_error at the last iteration
// and no smaller than at the first is a failed solve), its maxima reset; a
// failed substep closes the gate.
@compute @workgroup_size(256)
fn reduce(@builtin(local_invocation_index) t: u32) {
    let groups = (f.n + GROUP - 1u) / GROUP;
    var sum = 0.0;
    for (var g = t; g < groups; g += 256u) {
        sum += partials[g];
    }
    reduce_sums[t] = sum;
    for (var half = 128u; half > 0u; half /= 2u) {
        workgroupBarrier();
        if t < half {
            reduce_sums[t] += reduce_sums[t + half];
        }
    }
    workgroupBarrier();
    if t != 0u || halted != 0u {
        return;
    }
    stats.error_sum += reduce_sums[0] / f32(max(f.n, 1u));
    let first = bitcast<f32>(atomicExchange(&stats.first_max, 0u)) * f.inv_rho0 - 1.0;
    let last = bitcast<f32>(atomicExchange(&stats.last_max, 0u)) * f.inv_rho0 - 1.0;
    if stats.unstable == 0u {
        if atomicLoad(&stats.nonfinite) != 0u || !finite(stats.error_sum) {
            stats.unstable = 1u;
            stats.unstable_substep = stats.substeps;
        } else if last > f.max_error && last >= first {
            stats.unstable = 2u;
            stats.unstable_substep = stats.substeps;
            stats.first_error = first;
            stats.last_error = last;
        } else if atomicLoad(&stats.most_neighbours) > f.max_neighbours {
            // A list was cut: the sums missed neighbours.
            stats.unstable = 3u;
            stats.unstable_substep = stats.substeps;
        }
    }
    stats.substeps += 1u;
    if stats.unstable != 0u {
        // The rest of the frame, and every later one, dispatches nothing.
        halted = 1u;
        for (var k = 0u; k < 12u; k++) {
            gate[k] = 0u;
        }
    }
}
