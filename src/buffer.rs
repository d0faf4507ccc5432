//! Large work buffers for the eigensolvers: zeroed ones backed by transparent huge pages, and
//! buffers kept from one solve to the next.
//!
//! Where it sits: under [`crate::eigen`] (LOBPCG blocks, multigrid scratch, Cholesky factors,
//! a carried answer's Grams) and [`crate::fem`]'s assembly, which allocate a few MB to a few
//! hundred MB per solve. Fresh memory arrives untouched from
//! the kernel and is mapped page by page on first write, at ~5 us a 4 KB page on the virtual
//! machines here: a 32^3 solve takes ~140k page faults, about a fifth of its time, and its
//! sparse products miss the TLB. Two remedies:
//! - [`zeroed`] asks for 2 MB pages (`MADV_HUGEPAGE`, honoured where transparent huge pages are
//!   set to `madvise` or `always`) for buffers of 4 MB and more. Elsewhere, or where the kernel
//!   declines, the buffer is an ordinary zeroed vector.
//! - [`take`] and [`recycle`] keep a few buffers between solves ([`KEPT_BYTES`] at most):
//!   the allocator hands large blocks back to the kernel when they
//!   are freed (glibc maps anything over its threshold afresh), so a worker that solves edit
//!   after edit faulted in its factor and scratch anew each time: ~6k faults (~25 ms of system
//!   time) of the default object's 150 ms cold solve. A Cholesky factor's values and its
//!   factorisation scratch go back to the pool when it is dropped, and so do a model's `K`
//!   and `M` ([`crate::fem::FemModel`]): a brush stroke's carried answer assembles the next
//!   model into them ([`take_unfilled`], the copied rows never cleared): with its Grams'
//!   previous rows in a kept buffer too, the ceramic cup's carried answer took 0.91x the time
//!   (stop 70).

use std::collections::TryReserveError;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

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

/// Most bytes of buffers the process keeps for each element type between solves (three types:
/// `f64`, `usize` and a stiffness block `[f64; 9]`), unless [`set_kept_bytes`] says otherwise:
/// the default object's three class factors, their scratch and Lanczos bases are ~20 MB, the
/// ceramic cup's `K` 35 MB; a larger object's whole factor may not fit, and is then freed as
/// before.
pub const KEPT_BYTES: usize = 64 << 20;

/// The budget [`recycle`] keeps to ([`KEPT_BYTES`] unless [`set_kept_bytes`] changed it).
static KEPT_BUDGET: AtomicUsize = AtomicUsize::new(KEPT_BYTES);

/// Sets how many bytes of buffers the process keeps for each element type (from the next
/// [`recycle`] on; a lower budget drops the oldest kept buffers as the next ones come back).
/// For a batch job in a process of its own that solves large objects one after another, whose
/// whole factors (a few hundred MB for an object filling the 32^3 box) are over
/// [`KEPT_BYTES`]: each would otherwise come as fresh memory that the kernel zeroes page by
/// page (`modalforge dataset`: 35 % of its labelling time in `clear_page_erms` under perf,
/// [`crate::predictor::dataset::KEPT_BYTES_WHILE_LABELLING`]). A plugin keeps the default.
pub fn set_kept_bytes(bytes: usize) {
    KEPT_BUDGET.store(bytes, Ordering::Relaxed);
}

/// The budget of [`set_kept_bytes`].
pub fn kept_bytes() -> usize {
    KEPT_BUDGET.load(Ordering::Relaxed)
}

/// Most buffers the process keeps for each element type ([`KEPT_BYTES`] bounds them first on
/// most objects). A class-by-class solve holds four or five buffers a class until it combines
/// the classes (the packed factor, the solve scratch, the Lanczos basis and its `M` image):
/// with 12 kept, the tin can's six classes left half of theirs to the allocator, and each
/// solve after the first took ~1,650 page faults (`perf stat`, 10 solves in one process);
/// with 48, ~40.
const KEPT_COUNT: usize = 48;

/// Buffers smaller than this are not kept (their first touch is cheap).
const MIN_KEPT_BYTES: usize = 64 << 10;

/// Buffers kept for a later solve, oldest first. One pool for the process, not one per
/// thread: a plugin runs a worker thread per instance, and its memory stays bounded however
/// many instances a session holds.
pub struct Pool<T> {
    buffers: Vec<Vec<T>>,
}

