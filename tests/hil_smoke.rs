//! HIL smoke test: proves the route from the test binary to the kernel's CAN
//! and ALSA interfaces end to end, on `vcan0` and the `snd-aloop` loopback.
//!
//! Run with `tools/hil/run` (natively where the kernel has vcan and snd-aloop,
//! else in a VM). These tests FAIL where the interfaces are missing: they are
//! kept out of the ordinary `cargo nextest run` by `.config/nextest.toml`.
//!
//! The tests of one binary run in parallel threads, so each CAN test uses its
//! own identifier range with receive filters (0x1xx, 0x2xx/0x3xx, 0x4xx) and
//! each ALSA test its own loopback subdevice.

use std::io::BufRead;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use alsa::pcm::{Access, Format, HwParams, PCM, State};
use alsa::{Direction, ValueOr};
use anyhow::{Context, bail, ensure};
use grip_tests::hil::{
    self, CAN_EFF_FLAG, CAN_EFF_MASK, CAN_RTR_FLAG, CAN_SFF_MASK, Proc, RawCanSocket, RawFrame,
};
use socketcan::{
    CanFilter, CanFrame, CanSocket, EmbeddedFrame, ExtendedId, Frame, Socket, SocketOptions,
    StandardId,
};

const RX_TIMEOUT: Duration = Duration::from_secs(2);

fn open_socketcan() -> anyhow::Result<CanSocket> {
    let iface = hil::vcan_iface();
    hil::require_can_iface(&iface)?;
    CanSocket::open(&iface).with_context(|| format!("socketcan: open {iface}"))
}

fn open_raw() -> anyhow::Result<RawCanSocket> {
    let iface = hil::vcan_iface();
    hil::require_can_iface(&iface)?;
    RawCanSocket::open(&iface)
}

fn std_frame(id: u16, data: &[u8]) -> anyhow::Result<CanFrame> {
    let sid = StandardId::new(id).context("standard id out of range")?;
    CanFrame::new(sid, data).context("building a standard frame")
}

fn ext_frame(id: u32, data: &[u8]) -> anyhow::Result<CanFrame> {
    let eid = ExtendedId::new(id).context("extended id out of range")?;
    CanFrame::new(eid, data).context("building an extended frame")
}

/// Filter masks that include the EFF and RTR flags, so a standard-id filter
/// does not also pass the extended frame with the same low bits.
const STD_MASK: u32 = CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_SFF_MASK;
const EXT_MASK: u32 = CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_EFF_MASK;

#[test]
fn socketcan_frames_reach_an_independent_raw_socket() -> anyhow::Result<()> {
    let rx = open_raw()?;
    rx.set_filters(&[
        (0x100, CAN_EFF_FLAG | CAN_RTR_FLAG | 0x7F0),
        (CAN_EFF_FLAG | 0x1234_5678, EXT_MASK),
    ])?;
    let tx = open_socketcan()?;

    let sent: Vec<(u32, Vec<u8>)> = vec![
        (0x100, vec![]),
        (0x101, vec![0xA5]),
        (0x10F, vec![1, 2, 3]),
        (0x102, vec![0x00, 0xFF, 0x55, 0xAA, 0x01, 0x80, 0x7F, 0xFE]),
        (CAN_EFF_FLAG | 0x1234_5678, vec![9, 8, 7, 6, 5]),
    ];
    for (id_word, data) in &sent {
        let f = if id_word & CAN_EFF_FLAG != 0 {
            ext_frame(id_word & CAN_EFF_MASK, data)?
        } else {
            std_frame((id_word & CAN_SFF_MASK) as u16, data)?
        };
        tx.write_frame(&f).context("socketcan: write_frame")?;
    }
    for (i, (id_word, data)) in sent.iter().enumerate() {
        let got = rx
            .recv_timeout(RX_TIMEOUT)?
            .with_context(|| format!("frame {i} ({id_word:#x}) never reached the raw socket"))?;
        assert_eq!(got.can_id, *id_word, "frame {i}: identifier word");
        assert_eq!(got.payload(), data.as_slice(), "frame {i}: payload");
        assert!(
            got.data[got.payload().len()..].iter().all(|&b| b == 0),
            "frame {i}: bytes past len must be zero: {got:?}"
        );
    }
    assert_eq!(
        rx.recv_timeout(Duration::from_millis(200))?,
        None,
        "no extra frames"
    );
    Ok(())
}

