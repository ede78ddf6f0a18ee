//! `grip inspect --csv DIR`: the log's cycle records, road estimates,
//! ground truth and CAN frames as CSV files, one row per message. Every file
//! has two times: `t_s`, seconds since the first message of the log, and
//! `t_scenario_s`, seconds since the scenario start as the summary finds it
//! (empty when the log does not show it: no ground truth, or the scenario
//! never started); plus the raw ns stamp. An index with nothing behind it
//! (`NO_CLASS`, u32::MAX in the message: no road, no class, no believed
//! road) is an empty field, as is a value that is not finite (NaN: no cap,
//! no belief); `road_taken` counts 0 for none.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::Context;
use grip_msgs::{NO_CLASS, can_dir};

use grip_drive::{DriveLog, summary};

fn f(x: f64) -> String {
    if x.is_finite() {
        format!("{x}")
    } else {
        String::new()
    }
}

/// A text field, quoted when it holds a comma, a quote or a line break.
fn q(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

/// An index field: empty for [`NO_CLASS`].
fn idx(i: u32) -> String {
    if i == NO_CLASS {
        String::new()
    } else {
        i.to_string()
    }
}

fn open(dir: &Path, name: &str) -> anyhow::Result<(BufWriter<File>, PathBuf)> {
    let p = dir.join(name);
    let w = File::create(&p).with_context(|| format!("creating {}", p.display()))?;
    Ok((BufWriter::new(w), p))
}

/// The two time origins of `grip inspect`'s outputs (CSV, road timeline,
/// plots).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TimeBase {
    /// The first message of the log ([`DriveLog::first_stamp_ns`]): `t_s` = 0.
    pub first_ns: u64,
    /// The scenario start, the origin of the summary's times (a road change
    /// "at 0.428 s"): the ground-truth sample [`summary::scenario_start`]
    /// picks. None without ground truth or when the scenario never started.
    pub scenario_ns: Option<u64>,
}

fn secs(ns: u64, origin: u64) -> f64 {
    (ns as i128 - origin as i128) as f64 * 1e-9
}

impl TimeBase {
    /// The time origins of `log`.
    pub fn of(log: &DriveLog) -> Self {
        Self {
            first_ns: log.first_stamp_ns(),
            scenario_ns: summary::scenario_start(&log.truth)
                .and_then(|i| log.truth.get(i))
                .map(|g| g.stamp_ns),
        }
    }

    /// Seconds since the first message (`t_s`).
    pub fn since_first(&self, ns: u64) -> f64 {
        secs(ns, self.first_ns)
    }

    /// Seconds since the scenario start (`t_scenario_s`), if known.
    pub fn since_scenario(&self, ns: u64) -> Option<f64> {
        self.scenario_ns.map(|s| secs(ns, s))
    }

    /// The origin of the timeline and the plots: the scenario start when
    /// known, else the first message.
    pub fn origin_ns(&self) -> u64 {
        self.scenario_ns.unwrap_or(self.first_ns)
    }

    /// Seconds since [`TimeBase::origin_ns`].
    pub fn axis(&self, ns: u64) -> f64 {
        secs(ns, self.origin_ns())
    }

    /// What [`TimeBase::axis`] counts from, for labels.
    pub fn axis_label(&self) -> &'static str {
        if self.scenario_ns.is_some() {
            "t (s) from the scenario start (negative: held, and the pre-roll if any)"
        } else {
            "t (s) from the first message of the log (scenario start unknown: no ground truth)"
        }
    }
}

/// Road names by catalogue index, from the `roads.toml` attached to the log
/// (the `[[road]]` entries in order; None if not attached or not readable).
pub fn catalogue_names(log: &DriveLog) -> Option<Vec<String>> {
    let v: toml::Value = toml::from_str(log.attachment_text("roads.toml")?).ok()?;
    v.get("road")?
        .as_array()?
        .iter()
        .map(|r| r.get("name")?.as_str().map(str::to_owned))
        .collect()
}

