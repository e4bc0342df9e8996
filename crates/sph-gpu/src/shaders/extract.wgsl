// Surfel extraction (Vesterlund 2004, 4.2.1) as compute passes: the colour
// field c(x) = sum_j V_j W_poly6(x - x_j) through the GPU grid, the initial
// guess from the particles, then Newton-Raphson refinement (eq. 33) with
// splitting. The same equations, thresholds and order of decisions as
// surfel-extract's thesis mode; surfels are appended to buffers with atomic
// counters, in the splat renderer's layout, and drawn indirectly.
//
// With `anisotropic` set the field is Yu & Turk's, as surfel-extract's
// Surface::Anisotropic makes it: positions are the kernel centres and each
// kernel is det(G_j) W_poly6(|G_j (x - x_j)|) (`kernels`, anisotropy.wgsl),
// and the guess and refinement follow the CPU's anisotropic path: crossings
// bracketed along a line where the isotropic field takes one Newton step,
// droplets of isolated kernels seeded on their spheres, lone particles
// drawn as 400 surfels.

struct Extract {
    h: f32,
    inv_h: f32,
    n: u32,
    table: u32,
    iso: f32,
    interior_step: f32,       // x h
    discard_step: f32,        // x h
    split_laplacian: f32,     // |lap c| h^2 above this splits an initial surfel
    covariance_threshold: f32,
    all_around: u32,          // 6 or 8
    radius: f32,              // x h
    has_camera: u32,
    camera: vec4<f32>,
    poly6: f32,               // 315 / (64 pi h^9)
    poly6_grad: f32,          // 945 / (32 pi h^9)
    work_capacity: u32,
    out_capacity: u32,
    anisotropic: u32,         // 1: Yu & Turk's field (`kernels`)
    fill_cell: f32,           // hole closing's surfel grid: cell size (m)
    fill_table: u32,          // and its hash buckets (fill.wgsl)
    first_split: u32,         // cells along a side of the first split: 2 or 3
    fill_capacity: u32,       // hole closing's candidates buffer (fill.wgsl)
    fill_thickness: f32,      // and its discs' thickness (m)
    pad1: u32,
    pad2: u32,
};

