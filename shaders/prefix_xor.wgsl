// solid, step 2: turn toggles into parity, one invocation per column of the slab: bit k becomes
// the XOR of the toggles at 0..=k; bits at k >= Z are cleared.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> words: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let col = linear_id(gid);
    if (col >= params.slab_rows * params.dims.y) { return; }
    let wpc = params.words_per_column;
    let z = params.dims.z;
    var carry = 0u;
    for (var w = 0u; w < wpc; w++) {
        var x = words[col * wpc + w];
        x ^= x << 1u;
        x ^= x << 2u;
        x ^= x << 4u;
        x ^= x << 8u;
        x ^= x << 16u;
        x ^= carry;
        carry = select(0u, 0xffffffffu, (x >> 31u) == 1u);
        let first = w * 32u;
        if (first >= z) {
            x = 0u;
        } else if (z - first < 32u) {
            x &= (1u << (z - first)) - 1u;
        }
        words[col * wpc + w] = x;
    }
}
