//! The summary of a drive, computed from its MCAP log alone (so `grip drive`
//! and `grip inspect` print the same thing for the same file):
//!
//! - run description (`grip.run` metadata), the model arte ran
//!   ([`model_of`]: the attached `arte-svc.toml`'s `model`), whether the
//!   log is a replay's (`grip replay --out`: [`replay_of`]), and what the
//!   reader found;
//! - messages per topic, gaps by sequence number in the log, and the
//!   recorder's own counters (`grip.recorder`: received, queue drops);
//! - loop timing from the `CycleRecord`s: wake-up latency and compute time
//!   (p50/p99/max), deadline misses, safe-state cycles and entries, during
//!   the scenario and over the whole log (start-up and stop included);
//! - the control loop's health over the scenario window ([`ControlHealth`]):
//!   in control at its end, or control lost and not regained (in the safe
//!   state, or without a cycle in control, for the last
//!   [`CONTROL_LOST_MIN_S`] or more of the window, or for all of it), with
//!   when, for how long and what the log says of why; `grip drive` fails
//!   such a drive;
//! - the scenario window (from the plant's start for the scenario's
//!   duration) and how much of it the log covers ([`WindowStatus`]);
//! - the metrics (`grip_tcs::metrics`) via `grip_tcs::MetricsAccumulator` (the
//!   code the offline simulator uses) on the plant's ground truth over the
//!   scenario window (none when the log has no scenario window);
//! - CAN: frames per message and direction, E2E rejections, the loop's
//!   fault counters;
//! - the inverter ([`inverter()`]): from its `MotorStatus` frames on the
//!   loop's CAN log, the episodes of `Fault`, `Derating`, `CmdTimeout` and
//!   not `Ready` (during the scenario and over the whole log), the
//!   FaultCodes it sent, and whether the loop was in its safe state during
//!   each fault;
//! - ARTE: accuracy against the ground truth during the scenario (and over
//!   the whole log, labelled so), per-road recall, detection delay at each
//!   change of the road at the microphone (from the first truth sample, so
//!   a front-mic car's pre-roll counts), how often the controller used the
//!   estimate, and how much of the scenario ran below or above the speeds
//!   the model was trained at ([`speeds`]: a note; extrapolation there);
//! - what the loop itself measured ([`measured()`], for every log, with
//!   ground truth or without): slip from the measured ω and V, spin
//!   events, acceleration from V, command against demand, per believed
//!   road; never ground truth, and labelled so.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use grip_msgs::{CycleRecord, E2eFaults, GroundTruth, RoadEstimate, can_dir, can_flags, topics};
use grip_physics::{RoadCatalogue, VehicleParams};
use grip_tcs::{Metrics, MetricsAccumulator, Sample};

use crate::log::DriveLog;
use crate::roads::LogRoads;

pub mod inverter;
pub mod measured;
pub mod speeds;
pub use inverter::{Inverter, inverter};
pub use measured::{Measured, measured};

/// The plant's period, ns: a truth sample stands for this long (the last
/// one of the stream too).
const TRUTH_PERIOD_NS: u64 = 1_000_000;

/// A window this much shorter than the scenario still covers it (the
/// plant's stamps jitter by a fraction of a period), s.
const COVER_TOL_S: f64 = 0.005;

/// A truth sample holds for at most this many plant periods: a longer
/// hole in the stream is time the metrics do not cover (the measured
/// section's rule for cycle records, `measured::MAX_DT_PERIODS`).
const TRUTH_MAX_HOLD_PERIODS: u64 = 5;

/// Consecutive truth samples further apart than this leave a gap in the
/// ground truth, s (five plant periods: the longest hold).
const GAP_S: f64 = TRUTH_MAX_HOLD_PERIODS as f64 * TRUTH_PERIOD_NS as f64 * 1e-9;

/// Gaps in the ground truth of a complete log up to this much in all are
/// plant-sim's skipped periods (scheduling pauses), not lost data, s.
const SMALL_GAPS_S: f64 = 0.05;

/// A drive whose scenario window ends with this long or longer without a
/// cycle of the control loop in control (in its safe state, or no cycle
/// record), s, lost control and did not regain it ([`ControlHealth`]).
/// Brief safe-state entries that recover (a loaded machine's stalls: 10-15
/// of a few ms in a drive; a bus outage the fault matrix injects) are far
/// shorter; 1 s is also longer than tcs-loop's recovery (`recover_ms`) after
/// any input timeout, so an entry just before the scenario's end cannot
/// reach it.
pub const CONTROL_LOST_MIN_S: f64 = 1.0;

/// The control loop (tcs-loop's cycle records) over the scenario window:
/// whether it was in control at the window's end. A cycle is in control
/// when it is not in the safe state; time after the last cycle in control
/// counts as out of control whether the records show the safe state or
/// stop.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ControlHealth {
    /// Cycle records in the window.
    pub cycles: u64,
    /// The window's length, s.
    pub window_s: f64,
    /// Entries into the safe state (active → safe) in the window.
    pub entries: u64,
    /// Safe-state runs in the window that ended in control again.
    pub recovered: u64,
    /// The longest of those: (length s, start s from the scenario start).
    pub longest_recovered: Option<(f64, f64)>,
    /// No cycle of the window in control (or no cycle record in it).
    pub never_in_control: bool,
    /// Out of control at the window's end: from `since_s` (s from the
    /// scenario start: the first cycle after the last one in control, or
    /// the window's start) to the window's end, `for_s` s. None: the last
    /// cycle of the window was in control.
    pub end_out: Option<(f64, f64)>,
    /// Cycle records after the last one in control (all in the safe
    /// state), and whether the records reach the window's end (within
    /// [`CONTROL_LOST_MIN_S`]) or stop before.
    pub end_records: (u64, bool),
    /// What the log says of why, when out of control at the end (the
    /// loop's fault counters over that time, the CAN frames tcs-loop
    /// received in it); empty when it says nothing.
    pub reason: String,
    /// The window ends before the scenario does (the log's ground truth
    /// stops: a drive cut short, a service that died): (window, scenario)
    /// lengths, s. The statement then is of the window's end, not the
    /// scenario's, and says so.
    pub cut_short: Option<(f64, f64)>,
}

impl ControlHealth {
    /// Control lost and not regained: out of control for the last
    /// [`CONTROL_LOST_MIN_S`] or more of the window, or never in control
    /// in it.
    pub fn lost(&self) -> bool {
        self.never_in_control
            || self
                .end_out
                .is_some_and(|(_, d)| d >= CONTROL_LOST_MIN_S - 1e-9)
    }

    /// The statement the summary prints (one line, no indent).
    pub fn line(&self) -> String {
        let why = if self.reason.is_empty() {
            String::new()
        } else {
            format!("; the log says: {}", self.reason)
        };
        if self.cycles == 0 {
            return format!(
                "CONTROL NOT SHOWN: no cycle record of the loop in the scenario window (0.000-{:.3} s): no command was logged during the scenario{why}",
                self.window_s
            );
        }
        if self.never_in_control {
            return format!(
                "CONTROL NEVER HELD: the loop was in its safe state for the whole scenario window (0.000-{:.3} s, {} cycles){why}",
                self.window_s, self.cycles
            );
        }
        let recovered = match (self.entries, self.longest_recovered) {
            (0, _) => "no safe-state entry during it".to_owned(),
            (n, Some((d, at))) => format!(
                "{n} safe-state {} during it, {} recovered (longest {d:.3} s, from {at:.3} s)",
                if n == 1 { "entry" } else { "entries" },
                if self.recovered >= n {
                    "all".to_owned()
                } else {
                    self.recovered.to_string()
                }
            ),
            (n, None) => format!(
                "{n} safe-state {} during it",
                if n == 1 { "entry" } else { "entries" }
            ),
        };
        let state = if self.end_records.1 {
            "in the safe state".to_owned()
        } else {
            format!(
                "without a cycle in control ({} safe-state cycle records, then none)",
                self.end_records.0
            )
        };
        // a window cut short ends where the log does, not the scenario
        let (end, of) = match self.cut_short {
            Some((_, d)) => (
                format!("the end of the log's window (of a {d:.3} s scenario)"),
                "the log's window",
            ),
            None => ("the scenario's end".to_owned(), "the scenario"),
        };
        match self.end_out {
            Some((since, d)) if self.lost() => format!(
                "CONTROL LOST AND NOT REGAINED: {state} from {since:.3} s to {end} at {:.3} s ({d:.3} s; {CONTROL_LOST_MIN_S} s or more at the end fails a drive); {recovered}{why}",
                self.window_s
            ),
            Some((since, d)) => format!(
                "{state} for the last {d:.3} s of {of} (from {since:.3} s; under the {CONTROL_LOST_MIN_S} s that fails a drive); {recovered}{why}"
            ),
            None => match self.cut_short {
                Some((w, d)) => format!(
                    "in control at the end of the log's scenario window, {w:.3} s of the {d:.3} s scenario: the log ends there (a drive cut short, or a service that stopped), and what the loop did after it is not in the log; {recovered}"
                ),
                None => format!("in control at the end of the scenario; {recovered}"),
            },
        }
    }
}

/// p50 / p99 / max of a set of values (ns), and the count.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Percentiles {
    /// Values.
    pub n: usize,
    /// Median.
    pub p50: i64,
    /// 99th percentile.
    pub p99: i64,
    /// 99.9th percentile.
    pub p999: i64,
    /// Maximum.
    pub max: i64,
}

impl Percentiles {
    /// Nearest-rank percentiles of `v` (sorted in place).
    pub fn of(v: &mut [i64]) -> Self {
        if v.is_empty() {
            return Self::default();
        }
        v.sort_unstable();
        let at = |q: f64| v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
        Self {
            n: v.len(),
            p50: at(0.5),
            p99: at(0.99),
            p999: at(0.999),
            max: v[v.len() - 1],
        }
    }
}

/// Per-topic accounting.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TopicLine {
    /// Topic.
    pub topic: String,
    /// Messages in the log.
    pub in_log: u64,
    /// Sequence numbers missing between consecutive messages in the log;
    /// for the CAN log (no sequence number) the recorder's alive-counter gap
    /// count; None when unknown.
    pub seq_gaps: Option<u64>,
    /// Times the sequence went backwards (publisher restarted).
    pub seq_resets: Option<u64>,
    /// The recorder's counters: received, written, queue drops.
    pub recorder: Option<(u64, u64, u64)>,
}

/// A detected (or missed) change of the road at the microphone.
#[derive(Debug, Clone, PartialEq)]
pub struct RoadChange {
    /// Time of the change from the scenario start, s (negative before it:
    /// a microphone ahead of the wheel reaches a road during the pre-roll).
    pub t: f64,
    /// Road before.
    pub from: String,
    /// Road after.
    pub to: String,
    /// Delay until ARTE first published the new road, s (None: not before
    /// the next change or the end).
    pub delay: Option<f64>,
    /// Delay until ARTE first published the new road with a confidence the
    /// loop's gate passes (`[arte] min_confidence` of the attached
    /// `controllers.toml`, [`ArteEval::min_confidence`]), s (None: not
    /// before the next change or the end).
    pub gated_delay: Option<f64>,
}

/// Width of the speed bands of [`ArteEval::per_speed_band`], km/h.
pub const SPEED_BAND_KMH: f64 = 5.0;

/// ARTE against the ground truth: an estimate is judged against the road
/// at the microphone at its frame's midpoint. `judged`, `correct`,
/// `per_road`, `confusion` and `per_speed_band` count the estimates whose
/// midpoint lies in the scenario window; `log_judged` and `log_correct`
/// every estimate whose midpoint has ground truth (hold, pre-roll and stop
/// included; none after the truth stream ends).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ArteEval {
    /// Estimates in the log.
    pub estimates: u64,
    /// Estimates with a class whose frame's midpoint lies in the scenario
    /// window (and has ground truth).
    pub judged: u64,
    /// Of those, equal to the true road.
    pub correct: u64,
    /// Estimates with a class and ground truth at their frame's midpoint,
    /// anywhere in the log.
    pub log_judged: u64,
    /// Of those, equal to the true road.
    pub log_correct: u64,
    /// Per true road: (judged, correct), in the scenario window.
    pub per_road: BTreeMap<String, (u64, u64)>,
    /// Judged estimates per (true road, estimated road): the confusion
    /// counts behind `per_road` (fleet tables add them up across drives).
    pub confusion: BTreeMap<(String, String), u64>,
    /// Per speed band of [`SPEED_BAND_KMH`] (key: band index, speed
    /// `|v|` of the truth at the frame's midpoint): (judged, correct).
    pub per_speed_band: BTreeMap<u32, (u64, u64)>,
    /// Changes of the road at the microphone from the first truth sample
    /// to the scenario window's end (before the start: the pre-roll of a
    /// microphone ahead of the wheel).
    pub changes: Vec<RoadChange>,
    /// Cycles (scenario window, out of safe state) the controller used the
    /// estimate; without a scenario window, those of the measured
    /// section's window (the time the driver demanded torque,
    /// `used_in_demand_window`).
    pub used_cycles: u64,
    /// Cycles in the scenario window out of safe state (without one: in
    /// the driver-demand window).
    pub active_cycles: u64,
    /// Of `active_cycles`, those whose command road knowledge's torque cap
    /// held below the driver's demand ([`cap_binding`]): where ARTE's
    /// knowledge acted on the torque, whether or not the cycle's
    /// `used_arte` (the road belief usable: a decision within
    /// `max_age_s`, its probability at or above `min_confidence`) was set.
    pub capped_cycles: u64,
    /// `used_cycles` and `active_cycles` count the driver-demand window of
    /// [`Measured`] (the log has no scenario window: a car's log).
    pub used_in_demand_window: bool,
    /// The loop's confidence gate the delays' `gated_delay` uses, and
    /// whether the log gave it (its `controllers.toml`, or a replay's
    /// record; else the default 0.6): [`gate_of`].
    pub min_confidence: (f64, bool),
    /// Where that gate came from ([`gate_of`]).
    pub gate_from: GateFrom,
}

impl ArteEval {
    /// correct / judged in the scenario window (NaN with nothing judged).
    pub fn accuracy(&self) -> f64 {
        if self.judged == 0 {
            f64::NAN
        } else {
            self.correct as f64 / self.judged as f64
        }
    }

    /// log_correct / log_judged: over the whole log (NaN with nothing
    /// judged).
    pub fn accuracy_whole_log(&self) -> f64 {
        if self.log_judged == 0 {
            f64::NAN
        } else {
            self.log_correct as f64 / self.log_judged as f64
        }
    }
}

/// CAN accounting.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CanSummary {
    /// (message name or id, CAN id, direction) → frames.
    pub frames: BTreeMap<(String, u32, &'static str), u64>,
    /// The protocol the frames are named by: the log's DBC, or the
    /// built-in one.
    pub bus: String,
    /// Frames flagged `E2E_REJECTED` by the receiver.
    pub rejected: u64,
    /// The loop's E2E fault counters at its last record (whole log).
    pub faults: E2eFaults,
    /// Faults counted during the scenario window (last minus first record in it).
    pub faults_in_window: Option<E2eFaults>,
    /// The signals grip controls with that the log's protocol cannot carry
    /// for the drive's vehicle, and how often each sat at its limit
    /// ([`short_signals`]; empty for a protocol that carries them all).
    pub short: Vec<ShortSignal>,
}

/// A signal grip controls with whose largest value is under what grip
/// needs for the vehicle (`grip_io::can::protocol::ControlSignal`, as
/// tcs-loop warns of it at start), with the received frames that held it
/// at that limit: grip read any larger value as the limit, so the slip
/// and control figures of such a drive mean little.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ShortSignal {
    /// tcs-loop's start-up warning, word for word (naming the DBC, the
    /// message and signal, what it carries and what grip needs).
    pub warning: String,
    /// `Message.Signal`.
    pub name: String,
    /// Frames of its message received (not refused by the E2E check) in
    /// the scenario window, else over the whole log.
    pub frames: u64,
    /// Of those, frames holding the signal at its limit.
    pub at_limit: u64,
    /// Whether the counts are the scenario window's.
    pub in_window: bool,
}

impl ShortSignal {
    /// The report's line.
    pub fn line(&self) -> String {
        let when = if self.in_window {
            "during the scenario"
        } else {
            "in the log"
        };
        let seen = if self.at_limit > 0 {
            format!(
                "it sat at that limit in {} of the {} frames received {when}: grip read a larger value as the limit there, so the slip and control figures of this drive mean little",
                self.at_limit, self.frames
            )
        } else {
            format!(
                "it never reached that limit in the {} frames received {when}",
                self.frames
            )
        };
        format!(
            "the bus cannot carry what grip needs: {}; {seen}",
            self.warning
        )
    }
}

/// The signals grip controls with that `protocol` (named `dbc`) cannot
/// carry for `vehicle`, with the frames of `log` received in `window`
/// (else the whole log) that held each at its limit.
pub fn short_signals(
    log: &DriveLog,
    protocol: &grip_io::can::protocol::Protocol,
    dbc: &str,
    vehicle: &VehicleParams,
    window: Option<(u64, u64)>,
) -> Vec<ShortSignal> {
    let warnings = protocol.envelope_warnings(dbc, vehicle);
    protocol
        .control_signals(vehicle)
        .iter()
        .filter(|c| c.is_short())
        .map(|c| {
            let name = format!("{}.{}", c.message.name, c.signal.name);
            let mut out = ShortSignal {
                // the warning that names it as short (its first)
                warning: warnings
                    .iter()
                    .find(|w| w.contains(&format!("{name} carries at most")))
                    .cloned()
                    .unwrap_or_else(|| format!("{dbc}: {name} cannot carry what grip needs")),
                name,
                frames: 0,
                at_limit: 0,
                in_window: window.is_some(),
            };
            for f in log.can.iter().filter(|f| {
                f.direction != can_dir::TX
                    && f.id == c.message.id
                    && f.flags & can_flags::E2E_REJECTED == 0
                    && window.is_none_or(|(a, b)| (a..=b).contains(&f.stamp_ns))
            }) {
                out.frames += 1;
                if c.at_limit(&f.data) {
                    out.at_limit += 1;
                }
            }
            out
        })
        .collect()
}

/// Loop timing of the cycles stamped in the scenario window.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WindowTiming {
    /// Cycle records in the window.
    pub cycles: u64,
    /// Wake-up latency, ns.
    pub wakeup: Percentiles,
    /// Compute time (wake-up to command sent), ns.
    pub compute: Percentiles,
    /// Deadline misses counted by the window's cycles (the last one's
    /// count minus the count of the record before the first).
    pub deadline_misses: u64,
    /// Entries into the safe state (active → safe) at the window's cycles.
    pub safe_entries: u64,
}

/// Loop timing. The fields without `in_scenario` cover the whole log:
/// start-up before the scenario and the stop after it included.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Timing {
    /// Cycle records.
    pub cycles: u64,
    /// Wake-up latency, ns (whole log).
    pub wakeup: Percentiles,
    /// Compute time (wake-up to command sent), ns (whole log).
    pub compute: Percentiles,
    /// Deadline misses over the log (last record minus first).
    pub deadline_misses: u64,
    /// Cycles in the safe state (whole log).
    pub safe_cycles: u64,
    /// Entries into the safe state (active → safe) over the log; a log
    /// that starts in the safe state does not count its start. A `grip
    /// drive` log's stop is one: plant-sim stops sending, and the loop's
    /// input timeout puts it in the safe state after the scenario.
    pub safe_entries: u64,
    /// Cycle period from the stamps (median), ns.
    pub period_ns: i64,
    /// Wake-up latencies, ns (for the histogram; whole log).
    pub wakeup_ns: Vec<i64>,
    /// The same figures for the cycles in the scenario window (None: no
    /// scenario window).
    pub in_scenario: Option<WindowTiming>,
}

/// How much of the scenario the log's scenario window covers.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub enum WindowStatus {
    /// Fewer than two ground-truth samples (a log from the car): no window.
    #[default]
    NoTruth,
    /// The log is incomplete and its ground truth ends before the plant
    /// started the scenario (held, or pre-rolling): no window.
    EndsBeforeStart,
    /// A complete log whose plant never started the scenario: no window.
    NeverStarted,
    /// The window covers the scenario's duration.
    Complete,
    /// The ground truth ends before the scenario's end, or has gaps in the
    /// window: it covers `covered_s` of `duration_s`.
    Partial {
        /// Seconds covered.
        covered_s: f64,
        /// The scenario's duration, s.
        duration_s: f64,
    },
    /// The scenario's duration is unknown (no `grip.run`
    /// `scenario_duration_s`, no attached scenario file): the window runs
    /// to the end of the ground truth.
    DurationUnknown,
}

