// Shared by every voxd kernel (prepended by src/engine/gpu/mod.rs). Exact integer arithmetic on
// the 1/256-voxel lattice: i64 for edge functions and projections, 128-bit (two u64 halves, two's
// complement) where products exceed 64 bits. Needs SHADER_INT64.

const FIXED_ONE: i64 = 256li;
const FIXED_HALF: i64 = 128li;
const MASK32: u64 = 0xfffffffflu;

struct Params {
    dims: vec3<u32>,          // grid X, Y, Z
    slab_x0: u32,             // first x-row of the slab in the buffer
    slab_rows: u32,           // x-rows in the slab
    words_per_column: u32,    // u32 words per column (even)
    item_count: u32,
    item_offset: u32,         // first item of this dispatch in the items buffer
    thickness: u32,           // distance: the threshold in lattice units (0 for the others)
}

// value = hi * 2^64 + lo, two's complement.
struct I128 { lo: u64, hi: u64 }

fn mul_u64_wide(a: u64, b: u64) -> I128 {
    let a0 = a & MASK32; let a1 = a >> 32u;
    let b0 = b & MASK32; let b1 = b >> 32u;
    let p00 = a0 * b0; let p01 = a0 * b1; let p10 = a1 * b0; let p11 = a1 * b1;
    let mid = (p00 >> 32u) + (p01 & MASK32) + (p10 & MASK32);
    return I128((p00 & MASK32) | (mid << 32u), p11 + (p01 >> 32u) + (p10 >> 32u) + (mid >> 32u));
}

fn neg128(a: I128) -> I128 {
    let lo = ~a.lo + 1lu;
    var hi = ~a.hi;
    if (lo == 0lu) { hi += 1lu; }
    return I128(lo, hi);
}

fn abs64(a: i64) -> u64 {
    if (a < 0li) { return u64(-a); }
    return u64(a);
}

// Exact a * b for |a|, |b| < 2^63.
fn mul_i64_wide(a: i64, b: i64) -> I128 {
    let p = mul_u64_wide(abs64(a), abs64(b));
    if ((a < 0li) != (b < 0li)) { return neg128(p); }
    return p;
}

fn add128(a: I128, b: I128) -> I128 {
    let lo = a.lo + b.lo;
    var hi = a.hi + b.hi;
    if (lo < a.lo) { hi += 1lu; }
    return I128(lo, hi);
}

// Signed a < b.
const SIGN64: u64 = 0x8000000000000000lu;

fn less128(a: I128, b: I128) -> bool {
    // Signed order of the high halves is unsigned order with the sign bit flipped.
    let ah = a.hi ^ SIGN64;
    let bh = b.hi ^ SIGN64;
    return ah < bh || (ah == bh && a.lo < b.lo);
}

fn is_negative128(a: I128) -> bool {
    return (a.hi & SIGN64) != 0lu;
}

// i32 → i64 with the sign extended explicitly: lavapipe's conversion of negative i32 values to
// i64 zero-extends (measured: -256 became 4294967040).
fn widen(v: i32) -> i64 {
    var r = i64(v & 0x7fffffff);
    if (v < 0) { r -= 2147483648li; }
    return r;
}

// Linear invocation index of a 2D dispatch of 64-wide workgroups (65535 groups per row).
fn linear_id(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * 65535u * 64u;
}

// value = w3 * 2^192 + w2 * 2^128 + w1 * 2^64 + w0, unsigned.
struct U256 { w0: u64, w1: u64, w2: u64, w3: u64 }

// a + b + c (c ≤ 2) as (sum mod 2^64, carry).
fn adc(a: u64, b: u64, c: u64) -> vec2<u64> {
    let s = a + b;
    let s2 = s + c;
    return vec2<u64>(s2, select(0lu, 1lu, s < a) + select(0lu, 1lu, s2 < s));
}

// Exact a * b of unsigned 128-bit values (the I128 halves read as unsigned).
fn mul_u128_wide(a: I128, b: I128) -> U256 {
    let p0 = mul_u64_wide(a.lo, b.lo);
    let p1 = mul_u64_wide(a.lo, b.hi);
    let p2 = mul_u64_wide(a.hi, b.lo);
    let p3 = mul_u64_wide(a.hi, b.hi);
    let r1 = adc(p0.hi, p1.lo, 0lu);
    let r1b = adc(r1.x, p2.lo, 0lu);
    let r2 = adc(p1.hi, p2.hi, r1.y + r1b.y);
    let r2b = adc(r2.x, p3.lo, 0lu);
    return U256(p0.lo, r1b.x, r2b.x, p3.hi + r2.y + r2b.y);
}

// Unsigned a < b.
fn less256(a: U256, b: U256) -> bool {
    if (a.w3 != b.w3) { return a.w3 < b.w3; }
    if (a.w2 != b.w2) { return a.w2 < b.w2; }
    if (a.w1 != b.w1) { return a.w1 < b.w1; }
    return a.w0 < b.w0;
}
