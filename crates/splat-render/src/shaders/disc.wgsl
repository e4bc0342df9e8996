// What the raster and the compute splat passes share (layout of `Splat`:
// `GpuSplat` in splat.rs): a splat, and where a pixel's view ray meets its
// disc.

struct Splat {
    position_radius: vec4<f32>,
    normal: vec4<f32>,
};

// Ray-disc intersection for the pixel at `xy`: (view-space hit, r^2/h^2), or w < 0 on a miss.
fn hit_disc(xy: vec2<f32>, centre: vec4<f32>, normal_world: vec3<f32>) -> vec4<f32> {
    return hit_view(view_ray(xy), centre, (frame.view * vec4<f32>(normal_world, 0.0)).xyz);
}

// Where the view ray `d` meets the disc of view-space centre and radius
// `centre` and view-space normal `n`: (hit, r^2/h^2), or w < 0 on a miss.
fn hit_view(d: vec3<f32>, centre: vec4<f32>, n: vec3<f32>) -> vec4<f32> {
    let denom = dot(d, n);
    if abs(denom) < 1e-12 {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    let t = dot(centre.xyz, n) / denom;
    let q = d * t;
    let e = q - centre.xyz;
    let s = dot(e, e) / (centre.w * centre.w);
    if t <= 0.0 || s > 1.0 {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    return vec4<f32>(q, s);
}

// The half-sides u, v of the square bounding a disc of view-space normal `n`
// and radius `r` in its own plane: the quad the raster path draws, whose
// corners the compute path bins and pushes back the same way.
fn disc_axes(n: vec3<f32>, r: f32) -> mat2x3<f32> {
    var a = vec3<f32>(1.0, 0.0, 0.0);
    if abs(n.x) > 0.9 {
        a = vec3<f32>(0.0, 1.0, 0.0);
    }
    let u = normalize(cross(n, a)) * r;
    return mat2x3<f32>(u, cross(n, u));
}

fn depth_of(q: vec3<f32>) -> f32 {
    let c = frame.proj * vec4<f32>(q, 1.0);
    return c.z / c.w;
}

