// solid, step 1: toggle one bit per (column, triangle) crossing. One invocation per work item
// (a triangle and a tile of at most 1024 columns inside the slab), so no invocation comes near
// lavapipe's 65,535-iteration loop cap. Tie rules identical to src/engine/cpu/solid.rs: the
// triangle is oriented counter-clockwise in xy, a centre is inside iff each edge function
// w > 0, or w == 0 on an edge with d.y > 0 || (d.y == 0 && d.x < 0); the toggle goes to the
// smallest k with (2k+1)·128·A > Σ w_i z_i, found exactly by binary search.

// MASKS: instead of one toggle bit per crossing (and a prefix-XOR pass afterwards), XOR every
// voxel above the crossing directly: a partial mask into the crossing's word and all ones into
// the words above, clipped at Z. Chosen on the host (src/engine/gpu/mod.rs says which is used).
override MASKS: bool = false;

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

fn edge_fn(a: vec3<i64>, b: vec3<i64>, px: i64, py: i64) -> i64 {
    return (b.x - a.x) * (py - a.y) - (b.y - a.y) * (px - a.x);
}

fn edge_bias(a: vec3<i64>, b: vec3<i64>) -> i64 {
    let dx = b.x - a.x;
    let dy = b.y - a.y;
    return select(1li, 0li, dy > 0li || (dy == 0li && dx < 0li));
}

// Smallest k in [0, Z] with (2k+1)·128·A > num (Z when none).
fn first_voxel_above(num: I128, area2: i64) -> u32 {
    var lo = 0u;
    var hi = params.dims.z;
    for (var it = 0u; it < 24u && lo < hi; it++) {
        let mid = (lo + hi) / 2u;
        let lhs = mul_u64_wide(u64(2u * mid + 1u) * 128lu, u64(area2));
        if (less128(num, lhs)) { hi = mid; } else { lo = mid + 1u; }
    }
    return lo;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let id = linear_id(gid);
    if (id >= params.item_count) { return; }
    let it = (params.item_offset + id) * 4u;
    let t = items[it];
    let x0 = items[it + 1u];
    let y0 = items[it + 2u];
    let nx = items[it + 3u] >> 16u;
    let ny = items[it + 3u] & 0xffffu;

    var v0 = vertex(t, 0u);
    var v1 = vertex(t, 1u);
    var v2 = vertex(t, 2u);
    var area2 = (v1.x - v0.x) * (v2.y - v0.y) - (v1.y - v0.y) * (v2.x - v0.x);
    if (area2 == 0li) { return; }
    if (area2 < 0li) {
        let tmp = v1; v1 = v2; v2 = tmp;
        area2 = -area2;
    }
    let b0 = edge_bias(v1, v2);
    let b1 = edge_bias(v2, v0);
    let b2 = edge_bias(v0, v1);
    let wpc = params.words_per_column;
    for (var i = 0u; i < nx; i++) {
        let x = x0 + i;
        let px = i64(x) * FIXED_ONE + FIXED_HALF;
        for (var j = 0u; j < ny; j++) {
            let y = y0 + j;
            let py = i64(y) * FIXED_ONE + FIXED_HALF;
            let w0 = edge_fn(v1, v2, px, py);
            let w1 = edge_fn(v2, v0, px, py);
            let w2 = edge_fn(v0, v1, px, py);
            if (w0 >= b0 && w1 >= b1 && w2 >= b2) {
                let num = add128(add128(mul_i64_wide(w0, v0.z), mul_i64_wide(w1, v1.z)), mul_i64_wide(w2, v2.z));
                let k = first_voxel_above(num, area2);
                if (k < params.dims.z) {
                    let col = (x - params.slab_x0) * params.dims.y + y;
                    if (MASKS) {
                        let last = (params.dims.z - 1u) / 32u;
                        for (var w = k / 32u; w <= last; w++) {
                            var m = 0xffffffffu;
                            if (w == k / 32u) { m = m << (k % 32u); }
                            let top = params.dims.z - w * 32u;
                            if (top < 32u) { m &= (1u << top) - 1u; }
                            atomicXor(&words[col * wpc + w], m);
                        }
                    } else {
                        atomicXor(&words[col * wpc + k / 32u], 1u << (k % 32u));
                    }
                }
            }
        }
    }
}
