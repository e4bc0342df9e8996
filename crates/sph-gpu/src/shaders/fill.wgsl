// Hole closing (surfel-extract's `fill::close_holes`, beyond the thesis) as
// compute passes, on the first iteration's refined surfels before they
// split (the kept buffer: `work_out`, counter 1). Each round:
//   fill_prepare → clear_heads → insert_kept → probe
//   → fill_prepare_dedup → clear_heads → insert_candidates → dedup.
// Surfels probe six points 1.2 radii out on their rim; a probe no kept
// surfel covers (loosely: twice the thickness) is taken onto the
// iso-surface by two Newton steps and, if still uncovered and facing the
// camera, is a candidate. A candidate is kept unless a candidate of smaller
// key (a hash of its position: the same choice whatever order the GPU
// appended them in) covers it; the round's new surfels probe in the next.
// Then `split_kept` splits every kept surfel into four for the next
// iteration, or `kept_to_out` makes them the result after one iteration.
// Surfels are found through a hashed grid of cells `fill_cell` wide whose
// buckets hold linked lists (heads swapped in with atomics), built on the
// GPU from counts the CPU never reads.
//
// Expects extract.wgsl (and hash.wgsl) before it.

// Per kept surfel, the next in its bucket's list; per candidate, the same.
@group(0) @binding(16) var<storage, read_write> heads: array<atomic<u32>>;
@group(0) @binding(17) var<storage, read_write> kept_next: array<u32>;
struct Candidate {
    s: Surfel,
    key: vec4<u32>,   // x: the hash that orders candidates
};
@group(0) @binding(18) var<storage, read_write> candidates: array<Candidate>;
@group(0) @binding(19) var<storage, read_write> candidate_next: array<u32>;
// Indirect dispatches: [0..3] the probing surfels, [3..6] the kept ones,
// [6..9] the candidates, [9..12] the split, [12..15] the lone surfels.
@group(0) @binding(20) var<storage, read_write> fill_args: array<u32, 15>;

const EMPTY: u32 = 0xffffffffu;
const KEPT: u32 = 1u;
const PROBE: f32 = 1.2;
const LOOSE: f32 = 2.0;

// The disc's thickness for coverage (surfel-extract's `fill::thickness`).
fn thickness() -> f32 {
    return e.fill_thickness;
}

// Whether q lies on s's disc: within `t` of its plane and its radius of
// its centre in the plane (surfel-extract's `disc_covers`).
fn disc_covers(s: Surfel, q: vec3<f32>, t: f32) -> bool {
    let d = q - s.position_radius.xyz;
    let along = dot(d, s.normal.xyz);
    let across = d - along * s.normal.xyz;
    let r = s.position_radius.w;
    return abs(along) <= t && dot(across, across) <= r * r;
}

fn fill_cell_of(x: vec3<f32>) -> vec3<i32> {
    return cell_at(x, 1.0 / e.fill_cell);
}

// Workgroups of 64 for `count` threads as an (x, y, 1) triple at `at`.
fn set_groups(at: u32, count: u32) {
    let groups = (count + 63u) / 64u;
    let y = max((groups + 65534u) / 65535u, 1u);
    fill_args[at] = (groups + y - 1u) / y;
    fill_args[at + 1u] = y;
    fill_args[at + 2u] = 1u;
}

// With a single iteration the lone particles' spheres, already in the
// result, join the kept surfels first: they probe and cover like the others
// (the CPU closes holes over its whole result then), and `kept_to_out` puts
// them back.
@compute @workgroup_size(1)
fn fill_prepare_lone() {
    set_groups(12u, min(atomicLoad(&counters[OUT]), e.out_capacity));
}

@compute @workgroup_size(64)
fn lone_to_kept(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = flat_index(wid, groups, lid);
    if i >= min(atomicLoad(&counters[OUT]), e.out_capacity) {
        return;
    }
    let at = reserve(KEPT, 1u);
    if at < e.work_capacity {
        work_out[at] = result[i];
    }
}

@compute @workgroup_size(1)
fn lone_reset() {
    atomicStore(&counters[OUT], 0u);
}

// One thread, a round's start: the probing surfels (those added last
// round, all of them in the first), the kept ones to index, no candidates.
@compute @workgroup_size(1)
fn fill_prepare() {
    let end = min(atomicLoad(&counters[KEPT]), e.work_capacity);
    let start = min(atomicLoad(&counters[PROBE_START]), end);
    set_groups(0u, end - start);
    set_groups(3u, end);
    atomicStore(&counters[CANDIDATES], 0u);
}

@compute @workgroup_size(256)
fn clear_heads(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x < e.fill_table {
        atomicStore(&heads[id.x], EMPTY);
    }
}

@compute @workgroup_size(64)
fn insert_kept(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = flat_index(wid, groups, lid);
    if i >= min(atomicLoad(&counters[KEPT]), e.work_capacity) {
        return;
    }
    let b = bucket_of(fill_cell_of(work_out[i].position_radius.xyz), e.fill_table);
    kept_next[i] = atomicExchange(&heads[b], i);
}

