// Semi-implicit Euler (v += a dt, x += v dt), then the boundary: obstacles and
// the domain box, moved into the fluid by the clearance (domain_min.w,
// `Boundary::clearance`), project the particle onto their surface and reflect the
// normal velocity with the restitution, up to three rounds — sph-core's
// Integrate and Boundaries processors (`Boundary::resolve`).
// Expects solver_params.wgsl (struct Params, binding 0 `f`) and walls.wgsl prepended.

@group(0) @binding(1) var<storage, read_write> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> velocities: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> accelerations: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> obstacles: array<Obstacle>;
// Only `dt` is read: the step chosen by timestep.wgsl (StepState's layout).
struct Step {
    v_max: u32,
    a_max: u32,
    dt: f32,
};
@group(0) @binding(5) var<storage, read> chosen: Step;

// The obstacle grown by the clearance c: a sphere's radius, a box's faces.
fn grown(o: Obstacle, c: f32) -> Obstacle {
    var g = o;
    if o.a.w == SPHERE {
        g.b.x = o.b.x + c;
    } else {
        g.a = vec4<f32>(o.a.xyz - c, o.a.w);
        g.b = vec4<f32>(o.b.xyz + c, o.b.w);
    }
    return g;
}

fn inside(o: Obstacle, x: vec3<f32>) -> bool {
    if o.a.w == SPHERE {
        let d = x - o.a.xyz;
        return dot(d, d) < o.b.x * o.b.x;
    }
    return o.a.w == BOX && all(x > o.a.xyz) && all(x < o.b.xyz);
}

fn reflect_normal(v: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let vn = dot(v, n);
    if vn < 0.0 {
        return v - (1.0 + f.restitution) * vn * n;
    }
    return v;
}

@compute @workgroup_size(64)
fn integrate(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= f.n {
        return;
    }
    let dt = chosen.dt;
    if dt <= 0.0 {
        return;
    }
    let p = positions[i];
    var v = velocities[i].xyz + accelerations[i].xyz * dt;
    var x = p.xyz + v * dt;
    let c = f.domain_min.w;
    let lo = f.domain_min.xyz + c;
    let hi = f.domain_max.xyz - c;
    for (var rounds = 0; rounds < 3; rounds++) {
        var moved = false;
        for (var k = 0u; k < arrayLength(&obstacles); k++) {
            let o = grown(obstacles[k], c);
            if !inside(o, x) {
                continue;
            }
            var n = vec3<f32>(0.0, 1.0, 0.0);
            if o.a.w == SPHERE {
                let d = x - o.a.xyz;
                let len = length(d);
                if len > 0.0 {
                    n = d / len;
                }
                x = o.a.xyz + n * o.b.x;
                for (var nudge = 0; nudge < 16 && inside(o, x); nudge++) {
                    x += n * (o.b.x * 4.0 * 1.1920929e-7);
                }
            } else {
                // The nearest face, ties to the lower axis and the min face.
                let to_min = x - o.a.xyz;
                let to_max = o.b.xyz - x;
                var best = 3.0e38;
                var q = x;
                for (var a = 0; a < 3; a++) {
                    if to_min[a] < best {
                        best = to_min[a];
                        n = vec3<f32>(0.0);
                        n[a] = -1.0;
                        q = x;
                        q[a] = o.a[a];
                    }
                    if to_max[a] < best {
                        best = to_max[a];
                        n = vec3<f32>(0.0);
                        n[a] = 1.0;
                        q = x;
                        q[a] = o.b[a];
                    }
                }
                x = q;
            }
            v = reflect_normal(v, n);
            moved = true;
        }
        for (var a = 0; a < 3; a++) {
            var n = vec3<f32>(0.0);
            if x[a] < lo[a] {
                x[a] = lo[a];
                n[a] = 1.0;
                v = reflect_normal(v, n);
                moved = true;
            } else if x[a] > hi[a] {
                x[a] = hi[a];
                n[a] = -1.0;
                v = reflect_normal(v, n);
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    positions[i] = vec4<f32>(x, p.w);
    velocities[i] = vec4<f32>(v, 0.0);
}
