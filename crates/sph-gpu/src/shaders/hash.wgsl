// Shared by every pass that walks the grid: cells of size h hashed into a
// power-of-two table (Teschner et al. 2003's primes).

fn cell_at(x: vec3<f32>, inv_h: f32) -> vec3<i32> {
    return vec3<i32>(floor(x * inv_h));
}

// A grid over a box (`GpuGrid::in_box`) gives each of the box's cells its
// own bucket, x fastest, so that neighbouring cells are neighbouring buckets
// and a cell-ordered sweep walks space. Cells outside the box wrap around
// onto cells inside (callers keep only their own cell's particles, as they
// do for hash collisions).
override BOX_CELLS: bool = false;
override BOX_MIN_X: i32 = 0;
override BOX_MIN_Y: i32 = 0;
override BOX_MIN_Z: i32 = 0;
override BOX_DIM_X: i32 = 1;
override BOX_DIM_Y: i32 = 1;
override BOX_DIM_Z: i32 = 1;

fn bucket_of(c: vec3<i32>, table: u32) -> u32 {
    if BOX_CELLS {
        let dims = vec3<i32>(BOX_DIM_X, BOX_DIM_Y, BOX_DIM_Z);
        let r = ((c - vec3<i32>(BOX_MIN_X, BOX_MIN_Y, BOX_MIN_Z)) % dims + dims) % dims;
        return u32(r.x + dims.x * (r.y + dims.y * r.z));
    }
    let u = bitcast<vec3<u32>>(c);
    return ((u.x * 73856093u) ^ (u.y * 19349663u) ^ (u.z * 83492791u)) & (table - 1u);
}
