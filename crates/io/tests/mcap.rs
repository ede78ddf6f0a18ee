//! MCAP: every payload type written and read back exactly; metadata,
//! attachments; a log cut off after a flush is readable up to the flush;
//! the official Python reader is tested in `mcap_python.rs`.
#![allow(clippy::type_complexity)]

use std::collections::BTreeMap;
use std::time::Duration;

use grip_io::mcaplog::*;
use grip_msgs::*;
use proptest::prelude::*;

fn sample_set(
    n: u64,
) -> (
    Vec<AudioBlock>,
    Vec<RoadEstimate>,
    Vec<CycleRecord>,
    Vec<CanFrame>,
    Vec<GroundTruth>,
) {
    let mut audio = Vec::new();
    let mut road = Vec::new();
    let mut cyc = Vec::new();
    let mut can = Vec::new();
    let mut truth = Vec::new();
    for i in 0..n {
        let t = 1_000_000_000 + i * 1_000_000;
        let mut a = AudioBlock::zeroed();
        a.seq = i;
        a.stamp_ns = t;
        a.sample_rate = 44_100;
        a.n_samples = (64 + i as u32 * 7) % AUDIO_MAX_SAMPLES as u32;
        a.channel = 1;
        a.xruns = i as u32 / 3;
        for k in 0..a.n_samples as usize {
            a.samples[k] = ((k as i64 * 7919 + i as i64 * 31) % 65536 - 32768) as i16;
        }
        audio.push(a);
        let mut r = RoadEstimate::zeroed();
        r.seq = i;
        r.stamp_ns = t + 1;
        r.frame_t0_ns = t - 100_000_000;
        r.frame_t1_ns = t;
        r.class_index = (i % 4) as u32;
        r.n_classes = 4;
        r.class_name = name_to_bytes(["asphalt", "gravel", "snow", "stone"][(i % 4) as usize]);
        r.probabilities = [0.1, 0.2, 0.3, 0.4, 0.0, 0.0, 0.0, f32::MIN_POSITIVE];
        r.probabilities[0] = 1.0 / (i as f32 + 3.0);
        r.confidence = 0.8 + 1e-17 * i as f64;
        r.lambda_opt = 0.17 + i as f64 * 1e-9;
        r.mu_peak = 1.17;
        r.alpha = 1.0 / 3.0;
        r.x_from = 1.5 * i as f64 - 0.28;
        r.x_to = 1.5 * i as f64;
        road.push(r);
        let mut c = CycleRecord::zeroed();
        c.seq = i;
        c.stamp_ns = t + 2;
        c.wakeup_latency_ns = 13_000 - i as i64 * 100;
        c.compute_ns = 4_200;
        c.deadline_misses = i / 50;
        c.omega = 30.0 + (i as f64).sin();
        c.v = 8.3e-3 * i as f64;
        c.torque = -12.5;
        c.demand = 300.0;
        c.torque_cmd = 187.25;
        c.internal = f64::MAX;
        c.mu_hat = f64::MIN_POSITIVE;
        c.odometer = 0.001 * i as f64;
        c.torque_cap = 182.66;
        c.belief_prob = 0.75;
        c.belief_road = 3;
        c.road_class = if i % 5 == 0 { NO_CLASS } else { 2 };
        c.used_arte = (i % 2) as u8;
        c.safe_state = (i % 7 == 0) as u8;
        c.v_valid = 1;
        c.faults.crc = i as u32;
        c.faults.timeout = 2;
        cyc.push(c);
        let mut f = CanFrame::new(
            0x100 + (i as u32 % 5) * 0x10,
            &[i as u8, 2, 3, 4, 5, 6, 7, 255],
        );
        f.stamp_ns = t + 3;
        f.direction = (i % 2) as u8;
        f.flags = can_flags::E2E_REJECTED;
        can.push(f);
        let mut g = GroundTruth::zeroed();
        g.seq = i;
        g.stamp_ns = t + 4;
        g.road_index = 1;
        g.road_name = name_to_bytes("wet_cobblestone");
        g.mic_road_index = 2;
        g.mic_road_name = name_to_bytes("snow");
        g.v = 2.7777777777777777;
        g.omega = 10.0;
        g.lambda = -0.0;
        g.torque = 1e-300;
        g.x = 12345.678;
        truth.push(g);
    }
    (audio, road, cyc, can, truth)
}

