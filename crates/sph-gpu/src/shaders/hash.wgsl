// Shared by every pass that walks the grid: cells of size h hashed into a
// power-of-two table (Teschner et al. 2003's primes).

fn cell_at(x: vec3<f32>, inv_h: f32) -> vec3<i32> {
    return vec3<i32>(floor(x * inv_h));
}

fn bucket_of(c: vec3<i32>, table: u32) -> u32 {
    let u = bitcast<vec3<u32>>(c);
    return ((u.x * 73856093u) ^ (u.y * 19349663u) ^ (u.z * 83492791u)) & (table - 1u);
}
