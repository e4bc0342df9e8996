// sph-core's `Boundary::resolve` on the GPU: obstacles and the domain box,
// moved into the fluid by the clearance (`f.domain_min.w`,
// `Boundary::clearance`), project a point onto their surface and reflect the
// normal velocity with `restitution`, up to three rounds (corners where an
// obstacle meets a wall). Expects a uniform `f` with `domain_min` and
// `domain_max`, and walls.wgsl (struct Obstacle, `obstacles`) prepended.

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

fn reflect_normal(v: vec3<f32>, n: vec3<f32>, restitution: f32) -> vec3<f32> {
    let vn = dot(v, n);
    if vn < 0.0 {
        return v - (1.0 + restitution) * vn * n;
    }
    return v;
}

fn resolve(x_in: vec3<f32>, v_in: vec3<f32>, restitution: f32) -> array<vec3<f32>, 2> {
    var x = x_in;
    var v = v_in;
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
                // Growing steps, as on the CPU: out even where a few ulps
                // of the radius are below an ulp of the position.
                var step = o.b.x * 4.0 * 1.1920929e-7;
                for (var nudge = 0; nudge < 32 && inside(o, x); nudge++) {
                    x += n * step;
                    step *= 2.0;
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
            v = reflect_normal(v, n, restitution);
            moved = true;
        }
        for (var a = 0; a < 3; a++) {
            var n = vec3<f32>(0.0);
            if x[a] < lo[a] {
                x[a] = lo[a];
                n[a] = 1.0;
                v = reflect_normal(v, n, restitution);
                moved = true;
            } else if x[a] > hi[a] {
                x[a] = hi[a];
                n[a] = -1.0;
                v = reflect_normal(v, n, restitution);
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    return array<vec3<f32>, 2>(x, v);
}