#[test]
fn all_types_round_trip_exactly_with_metadata_and_attachments() {
    for comp in [Compression::None, Compression::Lz4, Compression::Zstd] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("all.mcap");
        let (audio, road, cyc, can, truth) = sample_set(300);
        let mut w = McapWriter::create(
            &path,
            McapWriterOptions {
                compression: comp,
                chunk_size: 64 * 1024,
                ..McapWriterOptions::default()
            },
        )
        .unwrap();
        let mut info = RunInfo {
            version: "0.1.0".into(),
            git_revision: "abc123".into(),
            ..RunInfo::default()
        };
        let dbc = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/inverter.dbc");
        let h = w
            .attach_file(std::path::Path::new(dbc), "text/x-dbc")
            .unwrap();
        info.config_hashes.insert("inverter.dbc".into(), h.clone());
        info.model_hashes
            .insert("arte.json".into(), sha256_hex(b"model"));
        w.write_run_info(&info).unwrap();
        w.attach_bytes("model.bin", "application/octet-stream", &[0, 1, 2, 255])
            .unwrap();
        for i in 0..300 {
            w.write(topics::AUDIO, &audio[i]).unwrap();
            w.write(topics::ROAD, &road[i]).unwrap();
            w.write(topics::CYCLE, &cyc[i]).unwrap();
            w.write(topics::CAN_LOG, &can[i]).unwrap();
            w.write(topics::TRUTH, &truth[i]).unwrap();
        }
        // a topic cannot change its type
        assert!(matches!(
            w.write(topics::CYCLE, &can[0]),
            Err(McapLogError::TopicTypeClash { .. })
        ));
        assert_eq!(w.messages(), 1500);
        w.finish().unwrap();

        let log = McapLog::open(&path).unwrap();
        let (msgs, rep) = log.messages().unwrap();
        assert_eq!(rep.truncated, None, "{comp:?}");
        assert_eq!(
            (rep.messages, rep.bad, rep.foreign),
            (1500, 0, 0),
            "{rep:?}"
        );
        let (mut ia, mut ir, mut ic, mut ik, mut it) = (0, 0, 0, 0, 0);
        for e in &msgs {
            match &e.msg {
                LogMessage::Audio(a) => {
                    assert_eq!(e.topic, topics::AUDIO);
                    assert_eq!(**a, audio[ia]);
                    assert_eq!(e.log_time_ns, audio[ia].stamp_ns);
                    ia += 1;
                }
                LogMessage::Road(r) => {
                    assert_eq!(*r, road[ir]);
                    ir += 1;
                }
                LogMessage::Cycle(c) => {
                    assert_eq!(*c, cyc[ic]);
                    ic += 1;
                }
                LogMessage::Can(f) => {
                    assert_eq!(*f, can[ik]);
                    ik += 1;
                }
                LogMessage::Truth(g) => {
                    // -0.0 == 0.0 under PartialEq; check the sign bit too
                    assert_eq!(*g, truth[it]);
                    assert!(g.lambda.is_sign_negative());
                    it += 1;
                }
                LogMessage::Bus(b) => panic!("no bus frame was written: {b:?}"),
            }
        }
        assert_eq!((ia, ir, ic, ik, it), (300, 300, 300, 300, 300));
        let md = log.metadata().unwrap();
        let run = md.iter().find(|(n, _)| n == "grip.run").expect("grip.run");
        assert_eq!(run.1["git_revision"], "abc123");
        assert_eq!(run.1["config.inverter.dbc"], h);
        assert!(
            md.iter()
                .any(|(n, m)| n == "grip.clock" && m.contains_key("monotonic_ns"))
        );
        let att = log.attachments().unwrap();
        assert_eq!(att.len(), 2);
        assert_eq!(att[0].data, std::fs::read(dbc).unwrap());
        assert_eq!(att[1].data, vec![0, 1, 2, 255]);
    }
}

