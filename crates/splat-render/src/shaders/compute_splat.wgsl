// Compute splatting: the visibility and attribute passes of splat.wgsl
// without the raster hardware (renderer/compute.rs). Splats are binned to
// 8×8-pixel tiles by a counting sort (count, scan, scatter); each work
// item is one tile and at most CHUNK of its splats, so a dense tile is split
// over several workgroups. A workgroup loads its splats into workgroup
// memory and each thread tests its own pixel against them all:
// - visibility: the nearest splat depth, pushed back by epsilon, min'd with
//   the scene's depth by an integer atomicMin (depths in 0..1 order as their
//   bits);
// - attributes: w (n, 1) for the splats within it, summed in registers and
//   added to the pixel's sums once per work item, by compare-and-swap on
//   the floats' bits (a dense tile's work items add in any order, as the
//   raster hardware blends in its own).
// When the lists outgrow their buffer (the renderer reads the total back
// and grows it for the next frame), the frame is still drawn whole: a splat
// that did not fit in one of its tiles' lists is flagged, skipped there,
// and listed apart; every tile then also runs over that list in chunks.
// The depth and sums stay in their buffers, which the shade pass reads
// (shade_buffers.wgsl).

const TILE: u32 = 8u;
// The list sums saturate here: a frame whose lists would pass 2^31 entries
// (far past any binding's capacity) reads back CAP, and its cursors, which
// start at most at CAP and grow by at most the splat count, never wrap.
const CAP: u32 = 0x80000000u;
const CHUNK: u32 = 64u;
// Largest workgroup count per dispatch dimension.
const ROW: u32 = 65535u;

@group(0) @binding(1) var<storage, read> splats: array<Splat>;
// Tiles across, tiles down, entry capacity, splats the buffer holds.
@group(0) @binding(2) var<uniform> setup: vec4<u32>;
// DrawIndirectArgs: the splat count is the instance count.
@group(0) @binding(3) var<storage, read> draw_args: array<u32>;
// Each splat's pixels (x0, y0, x1, y1), empty (x0 > x1) when it is dropped;
// x0 is stored as -x0 - 1 when the splat overflowed the lists. After the
// splats' (from index setup.w), the splats that overflowed, in .x.
@group(0) @binding(4) var<storage, read_write> rects: array<vec4<i32>>;
// [0] entries, [1] work items, [2] splats that overflowed the lists; then
// per tile its count, the first entry (tiles + 1), the first work item
// (tiles + 1) and the scatter's cursor.
@group(0) @binding(5) var<storage, read_write> tiles: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> entries: array<u32>;
@group(0) @binding(7) var<storage, read_write> depth_bits: array<atomic<u32>>;
@group(0) @binding(8) var<storage, read_write> accum: array<atomic<u32>>;
@group(0) @binding(9) var scene_depth: texture_depth_2d;
// The work items' indirect dispatch, the entries and work items again (read
// back to size the entries), then the overflow's work items' dispatch (from
// word 8).
@group(1) @binding(0) var<storage, read_write> dispatch: array<u32>;

const HEAD: u32 = 3u;

fn tile_count() -> u32 {
    return setup.x * setup.y;
}
fn counts_at() -> u32 {
    return HEAD;
}
fn starts_at() -> u32 {
    return HEAD + tile_count();
}
fn items_at() -> u32 {
    return HEAD + 2u * tile_count() + 1u;
}
fn cursors_at() -> u32 {
    return HEAD + 3u * tile_count() + 2u;
}

fn screen() -> vec2<u32> {
    return vec2<u32>(frame.viewport.xy);
}

// The scene's depth into the visibility depth; the sums cleared.
@compute @workgroup_size(8, 8)
fn cs_clear(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = screen();
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let p = id.y * size.x + id.x;
    atomicStore(&depth_bits[p], bitcast<u32>(max(textureLoad(scene_depth, vec2<i32>(id.xy), 0), 0.0)));
    for (var k = 0u; k < 4u; k++) {
        atomicStore(&accum[4u * p + k], 0u);
    }
}

