// conservative = solid | surface, interior = solid & !surface, word by word, into `a`.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> a: array<u32>;
@group(0) @binding(2) var<storage, read> b: array<u32>;

override SUBTRACT: bool = false;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = linear_id(gid);
    if (i >= params.slab_rows * params.dims.y * params.words_per_column) { return; }
    a[i] = select(a[i] | b[i], a[i] & ~b[i], SUBTRACT);
}
