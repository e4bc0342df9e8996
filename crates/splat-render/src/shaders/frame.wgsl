// Per-frame uniforms shared by every pass (layout: `FrameUniform` in renderer.rs).
struct Frame {
    view: mat4x4<f32>,      // world -> view
    proj: mat4x4<f32>,      // view -> clip (depth 0..1)
    inv_view: mat4x4<f32>,  // view -> world
    viewport: vec4<f32>,    // width, height, 1/width, 1/height
    ray: vec4<f32>,         // 1/proj[0][0], 1/proj[1][1], near, far
    params: vec4<f32>,      // depth epsilon, refraction mu, weight scale, view code
    fluid: vec4<f32>,       // fluid colour (rgb), reflectivity (w)
    flags: vec4<f32>,       // x: 1 culls back-facing splats, y: 1 draws the environment as backdrop, z: 1 when the back surface was drawn
    sun: vec4<f32>,         // unit direction towards the sun (xyz)
    absorption: vec4<f32>,  // Beer-Lambert absorption per world unit (rgb)
};

@group(0) @binding(0) var<uniform> frame: Frame;

// View-space direction (z = -1) of the ray through framebuffer position `xy`.
fn view_ray(xy: vec2<f32>) -> vec3<f32> {
    let ndc = vec2<f32>(xy.x * frame.viewport.z * 2.0 - 1.0, 1.0 - xy.y * frame.viewport.w * 2.0);
    return vec3<f32>(ndc.x * frame.ray.x, ndc.y * frame.ray.y, -1.0);
}

const PI: f32 = 3.14159265358979;

fn equirect_uv(d: vec3<f32>) -> vec2<f32> {
    return vec2<f32>(0.5 + atan2(d.x, -d.z) / (2.0 * PI), acos(clamp(d.y, -1.0, 1.0)) / PI);
}

// World-space unit direction of the ray through framebuffer position `xy`.
fn world_ray(xy: vec2<f32>) -> vec3<f32> {
    return normalize((frame.inv_view * vec4<f32>(view_ray(xy), 0.0)).xyz);
}