// Which counters a refinement iteration reads and appends to.
struct Stage {
    src: u32,
    dst: u32,
    last: u32,
    iteration: u32,
    keep: u32,       // 1: the refined surfels themselves to dst (before hole closing)
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

// A surfel, laid out as splat-render's splats: centre and radius, normal.
struct Surfel {
    position_radius: vec4<f32>,
    normal: vec4<f32>,
};

// counters[0], [1]: the two work buffers; [2]: output; then statistics.
const OUT: u32 = 2u;
const SURFACE_PARTICLES: u32 = 3u;
const ALL_AROUND: u32 = 4u;
const LONE: u32 = 5u;
const DISCARDED: u32 = 6u;
const EVALUATED: u32 = 7u;     // 7, 8, 9: surfels refined in iteration 0, 1, 2
const DROPPED: u32 = 10u;      // surfels that did not fit a buffer
const DROPLETS: u32 = 11u;     // particles of droplets of isolated kernels
const FILLED: u32 = 12u;       // surfels hole closing added
const CANDIDATES: u32 = 13u;   // hole closing's candidates this round
const PROBE_START: u32 = 14u;  // the first surfel of the kept buffer that probes

@group(0) @binding(0) var<uniform> e: Extract;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read> starts: array<u32>;
@group(0) @binding(4) var<storage, read> sorted: array<u32>;
@group(0) @binding(5) var<storage, read> volumes: array<f32>;
@group(0) @binding(6) var<storage, read_write> counters: array<atomic<u32>, 16>;
@group(0) @binding(7) var<storage, read> work_in: array<Surfel>;
@group(0) @binding(8) var<storage, read_write> work_out: array<Surfel>;
@group(0) @binding(9) var<storage, read_write> result: array<Surfel>;
@group(0) @binding(10) var<uniform> stage: Stage;
@group(0) @binding(11) var<storage, read_write> dispatch_args: array<u32, 3>;
@group(0) @binding(12) var<storage, read_write> draw_args: array<u32, 4>;

// One particle's anisotropic kernel (anisotropy.wgsl): G² as xx, xy, xz, yy
// in `a`, yz, zz in `b.xy`; det G in `b.z`; 1 in `b.w` for an isolated
// particle's sphere.
struct Kernel {
    a: vec4<f32>,
    b: vec4<f32>,
};
@group(0) @binding(15) var<storage, read> kernels: array<Kernel>;

struct Field {
    c: f32,
    gradient: vec3<f32>,
    laplacian: f32,
};

// Accumulates neighbour j at offset d = x - x_j, |d|^2 = r2 <= h^2.
fn add(f: ptr<function, Field>, j: u32, d: vec3<f32>, r2: f32) {
    let v = volumes[j];
    if e.anisotropic != 0u {
        // t = h² − dᵀ M d with M = G²: c = a t³, ∇c = −6 a t² M d,
        // ∇²c = a (24 t |M d|² − 6 t² tr M), a = V det G k_poly6
        // (surfel-extract's `ellipsoid_sums`).
        let k = kernels[j];
        let md = vec3<f32>(
            k.a.x * d.x + k.a.y * d.y + k.a.z * d.z,
            k.a.y * d.x + k.a.w * d.y + k.b.x * d.z,
            k.a.z * d.x + k.b.x * d.y + k.b.y * d.z,
        );
        let t = max(e.h * e.h - dot(d, md), 0.0);
        let at = v * k.b.z * e.poly6 * t;
        let at2 = at * t;
        (*f).c += at2 * t;
        (*f).gradient += (-6.0 * at2) * md;
        (*f).laplacian += at * (24.0 * dot(md, md)) - 6.0 * at2 * (k.a.x + k.a.w + k.b.y);
        return;
    }
    let q = e.h * e.h - r2;
    (*f).c += v * e.poly6 * q * q * q;
    (*f).gradient += v * (-e.poly6_grad * q * q) * d;
    (*f).laplacian += v * e.poly6_grad * q * (7.0 * r2 - 3.0 * e.h * e.h);
}

// The field at x and the covariance of the neighbourhood within h (eq. 35,
// offsets in units of h) from one scan: one evaluation. `refine` uses the
// field only (the compiler drops the unused sums).
struct Scan {
    field: Field,
    diagonal: vec3<f32>,  // xx, yy, zz
    off: vec3<f32>,       // xy, xz, yz
    hits: u32,            // particles within h, x's own included
};

fn scan(x: vec3<f32>) -> Scan {
    var f = Field(0.0, vec3<f32>(0.0), 0.0);
    var diagonal = vec3<f32>(0.0);
    var off = vec3<f32>(0.0);
    var hits = 0u;
    let c = cell_at(x, e.inv_h);
    let h2 = e.h * e.h;
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let cell = c + vec3<i32>(dx, dy, dz);
                let b = bucket_of(cell, e.table);
                let first = starts[b];
                for (var k = 0u; k < counts[b]; k++) {
                    let j = sorted[first + k];
                    let y = positions[j].xyz;
                    if any(cell_at(y, e.inv_h) != cell) {
                        continue;
                    }
                    let d = x - y;
                    let r2 = dot(d, d);
                    if r2 <= h2 {
                        add(&f, j, d, r2);
                        let u = d * e.inv_h;
                        diagonal += u * u;
                        off += u.xxy * u.yzz;
                        hits++;
                    }
                }
            }
        }
    }
    return Scan(f, diagonal, off, hits);
}

// The field's value alone at x (one evaluation; the scan's other sums are
// a few multiply-adds beside its loads).
fn value_at(x: vec3<f32>) -> f32 {
    return scan(x).field.c;
}