impl<T> Pool<T> {
    const fn new() -> Self {
        Pool {
            buffers: Vec::new(),
        }
    }

    fn bytes(&self) -> usize {
        self.buffers
            .iter()
            .map(|b| b.capacity() * std::mem::size_of::<T>())
            .sum()
    }

    /// The smallest kept buffer with room for `capacity` elements, as it was left.
    fn remove_smallest(&mut self, capacity: usize) -> Option<Vec<T>> {
        let best = (self.buffers.iter().enumerate())
            .filter(|(_, b)| b.capacity() >= capacity)
            .min_by_key(|(_, b)| b.capacity())
            .map(|(i, _)| i)?;
        Some(self.buffers.remove(best))
    }

    /// The smallest kept buffer with room for `capacity` elements, emptied.
    fn take(&mut self, capacity: usize) -> Option<Vec<T>> {
        let mut v = self.remove_smallest(capacity)?;
        v.clear();
        Some(v)
    }

    /// The smallest kept buffer with room for `len` elements, as it was left but for the
    /// length: elements beyond its last length are zeros.
    fn take_unfilled(&mut self, len: usize) -> Option<Vec<T>>
    where
        T: Copy + Default,
    {
        let mut v = self.remove_smallest(len)?;
        v.truncate(len);
        v.resize(len, T::default());
        Some(v)
    }

    /// Keeps `v`, dropping the oldest beyond `budget_bytes` or [`KEPT_COUNT`]; a buffer
    /// under [`MIN_KEPT_BYTES`] or over `budget_bytes` is dropped at once.
    fn keep(&mut self, v: Vec<T>, budget_bytes: usize) {
        let bytes = v.capacity() * std::mem::size_of::<T>();
        if !(MIN_KEPT_BYTES..=budget_bytes).contains(&bytes) {
            return;
        }
        self.buffers.push(v);
        while self.buffers.len() > KEPT_COUNT || self.bytes() > budget_bytes {
            self.buffers.remove(0);
        }
    }
}

/// Element types with a pool of kept buffers.
pub trait Recycled: Copy + 'static {
    /// The pool for the type.
    fn pool() -> &'static Mutex<Pool<Self>>;

    /// Runs `f` on the pool (a panic while it was held left nothing half-done that matters:
    /// the buffers are only memory).
    fn with_pool<R>(f: impl FnOnce(&mut Pool<Self>) -> R) -> R {
        f(&mut Self::pool().lock().unwrap_or_else(PoisonError::into_inner))
    }
}

impl Recycled for f64 {
    fn pool() -> &'static Mutex<Pool<Self>> {
        static POOL: Mutex<Pool<f64>> = Mutex::new(Pool::new());
        &POOL
    }
}

impl Recycled for usize {
    fn pool() -> &'static Mutex<Pool<Self>> {
        static POOL: Mutex<Pool<usize>> = Mutex::new(Pool::new());
        &POOL
    }
}

impl Recycled for [f64; 9] {
    fn pool() -> &'static Mutex<Pool<Self>> {
        static POOL: Mutex<Pool<[f64; 9]>> = Mutex::new(Pool::new());
        &POOL
    }
}

/// An empty vector with room for at least `capacity` elements where the pool keeps one that
/// large (the smallest such), else an empty vector without room (the caller reserves, and
/// may use `try_reserve` to report a failure). Its memory may have been written before: fill
/// it before reading.
pub fn take<T: Recycled>(capacity: usize) -> Vec<T> {
    T::with_pool(|pool| pool.take(capacity)).unwrap_or_default()
}

/// A vector of `len` elements whose values are unspecified, for a buffer its user writes
/// before reading: a kept buffer holds what its last use left (only a tail beyond that use's
/// length is zeroed here), fresh memory comes zeroed from the allocator and is mapped by the
/// kernel on first touch. Either way no pass over the whole buffer is made: a Lanczos basis
/// is sized for a request's worst case and mostly left unused.
pub fn take_unfilled<T: Recycled + Default>(len: usize) -> Result<Vec<T>, TryReserveError> {
    match T::with_pool(|pool| pool.take_unfilled(len)) {
        Some(v) => Ok(v),
        None => zeroed_fallible(len),
    }
}

