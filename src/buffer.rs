//! Large zeroed work buffers for the eigensolvers, backed by transparent huge pages.
//!
//! Where it sits: under [`crate::eigen`] (LOBPCG blocks, multigrid scratch), which allocate a few
//! hundred MB of vectors per solve. Zeroed memory arrives untouched from the kernel and is
//! mapped page by page on first write; with 4 KB pages a 32^3 solve takes ~140k page faults,
//! about a fifth of its time on a virtual machine, and its sparse products miss the TLB. Asking
//! for 2 MB pages (`MADV_HUGEPAGE`, honoured where transparent huge pages are set to `madvise`
//! or `always`) cuts both. Elsewhere, or where the kernel declines, the buffer is an ordinary
//! zeroed vector.

/// Buffers smaller than this are left alone (their first touch is cheap).
const MIN_ADVISED_BYTES: usize = 4 << 20;

/// Transparent huge page size on x86-64 and aarch64 Linux.
#[cfg(target_os = "linux")]
const HUGE_PAGE_BYTES: usize = 2 << 20;

/// A vector of `len` zeros (`T::default()` must be all-zero bits for the allocation to come
/// zeroed from the kernel, as it is for floats, integers and arrays of them).
pub fn zeroed<T: Copy + Default>(len: usize) -> Vec<T> {
    let v = vec![T::default(); len];
    advise_huge_pages(&v);
    v
}

#[cfg(target_os = "linux")]
fn advise_huge_pages<T>(v: &[T]) {
    let bytes = std::mem::size_of_val(v);
    if bytes < MIN_ADVISED_BYTES {
        return;
    }
    let start = v.as_ptr() as usize;
    let first = start.next_multiple_of(HUGE_PAGE_BYTES);
    let end = (start + bytes) / HUGE_PAGE_BYTES * HUGE_PAGE_BYTES;
    if end > first {
        // SAFETY: `first..end` is page-aligned and lies inside `v`'s allocation; MADV_HUGEPAGE
        // only changes how the kernel backs those pages, never their contents or validity. A
        // failure (no THP support) leaves ordinary pages, so the result is ignored.
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages<T>(_: &[T]) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zeroed_buffers_are_zero_and_writable() {
        for len in [0, 10, (MIN_ADVISED_BYTES / 8) * 3 + 5] {
            let mut v: Vec<f64> = zeroed(len);
            assert_eq!(v.len(), len);
            assert!(v.iter().all(|&x| x == 0.0));
            v.iter_mut().enumerate().for_each(|(i, x)| *x = i as f64);
            assert!(v.iter().enumerate().all(|(i, &x)| x == i as f64));
        }
    }
}
