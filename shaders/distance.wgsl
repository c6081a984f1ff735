// distance: set every voxel whose centre lies within params.thickness lattice units of the
// triangle, exactly as src/engine/geom/lattice.rs `compare` decides it (ties set): the least of
// the vertices, the edges whose interior holds the centre's foot, and the plane when the
// triangle has an area and the centre projects into it, each squared distance compared with t²
// in integers (128-bit for the edges, 256-bit for the plane). One invocation per work item (a
// triangle and a tile of at most 1024 voxels of its bounding box dilated by t, tiles far from
// its plane left out on the host: src/engine/gpu/work.rs).
//
// Magnitudes (coordinates ≤ 2^29, differences ≤ 2^30): dot products of differences < 2^62
// (i64); cross products < 2^62 (i64); their squares and n·(e × w) < 2^125 (I128); t ≤ 2^13.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> tris: array<i32>;
@group(0) @binding(2) var<storage, read> items: array<u32>;
@group(0) @binding(3) var<storage, read_write> words: array<atomic<u32>>;

fn vertex(t: u32, v: u32) -> vec3<i64> {
    let b = t * 9u + v * 3u;
    return vec3<i64>(widen(tris[b]), widen(tris[b + 1u]), widen(tris[b + 2u]));
}

fn dot64(a: vec3<i64>, b: vec3<i64>) -> i64 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

fn cross64(a: vec3<i64>, b: vec3<i64>) -> vec3<i64> {
    return vec3<i64>(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

fn dot128(a: vec3<i64>, b: vec3<i64>) -> I128 {
    return add128(add128(mul_i64_wide(a.x, b.x), mul_i64_wide(a.y, b.y)), mul_i64_wide(a.z, b.z));
}

// Vertex a, or the interior of edge a→b, within t of p (t2 = t²)?
fn near_vertex_or_edge(p: vec3<i64>, a: vec3<i64>, b: vec3<i64>, t2: i64) -> bool {
    let w = p - a;
    if (dot64(w, w) <= t2) { return true; }
    let d = b - a;
    let wd = dot64(w, d);
    let dd = dot64(d, d);
    if (wd > 0li && wd < dd) {
        // |w × d|² / |d|² ≤ t²
        let c = cross64(w, d);
        return !less128(mul_u64_wide(u64(t2), u64(dd)), dot128(c, c));
    }
    return false;
}

// Is p on the inner side of edge a→b (n the triangle's normal)?
fn inner(p: vec3<i64>, a: vec3<i64>, b: vec3<i64>, n: vec3<i64>) -> bool {
    return !is_negative128(dot128(n, cross64(b - a, p - a)));
}

fn within(p: vec3<i64>, v0: vec3<i64>, v1: vec3<i64>, v2: vec3<i64>, n: vec3<i64>, t2: i64) -> bool {
    if (near_vertex_or_edge(p, v0, v1, t2) || near_vertex_or_edge(p, v1, v2, t2) || near_vertex_or_edge(p, v2, v0, t2)) {
        return true;
    }
    if (all(n == vec3<i64>(0li)) || !(inner(p, v0, v1, n) && inner(p, v1, v2, n) && inner(p, v2, v0, n))) {
        return false;
    }
    // (n·(p − v0))² ≤ t²·|n|²
    var q = dot128(n, p - v0);
    if (is_negative128(q)) { q = neg128(q); }
    let nn = dot128(n, n);
    return !less256(mul_u128_wide(I128(u64(t2), 0lu), nn), mul_u128_wide(q, q));
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
    let n = cross64(v1 - v0, v2 - v0);
    let th = i64(params.thickness);
    let t2 = th * th;
    // The triangle's bounding box: a centre farther than t from it is farther from the triangle.
    let lo = min(v0, min(v1, v2));
    let hi = max(v0, max(v1, v2));
    let wpc = params.words_per_column;
    for (var i = 0u; i < nx; i++) {
        let x = x0 + i;
        for (var j = 0u; j < ny; j++) {
            let y = y0 + j;
            let col = (x - params.slab_x0) * params.dims.y + y;
            for (var k = 0u; k < nz; k++) {
                let z = z0 + k;
                let c = vec3<i64>(i64(x), i64(y), i64(z)) * FIXED_ONE + vec3<i64>(FIXED_HALF);
                let g = max(max(lo - c, c - hi), vec3<i64>(0li));
                if (dot64(g, g) > t2) { continue; }
                if (within(c, v0, v1, v2, n, t2)) {
                    atomicOr(&words[col * wpc + z / 32u], 1u << (z % 32u));
                }
            }
        }
    }
}
