//! HIL: audio-acq's ALSA source on a real kernel driver, the `snd-aloop`
//! loopback (subdevices 2 and 3: `hw:Loopback,0,N` → `hw:Loopback,1,N`;
//! the grip HIL smoke test uses subdevices 0 and 1). Built only with
//! `--features hil`; run by `tools/hil/run` (natively or in a VM). FAILS,
//! never skips, without a Loopback card.
//!
//! Checks: a 1 kHz tone played into the loopback arrives as 1 kHz blocks of
//! 1024 samples at half full scale (S16_LE, chosen by `format = "auto"`)
//! with driver time stamps (no fallback) spaced one block apart and not in
//! the future; a stall longer than the ALSA buffer is an overrun that is
//! counted and recovered, the tone continues, and the stamps jump by the
//! stall; the `audio-acq` binary runs with `--source alsa --device
//! hw:Loopback,1,2`, logs its sample format and exits 0; a missing device
//! lists the Loopback PCMs. Then (`alsa_loopback_formats_and_resampling`)
//! the same tone captured in S32_LE, FLOAT_LE, S24_3LE and S24_LE set
//! explicitly, a format the device does not offer refused, and alsa-lib's
//! resampling through `plughw:` with `resample = true`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use alsa::pcm::{Access, HwParams, PCM};
use alsa::{Direction, ValueOr};
use grip_audio_acq::alsa_src::{AlsaPcm, AlsaSource};
use grip_audio_acq::config::AlsaSection;
use grip_audio_acq::format::{FormatSetting, SampleFormat};
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
        format: FormatSetting::Auto,
        resample: false,
    }
}

/// Plays a 1 kHz tone at half full scale into `device` in `format` at
/// `rate` Hz, each sample at the format's full resolution, until `stop`;
/// sends on `ready` once the first period is written (the device is set
/// up and running then).
fn player(
    device: &'static str,
    format: SampleFormat,
    rate: u32,
    stop: Arc<AtomicBool>,
    ready: Option<mpsc::Sender<()>>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let pcm = PCM::new(device, Direction::Playback, false).unwrap();
        {
            let hwp = HwParams::any(&pcm).unwrap();
            hwp.set_channels(1).unwrap();
            hwp.set_rate(rate, ValueOr::Nearest).unwrap();
            hwp.set_format(format.alsa()).unwrap();
            hwp.set_access(Access::RWInterleaved).unwrap();
            hwp.set_period_size_near(1024, ValueOr::Nearest).unwrap();
            hwp.set_buffer_size_near(16 * 1024).unwrap();
            pcm.hw_params(&hwp).unwrap();
        }
        let io = pcm.io_bytes();
        let bytes = format.bytes();
        let mut phase = 0u64;
        let mut buf = vec![0u8; 1024 * bytes];
        while !stop.load(Ordering::Relaxed) {
            for s in buf.chunks_exact_mut(bytes) {
                let t = phase as f64 / f64::from(rate);
                let x = 0.5 * (2.0 * std::f64::consts::PI * 1000.0 * t).sin();
                encode(format, x, s);
                phase += 1;
            }
            let mut off = 0;
            while off < buf.len() {
                match io.writei(&buf[off..]) {
                    Ok(n) => off += n * bytes,
                    Err(e) => pcm.try_recover(e, true).unwrap(),
                }
            }
            if let Some(r) = &ready {
                let _ = r.send(());
            }
        }
        let _ = pcm.drop();
    })
}

/// `x` (full scale ±1) as one sample of `format`, at its full resolution.
fn encode(format: SampleFormat, x: f64, out: &mut [u8]) {
    let int = |bits: i32| (x * f64::from(1u32 << (bits - 1))).round() as i32;
    match format {
        SampleFormat::S16Le => out.copy_from_slice(&(int(16) as i16).to_le_bytes()),
        SampleFormat::S32Le => {
            out.copy_from_slice(&((x * 2_147_483_648.0).round() as i32).to_le_bytes())
        }
        SampleFormat::S24_3Le => out.copy_from_slice(&int(24).to_le_bytes()[..3]),
        // low-aligned, sign-extended into the top byte
        SampleFormat::S24Le => out.copy_from_slice(&int(24).to_le_bytes()),
        SampleFormat::FloatLe => out.copy_from_slice(&(x as f32).to_le_bytes()),
    }
}

fn freq(x: &[i16], rate: u32) -> f64 {
    let zc = x.windows(2).filter(|w| (w[0] < 0) != (w[1] < 0)).count();
    zc as f64 / 2.0 / (x.len() as f64 / f64::from(rate))
}

