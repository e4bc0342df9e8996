// The shade pass's inputs on the raster path: the accumulation and depth
// targets the visibility and attribute passes drew into.

@group(0) @binding(1) var accum_tex: texture_2d<f32>;
@group(0) @binding(2) var depth_tex: texture_depth_2d;

fn sums_at(px: vec2<i32>) -> vec4<f32> {
    return textureLoad(accum_tex, px, 0);
}

fn depth_at(px: vec2<i32>) -> f32 {
    return textureLoad(depth_tex, px, 0);
}
