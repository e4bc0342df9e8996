// The shade pass's inputs on the compute path: compute_splat.wgsl's sums
// (four f32 as bits per pixel) and visible depth (f32 bits), row-major.

@group(0) @binding(1) var<storage, read> sums_bits: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> depth_bits: array<u32>;

fn pixel_index(px: vec2<i32>) -> u32 {
    return u32(px.y) * u32(frame.viewport.x) + u32(px.x);
}

fn sums_at(px: vec2<i32>) -> vec4<f32> {
    return bitcast<vec4<f32>>(sums_bits[pixel_index(px)]);
}

fn depth_at(px: vec2<i32>) -> f32 {
    return bitcast<f32>(depth_bits[pixel_index(px)]);
}
