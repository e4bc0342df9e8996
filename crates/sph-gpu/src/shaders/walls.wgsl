// The walls of sph-core's `Boundary`: the domain box's six planes, then the
// obstacles (boxes and spheres), in the CPU's order. Expects a uniform `f` with
// `h`, `inv_h`, `rest_density`, `domain_min` (w: the clearance) and
// `domain_max`, and the shader's
// `obstacles: array<Obstacle>` (one entry of kind NONE when there are none).

// A box: a = (min, BOX), b = (max, 0); a sphere: a = (centre, SPHERE), b.x = radius.
struct Obstacle {
    a: vec4<f32>,
    b: vec4<f32>,
};

const BOX: f32 = 0.0;
const SPHERE: f32 = 1.0;
const NONE: f32 = 2.0;

fn wall_count() -> u32 {
    return 6u + arrayLength(&obstacles);
}

// Wall k seen from x: (outward unit normal, distance); distance >= h (or
// infinite) where the wall is not within reach — `for_each_wall_within`.
fn wall(k: u32, x: vec3<f32>) -> vec4<f32> {
    let far = vec4<f32>(0.0, 1.0, 0.0, 3.0e38);
    if k < 6u {
        let a = k / 2u;
        var n = vec3<f32>(0.0);
        var d = 0.0;
        if (k & 1u) == 0u {
            d = x[a] - f.domain_min[a];
            n[a] = 1.0;
        } else {
            d = f.domain_max[a] - x[a];
            n[a] = -1.0;
        }
        return vec4<f32>(n, d);
    }
    let o = obstacles[k - 6u];
    if o.a.w == SPHERE {
        let r = x - o.a.xyz;
        let len = length(r);
        var n = vec3<f32>(0.0, 1.0, 0.0);
        if len > 0.0 {
            n = r / len;
        }
        return vec4<f32>(n, len - o.b.x);
    }
    if o.a.w == BOX {
        let r = x - clamp(x, o.a.xyz, o.b.xyz);
        let len = length(r);
        if len > 0.0 {
            return vec4<f32>(r / len, len);
        }
    }
    return far;
}

// The walls' density fraction at distance d (units of rest density): the
// integral of W_poly6 over the half-space beyond a plane, 315/256 (G(1) - G(s)),
// G(s) = s (1 - 4s^2/3 + 6s^4/5 - 4s^6/7 + s^8/9), s = d/h.
fn wall_volume_fraction(d: f32) -> f32 {
    let s = clamp(d * f.inv_h, 0.0, 1.0);
    let s2 = s * s;
    let g = s * (1.0 + s2 * (-4.0 / 3.0 + s2 * (6.0 / 5.0 + s2 * (-4.0 / 7.0 + s2 / 9.0))));
    let g1 = 1.0 - 4.0 / 3.0 + 6.0 / 5.0 - 4.0 / 7.0 + 1.0 / 9.0;
    return 315.0 / 256.0 * (g1 - g);
}

// 315/(256 h^9) (h^2 - d^2)^4: the wall density term's derivative.
fn plane_density(d: f32) -> f32 {
    let dd = clamp(d, 0.0, f.h);
    let q = f.h * f.h - dd * dd;
    return 315.0 / 256.0 * pow(f.inv_h, 9.0) * q * q * q * q;
}

// ∫ W_poly6 over the plane at distance d and its slope −d/dd
// (`WallKernel::plane_and_slope`).
fn plane_and_slope(d: f32) -> vec2<f32> {
    let u = clamp(d * f.inv_h, 0.0, 1.0);
    let w = 1.0 - u * u;
    let w3 = w * w * w;
    let c = 315.0 / 256.0;
    return vec2<f32>(c * f.inv_h * w3 * w, 8.0 * c * f.inv_h * f.inv_h * u * w3);
}

// Under a clearance, a wall's fraction of ρ0 and its slope at distance d,
// the fluid's lattice continued behind the wall in the layers `f.layers`
// (spacing, thickness: `WallKernel::lattice_layers` of the lightest
// particle, and `WallKernel::layers_fraction_and_density`). The host writes
// layers only under a clearance; `half_space` is returned without them.
fn wall_term(d: f32, half_space: vec2<f32>) -> vec2<f32> {
    let s = f.layers.x;
    if s <= 0.0 {
        return half_space;
    }
    var sum = vec2<f32>(0.0);
    var z = max(d, 0.0) + 0.5 * s;
    loop {
        if z >= f.h {
            break;
        }
        sum += plane_and_slope(z);
        z += s;
    }
    return f.layers.y * sum;
}
