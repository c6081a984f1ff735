//! The `voxd` binary's allocator: the system allocator for small blocks; every large block (at
//! least [`LARGE`] bytes) a mapping of its own, aligned to 2 MiB, marked for transparent huge
//! pages (`madvise(MADV_HUGEPAGE)`, Linux), and kept for reuse when freed, up to a bound.
//!
//! A volume's passes allocate arrays of tens of MiB (a 512³ mesh extraction's quads, offsets,
//! graph, positions and triangles), one after another, each freed before the next pass's.
//!
//! * **Huge pages.** A fresh mapping is filled by the kernel one page per fault: with 4 KiB
//!   pages the faults took a quarter of a 512³ extraction's time; with 2 MiB pages there are
//!   512 times fewer. Hosts whose `transparent_hugepage/enabled` is `madvise` (Debian's
//!   default) give them only to memory marked so; `always` gives them anyway, and `never`
//!   refuses them (the mark is then ignored).
//! * **Reuse.** Even in huge pages, every fresh page is cleared by the kernel (on this
//!   project's virtual machines that clearing was 40 % of a 512³ extraction's samples), while
//!   the previous pass has just freed pages that are already there. So a freed large block is
//!   kept (up to [`cache_limit`] bytes in all, `VOXD_LARGE_CACHE_MIB`, 256 by default; the
//!   oldest are unmapped first) and the next large block that fits in it takes it, its excess
//!   unmapped; a block asked zeroed is cleared by `memset`. A grown block is moved by `mremap`
//!   (its pages change address, nothing is copied).
//!
//! The memory kept is at most the bound above the memory in use; `VOXD_LARGE_CACHE_MIB=0`
//! keeps none, `VOXD_HUGE_PAGES=off` marks none (both read once, at the start of `main`, by
//! [`configure`]). Blocks are rounded up to 2 MiB.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Blocks at least this large are mappings of their own (smaller blocks come from the system
/// allocator's arenas).
pub const LARGE: usize = 4 << 20;

/// A huge page's size on x86-64 and on aarch64 with 4 KiB base pages.
const HUGE: usize = 2 << 20;

/// Freed large blocks kept at most (a fixed table: the allocator must not allocate).
const SLOTS: usize = 32;

static ON: AtomicBool = AtomicBool::new(true);
static CACHE_LIMIT: AtomicUsize = AtomicUsize::new(256 << 20);

/// The freed large blocks kept: (address, length), oldest first, and their total length.
struct Cache {
    blocks: [(usize, usize); SLOTS],
    len: usize,
    bytes: usize,
}

impl Cache {
    /// Takes kept block `i` out of the table: (address, length).
    fn remove(&mut self, i: usize) -> (usize, usize) {
        let b = self.blocks[i];
        self.blocks.copy_within(i + 1..self.len, i);
        self.len -= 1;
        self.bytes -= b.1;
        b
    }
}

static CACHE: Mutex<Cache> = Mutex::new(Cache {
    blocks: [(0, 0); SLOTS],
    len: 0,
    bytes: 0,
});

/// The system allocator, its large blocks on huge pages and reused (see the module doc).
pub struct HugePages;

/// Reads `VOXD_HUGE_PAGES` (`on`, the default, or `off`) and `VOXD_LARGE_CACHE_MIB` (the
/// bytes of freed large blocks kept, in MiB; 256 by default, 0 for none); call before any
/// thread starts. Returns an error naming the value when one is invalid.
pub fn configure() -> Result<(), String> {
    match std::env::var("VOXD_HUGE_PAGES").as_deref() {
        Err(_) | Ok("on") | Ok("1") => ON.store(true, Ordering::Relaxed),
        Ok("off") | Ok("0") => ON.store(false, Ordering::Relaxed),
        Ok(other) => return Err(format!("VOXD_HUGE_PAGES must be on or off, not {other:?}")),
    }
    if let Ok(v) = std::env::var("VOXD_LARGE_CACHE_MIB") {
        let mib: usize = v
            .parse()
            .ok()
            .filter(|&m: &usize| m <= 1 << 20)
            .ok_or_else(|| {
                format!("VOXD_LARGE_CACHE_MIB must be a number of MiB up to 1048576, not {v:?}")
            })?;
        CACHE_LIMIT.store(mib << 20, Ordering::Relaxed);
    }
    Ok(())
}