#[test]
fn receive_filters_pass_only_matching_frames() -> anyhow::Result<()> {
    // Raw socket filters, frames from socketcan.
    let raw_rx = open_raw()?;
    raw_rx.set_filters(&[(0x200, STD_MASK)])?;
    let sc_tx = open_socketcan()?;
    let sequence: [(bool, u32, u8); 5] = [
        (false, 0x200, 1), // passes
        (false, 0x201, 2), // other id
        (true, 0x200, 3),  // extended frame with the same low bits
        (false, 0x280, 4), // other id, same high bits
        (false, 0x200, 5), // passes
    ];
    for &(ext, id, tag) in &sequence {
        let f = if ext {
            ext_frame(id, &[tag])?
        } else {
            std_frame(id as u16, &[tag])?
        };
        sc_tx.write_frame(&f)?;
    }
    let mut got = Vec::new();
    while let Some(f) = raw_rx.recv_timeout(Duration::from_millis(300))? {
        got.push((f.can_id, f.payload().to_vec()));
    }
    assert_eq!(
        got,
        vec![(0x200, vec![1]), (0x200, vec![5])],
        "raw socket filter"
    );

    // socketcan filters (including an inverted one), frames from the raw socket.
    let sc_rx = open_socketcan()?;
    sc_rx.set_filters(&[
        CanFilter::new(0x300, STD_MASK),
        CanFilter::new(CAN_EFF_FLAG | 0x0ABC_0300, EXT_MASK),
    ])?;
    let raw_tx = open_raw()?;
    for (id_word, tag) in [
        (0x2FFu32, 1u8),
        (0x300, 2),
        (0x301, 3),
        (CAN_EFF_FLAG | 0x0ABC_0300, 4),
        (CAN_EFF_FLAG | 0x0ABC_0301, 5),
        (0x300, 6),
    ] {
        raw_tx.send(&RawFrame::new(id_word, &[tag, tag, tag])?)?;
    }
    let mut got = Vec::new();
    loop {
        match sc_rx.read_frame_timeout(Duration::from_millis(300)) {
            Ok(f) => got.push((f.id_word(), f.data().to_vec())),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => break,
            Err(e) => return Err(e).context("socketcan: read_frame_timeout"),
        }
    }
    assert_eq!(
        got,
        vec![
            (0x300, vec![2, 2, 2]),
            (CAN_EFF_FLAG | 0x0ABC_0300, vec![4, 4, 4]),
            (0x300, vec![6, 6, 6]),
        ],
        "socketcan filter"
    );

    // An inverted filter: every standard frame except 0x3F5. It also passes
    // the other tests' frames, so look only at this test's 0x3F0..=0x3FF.
    let inv_rx = open_socketcan()?;
    inv_rx.set_filters(&[CanFilter::new_inverted(0x3F5, STD_MASK)])?;
    for id in [0x3F4u32, 0x3F5, 0x3F6] {
        raw_tx.send(&RawFrame::new(id, &[0x77])?)?;
    }
    let mut seen = Vec::new();
    let end = Instant::now() + Duration::from_millis(500);
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        match inv_rx.read_frame_timeout(left) {
            Ok(f) if (0x3F0..=0x3FF).contains(&f.id_word()) => seen.push(f.id_word()),
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => break,
            Err(e) => return Err(e).context("socketcan: read_frame_timeout"),
        }
    }
    assert_eq!(seen, vec![0x3F4, 0x3F6], "inverted socketcan filter");
    Ok(())
}