impl WindowStatus {
    /// `no_truth`, `ends_before_start`, `never_started`, `complete`,
    /// `partial` or `duration_unknown` (`grip inspect --json`'s
    /// `scenario_window`).
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::NoTruth => "no_truth",
            Self::EndsBeforeStart => "ends_before_start",
            Self::NeverStarted => "never_started",
            Self::Complete => "complete",
            Self::Partial { .. } => "partial",
            Self::DurationUnknown => "duration_unknown",
        }
    }

    /// Why there is no scenario window (None: there is one).
    pub fn no_window_reason(&self) -> Option<&'static str> {
        match self {
            Self::NoTruth => Some("no ground truth in the log"),
            Self::EndsBeforeStart => Some("the log ends before the scenario start"),
            Self::NeverStarted => Some("the scenario never started"),
            _ => None,
        }
    }
}

/// Everything `grip drive` / `grip inspect` print.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// Log file.
    pub file: String,
    /// `grip.run` entries worth showing.
    pub run: Vec<(String, String)>,
    /// Reader findings (truncation etc.), as lines.
    pub warnings: Vec<String>,
    /// Per topic.
    pub topics: Vec<TopicLine>,
    /// Loop timing.
    pub timing: Timing,
    /// The `grip_tcs::metrics` metrics over the scenario window (None: no
    /// scenario window, see `window_status`). A truth sample holds until
    /// the next one, at most five plant periods: the metrics cover the
    /// window less the rest of each longer hole (`duration`, and the
    /// `covered_s` of a partial window). The command's figures start at
    /// the first cycle in the window with the driver's demand
    /// (`cmd_from_s`).
    pub metrics: Option<Metrics>,
    /// The largest true |λ| over the scenario window and when, s from the
    /// scenario start (None: no window).
    pub max_slip: Option<(f64, f64)>,
    /// Where the command's figures of `metrics` start, s from the scenario
    /// start: the first cycle record in the window whose demand is above
    /// [`measured::DEMAND_MIN_NM`] (None: no such cycle, no command
    /// figures).
    pub cmd_from_s: Option<f64>,
    /// Scenario window, s from the first truth: (start, end).
    pub window: Option<(f64, f64)>,
    /// How much of the scenario the window covers.
    pub window_status: WindowStatus,
    /// The scenario's duration, s (`grip.run` `scenario_duration_s`, else
    /// the attached scenario file; None: unknown).
    pub scenario_duration_s: Option<f64>,
    /// The scenario (`grip.run` `scenario`).
    pub scenario: Option<String>,
    /// SHA-256 of the scenario file the drive ran ([`scenario_attachment`]:
    /// `grip.run` `config.drive/scenario.toml` or
    /// `config.scenarios/NAME.toml`, else of the attachment).
    pub scenario_sha256: Option<String>,
    /// SHA-256 of the vehicle file the summary used, when it came from the
    /// log's attachments.
    pub vehicle_sha256: Option<String>,
    /// The vehicle parameters used.
    pub vehicle_params: VehicleParams,
    /// Where the preview report's road catalogue came from (None: not said,
    /// [`summarize`] without [`summarize_with_roads`]).
    pub roads_from: Option<String>,
    /// Why this summary is not that of a complete drive, one reason each
    /// (log truncated or damaged, recorder not finished, window shorter
    /// than the scenario or none): what `compare` warns about.
    pub incomplete: Vec<String>,
    /// CAN.
    pub can: CanSummary,
    /// ARTE.
    pub arte: ArteEval,
    /// Speed at the window's start and end, km/h.
    pub speed_kmh: Option<(f64, f64)>,
    /// Cycles in the safe state during the scenario window.
    pub safe_cycles_in_window: Option<u64>,
    /// Where the vehicle parameters (metrics, N · r) came from.
    pub vehicle: String,
    /// What the torque did before each change of the road under the driven
    /// wheel to one that carries less (None: no road catalogue).
    pub preview: Option<Vec<PreviewEvent>>,
    /// What the torque did after each change of the road under the driven
    /// wheel to one that carries more (None: no road catalogue).
    pub releases: Option<Vec<ReleaseEvent>>,
    /// The model arte ran ([`model_of`]; None: the log does not say).
    pub model: Option<ModelInfo>,
    /// Where arte's audio came from ([`audio_of`]: the attached
    /// `audio-acq.toml`; None: the log does not carry one).
    pub audio: Option<AudioSource>,
    /// The log was written by `grip replay --out` (its `grip.replay`
    /// record); None: a drive's (or the recorder's) log.
    pub replay: Option<ReplayInfo>,
    /// The scenario window in log time, ns: [start, end) (None: no window).
    pub window_ns: Option<(u64, u64)>,
    /// The control loop's health over the scenario window (None: no
    /// window).
    pub control: Option<ControlHealth>,
    /// What the loop measured (its cycle records: slip, spin events,
    /// traction, torque, per believed road) over the scenario window, or
    /// without one the time the driver demanded torque; not ground truth
    /// ([`measured()`]).
    pub measured: Measured,
    /// The inverter as its `MotorStatus` frames report it: fault,
    /// derating, command-timeout and not-ready episodes, FaultCodes, the
    /// loop's safe state during faults ([`inverter()`]).
    pub inverter: Inverter,
    /// The drive's speeds against the speeds arte's model was trained at
    /// ([`speeds::drive_speeds`]; None: the log names no model).
    pub training_speeds: Option<speeds::DriveSpeeds>,
    /// The classes of arte's model, as the log carries it (None: the log
    /// names no model, or does not carry it readable): a road it has no
    /// class for is never estimated right, and the ARTE section says so.
    pub model_classes: Option<Vec<String>>,
}

/// The model arte ran, as the log says it ([`model_of`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ModelInfo {
    /// The model file as arte's configuration names it (`arte-svc.toml`'s
    /// `model`, e.g. `models/default.model`), or as `grip replay --model`
    /// was given it.
    pub name: String,
    /// Its SHA-256 (`grip.run` `model.NAME`, else of the attachment;
    /// None: neither).
    pub sha256: Option<String>,
    /// Where the summary found it, for the report.
    pub from: String,
}

impl ModelInfo {
    /// The model file's bytes as `log` carries it: the attachment of its
    /// name, else the attachment whose SHA-256 is its (a replay's model, the
    /// copy a `grip drive --model` drive ran); None: not attached.
    pub fn bytes<'a>(&self, log: &'a DriveLog) -> Option<&'a [u8]> {
        log.attachments
            .get(&self.name)
            .or_else(|| {
                let h = self.sha256.as_deref()?;
                log.attachments
                    .values()
                    .find(|d| grip_digest::sha256_hex(d).eq_ignore_ascii_case(h))
            })
            .map(Vec::as_slice)
    }
}

impl ModelInfo {
    /// `models/NAME (sha256 0123456789ab, FROM)`.
    pub fn line(&self) -> String {
        format!(
            "{} (sha256 {}, {})",
            self.name,
            short_sha(self.sha256.as_ref()),
            self.from
        )
    }
}

/// Where arte's audio came from: audio-acq's `[audio] source` and what
/// goes with it, as the attached `audio-acq.toml` says ([`audio_of`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct AudioSource {
    /// `synth` (the plant's roads, synthesised), `wav` (a file) or `alsa`
    /// (a microphone).
    pub source: String,
    /// `[wav] path` (with `source = "wav"`).
    pub wav: Option<String>,
    /// `[synth.aliases]` as audio-acq resolved it
    /// (`grip_arte::synth::SynthAliases::resolve`): roads the synthesiser
    /// has no sound for, played as the synthesiser road named.
    pub aliases: BTreeMap<String, String>,
}

impl AudioSource {
    /// Whether the audio followed the plant's roads (synthesised from its
    /// ground truth): only then does grading ARTE against them grade the
    /// chain on what it heard.
    pub fn follows_the_plant(&self) -> bool {
        self.source == "synth"
    }

    /// What a true road sounded like, for a road without a sound of its
    /// own (not a synthesiser road): `Some(note)` for such a road with
    /// synthesised audio, `None` otherwise.
    pub fn road_note(&self, road: &str) -> Option<String> {
        if !self.follows_the_plant() || grip_arte::synth::road_index(road).is_some() {
            return None;
        }
        Some(match self.aliases.get(road) {
            Some(to) => format!(
                "no sound of its own: played as {to} (audio-acq.toml [synth.aliases] {road} = \"{to}\")"
            ),
            _ => "no sound of its own: vehicle and microphone noise only (no [synth.aliases] entry in audio-acq.toml)".to_owned(),
        })
    }

    /// The report's line on the source when the audio did not follow the
    /// plant's roads (`None` for synthesised audio).
    pub fn line(&self) -> Option<String> {
        match self.source.as_str() {
            "synth" => None,
            "wav" => Some(format!(
                "audio: from the WAV file {} (audio-acq.toml [audio] source = \"wav\"), not synthesised from the plant's roads: the accuracy below grades that recording's estimates against the roads of the plant's scenario, which the recording need not follow",
                self.wav.as_deref().unwrap_or("?")
            )),
            other => Some(format!(
                "audio: from the {} (audio-acq.toml [audio] source = \"{other}\"), not synthesised from the plant's roads: the accuracy below grades its estimates against the roads of the plant's scenario, which it need not follow",
                if other == "alsa" {
                    "microphone"
                } else {
                    "source"
                }
            )),
        }
    }
}

/// Where arte's audio came from: the `audio-acq.toml` attached to the log
/// (the recorder attaches the configuration the services started with;
/// `grip drive` runs audio-acq with no `--source`). None without one, or
/// when it does not parse.
pub fn audio_of(log: &DriveLog) -> Option<AudioSource> {
    let text = log.attachment_text("audio-acq.toml")?;
    let v: toml::Table = toml::from_str(text).ok()?;
    let source = v.get("audio")?.get("source")?.as_str()?.to_owned();
    let wav = v
        .get("wav")
        .and_then(|w| w.get("path"))
        .and_then(|p| p.as_str())
        .map(str::to_owned);
    // the one rule audio-acq started by (`SynthAliases::resolve`); a table
    // it would have refused gives no aliases (the summary never fails on
    // an attachment)
    let aliases = toml::from_str::<grip_arte::synth::AudioAcqAliases>(text)
        .ok()
        .and_then(|a| {
            a.aliases()
                .resolve(std::path::Path::new("audio-acq.toml"))
                .ok()
        })
        .map(|r| r.sounds)
        .unwrap_or_default();
    Some(AudioSource {
        source,
        wav,
        aliases,
    })
}

/// A log written by `grip replay --out` (its `grip.replay` metadata).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayInfo {
    /// The log that was replayed.
    pub source: String,
    /// `open loop` or `closed loop`.
    pub mode: String,
    /// The configuration the replay ran with.
    pub configuration: String,
    /// The what-if changes (empty: none).
    pub changes: String,
    /// The controller and ARTE switch the replay ran (None: a replay log
    /// written before they were recorded; `grip.run`'s are the source's).
    pub controller: Option<String>,
    /// `on` or `off`.
    pub arte: Option<String>,
    /// Whether the source log's recorder finished it (None: not recorded).
    pub source_finished: Option<bool>,
    /// The confidence gate the replay's tcs-loop ran, `[arte]
    /// min_confidence` of its configuration (None: a replay log written
    /// before the record carried it).
    pub min_confidence: Option<f64>,
    /// The vehicle file the replay's tcs-loop ran (and in closed loop its
    /// plant), as given: `--vehicle`'s path, else the source's attachment
    /// (`vehicle.toml`, `drive/vehicle.toml`), a `--set` on it applied
    /// (None: not recorded).
    pub vehicle: Option<String>,
    /// The `--set`s that changed it (`--set vehicle.toml:vehicle.mass=1800`;
    /// None: none, or not recorded).
    pub vehicle_set: Option<String>,
    /// That file's SHA-256; when it is not the source's, the log carries
    /// it as [`crate::plan::REPLAY_VEHICLE_ATTACHMENT`].
    pub vehicle_sha256: Option<String>,
}

impl ReplayInfo {
    /// Whether the plant (ground truth) is the logged drive's, copied: the
    /// metrics are then not a consequence of the replayed commands.
    pub fn open_loop(&self) -> bool {
        self.mode != "closed loop"
    }

    /// `replay of SOURCE (open loop)`.
    pub fn headline(&self) -> String {
        format!("replay of {} ({})", self.source, self.mode)
    }

    /// The replay's change lines (`grip.replay` `changes`, one each).
    fn change_lines(&self) -> impl Iterator<Item = &str> {
        self.changes.split("; ").filter(|c| !c.is_empty())
    }

    /// Whether the replay changed the loop's confidence gate, as far as its
    /// change lines tell: a `--set` of `[arte] min_confidence`, or another
    /// configuration directory. For a record without `min_confidence` (a
    /// replay log from before it was recorded), whose log then carries
    /// only the source's gate.
    pub fn changed_gate(&self) -> bool {
        self.change_lines().any(|c| {
            c.starts_with("configuration directory ")
                || (c.starts_with("controllers.toml:") && c.contains("min_confidence"))
        })
    }

    /// Whether the replay changed the vehicle, as far as its change lines
    /// tell: `--vehicle`, a `--set` on a vehicle file, or another
    /// configuration directory. For a record without `vehicle` (a replay
    /// log from before it was recorded).
    pub fn changed_vehicle(&self) -> bool {
        self.change_lines().any(|c| {
            c.starts_with("vehicle ")
                || c.starts_with("configuration directory ")
                || c.split_once(": ").is_some_and(|(file, _)| {
                    (file.contains("vehicle") && file.contains(".toml"))
                        || file.contains("(--vehicle ")
                })
        })
    }

    /// What the summary says of the vehicle the replay ran, when it is not
    /// the one the summary used (`used`: where that came from, `used_sha256`
    /// its SHA-256): the replay's own (recorded; an open-loop replay's
    /// ground truth is its source's car's, so the summary keeps the
    /// source's vehicle), or, for a record from before the vehicle was
    /// recorded whose changes touched it, that the log does not carry it.
    /// None when the replay ran the vehicle the summary used.
    pub fn vehicle_line(&self, used: &str, used_sha256: Option<&String>) -> Option<String> {
        match (&self.vehicle, &self.vehicle_sha256) {
            (Some(v), Some(h)) if used_sha256 != Some(h) => Some(format!(
                "the replay's tcs-loop ran vehicle {v}{} (sha256 {}, attached to the log as {}), not {used}{}",
                self.vehicle_set
                    .as_ref()
                    .map_or_else(String::new, |s| format!(" with {s}")),
                short_sha(Some(h)),
                crate::plan::REPLAY_VEHICLE_ATTACHMENT,
                if self.open_loop() {
                    ": in open loop the ground truth is the source drive's car's, so the metrics, the preview's limits and the measured slip are computed with the source's vehicle"
                } else {
                    ""
                }
            )),
            (None, _) if self.changed_vehicle() => Some(format!(
                "the replay's changes (above) touch the vehicle or the configuration directory it comes from, and this log, written before grip replay recorded the vehicle it ran, does not carry the one it ran: the vehicle used here, {used}, is the source drive's"
            )),
            _ => None,
        }
    }
}

/// The `grip.replay` record of a log written by `grip replay --out`.
pub fn replay_of(log: &DriveLog) -> Option<ReplayInfo> {
    let m = log.metadata.get("grip.replay")?;
    let get = |k: &str| m.get(k).cloned().unwrap_or_default();
    Some(ReplayInfo {
        source: m.get("source").cloned().unwrap_or_else(|| "?".into()),
        mode: m.get("mode").cloned().unwrap_or_else(|| "open loop".into()),
        configuration: get("configuration"),
        changes: get("changes"),
        controller: m.get("controller").cloned(),
        arte: m.get("arte").cloned(),
        source_finished: m.get("source_recorder_finished").map(|v| v != "false"),
        min_confidence: m
            .get("min_confidence")
            .and_then(|v| v.parse::<f64>().ok())
            .filter(|c| (0.0..=1.0).contains(c)),
        vehicle: m.get("vehicle").cloned().filter(|v| !v.is_empty()),
        vehicle_set: m.get("vehicle_set").cloned().filter(|v| !v.is_empty()),
        vehicle_sha256: m.get("vehicle_sha256").cloned().filter(|v| !v.is_empty()),
    })
}

/// Whether the log was finished by its writer: the recorder's
/// `grip.recorder` summary, or the `grip.replay` record `grip replay --out`
/// writes (a replay has no recorder; it writes the whole log at once).
pub fn log_finished(log: &DriveLog) -> bool {
    log.recorder.is_some() || replay_of(log).is_some_and(|r| r.source_finished != Some(false))
}

/// The model arte ran: for a log of `grip replay --out` the one its
/// `grip.replay` record names (`model`, `model_sha256`), else the `model`
/// of the `arte-svc.toml` attached to the log (the recorder attaches the
/// configuration arte started with, and every model file of it, so
/// `grip.run`'s `model.*` keys alone do not say which one ran), with its
/// SHA-256 from `grip.run` (`model.NAME`), else of the attached file.
/// None when the log carries no `arte-svc.toml` naming a model.
pub fn model_of(log: &DriveLog) -> Option<ModelInfo> {
    if let Some(m) = log.metadata.get("grip.replay")
        && let Some(name) = m.get("model").filter(|n| !n.is_empty())
    {
        return Some(ModelInfo {
            name: name.clone(),
            sha256: m.get("model_sha256").cloned().filter(|h| !h.is_empty()),
            from: "the model grip replay ran".into(),
        });
    }
    let text = log.attachment_text("arte-svc.toml")?;
    let v: toml::Table = toml::from_str(text).ok()?;
    let name = v.get("model")?.as_str()?.to_owned();
    let recorded = log.run.get(&format!("model.{name}")).cloned();
    let (sha256, from) = match (log.attachments.get(&name), recorded) {
        (Some(d), _) => (
            Some(grip_digest::sha256_hex(d)),
            "arte-svc.toml's model, attached to the log".to_owned(),
        ),
        (None, Some(h)) => (
            Some(h),
            "arte-svc.toml's model; grip.run records its SHA-256, the file is not attached"
                .to_owned(),
        ),
        (None, None) => (
            None,
            "arte-svc.toml's model; neither attached nor in grip.run".to_owned(),
        ),
    };
    // `grip drive --model FILE`: the services ran a copy of the user's file
    // under arte-svc.toml's name; the summary names the user's file
    if let Some(g) = log.run.get("model_given") {
        return Some(ModelInfo {
            from: format!(
                "grip drive --model; the services ran a copy as {}",
                from.replacen(
                    "arte-svc.toml's model",
                    &format!("arte-svc.toml's model {name}"),
                    1
                )
            ),
            name: g.clone(),
            sha256,
        });
    }
    Some(ModelInfo { name, sha256, from })
}

/// The loop's confidence gate, `[arte] min_confidence`: the controller
/// takes no road knowledge less confident ([`gate_of`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gate {
    /// The gate (the default 0.6 when the log does not give it).
    pub min_confidence: f64,
    /// Where it came from.
    pub from: GateFrom,
}

/// Where the loop's confidence gate of a log came from ([`gate_of`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum GateFrom {
    /// The log's `controllers.toml` (for a replay's log: its source's
    /// copy, which the replay ran unchanged).
    Log,
    /// The default: the log carries no `controllers.toml`, or one without
    /// `[arte] min_confidence`.
    #[default]
    Default,
    /// The log's `controllers.toml`, a replay's copy of its source's,
    /// which the replay changed (`--set ...min_confidence`, or another
    /// configuration directory), in a replay log from before the record
    /// carried the gate the replay ran: perhaps not that gate.
    ReplayChanged,
    /// The gate the replay's tcs-loop ran (its `grip.replay` record), not
    /// the source's `controllers.toml` copied into the log.
    Replay,
    /// The log's `controllers.toml` does not read (no TOML), or its
    /// `[arte] min_confidence` is no number in [0, 1]: the gate is
    /// unknown, the default stands in.
    Unknown,
}

impl GateFrom {
    /// `log`, `default`, `replay_changed`, `replay`, `unknown` (`grip
    /// inspect --json`'s `arte_min_confidence_from`).
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Log => "log",
            Self::Default => "default",
            Self::ReplayChanged => "replay_changed",
            Self::Replay => "replay",
            Self::Unknown => "unknown",
        }
    }

    /// Whether the log gives the gate (else the default stands in).
    pub fn given(&self) -> bool {
        matches!(self, Self::Log | Self::ReplayChanged | Self::Replay)
    }
}

/// `[arte] min_confidence` of the log's `controllers.toml`, deserialized
/// as the loop's field is (`grip_tcs::ArteUse::min_confidence`, an `f64`:
/// an integer such as `1` reads too) and held to the loop's range [0, 1].
/// Only that key is read, not the whole file nor the whole `[arte]` table
/// as `grip_tcs::ControllersConfig` does (every section required, unknown
/// fields refused, `max_age_s` required beside it): a log from before a
/// section or key existed keeps its gate. `Ok(None)` without the file or
/// the key; `Err` when the file is no TOML or the key no number in [0, 1].
fn logged_gate(log: &DriveLog) -> Result<Option<f64>, ()> {
    let Some(text) = log.attachment_text("controllers.toml") else {
        return Ok(None);
    };
    let table = text.parse::<toml::Table>().map_err(|_| ())?;
    let Some(value) = table.get("arte").and_then(|a| a.get("min_confidence")) else {
        return Ok(None);
    };
    let c: f64 = value.clone().try_into().map_err(|_| ())?;
    if (0.0..=1.0).contains(&c) {
        Ok(Some(c))
    } else {
        Err(())
    }
}