/// ARTE's class names by class index, as its estimates in the log name them
/// (the classifier's class list, which need not be the catalogue's order);
/// an index named two ways is left out.
pub fn class_names(log: &DriveLog) -> BTreeMap<u32, String> {
    let mut seen: BTreeMap<u32, Option<String>> = BTreeMap::new();
    for e in &log.roads {
        if e.class_index == NO_CLASS {
            continue;
        }
        let name = e.class_name().unwrap_or("").to_owned();
        seen.entry(e.class_index)
            .and_modify(|n| {
                if n.as_deref() != Some(name.as_str()) {
                    *n = None;
                }
            })
            .or_insert(Some(name));
    }
    seen.into_iter()
        .filter_map(|(k, n)| Some((k, n?)))
        .collect()
}

/// The header of `cycles.csv` (`road_class`, `belief_road`: empty for
/// none).
pub const CYCLES_HEADER: &str = "t_s,t_scenario_s,stamp_ns,seq,wakeup_latency_ns,compute_ns,deadline_misses,omega,v,v_valid,torque,demand,torque_cmd,internal,mu_hat,road_class,road_class_name,used_arte,road_taken,roads_taken,safe_state,faults_crc,faults_counter_repeated,faults_counter_skipped,faults_length,faults_unknown_id,faults_timeout,odometer,torque_cap,belief_road,belief_road_name,belief_prob";
/// The header of `estimates.csv` (`class_index`: empty for no class).
pub const ESTIMATES_HEADER: &str = "t_s,t_scenario_s,stamp_ns,seq,frame_t0_s,frame_t1_s,frame_t0_scenario_s,frame_t1_scenario_s,frame_t0_ns,frame_t1_ns,class_index,class_name,confidence,lambda_opt,mu_peak,alpha,n_classes,probabilities,x_from,x_to";
/// The header of `truth.csv` (`road_index`, `mic_road_index`: indices
/// into the road catalogue; empty for no road).
pub const TRUTH_HEADER: &str = "t_s,t_scenario_s,stamp_ns,seq,road_index,road_name,v,omega,lambda,torque,x,mic_road_index,mic_road_name";
/// The header of `can.csv`.
pub const CAN_HEADER: &str = "t_s,t_scenario_s,stamp_ns,id,name,direction,bus,dlc,flags,data";