/// A vector of `len` zeros: a kept buffer cleared in one pass where the pool has one (its pages
/// are mapped already), else [`zeroed`] memory from the allocator (mapped on first touch).
pub fn take_zeroed<T: Recycled + Default>(len: usize) -> Vec<T> {
    match T::with_pool(|pool| pool.take(len)) {
        Some(mut v) => {
            v.resize(len, T::default());
            v
        }
        None => zeroed(len),
    }
}

/// `len` zeros from the allocator's zeroed memory (`T::default()` must be all-zero bits, as
/// it is for floats and integers), or the allocation's failure.
fn zeroed_fallible<T: Copy + Default>(len: usize) -> Result<Vec<T>, TryReserveError> {
    let mut probe: Vec<T> = Vec::new();
    probe.try_reserve_exact(len)?;
    drop(probe);
    Ok(zeroed(len))
}

/// Keeps `v`'s memory for a later [`take`], dropping the oldest kept buffers beyond
/// [`kept_bytes`] ([`KEPT_BYTES`] by default) or [`KEPT_COUNT`]. Small buffers are freed.
pub fn recycle<T: Recycled>(v: Vec<T>) {
    let budget_bytes = kept_bytes();
    T::with_pool(|pool| pool.keep(v, budget_bytes));
}

/// Keeps a buffer of `len` NaNs of each element type, so that the next solve or assembly that
/// takes one and reads a value it did not write is caught (tests of the buffers' users).
#[cfg(test)]
pub(crate) fn poison_kept(len: usize) {
    recycle(vec![f64::NAN; len]);
    recycle(vec![[f64::NAN; 9]; len]);
}

/// Frees every kept buffer.
pub fn free_kept() {
    f64::with_pool(|pool| pool.buffers.clear());
    usize::with_pool(|pool| pool.buffers.clear());
    <[f64; 9]>::with_pool(|pool| pool.buffers.clear());
}

/// A column-major `nrows x ncols` block in a kept buffer ([`take_unfilled`]), handed back to
/// the pool when dropped: the Lanczos basis, rebuilt per solve. Like a `faer::Mat`, each
/// column starts on a 64-byte boundary (the matrix products' loads are aligned).
pub struct KeptColumns {
    values: Vec<f64>,
    /// Where the first column starts in `values`.
    offset: usize,
    nrows: usize,
    ncols: usize,
    col_stride: usize,
}

/// `f64`s in 64 bytes.
const ALIGN_F64S: usize = 8;

impl KeptColumns {
    /// `nrows x ncols` of unspecified values ([`take_unfilled`]), for a block whose columns
    /// are written before they are read.
    pub fn unfilled(nrows: usize, ncols: usize) -> Self {
        let col_stride = nrows.next_multiple_of(ALIGN_F64S);
        let len = col_stride * ncols + ALIGN_F64S;
        let values = take_unfilled(len).unwrap_or_else(|_| vec![0.0; len]);
        Self::aligned(values, nrows, ncols, col_stride)
    }

    fn aligned(values: Vec<f64>, nrows: usize, ncols: usize, col_stride: usize) -> Self {
        let misaligned = (values.as_ptr() as usize / std::mem::size_of::<f64>()) % ALIGN_F64S;
        KeptColumns {
            values,
            offset: (ALIGN_F64S - misaligned) % ALIGN_F64S,
            nrows,
            ncols,
            col_stride,
        }
    }

    /// Rows.
    pub fn nrows(&self) -> usize {
        self.nrows
    }

    /// Columns.
    pub fn ncols(&self) -> usize {
        self.ncols
    }

    /// The block, to read.
    pub fn as_ref(&self) -> faer::MatRef<'_, f64> {
        faer::MatRef::from_column_major_slice_with_stride(
            &self.values[self.offset..],
            self.nrows,
            self.ncols,
            self.col_stride,
        )
    }

    /// The block, to write.
    pub fn as_mut(&mut self) -> faer::MatMut<'_, f64> {
        faer::MatMut::from_column_major_slice_with_stride_mut(
            &mut self.values[self.offset..],
            self.nrows,
            self.ncols,
            self.col_stride,
        )
    }
}