#[test]
fn can_utils_interoperate_with_socketcan() -> anyhow::Result<()> {
    let iface = hil::vcan_iface();
    let cansend = hil::tool("cansend")?;
    let candump = hil::tool("candump")?;

    // cansend -> socketcan
    let rx = open_socketcan()?;
    rx.set_filters(&[
        CanFilter::new(0x401, STD_MASK),
        CanFilter::new(CAN_EFF_FLAG | 0x1ABC_D401, EXT_MASK),
    ])?;
    for arg in ["401#DEADBEEF", "1ABCD401#0102030405060708", "401#"] {
        let st = Command::new(&cansend)
            .args([iface.as_str(), arg])
            .status()?;
        ensure!(st.success(), "cansend {iface} {arg}: {st}");
    }
    let mut got = Vec::new();
    for _ in 0..3 {
        let f = rx
            .read_frame_timeout(RX_TIMEOUT)
            .context("frame from cansend")?;
        got.push((f.id_word(), f.data().to_vec()));
    }
    assert_eq!(
        got,
        vec![
            (0x401, vec![0xDE, 0xAD, 0xBE, 0xEF]),
            (CAN_EFF_FLAG | 0x1ABC_D401, vec![1, 2, 3, 4, 5, 6, 7, 8]),
            (0x401, vec![]),
        ]
    );

    // socketcan -> candump. candump needs a moment to bind; keep sending the
    // same frames until it has printed two and exited (-n 2), at most 20 s.
    let mut dump = Command::new(&candump)
        .args([
            "-L",
            "-n",
            "2",
            &format!("{iface},402:7FF,1ABCD402:1FFFFFFF"),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .context("spawning candump")?;
    let tx = open_socketcan()?;
    let a = std_frame(0x402, &[0x11, 0x22, 0x33])?;
    let b = ext_frame(0x1ABC_D402, &[0xF0; 8])?;
    let end = Instant::now() + Duration::from_secs(20);
    let status = loop {
        tx.write_frame(&a)?;
        tx.write_frame(&b)?;
        std::thread::sleep(Duration::from_millis(50));
        if let Some(st) = dump.try_wait()? {
            break st;
        }
        if Instant::now() > end {
            let _ = dump.kill();
            bail!("candump did not see two frames within 20 s");
        }
    };
    let stdout = dump.stdout.take().context("candump stdout")?;
    let lines: Vec<String> = std::io::BufReader::new(stdout)
        .lines()
        .collect::<Result<_, _>>()?;
    ensure!(
        status.success(),
        "candump failed: {status}, output {lines:?}"
    );
    // -L lines look like "(1700000000.123456) vcan0 402#112233".
    let frames: Vec<&str> = lines
        .iter()
        .filter_map(|l| l.split_whitespace().nth(2))
        .collect();
    assert_eq!(frames.len(), 2, "candump output: {lines:?}");
    for f in &frames {
        assert!(
            *f == "402#112233" || *f == "1ABCD402#F0F0F0F0F0F0F0F0",
            "unexpected frame {f} in candump output {lines:?}"
        );
    }
    assert!(lines.iter().all(|l| l.contains(&iface)), "{lines:?}");
    Ok(())
}

// --- ALSA loopback ------------------------------------------------------------

const RATE: u32 = 48_000;

/// Opens an ALSA PCM as 48 kHz mono S16 with `periods` periods of `period` frames.
fn open_pcm(name: &str, dir: Direction, period: usize, periods: usize) -> anyhow::Result<PCM> {
    hil::require_alsa_loopback()?;
    let pcm = PCM::new(name, dir, false).with_context(|| format!("opening ALSA PCM {name}"))?;
    {
        let hwp = HwParams::any(&pcm)?;
        hwp.set_channels(1).context("channels = 1")?;
        hwp.set_rate(RATE, ValueOr::Nearest).context("rate")?;
        hwp.set_format(Format::s16()).context("format S16")?;
        hwp.set_access(Access::RWInterleaved).context("access")?;
        hwp.set_period_size(period as alsa::pcm::Frames, ValueOr::Nearest)
            .context("period size")?;
        hwp.set_buffer_size((period * periods) as alsa::pcm::Frames)
            .context("buffer size")?;
        pcm.hw_params(&hwp)
            .with_context(|| format!("{name}: hw_params"))?;
    }
    {
        let hwp = pcm.hw_params_current()?;
        ensure!(
            hwp.get_rate()? == RATE,
            "{name}: rate {} != {RATE}",
            hwp.get_rate()?
        );
        ensure!(
            hwp.get_period_size()? == period as alsa::pcm::Frames,
            "{name}: period size"
        );
        ensure!(
            hwp.get_buffer_size()? == (period * periods) as alsa::pcm::Frames,
            "{name}: buffer size"
        );
    }
    Ok(pcm)
}

/// What one play-and-capture attempt saw.
struct ToneCapture {
    samples: Vec<i16>,
    /// Index of the first sample of the tone in `samples`.
    start: usize,
    capture_xruns: u32,
    playback_xruns: u32,
}

/// Plays `tone` into `hw:Loopback,0,0` while capturing `hw:Loopback,1,0`
/// until 1.2 s after the tone has started (at most 6 s).
fn play_and_capture(tone: Vec<i16>) -> anyhow::Result<ToneCapture> {
    // Large buffers (1024 x 16 frames, 341 ms): the VM's scheduling stalls
    // must not turn a data-path test into a timing test.
    const PERIOD: usize = 1024;
    const PERIODS: usize = 16;
    let capture = open_pcm("hw:Loopback,1,0", Direction::Capture, PERIOD, PERIODS)?;
    let io = capture.io_i16()?;
    capture.start().context("capture start")?;
    let player = std::thread::spawn(move || -> anyhow::Result<u32> {
        let pcm = open_pcm("hw:Loopback,0,0", Direction::Playback, PERIOD, PERIODS)?;
        let io = pcm.io_i16()?;
        let mut xruns = 0;
        let mut off = 0;
        while off < tone.len() {
            match io.writei(&tone[off..(off + PERIOD).min(tone.len())]) {
                Ok(n) => off += n,
                Err(e) => {
                    xruns += 1;
                    pcm.try_recover(e, true).context("playback recover")?;
                }
            }
        }
        pcm.drain().context("playback drain")?;
        Ok(xruns)
    });

    let mut samples = vec![0i16; RATE as usize * 6];
    let (mut filled, mut capture_xruns, mut start) = (0, 0, None);
    while filled < samples.len() {
        let end = (filled + PERIOD).min(samples.len());
        match io.readi(&mut samples[filled..end]) {
            Ok(n) => {
                // capture runs before playback and delivers silence first
                if start.is_none() {
                    start = samples[filled..filled + n]
                        .iter()
                        .position(|&s| s.unsigned_abs() > 1000)
                        .map(|i| filled + i);
                }
                filled += n;
                if start.is_some_and(|s| filled >= s + RATE as usize * 6 / 5) {
                    break;
                }
            }
            Err(e) => {
                capture_xruns += 1;
                capture.try_recover(e, true).context("capture recover")?;
                capture.start()?;
            }
        }
    }
    let playback_xruns = player
        .join()
        .map_err(|_| anyhow::anyhow!("playback thread panicked"))??;
    samples.truncate(filled);
    Ok(ToneCapture {
        samples,
        start: start.context("the captured stream holds no tone at all")?,
        capture_xruns,
        playback_xruns,
    })
}

/// Plays 1.5 s of a 1 kHz tone at -6 dBFS peak into `hw:Loopback,0,0` and
/// captures it from `hw:Loopback,1,0`: the frequency, the level and every
/// sample must come through unchanged.
#[test]
fn alsa_loopback_carries_a_1khz_tone_unchanged() -> anyhow::Result<()> {
    const AMP: f64 = 0.5;
    // 48 samples are exactly one period at 48 kHz: repeat one cycle, so the
    // played stream is exactly periodic and can be compared sample by sample.
    let cycle = hil::sine_i16(1000.0, RATE, AMP, 48);
    let tone: Vec<i16> = cycle
        .iter()
        .copied()
        .cycle()
        .take(RATE as usize * 3 / 2)
        .collect();

    // An xrun on either side (a scheduling stall, likely under emulation)
    // leaves a gap in the stream, which is not what this test is about (the
    // next test is): try again, up to three times.
    let mut attempts = Vec::new();
    let cap = loop {
        let c = play_and_capture(tone.clone())?;
        if c.capture_xruns == 0 && c.playback_xruns == 0 {
            break c;
        }
        attempts.push((c.capture_xruns, c.playback_xruns));
        ensure!(
            attempts.len() < 3,
            "every attempt had xruns (capture, playback): {attempts:?}"
        );
    };
    if !attempts.is_empty() {
        println!("attempts with xruns (capture, playback), retried: {attempts:?}");
    }

    let window = cap
        .samples
        .get(cap.start + 1024..cap.start + 1024 + RATE as usize)
        .context("less than 1 s of tone captured")?;
    let f = hil::zero_crossing_frequency(window, RATE).context("no zero crossings")?;
    assert!(
        (f - 1000.0).abs() < 0.5,
        "captured frequency {f:.3} Hz, expected 1000 Hz"
    );
    let level_db = 20.0 * (hil::rms(window) / (AMP / 2f64.sqrt())).log10();
    assert!(
        level_db.abs() < 0.05,
        "captured level off by {level_db:.3} dB"
    );

    // The loopback copies samples unchanged: the window must equal the played
    // cycle at some phase, sample for sample.
    let phase = (0..48)
        .find(|&p| {
            window
                .iter()
                .take(48)
                .enumerate()
                .all(|(i, &s)| s == cycle[(p + i) % 48])
        })
        .context("captured samples are not a bit-exact copy of the tone")?;
    let mismatches = window
        .iter()
        .enumerate()
        .filter(|&(i, &s)| s != cycle[(phase + i) % 48])
        .count();
    assert_eq!(
        mismatches, 0,
        "samples changed on the way through the loopback"
    );
    Ok(())
}

/// Stops reading a running capture for longer than its buffer, checks that the
/// overrun is reported (EPIPE, state XRun), recovers, and reads on.
#[test]
fn alsa_capture_overrun_is_detected_and_recovered() -> anyhow::Result<()> {
    // Small buffers (480 x 4 frames, 40 ms), so starving capture overruns fast.
    const PERIOD: usize = 480;
    const PERIODS: usize = 4;
    // Subdevice 1, so that this runs beside the tone test on subdevice 0.
    // Playback is kept fed from a thread, so the cable keeps running while
    // the capture side is starved.
    let capture = open_pcm("hw:Loopback,1,1", Direction::Capture, PERIOD, PERIODS)?;
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = stop.clone();
    let feeder = std::thread::spawn(move || -> anyhow::Result<()> {
        let playback = open_pcm("hw:Loopback,0,1", Direction::Playback, PERIOD, PERIODS)?;
        let io = playback.io_i16()?;
        let chunk = hil::sine_i16(1000.0, RATE, 0.25, PERIOD);
        while !stop2.load(Ordering::Relaxed) {
            if let Err(e) = io.writei(&chunk) {
                playback.try_recover(e, true)?;
            }
        }
        Ok(())
    });
    let cio = capture.io_i16()?;
    capture.start()?;
    let mut buf = vec![0i16; PERIOD];
    // One good read first (a stall right after start could already overrun).
    let mut early_xruns = 0;
    while let Err(e) = cio.readi(&mut buf) {
        early_xruns += 1;
        ensure!(
            early_xruns < 5,
            "capture keeps failing before the test starts: {e}"
        );
        capture.try_recover(e, true)?;
        capture.start()?;
    }
    let buffer_time = Duration::from_millis((PERIOD * PERIODS * 1000 / RATE as usize) as u64);
    std::thread::sleep(buffer_time * 5);

    let err = match cio.readi(&mut buf) {
        Ok(n) => {
            bail!("capture read {n} frames after {buffer_time:?}x5 without reading: no overrun")
        }
        Err(e) => e,
    };
    assert_eq!(
        err.errno(),
        libc::EPIPE,
        "an overrun is reported as EPIPE: {err}"
    );
    assert_eq!(
        capture.state(),
        State::XRun,
        "capture state after the overrun"
    );
    capture
        .try_recover(err, true)
        .context("snd_pcm_recover after the overrun")?;
    ensure!(
        capture.state() == State::Prepared,
        "state after recovery: {:?}",
        capture.state()
    );
    capture.start()?;
    // Read 0.5 s after recovery; the stream must still carry the tone that
    // playback feeds (most periods: under emulation the feeder may underrun,
    // and a stall of more than 40 ms overruns capture again, which is
    // recovered the same way and counted).
    let (mut periods, mut with_tone, mut later_xruns) = (0, 0, 0);
    while periods < 50 {
        match cio.readi(&mut buf) {
            Ok(n) => {
                ensure!(n == PERIOD, "short read {n}");
                periods += 1;
                if hil::zero_crossing_frequency(&buf, RATE)
                    .is_some_and(|f| (f - 1000.0).abs() < 20.0)
                {
                    with_tone += 1;
                }
            }
            Err(e) => {
                later_xruns += 1;
                ensure!(
                    later_xruns <= 10,
                    "capture does not stay up after recovery: {e}"
                );
                capture
                    .try_recover(e, true)
                    .context("recovering a later overrun")?;
                capture.start()?;
            }
        }
    }
    assert!(
        with_tone >= periods / 2,
        "only {with_tone}/{periods} periods carry the tone after recovery"
    );
    if later_xruns > 0 {
        println!("{later_xruns} more overrun(s) after the provoked one, recovered");
    }

    stop.store(true, Ordering::Relaxed);
    feeder
        .join()
        .map_err(|_| anyhow::anyhow!("feeder thread panicked"))??;
    Ok(())
}

/// The helper that later HIL tests use to run service binaries works in this
/// environment (a static binary from the guest or host: `sh`), and logs land
/// in `GRIP_HIL_OUT`, which the harness copies back to the host.
#[test]
fn child_processes_run_and_their_logs_are_kept() -> anyhow::Result<()> {
    let dir = hil::out_dir("hil_smoke")?;
    let sh = hil::tool("sh")?;
    let mut p = Proc::spawn(&sh, &["-c", "echo hello from $$; exit 3"], "sh-echo", &dir)?;
    let st = p
        .wait_timeout(Duration::from_secs(10))?
        .context("sh did not exit")?;
    assert_eq!(st.code(), Some(3));
    let text = p.log_text();
    assert!(text.starts_with("hello from "), "log: {text:?}");
    assert!(p.log_path().starts_with(&dir));
    Ok(())
}

/// The workspace's binaries and `config/` are where later HIL tests will look
/// for them (`GRIP_BIN_DIR`, `GRIP_CONFIG_DIR`; the harness builds and copies
/// them): `grip`, the one binary every workspace has, runs from there.
#[test]
fn workspace_binaries_and_config_are_in_place() -> anyhow::Result<()> {
    let cfg = hil::config_dir();
    let vehicle = std::fs::read_to_string(cfg.join("vehicle.toml"))
        .with_context(|| format!("reading {}/vehicle.toml", cfg.display()))?;
    ensure!(
        !vehicle.trim().is_empty(),
        "{}/vehicle.toml is empty",
        cfg.display()
    );

    let dir = hil::out_dir("hil_smoke")?;
    let mut p = Proc::service("grip", &["--version"], &dir)?;
    let st = p
        .wait_timeout(Duration::from_secs(30))?
        .context("grip --version did not exit")?;
    let text = p.log_text();
    assert!(st.success(), "grip --version: {st}, output {text:?}");
    assert!(text.starts_with("grip "), "grip --version printed {text:?}");
    Ok(())
}