/// Writes `cycles.csv`, `estimates.csv`, `truth.csv`, `can.csv` into `dir`
/// (created); returns the paths.
pub fn write_csv(log: &DriveLog, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let tb = TimeBase::of(log);
    let t = |ns: u64| format!("{:.6}", tb.since_first(ns));
    let ts = |ns: u64| {
        tb.since_scenario(ns)
            .map_or_else(String::new, |s| format!("{s:.6}"))
    };
    let roads = catalogue_names(log);
    let road_name = |i: u32| {
        roads
            .as_ref()
            .and_then(|r| r.get(usize::try_from(i).ok()?))
            .map_or_else(String::new, |n| q(n))
    };
    let classes = class_names(log);
    let class_name = |i: u32| classes.get(&i).map_or_else(String::new, |n| q(n));
    let mut out = Vec::new();

    let (mut w, p) = open(dir, "cycles.csv")?;
    writeln!(w, "{CYCLES_HEADER}")?;
    for c in &log.cycles {
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            t(c.stamp_ns),
            ts(c.stamp_ns),
            c.stamp_ns,
            c.seq,
            c.wakeup_latency_ns,
            c.compute_ns,
            c.deadline_misses,
            f(c.omega),
            f(c.v),
            c.v_valid,
            f(c.torque),
            f(c.demand),
            f(c.torque_cmd),
            f(c.internal),
            f(c.mu_hat),
            idx(c.road_class),
            class_name(c.road_class),
            c.used_arte,
            c.road_taken,
            c.roads_taken,
            c.safe_state,
            c.faults.crc,
            c.faults.counter_repeated,
            c.faults.counter_skipped,
            c.faults.length,
            c.faults.unknown_id,
            c.faults.timeout,
            f(c.odometer),
            f(c.torque_cap),
            idx(c.belief_road),
            road_name(c.belief_road),
            f(c.belief_prob)
        )?;
    }
    w.flush()?;
    out.push(p);

    let (mut w, p) = open(dir, "estimates.csv")?;
    writeln!(w, "{ESTIMATES_HEADER}")?;
    for e in &log.roads {
        let n = (e.n_classes as usize).min(e.probabilities.len());
        let probs: Vec<String> = e.probabilities[..n]
            .iter()
            .map(|p| format!("{p}"))
            .collect();
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            t(e.stamp_ns),
            ts(e.stamp_ns),
            e.stamp_ns,
            e.seq,
            t(e.frame_t0_ns),
            t(e.frame_t1_ns),
            ts(e.frame_t0_ns),
            ts(e.frame_t1_ns),
            e.frame_t0_ns,
            e.frame_t1_ns,
            idx(e.class_index),
            q(e.class_name().unwrap_or("")),
            f(e.confidence),
            f(e.lambda_opt),
            f(e.mu_peak),
            f(e.alpha),
            e.n_classes,
            probs.join(" "),
            f(e.x_from),
            f(e.x_to)
        )?;
    }
    w.flush()?;
    out.push(p);

    let (mut w, p) = open(dir, "truth.csv")?;
    writeln!(w, "{TRUTH_HEADER}")?;
    for g in &log.truth {
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{},{}",
            t(g.stamp_ns),
            ts(g.stamp_ns),
            g.stamp_ns,
            g.seq,
            idx(g.road_index),
            q(g.road_name().unwrap_or("")),
            f(g.v),
            f(g.omega),
            f(g.lambda),
            f(g.torque),
            f(g.x),
            idx(g.mic_road_index),
            q(g.mic_road_name().unwrap_or(""))
        )?;
    }
    w.flush()?;
    out.push(p);

    let (mut w, p) = open(dir, "can.csv")?;
    writeln!(w, "{CAN_HEADER}")?;
    let protocol = log
        .protocol()
        .unwrap_or_else(|_| grip_io::can::protocol::Protocol::builtin().clone());
    for c in &log.can {
        let data: Vec<String> = c.payload().iter().map(|b| format!("{b:02X}")).collect();
        writeln!(
            w,
            "{},{},{},0x{:03X},{},{},{},{},{},{}",
            t(c.stamp_ns),
            ts(c.stamp_ns),
            c.stamp_ns,
            c.id,
            protocol.spec_for_id(c.id).map_or("", |m| m.name),
            if c.direction == can_dir::TX {
                "tx"
            } else {
                "rx"
            },
            c.bus,
            c.dlc,
            c.flags,
            data.join(" ")
        )?;
    }
    w.flush()?;
    out.push(p);
    Ok(out)
}

/// A small front-mic drive in memory, for the tests of the CSV export, the
/// road timeline and the plots.
#[cfg(test)]
pub(crate) mod test_log {
    use grip_drive::DriveLog;
    use grip_msgs::{CanFrame, CycleRecord, GroundTruth, NO_CLASS, RoadEstimate, name_to_bytes};

    pub const MS: u64 = 1_000_000;
    /// The first message.
    pub const T0: u64 = 10_000 * MS;
    /// The scenario start (the last sample of the pre-roll).
    pub const START: u64 = T0 + 1290 * MS;
    /// The microphone's lead, m.
    pub const LEAD: f64 = 2.0;
    /// Wheel radius, m.
    pub const R: f64 = 0.3;
    /// The attached catalogue's order (what `belief_road` and the truth's
    /// indices count in).
    pub const CATALOGUE: [&str; 3] = ["asphalt", "gravel", "snow"];
    /// ARTE's class list (what `class_index` and `road_class` count in):
    /// not the catalogue's order.
    pub const CLASSES: [&str; 2] = ["asphalt", "snow"];
    /// Publication time of the one wrong estimate (asphalt while the
    /// microphone hears snow).
    pub const WRONG_AT: u64 = T0 + 1520 * MS;

