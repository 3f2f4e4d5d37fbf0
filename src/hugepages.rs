//! A global allocator that asks Linux for transparent huge pages on large
//! blocks.
//!
//! `dxf2chains` touches about 100 MB of fresh memory for a 35 MB drawing,
//! much of it in a few large arrays (the pieces, the nodes' tables, the
//! output text): some 26,000 page faults of 4 KiB, each a trip into the
//! kernel on whichever core touches the page first. Debian's kernels give
//! huge pages only where a program asks (`transparent_hugepage` set to
//! `madvise`), and glibc asks only when told to by `GLIBC_TUNABLES`, which a
//! program cannot set for itself once started. So this allocator asks: every
//! block of [`THRESHOLD`] bytes or more gets `madvise(MADV_HUGEPAGE)`.
//! Smaller blocks, and other systems, are [`System`]'s alone. Advice never
//! changes what memory holds, only how the kernel backs it; when the kernel
//! says no, nothing changes.
//!
//! A binary opts in with
//! `#[global_allocator] static ALLOC: microcam::hugepages::HugePages = microcam::hugepages::HugePages;`
//! The figures are in docs/dxf.md ("Huge pages").

use std::alloc::{GlobalAlloc, Layout, System};

/// The kernel's transparent huge page size on x86-64 and most arm64 kernels.
const HUGE_PAGE: usize = 2 << 20;

/// The base page size `madvise` ranges are aligned to.
const PAGE: usize = 4096;

/// Blocks at least this large are advised. A huge page is backed whole once
/// any byte of it is touched, so a block grown ahead of its use (a vector's
/// spare capacity) holds up to 2 MiB more than with small pages: advising
/// from 4 MiB raised `dxf2chains`' peak memory by 3 MiB (1.87x to 1.96x the
/// mix benchmark drawing, against a limit of 2x) for no more speed than
/// from 8 MiB, which leaves the peak as it was.
pub const THRESHOLD: usize = 4 * HUGE_PAGE;

/// [`System`], plus huge-page advice on blocks of [`THRESHOLD`] bytes or more.
pub struct HugePages;

// SAFETY: every call is passed to `System` unchanged; `advise` only hints
// at how already allocated memory is backed and never touches its contents.
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc`, passed on.
        let block = unsafe { System.alloc(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc_zeroed`, passed on.
        let block = unsafe { System.alloc_zeroed(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn dealloc(&self, block: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract for `dealloc`, passed on.
        unsafe { System.dealloc(block, layout) }
    }

    unsafe fn realloc(&self, block: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract for `realloc`, passed on.
        let moved = unsafe { System.realloc(block, layout, new_size) };
        // A growing vector is advised again at each size: the new tail is
        // not yet advised, and advising the head twice costs one system call.
        if new_size > layout.size() {
            advise(moved, new_size);
        }
        moved
    }
}

/// Ask for huge pages on the block of `len` bytes at `block`, widened to
/// whole 4 KiB pages.
///
/// Widened, not narrowed to whole huge pages: glibc maps a large block on its
/// own, 16 bytes of header before it and the rest of the last page after it,
/// so the widened range is exactly that mapping, and the advice covers it
/// without splitting it. A split mapping would defeat `realloc`, which glibc
/// grows with `mremap` only within one mapping (it would copy instead). The
/// kernel itself uses huge pages only on the 2 MiB pages wholly inside.
fn advise(block: *mut u8, len: usize) {
    if block.is_null() || len < THRESHOLD {
        return;
    }
    let (start, end) = pages_around(block as usize, len);
    #[cfg(target_os = "linux")]
    // SAFETY: [start, end) is page-aligned and lies within the pages of the
    // block just allocated (and its allocator's header), and MADV_HUGEPAGE
    // does not change any memory's contents. The result is ignored: a kernel
    // without huge pages says EINVAL, and the memory works as before.
    unsafe {
        libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (start, end);
}

/// Smallest range of whole pages holding `[addr, addr + len)`.
fn pages_around(addr: usize, len: usize) -> (usize, usize) {
    let start = addr / PAGE * PAGE;
    let end = (addr + len).div_ceil(PAGE) * PAGE;
    (start, end)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn advice_covers_the_block_widened_to_whole_pages() {
        // glibc's own mapping for a large block: 16 bytes of header, then the
        // block, then the rest of the last page. The advice is that mapping.
        let map = 0x7f00_0000_0000;
        assert_eq!(pages_around(map + 16, 3 * PAGE), (map, map + 4 * PAGE));
        assert_eq!(pages_around(map + 16, 3 * PAGE - 16), (map, map + 3 * PAGE));
        // Page-aligned block: itself.
        assert_eq!(pages_around(map, 2 * PAGE), (map, map + 2 * PAGE));
    }

    #[test]
    fn large_blocks_hold_what_was_written_through_growth() {
        let a = HugePages;
        let small = Layout::from_size_align(1024, 8).unwrap();
        let big = THRESHOLD + 12345;
        unsafe {
            let p = a.alloc(small);
            assert!(!p.is_null());
            for i in 0..1024 {
                *p.add(i) = (i % 251) as u8;
            }
            // Grow across the threshold, then again: contents kept.
            let p = a.realloc(p, small, big);
            assert!(!p.is_null());
            let big_layout = Layout::from_size_align(big, 8).unwrap();
            for i in 1024..big {
                *p.add(i) = (i % 251) as u8;
            }
            let p = a.realloc(p, big_layout, 3 * big);
            assert!(!p.is_null());
            assert!((0..big).all(|i| *p.add(i) == (i % 251) as u8));
            a.dealloc(p, Layout::from_size_align(3 * big, 8).unwrap());

            let z = Layout::from_size_align(THRESHOLD * 2, 64).unwrap();
            let q = a.alloc_zeroed(z);
            assert!(!q.is_null());
            assert_eq!(q as usize % 64, 0);
            assert!((0..z.size()).step_by(4093).all(|i| *q.add(i) == 0));
            a.dealloc(q, z);
        }
    }
}
