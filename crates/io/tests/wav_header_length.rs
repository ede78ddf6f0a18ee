//! A WAV file whose data-chunk header claims far more samples than the file
//! holds (0xFFFFFFFE bytes of 16-bit samples in a file of 52 bytes) is read
//! as far as the file goes, with the declared length kept
//! (`Audio::data_declared`; since 2026-12-07, before which it was refused
//! as truncated), and the reader reserves no more than the file can hold:
//! before 2026-12-05 it reserved what the header claimed (8.6 GB here;
//! 17 GB for 8-bit samples) and aborted where the system would not give it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use grip_io::wav::{decode_mono, read_mono, write_mono_i16};

/// Forwards to the system allocator; records this thread's largest request.
struct Largest;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn note(size: usize) {
    let _ = LARGEST.try_with(|c| c.set(c.get().max(size)));
}

// SAFETY: forwards every call to the system allocator unchanged; only records sizes.
unsafe impl GlobalAlloc for Largest {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        note(l.size());
        // SAFETY: same layout contract as the caller's.
        unsafe { System.alloc(l) }
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        note(l.size());
        // SAFETY: same layout contract as the caller's.
        unsafe { System.alloc_zeroed(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: p was allocated by System with l.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        note(n);
        // SAFETY: forwarded unchanged.
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static A: Largest = Largest;

/// The largest single allocation `f` asks for on this thread.
fn largest(f: impl FnOnce()) -> usize {
    LARGEST.with(|c| c.set(0));
    f();
    LARGEST.with(Cell::get)
}

#[test]
fn a_data_length_beyond_the_file_is_truncated_not_reserved() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge_header.wav");
    write_mono_i16(&p, 8000, &[0.0; 4]).unwrap();
    let mut bytes = std::fs::read(&p).unwrap();
    let data = bytes.windows(4).position(|w| w == b"data").unwrap();
    bytes[data + 4..data + 8].copy_from_slice(&0xFFFF_FFFEu32.to_le_bytes());
    std::fs::write(&p, &bytes).unwrap();
    let mut read = Vec::new();
    let big = largest(|| {
        read.push(read_mono(&p).unwrap());
        read.push(decode_mono(&bytes, &p).unwrap());
    });
    for a in read {
        assert_eq!(a.samples, [0.0; 4]);
        assert_eq!(a.data_declared, Some(0xFFFF_FFFE));
    }
    // hound's read buffer (8 KiB) is the largest thing a 52-byte file needs
    assert!(
        big < 64 * 1024,
        "the reader asked for {big} bytes at once for a {}-byte file",
        bytes.len()
    );
}
