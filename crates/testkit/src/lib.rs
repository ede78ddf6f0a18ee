//! Test support shared by grip's crates; a dev-dependency only, never
//! linked into a service or tool. [`svc`] runs a service binary from its
//! own tests; the rest of this page is the counting allocator.
//!
//! [`CountingAlloc`] is the global allocator of every "hot loop allocates
//! nothing" test: it forwards to the system allocator and counts
//! allocations (and reallocations) two ways:
//!
//! - per thread ([`thread_allocations`], and [`allocations`] for what a
//!   closure does on the calling thread): what a test of one thread's
//!   cycle wants, since other threads (iceoryx2's, the test harness's) are
//!   not counted; calls nest;
//! - process-wide ([`total_allocations`]), for tests that want every
//!   thread's allocations in the count. Beware: the test harness's main
//!   thread is one of them and may allocate while a test runs (it did, 4
//!   times, in a CI run of a single-threaded test), so assert "zero" on a
//!   process-wide count only where the harness is not running alongside.
//!
//! ```ignore
//! #[global_allocator]
//! static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;
//!
//! let n = grip_testkit::allocations(|| hot_loop());
//! assert_eq!(n, 0);
//! ```
#![warn(missing_docs)]

pub mod drives;
pub mod own_bus;
pub mod svc;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counting global allocator (see the crate documentation).
pub struct CountingAlloc;

thread_local! {
    // const-initialised and without a destructor: usable from inside the
    // allocator at any point of a thread's life, and never allocates.
    static COUNT: Cell<u64> = const { Cell::new(0) };
}
static TOTAL: AtomicU64 = AtomicU64::new(0);

#[inline]
fn count() {
    TOTAL.fetch_add(1, Ordering::Relaxed);
    let _ = COUNT.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        count();
        // SAFETY: same layout contract as the caller's.
        unsafe { System.alloc(l) }
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        count();
        // SAFETY: same layout contract as the caller's.
        unsafe { System.alloc_zeroed(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: p was allocated by System with l.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        count();
        // SAFETY: forwarded unchanged.
        unsafe { System.realloc(p, l, n) }
    }
}

/// Allocations (and reallocations) made by the current thread while `f`
/// runs (other threads' are not counted). Only meaningful where
/// [`CountingAlloc`] is the global allocator; elsewhere it returns 0.
pub fn allocations(f: impl FnOnce()) -> u64 {
    let before = thread_allocations();
    f();
    thread_allocations() - before
}

/// Allocations (and reallocations) made by the current thread since it
/// started (where [`CountingAlloc`] is the global allocator).
pub fn thread_allocations() -> u64 {
    COUNT.with(Cell::get)
}

/// Allocations (and reallocations) made by every thread of the process
/// since it started (where [`CountingAlloc`] is the global allocator),
/// the test harness's own threads included (see the crate documentation).
pub fn total_allocations() -> u64 {
    TOTAL.load(Ordering::Relaxed)
}
