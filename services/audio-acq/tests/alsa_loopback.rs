//! HIL: audio-acq's ALSA source on a real kernel driver, the `snd-aloop`
//! loopback (subdevice 2: `hw:Loopback,0,2` → `hw:Loopback,1,2`; the grip
//! HIL smoke test uses subdevices 0 and 1). Built only with `--features
//! hil`; run by `tools/hil/run` (natively or in a VM). FAILS, never skips,
//! without a Loopback card.
//!
//! Checks: a 1 kHz tone played into the loopback arrives as 1 kHz blocks of
//! 1024 samples with driver time stamps (no fallback) spaced one block apart
//! and not in the future; a stall longer than the ALSA buffer is an
//! overrun that is counted and recovered, the tone continues, and the
//! stamps jump by the stall; the `audio-acq` binary runs with `--source
//! alsa --device hw:Loopback,1,2` and exits 0; a missing device lists the
//! Loopback PCMs.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use alsa::pcm::{Access, Format, HwParams, PCM};
use alsa::{Direction, ValueOr};
use grip_audio_acq::alsa_src::{AlsaPcm, AlsaSource};
use grip_audio_acq::config::AlsaSection;
use grip_audio_acq::{AcqError, Read, Source};
use grip_io::clock::monotonic_now_ns;

const RATE: u32 = 44_100;
const BLOCK: usize = 1024;
const BLOCK_NS: f64 = BLOCK as f64 * 1e9 / RATE as f64;

fn require_loopback() {
    let cards = std::fs::read_to_string("/proc/asound/cards").unwrap_or_default();
    assert!(
        cards.contains("[Loopback"),
        "no ALSA Loopback card (modprobe snd-aloop, or run tools/hil/run); /proc/asound/cards: {cards:?}"
    );
}

fn section(device: &str) -> AlsaSection {
    AlsaSection {
        device: device.into(),
        channels: 1,
        channel: 0,
        period_frames: 512,
        // 0.37 s: the capture thread of the emulated VM must not overrun in
        // the 2 s of the first check (the stall check sizes itself from it)
        buffer_frames: 16384,
        wait_timeout_ms: 500,
    }
}

/// Plays a 1 kHz tone (amplitude 0.5) into `hw:Loopback,0,2` until `stop`.
fn player(stop: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let pcm = PCM::new("hw:Loopback,0,2", Direction::Playback, false).unwrap();
        {
            let hwp = HwParams::any(&pcm).unwrap();
            hwp.set_channels(1).unwrap();
            hwp.set_rate(RATE, ValueOr::Nearest).unwrap();
            hwp.set_format(Format::s16()).unwrap();
            hwp.set_access(Access::RWInterleaved).unwrap();
            hwp.set_period_size_near(1024, ValueOr::Nearest).unwrap();
            hwp.set_buffer_size_near(16 * 1024).unwrap();
            pcm.hw_params(&hwp).unwrap();
        }
        let io = pcm.io_i16().unwrap();
        let mut phase = 0u64;
        let mut buf = vec![0i16; 1024];
        while !stop.load(Ordering::Relaxed) {
            for s in buf.iter_mut() {
                let t = phase as f64 / f64::from(RATE);
                *s = (16_384.0 * (2.0 * std::f64::consts::PI * 1000.0 * t).sin()) as i16;
                phase += 1;
            }
            let mut off = 0;
            while off < buf.len() {
                match io.writei(&buf[off..]) {
                    Ok(n) => off += n,
                    Err(e) => pcm.try_recover(e, true).unwrap(),
                }
            }
        }
        let _ = pcm.drop();
    })
}

fn freq(x: &[i16]) -> f64 {
    let zc = x.windows(2).filter(|w| (w[0] < 0) != (w[1] < 0)).count();
    zc as f64 / 2.0 / (x.len() as f64 / f64::from(RATE))
}

fn read_blocks(src: &mut AlsaSource<AlsaPcm>, n: usize) -> Vec<(u64, Vec<i16>)> {
    let mut out = Vec::new();
    let mut buf = [0i16; BLOCK];
    let mut timeouts = 0;
    while out.len() < n {
        match src.read(&mut buf).unwrap() {
            Read::Block { n, stamp_ns } => out.push((stamp_ns, buf[..n].to_vec())),
            Read::Timeout => {
                timeouts += 1;
                assert!(timeouts < 20, "capture delivers no data");
            }
            Read::End => panic!("ALSA source ended"),
        }
    }
    out
}

