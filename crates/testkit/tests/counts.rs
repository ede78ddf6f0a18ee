//! The counter sees what it must and nothing else.

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

use grip_testkit::{allocations, thread_allocations, total_allocations};

#[test]
fn counts_this_threads_allocations_inside_the_closure_only() {
    let v = allocations(|| {
        std::hint::black_box(vec![1u8; 64]);
    });
    assert_eq!(v, 1);
    let mut s = String::with_capacity(1);
    let grow = allocations(|| {
        s.push_str("longer than one byte");
    });
    assert_eq!(grow, 1, "a reallocation counts");
    assert_eq!(allocations(|| std::hint::black_box(())), 0);
    // Another thread's allocations are not this thread's.
    let other = allocations(|| {
        let h = std::thread::spawn(|| std::hint::black_box(vec![0u64; 1000]).len());
        // (spawning and joining allocate on this thread too: only compare
        // with the same work without the other thread's vector)
        h.join().unwrap();
    });
    let spawn_only = allocations(|| {
        std::thread::spawn(|| 0usize).join().unwrap();
    });
    assert_eq!(other, spawn_only);
    // Calls nest; the thread's running count agrees.
    let t0 = thread_allocations();
    let mut inner = 0;
    let outer = allocations(|| {
        std::hint::black_box(vec![1u8; 8]);
        inner = allocations(|| {
            std::hint::black_box(vec![2u8; 8]);
        });
    });
    assert_eq!((outer, inner), (2, 1));
    assert_eq!(thread_allocations() - t0, 2);
}

#[test]
fn the_process_total_counts_every_thread() {
    let before = total_allocations();
    std::thread::spawn(|| std::hint::black_box(vec![0u64; 1000]).len())
        .join()
        .unwrap();
    assert!(total_allocations() > before);
}