/// The tone of [`player`] after its first blocks: at least 0.5 s of it,
/// checked for 1000 Hz (± 5) and half full scale (peak 16384 and RMS
/// 16384/√2, each ± 4 %), which a wrong sample conversion cannot give.
fn check_tone(blocks: &[(u64, Vec<i16>)], what: &str) {
    let start = blocks
        .iter()
        .position(|(_, b)| b.iter().any(|&s| s.unsigned_abs() > 8000))
        .unwrap_or_else(|| panic!("{what}: the tone never arrives"));
    let tone: Vec<i16> = blocks[start + 2..]
        .iter()
        .flat_map(|(_, b)| b.clone())
        .collect();
    assert!(
        tone.len() > RATE as usize / 2,
        "{what}: at least 0.5 s of tone"
    );
    let f = freq(&tone, RATE);
    let peak = tone.iter().map(|s| s.unsigned_abs()).max().unwrap_or(0);
    let rms = (tone.iter().map(|&s| f64::from(s).powi(2)).sum::<f64>() / tone.len() as f64).sqrt();
    println!(
        "{what}: {} samples of tone at {f:.1} Hz, peak {peak}, RMS {rms:.0} (expected 1000 Hz, 16384, {:.0})",
        tone.len(),
        16_384.0 / 2f64.sqrt()
    );
    assert!((f - 1000.0).abs() < 5.0, "{what}: {f} Hz");
    assert!(
        (f64::from(peak) - 16_384.0).abs() < 0.04 * 16_384.0,
        "{what}: peak {peak}, expected 16384"
    );
    let want = 16_384.0 / 2f64.sqrt();
    assert!(
        (rms - want).abs() < 0.04 * want,
        "{what}: RMS {rms}, expected {want}"
    );
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

/// The two tests share the emulated CPU and the card: one at a time.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

#[test]
fn alsa_loopback_capture_stamps_overruns_and_binary() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    require_loopback();
    // a missing device names itself and lists what exists
    let e = AlsaPcm::open(&section("hw:NoSuchCard,1,0"), RATE).unwrap_err();
    assert!(matches!(e, AcqError::AlsaDevice { .. }));
    let msg = e.to_string();
    assert!(msg.contains("Loopback"), "{msg}");

    let stop = Arc::new(AtomicBool::new(false));
    let cfg = section("hw:Loopback,1,2");
    let pcm = AlsaPcm::open(&cfg, RATE).unwrap();
    assert_eq!(pcm.format, SampleFormat::S16Le, "auto keeps S16_LE first");
    let buffer_frames = pcm.buffer_frames;
    let play = player(
        "hw:Loopback,0,2",
        SampleFormat::S16Le,
        RATE,
        Arc::clone(&stop),
        None,
    );
    let mut src = AlsaSource::new(pcm, &cfg, RATE, BLOCK);
    // 2 s of blocks; the tone starts when the player does
    let blocks = read_blocks(&mut src, 86);
    check_tone(&blocks, "S16_LE (auto)");
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
    let f = freq(&tone, RATE);
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
    assert!(
        err.contains("ALSA capture sample format S16_LE"),
        "the chosen format is logged: {err}"
    );

    stop.store(true, Ordering::Relaxed);
    play.join().unwrap();
}

fn with_format(device: &str, format: FormatSetting) -> AlsaSection {
    AlsaSection {
        format,
        ..section(device)
    }
}

