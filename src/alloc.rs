//! The `voxd` binary's allocator: the system allocator, with every large block (at least
//! [`LARGE`] bytes) marked for transparent huge pages (`madvise(MADV_HUGEPAGE)`, Linux).
//!
//! A volume's passes allocate arrays of tens of MiB (a 512³ mesh extraction's quads, sums,
//! positions and triangles), which the system allocator maps fresh and the kernel then fills
//! one 4 KiB page per fault: at 512³ the faults took a quarter of the extraction's time. With
//! 2 MiB pages there are 512 times fewer. Hosts whose `transparent_hugepage/enabled` is
//! `madvise` (Debian's default) give them only to memory marked so; `always` gives them
//! anyway, and `never` refuses them (the mark is then ignored). Where huge pages are taken
//! the memory is the same, rounded to 2 MiB within large blocks only.
//!
//! With huge pages on, [`configure`] also fixes glibc's mmap threshold at [`LARGE`]: every
//! large block is then a mapping of its own, returned to the system when freed. (glibc would
//! otherwise raise the threshold after the first large frees and serve later large blocks from
//! its heaps, whose marked ranges would stay marked under the small blocks that reuse them,
//! and fragment the heaps' mappings.)
//!
//! `VOXD_HUGE_PAGES=off` (read once, at the start of `main`, by [`configure`]) leaves every
//! block, and glibc's threshold, as the system allocator has them.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, Ordering};

/// Blocks at least this large are marked (one system call each; smaller blocks come from the
/// allocator's reused arenas, where the mark would be wasted).
pub const LARGE: usize = 4 << 20;

/// A huge page's size on x86-64 and on aarch64 with 4 KiB base pages.
const HUGE: usize = 2 << 20;

static ON: AtomicBool = AtomicBool::new(true);

/// The system allocator, its large blocks marked for huge pages (see the module doc).
pub struct HugePages;

/// Reads `VOXD_HUGE_PAGES` (`on`, the default, or `off`); call before any thread starts.
/// Returns an error naming the value when it is neither.
pub fn configure() -> Result<(), String> {
    match std::env::var("VOXD_HUGE_PAGES").as_deref() {
        Err(_) | Ok("on") | Ok("1") => ON.store(true, Ordering::Relaxed),
        Ok("off") | Ok("0") => {
            ON.store(false, Ordering::Relaxed);
            return Ok(());
        }
        Ok(other) => return Err(format!("VOXD_HUGE_PAGES must be on or off, not {other:?}")),
    }
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter (under glibc's own lock); LARGE fits
    // in an int. Its result (1 on success) is ignored: the default threshold only means large
    // blocks may come from the heaps, still marked.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, LARGE as libc::c_int)
    };
    Ok(())
}

/// Whether large blocks are marked.
pub fn enabled() -> bool {
    ON.load(Ordering::Relaxed)
}

/// The whole huge pages inside `[p, p + len)`: (start, length), length 0 when there is none.
fn inner_pages(p: usize, len: usize) -> (usize, usize) {
    let start = p.next_multiple_of(HUGE);
    let end = (p + len) / HUGE * HUGE;
    (start, end.saturating_sub(start))
}

fn mark(p: *mut u8, len: usize) {
    if p.is_null() || len < LARGE || !enabled() {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        let (start, n) = inner_pages(p as usize, len);
        if n > 0 {
            // SAFETY: the range lies inside the block just allocated (whole pages of it);
            // MADV_HUGEPAGE changes how its pages are backed, never their contents. Its result
            // is ignored: a kernel without huge pages refuses it, and the block stays as it is.
            unsafe { libc::madvise(start as *mut libc::c_void, n, libc::MADV_HUGEPAGE) };
        }
    }
}

// SAFETY: every block comes from `System` and goes back to it with the same layout; `mark`
// only advises the kernel about pages inside a live block.
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.alloc(layout) };
        mark(p, layout.size());
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.alloc_zeroed(layout) };
        mark(p, layout.size());
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if new_size > layout.size() {
            mark(p, new_size);
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_whole_huge_pages_inside_the_block_are_marked() {
        // A block starting just past a page boundary and ending just before another: the
        // pages strictly inside.
        assert_eq!(inner_pages(HUGE + 16, 3 * HUGE), (2 * HUGE, 2 * HUGE));
        assert_eq!(inner_pages(HUGE + 16, 3 * HUGE - 32), (2 * HUGE, HUGE));
        assert_eq!(inner_pages(2 * HUGE, 2 * HUGE), (2 * HUGE, 2 * HUGE));
        // Under one whole page inside: nothing.
        assert_eq!(inner_pages(HUGE + 1, HUGE + 100).1, 0);
        assert_eq!(inner_pages(7, 100).1, 0);
    }

    /// The `VmFlags` of the mapping of this process that holds address `p` (Linux).
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

    #[test]
    fn a_large_block_is_marked_for_huge_pages() {
        if !std::path::Path::new("/sys/kernel/mm/transparent_hugepage").exists() {
            eprintln!("SKIP: this kernel has no transparent huge pages");
            return;
        }
        assert!(enabled());
        let a = HugePages;
        let layout = Layout::from_size_align(3 * LARGE, 64).unwrap();
        // SAFETY: non-zero size; freed with its layout below.
        let p = unsafe { a.alloc(layout) };
        assert!(!p.is_null());
        let (start, n) = inner_pages(p as usize, 3 * LARGE);
        assert!(n >= HUGE);
        let flags = vm_flags(start).expect("the block's mapping");
        // SAFETY: as allocated above.
        unsafe { a.dealloc(p, layout) };
        assert!(flags.split(' ').any(|f| f == "hg"), "VmFlags: {flags}");
    }

    #[test]
    fn the_allocator_gives_usable_zeroed_and_grown_blocks() {
        let a = HugePages;
        for size in [64, LARGE, LARGE + 12345, 3 * HUGE] {
            let layout = Layout::from_size_align(size, 64).unwrap();
            // SAFETY: non-zero size; every block is freed with its layout.
            unsafe {
                let p = a.alloc_zeroed(layout);
                assert!(!p.is_null());
                let s = std::slice::from_raw_parts_mut(p, size);
                assert!(s.iter().all(|&b| b == 0));
                s[size - 1] = 7;
                let q = a.realloc(p, layout, 2 * size);
                assert!(!q.is_null());
                assert_eq!(*q.add(size - 1), 7);
                a.dealloc(q, Layout::from_size_align(2 * size, 64).unwrap());
            }
        }
    }
}