/// The loop's confidence gate of `log`: the one rule the summary's
/// detection delays and `grip inspect --plot`'s ARTE strip use. For a log
/// of `grip replay --out` the gate its tcs-loop ran (its `grip.replay`
/// record; the log's `controllers.toml` is the source's, copied); for a
/// replay log from before the record carried it, the source's, marked as
/// changed when the replay's changes touched it; else `[arte]
/// min_confidence` of the log's `controllers.toml`; else the default 0.6
/// (no file or no key: [`GateFrom::Default`]; a file that does not read:
/// [`GateFrom::Unknown`]). Never fails.
pub fn gate_of(log: &DriveLog) -> Gate {
    let default = grip_tcs::ArteUse::default().min_confidence;
    let (min_confidence, from) = match logged_gate(log) {
        Ok(Some(c)) => (c, GateFrom::Log),
        Ok(None) => (default, GateFrom::Default),
        Err(()) => (default, GateFrom::Unknown),
    };
    let logged = Gate {
        min_confidence,
        from,
    };
    let Some(r) = replay_of(log) else {
        return logged;
    };
    match r.min_confidence {
        // the replay ran the source's gate: the log's file says it
        Some(c) if logged.from == GateFrom::Log && c == logged.min_confidence => logged,
        Some(c) => Gate {
            min_confidence: c,
            from: GateFrom::Replay,
        },
        // (an old replay's log whose file gives no gate keeps saying so)
        None if r.changed_gate() && logged.from == GateFrom::Log => Gate {
            from: GateFrom::ReplayChanged,
            ..logged
        },
        None => logged,
    }
}

/// The loop's confidence gate ([`gate_of`]) and whether the log gives it
/// (true), else its default 0.6 (false).
pub fn min_confidence_of(log: &DriveLog) -> (f64, bool) {
    let g = gate_of(log);
    (g.min_confidence, g.from.given())
}

/// The wheel reaching a road that carries less (`grip inspect`'s
/// "preview" section).
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewEvent {
    /// When the wheel reached the new road, s from the scenario start.
    pub t: f64,
    /// Where (the plant's x), m.
    pub x: f64,
    /// Road before and after.
    pub from: String,
    /// The new road.
    pub to: String,
    /// What the new road transmits, μ_peak · N · r, N m.
    pub limit: f64,
    /// How long (s) and how far (m) before the wheel arrived the command
    /// was continuously at or below `limit` (None: it was not at arrival).
    pub ahead: Option<(f64, f64)>,
    /// The command was at or below `limit` from the drive's first cycle on
    /// (`ahead` then counts from there: the road change needed no drop).
    pub ahead_since_start: bool,
    /// Command and motor torque when the wheel arrived, N m.
    pub cmd_at_arrival: f64,
    /// Motor torque (truth) at arrival, N m.
    pub torque_at_arrival: f64,
    /// Largest true slip in the 0.2 s after arrival.
    pub max_slip_after: f64,
}

/// The command may sit this far above a limit and still count as at it
/// (the CAN signal's resolution is 0.1 N m).
const LIMIT_TOL_NM: f64 = 0.2;

/// Whether road knowledge's torque cap bound the command of cycle `c`:
/// a finite `torque_cap` below the driver's demand, and the command at it
/// (within the CAN signal's resolution; the command is min(controller,
/// cap), so one well below the cap is the controller's own). An ARTE-off
/// drive logs no cap, so never.
pub fn cap_binding(c: &CycleRecord) -> bool {
    c.torque_cap.is_finite()
        && c.demand.is_finite()
        && c.torque_cap < c.demand - LIMIT_TOL_NM
        && (c.torque_cmd - c.torque_cap).abs() <= LIMIT_TOL_NM
}

/// The catalogue's road of a truth sample's road under the wheel, by name
/// (by index only when the sample carries no name).
fn road_of<'a>(
    roads: &'a RoadCatalogue,
    g: &GroundTruth,
) -> Result<&'a grip_physics::Road, String> {
    match g.road_name() {
        Some(n) => roads.get(n).ok_or_else(|| n.to_owned()),
        None => roads
            .by_index(g.road_index as usize)
            .ok_or_else(|| format!("road index {}", g.road_index)),
    }
}

/// The indices k in `i0 + 1..=i1` where the road under the driven wheel
/// changes between truth samples k − 1 and k (index or name): the changes
/// the preview and release lines are about.
fn road_changes(log: &DriveLog, i0: usize, i1: usize) -> Vec<usize> {
    (i0 + 1..=i1)
        .filter(|&k| {
            let (a, b) = (&log.truth[k - 1], &log.truth[k]);
            a.road_index != b.road_index || a.road_name != b.road_name
        })
        .collect()
}

/// The cycle records stamped at or before `t_ns` (how many) and the last
/// of them, whose command was in force at `t_ns`; None before the first.
fn in_force_at(log: &DriveLog, t_ns: u64) -> Option<(usize, &CycleRecord)> {
    let upto = log.cycles.partition_point(|c| c.stamp_ns <= t_ns);
    upto.checked_sub(1).map(|i| (upto, &log.cycles[i]))
}

/// Preview events over the truth samples `truth[i0..=i1]` (see
/// [`PreviewEvent`]), and the roads of the ground truth the catalogue
/// lacks.
fn preview_events(
    log: &DriveLog,
    i0: usize,
    i1: usize,
    roads: &RoadCatalogue,
    vehicle: &VehicleParams,
) -> (Vec<PreviewEvent>, Vec<String>) {
    let nr = vehicle.normal_force() * vehicle.r;
    let start_ns = log.truth[i0].stamp_ns;
    let mut out = Vec::new();
    let mut missing: Vec<String> = Vec::new();
    for k in road_changes(log, i0, i1) {
        let (a, b) = (&log.truth[k - 1], &log.truth[k]);
        let (ra, rb) = match (road_of(roads, a), road_of(roads, b)) {
            (Ok(ra), Ok(rb)) => (ra, rb),
            (x, y) => {
                for n in [x.err(), y.err()].into_iter().flatten() {
                    if !missing.contains(&n) {
                        missing.push(n);
                    }
                }
                continue;
            }
        };
        if rb.mu_peak() >= ra.mu_peak() {
            continue;
        }
        let limit = rb.mu_peak() * nr;
        let tc = b.stamp_ns;
        // the cycles up to arrival, newest first
        let Some((upto, at)) = in_force_at(log, tc) else {
            continue;
        };
        let mut since: Option<u64> = None;
        // Whether the scan got back to the drive's start (the cycles before
        // its window, start-up, are not counted).
        let mut reached_start = true;
        for c in log.cycles[..upto].iter().rev() {
            if c.stamp_ns < start_ns {
                break;
            }
            if c.safe_state == 0 && c.torque_cmd <= limit + LIMIT_TOL_NM {
                since = Some(c.stamp_ns);
            } else {
                reached_start = false;
                break;
            }
        }
        let ahead = since.map(|t| {
            let x_then = truth_at(&log.truth, t).map_or(b.x, |g| g.x);
            // signed: cycles out of time order can put `t` after `tc`
            (secs_between(t, tc), b.x - x_then)
        });
        let max_slip_after = log.truth[k..]
            .iter()
            .take_while(|g| g.stamp_ns < tc.saturating_add(200_000_000))
            .map(|g| g.lambda)
            .fold(f64::MIN, f64::max);
        out.push(PreviewEvent {
            t: secs_between(start_ns, tc),
            x: b.x,
            from: ra.name().to_owned(),
            to: rb.name().to_owned(),
            limit,
            ahead,
            ahead_since_start: since.is_some() && reached_start,
            cmd_at_arrival: at.torque_cmd,
            torque_at_arrival: b.torque,
            max_slip_after,
        });
    }
    (out, missing)
}

/// The driven wheel reaching a road that carries more than the one it
/// left (`grip inspect`'s "release" lines): how long the command stayed
/// at or below what the previous road transmits after the wheel arrived,
/// i.e. what a cap held for the old road cost on the new one.
#[derive(Debug, Clone, PartialEq)]
pub struct ReleaseEvent {
    /// When the wheel reached the new road, s from the scenario start.
    pub t: f64,
    /// Where (the plant's x), m.
    pub x: f64,
    /// The road it left.
    pub from: String,
    /// The new road.
    pub to: String,
    /// What the road it left transmits, μ_peak · N · r, N m.
    pub old_limit: f64,
    /// The driver's demand in the cycle in force at arrival, N m.
    pub demand_at_arrival: f64,
    /// The command in force at arrival, N m.
    pub cmd_at_arrival: f64,
    /// What happened to the command after arrival.
    pub after: Release,
    /// ∫ (demand − command)⁺ dt over the 0.2 s after arrival (to the next
    /// road change or the window's end if sooner), N m s: the torque
    /// withheld on the new road.
    pub withheld_nms: f64,
}

/// How the command left the previous road's limit ([`ReleaseEvent`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Release {
    /// The demand was within the previous road's limit: nothing to release.
    NotNeeded,
    /// The command was already above the previous road's limit when the
    /// wheel arrived.
    AlreadyAbove,
    /// It rose above the limit this long (s) and far (m) after the wheel
    /// arrived.
    After(f64, f64),
    /// It stayed at or below the limit until this long (s) after arrival,
    /// when the next road change or the window's end came.
    Held(f64),
}

/// Release events over the truth samples `truth[i0..=i1]` (see
/// [`ReleaseEvent`]; roads the catalogue lacks are left out, as
/// [`preview_events`] reports them).
fn release_events(
    log: &DriveLog,
    (i0, i1): (usize, usize),
    end_ns: u64,
    roads: &RoadCatalogue,
    vehicle: &VehicleParams,
) -> Vec<ReleaseEvent> {
    let nr = vehicle.normal_force() * vehicle.r;
    let start_ns = log.truth[i0].stamp_ns;
    let mut changes = road_changes(log, i0, i1);
    changes.push(usize::MAX);
    let mut out = Vec::new();
    for w in changes.windows(2) {
        let (k, next) = (w[0], w[1]);
        let (a, b) = (&log.truth[k - 1], &log.truth[k]);
        let (Ok(ra), Ok(rb)) = (road_of(roads, a), road_of(roads, b)) else {
            continue;
        };
        if rb.mu_peak() <= ra.mu_peak() {
            continue;
        }
        let old_limit = ra.mu_peak() * nr;
        let tc = b.stamp_ns;
        let until = log.truth.get(next).map_or(end_ns, |g| g.stamp_ns);
        let Some((upto, at)) = in_force_at(log, tc) else {
            continue;
        };
        let above = |c: &CycleRecord| c.torque_cmd > old_limit + LIMIT_TOL_NM;
        let after = if at.demand.is_nan() || at.demand <= old_limit + LIMIT_TOL_NM {
            Release::NotNeeded
        } else if above(at) {
            Release::AlreadyAbove
        } else {
            match log.cycles[upto..]
                .iter()
                .take_while(|c| c.stamp_ns < until)
                .find(|c| above(c))
            {
                Some(c) => {
                    let x_then = truth_at(&log.truth, c.stamp_ns).map_or(b.x, |g| g.x);
                    Release::After(secs_between(tc, c.stamp_ns), x_then - b.x)
                }
                None => Release::Held(secs_between(tc, until)),
            }
        };
        // the command in force from arrival over the next 0.2 s on this
        // road (to the next change or the window's end if sooner)
        let t_end = tc.saturating_add(200_000_000).min(until);
        let mut withheld = 0.0;
        let mut prev = (tc, at);
        for c in log.cycles[upto..].iter().take_while(|c| c.stamp_ns < t_end) {
            withheld +=
                (prev.1.demand - prev.1.torque_cmd).max(0.0) * secs_between(prev.0, c.stamp_ns);
            prev = (c.stamp_ns, c);
        }
        // the last command holds to t_end, but not more than a cycle past
        // the loop's last record (a log cut short)
        let last = log
            .cycles
            .last()
            .map_or(t_end, |c| c.stamp_ns.saturating_add(1_000_000));
        withheld += (prev.1.demand - prev.1.torque_cmd).max(0.0)
            * secs_between(prev.0, t_end.min(last).max(prev.0));
        out.push(ReleaseEvent {
            t: secs_between(start_ns, tc),
            x: b.x,
            from: ra.name().to_owned(),
            to: rb.name().to_owned(),
            old_limit,
            demand_at_arrival: at.demand,
            cmd_at_arrival: at.torque_cmd,
            after,
            withheld_nms: withheld,
        });
    }
    out
}

impl ReleaseEvent {
    /// One line of the report.
    pub fn line(&self) -> String {
        let head = format!(
            "{} -> {} at {:.3} s (x {:.2} m), {}'s limit {:.1} N m, demand {:.1} N m:",
            self.from, self.to, self.t, self.x, self.from, self.old_limit, self.demand_at_arrival
        );
        let what = match self.after {
            Release::NotNeeded => "the demand was within it: nothing to release".to_owned(),
            Release::AlreadyAbove => format!(
                "command already above it when the wheel arrived ({:.1} N m)",
                self.cmd_at_arrival
            ),
            Release::After(s, m) => format!(
                "command rose above it {s:.3} s / {m:.2} m after the wheel arrived (at arrival {:.1} N m)",
                self.cmd_at_arrival
            ),
            Release::Held(s) => format!(
                "command held at or below it for all {s:.3} s the wheel was on {} in the window",
                self.to
            ),
        };
        format!(
            "{head} {what}; withheld in the next 0.2 s on {} ∫(T_d − T*)⁺dt {:.1} N m s",
            self.to, self.withheld_nms
        )
    }
}

impl PreviewEvent {
    /// One line of the report.
    pub fn line(&self) -> String {
        let head = format!(
            "{} -> {} at {:.3} s (x {:.2} m), limit {:.1} N m:",
            self.from, self.to, self.t, self.x, self.limit
        );
        let capped = match self.ahead {
            Some((s, m)) if self.ahead_since_start => format!(
                "command at or below it since the drive began ({s:.3} s / {m:.2} m before the wheel arrived: no drop needed)"
            ),
            Some((s, m)) => {
                format!("command at or below it from {s:.3} s / {m:.2} m before the wheel arrived")
            }
            None => "command NOT at or below it when the wheel arrived".to_owned(),
        };
        format!(
            "{head} {capped}; at arrival command {:.1}, motor {:.1} N m; max slip in the next 0.2 s {:.3}",
            self.cmd_at_arrival, self.torque_at_arrival, self.max_slip_after
        )
    }
}

/// `to - from` in seconds, signed (stamps out of time order give a
/// negative time, never a wrapped one).
fn secs_between(from_ns: u64, to_ns: u64) -> f64 {
    (i128::from(to_ns) - i128::from(from_ns)) as f64 * 1e-9
}

/// Messages stamped earlier than the message before them on their topic.
pub fn out_of_time_order(stamps: impl IntoIterator<Item = u64>) -> u64 {
    let mut last: Option<u64> = None;
    let mut n = 0;
    for s in stamps {
        n += u64::from(last.is_some_and(|l| s < l));
        last = Some(s);
    }
    n
}

/// Where an estimate is judged: the middle of the audio frame it heard
/// (CLOCK_MONOTONIC ns); the summary's accuracy and `grip inspect`'s
/// timeline both take the road at the microphone there.
pub fn frame_mid_ns(e: &RoadEstimate) -> u64 {
    e.frame_t0_ns / 2 + e.frame_t1_ns / 2
}

/// The largest jump forward of a sequence number counted as lost
/// messages: 2^32 (seven weeks of 1 kHz cycles). A larger one is no
/// plausible loss but a damaged or foreign number (a cycle `seq` of
/// u64::MAX), counted as a restart.
pub const SEQ_GAP_MAX: u64 = 1 << 32;

/// Sequence gaps and resets of a sequence: a jump back, or forward by
/// more than [`SEQ_GAP_MAX`], is a reset (restart).
pub fn seq_gaps(seqs: impl IntoIterator<Item = u64>) -> (u64, u64) {
    let mut last: Option<u64> = None;
    let (mut gaps, mut resets) = (0u64, 0);
    for s in seqs {
        if let Some(l) = last {
            if s > l && s - l - 1 <= SEQ_GAP_MAX {
                gaps = gaps.saturating_add(s - l - 1);
            } else {
                resets += 1;
            }
        }
        last = Some(s);
    }
    (gaps, resets)
}

/// Bounds of a plausible ground-truth sample: |V| in m/s, |ω| in rad/s,
/// |T| in N m, |x| in m (no road car goes 1000 m/s; a wheel at 10^4
/// rad/s is far beyond any tyre), and |λ| ≤ 2, which the plant's slip
/// (ωr − V) / max(|ωr|, |V|, v_eps) cannot exceed.
const TRUTH_PLAUSIBLE: [(&str, &str, f64); 5] = [
    ("v", "m/s", 1000.0),
    ("omega", "rad/s", 1e4),
    ("lambda", "", 2.0),
    ("torque", "N m", 1e5),
    ("x", "m", 1e8),
];

/// The first value of `g` that no plant makes: not finite, or beyond
/// [`TRUTH_PLAUSIBLE`]; (field, value, unit, bound).
fn implausible_truth(g: &GroundTruth) -> Option<(&'static str, f64, &'static str, f64)> {
    let values = [g.v, g.omega, g.lambda, g.torque, g.x];
    TRUTH_PLAUSIBLE
        .iter()
        .zip(values)
        .find(|((_, _, max), v)| !v.is_finite() || v.abs() > *max)
        .map(|(&(name, unit, max), v)| (name, v, unit, max))
}

/// The scenario's duration, s: `grip.run` `scenario_duration_s`, else the
/// `duration` of the attached `scenarios/<scenario>.toml`.
/// A duration that is not finite and positive is no duration.
pub fn scenario_duration(log: &DriveLog) -> Option<f64> {
    let valid = |d: f64| (d.is_finite() && d > 0.0).then_some(d);
    if let Some(d) = log
        .run
        .get("scenario_duration_s")
        .and_then(|s| s.parse::<f64>().ok())
        .and_then(valid)
    {
        return Some(d);
    }
    attached_scenario(log)?
        .get("duration")?
        .as_float()
        .and_then(valid)
}

/// The attachment that is the scenario file the drive ran: the drive's
/// own [`crate::plan::SCENARIO_ATTACHMENT`] (`grip drive --scenario PATH`)
/// when the log carries it or `grip.run` records its hash; else for a
/// scenario named under the configuration directory
/// `scenarios/<grip.run scenario>.toml` (a name or a path:
/// `grip_config::dir::ScenarioArg::by_spelling`). `None`: the log does not say (a
/// path, from a drive before the file was attached: an attached
/// `scenarios/*.toml` with the same tail may be another file, so none is
/// taken for it).
pub fn scenario_attachment(log: &DriveLog) -> Option<String> {
    let own = crate::plan::SCENARIO_ATTACHMENT;
    if log.attachments.contains_key(own) || log.run.contains_key(&format!("config.{own}")) {
        return Some(own.to_owned());
    }
    grip_config::dir::ScenarioArg::by_spelling(log.run.get("scenario")?).in_config_dir()
}

/// The attached scenario file ([`scenario_attachment`]), parsed (`None`
/// without one, or when it does not parse).
fn attached_scenario(log: &DriveLog) -> Option<toml::Value> {
    let text = log.attachment_text(&scenario_attachment(log)?)?;
    toml::from_str(text).ok()
}

/// When the attached scenario's driver first demands torque, s after its
/// start (`grip_physics::Demand::begins` on a 1 ms grid; `None` without an
/// attached scenario whose `[demand]` and `duration` read).
pub fn scenario_demand_begins(log: &DriveLog) -> Option<f64> {
    let v = attached_scenario(log)?;
    let duration = v.get("duration")?.as_float()?;
    let demand: grip_physics::Demand = v.get("demand")?.clone().try_into().ok()?;
    demand.begins(duration, 1e-3)
}

/// SHA-256 of the attachment `name`: the one `grip.run` records for it
/// (`config.NAME`) when it records one, else of the attached bytes; a
/// recorded hash the attachment does not match is a warning.
fn attachment_sha256(log: &DriveLog, name: &str, warnings: &mut Vec<String>) -> Option<String> {
    let data = log.attachments.get(name);
    let recorded = log.run.get(&format!("config.{name}")).cloned();
    match (data, recorded) {
        (Some(d), Some(r)) => {
            let got = grip_digest::sha256_hex(d);
            if got != r {
                warnings.push(format!(
                    "attachment {name}: its SHA-256 {got} is not the one grip.run records ({r}): the attachment is damaged"
                ));
            }
            Some(got)
        }
        (Some(d), None) => Some(grip_digest::sha256_hex(d)),
        (None, r) => r,
    }
}

/// SHA-256 of the scenario file the drive ran ([`scenario_attachment`]).
fn scenario_sha256(log: &DriveLog, warnings: &mut Vec<String>) -> Option<String> {
    attachment_sha256(log, &scenario_attachment(log)?, warnings)
}