// Where c crosses iso along x + t n, |t| ≤ reach, on the side c(x) = c0
// says (t > 0 when c0 > iso): regula falsi (Illinois) from the bracket
// [0, ±reach] until |c − iso| ≤ tolerance, at most 6 steps (surfel-extract's
// `crossing`). `.y` is 0 when c is still on c0's side at reach.
fn crossing(x: vec3<f32>, c0: f32, n: vec3<f32>, reach: f32, tolerance: f32) -> vec2<f32> {
    let side = select(-1.0, 1.0, c0 >= e.iso);
    var a = 0.0;
    var fa = c0 - e.iso;
    var b = side * reach;
    var fb = value_at(x + b * n) - e.iso;
    if fb * fa > 0.0 {
        return vec2<f32>(0.0, 0.0);
    }
    var last = 0;
    for (var step = 0; step < 6; step++) {
        var t = 0.5 * (a + b);
        if fa != fb {
            t = b - fb * (b - a) / (fb - fa);
        }
        let ft = value_at(x + t * n) - e.iso;
        if abs(ft) <= tolerance {
            return vec2<f32>(t, 1.0);
        }
        if (ft > 0.0) == (fa > 0.0) {
            a = t;
            fa = ft;
            if last == -1 {
                fb *= 0.5;
            }
            last = -1;
        } else {
            b = t;
            fb = ft;
            if last == 1 {
                fa *= 0.5;
            }
            last = 1;
        }
    }
    return vec2<f32>(select(b, a, abs(fa) < abs(fb)), 1.0);
}

// How close to iso the guess's crossings stop (surfel-extract's
// GUESS_TOLERANCE).
const GUESS_TOLERANCE: f32 = 1e-3;

// The distance from particle i, alone, at which its kernel reaches iso (an
// anisotropic kernel's sphere scaled by det G), or a negative value if it
// never does (surfel-extract's `lone_radius`).
fn lone_radius(i: u32) -> f32 {
    let h2 = e.h * e.h;
    var volume = volumes[i];
    var scale = 1.0;
    if e.anisotropic != 0u {
        let det = kernels[i].b.z;
        volume *= det;
        scale = 1.0 / pow(det, 1.0 / 3.0);
    }
    let d = pow(e.iso / (volume * e.poly6), 1.0 / 3.0);
    if !(e.iso > 0.0 && d < h2) {
        return -1.0;
    }
    return scale * sqrt(h2 - d);
}

// Direction k of `count` spread evenly over the sphere (a Fibonacci lattice).
fn sphere_direction(k: u32, count: u32) -> vec3<f32> {
    let z = 1.0 - f32(2u * k + 1u) / f32(count);
    let r = sqrt(max(1.0 - z * z, 0.0));
    let phi = 2.3999632 * f32(k);
    return vec3<f32>(r * cos(phi), z, r * sin(phi));
}

// Surfel k of `count` on the sphere of `radius` about x: discs that overlap
// (1.3 × the radius of the cap each owns), sunk by a quarter of their rim's
// rise (surfel-extract's `sphere_surfels`).
fn sphere_surfel(x: vec3<f32>, radius: f32, k: u32, count: u32) -> Surfel {
    let disc = 1.3 * radius * sqrt(4.0 / f32(count));
    let sunk = radius - 0.125 * disc * disc / radius;
    let d = sphere_direction(k, count);
    return surfel(x + sunk * d, d, disc);
}

// The front-facing surfels of the sphere of `radius` about x from `count`
// directions, appended to buffer `slot` (0: work, OUT: final).
fn push_sphere(x: vec3<f32>, radius: f32, count: u32, slot: u32) {
    var keep = 0u;
    for (var k = 0u; k < count; k++) {
        let s = sphere_surfel(x, radius, k, count);
        keep += u32(front_facing(s.position_radius.xyz, s.normal.xyz));
    }
    var at = reserve(slot, keep);
    for (var k = 0u; k < count; k++) {
        let s = sphere_surfel(x, radius, k, count);
        if front_facing(s.position_radius.xyz, s.normal.xyz) {
            if slot == OUT {
                push_out(at, s);
            } else {
                push_work(at, s);
            }
            at++;
        }
    }
}

// The thread's index in a dispatch of up to 65535 x 65535 groups of 64.
fn flat_index(wid: vec3<u32>, groups: vec3<u32>, lid: u32) -> u32 {
    return (wid.y * groups.x + wid.x) * 64u + lid;
}

fn front_facing(p: vec3<f32>, n: vec3<f32>) -> bool {
    return e.has_camera == 0u || dot(e.camera.xyz - p, n) > 0.0;
}

