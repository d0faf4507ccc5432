//! A global allocator that counts the allocations and frees made inside marked sections of a
//! thread: the audio-thread contract says nothing there allocates or frees. A test binary that
//! uses it declares `#[global_allocator] static GLOBAL: Counting = Counting;` and runs the
//! real-time work inside [`marked`]; other threads (the test harness, a worker) are not counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicIsize, AtomicUsize, Ordering};

/// The counting allocator (forwards to the system allocator).
pub struct Counting;

static ALLOCS: AtomicUsize = AtomicUsize::new(0);
static FREES: AtomicUsize = AtomicUsize::new(0);
/// Bytes allocated and not yet freed, on every thread.
static LIVE: AtomicIsize = AtomicIsize::new(0);

thread_local! {
    // Const-initialised: reading it never allocates.
    static MARKED: Cell<bool> = const { Cell::new(false) };
}

fn marked_now() -> bool {
    MARKED.try_with(|c| c.get()).unwrap_or(false)
}

/// Runs `f` with this thread's allocations and frees counted.
pub fn marked<R>(f: impl FnOnce() -> R) -> R {
    MARKED.with(|c| c.set(true));
    let r = f();
    MARKED.with(|c| c.set(false));
    r
}

/// Allocations (and reallocations) made in marked sections so far.
pub fn allocations() -> usize {
    ALLOCS.load(Ordering::SeqCst)
}

/// Heap bytes in use by the whole process (every thread), as the allocator was asked.
pub fn live_bytes() -> isize {
    LIVE.load(Ordering::Relaxed)
}

/// Frees made in marked sections so far.
pub fn frees() -> usize {
    FREES.load(Ordering::SeqCst)
}

// SAFETY: forwards to the system allocator unchanged; only counts calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if marked_now() {
            ALLOCS.fetch_add(1, Ordering::SeqCst);
        }
        LIVE.fetch_add(layout.size() as isize, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if marked_now() {
            FREES.fetch_add(1, Ordering::SeqCst);
        }
        LIVE.fetch_sub(layout.size() as isize, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if marked_now() {
            ALLOCS.fetch_add(1, Ordering::SeqCst);
        }
        LIVE.fetch_add(
            new_size as isize - layout.size() as isize,
            Ordering::Relaxed,
        );
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
