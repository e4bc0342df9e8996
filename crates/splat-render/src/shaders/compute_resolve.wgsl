// Compute splatting's last pass: the visibility depth and the sums of
// compute_splat.wgsl (both as bits) into the depth and accumulation targets, one
// full-screen triangle.

@group(0) @binding(1) var<storage, read> depth_bits: array<u32>;
@group(0) @binding(2) var<storage, read> accum: array<u32>;

@vertex
fn vs_full(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

struct Resolved {
    @location(0) sums: vec4<f32>,
    @builtin(frag_depth) depth: f32,
};

@fragment
fn fs_resolve(@builtin(position) pos: vec4<f32>) -> Resolved {
    let p = u32(pos.y) * u32(frame.viewport.x) + u32(pos.x);
    let a = vec4<u32>(accum[4u * p], accum[4u * p + 1u], accum[4u * p + 2u], accum[4u * p + 3u]);
    var out: Resolved;
    out.sums = bitcast<vec4<f32>>(a);
    out.depth = bitcast<f32>(depth_bits[p]);
    return out;
}