// The tiles a pixel rectangle covers (empty stays empty).
fn tiles_of(pixels: vec4<i32>) -> vec4<i32> {
    if pixels.x > pixels.z {
        return pixels;
    }
    return pixels / i32(TILE);
}

fn splat_index(id: vec3<u32>) -> u32 {
    return id.x + id.y * ROW * 256u;
}

// Each splat's tiles, as the raster path's quad covers them (splat_quad in
// splat.wgsl: dropped when a corner is in front of the near plane or, with
// culling, when it faces away), counted per tile.
@compute @workgroup_size(256)
fn cs_bin(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = splat_index(id);
    if i >= min(draw_args[1], setup.w) {
        return;
    }
    let s = splats[i];
    let r = s.position_radius.w;
    let c = (frame.view * vec4<f32>(s.position_radius.xyz, 1.0)).xyz;
    let n = (frame.view * vec4<f32>(s.normal.xyz, 0.0)).xyz;
    let axes = disc_axes(n, r);
    let u = axes[0];
    let v = axes[1];
    let size = vec2<f32>(frame.viewport.xy);
    var lo = vec2<f32>(3.0e38);
    var hi = vec2<f32>(-3.0e38);
    var clipped = false;
    for (var k = 0u; k < 4u; k++) {
        let su = select(-1.0, 1.0, (k & 1u) != 0u);
        let sv = select(-1.0, 1.0, (k & 2u) != 0u);
        let p = c + su * u + sv * v;
        if -p.z < frame.ray.z {
            clipped = true;
        }
        let clip = frame.proj * vec4<f32>(p, 1.0);
        let ndc = clip.xy / clip.w;
        let px = vec2<f32>((ndc.x * 0.5 + 0.5) * size.x, (0.5 - ndc.y * 0.5) * size.y);
        lo = min(lo, px);
        hi = max(hi, px);
    }
    let culled = frame.flags.x > 0.5 && dot(n, c) >= 0.0;
    var pixels = vec4<i32>(0, 0, -1, -1);
    if !clipped && !culled && hi.x >= 0.0 && hi.y >= 0.0 && lo.x < size.x && lo.y < size.y {
        let last = vec2<f32>(size) - 1.0;
        let p0 = vec2<i32>(clamp(floor(lo), vec2<f32>(0.0), last));
        let p1 = vec2<i32>(clamp(floor(hi), vec2<f32>(0.0), last));
        pixels = vec4<i32>(p0, p1);
    }
    rects[i] = pixels;
    let rect = tiles_of(pixels);
    for (var ty = rect.y; ty <= rect.w; ty++) {
        for (var tx = rect.x; tx <= rect.z; tx++) {
            atomicAdd(&tiles[counts_at() + u32(ty) * setup.x + u32(tx)], 1u);
        }
    }
}

var<workgroup> partial: array<vec2<u32>, 256>;

// One workgroup: each tile's first entry and first work item (exclusive
// prefix sums of the counts and of ceil(count / CHUNK)), the cursors, the
// totals and the work items' dispatch.
// a + b, or CAP where that reaches it (a and b at most CAP).
fn sat_add(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    return select(a + b, vec2<u32>(CAP), b >= vec2<u32>(CAP) - a);
}