/// SHA-256 of the vehicle file the summary used, when [`crate::vehicle_for`]
/// took it from an attachment (`vehicle_from` names it).
fn vehicle_sha256(
    log: &DriveLog,
    vehicle_from: &str,
    warnings: &mut Vec<String>,
) -> Option<String> {
    if crate::plan::drive_vehicle_label(log) == vehicle_from {
        return attachment_sha256(log, crate::plan::VEHICLE_ATTACHMENT, warnings);
    }
    if crate::plan::replay_vehicle_label(log) == vehicle_from {
        return attachment_sha256(log, crate::plan::REPLAY_VEHICLE_ATTACHMENT, warnings);
    }
    let name = log
        .attachments
        .keys()
        .find(|n| crate::plan::attached_label(n) == vehicle_from)?;
    attachment_sha256(log, name, warnings)
}

/// Index of the first truth sample of the running scenario: plant-sim
/// holds the vehicle (state frozen) until the start, so it is the last
/// sample before the state first changes; with a microphone ahead of the
/// wheel it first pre-rolls (x rising from minus the lead to 0 at v0, speed
/// and wheel speed unchanged), so changes of x at or below 0 do not count:
/// the start is the last sample before x passes 0 or the speeds change.
/// `None` if it never changes (the scenario never started).
pub fn scenario_start(truth: &[GroundTruth]) -> Option<usize> {
    let f = truth.first()?;
    truth
        .iter()
        .position(|g| (g.x != f.x && g.x > 0.0) || g.v != f.v || g.omega != f.omega)
        .map(|i| i.saturating_sub(1))
}

fn fault_delta(a: &E2eFaults, b: &E2eFaults) -> E2eFaults {
    E2eFaults {
        crc: b.crc.wrapping_sub(a.crc),
        counter_repeated: b.counter_repeated.wrapping_sub(a.counter_repeated),
        counter_skipped: b.counter_skipped.wrapping_sub(a.counter_skipped),
        length: b.length.wrapping_sub(a.length),
        unknown_id: b.unknown_id.wrapping_sub(a.unknown_id),
        timeout: b.timeout.wrapping_sub(a.timeout),
    }
}

/// How the summary names a drive's bus when its log attaches no DBC.
const BUILTIN_PROTOCOL: &str = "the built-in protocol";

/// Truth in effect at `t_ns` (the last sample at or before it).
pub fn truth_at(truth: &[GroundTruth], t_ns: u64) -> Option<&GroundTruth> {
    let i = truth.partition_point(|g| g.stamp_ns <= t_ns);
    if i == 0 { None } else { truth.get(i - 1) }
}

/// The road the microphone hears (`mic_lead_m` ahead of the driven wheel):
/// what ARTE is judged against.
fn name_of_mic_truth(g: &GroundTruth) -> String {
    g.mic_road_name().unwrap_or("?").to_owned()
}

fn name_of_est(e: &RoadEstimate) -> Option<String> {
    if e.class_index == grip_msgs::NO_CLASS {
        None
    } else {
        e.class_name().map(str::to_owned)
    }
}

fn timing(cycles: &[CycleRecord]) -> Timing {
    let mut wake: Vec<i64> = cycles.iter().map(|c| c.wakeup_latency_ns).collect();
    let wakeup_ns = wake.clone();
    let mut comp: Vec<i64> = cycles.iter().map(|c| c.compute_ns as i64).collect();
    let mut periods: Vec<i64> = cycles
        .windows(2)
        // the signed difference, without overflow on absurd stamps (a
        // damaged log: 0 next to 2^63)
        .map(|w| w[1].stamp_ns.wrapping_sub(w[0].stamp_ns) as i64)
        .collect();
    Timing {
        cycles: cycles.len() as u64,
        wakeup: Percentiles::of(&mut wake),
        compute: Percentiles::of(&mut comp),
        deadline_misses: match (cycles.first(), cycles.last()) {
            (Some(a), Some(b)) => b.deadline_misses.saturating_sub(a.deadline_misses),
            _ => 0,
        },
        safe_cycles: cycles.iter().filter(|c| c.safe_state != 0).count() as u64,
        safe_entries: cycles
            .windows(2)
            .filter(|w| w[0].safe_state == 0 && w[1].safe_state != 0)
            .count() as u64,
        period_ns: Percentiles::of(&mut periods).p50,
        wakeup_ns,
        in_scenario: None,
    }
}

/// The timing of the cycles stamped in `[start_ns, end_ns)`.
fn window_timing(cycles: &[CycleRecord], start_ns: u64, end_ns: u64) -> WindowTiming {
    let idx: Vec<usize> = (0..cycles.len())
        .filter(|&i| (start_ns..end_ns).contains(&cycles[i].stamp_ns))
        .collect();
    let (Some(&first), Some(&last)) = (idx.first(), idx.last()) else {
        return WindowTiming::default();
    };
    let mut wake: Vec<i64> = idx.iter().map(|&i| cycles[i].wakeup_latency_ns).collect();
    let mut comp: Vec<i64> = idx.iter().map(|&i| cycles[i].compute_ns as i64).collect();
    // a cycle's count includes the deadlines missed just before it
    let base = cycles[first.saturating_sub(1)].deadline_misses;
    WindowTiming {
        cycles: idx.len() as u64,
        wakeup: Percentiles::of(&mut wake),
        compute: Percentiles::of(&mut comp),
        deadline_misses: cycles[last].deadline_misses.saturating_sub(base),
        safe_entries: idx
            .iter()
            .filter(|&&i| i > 0 && cycles[i - 1].safe_state == 0 && cycles[i].safe_state != 0)
            .count() as u64,
    }
}

/// The truth sample in effect at `t_ns` if the truth stream covers it: the
/// last sample at or before it, as long as `t_ns` is within one plant
/// period of the stream's last sample (after the stream ends there is no
/// truth to judge against).
fn truth_covering(truth: &[GroundTruth], t_ns: u64) -> Option<&GroundTruth> {
    let last = truth.last()?;
    if t_ns >= last.stamp_ns.saturating_add(TRUTH_PERIOD_NS) {
        return None;
    }
    truth_at(truth, t_ns)
}

/// The scenario window in the truth stream.
struct Window {
    /// Its first sample (the last one of the hold or pre-roll).
    i0: usize,
    /// Its last sample.
    last_in: usize,
    /// The stamp of `truth[i0]`, ns.
    start_ns: u64,
    /// Its end (exclusive), ns: the scenario's end, or where the truth
    /// stream ends if that is earlier.
    end_ns: u64,
}

/// [`summarize`], saying where `roads` came from in the report and adding
/// the catalogue's warnings to the summary's (what `grip inspect` uses).
pub fn summarize_with_roads(
    log: &DriveLog,
    vehicle: &VehicleParams,
    vehicle_from: &str,
    roads: &LogRoads,
) -> Summary {
    let mut s = summarize(log, vehicle, vehicle_from, roads.catalogue.as_ref());
    s.roads_from = Some(roads.from.clone());
    s.warnings.extend(roads.warnings.iter().cloned());
    s
}

/// Computes the summary of `log`; `vehicle` (the one the drive ran with,
/// [`crate::vehicle_for`], described by `vehicle_from`) gives M/n and J_w
/// for the kinetic-energy metric and N · r for the preview report, which
/// needs the road catalogue `roads` (None: no preview report; the drive's
/// own: [`DriveLog::road_catalogue`] and [`summarize_with_roads`]).
pub fn summarize(
    log: &DriveLog,
    vehicle: &VehicleParams,
    vehicle_from: &str,
    roads: Option<&RoadCatalogue>,
) -> Summary {
    let mut s = Summary {
        file: log.path.display().to_string(),
        vehicle: vehicle_from.to_owned(),
        vehicle_params: *vehicle,
        scenario: log.run.get("scenario").cloned(),
        scenario_duration_s: scenario_duration(log),
        ..Summary::default()
    };
    for k in [
        "scenario",
        "controller",
        "arte",
        "seed",
        "version",
        "git_revision",
        "instance",
        // `grip generate`: source = generated, clock = scripted
        "source",
        "clock",
    ] {
        if let Some(v) = log.run.get(k) {
            s.run.push((k.to_owned(), v.clone()));
        }
    }
    if let Some(t) = &log.report.truncated {
        s.warnings.push(format!(
            "log is incomplete (not all of the file could be read): {t}"
        ));
        s.incomplete.push(format!("the log is incomplete: {t}"));
    }
    if log.report.bad > 0 {
        let w = format!(
            "{} messages did not decode (first: {})",
            log.report.bad,
            log.report.first_error.as_deref().unwrap_or("?")
        );
        s.incomplete.push(w.clone());
        s.warnings.push(w);
    }
    let late: Vec<String> = [
        (
            topics::CYCLE,
            out_of_time_order(log.cycles.iter().map(|c| c.stamp_ns)),
        ),
        (
            topics::TRUTH,
            out_of_time_order(log.truth.iter().map(|g| g.stamp_ns)),
        ),
        (
            topics::ROAD,
            out_of_time_order(log.roads.iter().map(|e| e.stamp_ns)),
        ),
    ]
    .into_iter()
    .filter(|(_, n)| *n > 0)
    .map(|(t, n)| format!("{t} {n}"))
    .collect();
    if !late.is_empty() {
        s.warnings.push(format!(
            "messages out of time order (stamped before the one logged before them): {}; the times computed from them may be off",
            late.join(", ")
        ));
    }
    s.replay = replay_of(log);
    s.model = model_of(log);
    s.model_classes = s
        .model
        .as_ref()
        .and_then(|m| m.bytes(log))
        .and_then(|b| grip_arte::model::Model::from_bytes(b).ok())
        .map(|m| m.classes().to_vec());
    s.audio = audio_of(log);
    // a replay's controller and ARTE switch are its own (`grip.run` is
    // the source's, copied)
    if let Some(r) = &s.replay {
        for (k, v) in [("controller", &r.controller), ("arte", &r.arte)] {
            let Some(v) = v else { continue };
            match s.run.iter_mut().find(|(kk, _)| kk == k) {
                Some(e) => e.1 = v.clone(),
                None => s.run.push((k.to_owned(), v.clone())),
            }
        }
    }
    if s.replay.is_some() && !log_finished(log) {
        s.warnings.push(
            "the replayed log's recorder did not finish it (crash or kill; its grip.replay record says so): the replay covers what it had".into(),
        );
        s.incomplete
            .push("the replayed log's recorder did not finish it".into());
    } else if !log_finished(log) {
        s.warnings
            .push("no grip.recorder summary: the recorder did not finish (crash or kill)".into());
        s.incomplete
            .push("no grip.recorder summary: the recorder did not finish".into());
    }
    let mut hash_warnings = Vec::new();
    s.scenario_sha256 = scenario_sha256(log, &mut hash_warnings);
    s.vehicle_sha256 = vehicle_sha256(log, vehicle_from, &mut hash_warnings);
    s.warnings.extend(hash_warnings);

    // topics
    for (t, _) in topics::ALL {
        let in_log = log.counts.get(t).copied().unwrap_or(0);
        let seqs: Option<Vec<u64>> = match t {
            x if x == topics::CYCLE => Some(log.cycles.iter().map(|c| c.seq).collect()),
            x if x == topics::TRUTH => Some(log.truth.iter().map(|c| c.seq).collect()),
            x if x == topics::ROAD => Some(log.roads.iter().map(|c| c.seq).collect()),
            x if x == topics::AUDIO => Some(log.audio.seqs.clone()),
            _ => None,
        };
        let (mut g, r) = seqs.map(seq_gaps).unzip();
        if t == topics::CAN_LOG {
            // no sequence number: the recorder's alive-counter gap count
            g = log
                .recorder
                .as_ref()
                .and_then(|m| m.get(&format!("{t}.counter_gaps")))
                .and_then(|v| v.parse().ok());
        }
        let recorder = log.recorder.as_ref().and_then(|m| {
            let get = |k: &str| {
                m.get(&format!("{t}.{k}"))
                    .and_then(|v| v.parse::<u64>().ok())
            };
            Some((get("received")?, get("written")?, get("queue_dropped")?))
        });
        s.topics.push(TopicLine {
            topic: t.to_owned(),
            in_log,
            seq_gaps: g,
            seq_resets: r,
            recorder,
        });
    }

    s.timing = timing(&log.cycles);

    // ground truth no plant makes (a damaged file): said, as other damage
    let bad: Vec<(&GroundTruth, _)> = log
        .truth
        .iter()
        .filter_map(|g| implausible_truth(g).map(|b| (g, b)))
        .collect();
    if let Some((g, (name, v, unit, max))) = bad.first() {
        let t = log
            .truth
            .first()
            .map_or(0.0, |f| secs_between(f.stamp_ns, g.stamp_ns));
        let w = format!(
            "{} ground-truth sample(s) hold values no plant makes (the first, seq {} at {t:.3} s from the first sample: {name} = {v:e}{}{unit}, beyond ±{max:e}): the log is damaged; the metrics and the ARTE figures judged against the ground truth are not to be trusted",
            bad.len(),
            g.seq,
            if unit.is_empty() { "" } else { " " },
        );
        s.incomplete.push(w.clone());
        s.warnings.push(w);
    }

    // the scenario window and its metrics
    let window = scenario_window(log, vehicle, &mut s);

    // ARTE: every estimate whose frame's midpoint has ground truth is
    // judged for the whole-log figure; those in the window for the
    // scenario's (the headline)
    let mut a = ArteEval {
        estimates: log.roads.len() as u64,
        // the log's gate, with a scenario window or without (a car's log)
        min_confidence: min_confidence_of(log),
        gate_from: gate_of(log).from,
        ..ArteEval::default()
    };
    for e in &log.roads {
        let mid = frame_mid_ns(e);
        let (Some(est), Some(g)) = (name_of_est(e), truth_covering(&log.truth, mid)) else {
            continue;
        };
        let truth_name = name_of_mic_truth(g);
        let ok = est == truth_name;
        a.log_judged += 1;
        a.log_correct += u64::from(ok);
        if !window
            .as_ref()
            .is_some_and(|w| (w.start_ns..w.end_ns).contains(&mid))
        {
            continue;
        }
        a.judged += 1;
        a.correct += u64::from(ok);
        let band = (g.v.abs() * 3.6 / SPEED_BAND_KMH).floor();
        if band.is_finite() {
            let b = a.per_speed_band.entry(band as u32).or_default();
            b.0 += 1;
            b.1 += u64::from(ok);
        }
        *a.confusion.entry((truth_name.clone(), est)).or_default() += 1;
        let r = a.per_road.entry(truth_name).or_default();
        r.0 += 1;
        r.1 += u64::from(ok);
    }

    if let Some(w) = &window {
        // changes of the true road at the microphone from the first truth
        // sample (a microphone ahead of the wheel reaches a road during
        // the pre-roll, before the scenario clock starts) to the window's
        // end
        let mut change_at: Vec<(u64, String, String)> = Vec::new();
        for p in log.truth[..=w.last_in].windows(2) {
            if p[1].mic_road_index != p[0].mic_road_index {
                change_at.push((
                    p[1].stamp_ns,
                    name_of_mic_truth(&p[0]),
                    name_of_mic_truth(&p[1]),
                ));
            }
        }
        let gate = a.min_confidence.0;
        for (k, (tc, from, to)) in change_at.iter().enumerate() {
            let until = change_at.get(k + 1).map_or(u64::MAX, |c| c.0);
            let naming = || {
                log.roads
                    .iter()
                    .filter(|e| e.stamp_ns >= *tc && e.stamp_ns < until)
                    .filter(|e| name_of_est(e).as_deref() == Some(to.as_str()))
            };
            let delay = naming().next().map(|e| secs_between(*tc, e.stamp_ns));
            let gated_delay = naming()
                .find(|e| e.confidence >= gate)
                .map(|e| secs_between(*tc, e.stamp_ns));
            a.changes.push(RoadChange {
                t: secs_between(w.start_ns, *tc),
                from: from.clone(),
                to: to.clone(),
                delay,
                gated_delay,
            });
        }

        // the loop during the scenario
        let mut safe_in = 0;
        let mut first_in: Option<&CycleRecord> = None;
        let mut last_in_c: Option<&CycleRecord> = None;
        for c in &log.cycles {
            if (w.start_ns..w.end_ns).contains(&c.stamp_ns) {
                first_in.get_or_insert(c);
                last_in_c = Some(c);
                if c.safe_state == 0 {
                    a.active_cycles += 1;
                    a.used_cycles += u64::from(c.used_arte != 0);
                    a.capped_cycles += u64::from(cap_binding(c));
                } else {
                    safe_in += 1;
                }
            }
        }
        s.safe_cycles_in_window = Some(safe_in);
        s.timing.in_scenario = Some(window_timing(&log.cycles, w.start_ns, w.end_ns));
        if let Some(r) = roads {
            let (events, missing) = preview_events(log, w.i0, w.last_in, r, vehicle);
            if !missing.is_empty() {
                s.warnings.push(format!(
                    "preview: the road catalogue has no road {} of the ground truth; its changes are left out",
                    missing.join(", ")
                ));
            }
            s.preview = Some(events);
            s.releases = Some(release_events(log, (w.i0, w.last_in), w.end_ns, r, vehicle));
        }
        if let (Some(a0), Some(a1)) = (first_in, last_in_c) {
            s.can.faults_in_window = Some(fault_delta(&a0.faults, &a1.faults));
        }
    }
    s.arte = a;

    // CAN, named by the drive's own protocol
    let dbc = log
        .attachment_text("can.toml")
        .and_then(|t| grip_io::service::parse_can(std::path::Path::new("can.toml"), t).ok())
        .and_then(|c| c.dbc);
    s.can.bus = dbc
        .as_ref()
        .map_or_else(|| BUILTIN_PROTOCOL.to_owned(), |d| format!("{d}, attached"));
    let dbc = dbc.unwrap_or_else(|| BUILTIN_PROTOCOL.to_owned());
    let protocol = log.protocol().unwrap_or_else(|e| {
        s.warnings
            .push(format!("CAN frames named by the built-in protocol: {e}"));
        grip_io::can::protocol::Protocol::builtin().clone()
    });
    for f in &log.can {
        let name = protocol
            .spec_for_id(f.id)
            .map_or_else(|| format!("0x{:X}", f.id), |m| m.name.to_owned());
        let dir = if f.direction == can_dir::TX {
            "tx"
        } else {
            "rx"
        };
        *s.can.frames.entry((name, f.id, dir)).or_default() += 1;
        if f.flags & can_flags::E2E_REJECTED != 0 {
            s.can.rejected += 1;
        }
    }
    if let Some(c) = log.cycles.last() {
        s.can.faults = c.faults;
    }
    s.inverter = inverter(log, &protocol, s.window_ns);
    s.can.short = short_signals(log, &protocol, &dbc, vehicle, s.window_ns);
    for sh in &s.can.short {
        s.warnings.push(sh.line());
    }
    if let Some((ws, we)) = s.window_ns {
        let period = u64::try_from(s.timing.period_ns)
            .ok()
            .filter(|&p| p > 0)
            .unwrap_or(1_000_000);
        let mut h = control_health(log, ws, we, period, &protocol);
        if let WindowStatus::Partial {
            covered_s,
            duration_s,
        } = s.window_status
        {
            h.cut_short = Some((covered_s, duration_s));
        }
        if h.lost() {
            s.warnings.push(h.line());
        }
        s.control = Some(h);
    }
    s.measured = measured(log, vehicle, s.window_ns, roads);
    s.training_speeds = speeds::drive_speeds(log, s.window_ns);
    if window.is_none() && s.measured.window == measured::MeasuredWindow::Demand {
        // no scenario window (a car's log): how often the controller used
        // the estimate over the measured section's window, labelled so
        s.arte.used_cycles = s.measured.used_arte_cycles;
        s.arte.active_cycles = s.measured.active_cycles;
        s.arte.capped_cycles = s.measured.capped_cycles;
        s.arte.used_in_demand_window = true;
    }
    s
}

/// The fault kinds that grew from `a` to `b`, named, with by how much.
fn faults_grown(a: &E2eFaults, b: &E2eFaults) -> Vec<String> {
    let d = fault_delta(a, b);
    [
        ("input timeouts", d.timeout),
        ("CRC errors", d.crc),
        ("alive counter repeated", d.counter_repeated),
        ("alive counter skipped", d.counter_skipped),
        ("wrong lengths", d.length),
        ("unknown ids", d.unknown_id),
    ]
    .into_iter()
    .filter(|(_, n)| *n > 0)
    .map(|(k, n)| format!("{k} +{n}"))
    .collect()
}