fn surfel(p: vec3<f32>, n: vec3<f32>, r: f32) -> Surfel {
    return Surfel(vec4<f32>(p, r), vec4<f32>(n, 0.0));
}

// Two unit vectors spanning the plane normal to n (surfel-extract's basis).
fn tangent(n: vec3<f32>) -> vec3<f32> {
    var helper = vec3<f32>(0.0, 1.0, 0.0);
    if abs(n.x) < 0.6 {
        helper = vec3<f32>(1.0, 0.0, 0.0);
    }
    return normalize(cross(n, helper));
}

// Child k (0..3) of the four covering s in its tangent plane (figure 6).
fn child(s: Surfel, k: u32) -> Surfel {
    return split_child(s, k, 2u);
}

// Child k (0..n²) of the n × n covering s in its tangent plane: the disc's
// bounding square cut into cells, each child wide enough to cover its
// cell's corners, 5 % over (surfel-extract's `split`).
fn split_child(s: Surfel, k: u32, n: u32) -> Surfel {
    let normal = s.normal.xyz;
    let t1 = tangent(normal);
    let t2 = cross(normal, t1);
    let r = s.position_radius.w;
    let cells = f32(n);
    let u = (cells - 1.0 - 2.0 * f32(k % n)) / cells;
    let v = (cells - 1.0 - 2.0 * f32(k / n)) / cells;
    let p = s.position_radius.xyz + r * (u * t1 + v * t2);
    return surfel(p, normal, r * (1.4142135 / cells) * 1.05);
}

// Box faces (0..5) then corners (6..13).
fn box_direction(k: u32) -> vec3<f32> {
    if k < 6u {
        var d = vec3<f32>(0.0);
        d[k / 2u] = select(1.0, -1.0, (k & 1u) == 1u);
        return d;
    }
    let c = k - 6u;
    let s = 0.57735026;
    return vec3<f32>(
        select(s, -s, (c & 1u) != 0u),
        select(s, -s, (c & 2u) != 0u),
        select(s, -s, (c & 4u) != 0u),
    );
}

// Reserves `count` slots of buffer `slot` (0, 1: work; 2: output); returns the first.
fn reserve(slot: u32, count: u32) -> u32 {
    let base = atomicAdd(&counters[slot], count);
    let capacity = select(e.work_capacity, e.out_capacity, slot == OUT);
    let fit = min(base + count, max(capacity, base)) - base;
    if fit < count {
        atomicAdd(&counters[DROPPED], count - fit);
    }
    return base;
}

fn push_work(at: u32, s: Surfel) {
    if at < e.work_capacity {
        work_out[at] = s;
    }
}

fn push_out(at: u32, s: Surfel) {
    if at < e.out_capacity {
        result[at] = s;
    }
}