@compute @workgroup_size(256)
fn cs_scan(@builtin(local_invocation_index) li: u32) {
    let t = tile_count();
    let per = (t + 255u) / 256u;
    let first = min(li * per, t);
    let last = min(first + per, t);
    var sum = vec2<u32>(0u);
    for (var k = first; k < last; k++) {
        let c = atomicLoad(&tiles[counts_at() + k]);
        sum = sat_add(sum, vec2<u32>(c, (c + CHUNK - 1u) / CHUNK));
    }
    partial[li] = sum;
    workgroupBarrier();
    // Hillis-Steele inclusive scan of the 256 partial sums.
    for (var step = 1u; step < 256u; step *= 2u) {
        var add = vec2<u32>(0u);
        if li >= step {
            add = partial[li - step];
        }
        workgroupBarrier();
        partial[li] = sat_add(partial[li], add);
        workgroupBarrier();
    }
    var run = vec2<u32>(0u);
    if li > 0u {
        run = partial[li - 1u];
    }
    for (var k = first; k < last; k++) {
        let c = atomicLoad(&tiles[counts_at() + k]);
        atomicStore(&tiles[starts_at() + k], run.x);
        atomicStore(&tiles[cursors_at() + k], run.x);
        atomicStore(&tiles[items_at() + k], run.y);
        run = sat_add(run, vec2<u32>(c, (c + CHUNK - 1u) / CHUNK));
    }
    if li == 255u {
        let total = partial[255];
        atomicStore(&tiles[starts_at() + t], total.x);
        atomicStore(&tiles[items_at() + t], total.y);
        let items = total.y;
        atomicStore(&tiles[0], total.x);
        atomicStore(&tiles[1], items);
        // Work items past the capacity's load nothing: at most a chunk
        // per CHUNK entries, plus one partial chunk per tile, do work.
        let working = min(items, (setup.z + CHUNK - 1u) / CHUNK + t);
        dispatch[0] = min(working, ROW);
        dispatch[1] = (working + ROW - 1u) / ROW;
        dispatch[2] = 1u;
        dispatch[3] = total.x;
        dispatch[4] = items;
    }
}

// Each splat into the lists of its tiles, up to the entry capacity; a
// splat that does not fit in one is flagged and listed apart.
@compute @workgroup_size(256)
fn cs_scatter(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = splat_index(id);
    if i >= min(draw_args[1], setup.w) {
        return;
    }
    let pixels = rects[i];
    let rect = tiles_of(pixels);
    var overflow = false;
    for (var ty = rect.y; ty <= rect.w; ty++) {
        for (var tx = rect.x; tx <= rect.z; tx++) {
            let slot = atomicAdd(&tiles[cursors_at() + u32(ty) * setup.x + u32(tx)], 1u);
            if slot < setup.z {
                entries[slot] = i;
            } else {
                overflow = true;
            }
        }
    }
    if overflow {
        rects[i].x = -pixels.x - 1;
        let k = atomicAdd(&tiles[2], 1u);
        rects[setup.w + k].x = i32(i);
    }
}

// The chunks of the overflow list per tile (0 without overflow).
fn lone_chunks() -> u32 {
    return (atomicLoad(&tiles[2]) + CHUNK - 1u) / CHUNK;
}

// The overflow's work items: every tile times the chunks of its list, at
// most a dispatch's ROW × ROW (past it, far beyond any real frame, the
// last tiles miss the overflowed splats).
fn lone_items() -> u32 {
    let chunks = lone_chunks();
    if chunks > 0u && tile_count() > ROW * ROW / chunks {
        return ROW * ROW;
    }
    return tile_count() * chunks;
}

@compute @workgroup_size(1)
fn cs_lone_dispatch() {
    let items = lone_items();
    dispatch[8] = min(items, ROW);
    dispatch[9] = (items + ROW - 1u) / ROW;
    dispatch[10] = 1u;
}

// A work item's splats: view-space centre and radius, view-space normal,
// the pixels their quads cover (a pixel outside skips the ray test).
var<workgroup> s_centre: array<vec4<f32>, CHUNK>;
var<workgroup> s_normal: array<vec4<f32>, CHUNK>;
var<workgroup> s_pixels: array<vec4<i32>, CHUNK>;
// The work item's tile, first entry and splat count, and whether it is its
// tile's only one, set by thread 0.
var<workgroup> w_tile: u32;
var<workgroup> w_base: u32;
var<workgroup> w_count: u32;
var<workgroup> w_alone: u32;