/// Capture in each format set explicitly, on subdevice 3: the playback
/// writes the tone in that very format at its full resolution (the capture
/// is prepared first, which fixes the loopback's format), and the published
/// S16 must be the tone (1000 Hz, peak and RMS of half full scale). S32_LE
/// and FLOAT_LE must work; S24_3LE and S24_LE are checked the same way
/// where the card offers them (Debian's 6.1 snd-aloop does), and otherwise
/// must be refused with an error naming the device, the format and what it
/// offers. Then a playback of S16_LE at 48 kHz fixes the loopback's format
/// and rate: an explicit S32_LE capture is refused (device, format, "the
/// device offers: S16_LE"), "auto" takes S16_LE; a capture at 44.1 kHz
/// through `plughw:Loopback,1,3` is refused with `resample = false` (the
/// error says to set `resample = true`) and carries the tone at 1000 Hz
/// with it (unresampled it would be at 1088 Hz).
#[test]
fn alsa_loopback_formats_and_resampling() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    require_loopback();
    let capture = "hw:Loopback,1,3";
    let mut refused = Vec::new();
    for (setting, format) in [
        (FormatSetting::S32Le, SampleFormat::S32Le),
        (FormatSetting::FloatLe, SampleFormat::FloatLe),
        (FormatSetting::S24_3Le, SampleFormat::S24_3Le),
        (FormatSetting::S24Le, SampleFormat::S24Le),
    ] {
        let cfg = with_format(capture, setting);
        let pcm = match AlsaPcm::open(&cfg, RATE) {
            Ok(p) => p,
            Err(e) => {
                let msg = e.to_string();
                println!("{format}: {msg}");
                assert!(
                    !matches!(format, SampleFormat::S32Le | SampleFormat::FloatLe),
                    "snd-aloop offers {format}: {msg}"
                );
                assert!(matches!(e, AcqError::AlsaParams { .. }), "{msg}");
                assert!(
                    msg.contains(&format!("\"{capture}\"")),
                    "names the device: {msg}"
                );
                assert!(
                    msg.contains(&format!(
                        "sample format {format} ([alsa] format) is not offered"
                    )),
                    "names the format asked for: {msg}"
                );
                assert!(
                    msg.contains("the device offers: ")
                        && ["S16_LE", "S32_LE", "FLOAT_LE"]
                            .iter()
                            .all(|f| msg.contains(f)),
                    "lists the formats the device offers: {msg}"
                );
                refused.push(format);
                continue;
            }
        };
        assert_eq!(pcm.format, format);
        let stop = Arc::new(AtomicBool::new(false));
        let play = player("hw:Loopback,0,3", format, RATE, Arc::clone(&stop), None);
        let mut src = AlsaSource::new(pcm, &cfg, RATE, BLOCK);
        let blocks = read_blocks(&mut src, 60);
        stop.store(true, Ordering::Relaxed);
        check_tone(&blocks, &format!("{format} (set explicitly)"));
        assert_eq!(src.stats().xruns, 0, "{format}");
        drop(src);
        play.join().unwrap();
    }
    println!("formats the loopback refused: {refused:?}");

    // resampling: the playback first, at 48 kHz, fixes the loopback's rate
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let play = player(
        "hw:Loopback,0,3",
        SampleFormat::S16Le,
        48_000,
        Arc::clone(&stop),
        Some(tx),
    );
    rx.recv_timeout(Duration::from_secs(30))
        .expect("the 48 kHz playback runs");
    // the running S16_LE playback also fixes the format: a capture that
    // asks for S32_LE is refused naming the device, the format and what it
    // offers; "auto" takes S16_LE
    let e = AlsaPcm::open(&with_format(capture, FormatSetting::S32Le), 48_000).unwrap_err();
    let msg = e.to_string();
    println!("S32_LE from a loopback fixed at S16_LE: {msg}");
    assert!(matches!(e, AcqError::AlsaParams { .. }), "{msg}");
    assert!(
        msg.starts_with(&format!(
            "ALSA capture device \"{capture}\": sample format S32_LE ([alsa] format) is not offered; the device offers: S16_LE (set [alsa] format = \"auto\" or one of S16_LE;"
        )),
        "{msg}"
    );
    let pcm = AlsaPcm::open(&section(capture), 48_000).unwrap();
    assert_eq!(pcm.format, SampleFormat::S16Le);
    drop(pcm);

    let plug = "plughw:Loopback,1,3";
    let e = AlsaPcm::open(&section(plug), RATE).unwrap_err();
    let msg = e.to_string();
    println!("resample = false through {plug} against a 48 kHz loopback: {msg}");
    assert!(msg.contains(&format!("\"{plug}\"")), "{msg}");
    assert!(msg.contains("rate 44100 Hz"), "{msg}");
    assert!(
        msg.contains("set [alsa] resample = true with a plug device"),
        "{msg}"
    );
    let cfg = AlsaSection {
        resample: true,
        ..section(plug)
    };
    let pcm = AlsaPcm::open(&cfg, RATE).unwrap();
    let mut src = AlsaSource::new(pcm, &cfg, RATE, BLOCK);
    let blocks = read_blocks(&mut src, 60);
    stop.store(true, Ordering::Relaxed);
    // without resampling, 48 kHz samples read as 44.1 kHz would put the
    // tone at 1088 Hz
    check_tone(&blocks, "48 kHz resampled to 44.1 kHz by plughw");
    drop(src);
    play.join().unwrap();
}