/// [`ControlHealth`] of the cycles stamped in `[ws, we)`; `period` (ns)
/// is what one cycle stands for after the last one.
fn control_health(
    log: &DriveLog,
    ws: u64,
    we: u64,
    period: u64,
    protocol: &grip_io::can::protocol::Protocol,
) -> ControlHealth {
    use grip_io::can::protocol::MsgKind;
    let inw: Vec<&CycleRecord> = log
        .cycles
        .iter()
        .filter(|c| (ws..we).contains(&c.stamp_ns))
        .collect();
    let rel = |ns: u64| secs_between(ws, ns);
    let mut h = ControlHealth {
        cycles: inw.len() as u64,
        window_s: rel(we),
        ..ControlHealth::default()
    };
    // safe-state runs: entered in the window (or safe at its start), and
    // whether each ended in control again
    let mut run_start: Option<(u64, bool)> = None;
    for (i, c) in inw.iter().enumerate() {
        if c.safe_state != 0 {
            if run_start.is_none() {
                // at the first record: safe since the window's start
                run_start = Some(if i == 0 {
                    (ws, false)
                } else {
                    (c.stamp_ns, true)
                });
                h.entries += u64::from(i > 0);
            }
        } else if let Some((s0, entered)) = run_start.take() {
            h.recovered += u64::from(entered);
            let d = secs_between(s0, c.stamp_ns);
            if h.longest_recovered.is_none_or(|(l, _)| d > l) {
                h.longest_recovered = Some((d, rel(s0)));
            }
        }
    }
    let last_active = inw.iter().rposition(|c| c.safe_state == 0);
    h.never_in_control = last_active.is_none();
    let (since, before) = match last_active {
        None => (ws, None),
        Some(i) => (
            inw.get(i + 1)
                .map_or(inw[i].stamp_ns.saturating_add(period), |c| c.stamp_ns),
            Some(inw[i]),
        ),
    };
    let after = &inw[last_active.map_or(0, |i| i + 1)..];
    // the last cycle in control, a few periods before the end without a
    // record after it (a stall at the end): in control at the end
    let out_at_end = !after.is_empty() || secs_between(since, we) >= CONTROL_LOST_MIN_S;
    if since < we && (h.never_in_control || out_at_end) {
        let reaches = after.last().is_some_and(|c| {
            secs_between(c.stamp_ns, we) < CONTROL_LOST_MIN_S
                && c.stamp_ns.saturating_add(period.saturating_mul(5)) >= we
        });
        h.end_out = Some((rel(since), secs_between(since, we)));
        h.end_records = (after.len() as u64, reaches);
        // what the log says of why
        let mut why = Vec::new();
        let from = before.or_else(|| {
            log.cycles
                .iter()
                .rev()
                .find(|c| c.stamp_ns < ws)
                .or(inw.first().copied())
        });
        if let (Some(a), Some(b)) = (from, inw.last()) {
            let grown = faults_grown(&a.faults, &b.faults);
            if !grown.is_empty() {
                why.push(format!(
                    "the loop's fault counters over that time: {}",
                    grown.join(", ")
                ));
            }
        }
        if !log.can.is_empty() {
            let rx: Vec<&grip_msgs::CanFrame> = log
                .can
                .iter()
                .filter(|f| f.direction != can_dir::TX && (since..we).contains(&f.stamp_ns))
                .collect();
            if rx.is_empty() {
                let last_rx = log
                    .can
                    .iter()
                    .filter(|f| f.direction != can_dir::TX && f.stamp_ns < since)
                    .map(|f| f.stamp_ns)
                    .max();
                why.push(match last_rx {
                    Some(t) => format!(
                        "tcs-loop received no CAN frame from then to the scenario's end (its last one at {:.3} s: the bus silent, down or gone)",
                        secs_between(ws, t)
                    ),
                    None => "tcs-loop received no CAN frame in it (the bus silent, down or gone)"
                        .to_owned(),
                });
            } else {
                let rejected = rx
                    .iter()
                    .filter(|f| f.flags & can_flags::E2E_REJECTED != 0)
                    .count();
                let missing: Vec<&str> = [
                    MsgKind::WheelSpeeds,
                    MsgKind::MotorStatus,
                    MsgKind::DriverDemand,
                ]
                .into_iter()
                .map(|k| protocol.spec(k))
                .filter(|m| {
                    !rx.iter()
                        .any(|f| f.id == m.id && f.flags & can_flags::E2E_REJECTED == 0)
                })
                .map(|m| m.name)
                .collect();
                why.push(format!(
                    "tcs-loop received {} CAN frames in it ({rejected} rejected by the E2E check){}",
                    rx.len(),
                    if missing.is_empty() {
                        String::new()
                    } else {
                        format!(", no valid {}", missing.join(", "))
                    }
                ));
            }
        }
        h.reason = why.join("; ");
    }
    h
}

/// Finds the scenario window of `log`, sets the summary's window, its
/// status, the metrics and the start and end speeds, and warns when the
/// log has no window or a window shorter than the scenario.
fn scenario_window(log: &DriveLog, vehicle: &VehicleParams, s: &mut Summary) -> Option<Window> {
    if log.truth.len() < 2 {
        s.window_status = WindowStatus::NoTruth;
        return None;
    }
    let t_first = log.truth[0].stamp_ns;
    let rel = |ns: u64| secs_between(t_first, ns);
    let truth_s = rel(log.truth[log.truth.len() - 1].stamp_ns);
    let Some(i0) = scenario_start(&log.truth) else {
        // a log that stops early (truncated, or the recorder did not
        // finish) has simply not reached the start; a complete one shows a
        // plant that never started
        if log.report.truncated.is_some() || !log_finished(log) {
            s.window_status = WindowStatus::EndsBeforeStart;
            let w = format!(
                "the log ends before the scenario start: its ground truth stops after {truth_s:.3} s with the car still held or pre-rolling; no metrics, no figures during the scenario"
            );
            s.incomplete.push(w.clone());
            s.warnings.push(w);
        } else {
            s.window_status = WindowStatus::NeverStarted;
            let w = format!(
                "the scenario never started: the plant stayed held (or pre-rolling) through the log's {truth_s:.3} s of ground truth; no metrics, no figures during the scenario"
            );
            s.incomplete.push(w.clone());
            s.warnings.push(w);
        }
        return None;
    };
    // From rest nothing moves until the driver's demand has reached the
    // motor: a driver who waits (the scenario's demand begins later) puts
    // the first movement that much after the start; not a car that moved
    // before the loop had any demand (a hill start rolling back: it moved
    // as the plant started)
    let moved_ns = log.truth.get(i0 + 1).map_or(u64::MAX, |g| g.stamp_ns);
    let demanded_before = log
        .cycles
        .iter()
        .find(|c| c.demand.is_finite() && c.demand > 0.0)
        .is_some_and(|c| c.stamp_ns <= moved_ns);
    let i0 = match scenario_demand_begins(log) {
        Some(wait)
            if wait > 0.0
                && demanded_before
                && log.truth[0].v == 0.0
                && log.truth[0].omega == 0.0 =>
        {
            let at = log.truth[i0]
                .stamp_ns
                .saturating_sub((wait * 1e9).round() as u64);
            log.truth[..i0]
                .partition_point(|g| g.stamp_ns <= at)
                .saturating_sub(1)
        }
        _ => i0,
    };
    let start_ns = log.truth[i0].stamp_ns;
    let end_ns = s
        .scenario_duration_s
        .map_or(u64::MAX, |d| start_ns.saturating_add((d * 1e9) as u64));
    let mut acc = MetricsAccumulator::new(vehicle);
    // the largest true |λ| and when (the first of equals)
    let mut max_slip = (f64::NEG_INFINITY, f64::NAN);
    let mut last_in = i0;
    // The command in force at each truth sample: the latest cycle record
    // stamped at or before it, from the first cycle in the window at which
    // the loop had the driver's demand (above `DEMAND_MIN_NM`) on; NaN
    // before (the command's figures skip those samples). The demand reaches
    // the loop a few ms after the plant starts, and the cycles before carry
    // the pre-start command (0): counting them would add the pedal's step
    // to the command's variation, which `grip sim` (whose controller has
    // the demand from its first cycle) does not see.
    let mut next_cycle = 0usize;
    let mut cmd = f64::NAN;
    let mut cmd_from: Option<u64> = None;
    let max_hold = TRUTH_PERIOD_NS * TRUTH_MAX_HOLD_PERIODS;
    for k in i0..log.truth.len() {
        let g = &log.truth[k];
        if g.stamp_ns >= end_ns {
            break;
        }
        while let Some(c) = log.cycles.get(next_cycle)
            && c.stamp_ns <= g.stamp_ns
        {
            if cmd_from.is_none()
                && c.stamp_ns >= start_ns
                && c.demand.is_finite()
                && c.demand > measured::DEMAND_MIN_NM
            {
                cmd_from = Some(c.stamp_ns);
            }
            if cmd_from.is_some() {
                cmd = c.torque_cmd;
            }
            next_cycle += 1;
        }
        // a sample holds until the next one, at most `max_hold` (a longer
        // hole in the stream is time the metrics do not cover), and not
        // past the scenario's end
        let next = log
            .truth
            .get(k + 1)
            .map_or(g.stamp_ns.saturating_add(TRUTH_PERIOD_NS), |n| {
                n.stamp_ns.min(g.stamp_ns.saturating_add(max_hold))
            });
        let next = next.min(end_ns);
        if g.lambda.abs() > max_slip.0 {
            max_slip = (g.lambda.abs(), secs_between(start_ns, g.stamp_ns));
        }
        acc.push(&Sample {
            dt: next.saturating_sub(g.stamp_ns) as f64 * 1e-9,
            lambda: g.lambda,
            torque: g.torque,
            omega: g.omega,
            v: g.v,
            torque_cmd: cmd,
        });
        last_in = k;
    }
    s.metrics = Some(acc.finish());
    s.max_slip = max_slip.1.is_finite().then_some(max_slip);
    s.cmd_from_s = cmd_from.map(|t| secs_between(start_ns, t));
    let last_ns = log.truth[last_in].stamp_ns;
    let w_end = end_ns.min(last_ns.saturating_add(TRUTH_PERIOD_NS));
    s.window = Some((rel(start_ns), rel(w_end)));
    s.window_ns = Some((start_ns, w_end));
    s.speed_kmh = Some((log.truth[i0].v * 3.6, log.truth[last_in].v * 3.6));
    let span_s = secs_between(start_ns, w_end);
    // holes in the ground truth inside the window (a damaged part of the
    // file skipped, samples lost): a sample holds for at most `GAP_S`
    // (five plant periods, the rule of the measured section), so each
    // hole's time beyond that is time the metrics do not see
    let (mut gaps_s, mut longest) = (0.0, (0.0, 0.0));
    for p in log.truth[i0..=last_in].windows(2) {
        let dt = secs_between(p[0].stamp_ns, p[1].stamp_ns);
        if dt > GAP_S {
            gaps_s += dt - GAP_S;
            if dt > longest.0 {
                longest = (dt, secs_between(start_ns, p[0].stamp_ns));
            }
        }
    }
    let incomplete_log = log.report.truncated.is_some() || !log_finished(log);
    // A complete live drive misses a few samples where plant-sim's timer
    // skipped periods (a scheduling pause of a few ms: the samples were
    // never made, the log lost nothing; the sample count shows them): such
    // gaps, up to `SMALL_GAPS_S` in all, do not make the metrics partial.
    // In a damaged or unfinished log, or beyond that, they do.
    if !incomplete_log && gaps_s <= SMALL_GAPS_S {
        gaps_s = 0.0;
    }
    let covered_s = span_s - gaps_s;
    let gap_words = (gaps_s > 0.0).then(|| {
        format!(
            "the ground truth has gaps of {gaps_s:.3} s in all in the window (the longest {:.3} s, {:.3} s after the start)",
            longest.0, longest.1
        )
    });
    s.window_status = match s.scenario_duration_s {
        None => {
            s.warnings.push(format!(
                "the scenario's duration is unknown (no grip.run scenario_duration_s, no attached {}): the scenario window runs to the end of the ground truth ({span_s:.3} s)",
                scenario_attachment(log).unwrap_or_else(|| "scenario file".to_owned())
            ));
            if let Some(g) = gap_words {
                s.incomplete.push(g.clone());
                s.warnings.push(g);
            }
            WindowStatus::DurationUnknown
        }
        Some(d) if covered_s < d - COVER_TOL_S => {
            let mut why = Vec::new();
            if span_s < d - COVER_TOL_S {
                why.push(format!(
                    "the ground truth ends {:.3} s before the scenario's end",
                    d - span_s
                ));
            }
            why.extend(gap_words);
            let w = format!(
                "metrics cover {covered_s:.3} of {d:.3} s of the scenario: {}{}",
                why.join("; "),
                if incomplete_log {
                    " (the log is incomplete)"
                } else {
                    ""
                }
            );
            s.incomplete.push(w.clone());
            s.warnings.push(w);
            WindowStatus::Partial {
                covered_s,
                duration_s: d,
            }
        }
        Some(_) => WindowStatus::Complete,
    };
    Some(Window {
        i0,
        last_in,
        start_ns,
        end_ns: w_end,
    })
}

fn us(ns: i64) -> String {
    format!("{:.1}", ns as f64 / 1e3)
}

/// Text histogram of wake-up latencies (µs buckets, log-spaced).
pub fn latency_histogram(lat_ns: &[i64]) -> String {
    const EDGES_US: [i64; 11] = [0, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10_000];
    let mut counts = [0u64; 11];
    for &l in lat_ns {
        let u = l / 1000;
        let i = EDGES_US.iter().rposition(|&e| u >= e).unwrap_or(0);
        counts[i] += 1;
    }
    let max = counts.iter().copied().max().unwrap_or(0).max(1);
    let mut out = String::new();
    for (i, &c) in counts.iter().enumerate() {
        let label = if i + 1 < EDGES_US.len() {
            format!("{:>6}-{:<6}", EDGES_US[i], EDGES_US[i + 1])
        } else {
            format!("{:>6}+      ", EDGES_US[i])
        };
        // log-ish bar so rare outliers stay visible
        let bar = if c == 0 {
            0
        } else {
            1 + ((c as f64).ln() / (max as f64).ln().max(1e-9) * 49.0) as usize
        };
        let _ = writeln!(out, "  {label} µs {c:>8} {}", "#".repeat(bar));
    }
    out
}

impl Summary {
    /// The printed report.
    pub fn render(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "drive log {}", self.file);
        if !self.run.is_empty() {
            let parts: Vec<String> = self.run.iter().map(|(k, v)| format!("{k}={v}")).collect();
            let _ = writeln!(o, "  {}", parts.join("  "));
        }
        if let Some(r) = &self.replay {
            let _ = writeln!(
                o,
                "  {}: written by grip replay --out, not by the recorder (no grip.recorder summary; grip.run is the source's){}",
                r.headline(),
                if r.open_loop() {
                    "; the ground truth, and so the metrics, are the source drive's, not a consequence of the replayed commands"
                } else {
                    ""
                }
            );
            let _ = writeln!(
                o,
                "  replay configuration: {}; changes: {}",
                if r.configuration.is_empty() {
                    "?"
                } else {
                    &r.configuration
                },
                if r.changes.is_empty() {
                    "none"
                } else {
                    &r.changes
                }
            );
            if let Some(l) = r.vehicle_line(&self.vehicle, self.vehicle_sha256.as_ref()) {
                let _ = writeln!(o, "  {l}");
            }
        }
        match &self.model {
            Some(m) => {
                let _ = writeln!(o, "  model: {}", m.line());
            }
            None => {
                let _ = writeln!(
                    o,
                    "  model: - (the log carries no arte-svc.toml naming a model)"
                );
            }
        }
        for w in &self.warnings {
            let _ = writeln!(o, "  WARNING: {w}");
        }

        let _ = writeln!(
            o,
            "\nmessages per topic (recorder: received / written / dropped in its queue)"
        );
        for t in &self.topics {
            let gaps = match (t.seq_gaps, t.seq_resets) {
                (Some(g), Some(r)) => format!("seq gaps {g:<5} restarts {r:<3}"),
                (Some(g), None) => format!("counter gaps {g:<13}"),
                _ => "(no sequence number)      ".to_owned(),
            };
            let rec = t.recorder.map_or_else(
                || "recorder: -".to_owned(),
                |(r, w, d)| format!("recorder: {r} / {w} / {d}"),
            );
            let _ = writeln!(o, "  {:<20} {:>9}  {gaps}  {rec}", t.topic, t.in_log);
        }

        let tm = &self.timing;
        let _ = writeln!(
            o,
            "\ncontrol loop timing ({} cycles, period {} µs)",
            tm.cycles,
            us(tm.period_ns)
        );
        let lat = |o: &mut String, label: &str, p: &Percentiles| {
            let _ = writeln!(
                o,
                "    {label:<17}p50 {} µs  p99 {} µs  p99.9 {} µs  max {} µs",
                us(p.p50),
                us(p.p99),
                us(p.p999),
                us(p.max)
            );
        };
        match (&tm.in_scenario, self.window) {
            (Some(w), Some((t0, t1))) => {
                let _ = writeln!(
                    o,
                    "  during the scenario ({} cycles, {t0:.3}-{t1:.3} s of the truth stream):",
                    w.cycles
                );
                lat(&mut o, "wake-up latency", &w.wakeup);
                lat(&mut o, "compute time", &w.compute);
                let _ = writeln!(
                    o,
                    "    deadline misses {}   cycles in safe state {}   safe-state entries {}",
                    w.deadline_misses,
                    self.safe_cycles_in_window.unwrap_or(0),
                    w.safe_entries
                );
                if let Some(c) = &self.control {
                    let _ = writeln!(o, "    control: {}", c.line());
                }
            }
            _ => {
                let _ = writeln!(
                    o,
                    "  during the scenario: - ({})",
                    self.window_status
                        .no_window_reason()
                        .unwrap_or("no scenario window")
                );
            }
        }
        let _ = writeln!(
            o,
            "  whole log (incl. start-up before the scenario and the stop after it):"
        );
        lat(&mut o, "wake-up latency", &tm.wakeup);
        lat(&mut o, "compute time", &tm.compute);
        let _ = writeln!(
            o,
            "    deadline misses {}   cycles in safe state {}   safe-state entries {}",
            tm.deadline_misses, tm.safe_cycles, tm.safe_entries
        );

        if let (Some(m), Some((t0, t1))) = (&self.metrics, self.window) {
            let _ = writeln!(
                o,
                "\nmetrics (grip_tcs::metrics, ground truth, scenario window {t0:.3}-{t1:.3} s of the truth stream)"
            );
            match self.window_status {
                WindowStatus::Partial {
                    covered_s,
                    duration_s,
                } => {
                    let _ = writeln!(
                        o,
                        "  PARTIAL: these cover {covered_s:.3} of the scenario's {duration_s:.3} s (see the warning above)"
                    );
                }
                WindowStatus::DurationUnknown => {
                    let _ = writeln!(
                        o,
                        "  the scenario's duration is unknown: the window runs to the end of the ground truth"
                    );
                }
                _ => {}
            }
            let n = |x: f64, p: usize| {
                if x.is_finite() {
                    format!("{x:.p$}")
                } else {
                    "none".to_owned()
                }
            };
            let _ = writeln!(
                o,
                "  slip deviation (1/T)∫|λ|dt      {}",
                n(m.slip_deviation, 4)
            );
            if let Some((l, t)) = self.max_slip {
                let _ = writeln!(o, "  max slip |λ|                    {l:.4} at {t:.3} s");
            }
            let _ = writeln!(
                o,
                "  max torque                      {} N m",
                n(m.max_torque, 2)
            );
            let _ = writeln!(
                o,
                "  torque effort (normalised area) {} N m",
                n(m.torque_effort, 2)
            );
            let _ = writeln!(
                o,
                "  mean acceleration               {} m/s²",
                n(m.mean_accel, 3)
            );
            let _ = writeln!(
                o,
                "  command total variation Σ|ΔT*|/T {} N m/s",
                n(m.cmd_tv_per_s, 0)
            );
            let _ = writeln!(
                o,
                "  command above 20 Hz (RMS, share) {} N m, {} of its variance",
                n(m.cmd_hf_rms, 2),
                n(m.cmd_hf_share, 3)
            );
            let _ = writeln!(
                o,
                "  (the command's figures from {}: the first cycle in the window with the driver's demand above {} N m)",
                self.cmd_from_s
                    .map_or("- (no such cycle)".to_owned(), |t| format!("{t:.3} s")),
                measured::DEMAND_MIN_NM
            );
            let _ = writeln!(o, "  distance                        {:.2} m", m.distance);
            let _ = writeln!(o, "  energy ∫Tω dt                   {:.1} J", m.energy);
            let _ = writeln!(
                o,
                "  kinetic energy gained           {:.1} J",
                m.kinetic_energy_gain
            );
            if let Some((a, b)) = self.speed_kmh {
                let _ = writeln!(o, "  speed                           {a:.1} -> {b:.1} km/h");
            }
            let _ = writeln!(
                o,
                "  duration {:.3} s, {} samples ({} rejected)",
                m.duration, m.samples, m.rejected
            );
            let _ = writeln!(o, "  vehicle: {}", self.vehicle);
            let vp = &self.vehicle_params;
            let _ = writeln!(
                o,
                "  torques, ∫Tω dt and ΔKE are one driven wheel's (torque at the wheel, after the gear; ΔKE of its share M / n_driven = {:.0} kg): the car's are {} times these",
                vp.mass_share(),
                vp.n_driven
            );
        } else {
            let _ = writeln!(
                o,
                "\nmetrics: none ({}; the loop's own measurements follow)",
                self.window_status
                    .no_window_reason()
                    .unwrap_or("no scenario window")
            );
        }
        o.push_str(&self.measured.render());

