//! The WAV decoder (`grip_io::wav::decode_mono`, what `read_mono` and
//! `read_mono_at` run on a file's bytes: audio-acq's file source, `grip
//! features`, `grip classify`, `grip train`), then the resampling to
//! audio-acq's 44.1 kHz that `read_mono_at` does for a file at another rate.
//!
//! Checked besides "no panic": a decoded file has a rate and at least one
//! channel, every sample is finite and within [-1, 1] (integer PCM is
//! scaled by 2^(bits-1), float PCM has non-finite samples zeroed; a mixdown
//! averages), and resampling gives the documented length of finite samples.
#![no_main]

use std::path::Path;

use grip_io::wav::{decode_mono, resample};
use libfuzzer_sys::fuzz_target;

/// audio-acq's capture rate (`config/audio-acq.toml`).
const RATE: u32 = 44_100;

fuzz_target!(|data: &[u8]| {
    let Ok(a) = decode_mono(data, Path::new("fuzz.wav")) else {
        return;
    };
    assert!(a.sample_rate > 0 && a.file_channels > 0);
    for &s in &a.samples {
        assert!(
            s.is_finite() && s.abs() <= 1.0 + 1e-6,
            "sample {s} out of range"
        );
    }
    let n_out = a.samples.len() as u64 * u64::from(RATE) / u64::from(a.sample_rate);
    let y = resample(&a.samples, a.sample_rate, RATE);
    if a.sample_rate != RATE && !a.samples.is_empty() {
        assert_eq!(y.len() as u64, n_out);
    }
    assert!(y.iter().all(|v| v.is_finite()));
});