// Whether a kept surfel covers q within thickness t.
fn kept_cover(q: vec3<f32>, t: f32) -> bool {
    let c = fill_cell_of(q);
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let b = bucket_of(c + vec3<i32>(dx, dy, dz), e.fill_table);
                var k = atomicLoad(&heads[b]);
                while k != EMPTY {
                    if disc_covers(work_out[k], q, t) {
                        return true;
                    }
                    k = kept_next[k];
                }
            }
        }
    }
    return false;
}

// Six probes around each probing surfel (surfel-extract's `probe`).
@compute @workgroup_size(64)
fn probe(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let end = min(atomicLoad(&counters[KEPT]), e.work_capacity);
    let i = atomicLoad(&counters[PROBE_START]) + flat_index(wid, groups, lid);
    if i >= end {
        return;
    }
    let s = work_out[i];
    let n = s.normal.xyz;
    let t1 = tangent(n);
    let t2 = cross(n, t1);
    let r = s.position_radius.w;
    for (var k = 0u; k < 6u; k++) {
        let angle = 1.0471976 * f32(k);
        let q = s.position_radius.xyz + PROBE * r * (cos(angle) * t1 + sin(angle) * t2);
        if kept_cover(q, LOOSE * thickness()) {
            continue;
        }
        let first = newton(q);
        if first.ok == 0u || kept_cover(first.position, thickness()) {
            continue;
        }
        let second = newton(first.position);
        if second.ok == 0u {
            continue;
        }
        let found = surfel(second.position, second.normal, r);
        if !front_facing(second.position, second.normal) || kept_cover(second.position, thickness()) {
            continue;
        }
        let slot = atomicAdd(&counters[CANDIDATES], 1u);
        if slot < e.fill_capacity {
            let u = bitcast<vec3<u32>>(second.position);
            let key = (u.x * 73856093u) ^ (u.y * 19349663u) ^ (u.z * 83492791u) ^ k;
            candidates[slot] = Candidate(found, vec4<u32>(key, 0u, 0u, 0u));
        } else {
            atomicAdd(&counters[DROPPED], 1u);
        }
    }
}

// One thread: the candidates to index and judge; the next round probes the
// surfels this one adds (those past the kept buffer's present end).
@compute @workgroup_size(1)
fn fill_prepare_dedup() {
    set_groups(6u, min(atomicLoad(&counters[CANDIDATES]), e.fill_capacity));
    atomicStore(&counters[PROBE_START], min(atomicLoad(&counters[KEPT]), e.work_capacity));
}

@compute @workgroup_size(64)
fn insert_candidates(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let j = flat_index(wid, groups, lid);
    if j >= min(atomicLoad(&counters[CANDIDATES]), e.fill_capacity) {
        return;
    }
    let b = bucket_of(fill_cell_of(candidates[j].s.position_radius.xyz), e.fill_table);
    candidate_next[j] = atomicExchange(&heads[b], j);
}

// A candidate joins the kept surfels unless one of smaller key covers it.
@compute @workgroup_size(64)
fn dedup(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let j = flat_index(wid, groups, lid);
    if j >= min(atomicLoad(&counters[CANDIDATES]), e.fill_capacity) {
        return;
    }
    let c = candidates[j];
    let q = c.s.position_radius.xyz;
    let cell = fill_cell_of(q);
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let b = bucket_of(cell + vec3<i32>(dx, dy, dz), e.fill_table);
                var k = atomicLoad(&heads[b]);
                while k != EMPTY {
                    let other = candidates[k];
                    let before = other.key.x < c.key.x || (other.key.x == c.key.x && k < j);
                    if k != j && before && disc_covers(other.s, q, thickness()) {
                        return;
                    }
                    k = candidate_next[k];
                }
            }
        }
    }
    atomicAdd(&counters[FILLED], 1u);
    let at = reserve(KEPT, 1u);
    if at < e.work_capacity {
        work_out[at] = c.s;
    }
}

// One thread, after the rounds: the kept surfels to split (or to output);
// the buffer their children go to starts empty.
@compute @workgroup_size(1)
fn fill_prepare_split() {
    set_groups(9u, min(atomicLoad(&counters[KEPT]), e.work_capacity));
    atomicStore(&counters[0], 0u);
}

// Each kept surfel (here `work_in`) split into work buffer 0.
@compute @workgroup_size(64)
fn split_kept(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = flat_index(wid, groups, lid);
    if i >= min(atomicLoad(&counters[KEPT]), e.work_capacity) {
        return;
    }
    // 3 × 3 where the first iteration chose it (normal.w), the fills 2 × 2.
    let s = work_in[i];
    let cells = select(2u, 3u, s.normal.w != 0.0);
    let at = reserve(0u, cells * cells);
    for (var k = 0u; k < cells * cells; k++) {
        push_work(at + k, split_child(s, k, cells));
    }
}

// After a single iteration: the kept surfels (here `work_in`) are the result.
@compute @workgroup_size(64)
fn kept_to_out(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = flat_index(wid, groups, lid);
    if i >= min(atomicLoad(&counters[KEPT]), e.work_capacity) {
        return;
    }
    var s = work_in[i];
    s.normal.w = 0.0;
    push_out(reserve(OUT, 1u), s);
}