// The initial guess (4.2.1) at particle i, appended to work buffer 0 (through
// dst) or, for a lone particle's final iso-sphere, to the output.
@compute @workgroup_size(64)
fn guess(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    // Particles in the grid's cell order (thread k takes sorted[k]): a
    // warp's particles share their neighbourhoods.
    let k = flat_index(wid, groups, lid);
    if k >= e.n {
        return;
    }
    let i = sorted[k];
    let x = positions[i].xyz;
    let h = e.h;
    let h2 = h * h;
    let at = scan(x);
    let f = at.field;
    if at.hits <= 1u {
        // Alone: the analytic iso-sphere V W(R) = iso, final as it is.
        let radius = lone_radius(i);
        if radius < 0.0 {
            return;
        }
        atomicAdd(&counters[LONE], 1u);
        if e.anisotropic != 0u {
            push_sphere(x, radius, 400u, OUT);
            return;
        }
        var keep = 0u;
        for (var k = 0u; k < 14u; k++) {
            let n = box_direction(k);
            keep += u32(front_facing(x + radius * n, n));
        }
        var at = reserve(OUT, keep);
        for (var k = 0u; k < 14u; k++) {
            let n = box_direction(k);
            if front_facing(x + radius * n, n) {
                push_out(at, surfel(x + radius * n, n, 0.8 * radius));
                at++;
            }
        }
        return;
    }
    // A particle of a droplet too small for anisotropic kernels: seeds on
    // its sphere, refined like the others.
    if e.anisotropic != 0u && kernels[i].b.w != 0.0 {
        let radius = lone_radius(i);
        if radius >= 0.0 {
            atomicAdd(&counters[DROPLETS], 1u);
            push_sphere(x, radius, 100u, 0u);
            return;
        }
    }
    // Surface on several sides (eq. 36): P = det C / (tr C / 3)^3.
    let xx = at.diagonal.x;
    let yy = at.diagonal.y;
    let zz = at.diagonal.z;
    let xy = at.off.x;
    let xz = at.off.y;
    let yz = at.off.z;
    let trace = xx + yy + zz;
    let det = xx * (yy * zz - yz * yz) - xy * (xy * zz - yz * xz) + xz * (xy * yz - yy * xz);
    var shape = 0.0;
    if trace > 0.0 {
        let t = trace / 3.0;
        shape = det / (t * t * t);
    }
    if shape < e.covariance_threshold {
        atomicAdd(&counters[ALL_AROUND], 1u);
        let first = select(6u, 0u, e.all_around == 6u);
        if e.anisotropic != 0u {
            // Each surfel where c crosses iso along its direction, if it
            // does within reach.
            var found: array<f32, 8>;
            var keep = 0u;
            for (var k = 0u; k < e.all_around; k++) {
                let n = box_direction(first + k);
                let t = crossing(x, f.c, n, e.interior_step * h, GUESS_TOLERANCE);
                found[k] = select(-1.0, t.x, t.y != 0.0 && t.x > 0.0);
                if found[k] > 0.0 && front_facing(x + found[k] * n, n) {
                    keep++;
                }
            }
            var at = reserve(0u, keep);
            for (var k = 0u; k < e.all_around; k++) {
                let n = box_direction(first + k);
                if found[k] > 0.0 && front_facing(x + found[k] * n, n) {
                    push_work(at, surfel(x + found[k] * n, n, e.radius * h));
                    at++;
                }
            }
            return;
        }
        var keep = 0u;
        for (var k = first; k < first + e.all_around; k++) {
            let n = box_direction(k);
            keep += u32(front_facing(x + 0.5 * h * n, n));
        }
        var at = reserve(0u, keep);
        for (var k = first; k < first + e.all_around; k++) {
            let n = box_direction(k);
            if front_facing(x + 0.5 * h * n, n) {
                push_work(at, surfel(x + 0.5 * h * n, n, e.radius * h));
                at++;
            }
        }
        return;
    }
    let g = length(f.gradient);
    if !(g > 1e-6 / h) {
        return;
    }
    let normal = -f.gradient / g;
    var nr = (f.c - e.iso) / g;
    if e.anisotropic != 0u {
        // Thin kernels make c peak near a surface particle and fall
        // steeply beyond it: the crossing is bracketed along the normal.
        let t = crossing(x, f.c, normal, e.interior_step * h, GUESS_TOLERANCE);
        if t.y == 0.0 {
            return;
        }
        nr = t.x;
    }
    if abs(nr) > e.interior_step * h {
        return;
    }
    atomicAdd(&counters[SURFACE_PARTICLES], 1u);
    let s = surfel(x + normal * clamp(nr, -0.5 * h, 0.5 * h), normal, e.radius * h);
    if abs(f.laplacian) * h2 > e.split_laplacian {
        var keep = 0u;
        for (var k = 0u; k < 4u; k++) {
            let q = child(s, k);
            keep += u32(front_facing(q.position_radius.xyz, normal));
        }
        var at = reserve(0u, keep);
        for (var k = 0u; k < 4u; k++) {
            let q = child(s, k);
            if front_facing(q.position_radius.xyz, normal) {
                push_work(at, q);
                at++;
            }
        }
    } else if front_facing(s.position_radius.xyz, normal) {
        push_work(reserve(0u, 1u), s);
    }
}

// One thread: the groups for this iteration's surfels, an empty buffer to
// append to, and the count refined.
@compute @workgroup_size(1)
fn prepare() {
    let count = atomicLoad(&counters[stage.src]);
    let n = min(count, e.work_capacity);
    let groups = (n + 63u) / 64u;
    let y = max((groups + 65534u) / 65535u, 1u);
    dispatch_args[0] = (groups + y - 1u) / y;
    dispatch_args[1] = y;
    dispatch_args[2] = 1u;
    if stage.last == 0u {
        atomicStore(&counters[stage.dst], 0u);
    }
    atomicStore(&counters[EVALUATED + stage.iteration], n);
}

