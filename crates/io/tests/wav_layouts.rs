//! Sample layouts of WAV files (crates/io/README.md, "WAV files"): a
//! `WAVE_FORMAT_EXTENSIBLE` file with fewer valid bits than its container
//! holds them left-aligned (the Microsoft spec); hound 3.5 took the low
//! bytes, so 24 valid bits in 32-bit containers decoded to garbage without
//! a word (a road classified wet_stone instead of asphalt). Layouts that
//! cannot be read correctly are refused by name, and float samples beyond
//! full scale are counted, not clamped silently.

use std::path::Path;

use grip_io::wav::{WavErrorKind, decode_mono, read_mono};

const RATE: u32 = 48_000;
const PCM_GUID: [u8; 16] = [
    0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x80, 0x00, 0x00, 0xaa, 0x00, 0x38, 0x9b, 0x71,
];

/// A 1 kHz tone at half full scale as 24-bit integers.
fn tone24() -> Vec<i32> {
    (0..4800)
        .map(|n| {
            let x =
                0.5 * (2.0 * std::f64::consts::PI * 1000.0 * f64::from(n) / f64::from(RATE)).sin();
            (x * f64::from(1 << 23)).round() as i32
        })
        .collect()
}

fn chunk(tag: &[u8; 4], payload: &[u8]) -> Vec<u8> {
    let mut c = tag.to_vec();
    c.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    c.extend_from_slice(payload);
    if payload.len() % 2 == 1 {
        c.push(0);
    }
    c
}

/// A RIFF WAVE file of `chunks`.
fn riff(chunks: &[Vec<u8>]) -> Vec<u8> {
    let body: Vec<u8> = b"WAVE".iter().copied().chain(chunks.concat()).collect();
    let mut f = b"RIFF".to_vec();
    f.extend_from_slice(&(body.len() as u32).to_le_bytes());
    f.extend_from_slice(&body);
    f
}

/// A fmt chunk: plain (`valid` None, tag 1) or EXTENSIBLE PCM, mono.
fn fmt(container_bytes: u16, bits: u16, valid: Option<u16>) -> Vec<u8> {
    let mut f = Vec::new();
    let tag: u16 = if valid.is_some() { 0xFFFE } else { 1 };
    f.extend_from_slice(&tag.to_le_bytes());
    f.extend_from_slice(&1u16.to_le_bytes());
    f.extend_from_slice(&RATE.to_le_bytes());
    f.extend_from_slice(&(RATE * u32::from(container_bytes)).to_le_bytes());
    f.extend_from_slice(&container_bytes.to_le_bytes());
    f.extend_from_slice(&bits.to_le_bytes());
    if let Some(v) = valid {
        f.extend_from_slice(&22u16.to_le_bytes());
        f.extend_from_slice(&v.to_le_bytes());
        f.extend_from_slice(&4u32.to_le_bytes());
        f.extend_from_slice(&PCM_GUID);
    }
    chunk(b"fmt ", &f)
}

fn data(samples: &[i32], bytes: usize, shift: u32) -> Vec<u8> {
    let d: Vec<u8> = samples
        .iter()
        .flat_map(|&v| (v << shift).to_le_bytes()[..bytes].to_vec())
        .collect();
    chunk(b"data", &d)
}

fn decode(name: &str, bytes: &[u8]) -> Vec<f32> {
    decode_mono(bytes, Path::new(name))
        .unwrap_or_else(|e| panic!("{e}"))
        .samples
}

fn assert_close(a: &[f32], b: &[f32], lsb: f32, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (i, (u, v)) in a.iter().zip(b).enumerate() {
        assert!((u - v).abs() <= lsb, "{what}: sample {i}: {u} vs {v}");
    }
}

#[test]
fn extensible_24_valid_bits_in_32_bit_containers_decode_like_arecord_s24_le() {
    let x = tone24();
    let expect: Vec<f32> = x.iter().map(|&v| v as f32 / (1 << 23) as f32).collect();
    let lsb = 1.0 / (1 << 23) as f32;
    // arecord's S24_LE: plain PCM tag, 24 bits in the low 3 of 4 bytes
    // (sign-extended into the top byte)
    let plain = riff(&[fmt(4, 24, None), data(&x, 4, 0)]);
    let a = decode("s24le.wav", &plain);
    assert_close(&a, &expect, lsb, "plain PCM S24_LE in 4 bytes");
    // EXTENSIBLE: 24 valid bits left-aligned in 32-bit containers
    let ext = riff(&[fmt(4, 32, Some(24)), data(&x, 4, 8)]);
    let b = decode("ext24in32.wav", &ext);
    assert_close(&b, &a, lsb, "EXTENSIBLE 24 in 32 vs plain S24_LE");
    // the same from a file, and behind a chunk before fmt
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ext24in32.wav");
    let bwf = riff(&[
        chunk(b"bext", &[0u8; 602]),
        fmt(4, 32, Some(24)),
        chunk(b"LIST", b"INFOISFT\x06\x00\x00\x00grip\x00\x00"),
        data(&x, 4, 8),
    ]);
    std::fs::write(&p, &bwf).unwrap();
    assert_close(&read_mono(&p).unwrap().samples, &a, lsb, "from a file");
}

#[test]
fn extensible_20_valid_bits_in_24_bit_containers_are_left_aligned() {
    let x: Vec<i32> = tone24().iter().map(|v| v >> 4).collect();
    let expect: Vec<f32> = x.iter().map(|&v| v as f32 / (1 << 19) as f32).collect();
    let ext = riff(&[fmt(3, 24, Some(20)), data(&x, 3, 4)]);
    assert_close(
        &decode("ext20in24.wav", &ext),
        &expect,
        1e-7,
        "EXTENSIBLE 20 in 24",
    );
}