/// The bus log's frames (`grip/can/bus`) read back exactly, as their own
/// type: never as `CanFrame`s of the CAN log, whose readers would mix them in.
#[test]
fn bus_frames_round_trip_on_their_own_channel_and_type() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bus.mcap");
    let mut w = McapWriter::create(&path, McapWriterOptions::default()).unwrap();
    let frames: Vec<BusFrame> = (0..50u32)
        .map(|i| BusFrame {
            stamp_ns: 5_000_000_000 + u64::from(i) * 500_000,
            id: if i % 2 == 0 { 0x3E9 } else { 0x18DA_F110 },
            dlc: (i % 9) as u8,
            bus: 2,
            flags: if i % 2 == 0 { 0 } else { can_flags::EXTENDED }
                | if i % 7 == 0 { can_flags::RTR } else { 0 },
            _reserved: 0,
            data: [i as u8, 0xFF, 1, 2, 3, 4, 5, 255],
        })
        .collect();
    for f in &frames {
        w.write(topics::BUS, f).unwrap();
    }
    let mut c = CanFrame::new(0x100, &[1, 2]);
    c.stamp_ns = 5_000_000_001;
    w.write(topics::CAN_LOG, &c).unwrap();
    w.finish().unwrap();
    let (msgs, rep) = McapLog::open(&path).unwrap().messages().unwrap();
    assert_eq!((rep.messages, rep.bad, rep.foreign), (51, 0, 0), "{rep:?}");
    let bus: Vec<BusFrame> = msgs
        .iter()
        .filter_map(|e| match &e.msg {
            LogMessage::Bus(b) => {
                assert_eq!(e.topic, topics::BUS);
                assert_eq!(e.log_time_ns, b.stamp_ns);
                Some(*b)
            }
            _ => None,
        })
        .collect();
    assert_eq!(bus, frames);
    let cans = msgs
        .iter()
        .filter(|e| matches!(e.msg, LogMessage::Can(_)))
        .count();
    assert_eq!(cans, 1, "bus frames read as CAN-log frames");
}

#[test]
fn nan_is_logged_as_null_and_read_back_as_nan() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.mcap");
    let mut w = McapWriter::create(&path, McapWriterOptions::default()).unwrap();
    let mut c = CycleRecord::zeroed();
    c.mu_hat = f64::NAN;
    c.internal = f64::INFINITY;
    w.write(topics::CYCLE, &c).unwrap();
    w.finish().unwrap();
    let (m, _) = McapLog::open(&path).unwrap().messages().unwrap();
    let LogMessage::Cycle(r) = &m[0].msg else {
        panic!()
    };
    assert!(r.mu_hat.is_nan() && r.internal.is_nan());
}

#[test]
fn crash_after_flush_loses_nothing_before_the_flush() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("crash.mcap");
    let (_, _, cyc, _, _) = sample_set(200);
    let mut w = McapWriter::create(
        &path,
        McapWriterOptions {
            flush_interval: Duration::from_secs(3600),
            ..McapWriterOptions::default()
        },
    )
    .unwrap();
    for c in &cyc[..150] {
        w.write(topics::CYCLE, c).unwrap();
    }
    w.flush().unwrap();
    for c in &cyc[150..] {
        w.write(topics::CYCLE, c).unwrap();
    }
    // "crash": copy the file as it is on disk now, writer never finished
    let snapshot = dir.path().join("snapshot.mcap");
    std::fs::copy(&path, &snapshot).unwrap();
    drop(w);
    let log = McapLog::open(&snapshot).unwrap();
    let (m, rep) = log.messages().unwrap();
    assert!(
        rep.truncated.is_some(),
        "an unfinished file must be reported"
    );
    assert!(
        m.len() >= 150,
        "only {} of the 150 flushed records",
        m.len()
    );
    for (e, c) in m.iter().zip(&cyc) {
        assert_eq!(e.msg, LogMessage::Cycle(*c));
    }
}