// Where one Newton-Raphson step (eq. 33) from x goes, and the outward normal
// −∇c/|∇c| where it starts; `ok` 0 when the gradient vanishes or the step
// is longer than the discard step (surfel-extract's `newton_step`: on the
// anisotropic field a longer step is replaced by the crossing along the
// normal within reach, a safeguarded Newton step).
struct Step {
    position: vec3<f32>,
    ok: u32,
    normal: vec3<f32>,
    bend: f32,   // |∇²c|/|∇c| where it starts: the summed curvatures
};

fn newton(x: vec3<f32>) -> Step {
    var out: Step;
    out.ok = 0u;
    let f = scan(x).field;
    let g2 = dot(f.gradient, f.gradient);
    if !(g2 > 1e-12 * e.inv_h * e.inv_h) {
        return out;
    }
    var nr = -(f.c - e.iso) * f.gradient / g2;
    let n = -f.gradient / sqrt(g2);
    if !(length(nr) <= e.discard_step * e.h) {
        if e.anisotropic == 0u || !(length(nr) < 3.0e38) {
            return out;
        }
        let t = crossing(x, f.c, n, e.discard_step * e.h, 0.0);
        if t.y == 0.0 {
            return out;
        }
        nr = t.x * n;
    }
    out.position = x + nr;
    out.normal = n;
    out.bend = abs(f.laplacian) / sqrt(g2);
    out.ok = 1u;
    return out;
}

// One Newton-Raphson step (eq. 33) per surfel of the source buffer; too long a
// step discards it; the rest are split in four (appended to dst) or, in the
// last iteration, appended to the output.
@compute @workgroup_size(64)
fn refine(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = flat_index(wid, groups, lid);
    if i >= min(atomicLoad(&counters[stage.src]), e.work_capacity) {
        return;
    }
    let s = work_in[i];
    let step = newton(s.position_radius.xyz);
    if step.ok == 0u {
        atomicAdd(&counters[DISCARDED], 1u);
        return;
    }
    let p = step.position;
    let n = step.normal;
    if !front_facing(p, n) {
        return;
    }
    var refined = surfel(p, n, s.position_radius.w);
    if stage.last != 0u {
        push_out(reserve(OUT, 1u), refined);
        return;
    }
    // The first split 3 × 3 unless the surface curves away from the tangent
    // plane at its corner children (√2 · 2/3 r out) by more than a step
    // (surfel-extract's `corner_distance` and `Step::sag`).
    var cells = 2u;
    if stage.iteration == 0u && e.first_split == 3u {
        let corner = 0.94280904 * s.position_radius.w;
        cells = select(3u, 2u, 0.5 * step.bend * corner * corner > e.discard_step * e.h);
    }
    if stage.keep != 0u {
        // Held for hole closing, which splits it as chosen here (normal.w).
        refined.normal.w = select(0.0, 1.0, cells == 3u);
        push_work(reserve(stage.dst, 1u), refined);
        return;
    }
    let at = reserve(stage.dst, cells * cells);
    for (var k = 0u; k < cells * cells; k++) {
        push_work(at + k, split_child(refined, k, cells));
    }
}

// One thread: the indirect draw of the output (4 vertices per splat).
@compute @workgroup_size(1)
fn finish() {
    draw_args[0] = 4u;
    draw_args[1] = min(atomicLoad(&counters[OUT]), e.out_capacity);
    draw_args[2] = 0u;
    draw_args[3] = 0u;
}

@group(0) @binding(13) var<storage, read> densities: array<f32>;
@group(0) @binding(14) var<storage, read_write> volumes_out: array<f32>;

// V = m / rho from a solver's masses (positions' w) and densities.
@compute @workgroup_size(64)
fn volumes_from_densities(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = flat_index(wid, groups, lid);
    if i < e.n {
        volumes_out[i] = positions[i].w / densities[i];
    }
}
