// surface: set every voxel whose closed box the triangle touches. One invocation per work item
// (a triangle and a tile of at most 1024 voxels); every voxel of the tile gets the exact
// 13-axis separating-axis test of src/engine/cpu/surface.rs (i64 projections, 128-bit for the
// triangle normal). Zero axes never separate, so degenerate triangles work as segments/points.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> tris: array<i32>;
@group(0) @binding(2) var<storage, read> items: array<u32>;
@group(0) @binding(3) var<storage, read_write> words: array<atomic<u32>>;

// Vertex v of triangle t (WGSL cannot pass storage pointers to functions, so each kernel that
// binds `tris` has this accessor).
fn vertex(t: u32, v: u32) -> vec3<i64> {
    let b = t * 9u + v * 3u;
    return vec3<i64>(widen(tris[b]), widen(tris[b + 1u]), widen(tris[b + 2u]));
}

fn separates(p0: i64, p1: i64, p2: i64, r: i64) -> bool {
    return min(p0, min(p1, p2)) > r || max(p0, max(p1, p2)) < -r;
}

// Axis e × x̂ = (0, e.z, −e.y), e × ŷ = (−e.z, 0, e.x), e × ẑ = (e.y, −e.x, 0).
fn edge_axes_separate(e: vec3<i64>, a: vec3<i64>, b: vec3<i64>, c: vec3<i64>) -> bool {
    let rx = FIXED_HALF * (abs(e.z) + abs(e.y));
    if (separates(e.z * a.y - e.y * a.z, e.z * b.y - e.y * b.z, e.z * c.y - e.y * c.z, rx)) { return true; }
    let ry = FIXED_HALF * (abs(e.z) + abs(e.x));
    if (separates(e.x * a.z - e.z * a.x, e.x * b.z - e.z * b.x, e.x * c.z - e.z * c.x, ry)) { return true; }
    let rz = FIXED_HALF * (abs(e.y) + abs(e.x));
    return separates(e.y * a.x - e.x * a.y, e.y * b.x - e.x * b.y, e.y * c.x - e.x * c.y, rz);
}

fn overlaps(v0: vec3<i64>, v1: vec3<i64>, v2: vec3<i64>, n: vec3<i64>, c: vec3<i64>) -> bool {
    let a = v0 - c;
    let b = v1 - c;
    let d = v2 - c;
    if (separates(a.x, b.x, d.x, FIXED_HALF) || separates(a.y, b.y, d.y, FIXED_HALF) || separates(a.z, b.z, d.z, FIXED_HALF)) {
        return false;
    }
    // |n · a| > 128 · (|nx| + |ny| + |nz|)
    var dot = add128(add128(mul_i64_wide(n.x, a.x), mul_i64_wide(n.y, a.y)), mul_i64_wide(n.z, a.z));
    if (is_negative128(dot)) { dot = neg128(dot); }
    let r = mul_u64_wide(128lu, abs64(n.x) + abs64(n.y) + abs64(n.z));
    if (less128(r, dot)) { return false; }
    return !(edge_axes_separate(v1 - v0, a, b, d) || edge_axes_separate(v2 - v1, a, b, d) || edge_axes_separate(v0 - v2, a, b, d));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let id = linear_id(gid);
    if (id >= params.item_count) { return; }
    let it = (params.item_offset + id) * 5u;
    let t = items[it];
    let x0 = items[it + 1u];
    let y0 = items[it + 2u];
    let z0 = items[it + 3u];
    let size = items[it + 4u];
    let nx = size >> 20u;
    let ny = (size >> 10u) & 0x3ffu;
    let nz = size & 0x3ffu;
    let v0 = vertex(t, 0u);
    let v1 = vertex(t, 1u);
    let v2 = vertex(t, 2u);
    let e0 = v1 - v0;
    let e2 = v2 - v0;
    let n = vec3<i64>(e0.y * e2.z - e0.z * e2.y, e0.z * e2.x - e0.x * e2.z, e0.x * e2.y - e0.y * e2.x);
    let wpc = params.words_per_column;
    for (var i = 0u; i < nx; i++) {
        let x = x0 + i;
        for (var j = 0u; j < ny; j++) {
            let y = y0 + j;
            let col = (x - params.slab_x0) * params.dims.y + y;
            for (var k = 0u; k < nz; k++) {
                let z = z0 + k;
                let c = vec3<i64>(i64(x), i64(y), i64(z)) * FIXED_ONE + vec3<i64>(FIXED_HALF);
                if (overlaps(v0, v1, v2, n, c)) {
                    atomicOr(&words[col * wpc + z / 32u], 1u << (z % 32u));
                }
            }
        }
    }
}