// Loads work item `item`'s splats into workgroup memory and returns its
// tile, its splat count and 1 when it is the only work item drawing its
// tile's pixels (one chunk, nothing overflowed), else 0: from its tile's
// list, or with `lone` from the overflow list (work items tile-major). Work
// items past the last (the dispatch's rounding) have no splats; a flagged
// splat in a tile's list covers no pixel there. With `skip_alone` a work
// item alone on its tile loads nothing (the visibility pass drew it whole).
fn load_item(item: u32, li: u32, lone: bool, skip_alone: bool) -> vec3<u32> {
    if li == 0u {
        var tile = 0u;
        var base = 0u;
        var count = 0u;
        var alone = 0u;
        if lone {
            let chunks = lone_chunks();
            if item < lone_items() {
                tile = item / chunks;
                base = (item % chunks) * CHUNK;
                count = min(CHUNK, atomicLoad(&tiles[2]) - base);
            }
        } else if item < atomicLoad(&tiles[1]) {
            // The last tile whose first work item is at or before `item`.
            var lo = 0u;
            var hi = tile_count();
            while hi - lo > 1u {
                let mid = (lo + hi) / 2u;
                if atomicLoad(&tiles[items_at() + mid]) <= item {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            tile = lo;
            let first = atomicLoad(&tiles[items_at() + tile]);
            base = atomicLoad(&tiles[starts_at() + tile]) + (item - first) * CHUNK;
            let end = min(min(base + CHUNK, atomicLoad(&tiles[starts_at() + tile + 1u])), setup.z);
            if end > base {
                count = end - base;
            }
            if atomicLoad(&tiles[2]) == 0u && atomicLoad(&tiles[items_at() + tile + 1u]) == first + 1u {
                alone = 1u;
                if skip_alone {
                    count = 0u;
                }
            }
        }
        w_tile = tile;
        w_base = base;
        w_count = count;
        w_alone = alone;
    }
    workgroupBarrier();
    let tile = w_tile;
    let count = w_count;
    let alone = w_alone;
    if li < count {
        var index = 0u;
        if lone {
            index = u32(rects[setup.w + w_base + li].x);
        } else {
            index = entries[w_base + li];
        }
        let s = splats[index];
        let c = (frame.view * vec4<f32>(s.position_radius.xyz, 1.0)).xyz;
        s_centre[li] = vec4<f32>(c, s.position_radius.w);
        s_normal[li] = vec4<f32>((frame.view * vec4<f32>(s.normal.xyz, 0.0)).xyz, 0.0);
        var pixels = rects[index];
        if lone {
            pixels.x = -pixels.x - 1;
        } else if pixels.x < 0 {
            pixels = vec4<i32>(0, 0, -1, -1);
        }
        s_pixels[li] = pixels;
    }
    workgroupBarrier();
    return vec3<u32>(tile, count, alone);
}

fn pixel_of(tile: u32, lid: vec3<u32>) -> vec2<u32> {
    return vec2<u32>(tile % setup.x, tile / setup.x) * TILE + lid.xy;
}

// The depth the raster path's visibility pass gives the pixel of view ray
// `d`, whose ray meets the disc (`centre`, view-space normal `n`) at `q`:
// splat_quad's quad with its corners pushed back by `push` along their
// rays, and of its two triangles (split along the corners (+u, -v) and
// (-u, +v)) the one the pixel is in. The corners move along their own
// rays, so the quad's outline and diagonal stay where they were on screen,
// and the side of the diagonal is the side `q` is on.
fn pushed_depth(d: vec3<f32>, q: vec3<f32>, centre: vec4<f32>, n: vec3<f32>, push: f32) -> f32 {
    let axes = disc_axes(n, centre.w);
    let u = axes[0];
    let v = axes[1];
    let e = q - centre.xyz;
    var k0 = centre.xyz + u - v;
    var k1 = centre.xyz - u + v;
    var k2 = centre.xyz - u - v;
    if dot(e, u) + dot(e, v) > 0.0 {
        k2 = centre.xyz + u + v;
    }
    k0 += normalize(k0) * push;
    k1 += normalize(k1) * push;
    k2 += normalize(k2) * push;
    let m = cross(k1 - k0, k2 - k0);
    return depth_of(d * (dot(k0, m) / dot(d, m)));
}

// The visibility pass over work item `item`: the nearest pushed depth of
// its splats at each of the tile's pixels, min'd into the depth bits. A
// work item alone on its tile knows its pixels' final depth at once, and
// sums their attributes too (the attribute pass then skips it).
fn visibility(item: u32, lid: vec3<u32>, li: u32, lone: bool) {
    let work = load_item(item, li, lone, false);
    let px = pixel_of(work.x, lid);
    let size = screen();
    let d = view_ray(vec2<f32>(px) + 0.5);
    var best = 2.0;
    let at = vec2<i32>(px);
    for (var k = 0u; k < work.y; k++) {
        let r = s_pixels[k];
        if any(at < r.xy) || any(at > r.zw) {
            continue;
        }
        let h = hit_view(d, s_centre[k], s_normal[k].xyz);
        if h.w >= 0.0 {
            let pushed = pushed_depth(d, h.xyz, s_centre[k], s_normal[k].xyz, frame.params.x);
            best = min(best, max(pushed, 0.0));
        }
    }
    if px.x >= size.x || px.y >= size.y {
        return;
    }
    let p = px.y * size.x + px.x;
    if work.z == 0u {
        if best < 2.0 {
            atomicMin(&depth_bits[p], bitcast<u32>(best));
        }
        return;
    }
    // The only writer of these pixels: the depth and the sums are stored.
    let visible = min(bitcast<f32>(atomicLoad(&depth_bits[p])), best);
    atomicStore(&depth_bits[p], bitcast<u32>(visible));
    let sum = sums(at, d, visible, work.y);
    for (var k = 0u; k < 4u; k++) {
        atomicStore(&accum[4u * p + k], bitcast<u32>(sum[k]));
    }
}

// Σ w (n, 1) over the loaded splats that the pixel `at` (view ray `d`)
// sees within the depth `visible`.
fn sums(at: vec2<i32>, d: vec3<f32>, visible: f32, count: u32) -> vec4<f32> {
    var sum = vec4<f32>(0.0);
    for (var k = 0u; k < count; k++) {
        let r = s_pixels[k];
        if any(at < r.xy) || any(at > r.zw) {
            continue;
        }
        let h = hit_view(d, s_centre[k], s_normal[k].xyz);
        if h.w >= 0.0 && depth_of(h.xyz) <= visible {
            let m = 1.0 - h.w;
            let w = m * m * m;
            // The world-space normal, as the raster path sums it.
            let n = (frame.inv_view * vec4<f32>(s_normal[k].xyz, 0.0)).xyz;
            sum += vec4<f32>(n * w, w);
        }
    }
    return sum;
}

// accum[i] += x, on the float's bits.
fn add_float(i: u32, x: f32) {
    var old = atomicLoad(&accum[i]);
    loop {
        let r = atomicCompareExchangeWeak(&accum[i], old, bitcast<u32>(bitcast<f32>(old) + x));
        if r.exchanged {
            break;
        }
        old = r.old_value;
    }
}

// The attribute pass over work item `item`: w (n, 1) of its splats within
// the visibility depth, summed per pixel and added to the pixel's sums
// (work items alone on their tile were summed by the visibility pass).
fn attributes(item: u32, lid: vec3<u32>, li: u32, lone: bool) {
    let work = load_item(item, li, lone, true);
    let px = pixel_of(work.x, lid);
    let size = screen();
    if work.y == 0u || px.x >= size.x || px.y >= size.y {
        return;
    }
    let p = px.y * size.x + px.x;
    let visible = bitcast<f32>(atomicLoad(&depth_bits[p]));
    let sum = sums(vec2<i32>(px), view_ray(vec2<f32>(px) + 0.5), visible, work.y);
    if sum.w > 0.0 {
        for (var k = 0u; k < 4u; k++) {
            add_float(4u * p + k, sum[k]);
        }
    }
}

@compute @workgroup_size(8, 8)
fn cs_visibility(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    visibility(wid.x + wid.y * ROW, lid, li, false);
}

@compute @workgroup_size(8, 8)
fn cs_lone_visibility(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    visibility(wid.x + wid.y * ROW, lid, li, true);
}

@compute @workgroup_size(8, 8)
fn cs_attributes(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    attributes(wid.x + wid.y * ROW, lid, li, false);
}

@compute @workgroup_size(8, 8)
fn cs_lone_attributes(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    attributes(wid.x + wid.y * ROW, lid, li, true);
}