        let _ = writeln!(
            o,
            "\nCAN frames (logged by tcs-loop; bus: {})",
            self.can.bus
        );
        for ((name, id, dir), n) in &self.can.frames {
            let _ = writeln!(o, "  {name:<14} 0x{id:03X} {dir}  {n:>8}");
        }
        let fmt_f = |f: &E2eFaults| {
            format!(
                "crc {} repeated {} skipped {} length {} unknown id {} timeouts {}",
                f.crc, f.counter_repeated, f.counter_skipped, f.length, f.unknown_id, f.timeout
            )
        };
        let _ = writeln!(
            o,
            "  frames rejected by the E2E check: {}",
            self.can.rejected
        );
        if let Some(w) = &self.can.faults_in_window {
            let _ = writeln!(o, "  loop fault counters during the scenario: {}", fmt_f(w));
        }
        let _ = writeln!(
            o,
            "  loop fault counters, whole log (incl. start-up and after plant-sim stopped): {}",
            fmt_f(&self.can.faults)
        );
        o.push_str(&self.inverter.render());

        let a = &self.arte;
        let _ = writeln!(
            o,
            "\nARTE ({} estimates; judged against the road at the microphone at each frame's midpoint)",
            a.estimates
        );
        if a.log_judged > 0
            && let Some(l) = self.audio.as_ref().and_then(AudioSource::line)
        {
            let _ = writeln!(o, "  {l}");
        }
        if a.estimates > 0
            && let Some(sp) = &self.training_speeds
        {
            for l in sp.lines() {
                let _ = writeln!(o, "  {l}");
            }
        }
        if a.judged > 0 {
            let _ = writeln!(
                o,
                "  accuracy during the scenario {:.1} % ({}/{} frames with their midpoint in the scenario window)",
                100.0 * a.accuracy(),
                a.correct,
                a.judged
            );
            for (road, (n, c)) in &a.per_road {
                let no_class = self
                    .model_classes
                    .as_ref()
                    .filter(|cl| !cl.iter().any(|x| x == road))
                    .map(|cl| {
                        format!(
                            "arte's model has no class for it (its classes: {}), so it is never estimated right",
                            cl.join(", ")
                        )
                    });
                let sound = self.audio.as_ref().and_then(|au| au.road_note(road));
                let note = match (no_class, sound) {
                    (Some(a), Some(b)) => format!(": {a}; {b}"),
                    (Some(x), None) | (None, Some(x)) => format!(": {x}"),
                    (None, None) => String::new(),
                };
                let _ = writeln!(
                    o,
                    "    {road:<12} recall {:.1} % ({c}/{n}){note}",
                    100.0 * *c as f64 / *n as f64
                );
            }
        } else if a.log_judged > 0 {
            let _ = writeln!(
                o,
                "  accuracy during the scenario: - ({})",
                self.window_status
                    .no_window_reason()
                    .unwrap_or("no frame in the scenario window")
            );
        }
        if a.log_judged > 0 {
            let _ = writeln!(
                o,
                "  accuracy over the whole log {:.1} % ({}/{} frames with ground truth at their midpoint, incl. the hold, pre-roll and stop)",
                100.0 * a.accuracy_whole_log(),
                a.log_correct,
                a.log_judged
            );
        }
        if !a.changes.is_empty() {
            let (gate, _) = a.min_confidence;
            let _ = writeln!(
                o,
                "  road changes at the microphone, and the first estimate naming the new road (then the first at confidence >= {gate}, the loop's gate{}):",
                match a.gate_from {
                    GateFrom::Log => ", from the log's controllers.toml",
                    GateFrom::Default =>
                        ": the log carries no controllers.toml [arte] min_confidence, its default",
                    GateFrom::Replay =>
                        ", the one the replay's tcs-loop ran (its grip.replay record; the log's controllers.toml is the source drive's)",
                    GateFrom::ReplayChanged =>
                        ", from the log's controllers.toml, the source drive's: the replay changed the gate or its configuration (its changes above), and this log, written before grip replay recorded the gate it ran, does not say which it ran",
                    GateFrom::Unknown =>
                        ": the log's controllers.toml does not read as TOML or its [arte] min_confidence is no number in [0, 1], so the gate is unknown; its default",
                }
            );
        }
        for c in &a.changes {
            let d = match (c.delay, c.gated_delay) {
                (None, _) => "not detected before the next change".to_owned(),
                (Some(d), Some(g)) if g == d => format!("detected after {d:.3} s"),
                (Some(d), Some(g)) => {
                    format!("detected after {d:.3} s, past the gate after {g:.3} s")
                }
                (Some(d), None) => {
                    format!("detected after {d:.3} s, never past the gate before the next change")
                }
            };
            let _ = writeln!(o, "  change at {:.3} s {} -> {}: {d}", c.t, c.from, c.to);
        }
        if a.active_cycles > 0 {
            let pc = |n: u64| 100.0 * n as f64 / a.active_cycles as f64;
            let _ = writeln!(
                o,
                "  of the active {} ({}):",
                if a.used_in_demand_window {
                    format!(
                        "cycles of the time the driver demanded more than {} N m (no scenario window; the measured section's window)",
                        measured::DEMAND_MIN_NM
                    )
                } else {
                    "scenario cycles".to_owned()
                },
                a.active_cycles
            );
            let _ = writeln!(
                o,
                "    the road belief was usable in {:.1} % ({}; the cycle record's used_arte: a decision within [arte] max_age_s and the belief's probability at or above min_confidence)",
                pc(a.used_cycles),
                a.used_cycles
            );
            let _ = writeln!(
                o,
                "    road knowledge's torque cap held the command below the driver's demand in {:.1} % ({}; the cap acts through the road belief, gate or not)",
                pc(a.capped_cycles),
                a.capped_cycles
            );
        }
        if let Some(p) = &self.preview {
            let _ = writeln!(
                o,
                "\npreview (the driven wheel reaching a road that carries less; limit = that road's μ_peak · N · r)"
            );
            if let Some(f) = &self.roads_from {
                let _ = writeln!(o, "  road catalogue: {f}");
            }
            if p.is_empty() {
                let _ = writeln!(o, "  no such road change in the scenario window");
            }
            for e in p {
                let _ = writeln!(o, "  {}", e.line());
            }
        }
        if let Some(r) = self.releases.as_ref().filter(|r| !r.is_empty()) {
            let _ = writeln!(
                o,
                "release (the driven wheel reaching a road that carries more; limit = the road it left's μ_peak · N · r)"
            );
            for e in r {
                let _ = writeln!(o, "  {}", e.line());
            }
        }
        o
    }
}

/// The `A / B` cell of `grip inspect A B`: `0.150x`; `A is 0` where A's
/// figure is 0 and B's is not (a ratio `0.000x` read as a measured factor,
/// when A simply has none: no spin event, no energy), `B is 0` the other
/// way (no ratio), `both 0`; `-` where either is missing.
pub fn ratio_cell(a: f64, b: f64) -> String {
    if !(a.is_finite() && b.is_finite()) {
        "-".to_owned()
    } else if a == 0.0 && b == 0.0 {
        "both 0".to_owned()
    } else if a == 0.0 {
        "A is 0".to_owned()
    } else if b == 0.0 {
        "B is 0".to_owned()
    } else {
        format!("{:.3}x", a / b)
    }
}

/// The first 12 hex digits of a SHA-256, or `-`.
pub fn short_sha(h: Option<&String>) -> String {
    h.map_or("-".to_owned(), |h| h.chars().take(12).collect())
}

/// Why the two drives' figures do not compare like for like: different
/// scenarios (name or file), vehicles (file or parameters), window
/// lengths, a side that is not a complete drive or lost control, or
/// inverters that faulted or derated differently during the scenario
/// ([`inverter::comparability`]).
pub fn comparability(a: &Summary, b: &Summary) -> Vec<String> {
    let mut w = Vec::new();
    let scen = |s: &Summary| {
        format!(
            "{} (sha256 {})",
            s.scenario.as_deref().unwrap_or("?"),
            short_sha(s.scenario_sha256.as_ref())
        )
    };
    let hashes_differ =
        |x: &Option<String>, y: &Option<String>| matches!((x, y), (Some(x), Some(y)) if x != y);
    if a.scenario != b.scenario || hashes_differ(&a.scenario_sha256, &b.scenario_sha256) {
        w.push(format!(
            "the scenarios differ: A {}, B {}",
            scen(a),
            scen(b)
        ));
    }
    let veh_differ = match (&a.vehicle_sha256, &b.vehicle_sha256) {
        (Some(x), Some(y)) => x != y,
        _ => a.vehicle_params != b.vehicle_params,
    };
    if veh_differ {
        w.push(format!(
            "the vehicles differ: A {} (sha256 {}), B {} (sha256 {})",
            a.vehicle,
            short_sha(a.vehicle_sha256.as_ref()),
            b.vehicle,
            short_sha(b.vehicle_sha256.as_ref())
        ));
    }
    let len = |s: &Summary| s.window.map(|(t0, t1)| t1 - t0);
    if let (Some(x), Some(y)) = (len(a), len(b))
        && (x - y).abs() > COVER_TOL_S
    {
        w.push(format!("the metrics cover {x:.3} s in A and {y:.3} s in B"));
    }
    for (tag, s) in [("A", a), ("B", b)] {
        for r in &s.incomplete {
            w.push(format!("{tag} is not a complete drive: {r}"));
        }
        if let Some(c) = s.control.as_ref().filter(|c| c.lost()) {
            w.push(format!(
                "{tag}'s control loop lost control and did not regain it: {}",
                c.line()
            ));
        }
    }
    w.extend(inverter::comparability(&a.inverter, &b.inverter));
    w
}

/// Whether A and B ran different models (by SHA-256, else by name; a side
/// whose log does not say is not flagged).
pub fn models_differ(a: &Summary, b: &Summary) -> bool {
    match (&a.model, &b.model) {
        (Some(x), Some(y)) => match (&x.sha256, &y.sha256) {
            (Some(p), Some(q)) => p != q,
            _ => x.name != y.name,
        },
        _ => false,
    }
}

/// What `grip inspect A B` says of a side written by `grip replay --out`,
/// and of two different models: one line each.
pub fn replay_notes(a: &Summary, b: &Summary) -> Vec<String> {
    let mut n = Vec::new();
    for (tag, s) in [("A", a), ("B", b)] {
        let Some(r) = &s.replay else { continue };
        if r.open_loop() {
            n.push(format!(
                "{tag} is a {}: its ground truth is the source drive's, copied, so its plant metrics (slip deviation to final speed, and the preview's slip and motor torque) are the source's, not a consequence of its replayed commands; its torque commands, safe-state cycles and ARTE accuracy are the replay's",
                r.headline()
            ));
        } else {
            n.push(format!(
                "{tag} is a {}: the plant was re-simulated with the replayed commands; its loop timing is carried over from the source",
                r.headline()
            ));
        }
    }
    if models_differ(a, b) {
        let m = |s: &Summary| s.model.as_ref().map_or("-".to_owned(), ModelInfo::line);
        n.push(format!(
            "A and B ran different models: A {}, B {}",
            m(a),
            m(b)
        ));
    }
    n
}

