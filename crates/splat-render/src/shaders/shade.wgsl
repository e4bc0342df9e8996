// Per-pixel normalisation and deferred shading as a compute pass (eq. 38-40).
// `sums_at` and `depth_at` (the visibility pass's sums and depth) come from
// shade_targets.wgsl (the raster path) or shade_buffers.wgsl (the compute
// path), with bindings 1 and 2.

@group(0) @binding(3) var env_tex: texture_2d<f32>;
@group(0) @binding(4) var env_sampler: sampler;
// The scene pass's image: backdrop and geometry, what the fluid refracts.
@group(0) @binding(5) var scene_tex: texture_2d<f32>;
@group(0) @binding(6) var scene_sampler: sampler;
@group(0) @binding(7) var out_tex: texture_storage_2d<rgba8unorm, write>;
// The back surface pass's depth (0 where it drew nothing).
@group(0) @binding(8) var back_depth_tex: texture_depth_2d;

// Distance from the eye along the ray through `xy` to depth-buffer value `d`.
fn ray_distance(xy: vec2<f32>, d: f32) -> f32 {
    let near = frame.ray.z;
    let far = frame.ray.w;
    let z = near * far / (far - d * (far - near));
    return z * length(view_ray(xy));
}

// The fluid's thickness along the view ray at pixel `px`: from the front
// surface (the visibility depth, less its push-back epsilon) to the farthest
// back-facing splat or the geometry behind it, whichever is nearer; 0 where
// no back surface was drawn.
fn thickness(px: vec2<i32>, xy: vec2<f32>) -> f32 {
    let back = textureLoad(back_depth_tex, px, 0);
    if frame.flags.z < 0.5 || back <= 0.0 {
        return 0.0;
    }
    let front = ray_distance(xy, depth_at(px)) - frame.params.x;
    return max(ray_distance(xy, back) - front, 0.0);
}

@compute @workgroup_size(8, 8)
fn cs_shade(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = vec2<u32>(frame.viewport.xy);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let px = vec2<i32>(id.xy);
    let xy = vec2<f32>(id.xy) + 0.5;
    let uv = xy * frame.viewport.zw;
    let a = sums_at(px);
    let mode = u32(frame.params.w);
    let dir = world_ray(xy);

    var colour = vec3<f32>(0.0);
    if a.w <= 0.0 {
        if mode == 0u {
            colour = textureSampleLevel(scene_tex, scene_sampler, uv, 0.0).rgb;
        }
    } else {
        // A = sum(A_i w_i) / sum(w_i), then renormalised to a unit normal.
        let avg = a.xyz / a.w;
        var n = -dir;
        if dot(avg, avg) > 1e-20 {
            n = normalize(avg);
        }
        switch mode {
            case 1u: {
                colour = n * 0.5 + 0.5;
            }
            case 2u: {
                colour = vec3<f32>(min(a.w / frame.params.z, 1.0));
            }
            case 3u: {
                let d = depth_at(px);
                let near = frame.ray.z;
                let far = frame.ray.w;
                let linear = near * far / (far - d * (far - near));
                colour = vec3<f32>(clamp(1.0 - log(linear / near) / log(far / near), 0.0, 1.0));
            }
            default: {
                let r = reflect(dir, n);
                let f = 0.5 + 0.5 * dot(r, dir);
                let reflected = textureSampleLevel(env_tex, env_sampler, equirect_uv(r), 0.0).rgb;
                let rv = (frame.view * vec4<f32>(r, 0.0)).xyz;
                let offset = frame.params.y * vec2<f32>(-rv.x, rv.y);
                let refracted = textureSampleLevel(scene_tex, scene_sampler, uv + offset, 0.0).rgb;
                // Beer-Lambert: light through t of fluid keeps exp(-sigma t).
                let transmitted = frame.fluid.rgb * exp(-frame.absorption.rgb * thickness(px, xy));
                colour = frame.fluid.w * f * f * reflected + transmitted * refracted;
            }
        }
    }
    textureStore(out_tex, px, vec4<f32>(clamp(colour, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0));
}
