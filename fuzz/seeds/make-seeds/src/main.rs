//! Writes `fuzz/seeds/mcap/*.mcap` and `fuzz/seeds/model/paper-v2.model`.
//!
//! The MCAP seeds are small drive logs written by the recorder's own writer
//! (`grip_io::mcaplog::McapWriter`): every grip topic (audio blocks, road
//! estimates, cycle records, CAN frames encoded by the inverter protocol,
//! ground truth), the `grip.run` metadata and an attachment, in 4 KiB chunks,
//! once per compression (none, LZ4, zstd), plus the uncompressed one cut
//! short as a crash leaves it. The model seed is `config/models/paper.model`
//! with the confidence calibration of `config/models/default.model` (a
//! small format-2 model; default.model itself is 785 KB, too large to
//! mutate quickly).

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use grip_arte::model::Model;
use grip_io::can::protocol::{
    DriverDemand, E2eSender, MotorStatus, TorqueCommand, VehicleSpeed, WheelSpeeds,
};
use grip_io::mcaplog::{Compression, McapWriter, McapWriterOptions, RunInfo};
use grip_msgs::{
    AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, name_to_bytes, topics,
};

fn write_log(path: &Path, compression: Compression) {
    let opts = McapWriterOptions {
        compression,
        chunk_size: 4096,
        flush_interval: Duration::from_secs(3600),
    };
    let mut w = McapWriter::create(path, opts).expect("create");
    w.add_topic::<AudioBlock>(topics::AUDIO).unwrap();
    w.add_topic::<RoadEstimate>(topics::ROAD).unwrap();
    w.add_topic::<CycleRecord>(topics::CYCLE).unwrap();
    w.add_topic::<CanFrame>(topics::CAN_LOG).unwrap();
    w.add_topic::<GroundTruth>(topics::TRUTH).unwrap();
    let mut info = RunInfo {
        version: "0.1.0".into(),
        git_revision: "seed".into(),
        ..RunInfo::default()
    };
    info.config_hashes
        .insert("vehicle.toml".into(), "0".repeat(64));
    w.write_run_info(&info).unwrap();
    let t0 = 1_000_000_000u64;
    let (mut ws, mut ms, mut vs, mut dd, mut tc) = (
        E2eSender::<WheelSpeeds>::new(),
        E2eSender::<MotorStatus>::new(),
        E2eSender::<VehicleSpeed>::new(),
        E2eSender::<DriverDemand>::new(),
        E2eSender::<TorqueCommand>::new(),
    );
    for k in 0..20u64 {
        let t = t0 + k * 1_000_000;
        let v = 3.0 + 0.01 * k as f64;
        let omega = v / 0.3 * 1.05;
        let mut frames = vec![
            ws.encode(
                &WheelSpeeds {
                    driven_valid: true,
                    ref_valid: true,
                    omega_driven: omega,
                    omega_ref: v / 0.3,
                },
                t,
            ),
            ms.encode(
                &MotorStatus {
                    ready: true,
                    fault: false,
                    derating: false,
                    cmd_timeout: false,
                    torque_actual: 120.0,
                    motor_speed: omega,
                    fault_code: 0,
                },
                t,
            ),
            tc.encode(
                &TorqueCommand {
                    torque_request: 118.5,
                    enable: true,
                },
                t,
            ),
        ];
        if k % 10 == 0 {
            frames.push(vs.encode(
                &VehicleSpeed {
                    valid: true,
                    speed: v,
                    long_accel: 0.4,
                },
                t,
            ));
            frames.push(dd.encode(
                &DriverDemand {
                    brake_pressed: false,
                    tcs_enable: true,
                    torque_demand: 300.0,
                    pedal_position: 60.0,
                },
                t,
            ));
        }
        for f in &frames {
            w.write(topics::CAN_LOG, f).unwrap();
        }
        let mut rec = CycleRecord::zeroed();
        rec.seq = k;
        rec.stamp_ns = t;
        rec.omega = omega;
        rec.v = v;
        rec.v_valid = 1;
        rec.torque = 120.0;
        rec.demand = 300.0;
        rec.torque_cmd = 118.5;
        rec.mu_hat = 0.6;
        rec.internal = f64::NAN; // written as null
        rec.odometer = 0.003 * k as f64;
        w.write(topics::CYCLE, &rec).unwrap();
        if k % 10 == 0 {
            let mut a = AudioBlock::zeroed();
            a.seq = k / 10;
            a.stamp_ns = t;
            a.sample_rate = 44_100;
            a.n_samples = 64;
            for (i, s) in a.samples[..64].iter_mut().enumerate() {
                *s = ((i as f64 * 0.3).sin() * 8000.0) as i16;
            }
            w.write(topics::AUDIO, &a).unwrap();
            let mut e = RoadEstimate::zeroed();
            e.seq = k / 10;
            e.stamp_ns = t;
            e.frame_t0_ns = t - 50_000_000;
            e.frame_t1_ns = t;
            e.class_index = 0;
            e.n_classes = 2;
            e.class_name = name_to_bytes("asphalt");
            e.probabilities[0] = 0.9;
            e.probabilities[1] = 0.1;
            e.confidence = 0.9;
            e.lambda_opt = 0.17;
            e.mu_peak = 1.0;
            e.alpha = 0.83;
            w.write(topics::ROAD, &e).unwrap();
            let mut g = GroundTruth::zeroed();
            g.seq = k / 10;
            g.stamp_ns = t;
            g.road_name = name_to_bytes("asphalt");
            g.mic_road_name = name_to_bytes("asphalt");
            g.v = v;
            g.omega = omega;
            g.lambda = 0.05;
            w.write(topics::TRUTH, &g).unwrap();
        }
    }
    let mut m = BTreeMap::new();
    m.insert("cycles".to_owned(), "20".to_owned());
    w.write_metadata("grip.recorder", &m).unwrap();
    w.attach_bytes("vehicle.toml", "application/toml", b"[vehicle]\nr = 0.3\n")
        .unwrap();
    w.finish().unwrap();
}

fn main() {
    let here = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let repo = here.join("../..");
    let dir = here.join("mcap");
    std::fs::create_dir_all(&dir).unwrap();
    for (name, c) in [
        ("drive-none.mcap", Compression::None),
        ("drive-lz4.mcap", Compression::Lz4),
        ("drive-zstd.mcap", Compression::Zstd),
    ] {
        write_log(&dir.join(name), c);
    }
    let whole = std::fs::read(dir.join("drive-none.mcap")).unwrap();
    std::fs::write(
        dir.join("drive-crashed.mcap"),
        &whole[..whole.len() * 7 / 10],
    )
    .unwrap();

    let load = |name: &str| {
        Model::from_bytes(&std::fs::read(repo.join("config/models").join(name)).unwrap())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
    };
    let calib = load("default.model").calibration().cloned();
    let v2 = load("paper.model")
        .with_calibration(calib)
        .expect("paper + calibration");
    std::fs::create_dir_all(here.join("model")).unwrap();
    std::fs::write(here.join("model/paper-v2.model"), v2.to_bytes().unwrap()).unwrap();
}