#[test]
fn writer_flushes_by_itself_after_the_interval() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("auto.mcap");
    let (_, _, cyc, _, _) = sample_set(3);
    let mut w = McapWriter::create(
        &path,
        McapWriterOptions {
            flush_interval: Duration::from_millis(500),
            ..McapWriterOptions::default()
        },
    )
    .unwrap();
    w.write(topics::CYCLE, &cyc[0]).unwrap();
    std::thread::sleep(Duration::from_millis(550));
    w.write(topics::CYCLE, &cyc[1]).unwrap(); // triggers the flush
    // just flushed: not due again for another interval (checked before the
    // slow read below, so a stalled machine cannot make it due)
    assert!(!w.maybe_flush().unwrap());
    let (m, _) = McapLog::open(&path).unwrap().messages().unwrap();
    assert_eq!(
        m.len(),
        2,
        "both records must be on disk after the timed flush"
    );
}

#[test]
fn bad_json_is_counted_not_fatal_and_non_mcap_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.mcap");
    std::fs::write(&p, b"not an mcap file").unwrap();
    assert!(McapLog::open(&p).unwrap().messages().is_err());
    // a foreign writer puts a CycleRecord schema with broken JSON
    let p2 = dir.path().join("y.mcap");
    let mut w =
        mcap::Writer::new(std::io::BufWriter::new(std::fs::File::create(&p2).unwrap())).unwrap();
    let s = w
        .add_schema(CycleRecord::TYPE_NAME, "jsonschema", b"{}")
        .unwrap();
    let ch = w.add_channel(s, "x", "json", &BTreeMap::new()).unwrap();
    let hdr = mcap::records::MessageHeader {
        channel_id: ch,
        sequence: 0,
        log_time: 0,
        publish_time: 0,
    };
    w.write_to_known_channel(&hdr, br#"{"seq": -1}"#).unwrap();
    let s2 = w.add_schema("other", "jsonschema", b"{}").unwrap();
    let ch2 = w.add_channel(s2, "y", "json", &BTreeMap::new()).unwrap();
    w.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id: ch2,
            ..hdr
        },
        b"{}",
    )
    .unwrap();
    w.finish().unwrap();
    drop(w);
    let (m, rep) = McapLog::open(&p2).unwrap().messages().unwrap();
    assert!(m.is_empty());
    assert_eq!((rep.bad, rep.foreign), (1, 1));
    assert!(rep.first_error.unwrap().contains("seq"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Arbitrary finite values survive the JSON mapping bit for bit.
    #[test]
    fn arbitrary_cycle_records_round_trip(
        vals in proptest::array::uniform7(proptest::num::f64::NORMAL | proptest::num::f64::SUBNORMAL | proptest::num::f64::ZERO),
        ints in proptest::array::uniform4(any::<u64>()),
        lat in any::<i64>(), f in any::<[u32; 6]>(), b in any::<[u8; 4]>(), rc in any::<u32>(),
    ) {
        let c = CycleRecord {
            seq: ints[0], stamp_ns: ints[1], wakeup_latency_ns: lat, compute_ns: ints[2],
            deadline_misses: ints[3], omega: vals[0], v: vals[1], torque: vals[2], demand: vals[3],
            torque_cmd: vals[4], internal: vals[5], mu_hat: vals[6],
            odometer: vals[0] * 0.5, torque_cap: vals[1] * 0.25, belief_prob: vals[2] * 0.125,
            road_class: rc, belief_road: rc ^ 1,
            used_arte: b[0], safe_state: b[1], v_valid: b[2], roads_taken: b[3],
            faults: E2eFaults { crc: f[0], counter_repeated: f[1], counter_skipped: f[2],
                length: f[3], unknown_id: f[4], timeout: f[5] },
            road_taken: rc.rotate_left(3),
        };
        let mut buf = Vec::new();
        c.write_json(&mut buf);
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        let back = CycleRecord::from_json(&v).unwrap();
        prop_assert_eq!(back, c);
        for (x, y) in [back.omega, back.v, back.torque, back.demand, back.torque_cmd, back.internal, back.mu_hat]
            .iter().zip(vals.iter()) {
            prop_assert_eq!(x.to_bits(), y.to_bits());
        }
    }

    #[test]
    fn arbitrary_road_estimates_round_trip(
        p in proptest::array::uniform8(proptest::num::f32::NORMAL | proptest::num::f32::ZERO),
        name in "[a-z_]{0,16}", x in proptest::num::f64::NORMAL,
    ) {
        let mut r = RoadEstimate::zeroed();
        r.probabilities = p;
        r.class_name = name_to_bytes(&name);
        r.alpha = x;
        r.x_from = x * 0.5;
        r.x_to = -x;
        let mut buf = Vec::new();
        r.write_json(&mut buf);
        let back = RoadEstimate::from_json(&serde_json::from_slice(&buf).unwrap()).unwrap();
        for (a, b) in back.probabilities.iter().zip(p.iter()) {
            prop_assert_eq!(a.to_bits(), b.to_bits());
        }
        prop_assert_eq!(back.class_name(), Some(name.as_str()));
        prop_assert_eq!(back, r);
    }
}

/// Every cut and many single-byte corruptions of a chunked log open without
/// a panic or an abort (the mcap reader alone aborts on some corrupt chunk
/// lengths) and read the intact chunks before the damage in order; a cut or
/// a corruption that loses data is reported as truncated. (What a
/// corruption leaves readable after it: `mcap_damage.rs`.)
#[test]
fn damaged_logs_read_up_to_the_damage() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("whole.mcap");
    let (_, _, cyc, _, _) = sample_set(400);
    let mut w = McapWriter::create(
        &path,
        McapWriterOptions {
            chunk_size: 4096,
            ..McapWriterOptions::default()
        },
    )
    .unwrap();
    for c in &cyc {
        w.write(topics::CYCLE, c).unwrap();
    }
    w.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(first_damage(&bytes), None, "the whole file is intact");
    let q = dir.path().join("damaged.mcap");
    let read = |b: &[u8]| {
        std::fs::write(&q, b).unwrap();
        McapLog::open(&q).and_then(|l| l.messages())
    };
    let step = (bytes.len() / 150).max(1);
    let mut partial = 0;
    for cut in (8..bytes.len()).step_by(step) {
        let (m, rep) = read(&bytes[..cut]).unwrap();
        assert!(rep.truncated.is_some(), "cut at {cut} not reported");
        assert!(m.len() < cyc.len() || cut > bytes.len() / 2);
        for (e, c) in m.iter().zip(&cyc) {
            assert_eq!(e.msg, LogMessage::Cycle(*c), "cut at {cut}");
        }
        partial += usize::from(!m.is_empty() && m.len() < cyc.len());
    }
    assert!(partial > 50, "{partial} cuts kept part of the log");
    let mut reported = 0;
    for pos in (8..bytes.len()).step_by(step) {
        let mut b = bytes.clone();
        b[pos] ^= 0x5A;
        if let Ok((m, rep)) = read(&b) {
            reported += usize::from(rep.truncated.is_some() || rep.bad > 0);
            assert!(m.len() <= cyc.len());
        }
    }
    assert!(reported > 50, "{reported} corruptions reported");
}
