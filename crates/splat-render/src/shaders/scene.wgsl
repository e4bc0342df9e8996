// The scene pass: the backdrop, then opaque meshes lit by the environment
// (geometry.rs). Its colour is what the fluid refracts; its depth is where
// the splat passes start.

@group(0) @binding(1) var env_tex: texture_2d<f32>;
@group(0) @binding(2) var env_sampler: sampler;
@group(0) @binding(3) var back_tex: texture_2d<f32>;
@group(0) @binding(4) var back_sampler: sampler;

@vertex
fn vs_backdrop(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 1.0, 1.0);
}

@fragment
fn fs_backdrop(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    if frame.flags.y > 0.5 {
        let d = world_ray(pos.xy);
        return vec4<f32>(textureSampleLevel(env_tex, env_sampler, equirect_uv(d), 0.0).rgb, 1.0);
    }
    let uv = pos.xy * frame.viewport.zw;
    return vec4<f32>(textureSampleLevel(back_tex, back_sampler, uv, 0.0).rgb, 1.0);
}

struct MeshIn {
    @location(0) position_grid: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) colour: vec4<f32>,
};

struct MeshOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec4<f32>,   // position, grid spacing
    @location(1) normal: vec3<f32>,
    @location(2) colour: vec3<f32>,
};

@vertex
fn vs_mesh(v: MeshIn) -> MeshOut {
    var out: MeshOut;
    out.clip = frame.proj * frame.view * vec4<f32>(v.position_grid.xyz, 1.0);
    out.world = v.position_grid;
    out.normal = v.normal.xyz;
    out.colour = v.colour.rgb;
    return out;
}

// 1 on a grid line of spacing `grid` across the surface's two in-plane
// axes, 0 between them, antialiased over about a pixel.
fn grid_line(p: vec3<f32>, n: vec3<f32>, grid: f32) -> f32 {
    let q = p / grid;
    let width = max(fwidth(q), vec3<f32>(1e-6));
    let dist = abs(fract(q - 0.5) - 0.5) / width;
    // Along the normal the coordinate is constant: no line there.
    let along = step(vec3<f32>(0.5), abs(n));
    let d = select(dist, vec3<f32>(1e6), along > vec3<f32>(0.5));
    let nearest = min(d.x, min(d.y, d.z));
    return 1.0 - clamp(nearest - 0.5, 0.0, 1.0);
}

@fragment
fn fs_mesh(in: MeshOut) -> @location(0) vec4<f32> {
    let n = normalize(in.normal);
    // Sky light from the environment around the normal, and the sun.
    let sky = textureSampleLevel(env_tex, env_sampler, equirect_uv(n), 0.0).rgb;
    let sun = max(dot(n, frame.sun.xyz), 0.0);
    // Derivatives need uniform control flow: the line first, then whether
    // there is a grid.
    let line = grid_line(in.world.xyz, n, max(in.world.w, 1e-6));
    let albedo = in.colour * (1.0 - 0.45 * select(0.0, line, in.world.w > 0.0));
    // The sky around the normal tints a mostly white ambient.
    let light = 0.3 * sky + vec3<f32>(0.4 + 0.5 * sun);
    return vec4<f32>(clamp(albedo * light, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0);
}