impl Drop for KeptColumns {
    fn drop(&mut self) {
        recycle(std::mem::take(&mut self.values));
    }
}

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

    #[test]
    fn a_kept_buffer_taken_zeroed_is_zero() {
        // A length no other test's buffers have, so that the NaNs kept here are what comes
        // back (another test taking them first leaves a zeroed buffer all the same).
        let len = MIN_KEPT_BYTES / 72 + 12_345;
        poison_kept(len);
        let blocks: Vec<[f64; 9]> = take_zeroed(len);
        let scalars: Vec<f64> = take_zeroed(len);
        assert_eq!((blocks.len(), scalars.len()), (len, len));
        assert!(blocks.iter().flatten().chain(&scalars).all(|&v| v == 0.0));
    }

    #[test]
    fn kept_buffers_are_reused_smallest_first_and_bounded() {
        // A pool of its own (the process's is shared with other tests' solves).
        let mut pool = Pool::new();
        let len = MIN_KEPT_BYTES / 8;
        let (small, large) = (vec![1.0f64; len], vec![2.0f64; 4 * len]);
        let (small_at, large_at) = (small.as_ptr(), large.as_ptr());
        pool.keep(large, KEPT_BYTES);
        pool.keep(small, KEPT_BYTES);
        pool.keep(vec![3.0f64; 10], KEPT_BYTES); // too small to keep

        // The smallest that fits, emptied; then the next; then none.
        let a = pool.take(len / 2).unwrap();
        assert_eq!((a.as_ptr(), a.len()), (small_at, 0));
        let b = pool.take(len / 2).unwrap();
        assert_eq!((b.as_ptr(), b.len()), (large_at, 0));
        assert!(pool.take(1).is_none());
        // Bounded by count and bytes, oldest dropped first.
        // (Told apart by capacity: a freed buffer's address may come back.)
        pool.keep(Vec::<f64>::with_capacity(len + 1), KEPT_BYTES);
        for _ in 0..KEPT_COUNT + 2 {
            pool.keep(Vec::<f64>::with_capacity(len), KEPT_BYTES);
        }
        assert_eq!(pool.buffers.len(), KEPT_COUNT);
        assert!(pool.buffers.iter().all(|b| b.capacity() == len));
        pool.keep(Vec::<f64>::with_capacity(KEPT_BYTES / 8 - len), KEPT_BYTES);
        assert!(pool.bytes() <= KEPT_BYTES);
        assert_eq!(
            pool.buffers.len(),
            2,
            "the budget keeps the newest that fit"
        );
        // Over the budget alone.
        pool.keep(Vec::<f64>::with_capacity(KEPT_BYTES / 8 + 1), KEPT_BYTES);
        assert!(pool.bytes() <= KEPT_BYTES);
        // A larger budget (a batch job's, `set_kept_bytes`) keeps what the default drops.
        pool.keep(
            Vec::<f64>::with_capacity(KEPT_BYTES / 8 + 1),
            2 * KEPT_BYTES,
        );
        assert_eq!(
            pool.buffers.last().map(Vec::capacity),
            Some(KEPT_BYTES / 8 + 1)
        );
        assert!(pool.bytes() <= 2 * KEPT_BYTES);
        // The process's pools, through the public functions.
        let v = take::<usize>(len);
        recycle(v);
    }

    #[test]
    fn kept_columns_have_their_shape_and_aligned_columns() {
        let mut c = KeptColumns::unfilled(5, 3);
        assert_eq!((c.nrows(), c.ncols()), (5, 3));
        c.as_mut()[(4, 2)] = 1.0;
        assert_eq!(c.as_ref()[(4, 2)], 1.0);
        drop(c);
        let c = KeptColumns::unfilled(4, 2);
        for j in 0..2 {
            assert_eq!(
                c.as_ref().col(j).as_ptr() as usize % 64,
                0,
                "column {j} aligned"
            );
        }
    }

    #[test]
    fn unfilled_buffers_have_their_length_and_zeros_beyond_what_was_written() {
        // Fresh memory: zeros.
        let len = MIN_KEPT_BYTES / 8 + 100;
        let v: Vec<f64> = take_unfilled(len).expect("memory");
        assert_eq!(v.len(), len);
        // A buffer kept shorter than its capacity comes back longer: its tail is zeros.
        let mut pool = Pool::<f64>::new();
        let mut kept = Vec::with_capacity(2 * len);
        kept.resize(len, 7.0);
        pool.keep(kept, KEPT_BYTES);
        let again = pool.take_unfilled(len + 10).expect("kept");
        assert_eq!(again.len(), len + 10);
        assert!(again[..len].iter().all(|&x| x == 7.0), "as left");
        assert!(again[len..].iter().all(|&x| x == 0.0), "the tail zeroed");
    }
}
