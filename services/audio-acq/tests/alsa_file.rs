//! The ALSA data path on a host without sound hardware: alsa-lib's
//! user-space `file` plugin with an `infile` over a `null` slave captures a
//! raw S16_LE file through the ordinary ALSA API
//! (`ALSA_CONFIG_PATH=/usr/share/alsa/alsa.conf:EXTRA.conf`). Not paced in real time, so this checks
//! the data path (open, hw/sw params, reads, channel selection, blocks), not
//! timing; the loopback test in the HIL VM covers real capture. A missing
//! device must be a clear error naming it and listing what exists.

use std::sync::Arc;

use grip_audio_acq::alsa_src::{AlsaPcm, AlsaSource};
use grip_audio_acq::config::AlsaSection;
use grip_audio_acq::format::FormatSetting;
use grip_audio_acq::{AcqError, AcqLoop, AcqStatus, BlockSink, Step};
use grip_io::ipc::IpcError;
use grip_msgs::AudioBlock;

#[derive(Default)]
struct VecSink(Vec<AudioBlock>);
impl BlockSink for VecSink {
    fn send(&mut self, b: &AudioBlock) -> Result<(), IpcError> {
        self.0.push(*b);
        Ok(())
    }
}

fn section(device: &str, channels: u32, channel: u32) -> AlsaSection {
    AlsaSection {
        device: device.into(),
        channels,
        channel,
        period_frames: 512,
        buffer_frames: 4096,
        wait_timeout_ms: 200,
        format: FormatSetting::Auto,
        resample: false,
    }
}

// One test function: ALSA_CONFIG_PATH must be set before alsa-lib first
// reads its configuration, once per process.
#[test]
fn alsa_file_plugin_data_path_and_missing_device() {
    let dir = tempfile::tempdir().unwrap();
    // 2 channels interleaved: left = i, right = 30000 - i (mod 30000)
    let frames = 20 * 1024 + 300;
    let mut raw = Vec::with_capacity(frames * 4);
    for i in 0..frames {
        let l = (i % 30_000) as i16;
        let r = 30_000 - l;
        raw.extend_from_slice(&l.to_le_bytes());
        raw.extend_from_slice(&r.to_le_bytes());
    }
    let infile = dir.path().join("in.raw");
    std::fs::write(&infile, &raw).unwrap();
    let conf = dir.path().join("extra.conf");
    std::fs::write(
        &conf,
        format!(
            "pcm.grip_test_capture {{\n type file\n slave {{ pcm \"null\" }}\n file \"/dev/null\"\n infile \"{}\"\n format \"raw\"\n}}\n",
            infile.display()
        ),
    )
    .unwrap();
    // SAFETY: this test binary has a single test function and no other
    // threads read the environment at this point.
    unsafe {
        std::env::set_var(
            "ALSA_CONFIG_PATH",
            format!("/usr/share/alsa/alsa.conf:{}", conf.display()),
        )
    };

    // missing device: clear error naming it and listing what alsa-lib knows
    let e = AlsaPcm::open(&section("hw:NoSuchCard,1,0", 1, 0), 44_100).unwrap_err();
    assert!(matches!(e, AcqError::AlsaDevice { .. }), "{e}");
    let msg = e.to_string();
    println!("{msg}");
    assert!(msg.contains("\"hw:NoSuchCard,1,0\""), "{msg}");
    assert!(msg.contains("Capture PCMs alsa-lib knows:"), "{msg}");
    assert!(msg.contains("null"), "the list names the null PCM: {msg}");

    // the file-backed device, channel 1 of 2, blocks of 1024
    let cfg = section("grip_test_capture", 2, 1);
    let pcm = AlsaPcm::open(&cfg, 44_100).unwrap();
    println!(
        "opened {}: period {} buffer {}",
        pcm.device, pcm.period_frames, pcm.buffer_frames
    );
    let src = AlsaSource::new(pcm, &cfg, 44_100, 1024);
    let mut lp = AcqLoop::new(src, 1024, 1, Arc::new(AcqStatus::default()));
    let mut sink = VecSink::default();
    for _ in 0..20 {
        assert_eq!(lp.step(&mut sink).unwrap(), Step::Published);
    }
    let mut i = 0usize;
    for (k, b) in sink.0.iter().enumerate() {
        assert_eq!(b.seq, k as u64);
        assert_eq!(b.n_samples, 1024);
        assert_eq!(b.sample_rate, 44_100);
        assert_eq!(b.channel, 1);
        assert_eq!(b.xruns, 0);
        for &s in b.samples() {
            assert_eq!(s, 30_000 - (i % 30_000) as i16, "sample {i}");
            i += 1;
        }
    }
    // stamps are monotonic (the file plugin is not paced, so nothing more)
    for w in sink.0.windows(2) {
        assert!(w[1].stamp_ns >= w[0].stamp_ns);
    }
    println!("stamp fallbacks: {}", lp.source().stamp_fallbacks());
}