    /// Snow on 1 m ≤ x < 4 m, asphalt elsewhere.
    pub fn road_at(x: f64) -> &'static str {
        if (1.0..4.0).contains(&x) {
            "snow"
        } else {
            "asphalt"
        }
    }

    fn catalogue_index(name: &str) -> u32 {
        CATALOGUE.iter().position(|n| *n == name).unwrap() as u32
    }

    /// Ground truth every 10 ms for 3 s: held at x = -LEAD for 0.3 s, the
    /// pre-roll to x = 0 at 2 m/s for 1 s, then the scenario, accelerating
    /// at 1 m/s². The microphone reaches snow at -0.5 s (scenario time),
    /// the wheel at 0.45 s; the microphone leaves it at 0.83 s.
    pub fn truth() -> Vec<GroundTruth> {
        (0..=300u64)
            .map(|k| {
                let t = T0 + k * 10 * MS;
                let (x, v) = if k < 30 {
                    (-LEAD, 2.0)
                } else if k <= 129 {
                    (-LEAD + 0.02 * (k - 29) as f64, 2.0)
                } else {
                    let s = (k - 129) as f64 * 0.01;
                    (2.0 * s + 0.5 * s * s, 2.0 + s)
                };
                let (wheel, mic) = (road_at(x), road_at(x + LEAD));
                GroundTruth {
                    seq: k,
                    stamp_ns: t,
                    road_index: catalogue_index(wheel),
                    mic_road_index: catalogue_index(mic),
                    road_name: name_to_bytes(wheel),
                    mic_road_name: name_to_bytes(mic),
                    v,
                    omega: v * 1.02 / R,
                    lambda: 0.02,
                    torque: 200.0,
                    x,
                }
            })
            .collect()
    }

    /// The road at the microphone at `t_ns`.
    pub fn mic_road(truth: &[GroundTruth], t_ns: u64) -> String {
        grip_drive::summary::truth_at(truth, t_ns)
            .and_then(|g| g.mic_road_name())
            .unwrap()
            .to_owned()
    }

    /// A drive: ground truth, a cycle every ms, an estimate of each 100 ms
    /// audio frame 20 ms after its end (right about the road at the
    /// microphone at the frame's middle, but one: asphalt, published at
    /// [`WRONG_AT`], while the microphone is on snow), CAN frames, a
    /// `grip.run`, a `grip.clock` and the attached roads.toml.
    pub fn drive() -> DriveLog {
        let truth = truth();
        let roads: Vec<RoadEstimate> = (0..28u64)
            .map(|j| {
                let t0 = T0 + j * 100 * MS;
                let t1 = t0 + 100 * MS;
                let stamp = t1 + 20 * MS;
                let mut name = mic_road(&truth, t0 / 2 + t1 / 2);
                if stamp == WRONG_AT {
                    assert_eq!(name, "snow");
                    name = "asphalt".into();
                }
                let class = CLASSES.iter().position(|n| *n == name).unwrap() as u32;
                RoadEstimate {
                    seq: j,
                    stamp_ns: stamp,
                    frame_t0_ns: t0,
                    frame_t1_ns: t1,
                    class_index: class,
                    n_classes: 2,
                    class_name: name_to_bytes(&name),
                    confidence: 0.9,
                    ..RoadEstimate::zeroed()
                }
            })
            .collect();
        let cycles: Vec<CycleRecord> = (0..3000u64)
            .map(|k| {
                let stamp = T0 + k * MS;
                let taken = roads.iter().position(|e| e.stamp_ns == stamp);
                let latest = roads.iter().rev().find(|e| e.stamp_ns <= stamp);
                CycleRecord {
                    seq: k,
                    stamp_ns: stamp,
                    omega: 7.0,
                    v: 2.0,
                    v_valid: 1,
                    torque: 200.0,
                    demand: 300.0,
                    torque_cmd: 250.0,
                    road_class: latest.map_or(NO_CLASS, |e| e.class_index),
                    used_arte: u8::from(latest.is_some()),
                    belief_road: latest
                        .map_or(NO_CLASS, |e| catalogue_index(e.class_name().unwrap())),
                    belief_prob: 0.9,
                    road_taken: taken.map_or(0, |j| 1 + j as u32),
                    roads_taken: u8::from(taken.is_some()),
                    ..CycleRecord::zeroed()
                }
            })
            .collect();
        let can = (0..10u64)
            .map(|k| CanFrame {
                stamp_ns: T0 + 5 * MS + k * 100 * MS,
                bus: 0,
                ..CanFrame::new(0x123, &[1, 2, 3])
            })
            .collect();
        let mut log = DriveLog {
            path: "test/front-mic-drive.mcap".into(),
            truth,
            roads,
            cycles,
            can,
            ..DriveLog::default()
        };
        for (k, v) in [
            ("controller", "mtte"),
            ("arte", "on"),
            ("scenario", "paper"),
            ("seed", "7"),
            ("vehicle", "/somewhere/config/vehicles/front-mic.toml"),
            ("git_revision", "0123456789abcdef0123456789abcdef01234567"),
            ("version", "0.1.0"),
        ] {
            log.run.insert(k.into(), v.into());
        }
        log.metadata.insert("grip.run".into(), log.run.clone());
        // the first message, T0, at 2026-12-05 00:33:51 UTC
        let clock = [
            ("monotonic_ns", T0.to_string()),
            ("realtime_ns", "1796430831000000000".to_owned()),
        ];
        log.metadata.insert(
            "grip.clock".into(),
            clock.into_iter().map(|(k, v)| (k.into(), v)).collect(),
        );
        let roads_toml: String = CATALOGUE
            .iter()
            .map(|n| format!("[[road]]\nname = \"{n}\"\nmodel = \"burckhardt\"\nc1 = 1.0\nc2 = 20.0\nc3 = 0.5\n\n"))
            .collect();
        log.attachments
            .insert("roads.toml".into(), roads_toml.into_bytes());
        log
    }

    /// [`drive`] as the car records it: no ground truth.
    pub fn drive_without_truth() -> DriveLog {
        DriveLog {
            truth: Vec::new(),
            ..drive()
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::test_log::{self, MS, START, T0};
    use grip_io::mcaplog::McapRecord;
    use grip_msgs::{CanFrame, CycleRecord, GroundTruth, RoadEstimate};

    /// The CSV `name` of `dir`: header and rows, each a map column → value.
    fn read(dir: &std::path::Path, name: &str) -> (Vec<String>, Vec<BTreeMap<String, String>>) {
        let mut r = csv::Reader::from_path(dir.join(name)).unwrap();
        let header: Vec<String> = r.headers().unwrap().iter().map(str::to_owned).collect();
        let rows = r
            .records()
            .map(|rec| {
                header
                    .iter()
                    .cloned()
                    .zip(rec.unwrap().iter().map(str::to_owned))
                    .collect()
            })
            .collect();
        (header, rows)
    }

    /// The keys of a record's JSON encoding (the MCAP message), nested
    /// objects flattened as `outer_inner`.
    fn json_fields<T: McapRecord>(rec: &T) -> Vec<String> {
        fn walk(prefix: &str, v: &serde_json::Value, out: &mut Vec<String>) {
            match v.as_object() {
                Some(o) => {
                    for (k, v) in o {
                        let key = if prefix.is_empty() {
                            k.clone()
                        } else {
                            format!("{prefix}_{k}")
                        };
                        walk(&key, v, out);
                    }
                }
                None => out.push(prefix.to_owned()),
            }
        }
        let mut buf = Vec::new();
        rec.write_json(&mut buf);
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        let mut out = Vec::new();
        walk("", &v, &mut out);
        out
    }

    fn field(rows: &[BTreeMap<String, String>], key: &str, stamp: u64, col: &str) -> String {
        rows.iter()
            .find(|r| r[key] == stamp.to_string())
            .unwrap_or_else(|| panic!("no row with {key} {stamp}"))[col]
            .clone()
    }

    /// Every field of every logged record has its column: the header of
    /// each CSV is checked against the record's JSON encoding, so a field
    /// added to a record later cannot be left out unnoticed.
    #[test]
    fn every_field_of_every_record_has_a_column() {
        let dir = tempfile::tempdir().unwrap();
        super::write_csv(&test_log::drive(), dir.path()).unwrap();
        let checks = [
            ("cycles.csv", json_fields(&CycleRecord::zeroed())),
            ("estimates.csv", json_fields(&RoadEstimate::zeroed())),
            ("truth.csv", json_fields(&GroundTruth::zeroed())),
            ("can.csv", json_fields(&CanFrame::default())),
        ];
        for (file, fields) in checks {
            let (header, _) = read(dir.path(), file);
            assert!(fields.len() > 5, "{file}: {fields:?}");
            let missing: Vec<&String> = fields.iter().filter(|f| !header.contains(f)).collect();
            assert!(
                missing.is_empty(),
                "{file} has no column for {missing:?} (header {header:?})"
            );
        }
        assert!(json_fields(&CycleRecord::zeroed()).contains(&"road_taken".to_owned()));
    }

    /// road_taken is written, and the index columns have their names:
    /// `road_class` in ARTE's class list (named as its estimates name it),
    /// `belief_road` in the attached roads.toml's catalogue (the two
    /// orders differ here: snow is class 1, catalogue road 2).
    #[test]
    fn cycles_csv_names_the_road_indices_and_has_road_taken() {
        let log = test_log::drive();
        let dir = tempfile::tempdir().unwrap();
        super::write_csv(&log, dir.path()).unwrap();
        let (_, rows) = read(dir.path(), "cycles.csv");
        assert_eq!(rows.len(), log.cycles.len());
        let first_estimate = log.roads[0].stamp_ns;
        let row = |stamp: u64| {
            rows.iter()
                .find(|r| r["stamp_ns"] == stamp.to_string())
                .unwrap()
        };
        // before any estimate: no class, no names
        let r = row(T0);
        assert_eq!(
            (r["road_class"].as_str(), r["road_class_name"].as_str()),
            ("", "")
        );
        assert_eq!(
            (
                r["belief_road"].as_str(),
                r["belief_road_name"].as_str(),
                r["road_taken"].as_str()
            ),
            ("", "", "0")
        );
        // the cycle that took the first estimate (seq 0)
        assert_eq!(row(first_estimate)["road_taken"], "1");
        assert_eq!(row(first_estimate + MS)["road_taken"], "0");
        // on snow (from the estimate published at 0.92 s)
        let r = row(T0 + 1000 * MS);
        assert_eq!(r["road_class"], "1");
        assert_eq!(r["road_class_name"], "snow");
        assert_eq!(r["belief_road"], "2");
        assert_eq!(r["belief_road_name"], "snow");
        // without an attached roads.toml the catalogue's names are unknown
        let mut bare = log.clone();
        bare.attachments.clear();
        super::write_csv(&bare, dir.path()).unwrap();
        let (_, rows) = read(dir.path(), "cycles.csv");
        let r = rows
            .iter()
            .find(|r| r["stamp_ns"] == (T0 + 1000 * MS).to_string())
            .unwrap();
        assert_eq!(
            (r["belief_road"].as_str(), r["belief_road_name"].as_str()),
            ("2", "")
        );
        assert_eq!(r["road_class_name"], "snow");
    }

    /// A "no road" (`NO_CLASS`, u32::MAX) is an empty field in every CSV,
    /// never `4294967295`: the ground truth's road and microphone road (a
    /// plant with no road under the wheel, e.g. before a scenario's first
    /// segment), a cycle's class and believed road, an estimate's class.
    #[test]
    fn no_road_is_an_empty_field_not_u32_max() {
        let mut log = test_log::drive();
        log.truth[0].road_index = grip_msgs::NO_CLASS;
        log.truth[0].road_name = [0; grip_msgs::NAME_LEN];
        log.truth[0].mic_road_index = grip_msgs::NO_CLASS;
        log.truth[0].mic_road_name = [0; grip_msgs::NAME_LEN];
        log.roads[0].class_index = grip_msgs::NO_CLASS;
        let dir = tempfile::tempdir().unwrap();
        super::write_csv(&log, dir.path()).unwrap();
        for file in ["cycles.csv", "estimates.csv", "truth.csv", "can.csv"] {
            let text = std::fs::read_to_string(dir.path().join(file)).unwrap();
            assert!(!text.contains("4294967295"), "{file}:\n{text}");
        }
        let (_, truth) = read(dir.path(), "truth.csv");
        let r = &truth[0];
        assert_eq!(
            (
                r["road_index"].as_str(),
                r["road_name"].as_str(),
                r["mic_road_index"].as_str(),
                r["mic_road_name"].as_str()
            ),
            ("", "", "", "")
        );
        // a road is its catalogue index
        assert_eq!(truth[1]["road_index"], "0");
        assert_eq!(truth[1]["road_name"], "asphalt");
        let (_, est) = read(dir.path(), "estimates.csv");
        assert_eq!(est[0]["class_index"], "");
        // the first cycles come before any estimate: no class, no belief
        let (_, cycles) = read(dir.path(), "cycles.csv");
        assert_eq!(
            (
                cycles[0]["road_class"].as_str(),
                cycles[0]["belief_road"].as_str()
            ),
            ("", "")
        );
    }

    /// Every CSV has `t_s` (from the first message) and `t_scenario_s` (from
    /// the scenario start, the summary's clock: a road change the summary
    /// reports at t is at t_scenario_s = t); without ground truth the
    /// scenario start is unknown and `t_scenario_s` is empty.
    #[test]
    fn every_csv_has_the_scenario_clock_of_the_summary() {
        let log = test_log::drive();
        let dir = tempfile::tempdir().unwrap();
        super::write_csv(&log, dir.path()).unwrap();
        for file in ["cycles.csv", "estimates.csv", "truth.csv", "can.csv"] {
            let (header, rows) = read(dir.path(), file);
            assert_eq!(&header[..2], ["t_s", "t_scenario_s"], "{file}");
            for r in &rows {
                let (t, ts) = (
                    r["t_s"].parse::<f64>().unwrap(),
                    r["t_scenario_s"].parse::<f64>().unwrap(),
                );
                assert!((t - ts - 1.29).abs() < 1e-6, "{file}: {r:?}");
            }
        }
        let (_, truth) = read(dir.path(), "truth.csv");
        assert_eq!(field(&truth, "stamp_ns", START, "t_scenario_s"), "0.000000");
        assert_eq!(field(&truth, "stamp_ns", START, "t_s"), "1.290000");
        assert_eq!(field(&truth, "stamp_ns", T0, "t_scenario_s"), "-1.290000");
        let (_, est) = read(dir.path(), "estimates.csv");
        let e = &log.roads[15];
        assert_eq!(
            field(&est, "seq", e.seq, "frame_t0_scenario_s"),
            format!("{:.6}", (e.frame_t0_ns - START) as f64 * 1e-9)
        );

        // the summary's clock: its change of the road at the microphone
        // (snow -> asphalt, 0.83 s into the scenario) is at that time here
        let s = grip_drive::summary::summarize(
            &log,
            &grip_physics::VehicleParams::default(),
            "test",
            None,
        );
        let change = s
            .arte
            .changes
            .iter()
            .find(|c| c.from == "snow" && c.to == "asphalt")
            .expect("the summary sees the microphone leave the snow");
        let row = truth
            .iter()
            .zip(&truth[1..])
            .find(|(a, b)| a["mic_road_name"] == "snow" && b["mic_road_name"] == "asphalt")
            .unwrap()
            .1;
        let t: f64 = row["t_scenario_s"].parse().unwrap();
        assert!(
            (t - change.t).abs() < 1e-6,
            "CSV {t} s, summary {} s",
            change.t
        );

        // no ground truth: no scenario start, the column is empty
        super::write_csv(&test_log::drive_without_truth(), dir.path()).unwrap();
        for file in ["cycles.csv", "estimates.csv", "can.csv"] {
            let (header, rows) = read(dir.path(), file);
            assert_eq!(&header[..2], ["t_s", "t_scenario_s"], "{file}");
            assert!(rows.iter().all(|r| r["t_scenario_s"].is_empty()), "{file}");
            assert!(rows.iter().all(|r| !r["t_s"].is_empty()), "{file}");
        }
    }
}
