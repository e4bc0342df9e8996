// Visibility and attribute passes (Botsch et al. 2005; Vesterlund 2004, 4.2.2).
// Each splat is drawn as the square bounding its disc in the disc's plane,
// projected: the rasterizer interpolates the plane's depth, and the fragment
// shader intersects the pixel's view ray with the disc to mask it. The
// fragment shaders of passes 1 and 2 write no depth, so the depth test runs
// before them. Against screen-space rectangles that wrote frag_depth: the
// lavapipe render bench's 100k rows 17-24 % faster, the demo's frames 13 %;
// on an NVIDIA H200 4 % faster up to 100k splats, 7-10 % slower at 1M
// (BENCHMARKS.md, "Splats as planar quads").

@group(0) @binding(1) var<storage, read> splats: array<Splat>;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    // View-space centre and radius.
    @location(0) @interpolate(flat) centre: vec4<f32>,
    // World-space unit normal.
    @location(1) @interpolate(flat) normal: vec4<f32>,
};

// The splat's disc as the square c ± u ± v in its own plane, projected: the
// rasterizer then interpolates the plane's depth, exact at every pixel, so
// the fragment shaders need not write depth and the depth test runs before
// them. `push` moves each corner that far back along its view ray (the
// visibility pass's epsilon). Culling, by `keep`: 0 keeps every splat, 1
// drops back-facing ones, 2 drops front-facing ones.
fn splat_quad(vi: u32, ii: u32, keep: u32, push: f32) -> VsOut {
    let s = splats[ii];
    let r = s.position_radius.w;
    let c = (frame.view * vec4<f32>(s.position_radius.xyz, 1.0)).xyz;
    let n = (frame.view * vec4<f32>(s.normal.xyz, 0.0)).xyz;
    let axes = disc_axes(n, r);
    let u = axes[0];
    let v = axes[1];
    // Splats reaching in front of the near plane are dropped.
    var clipped = false;
    for (var k = 0u; k < 4u; k++) {
        let su = select(-1.0, 1.0, (k & 1u) != 0u);
        let sv = select(-1.0, 1.0, (k & 2u) != 0u);
        if -(c + su * u + sv * v).z < frame.ray.z {
            clipped = true;
        }
    }
    // Back-facing splats have their normal pointing away from the eye, at
    // the view-space origin.
    let facing_away = dot(n, c) >= 0.0;
    let back = (keep == 1u && facing_away) || (keep == 2u && !facing_away);
    let su = select(-1.0, 1.0, (vi & 1u) != 0u);
    let sv = select(-1.0, 1.0, (vi & 2u) != 0u);
    var p = c + su * u + sv * v;
    p += normalize(p) * push;
    var out: VsOut;
    out.clip = frame.proj * vec4<f32>(p, 1.0);
    if clipped || back {
        // A zero-area quad.
        out.clip = vec4<f32>(-2.0, -2.0, 0.5, 1.0);
    }
    out.centre = vec4<f32>(c, r);
    out.normal = vec4<f32>(s.normal.xyz, 0.0);
    return out;
}

@vertex
fn vs_splat(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    return splat_quad(vi, ii, select(0u, 1u, frame.flags.x > 0.5), 0.0);
}

// The visibility pass: the splats pushed back by epsilon.
@vertex
fn vs_splat_visibility(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    return splat_quad(vi, ii, select(0u, 1u, frame.flags.x > 0.5), frame.params.x);
}

// The back surface pass draws only the splats facing away from the eye.
@vertex
fn vs_splat_back(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    return splat_quad(vi, ii, 2u, 0.0);
}

// Pass 1: nearest surface depth, pushed back by epsilon along the view ray
// (by the vertex shader; the rasterizer writes it).
@fragment
fn fs_visibility(in: VsOut) {
    let h = hit_disc(in.clip.xy, in.centre, in.normal.xyz);
    if h.w < 0.0 {
        discard;
    }
}

// Pass 2: additive w * (normal, 1) with w the alpha mask of eq. 37, for the
// splats that pass the depth test against pass 1.
@fragment
fn fs_attribute(in: VsOut) -> @location(0) vec4<f32> {
    let h = hit_disc(in.clip.xy, in.centre, in.normal.xyz);
    if h.w < 0.0 {
        discard;
    }
    let m = 1.0 - h.w;
    let w = m * m * m;
    return vec4<f32>(in.normal.xyz * w, w);
}

// The scene's depth (geometry only) while the back surface pass runs.
@group(1) @binding(0) var scene_depth: texture_depth_2d;

// Back surface pass: the farthest back-facing splat (depth compare
// Greater), for the fluid's thickness. The fluid ends where the geometry
// starts: a splat behind it (the bottom of a pool, which the iso-surface
// puts a little inside the tank's floor) counts at the geometry's depth.
@fragment
fn fs_back(in: VsOut) -> @builtin(frag_depth) f32 {
    let h = hit_disc(in.clip.xy, in.centre, in.normal.xyz);
    if h.w < 0.0 {
        discard;
    }
    return min(depth_of(h.xyz), textureLoad(scene_depth, vec2<i32>(in.clip.xy), 0));
}