#[test]
fn alsa_loopback_capture_stamps_overruns_and_binary() {
    require_loopback();
    // a missing device names itself and lists what exists
    let e = AlsaPcm::open(&section("hw:NoSuchCard,1,0"), RATE).unwrap_err();
    assert!(matches!(e, AcqError::AlsaDevice { .. }));
    let msg = e.to_string();
    assert!(msg.contains("Loopback"), "{msg}");

    let stop = Arc::new(AtomicBool::new(false));
    let cfg = section("hw:Loopback,1,2");
    let pcm = AlsaPcm::open(&cfg, RATE).unwrap();
    let buffer_frames = pcm.buffer_frames;
    let play = player(Arc::clone(&stop));
    let mut src = AlsaSource::new(pcm, &cfg, RATE, BLOCK);
    // 2 s of blocks; the tone starts when the player does
    let blocks = read_blocks(&mut src, 86);
    let start = blocks
        .iter()
        .position(|(_, b)| b.iter().any(|&s| s.unsigned_abs() > 8000))
        .expect("the tone arrives");
    let tone: Vec<i16> = blocks[start + 2..]
        .iter()
        .flat_map(|(_, b)| b.clone())
        .collect();
    assert!(tone.len() > RATE as usize / 2, "at least 0.5 s of tone");
    let f = freq(&tone);
    println!("captured {} samples of tone at {f:.1} Hz", tone.len());
    assert!((f - 1000.0).abs() < 5.0, "{f} Hz");
    assert_eq!(src.stamp_fallbacks(), 0, "driver time stamps are used");
    let now = monotonic_now_ns();
    let mut d: Vec<f64> = blocks
        .windows(2)
        .map(|w| w[1].0 as f64 - w[0].0 as f64)
        .collect();
    assert!(
        blocks
            .iter()
            .all(|(t, _)| *t <= now && now - t < 5_000_000_000)
    );
    d.sort_by(f64::total_cmp);
    let med = d[d.len() / 2];
    println!(
        "block stamp spacing: median {:.3} ms (block {:.3} ms)",
        med / 1e6,
        BLOCK_NS / 1e6
    );
    assert!((med - BLOCK_NS).abs() < 1e6, "median spacing {med} ns");
    assert_eq!(src.stats().xruns, 0);

    // stall longer than the buffer: an overrun, counted and recovered
    let stall = Duration::from_millis(200 + 1000 * buffer_frames as u64 / u64::from(RATE));
    let before = blocks.last().unwrap().0;
    std::thread::sleep(stall);
    let after = read_blocks(&mut src, 30);
    let xruns = src.stats().xruns;
    println!("after a {stall:?} stall: {xruns} xrun(s)");
    assert!(xruns >= 1, "the stall must be an overrun");
    let first_after = after[0].0;
    assert!(
        first_after - before > stall.as_nanos() as u64 / 2,
        "stamps jump over the lost audio"
    );
    let tone: Vec<i16> = after[2..].iter().flat_map(|(_, b)| b.clone()).collect();
    let f = freq(&tone);
    assert!((f - 1000.0).abs() < 5.0, "after recovery: {f} Hz");
    drop(src);

    // the binary, from the command line only
    let exe = std::env::var("GRIP_BIN_DIR")
        .map(|d| std::path::Path::new(&d).join("audio-acq"))
        .unwrap_or_else(|_| env!("CARGO_BIN_EXE_audio-acq").into());
    let config_dir = std::env::var("GRIP_CONFIG_DIR")
        .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/../../config").into());
    let out = std::process::Command::new(exe)
        .args([
            "--config-dir",
            &config_dir,
            "--source",
            "alsa",
            "--device",
            "hw:Loopback,1,2",
            "--run-for",
            "1",
        ])
        .env("GRIP_INSTANCE", format!("hil_acq_{}", std::process::id()))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    println!("{err}");
    assert!(out.status.success(), "audio-acq failed: {err}");
    assert!(err.contains("audio-acq stopped"), "{err}");
    assert!(!err.contains("blocks=0"), "{err}");

    stop.store(true, Ordering::Relaxed);
    play.join().unwrap();
}