/// Whether large blocks are marked for huge pages.
pub fn enabled() -> bool {
    ON.load(Ordering::Relaxed)
}

/// The bytes of freed large blocks kept at most.
pub fn cache_limit() -> usize {
    CACHE_LIMIT.load(Ordering::Relaxed)
}

/// The bytes of freed large blocks kept now.
pub fn cached() -> usize {
    lock().bytes
}

/// Unmaps every freed large block kept (their memory goes back to the system).
pub fn release() {
    let mut c = lock();
    for &(p, len) in &c.blocks[..c.len] {
        unmap(p, len);
    }
    c.len = 0;
    c.bytes = 0;
}

fn lock() -> std::sync::MutexGuard<'static, Cache> {
    // A panic never happens under the lock (no allocation, no unwinding call): poisoning
    // cannot leave the table inconsistent.
    CACHE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Whether a block of `layout` is a large one (a mapping of its own; Linux only, elsewhere
/// every block is the system allocator's).
fn is_large(layout: &Layout) -> bool {
    cfg!(target_os = "linux") && layout.size() >= LARGE && layout.align() <= HUGE
}

/// A large block's mapped length.
fn span(size: usize) -> usize {
    size.next_multiple_of(HUGE)
}

fn unmap(p: usize, len: usize) {
    if len > 0 {
        // SAFETY: `[p, p + len)` is a mapping (or its tail) this allocator made and no live
        // block holds.
        unsafe { libc::munmap(p as *mut libc::c_void, len) };
    }
}

/// A fresh mapping of `len` bytes (a multiple of HUGE) aligned to HUGE, marked; 0 on failure.
fn map(len: usize) -> usize {
    let Some(total) = len.checked_add(HUGE) else {
        return 0;
    };
    // SAFETY: an anonymous private mapping at an address the kernel picks.
    let p = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            total,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
            -1,
            0,
        )
    };
    if p == libc::MAP_FAILED {
        return 0;
    }
    let p = p as usize;
    let start = p.next_multiple_of(HUGE);
    unmap(p, start - p);
    unmap(start + len, p + total - (start + len));
    mark(start, len);
    start
}

