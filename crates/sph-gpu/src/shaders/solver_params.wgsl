// Uniforms of the solver passes (forces, integrate); mirrors `Params` in solver.rs.

struct Params {
    h: f32,
    inv_h: f32,
    n: u32,
    table: u32,
    rest_density: f32,
    viscosity: f32,
    surface_tension: f32,
    surface_threshold: f32,
    gravity: vec4<f32>,
    domain_min: vec4<f32>, // w: Boundary::clearance, kept by integrate.wgsl
    domain_max: vec4<f32>,
    poly6_grad: f32,      // 945 / (32 pi h^9)
    visc_lap: f32,        // 45 / (pi h^6)
    spiky_grad: f32,      // 45 / (pi h^6)
    spiky_pressure: u32,  // 1: spiky pressure gradient, 0: poly6
    dt: f32,              // > 0: a fixed step; 0: adaptive (timestep.wgsl)
    restitution: f32,
    cfl: f32,             // TimeStepping::cfl
    force_factor: f32,    // TimeStepping::force_factor
    max_dt: f32,
    min_dt: f32,
    sound_speed: f32,     // sqrt(k)
    frame_dt: f32,        // > 0: adaptive steps land on this much time
    push_origin: vec4<f32>, // RayPush: a point on the ray, radius in w (0: none)
    push_dir: vec4<f32>,    // its unit direction
    push_accel: vec4<f32>,  // the acceleration on the ray (m/s²)
    layers: vec4<f32>,      // the walls' layers under a clearance: spacing, thickness (walls.wgsl)
};

@group(0) @binding(0) var<uniform> f: Params;