#[test]
fn extensible_with_as_many_valid_bits_as_the_container_is_unchanged() {
    let x = tone24();
    // 24 in 24, written by hound (EXTENSIBLE above 16 bits)
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ext24.wav");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: RATE,
        bits_per_sample: 24,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(&p, spec).unwrap();
    for &v in &x {
        w.write_sample(v).unwrap();
    }
    w.finalize().unwrap();
    assert_eq!(std::fs::read(&p).unwrap()[20..22], [0xFE, 0xFF]);
    let expect: Vec<f32> = x.iter().map(|&v| v as f32 / (1 << 23) as f32).collect();
    assert_eq!(read_mono(&p).unwrap().samples, expect);
    // 16 in 16, EXTENSIBLE and plain
    let x16: Vec<i32> = x.iter().map(|v| v >> 8).collect();
    let ext = decode(
        "ext16.wav",
        &riff(&[fmt(2, 16, Some(16)), data(&x16, 2, 0)]),
    );
    let plain = decode("pcm16.wav", &riff(&[fmt(2, 16, None), data(&x16, 2, 0)]));
    assert_eq!(ext, plain);
    let expect16: Vec<f32> = x16.iter().map(|&v| v as f32 / 32_768.0).collect();
    assert_eq!(ext, expect16);
}

/// An EXTENSIBLE file whose samples sit in the low bytes of their
/// containers (hound's own writer does this for 24 bits in 4 bytes) has
/// non-zero padding bits: refused by name, not decoded to garbage.
#[test]
fn extensible_samples_not_left_aligned_are_refused() {
    let x = tone24();
    let right = riff(&[fmt(4, 32, Some(24)), data(&x, 4, 0)]);
    let e = decode_mono(&right, Path::new("right_aligned.wav")).unwrap_err();
    assert!(matches!(e.kind, WavErrorKind::Layout(_)), "{e}");
    let text = e.to_string();
    assert!(
        text.contains("right_aligned.wav") && text.contains("padding bits"),
        "{text}"
    );
    // silence is the same either way and reads as silence
    let zero = riff(&[fmt(4, 32, Some(24)), data(&[0; 100], 4, 0)]);
    assert_eq!(decode("zero.wav", &zero), vec![0.0; 100]);
}

/// The fewest valid bits, 1 in a 32-bit container (the widest padding,
/// 31 bits): read as the sign bit, -1 or 0 (a debug build's padding mask
/// overflowed on it, before a sample was read); non-zero padding refused
/// as for any width.
#[test]
fn one_valid_bit_in_32_is_read() {
    let x = [1i32, 0, 1, 1];
    // the valid bit at the top of the container: -1 for a set bit
    let f = riff(&[fmt(4, 32, Some(1)), data(&x, 4, 31)]);
    assert_eq!(decode("one_bit.wav", &f), [-1.0, 0.0, -1.0, -1.0]);
    let empty = riff(&[fmt(4, 32, Some(1)), data(&[], 4, 0)]);
    assert_eq!(decode("empty.wav", &empty), Vec::<f32>::new());
    let padded = riff(&[fmt(4, 32, Some(1)), data(&[1], 4, 0)]);
    let e = decode_mono(&padded, Path::new("padded.wav")).unwrap_err();
    assert!(matches!(e.kind, WavErrorKind::Layout(_)), "{e}");
}

#[test]
fn layouts_that_cannot_be_read_are_refused_by_name() {
    let x: Vec<i32> = vec![0; 16];
    let cases = [
        // plain PCM 16 bits in 4-byte containers: hound cannot read it
        (
            "pcm16in32.wav",
            riff(&[fmt(4, 16, None), data(&x, 4, 0)]),
            "16-bit integer samples in 4-byte containers",
        ),
        // more valid bits than the container holds
        (
            "ext32in24.wav",
            riff(&[fmt(3, 24, Some(32)), data(&x, 3, 0)]),
            "32 valid bits in 24-bit containers",
        ),
    ];
    for (name, bytes, reason) in cases {
        let e = decode_mono(&bytes, Path::new(name))
            .unwrap_err()
            .to_string();
        assert!(e.contains(name) && e.contains(reason), "{e}");
    }
}

#[test]
fn float_samples_beyond_full_scale_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, xs: &[f32]| {
        let p = dir.path().join(name);
        let spec = hound::WavSpec {
            channels: 1,
            sample_rate: RATE,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let mut w = hound::WavWriter::create(&p, spec).unwrap();
        for &v in xs {
            w.write_sample(v).unwrap();
        }
        w.finalize().unwrap();
        p
    };
    let a = read_mono(&write("hot.wav", &[2.5, -1.5, 0.5, 1.0, f32::NAN])).unwrap();
    assert_eq!(a.samples, [1.0, -1.0, 0.5, 1.0, 0.0]);
    assert_eq!((a.clamped, a.non_finite), (2, 1));
    let b = read_mono(&write("ok.wav", &[1.0, -1.0, 0.25])).unwrap();
    assert_eq!(b.samples, [1.0, -1.0, 0.25]);
    assert_eq!((b.clamped, b.non_finite), (0, 0));
    // the counts survive a conversion (audio-acq's S16)
    let c = a.map(|s| (s * 32767.0) as i16);
    assert_eq!((c.clamped, c.non_finite), (2, 1));
}
