// `RayPush::acceleration_at` on the GPU: the push near a ray (the demo's
// Ctrl+drag). Expects a uniform `f` with `push_origin` (a point on the ray,
// the radius in w; 0: no push), `push_dir` (unit) and `push_accel`.

fn push_acceleration(x: vec3<f32>) -> vec3<f32> {
    let reach = f.push_origin.w;
    if reach <= 0.0 {
        return vec3<f32>(0.0);
    }
    let d = x - f.push_origin.xyz;
    let off = d - dot(d, f.push_dir.xyz) * f.push_dir.xyz;
    let q = dot(off, off) / (reach * reach);
    if q >= 1.0 {
        return vec3<f32>(0.0);
    }
    return f.push_accel.xyz * ((1.0 - q) * (1.0 - q));
}
