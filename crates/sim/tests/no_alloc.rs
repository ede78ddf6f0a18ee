//! `Sim::step` allocates nothing: a counting global allocator around the
//! per-cycle loop of every variant, with the trace recorded (it is
//! preallocated to the run length) and the confusion-matrix ARTE in the loop.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use grip_sim::{Sim, Variant};

struct Counting;

thread_local! {
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts calls per thread.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocs() -> u64 {
    ALLOCS.with(Cell::get)
}

#[test]
fn the_cycle_allocates_nothing() {
    let (setup, est) = common::reference();
    for v in Variant::ALL {
        let mut e = est.clone();
        let mut sim = Sim::new(&setup, v, 11, &mut e, true).unwrap();
        let before = allocs();
        let mut cycles = 0;
        while sim.step() {
            cycles += 1;
        }
        let during = allocs() - before;
        assert_eq!(cycles, setup.cycles());
        assert_eq!(during, 0, "{v}: {during} allocations in {cycles} cycles");
        let r = sim.finish();
        assert_eq!(r.trace.as_ref().map(|t| t.len()), Some(setup.cycles()));
    }
    // The counter works: a Vec allocates.
    let before = allocs();
    let v: Vec<u8> = Vec::with_capacity(10);
    assert!(allocs() > before);
    drop(v);
}