fn mark(p: usize, len: usize) {
    #[cfg(target_os = "linux")]
    if enabled() {
        // SAFETY: MADV_HUGEPAGE on a range of this allocator's mapping changes how its pages
        // are backed, never their contents. Its result is ignored: a kernel without
        // transparent huge pages refuses it, and the block is as good without.
        unsafe { libc::madvise(p as *mut libc::c_void, len, libc::MADV_HUGEPAGE) };
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (p, len);
}

/// A kept block cut or grown to `len` bytes, and how many of its first bytes were used before
/// (the rest is fresh, zero); (0, 0) if none is kept. The smallest that holds `len` (its
/// excess unmapped), else the largest, grown (its pages moved, only the rest fresh).
fn reuse(len: usize) -> (usize, usize) {
    let mut c = lock();
    let n = c.len;
    let fits = (0..n)
        .filter(|&i| c.blocks[i].1 >= len)
        .min_by_key(|&i| c.blocks[i].1);
    let Some(i) = fits.or_else(|| (0..n).max_by_key(|&i| c.blocks[i].1)) else {
        return (0, 0);
    };
    let (p, have) = c.remove(i);
    drop(c);
    if have >= len {
        unmap(p + len, have - len);
        return (p, len);
    }
    let q = grow(p, have, len);
    if q == 0 {
        unmap(p, have);
    }
    (q, have)
}

/// The mapping `[p, p + have)` grown to `len` bytes: in place if the addresses after it are
/// free, else moved to a fresh aligned range (mremap moves the pages: nothing is copied).
/// Returns its address, 0 on failure (the mapping is then left as it was).
#[cfg(target_os = "linux")]
fn grow(p: usize, have: usize, len: usize) -> usize {
    // SAFETY: `[p, p + have)` is one of this allocator's mappings, held by the caller.
    let q = unsafe { libc::mremap(p as *mut libc::c_void, have, len, 0) };
    if q != libc::MAP_FAILED {
        mark(p, len);
        return p;
    }
    let dst = map(len);
    if dst == 0 {
        return 0;
    }
    // SAFETY: moves the mapping onto `dst`, a mapping of `len` bytes made above for it
    // (MREMAP_FIXED replaces it).
    let q = unsafe {
        libc::mremap(
            p as *mut libc::c_void,
            have,
            len,
            libc::MREMAP_MAYMOVE | libc::MREMAP_FIXED,
            dst as *mut libc::c_void,
        )
    };
    if q == libc::MAP_FAILED {
        unmap(dst, len);
        return 0;
    }
    mark(dst, len);
    dst
}

/// Elsewhere there are no large blocks (`is_large`): never called, it fails.
#[cfg(not(target_os = "linux"))]
fn grow(_p: usize, _have: usize, _len: usize) -> usize {
    0
}

/// Keeps the freed block `[p, p + len)`, unmapping the oldest kept ones beyond the bound (or
/// this one, when it is over the bound alone).
fn keep(p: usize, len: usize) {
    let limit = cache_limit();
    if len > limit {
        unmap(p, len);
        return;
    }
    let mut c = lock();
    while c.len == SLOTS || c.bytes + len > limit {
        let (q, l) = c.remove(0);
        unmap(q, l);
    }
    let n = c.len;
    c.blocks[n] = (p, len);
    c.len += 1;
    c.bytes += len;
}

/// A large block of `size` bytes, zeroed if `zeroed`; null on failure.
fn large(size: usize, zeroed: bool) -> *mut u8 {
    let len = span(size);
    let (p, used) = reuse(len);
    if p != 0 {
        if zeroed {
            // SAFETY: the block is this allocator's, `len ≥ size` bytes, held by no one; its
            // bytes from `used` on are fresh (zero).
            unsafe { std::ptr::write_bytes(p as *mut u8, 0, size.min(used)) };
        }
        return p as *mut u8;
    }
    map(len) as *mut u8
}

// SAFETY: small blocks come from `System` and go back to it with the same layout; large ones
// are this allocator's own mappings of `span(size)` bytes, aligned to HUGE (so to any
// alignment `is_large` admits), each held by one block at a time.
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if is_large(&layout) {
            return large(layout.size(), false);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if is_large(&layout) {
            return large(layout.size(), true);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if is_large(&layout) {
            keep(ptr as usize, span(layout.size()));
            return;
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract: `new_size`, rounded to the alignment, fits an isize.
        let new = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
        match (is_large(&layout), is_large(&new)) {
            // SAFETY: the caller's contract, passed on.
            (false, false) => unsafe { System.realloc(ptr, layout, new_size) },
            (true, true) => {
                let (old, len) = (span(layout.size()), span(new_size));
                let p = ptr as usize;
                if len <= old {
                    unmap(p + len, old - len);
                    return ptr;
                }
                grow(p, old, len) as *mut u8
            }
            _ => {
                // Across the boundary: a new block, the contents copied, the old one freed.
                // SAFETY: `new` is a valid non-zero layout (the caller's contract).
                let q = unsafe { self.alloc(new) };
                if !q.is_null() {
                    // SAFETY: both blocks hold at least the smaller size; they are distinct.
                    unsafe {
                        std::ptr::copy_nonoverlapping(ptr, q, layout.size().min(new_size));
                        self.dealloc(ptr, layout);
                    }
                }
                q
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tests share the one cache: one at a time (the tests' own allocator is the system's,
    /// so nothing else uses it).
    static SERIAL: Mutex<()> = Mutex::new(());

    fn serial() -> std::sync::MutexGuard<'static, ()> {
        SERIAL.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The `VmFlags` of the mapping of this process that holds address `p` (Linux).
    #[cfg(target_os = "linux")]
    fn vm_flags(p: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut inside = false;
        for line in smaps.lines() {
            if let Some((range, _)) = line.split_once(' ')
                && let Some((lo, hi)) = range.split_once('-')
                && let (Ok(lo), Ok(hi)) =
                    (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
            {
                inside = lo <= p && p < hi;
            } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
                return Some(flags.trim().to_string());
            }
        }
        None
    }

    fn layout(size: usize) -> Layout {
        Layout::from_size_align(size, 64).unwrap()
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn a_large_block_is_aligned_and_marked_for_huge_pages() {
        let _s = serial();
        assert!(enabled());
        let a = HugePages;
        // SAFETY: non-zero size; freed with its layout below.
        let p = unsafe { a.alloc(layout(3 * LARGE + 5)) };
        assert!(!p.is_null());
        assert_eq!(p as usize % HUGE, 0);
        let flags = vm_flags(p as usize).expect("the block's mapping");
        // SAFETY: as allocated above.
        unsafe { a.dealloc(p, layout(3 * LARGE + 5)) };
        if !std::path::Path::new("/sys/kernel/mm/transparent_hugepage").exists() {
            eprintln!("SKIP the mark: this kernel has no transparent huge pages");
            return;
        }
        assert!(flags.split(' ').any(|f| f == "hg"), "VmFlags: {flags}");
    }

    #[test]
    fn the_allocator_gives_usable_zeroed_and_grown_blocks() {
        let _s = serial();
        let a = HugePages;
        for size in [64, LARGE - 64, LARGE, LARGE + 12345, 3 * HUGE] {
            // SAFETY: non-zero sizes; every block is freed with its layout.
            unsafe {
                let p = a.alloc_zeroed(layout(size));
                assert!(!p.is_null());
                let s = std::slice::from_raw_parts_mut(p, size);
                assert!(s.iter().all(|&b| b == 0));
                s.fill(9);
                // Grown across the threshold and beyond, then cut back: the contents stay.
                let q = a.realloc(p, layout(size), 5 * size);
                assert!(!q.is_null());
                let s = std::slice::from_raw_parts_mut(q, 5 * size);
                assert!(s[..size].iter().all(|&b| b == 9));
                s[5 * size - 1] = 7;
                let r = a.realloc(q, layout(5 * size), size / 2);
                assert!(
                    std::slice::from_raw_parts(r, size / 2)
                        .iter()
                        .all(|&b| b == 9)
                );
                a.dealloc(r, layout(size / 2));
            }
        }
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn a_freed_block_is_reused_cleared_and_the_cache_is_bounded() {
        let _s = serial();
        let a = HugePages;
        release();
        // SAFETY: non-zero sizes; every block is freed with its layout; the slices are read
        // while their blocks are held.
        unsafe {
            // Freed dirty, taken again zeroed: the same pages, cleared.
            let p = a.alloc(layout(2 * LARGE));
            std::slice::from_raw_parts_mut(p, 2 * LARGE).fill(0xa5);
            a.dealloc(p, layout(2 * LARGE));
            assert_eq!(cached(), 2 * LARGE);
            let q = a.alloc_zeroed(layout(LARGE + 1));
            assert_eq!(q, p, "the kept block, cut");
            assert_eq!(cached(), 0);
            assert!(
                std::slice::from_raw_parts(q, LARGE + 1)
                    .iter()
                    .all(|&b| b == 0)
            );
            std::slice::from_raw_parts_mut(q, LARGE + 1).fill(0x5a);
            a.dealloc(q, layout(LARGE + 1));
            // A larger block grows the kept one: its first part cleared, the rest fresh.
            let r = a.alloc_zeroed(layout(5 * LARGE));
            assert!(!r.is_null());
            assert_eq!(r as usize % HUGE, 0);
            assert!(
                std::slice::from_raw_parts(r, 5 * LARGE)
                    .iter()
                    .all(|&b| b == 0)
            );
            assert_eq!(cached(), 0);
            a.dealloc(r, layout(5 * LARGE));
            // Never more kept than the bound (blocks larger than it are unmapped at once).
            let big = cache_limit() / 3 + HUGE;
            let blocks: Vec<_> = (0..4).map(|_| a.alloc(layout(big))).collect();
            for &b in &blocks {
                assert!(!b.is_null());
                a.dealloc(b, layout(big));
                assert!(cached() <= cache_limit());
            }
            assert_eq!(cached(), 2 * span(big));
            // One over the bound takes a kept block (grown) and is not kept when freed.
            let huge = a.alloc(layout(cache_limit() + 1));
            assert_eq!(cached(), span(big));
            a.dealloc(huge, layout(cache_limit() + 1));
            assert_eq!(cached(), span(big));
        }
        release();
        assert_eq!(cached(), 0);
    }
}