/// `grip inspect A B`: the two drives' metrics side by side with A / B
/// (`grip inspect on.mcap off.mcap`: what ARTE changed), the inverter's
/// episodes and FaultCodes ([`inverter::compare_rows`]), then each one's
/// preview events. A warning heads the table when the two are not
/// comparable ([`comparability`]); each side's warnings follow it.
pub fn compare(a: &Summary, b: &Summary) -> String {
    let mut o = String::new();
    let run = |s: &Summary, k: &str| {
        s.run
            .iter()
            .find(|(kk, _)| kk == k)
            .map_or("-".to_owned(), |(_, v)| v.clone())
    };
    let _ = writeln!(
        o,
        "A: {}
B: {}",
        a.file, b.file
    );
    let issues = comparability(a, b);
    if !issues.is_empty() {
        let _ = writeln!(
            o,
            "WARNING: A and B are not comparable as they stand; the ratios below compare unlike drives:"
        );
        for i in &issues {
            let _ = writeln!(o, "  - {i}");
        }
    }
    for n in replay_notes(a, b) {
        let _ = writeln!(o, "NOTE: {n}");
    }
    let _ = writeln!(o, "{:<34} {:>12} {:>12} {:>8}", "", "A", "B", "A / B");
    for k in ["scenario", "controller", "arte", "seed"] {
        let _ = writeln!(o, "{k:<34} {:>12} {:>12}", run(a, k), run(b, k));
    }
    let _ = writeln!(
        o,
        "{:<34} {:>12} {:>12}",
        "scenario file (sha256)",
        short_sha(a.scenario_sha256.as_ref()),
        short_sha(b.scenario_sha256.as_ref())
    );
    let _ = writeln!(
        o,
        "{:<34} {:>12} {:>12}",
        "vehicle file (sha256)",
        short_sha(a.vehicle_sha256.as_ref()),
        short_sha(b.vehicle_sha256.as_ref())
    );
    let model_sha = |s: &Summary| short_sha(s.model.as_ref().and_then(|m| m.sha256.as_ref()));
    let row = format!(
        "{:<34} {:>12} {:>12} {:>8}",
        "model (sha256)",
        model_sha(a),
        model_sha(b),
        if models_differ(a, b) { "DIFFER" } else { "" }
    );
    let _ = writeln!(o, "{}", row.trim_end());
    let win = |s: &Summary| {
        s.window
            .map_or("-".to_owned(), |(t0, t1)| format!("{:.3}", t1 - t0))
    };
    let dur = |s: &Summary| {
        s.scenario_duration_s
            .map_or("-".to_owned(), |d| format!("{d:.3}"))
    };
    let _ = writeln!(
        o,
        "{:<34} {:>12} {:>12}",
        "scenario window (s) / duration (s)",
        format!("{} / {}", win(a), dur(a)),
        format!("{} / {}", win(b), dur(b))
    );
    let missing: Vec<String> = [("A", a), ("B", b)]
        .into_iter()
        .filter(|(_, s)| s.metrics.is_none())
        .map(|(tag, s)| {
            format!(
                "{tag} ({})",
                s.window_status
                    .no_window_reason()
                    .unwrap_or("no scenario window")
            )
        })
        .collect();
    if let (Some(ma), Some(mb)) = (&a.metrics, &b.metrics) {
        let rows: [(&str, f64, f64, &str); 8] = [
            (
                "slip deviation (1/T)∫|λ|dt",
                ma.slip_deviation,
                mb.slip_deviation,
                "{:.4}",
            ),
            (
                "mean acceleration (m/s²)",
                ma.mean_accel,
                mb.mean_accel,
                "{:.3}",
            ),
            ("max torque (N m)", ma.max_torque, mb.max_torque, "{:.1}"),
            (
                "torque effort (N m)",
                ma.torque_effort,
                mb.torque_effort,
                "{:.1}",
            ),
            ("distance (m)", ma.distance, mb.distance, "{:.2}"),
            ("energy ∫Tω dt (J)", ma.energy, mb.energy, "{:.0}"),
            (
                "kinetic energy gained (J)",
                ma.kinetic_energy_gain,
                mb.kinetic_energy_gain,
                "{:.0}",
            ),
            (
                "final speed (km/h)",
                a.speed_kmh.map_or(f64::NAN, |v| v.1),
                b.speed_kmh.map_or(f64::NAN, |v| v.1),
                "{:.2}",
            ),
        ];
        for (name, x, y, fmt) in rows {
            let f = |v: f64| match fmt {
                _ if !v.is_finite() => "-".to_owned(),
                "{:.4}" => format!("{v:.4}"),
                "{:.3}" => format!("{v:.3}"),
                "{:.2}" => format!("{v:.2}"),
                "{:.1}" => format!("{v:.1}"),
                _ => format!("{v:.0}"),
            };
            let ratio = ratio_cell(x, y);
            let _ = writeln!(o, "{name:<34} {:>12} {:>12} {ratio:>8}", f(x), f(y));
        }
    } else {
        let _ = writeln!(
            o,
            "(no ground-truth metrics in {}: nothing to compare)",
            missing.join(" and ")
        );
    }
    o.push_str(&measured::compare_rows(&a.measured, &b.measured));
    let safe = |s: &Summary| {
        s.safe_cycles_in_window
            .map_or("-".to_owned(), |n| n.to_string())
    };
    let _ = writeln!(
        o,
        "{:<34} {:>12} {:>12}",
        "safe-state cycles in the scenario",
        safe(a),
        safe(b)
    );
    let misses = |s: &Summary| {
        s.timing
            .in_scenario
            .as_ref()
            .map_or("-".to_owned(), |w| w.deadline_misses.to_string())
    };
    let _ = writeln!(
        o,
        "{:<34} {:>12} {:>12}",
        "deadline misses in the scenario",
        misses(a),
        misses(b)
    );
    let acc = |s: &Summary| {
        let x = s.arte.accuracy();
        if x.is_finite() {
            format!("{:.1}", 100.0 * x)
        } else {
            "-".to_owned()
        }
    };
    let _ = writeln!(
        o,
        "{:<34} {:>12} {:>12}",
        "ARTE accuracy in the scenario (%)",
        acc(a),
        acc(b)
    );
    o.push_str(&inverter::compare_rows(&a.inverter, &b.inverter));
    let _ = writeln!(
        o,
        "vehicle A: {} (sha256 {})
vehicle B: {} (sha256 {})",
        a.vehicle,
        short_sha(a.vehicle_sha256.as_ref()),
        b.vehicle,
        short_sha(b.vehicle_sha256.as_ref())
    );
    let model = |s: &Summary| s.model.as_ref().map_or("-".to_owned(), ModelInfo::line);
    let _ = writeln!(o, "model A: {}\nmodel B: {}", model(a), model(b));
    for (tag, s) in [("A", a), ("B", b)] {
        if !s.warnings.is_empty() {
            let _ = writeln!(o, "warnings {tag}:");
            for w in &s.warnings {
                let _ = writeln!(o, "  {w}");
            }
        }
    }
    for (tag, s) in [("A", a), ("B", b)] {
        if let Some(p) = &s.preview {
            let _ = writeln!(
                o,
                "preview {tag} (the driven wheel reaching a road that carries less; limit = μ_peak · N · r):"
            );
            for e in p {
                let _ = writeln!(o, "  {}", e.line());
            }
        }
        if let Some(r) = s.releases.as_ref().filter(|r| !r.is_empty()) {
            let _ = writeln!(
                o,
                "release {tag} (the driven wheel reaching a road that carries more; limit = the road it left's μ_peak · N · r):"
            );
            for e in r {
                let _ = writeln!(o, "  {}", e.line());
            }
        }
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A log whose DBC gives `OmegaDriven` 8 bits (±1.27 rad/s, found in a
    /// newcomer's trial: the drive passed "in control" at 4.4 times the
    /// slip): the summary warns, names the DBC and counts the received
    /// frames that held the signal at its limit; the shipped DBC gives no
    /// such line.
    #[test]
    fn a_signal_the_bus_cannot_carry_is_counted_at_its_limit() {
        use grip_io::can::protocol::{MsgKind, WheelSpeeds, encode_in};
        let shipped = include_str!("../../../config/inverter.dbc");
        let log_with = |dbc: String, omegas: &[f64]| {
            let mut log = DriveLog::default();
            log.attachments.insert(
                "can.toml".into(),
                b"transport = \"sim\"\ninterface = \"vcan0\"\ndbc = \"car.dbc\"\n".to_vec(),
            );
            log.attachments.insert("car.dbc".into(), dbc.into_bytes());
            let p = log.protocol().unwrap();
            for (k, &w) in omegas.iter().enumerate() {
                let m = WheelSpeeds {
                    driven_valid: true,
                    ref_valid: true,
                    omega_driven: w,
                    omega_ref: 1.0,
                };
                let mut f = encode_in(
                    p.spec(MsgKind::WheelSpeeds),
                    &m,
                    (k & 15) as u8,
                    k as u64 * 1_000_000,
                );
                f.direction = can_dir::RX;
                log.can.push(f);
            }
            log
        };
        let short = shipped.replacen(
            "OmegaDriven : 16|16@1- (0.01,0) [-327.68|327.67]",
            "OmegaDriven : 16|8@1- (0.01,0) [-1.28|1.27]",
            1,
        );
        assert_ne!(short, shipped);
        // 1.0 rad/s fits; 5 and 40 rad/s are read as 1.27
        let log = log_with(short.clone(), &[1.0, 5.0, 40.0, 1.27, 0.5]);
        let v = VehicleParams::default();
        let s = summarize(&log, &v, "test", None);
        assert_eq!(s.can.short.len(), 1, "{:?}", s.can.short);
        let sh = &s.can.short[0];
        assert_eq!(sh.name, "WheelSpeeds.OmegaDriven");
        assert_eq!((sh.frames, sh.at_limit, sh.in_window), (5, 3, false));
        assert!(
            sh.warning
                .starts_with("car.dbc: WheelSpeeds.OmegaDriven carries at most 1.27 rad/s"),
            "{}",
            sh.warning
        );
        let line = s
            .warnings
            .iter()
            .find(|w| w.contains("bus cannot carry"))
            .expect("a warning");
        assert!(
            line.contains("it sat at that limit in 3 of the 5 frames received in the log"),
            "{line}"
        );
        assert!(s.render().contains(line.as_str()));
        // never at the limit: said, not counted as saturated
        let calm = summarize(&log_with(short, &[1.0, 0.5]), &v, "test", None);
        assert_eq!(calm.can.short[0].at_limit, 0);
        assert!(
            calm.can.short[0]
                .line()
                .contains("it never reached that limit in the 2 frames")
        );
        // the shipped DBC: nothing to say, whatever the wheel does
        let fine = summarize(
            &log_with(shipped.to_owned(), &[1.0, 40.0]),
            &v,
            "test",
            None,
        );
        assert!(fine.can.short.is_empty(), "{:?}", fine.can.short);
    }

    #[test]
    fn percentiles_nearest_rank() {
        let mut v: Vec<i64> = (1..=1000).collect();
        let p = Percentiles::of(&mut v);
        assert_eq!((p.p50, p.p99, p.p999, p.max), (500, 990, 999, 1000));
        assert_eq!(Percentiles::of(&mut []), Percentiles::default());
    }

    #[test]
    fn gaps_and_restarts() {
        assert_eq!(seq_gaps([0, 1, 2, 3]), (0, 0));
        assert_eq!(seq_gaps([0, 2, 5, 0, 1]), (1 + 2, 1));
        // a damaged number: no 2^64 lost messages, a restart there and
        // one back (before: a gap of u64::MAX - 3, and an overflow panic
        // in a debug build at two of them)
        assert_eq!(seq_gaps([0, 1, 2, u64::MAX, 4, 5]), (0, 2));
        assert_eq!(seq_gaps([0, u64::MAX, 0, u64::MAX]), (0, 3));
        assert_eq!(seq_gaps([0, SEQ_GAP_MAX + 1]), (SEQ_GAP_MAX, 0));
        assert_eq!(seq_gaps([0, SEQ_GAP_MAX + 2]), (0, 1));
    }

    /// A ground-truth sample no plant makes is said as damage, naming it;
    /// a normal one is not.
    #[test]
    fn implausible_ground_truth_is_flagged() {
        let mut g = GroundTruth::zeroed();
        g.v = 10.0;
        g.lambda = -1.0;
        assert_eq!(implausible_truth(&g), None);
        g.v = -1e308;
        assert_eq!(implausible_truth(&g), Some(("v", -1e308, "m/s", 1000.0)));
        g.v = 1.0;
        g.x = f64::NAN;
        assert!(matches!(implausible_truth(&g), Some(("x", v, "m", _)) if v.is_nan()));
    }

    /// A road estimate `name` whose 20 ms frame ends at `t1_ms`, published
    /// 1 ns later.
    fn estimate_at(seq: u64, t1_ms: u64, name: &str) -> RoadEstimate {
        let mut e = RoadEstimate::zeroed();
        e.seq = seq;
        e.frame_t0_ns = (t1_ms - 20) * 1_000_000;
        e.frame_t1_ns = t1_ms * 1_000_000;
        e.stamp_ns = t1_ms * 1_000_000 + 1;
        e.class_index = 0;
        e.class_name = grip_msgs::name_to_bytes(name);
        e
    }

    fn truth(seq: u64, t_ms: u64, x: f64, road: u32, name: &str) -> GroundTruth {
        let mut g = GroundTruth::zeroed();
        g.seq = seq;
        g.stamp_ns = t_ms * 1_000_000;
        g.x = x;
        g.v = 3.0;
        g.omega = 10.0;
        g.road_index = road;
        g.road_name = grip_msgs::name_to_bytes(name);
        g.mic_road_index = road;
        g.mic_road_name = g.road_name;
        g
    }

    #[test]
    fn start_is_where_the_held_state_first_moves() {
        let mut t: Vec<GroundTruth> = (0..5).map(|k| truth(k, k, 0.0, 0, "asphalt")).collect();
        t.push(truth(5, 5, 0.003, 0, "asphalt"));
        assert_eq!(scenario_start(&t), Some(4));
        assert_eq!(scenario_start(&t[..5]), None);
        // a pre-roll: x rises from -0.012 m to 0 at the held speeds, then
        // the scenario moves the car beyond 0
        let mut p: Vec<GroundTruth> = (0..5)
            .map(|k| truth(k, k, -0.003 * (4 - k) as f64, 0, "asphalt"))
            .collect();
        assert_eq!(p[4].x, 0.0);
        p.push(truth(5, 5, 0.003, 0, "asphalt"));
        assert_eq!(scenario_start(&p), Some(4), "the sample at x = 0");
        assert_eq!(scenario_start(&p[..5]), None, "a pre-roll is no start");
        assert_eq!(truth_at(&t, 2_500_000).map(|g| g.seq), Some(2));
        assert!(truth_at(&t, 0).is_some());
    }

    /// 300 ms at 1 kHz: standing for 10 ms, then 3 mm a cycle, asphalt
    /// under the wheel until 110 ms and snow after; `each(k, truth,
    /// record)` sets the rest of sample k.
    fn snow_entry_log(mut each: impl FnMut(u64, &mut GroundTruth, &mut CycleRecord)) -> DriveLog {
        let mut t = Vec::new();
        let mut c = Vec::new();
        for k in 0..300u64 {
            let x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            let (r, n) = if k < 110 { (0, "asphalt") } else { (1, "snow") };
            let mut g = truth(k, k, x, r, n);
            let mut rec = CycleRecord::zeroed();
            rec.stamp_ns = k * 1_000_000;
            each(k, &mut g, &mut rec);
            t.push(g);
            c.push(rec);
        }
        DriveLog {
            truth: t,
            cycles: c,
            ..DriveLog::default()
        }
    }

    /// The wheel reaches snow at 100 ms: the command came down to snow's
    /// limit 30 ms before (at 0.003 m per ms: 0.09 m ahead) in the first
    /// log, never in the second; `compare` puts them side by side.
    #[test]
    fn preview_reports_how_far_ahead_the_torque_came_down() {
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let v = VehicleParams::default();
        let limit = roads[1].mu_peak() * v.normal_force() * v.r;
        let make = |capped: bool| {
            snow_entry_log(|k, g, rec| {
                g.lambda = if k >= 110 && !capped { 0.3 } else { 0.02 };
                g.torque = 150.0;
                rec.torque_cmd = if capped && (80..300).contains(&k) {
                    limit
                } else {
                    300.0
                };
            })
        };
        let s = summarize(&make(true), &v, "test", Some(&roads));
        let p = s.preview.as_ref().unwrap();
        assert_eq!(p.len(), 1, "{p:?}");
        let e = &p[0];
        assert_eq!((e.from.as_str(), e.to.as_str()), ("asphalt", "snow"));
        assert!((e.limit - limit).abs() < 1e-9);
        let (dt, dx) = e.ahead.unwrap();
        assert!((dt - 0.030).abs() < 1e-9, "{dt}");
        assert!((dx - 0.090).abs() < 1e-9, "{dx}");
        assert_eq!(e.cmd_at_arrival, limit);
        assert!((e.max_slip_after - 0.02).abs() < 1e-12);
        assert!(
            s.render()
                .contains("0.030 s / 0.09 m before the wheel arrived")
        );
        let off = summarize(&make(false), &v, "test", Some(&roads));
        let q = &off.preview.as_ref().unwrap()[0];
        assert_eq!(q.ahead, None);
        assert!((q.max_slip_after - 0.3).abs() < 1e-12);
        assert!(!e.ahead_since_start);
        // A command under snow's limit from the first cycle on (the driver
        // asks less than snow carries): no drop was needed, and the report
        // says so instead of a lead longer than the drive.
        let mut low = make(true);
        for c in &mut low.cycles {
            c.torque_cmd = limit - 1.0;
        }
        let l = summarize(&low, &v, "test", Some(&roads));
        let e = &l.preview.as_ref().unwrap()[0];
        assert!(e.ahead_since_start, "{e:?}");
        assert!(
            l.render().contains("since the drive began"),
            "{}",
            l.render()
        );
        let c = compare(&s, &off);
        assert!(c.contains("A / B"), "{c}");
        assert!(c.contains("NOT at or below"), "{c}");
        // snow -> asphalt carries more: no event; no catalogue: no report
        assert!(summarize(&make(true), &v, "test", None).preview.is_none());
    }

    /// The wheel leaves snow for asphalt at k = 110 (0.101 s from the start):
    /// a command held at snow's limit until k = 150 is released 40 ms
    /// (0.12 m) after arrival and withheld (300 − limit) · 0.040 N m s in
    /// the next 0.2 s; a command that never came down was already above;
    /// a demand within snow's limit needed no release; one held to the
    /// window's end is said so. JSON-free: the figures and the lines.
    #[test]
    fn release_reports_how_long_the_old_road_s_limit_held_on_a_grippier_road() {
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let v = VehicleParams::default();
        let limit = roads[1].mu_peak() * v.normal_force() * v.r;
        let make = |held_until: u64, demand: f64| {
            snow_entry_log(|k, g, rec| {
                // snow first, then asphalt
                let (r, n) = if k < 110 { (1, "snow") } else { (0, "asphalt") };
                g.road_index = r;
                g.road_name = grip_msgs::name_to_bytes(n);
                g.mic_road_index = r;
                g.mic_road_name = g.road_name;
                rec.demand = demand;
                rec.torque_cmd = if k < held_until {
                    demand.min(limit)
                } else {
                    demand
                };
            })
        };
        let s = summarize(&make(150, 300.0), &v, "test", Some(&roads));
        assert!(s.preview.as_ref().unwrap().is_empty());
        let r = s.releases.as_ref().unwrap();
        assert_eq!(r.len(), 1, "{r:?}");
        let e = &r[0];
        assert_eq!((e.from.as_str(), e.to.as_str()), ("snow", "asphalt"));
        assert!((e.old_limit - limit).abs() < 1e-9);
        // from the scenario's start, the last held sample (k = 9)
        assert!((e.t - 0.101).abs() < 1e-9, "{e:?}");
        let Release::After(dt, dx) = e.after else {
            panic!("{e:?}")
        };
        assert!((dt - 0.040).abs() < 1e-9, "{dt}");
        assert!((dx - 0.120).abs() < 1e-9, "{dx}");
        assert!(
            (e.withheld_nms - (300.0 - limit) * 0.040).abs() < 1e-9,
            "{e:?}"
        );
        let text = s.render();
        assert!(
            text.contains("command rose above it 0.040 s / 0.12 m after the wheel arrived"),
            "{text}"
        );
        // never capped: already above at arrival, nothing withheld
        let a = summarize(&make(0, 300.0), &v, "test", Some(&roads));
        let e = &a.releases.as_ref().unwrap()[0];
        assert_eq!(e.after, Release::AlreadyAbove);
        assert_eq!(e.withheld_nms, 0.0);
        // the demand within snow's limit: nothing to release
        let n = summarize(&make(300, limit - 5.0), &v, "test", Some(&roads));
        assert_eq!(n.releases.as_ref().unwrap()[0].after, Release::NotNeeded);
        // held to the window's end (a truth period after the last sample, k = 299)
        let h = summarize(&make(300, 300.0), &v, "test", Some(&roads));
        let Release::Held(held) = h.releases.as_ref().unwrap()[0].after else {
            panic!("{:?}", h.releases)
        };
        assert!((held - 0.190).abs() < 1e-9, "{held}");
        // side by side
        let c = compare(&s, &a);
        assert!(c.contains("release A") && c.contains("release B"), "{c}");
        // a road that carries less is the preview's, not a release
        assert!(
            summarize(&make(300, 300.0), &v, "test", None)
                .releases
                .is_none()
        );
    }

    /// A user's log with messages out of time order (a truth sample and a
    /// cycle record stamped before the one logged before them): the times
    /// computed from them stay small and signed (no wrap to "18446744073.709
    /// s", no panic in a debug build), and a warning counts them per topic.
    #[test]
    fn messages_out_of_time_order_give_signed_times_and_a_warning() {
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let v = VehicleParams::default();
        let limit = roads[1].mu_peak() * v.normal_force() * v.r;
        let mut log = snow_entry_log(|k, g, rec| {
            if k >= 50 {
                // the microphone reaches snow at the sample logged 50th
                g.mic_road_index = 1;
                g.mic_road_name = grip_msgs::name_to_bytes("snow");
            }
            rec.seq = k;
            rec.torque_cmd = if k >= 80 { limit } else { 300.0 };
        });
        // stamped 5 ms, before the scenario's start (9 ms), logged after it
        log.truth[50].stamp_ns = 5_000_000;
        // the first capped cycle stamped after the wheel reaches snow (110 ms)
        log.cycles[80].stamp_ns = 150_000_000;
        let s = summarize(&log, &v, "test", Some(&roads));
        let ch = &s.arte.changes;
        assert_eq!(ch.len(), 1, "{ch:?}");
        assert!((ch[0].t + 0.004).abs() < 1e-9, "{ch:?}");
        let p = s.preview.as_ref().unwrap();
        assert_eq!(p.len(), 1, "{p:?}");
        assert!((p[0].t - 0.101).abs() < 1e-9, "{p:?}");
        let (dt, _) = p[0].ahead.unwrap();
        assert!((dt + 0.040).abs() < 1e-9, "{dt}");
        let w = s.warnings.join("\n");
        assert!(
            w.contains("messages out of time order")
                && w.contains("grip/tcs/cycle 1")
                && w.contains("grip/plant/truth 1")
                && !w.contains("grip/arte/road"),
            "{w}"
        );
        let r = s.render();
        assert!(r.contains("change at -0.004 s asphalt -> snow"), "{r}");
        assert!(!r.contains("18446744073"), "{r}");
        assert_eq!(out_of_time_order([1, 2, 2, 3]), 0);
        assert_eq!(out_of_time_order([3, 1, 2, 0]), 2);
    }

    /// A log of `grip replay --out` has no `grip.recorder` record: its
    /// `grip.replay` record stands for it (no crash warning, the replay's
    /// own controller shown), unless it says the replayed log's recorder
    /// did not finish.
    #[test]
    fn a_replay_log_is_not_a_crashed_recording() {
        let mut log = DriveLog::default();
        log.run.insert("controller".into(), "mtte".into());
        let mut m = BTreeMap::new();
        m.insert("source".into(), "drive.mcap".to_owned());
        m.insert("mode".into(), "open loop".to_owned());
        m.insert("controller".into(), "src".to_owned());
        m.insert("source_recorder_finished".into(), "true".to_owned());
        log.metadata.insert("grip.replay".into(), m.clone());
        let v = VehicleParams::default();
        let s = summarize(&log, &v, "test", None);
        assert!(s.incomplete.is_empty(), "{:?}", s.incomplete);
        let r = s.render();
        assert!(r.contains("replay of drive.mcap (open loop)"), "{r}");
        assert!(r.contains("controller=src"), "{r}");
        assert!(!r.contains("recorder did not finish"), "{r}");
        m.insert("source_recorder_finished".into(), "false".to_owned());
        log.metadata.insert("grip.replay".into(), m);
        let s = summarize(&log, &v, "test", None);
        assert!(
            s.incomplete
                .iter()
                .any(|w| w.contains("replayed log's recorder did not finish")),
            "{:?}",
            s.incomplete
        );
        // without either record: the recorder did not finish
        let s = summarize(&DriveLog::default(), &v, "test", None);
        assert!(
            s.warnings.iter().any(|w| w.contains("grip.recorder")),
            "{:?}",
            s.warnings
        );
    }

    #[test]
    fn arte_accuracy_and_change_delay() {
        // held 10 ms, then asphalt 100 ms, snow 100 ms
        let mut t = Vec::new();
        for k in 0..210u64 {
            let x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            let (r, n) = if k < 110 { (0, "asphalt") } else { (1, "snow") };
            t.push(truth(k, k, x, r, n));
        }
        let log = DriveLog {
            truth: t,
            roads: vec![
                estimate_at(0, 50, "asphalt"),
                estimate_at(1, 100, "snow"), // wrong (truth asphalt at 90 ms)
                estimate_at(2, 140, "asphalt"), // wrong (truth snow at 130 ms)
                estimate_at(3, 160, "snow"),
                estimate_at(4, 180, "snow"),
            ],
            ..DriveLog::default()
        };
        // the first snow under the loop's gate (0.6 by default), the next over
        let mut log = log;
        log.roads[3].confidence = 0.55;
        log.roads[4].confidence = 0.9;
        let s = summarize(&log, &VehicleParams::default(), "defaults", None);
        assert_eq!((s.arte.judged, s.arte.correct), (5, 3));
        assert_eq!(s.arte.changes.len(), 1);
        let d = s.arte.changes[0].delay.unwrap();
        assert!((d - 0.050).abs() < 1e-6, "{d}");
        let g = s.arte.changes[0].gated_delay.unwrap();
        assert!((g - 0.070).abs() < 1e-6, "{g}");
        assert_eq!(s.arte.min_confidence, (0.6, false));
        let text = s.render();
        assert!(
            text.contains("detected after 0.050 s, past the gate after 0.070 s"),
            "{text}"
        );
        assert!(text.contains("its default"), "{text}");
        // none over the gate: said so
        log.roads[4].confidence = 0.3;
        let s2 = summarize(&log, &VehicleParams::default(), "defaults", None);
        assert_eq!(s2.arte.changes[0].gated_delay, None);
        assert!(
            s2.render()
                .contains("never past the gate before the next change")
        );
        let m = s.metrics.unwrap();
        assert_eq!(m.samples, 201, "window starts at the last held sample");
        // no cycle records: no command figures (none, not 0)
        assert!(m.cmd_tv_per_s.is_nan());
        assert_eq!(s.cmd_from_s, None);
    }

    /// `record`'s entries as a metadata record.
    fn record(entries: &[(&str, &str)]) -> BTreeMap<String, String> {
        entries
            .iter()
            .map(|(k, v)| ((*k).into(), (*v).into()))
            .collect()
    }

    /// The shipped `config/controllers.toml` with `[arte] min_confidence`
    /// set to `value` (TOML, as written in the file).
    fn controllers_with_gate(value: &str) -> Vec<u8> {
        let shipped = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/controllers.toml"),
        )
        .unwrap();
        assert!(
            shipped.contains("\nmin_confidence = 0.6\n"),
            "the shipped file's gate line"
        );
        shipped
            .replace("min_confidence = 0.6", &format!("min_confidence = {value}"))
            .into_bytes()
    }

    /// The loop's gate read as the loop's `f64` field: an integer `1` is a
    /// gate (alone in `[arte]` too: `summary_recomputed.rs`), and a file
    /// that does not read (a gate that is no number or outside [0, 1], no
    /// TOML) makes the gate unknown, said so, never an error (it read as
    /// the default, "the log carries no ... min_confidence"); no file or no
    /// key: the default, as before.
    #[test]
    fn the_gate_is_read_as_the_loops_field() {
        let mut log = DriveLog::default();
        let gate = |log: &DriveLog| {
            let g = gate_of(log);
            (g.min_confidence, g.from)
        };
        assert_eq!(gate(&log), (0.6, GateFrom::Default));
        for (value, want) in [
            ("0.85", (0.85, GateFrom::Log)),
            ("1", (1.0, GateFrom::Log)),
            ("0", (0.0, GateFrom::Log)),
            ("1.5", (0.6, GateFrom::Unknown)),
            ("\"high\"", (0.6, GateFrom::Unknown)),
        ] {
            log.attachments
                .insert("controllers.toml".into(), controllers_with_gate(value));
            assert_eq!(gate(&log), want, "min_confidence = {value}");
            assert_eq!(min_confidence_of(&log), (want.0, want.1.given()));
        }
        log.attachments.insert(
            "controllers.toml".into(),
            b"[arte\nmin_confidence = 0.7".to_vec(),
        );
        assert_eq!(gate(&log), (0.6, GateFrom::Unknown), "no TOML");
        log.attachments.insert(
            "controllers.toml".into(),
            b"[loop]\nrate_hz = 1000.0\n".to_vec(),
        );
        assert_eq!(gate(&log), (0.6, GateFrom::Default), "no [arte]");
        // said in the report
        let mut t = Vec::new();
        for k in 0..210u64 {
            let x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            let (r, n) = if k < 110 { (0, "asphalt") } else { (1, "snow") };
            t.push(truth(k, k, x, r, n));
        }
        log.truth = t;
        log.roads = vec![estimate_at(0, 50, "asphalt"), estimate_at(1, 160, "snow")];
        log.attachments
            .insert("controllers.toml".into(), controllers_with_gate("\"high\""));
        let s = summarize(&log, &VehicleParams::default(), "defaults", None);
        assert_eq!(s.arte.gate_from, GateFrom::Unknown);
        let text = s.render();
        assert!(
            text.contains("the loop's gate: the log's controllers.toml does not read as TOML or its [arte] min_confidence is no number in [0, 1]"),
            "{text}"
        );
        assert!(
            text.contains("so the gate is unknown; its default"),
            "{text}"
        );
    }

    /// A log of `grip replay --out` that changed the gate: the summary
    /// takes the gate the replay's tcs-loop ran (its `grip.replay` record),
    /// not the source's `controllers.toml` copied into the log, which it
    /// reported as "from the log's controllers.toml"; a replay log from
    /// before the record carried it says that the replay changed it; a
    /// replay that ran the source's gate reads as before.
    #[test]
    fn a_replays_gate_is_the_one_it_ran() {
        let mut t = Vec::new();
        for k in 0..210u64 {
            let x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            let (r, n) = if k < 110 { (0, "asphalt") } else { (1, "snow") };
            t.push(truth(k, k, x, r, n));
        }
        let mut log = DriveLog {
            truth: t,
            roads: vec![
                estimate_at(0, 50, "asphalt"),
                estimate_at(1, 140, "snow"),
                estimate_at(2, 160, "snow"),
            ],
            ..DriveLog::default()
        };
        // the first snow estimate passes the replay's gate 0.5, not the
        // source's 0.6
        log.roads[1].confidence = 0.55;
        log.attachments
            .insert("controllers.toml".into(), controllers_with_gate("0.6"));
        let changes = (
            "changes",
            "controllers.toml: [arte] min_confidence 0.6 -> 0.5",
        );
        log.metadata.insert(
            "grip.replay".into(),
            record(&[("source", "a.mcap"), changes, ("min_confidence", "0.5")]),
        );
        assert_eq!(
            gate_of(&log),
            Gate {
                min_confidence: 0.5,
                from: GateFrom::Replay
            }
        );
        let s = summarize(&log, &VehicleParams::default(), "defaults", None);
        assert_eq!(s.arte.min_confidence, (0.5, true));
        let g = s.arte.changes[0].gated_delay.unwrap();
        assert!((g - 0.030).abs() < 1e-6, "{g}: the estimate at 0.55");
        let text = s.render();
        assert!(
            text.contains("then the first at confidence >= 0.5, the loop's gate, the one the replay's tcs-loop ran (its grip.replay record; the log's controllers.toml is the source drive's)"),
            "{text}"
        );
        assert!(!text.contains("from the log's controllers.toml"), "{text}");
        // a replay log from before the record carried the gate: the
        // source's, and said to be changed
        log.metadata.insert(
            "grip.replay".into(),
            record(&[("source", "a.mcap"), changes]),
        );
        assert_eq!(
            gate_of(&log),
            Gate {
                min_confidence: 0.6,
                from: GateFrom::ReplayChanged
            }
        );
        let text = summarize(&log, &VehicleParams::default(), "defaults", None).render();
        assert!(
            text.contains("from the log's controllers.toml, the source drive's: the replay changed the gate or its configuration"),
            "{text}"
        );
        // ... unless that file gives no gate: then still its default
        let kept = log.attachments.remove("controllers.toml");
        assert_eq!(gate_of(&log).from, GateFrom::Default);
        if let Some(k) = kept {
            log.attachments.insert("controllers.toml".into(), k);
        }
        for c in [
            "configuration directory /x/config",
            "controllers.toml: [arte] min_confidence 0.6 -> 0.5 (the same)",
        ] {
            let r = ReplayInfo {
                changes: format!("controller mtte -> src; {c}"),
                ..ReplayInfo::default()
            };
            assert!(r.changed_gate(), "{c}");
        }
        // another change: not the gate
        for c in [
            "controller mtte -> src",
            "controllers.toml: [mfc] k_mfc 1 -> 2",
        ] {
            log.metadata.insert(
                "grip.replay".into(),
                record(&[("source", "a.mcap"), ("changes", c)]),
            );
            assert_eq!(gate_of(&log).from, GateFrom::Log, "{c}");
        }
        // the replay ran the source's gate: the log's file says it
        log.metadata.insert(
            "grip.replay".into(),
            record(&[("source", "a.mcap"), ("min_confidence", "0.6")]),
        );
        assert_eq!(gate_of(&log).from, GateFrom::Log);
    }

    /// A replay that ran another vehicle (`--vehicle`, or a `--set` on the
    /// vehicle): in closed loop (plant and loop both ran it) the summary
    /// uses the file the replay attached; in open loop (the ground truth is
    /// the source car's) it keeps the source's and names the one the
    /// replay's loop ran; a replay log from before the vehicle was recorded
    /// says that the replay changed it. It said the source's vehicle
    /// without a word.
    #[test]
    fn a_replays_vehicle_is_the_one_it_ran() {
        let cfg = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let shipped = std::fs::read_to_string(cfg.join("vehicle.toml")).unwrap();
        let heavy = shipped.replacen("mass = 1400.0", "mass = 1800.0", 1);
        assert_ne!(heavy, shipped, "the shipped file's mass line");
        let heavy_sha = grip_digest::sha256_hex(heavy.as_bytes());
        let mut log = snow_entry_log(|_, g, _| g.torque = 150.0);
        log.attachments
            .insert("vehicle.toml".into(), shipped.clone().into_bytes());
        log.attachments.insert(
            crate::plan::REPLAY_VEHICLE_ATTACHMENT.into(),
            heavy.into_bytes(),
        );
        let replay = |mode: &str| {
            record(&[
                ("source", "a.mcap"),
                ("mode", mode),
                ("changes", "vehicle.toml: [vehicle] mass 1400.0 -> 1800.0"),
                ("min_confidence", "0.6"),
                ("vehicle", "vehicle.toml"),
                ("vehicle_set", "--set vehicle.toml:vehicle.mass=1800"),
                ("vehicle_sha256", &heavy_sha),
            ])
        };
        let summary = |log: &DriveLog| {
            let (v, from, w) = crate::vehicle_for(log, &cfg);
            assert!(w.is_empty(), "{w:?}");
            (v, summarize(log, &v, &from, None))
        };
        // closed loop: the replay's vehicle
        log.metadata
            .insert("grip.replay".into(), replay("closed loop"));
        let (v, s) = summary(&log);
        assert_eq!(v.mass, 1800.0);
        assert_eq!(
            s.vehicle,
            "vehicle.toml (the vehicle the replay ran with --set vehicle.toml:vehicle.mass=1800, not its source drive's; attached to the log as replay/vehicle.toml)"
        );
        assert_eq!(s.vehicle_sha256.as_deref(), Some(heavy_sha.as_str()));
        let text = s.render();
        assert!(
            !text.contains("the replay's tcs-loop ran vehicle"),
            "{text}"
        );
        assert!(
            text.contains(&format!("  vehicle: {}", s.vehicle)),
            "{text}"
        );
        // open loop: the source's, and the replay's named
        log.metadata
            .insert("grip.replay".into(), replay("open loop"));
        let (v, s) = summary(&log);
        assert_eq!(v.mass, 1400.0);
        assert_eq!(s.vehicle, "vehicle.toml (attached to the log)");
        let text = s.render();
        assert!(
            text.contains(&format!(
                "  the replay's tcs-loop ran vehicle vehicle.toml with --set vehicle.toml:vehicle.mass=1800 (sha256 {}, attached to the log as replay/vehicle.toml), not vehicle.toml (attached to the log): in open loop the ground truth is the source drive's car's",
                &heavy_sha[..12]
            )),
            "{text}"
        );
        // a replay log from before: the source's, said to be changed
        log.attachments
            .remove(crate::plan::REPLAY_VEHICLE_ATTACHMENT);
        for c in [
            "vehicle /cars/heavy.toml",
            "vehicle.toml: [vehicle] mass 1400.0 -> 1800.0",
            "heavy.toml (--vehicle /cars/heavy.toml): [vehicle] mass 1800.0 -> 1900.0",
            "drive/vehicle.toml (the drive's --vehicle, from the log): [vehicle] r 0.28 -> 0.3",
        ] {
            log.metadata.insert(
                "grip.replay".into(),
                record(&[
                    ("source", "a.mcap"),
                    ("mode", "closed loop"),
                    ("changes", c),
                ]),
            );
            let (v, s) = summary(&log);
            assert_eq!(v.mass, 1400.0, "{c}");
            assert!(
                s.render().contains("  the replay's changes (above) touch the vehicle or the configuration directory it comes from, and this log, written before grip replay recorded the vehicle it ran, does not carry the one it ran: the vehicle used here, vehicle.toml (attached to the log), is the source drive's"),
                "{c}: {}",
                s.render()
            );
        }
        // a replay that ran the source's vehicle: nothing said
        log.metadata.insert(
            "grip.replay".into(),
            record(&[
                ("source", "a.mcap"),
                ("changes", "controller mtte -> src"),
                ("vehicle", "vehicle.toml"),
                (
                    "vehicle_sha256",
                    &grip_digest::sha256_hex(shipped.as_bytes()),
                ),
            ]),
        );
        let (_, s) = summary(&log);
        assert!(!s.render().contains("the replay's tcs-loop ran vehicle"));
        assert!(
            !s.render()
                .contains("the replay's changes (above) touch the vehicle")
        );
    }

    /// `grip inspect A B` where A's figure is 0 and B's is not: `A is 0`,
    /// not a ratio `0.000x` read as a factor; `B is 0` and `both 0` the
    /// same way; `-` only where a figure is missing.
    #[test]
    fn a_ratio_where_a_is_zero_says_so() {
        assert_eq!(ratio_cell(0.0, 2.0), "A is 0");
        assert_eq!(ratio_cell(-0.0, 2.0), "A is 0");
        assert_eq!(ratio_cell(1.0, 2.0), "0.500x");
        assert_eq!(ratio_cell(1.0, 0.0), "B is 0");
        assert_eq!(ratio_cell(0.0, 0.0), "both 0");
        assert_eq!(ratio_cell(f64::NAN, 2.0), "-");
        let log = snow_entry_log(|_, g, _| g.torque = 150.0);
        let b = summarize(&log, &VehicleParams::default(), "test", None);
        let mut a = b.clone();
        a.metrics.as_mut().expect("a scenario window").energy = 0.0;
        let mut b = b;
        b.measured.spins = vec![measured::SpinEvent::default(); 2];
        let c = compare(&a, &b);
        let line = |name: &str| {
            c.lines()
                .find(|l| l.starts_with(name))
                .unwrap_or_else(|| panic!("{name}: {c}"))
        };
        assert!(line("energy ∫Tω dt").ends_with(" A is 0"), "{c}");
        assert!(line("spin events").ends_with(" A is 0"), "{c}");
        assert!(line("distance (m)").ends_with(" 1.000x"), "{c}");
        assert!(!c.contains("0.000x"), "{c}");
    }

    #[test]
    fn the_command_in_force_at_each_truth_sample() {
        // held 10 ms, then 200 ms moving; the loop commands 100 N m and
        // 0 N m alternately every 10 ms (cycle records every 2 ms).
        let mut t = Vec::new();
        for k in 0..210u64 {
            let x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            t.push(truth(k, k, x, 0, "asphalt"));
        }
        let cycles = (0..105u64)
            .map(|i| {
                let mut c = CycleRecord::zeroed();
                c.seq = i;
                c.stamp_ns = 2 * i * 1_000_000;
                c.torque_cmd = if (2 * i / 10) % 2 == 0 { 100.0 } else { 0.0 };
                c.demand = 300.0;
                c
            })
            .collect();
        let log = DriveLog {
            truth: t,
            cycles,
            ..DriveLog::default()
        };
        let s = summarize(&log, &VehicleParams::default(), "defaults", None);
        let m = s.metrics.unwrap();
        // window: truth samples 9..=209, 201 samples of 1 ms; the command
        // figures start at the window's first cycle with the demand (10
        // ms), so over 0.200 s; the command changes at 20, ..., 200 ms: 19
        // edges of 100 N m (the one at 10 ms is their start).
        assert_eq!(m.samples, 201);
        assert!((m.cmd_duration - 0.200).abs() < 1e-9, "{}", m.cmd_duration);
        assert!(
            (m.cmd_tv_per_s - 1900.0 / 0.200).abs() < 1e-6,
            "{}",
            m.cmd_tv_per_s
        );
        assert!((s.cmd_from_s.unwrap() - 0.001).abs() < 1e-9);
        assert!(s.render().contains("command total variation"));
    }

    /// A drive with `grip drive --model FILE` names the user's file: the
    /// services ran a copy under arte-svc.toml's `model`, and the summary
    /// said only "arte-svc.toml's model" (found in review).
    #[test]
    fn the_model_the_user_gave_is_named() {
        let mut log = DriveLog::default();
        log.attachments.insert(
            "arte-svc.toml".into(),
            b"model = \"models/mine.model\"\n".to_vec(),
        );
        log.attachments
            .insert("models/mine.model".into(), b"bytes".to_vec());
        let plain = model_of(&log).unwrap();
        assert_eq!(plain.name, "models/mine.model");
        assert!(!plain.from.contains("--model"), "{}", plain.from);
        log.run
            .insert("model_given".into(), "/srv/recordings/mine.model".into());
        let given = model_of(&log).unwrap();
        // the model line names the file given, not arte-svc.toml's model
        // (a trial's `model:` line said "arte-svc.toml's model" first)
        assert_eq!(given.name, "/srv/recordings/mine.model");
        assert_eq!(
            given.line(),
            format!(
                "/srv/recordings/mine.model (sha256 {}, grip drive --model; the services ran a copy as arte-svc.toml's model models/mine.model, attached to the log)",
                short_sha(plain.sha256.as_ref())
            )
        );
        assert_eq!(given.sha256, plain.sha256);
    }

    /// A drive whose `--scenario` was a path carries the file as
    /// `drive/scenario.toml`: the summary hashes it and reads its duration
    /// (a trial's `--scenario scen/suv.toml` gave `scenario_sha256: null`).
    #[test]
    fn a_scenario_given_as_a_path_is_the_attached_one() {
        let text = b"duration = 3.5\n".to_vec();
        let h = grip_digest::sha256_hex(&text);
        let mut log = DriveLog::default();
        log.run.insert("scenario".into(), "scen/suv.toml".into());
        log.attachments
            .insert("scenarios/paper.toml".into(), b"duration = 2.4\n".to_vec());
        assert_eq!(scenario_attachment(&log), None);
        let s = summarize(&log, &VehicleParams::default(), "defaults", None);
        assert_eq!(s.scenario_sha256, None);
        log.attachments
            .insert(crate::plan::SCENARIO_ATTACHMENT.into(), text.clone());
        log.run
            .insert("config.drive/scenario.toml".into(), h.clone());
        assert_eq!(
            scenario_attachment(&log).as_deref(),
            Some("drive/scenario.toml")
        );
        assert_eq!(scenario_duration(&log), Some(3.5));
        let s = summarize(&log, &VehicleParams::default(), "defaults", None);
        assert_eq!(s.scenario_sha256.as_deref(), Some(h.as_str()));
        assert!(
            !s.warnings.iter().any(|w| w.contains("damaged")),
            "{:?}",
            s.warnings
        );
        // a name: the configuration directory's file, as before
        let mut log = DriveLog::default();
        log.run.insert("scenario".into(), "paper".into());
        log.attachments
            .insert("scenarios/paper.toml".into(), b"duration = 2.4\n".to_vec());
        assert_eq!(
            scenario_attachment(&log).as_deref(),
            Some("scenarios/paper.toml")
        );
        assert_eq!(scenario_duration(&log), Some(2.4));
        // a path, from an older drive that did not attach it: the attached
        // scenarios/paper.toml may be another file with the same tail (a
        // review's `--scenario trials/scenarios/paper.toml` elsewhere), so
        // none is taken
        log.run
            .insert("scenario".into(), "trials/scenarios/paper.toml".into());
        assert_eq!(scenario_attachment(&log), None);
        assert_eq!(scenario_duration(&log), None);
    }

    /// The attached `[synth.aliases]` as audio-acq resolved it (the one rule
    /// of grip-arte): an alias of a synthesiser road left out; a table
    /// audio-acq would have refused gives no aliases, never a failure (was:
    /// values that were not strings dropped, the rest kept as written).
    #[test]
    fn audio_of_resolves_the_aliases_and_never_fails() {
        let with = |aliases: &str| {
            let mut log = DriveLog::default();
            log.attachments.insert(
                "audio-acq.toml".into(),
                format!("[audio]\nsource = \"synth\"\n{aliases}").into_bytes(),
            );
            audio_of(&log).unwrap().aliases
        };
        let ok = BTreeMap::from([("wet_gravel".to_owned(), "gravel".to_owned())]);
        assert_eq!(
            with("[synth.aliases]\nwet_gravel = \"gravel\"\nsnow = \"stone\"\n"),
            ok
        );
        for bad in [
            "[synth.aliases]\nwet_gravel = \"gravel\"\nice = 3\n",
            "[synth.aliases]\nwet_gravel = \"gravel\"\nice = \"tarmac\"\n",
            "[synth.aliases]\nwet_gravel = { a = 1 }\n",
            "[synth]\naliases = 3\n",
            "synth = \"x\"\n",
            "",
        ] {
            assert!(with(bad).is_empty(), "{bad}");
        }
    }

    /// ARTE's accuracy says where the audio came from: a road without a
    /// sound of its own is noted (played as its alias, or noise only), and
    /// audio from a WAV file is said to be graded against the plant's
    /// roads (a trial's report gave `wet_gravel recall 0.0 %` with no note,
    /// and never said the audio was a file).
    #[test]
    fn the_accuracy_says_what_the_microphone_heard() {
        let mut t = Vec::new();
        for k in 0..210u64 {
            let x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            let (r, n) = if k < 110 {
                (0, "asphalt")
            } else {
                (1, "wet_gravel")
            };
            t.push(truth(k, k, x, r, n));
        }
        let mut log = DriveLog {
            truth: t,
            roads: vec![estimate_at(0, 50, "asphalt"), estimate_at(1, 160, "gravel")],
            ..DriveLog::default()
        };
        let acq = |source: &str, aliases: &str| {
            format!(
                "[audio]\nsource = \"{source}\"\nsample_rate = 44100\nblock_samples = 1024\n[wav]\npath = \"audio/drive.wav\"\n[synth.aliases]\n{aliases}"
            )
            .into_bytes()
        };
        let render =
            |log: &DriveLog| summarize(log, &VehicleParams::default(), "defaults", None).render();
        // no audio-acq.toml: no note (the log does not say)
        let r = render(&log);
        assert!(r.contains("    wet_gravel   recall 0.0 % (0/1)\n"), "{r}");
        log.attachments.insert(
            "audio-acq.toml".into(),
            acq("synth", "wet_gravel = \"gravel\"\n"),
        );
        let r = render(&log);
        assert!(
            r.contains("    wet_gravel   recall 0.0 % (0/1): no sound of its own: played as gravel (audio-acq.toml [synth.aliases] wet_gravel = \"gravel\")\n"),
            "{r}"
        );
        assert!(r.contains("    asphalt      recall 100.0 % (1/1)\n"), "{r}");
        assert!(!r.contains("audio: from"), "{r}");
        log.attachments
            .insert("audio-acq.toml".into(), acq("synth", ""));
        let r = render(&log);
        assert!(
            r.contains("(0/1): no sound of its own: vehicle and microphone noise only"),
            "{r}"
        );
        // a WAV file: said where the accuracy is; no per-road sound notes
        log.attachments.insert(
            "audio-acq.toml".into(),
            acq("wav", "wet_gravel = \"gravel\"\n"),
        );
        let r = render(&log);
        let l = r.find("  audio: from the WAV file audio/drive.wav (audio-acq.toml [audio] source = \"wav\"), not synthesised from the plant's roads").unwrap_or_else(|| panic!("{r}"));
        assert!(l < r.find("accuracy during the scenario").unwrap(), "{r}");
        assert!(r.contains("    wet_gravel   recall 0.0 % (0/1)\n"), "{r}");
        // arte's model (attached, named by arte-svc.toml) has no class for
        // wet_gravel: said, whatever the audio (a newcomer's own model
        // without wet_asphalt read "recall 0.0 %" and nothing more)
        log.attachments.insert(
            "arte-svc.toml".into(),
            b"model = \"models/paper.model\"\n".to_vec(),
        );
        log.attachments.insert(
            "models/paper.model".into(),
            include_bytes!("../../../config/models/paper.model").to_vec(),
        );
        let r = render(&log);
        assert!(
            r.contains("    wet_gravel   recall 0.0 % (0/1): arte's model has no class for it (its classes: asphalt, gravel, snow, stone, wet_asphalt, wet_stone), so it is never estimated right\n"),
            "{r}"
        );
        assert!(r.contains("    asphalt      recall 100.0 % (1/1)\n"), "{r}");
        log.attachments
            .insert("audio-acq.toml".into(), acq("synth", ""));
        let r = render(&log);
        assert!(
            r.contains("so it is never estimated right; no sound of its own: vehicle and microphone noise only"),
            "{r}"
        );
    }
}
