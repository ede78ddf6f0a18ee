//! `grip replay --closed-loop`: plant-sim's own loop and tcs-loop's, each
//! cycle run when, and with what, the logged drive's ran.
//!
//! A live drive's two loops are separate processes with their own timers:
//! plant-sim starts before tcs-loop (its sensor noise and encoder have run
//! a cycle apiece since), each wakes at its own phase of the millisecond
//! with some latency, a frame reaches the other side in the first cycle
//! that drains after it was sent, and a cycle that wakes or ends after the
//! next deadline makes the timer skip it (plant-sim then steps the skipped
//! periods in the next cycle). The log holds all of it: plant-sim's cycles
//! are the ground truth's sequence numbers and stamps (its "now"; a skip
//! shows as x advancing two periods' worth, or, where the car stands, as
//! a stamp a period late), tcs-loop's are the cycle records (deadline,
//! wake-up latency, compute time) with their TorqueCommands' stamps (its
//! "now"), and the CAN log says how many frames each loop cycle drained.
//! The closed loop replays that schedule: the plant from its first cycle
//! (sequence number 0, so its sensor noise and encoder are the live
//! plant's at every cycle), asked to start in the cycle the live plant
//! started (its pre-roll's first, with a microphone ahead of the wheel),
//! each of its cycles handed the commands sent before it ran (a command
//! counts as sent at the end of its cycle's compute); each loop cycle
//! handed the plant's next frames in the order they were sent, as many as
//! the logged cycle drained, from the first frame the loop received, and
//! with the logged reception stamps. Past the log (a what-if that runs
//! longer) the stamps alone decide, a period apiece. With nothing changed
//! it gives the drive's ground truth and cycle records bit for bit
//! (`tools/grip/README.md`, "Closed loop").

use std::collections::{BTreeSet, VecDeque};

use grip_drive::DriveLog;
use grip_io::can::MemBus;
use grip_io::can::protocol::counter_of;
use grip_msgs::{CanFrame, GroundTruth, RoadEstimate};
use grip_plant_sim::{Outcome, PlantSim, PlantTick};
use grip_tcs_loop::{CycleTick, TcsLoop};

use super::{Outputs, Road, ScriptClock, split_can, taken_per_cycle};

/// Collects plant-sim's ground truth.
#[derive(Debug, Default)]
struct Truths(Vec<GroundTruth>);

impl grip_plant_sim::TruthSink for Truths {
    fn truth(&mut self, g: &GroundTruth) {
        self.0.push(*g);
    }
}

/// What a closed-loop replay produced.
#[derive(Debug, Default)]
pub struct ClosedLoop {
    /// The re-simulated plant's ground truth.
    pub truth: Vec<GroundTruth>,
    /// The loop's outputs.
    pub outs: Outputs,
    /// How many logged ground-truth samples the plant gave bit for bit
    /// before the first that differs (a cycle whose sample the recorder
    /// did not write, or past the log, counts for nothing).
    pub agreed: u64,
    /// The sequence number of the first logged ground-truth sample the
    /// plant did not give bit for bit (`None`: none differed).
    pub diverged_at: Option<u64>,
}

/// The same ground truth, bit for bit (NaN equals NaN).
fn same_truth(a: &GroundTruth, b: &GroundTruth) -> bool {
    let bits = |g: &GroundTruth| [g.v, g.omega, g.lambda, g.torque, g.x].map(f64::to_bits);
    a.seq == b.seq
        && a.stamp_ns == b.stamp_ns
        && a.road_index == b.road_index
        && a.mic_road_index == b.mic_road_index
        && a.road_name == b.road_name
        && a.mic_road_name == b.mic_road_name
        && bits(a) == bits(b)
}

/// The logged ground truth while its sequence numbers rise (a restarted
/// plant ends it): the live plant's cycles the replay re-runs.
pub(super) fn rising(truth: &[GroundTruth]) -> &[GroundTruth] {
    let n = truth
        .windows(2)
        .position(|w| w[1].seq <= w[0].seq)
        .map_or(truth.len(), |i| i + 1);
    &truth[..n]
}

/// The first ground-truth sample that moved (x, V or ω changed), its
/// sequence number: where a drive that starts moving started (plant-sim
/// holds the car frozen until its start; with a microphone ahead, the
/// pre-roll's first cycle). `None`: nothing moved.
pub fn first_moved(truth: &[GroundTruth]) -> Option<u64> {
    let f = truth.first()?;
    truth
        .iter()
        .find(|g| g.x != f.x || g.v != f.v || g.omega != f.omega)
        .map(|g| g.seq)
}

/// How many plant cycles before the first driver demand the loop received
/// the start is looked for (`plant_start`): 50 ms at 1 kHz, five
/// DriverDemand periods of the shipped bus.
pub const START_WINDOW: u64 = 50;

/// At most this many candidates are tried ([`plant_start`]): a log whose
/// first demand and first movement lie further apart (a gap in the
/// sequence numbers, a damaged log) takes the first sample that moved.
pub const MAX_CANDIDATES: u64 = 4 * START_WINDOW;

/// Where a closed-loop replay starts the plant, and how that was found.
#[derive(Debug, Clone, PartialEq)]
pub enum PlantStart {
    /// The drive started moving: the first sample that moved (exact:
    /// plant-sim steps the car in the cycle it starts). `None`: nothing
    /// moved (started at once).
    Moved(Option<u64>),
    /// From rest nothing moves until the driver's demand has reached the
    /// motor (a DriverDemand period and more later), so each cycle from
    /// [`START_WINDOW`] before the loop's first demand up to the first
    /// that moved was tried with the drive's own configuration; `seq`
    /// reproduced the most logged ground truth from the plant's first cycle.
    Probed {
        /// The plant cycle started in.
        seq: u64,
        /// The first sample that moved (the rule for a moving start).
        moved: Option<u64>,
        /// Candidates tried.
        tried: usize,
        /// Of the logged samples, how many `seq` reproduced bit for bit,
        /// and how many there are.
        agreed: (u64, u64),
    },
    /// From rest, but the drive's own configuration could not be run to
    /// try the candidates: the first sample that moved, and why.
    NotProbed {
        /// The first sample that moved.
        moved: Option<u64>,
        /// Why.
        why: String,
    },
}

impl PlantStart {
    /// The plant cycle the replay starts the plant in (`None`: at once).
    pub fn seq(&self) -> Option<u64> {
        match self {
            Self::Moved(m) | Self::NotProbed { moved: m, .. } => *m,
            Self::Probed { seq, .. } => Some(*seq),
        }
    }

    /// The report's line.
    pub fn line(&self, period_ns: u64) -> String {
        let ms = |d: u64| d as f64 * period_ns as f64 * 1e-6;
        match self {
            Self::Moved(Some(s)) => {
                format!("plant started in its cycle {s} (the first ground-truth sample that moved)")
            }
            Self::Moved(None) => {
                "plant started at once (nothing in the ground truth moved)".to_owned()
            }
            Self::Probed {
                seq,
                moved,
                tried,
                agreed: (a, n),
            } => {
                let before = moved.map_or(String::new(), |m| {
                    format!(
                        ", {:.0} ms before the first sample that moved",
                        ms(m.saturating_sub(*seq))
                    )
                });
                let how = if a == n {
                    "reproduces the logged ground truth bit for bit".to_owned()
                } else {
                    format!(
                        "reproduces {a} of the {n} logged ground-truth samples, the most of them"
                    )
                };
                format!(
                    "plant started in its cycle {seq}{before}: a drive from rest, so {tried} candidate cycles were tried with the drive's own configuration, and this one {how}"
                )
            }
            Self::NotProbed { moved, why } => format!(
                "plant started in its cycle {} (the first ground-truth sample that moved; a drive from rest starts earlier, but the candidates could not be tried: {why})",
                moved.map_or("-".to_owned(), |m| m.to_string())
            ),
        }
    }
}

/// Where the live plant started (module docs): the first sample that
/// moved for a drive that starts moving; from rest, each candidate cycle
/// run by `probe` (a closed loop of the drive's own configuration, from
/// that cycle, stopped at the first ground-truth sample that differs,
/// returning [`ClosedLoop::agreed`]) and the one that reproduces the most
/// of the log taken (of equals, the latest). The candidates lie before the
/// loop's first demand by `demand_after`, the plant cycles from the
/// scenario's start to its first demand (0 for a demand from the start;
/// a ramp that starts later, steps from 0 N m), and [`START_WINDOW`] more.
/// `probe` failing to start ends the search with [`PlantStart::NotProbed`].
pub fn plant_start(
    log: &DriveLog,
    demand_after: u64,
    mut probe: impl FnMut(u64) -> anyhow::Result<u64>,
) -> PlantStart {
    let truth = rising(&log.truth);
    let moved = first_moved(truth);
    let Some(first) = truth.first() else {
        return PlantStart::Moved(moved);
    };
    if first.v != 0.0 || first.omega != 0.0 {
        return PlantStart::Moved(moved);
    }
    // the plant's cycle when the loop first had a demand other than its
    // first cycle's (the holding plant sends 0)
    let demanded = log.cycles.first().and_then(|c0| {
        let c = log.cycles.iter().find(|c| c.demand != c0.demand)?;
        let i = truth.partition_point(|g| g.stamp_ns <= c.stamp_ns);
        Some(truth.get(i.checked_sub(1)?)?.seq)
    });
    // a car that moved before the loop had any demand moved on its own (a
    // hill start rolling back): the plant steps it in the cycle it starts
    if let (Some(d), Some(m)) = (demanded, moved)
        && m < d
    {
        return PlantStart::Moved(Some(m));
    }
    let (lo, hi) = match (demanded, moved) {
        (Some(d), Some(m)) => (d.min(m), m),
        (Some(d), None) => (d, d),
        (None, Some(m)) => (m, m),
        (None, None) => return PlantStart::Moved(None),
    };
    let lo = lo.saturating_sub(demand_after.saturating_add(START_WINDOW));
    let hi = hi.saturating_sub(demand_after).max(lo);
    if hi - lo > MAX_CANDIDATES {
        return PlantStart::NotProbed {
            moved,
            why: format!(
                "{} cycles lie between the loop's first demand and the first sample that moved, more than the {MAX_CANDIDATES} tried",
                hi - lo + 1
            ),
        };
    }
    let mut best: Option<(u64, u64)> = None;
    for c in lo..=hi {
        match probe(c) {
            Ok(a) => {
                if best.is_none_or(|(_, b)| a >= b) {
                    best = Some((c, a));
                }
            }
            Err(e) => {
                return PlantStart::NotProbed {
                    moved,
                    why: format!("{e:#}"),
                };
            }
        }
    }
    let (seq, a) = best.unwrap_or((hi, 0));
    PlantStart::Probed {
        seq,
        moved,
        tried: (hi - lo + 1) as usize,
        agreed: (a, truth.len() as u64),
    }
}

/// The loop cycles whose command raced a plant cycle's drain: a command
/// goes out after the cycle's "now" (its TorqueCommand's stamp) and
/// before the end of its compute (the log copies and the record follow
/// it), and plant-sim drains the bus just before its own "now" (its
/// ground truth's stamp); where a logged plant "now" lies between the
/// two, the stamps cannot say whether that plant cycle received the
/// command or the next did. Each as `(loop cycle, plant cycle)`, in order.
pub fn racing_commands(log: &DriveLog) -> Vec<(usize, u64)> {
    let Ok(can) = split_can(log) else {
        return Vec::new();
    };
    let truth = rising(&log.truth);
    let mut out = Vec::new();
    for (k, c) in log.cycles.iter().enumerate() {
        let now = can.tx[k].stamp_ns;
        let done = c
            .stamp_ns
            .saturating_add_signed(c.wakeup_latency_ns)
            .saturating_add(c.compute_ns);
        let i = truth.partition_point(|g| g.stamp_ns <= now);
        if let Some(g) = truth.get(i)
            && g.stamp_ns <= done
        {
            out.push((k, g.seq));
        }
    }
    out
}

/// How the commands that raced a plant cycle's drain ([`racing_commands`])
/// were placed ([`command_races`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CommandRaces {
    /// The racing commands.
    pub racing: usize,
    /// Their loop cycles whose command the plant cycle it raced received
    /// (the logged ground truth says so); the others' went to the next.
    pub early: BTreeSet<usize>,
    /// Closed loops run to place them.
    pub runs: usize,
    /// Why they could not be placed (the commands then all count as sent
    /// at the end of their cycle's compute).
    pub not_placed: Option<String>,
}

impl CommandRaces {
    /// The report's line (`None`: no command raced a drain).
    pub fn line(&self) -> Option<String> {
        if self.racing == 0 {
            return None;
        }
        let how = match &self.not_placed {
            Some(why) => format!(
                "each taken as received by the next plant cycle (the drive's own closed loop could not be run to place them: {why})"
            ),
            None => format!(
                "{} taken as received by the plant cycle it raced, the others by the next, as the logged ground truth shows ({} closed loops of the drive's own configuration run to place them)",
                self.early.len(),
                self.runs
            ),
        };
        Some(format!(
            "commands that went out while plant-sim drained the bus (sent between the loop cycle's now and the end of its compute, the plant's now between the two): {}; {how}",
            self.racing
        ))
    }
}

/// Places the commands that raced a plant cycle's drain
/// ([`racing_commands`]): whether the plant cycle received it or the next
/// is not in the stamps, but where the command changed the torque the
/// logged ground truth shows it. `probe` runs the drive's own closed loop
/// (with `probe` set, from the plant's start) with the given commands
/// counted as sent at their cycle's "now" ([`closed_loop`]'s `early`);
/// where the ground truth first differs from the log in a plant cycle that
/// a racing command raced, that command is taken as received there if that
/// reproduces more of the log, and so on. The placement found is the
/// drive's timing, replayed as such with a what-if too (as the plant's
/// start). `probe` failing ends the search with every command sent at the
/// end of its compute, and says why.
pub fn command_races(
    log: &DriveLog,
    mut probe: impl FnMut(&BTreeSet<usize>) -> anyhow::Result<ClosedLoop>,
) -> CommandRaces {
    let racing = racing_commands(log);
    let mut out = CommandRaces {
        racing: racing.len(),
        ..CommandRaces::default()
    };
    if racing.is_empty() {
        return out;
    }
    let mut run = |early: &BTreeSet<usize>, out: &mut CommandRaces| {
        out.runs += 1;
        probe(early).map(|c| (c.agreed, c.diverged_at))
    };
    let mut early = BTreeSet::new();
    let mut best = match run(&early, &mut out) {
        Ok(b) => b,
        Err(e) => {
            out.not_placed = Some(format!("{e:#}"));
            return out;
        }
    };
    let mut tried = BTreeSet::new();
    while let Some(s) = best.1 {
        let mut better = false;
        for &(k, _) in racing.iter().filter(|&&(_, q)| q == s) {
            if !tried.insert(k) {
                continue;
            }
            early.insert(k);
            match run(&early, &mut out) {
                Ok(r) if r.0 > best.0 => {
                    best = r;
                    better = true;
                    break;
                }
                Ok(_) => {
                    early.remove(&k);
                }
                Err(e) => {
                    out.not_placed = Some(format!("{e:#}"));
                    return out;
                }
            }
        }
        if !better {
            break;
        }
    }
    out.early = early;
    out
}

/// The most periods a plant cycle is told its timer skipped
/// ([`PlantTimes::at`]): more (2^32 periods, 50 days at 1 kHz) is no
/// drive's, and plant-sim counts them in `u64`.
const MAX_SKIPPED: u64 = u32::MAX as u64;

/// plant-sim's cycles as the log's ground truth shows them.
struct PlantTimes {
    /// `(seq, stamp, periods skipped before it in all)` of every logged
    /// sample while the sequence numbers rise (a restarted plant ends it).
    cycles: Vec<(u64, u64, u64)>,
    period_ns: u64,
}

impl PlantTimes {
    fn new(truth: &[GroundTruth], period_ns: u64) -> Self {
        let seqs = rising(truth);
        let period_ns = period_ns.max(1);
        let p = i128::from(period_ns);
        let dt = period_ns as f64 * 1e-9;
        // Each stamp less its seq's periods: the timer's phase plus the
        // wake-up latency plus a period per deadline skipped so far; above
        // the smallest, in whole periods, how late a cycle woke (saturating:
        // `check::truth` refuses sequence numbers that do not fit)
        let phase = |g: &GroundTruth| {
            i128::from(g.stamp_ns).saturating_sub(i128::from(g.seq).saturating_mul(p))
        };
        let base = seqs.iter().map(phase).min().unwrap_or(0);
        let late = |g: &GroundTruth| -> u64 {
            let x = phase(g).saturating_sub(base);
            u64::try_from(x / p).unwrap_or(0)
        };
        let mut cycles = Vec::with_capacity(seqs.len());
        let mut skipped = 0u64;
        for (i, g) in seqs.iter().enumerate() {
            if i > 0 {
                let prev = &seqs[i - 1];
                // where the car moved, the periods it was stepped are on
                // record: x advanced by about V dt a period
                let v = 0.5 * (prev.v + g.v);
                let steps = (g.x - prev.x) / (v * dt);
                let n = steps.round();
                skipped =
                    if g.seq == prev.seq + 1 && v > 0.1 && n >= 1.0 && (steps - n).abs() < 0.25 {
                        skipped.saturating_add(n as u64 - 1)
                    } else {
                        // A cycle that wakes after the next deadline, or ends
                        // after it, makes the timer skip it: the *next* cycle
                        // steps the skipped periods (`PeriodicTimer::wait_next`)
                        skipped.max(late(prev))
                    };
            }
            cycles.push((g.seq, g.stamp_ns, skipped));
        }
        Self { cycles, period_ns }
    }

    /// Cycle `s`'s live "now" and the periods its timer skipped before it
    /// (past the logged cycles: a period apiece, none skipped). Saturating,
    /// and at most [`MAX_SKIPPED`] skipped: a damaged log's times stay
    /// times.
    fn at(&self, s: u64) -> (u64, u64) {
        let periods = |n: u64| n.saturating_mul(self.period_ns);
        let i = self.cycles.partition_point(|&(q, _, _)| q <= s);
        if i == 0 {
            let Some(&(q, t, _)) = self.cycles.first() else {
                return (periods(s), 0);
            };
            return (t.saturating_sub(periods(q - s)), 0);
        }
        let (q, t, k) = self.cycles[i - 1];
        if q == s {
            let before = if i >= 2 { self.cycles[i - 2].2 } else { k };
            return (t, (k - before).min(MAX_SKIPPED));
        }
        (t.saturating_add(periods(s - q)), 0)
    }
}

/// tcs-loop's cycle `k` as logged: its tick, its clock's two readings
/// (its "now", the TorqueCommand's stamp; the end of its compute) and the
/// stamps of the frames it drained (`None`: not logged, taken by time).
struct LoopCycle<'a> {
    tick: CycleTick,
    now: u64,
    done: u64,
    rx: Option<&'a [CanFrame]>,
}

/// `--closed-loop`: plant-sim's own loop (`PlantSim::cycle`, built by its
/// start-up from the drive's scenario, seed and vehicle) and `lp` over an
/// in-memory bus, each cycle run when and with what the logged drive's ran
/// (module docs); the plant is asked to start in its cycle `start` (where
/// the logged plant started, [`plant_start`]; `None`: at once; it then
/// also waits for valid commands, as in the drive). The road estimates are
/// the logged (or arte's replayed) ones, handed over in the cycle the
/// drive took them: what the microphone heard on the logged drive (the
/// acoustics stay open loop). Runs until plant-sim ends the scenario, then
/// the logged cycles left and the shutdown command; at most twice the
/// logged cycles; with `probe`, only until the first ground-truth sample
/// that differs from the logged one. A command counts as sent at the end
/// of its cycle's compute, except the commands of the loop cycles in
/// `early` ([`command_races`]): at the cycle's "now" (its TorqueCommand's
/// stamp), so a plant cycle whose "now" lies between the two receives it.
pub fn closed_loop(
    lp: &mut TcsLoop,
    plant: &mut PlantSim,
    log: &DriveLog,
    roads: &[RoadEstimate],
    period_ns: u64,
    start: Option<u64>,
    probe: bool,
    early: &BTreeSet<usize>,
) -> ClosedLoop {
    let can = split_can(log).ok();
    let taken = taken_per_cycle(log);
    let plant_t = PlantTimes::new(&log.truth, period_ns);
    let nk = log.cycles.len();
    let last = log.cycles.last().copied().unwrap_or_default();
    let loop_at = |k: usize| -> LoopCycle {
        if let Some(c) = log.cycles.get(k) {
            let woke = c.stamp_ns.saturating_add_signed(c.wakeup_latency_ns);
            let now = can.as_ref().map_or(woke, |can| can.tx[k].stamp_ns);
            LoopCycle {
                tick: CycleTick {
                    deadline_ns: c.stamp_ns,
                    woke_ns: woke,
                    deadline_misses: c.deadline_misses,
                },
                now,
                done: woke.saturating_add(c.compute_ns),
                rx: can.as_ref().map(|can| can.rx[k].as_slice()),
            }
        } else {
            let d = last
                .stamp_ns
                .saturating_add(((k + 1 - nk) as u64).saturating_mul(period_ns));
            LoopCycle {
                tick: CycleTick {
                    deadline_ns: d,
                    woke_ns: d,
                    deadline_misses: last.deadline_misses,
                },
                now: d,
                done: d,
                rx: None,
            }
        }
    };
    let start_seq = start;
    let logged = rising(&log.truth);
    // leading plant cycles that gave the logged truth, and whether one did not
    let agreed = std::cell::Cell::new(0u64);
    let diverged = std::cell::Cell::new(false);
    let diverged_at = std::cell::Cell::new(None);

    let pclock = ScriptClock::default();
    let tclock = ScriptClock::default();
    let mut bus_p = MemBus::new();
    // received frames numbered as the loop numbers what it sends (the
    // log's bus_id)
    let mut bus_t = MemBus::new().with_bus_id(lp.bus_id());
    // commands sent, with when (the end of the sending cycle's compute)
    let mut commands: VecDeque<(u64, CanFrame)> = VecDeque::new();
    // the plant's frames not yet received, with the cycle that sent them
    let mut frames: VecDeque<(u64, CanFrame)> = VecDeque::new();
    let mut truths = Truths::default();
    let mut outs = Outputs::default();
    let mut s: u64 = 0;
    let mut finished = false;
    let mut subscribed = false;

    // one plant cycle: the commands sent before it ran, then its own
    let mut plant_cycle = |s: &mut u64,
                           commands: &mut VecDeque<(u64, CanFrame)>,
                           frames: &mut VecDeque<(u64, CanFrame)>|
     -> bool {
        let (now, skipped) = plant_t.at(*s);
        while let Some(&(sent, f)) = commands.front() {
            if sent >= now {
                break;
            }
            bus_p.inject(f);
            commands.pop_front();
        }
        if start_seq.is_none_or(|q| *s >= q) {
            plant.request_start();
        }
        pclock.reset(now);
        let o = plant.cycle(
            &PlantTick {
                deadline_ns: now,
                skipped,
            },
            &pclock,
            &mut bus_p,
            &mut truths,
        );
        for f in bus_p.take_sent() {
            frames.push_back((*s, f));
        }
        if !diverged.get()
            && let Some(g) = truths.0.last()
        {
            let i = logged.partition_point(|l| l.seq < g.seq);
            match logged.get(i) {
                Some(l) if l.seq == g.seq => {
                    if same_truth(l, g) {
                        agreed.set(agreed.get() + 1);
                    } else {
                        diverged.set(true);
                        diverged_at.set(Some(g.seq));
                    }
                }
                _ => {}
            }
        }
        *s += 1;
        o == Outcome::Finished
    };

    let mut k = 0usize;
    // a probe has nothing left to compare once the plant is past the log
    let last_logged = logged.last().map_or(0, |g| g.seq);
    while k < nk * 2 && (!finished || k < nk) && !(probe && (diverged.get() || s > last_logged)) {
        let c = loop_at(k);
        let rx_logged = c.rx;
        // the plant cycles that ran before this loop cycle's drain
        while !finished && plant_t.at(s).0 < c.now {
            finished = plant_cycle(&mut s, &mut commands, &mut frames);
        }
        if k >= nk {
            // past the log, a plant cycle at this very instant goes first
            // (as in `grip generate`'s lock step, which ends the drive
            // without the loop cycle of the plant's last), and a plant
            // that has ended the scenario ends the replay. One: the plant
            // cycle after it is a period later (a damaged log's times,
            // saturated at the clock's end, would stay at this instant
            // for ever)
            if !finished && plant_t.at(s).0 <= c.now {
                finished = plant_cycle(&mut s, &mut commands, &mut frames);
            }
            if finished {
                break;
            }
        }
        if !subscribed {
            // the frames sent before the loop's first drain never reached
            // it: the first it received is, of those sent before that
            // drain, the newest one equal to it (same data: the plant
            // before its start is the live one), else of its counter
            let from = match rx_logged {
                Some([]) => None,
                Some([f1, ..]) => Some(
                    frames
                        .iter()
                        .rposition(|(_, f)| f.id == f1.id && f.data == f1.data)
                        .or_else(|| {
                            frames.iter().rposition(|(_, f)| {
                                f.id == f1.id && counter_of(f) == counter_of(f1)
                            })
                        })
                        .unwrap_or(0),
                ),
                // by the stamps: the newest plant cycle's frames
                None => Some(frames.back().map_or(0, |&(q, _)| {
                    frames.iter().position(|&(p, _)| p == q).unwrap_or(0)
                })),
            };
            if let Some(from) = from {
                frames.drain(..from);
                subscribed = true;
            }
        }
        match rx_logged {
            Some(rx) => {
                // as many frames as the logged cycle drained, in the order
                // sent, each stamped when it was received
                while !finished && frames.len() < rx.len() {
                    finished = plant_cycle(&mut s, &mut commands, &mut frames);
                }
                for logged in rx {
                    let Some((_, mut f)) = frames.pop_front() else {
                        break;
                    };
                    f.stamp_ns = logged.stamp_ns;
                    bus_t.inject(f);
                }
            }
            None => {
                while let Some(&(q, mut f)) = frames.front() {
                    if plant_t.at(q).0 >= c.now {
                        break;
                    }
                    f.stamp_ns = c.now;
                    bus_t.inject(f);
                    frames.pop_front();
                }
            }
        }
        tclock.reset(c.now);
        tclock.push(c.now);
        tclock.push(c.done);
        let mut road = Road::of(taken.of(k), roads);
        lp.cycle(&c.tick, &tclock, &mut bus_t, &mut road, &mut outs);
        let sent = if early.contains(&k) { c.now } else { c.done };
        for f in bus_t.take_sent() {
            commands.push_back((sent, f));
        }
        k += 1;
    }
    if finished && let Some(can) = &can {
        for f in &can.tail_tx {
            lp.shutdown(f.stamp_ns, &mut bus_t, &mut outs);
        }
    }
    ClosedLoop {
        truth: truths.0,
        outs,
        agreed: agreed.get(),
        diverged_at: diverged_at.get(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(seq: u64, stamp_ns: u64, x: f64) -> GroundTruth {
        GroundTruth {
            seq,
            stamp_ns,
            v: 2.0,
            x,
            ..GroundTruth::zeroed()
        }
    }

    /// From rest the start is looked for from [`START_WINDOW`] cycles
    /// before the loop's first demand to the first sample that moved, and
    /// the candidate that reproduces the most of the log taken (of equals
    /// the latest); a drive that starts moving starts at its first moved
    /// sample without trying any; a probe that cannot run is named.
    #[test]
    fn a_start_from_rest_is_the_candidate_that_reproduces_the_log() {
        let ms = 1_000_000u64;
        // at rest until seq 120; the loop's demand first at its cycle 100
        let mut log = DriveLog {
            truth: (0..200)
                .map(|q| GroundTruth {
                    seq: q,
                    stamp_ns: q * ms,
                    omega: if q >= 120 { 0.5 } else { 0.0 },
                    ..GroundTruth::zeroed()
                })
                .collect(),
            cycles: (0..200)
                .map(|k| grip_msgs::CycleRecord {
                    stamp_ns: k * ms + 300_000,
                    demand: if k >= 100 { 10.0 } else { 0.0 },
                    ..grip_msgs::CycleRecord::default()
                })
                .collect(),
            ..DriveLog::default()
        };
        let mut tried = Vec::new();
        let start = plant_start(&log, 0, |c| {
            tried.push(c);
            // the true start 108 reproduces everything; 109 and 110 as much
            // of it as 108 up to a late divergence, the rest less
            Ok(match c {
                108 => 200,
                109 | 110 => 150,
                _ => c.min(100),
            })
        });
        assert_eq!(tried.first(), Some(&(100 - START_WINDOW)));
        assert_eq!(tried.last(), Some(&120));
        assert_eq!(
            start,
            PlantStart::Probed {
                seq: 108,
                moved: Some(120),
                tried: 71,
                agreed: (200, 200),
            }
        );
        assert_eq!(start.seq(), Some(108));
        assert!(
            start.line(ms).contains("12 ms before"),
            "{}",
            start.line(ms)
        );
        // of equals, the latest
        let start = plant_start(&log, 0, |c| Ok(if c >= 105 { 200 } else { 0 }));
        assert_eq!(start.seq(), Some(120));
        // a probe that cannot run: the first moved sample, and why
        let start = plant_start(&log, 0, |_| anyhow::bail!("no attachments"));
        assert_eq!(start.seq(), Some(120));
        assert!(
            start.line(ms).contains("no attachments"),
            "{}",
            start.line(ms)
        );
        // a demand 0.04 s after the start: the window moves back by as much
        let mut tried = Vec::new();
        let start = plant_start(&log, 40, |c| {
            tried.push(c);
            Ok(if c == 28 { 200 } else { 10 })
        });
        assert_eq!(tried.first(), Some(&(100 - 40 - START_WINDOW)));
        assert_eq!(tried.last(), Some(&(120 - 40)));
        assert_eq!(start.seq(), Some(28));
        // standing, then rolling before any demand (a hill start rolling
        // back while the driver waits): it started where it moved
        for g in &mut log.truth {
            g.omega = 0.0;
            g.x = if g.seq >= 60 {
                -0.001 * (g.seq - 59) as f64
            } else {
                0.0
            };
        }
        let start = plant_start(&log, 40, |_| panic!("probed a rolling start"));
        assert_eq!(start, PlantStart::Moved(Some(60)));
        // moving from the first sample: no probe
        for g in &mut log.truth {
            g.v = 2.0;
            g.x = if g.seq >= 30 {
                0.002 * (g.seq - 29) as f64
            } else {
                0.0
            };
        }
        let start = plant_start(&log, 0, |_| panic!("probed a moving start"));
        assert_eq!(start, PlantStart::Moved(Some(30)));
    }

    /// A cycle that woke late by most of a period made the timer skip the
    /// next deadline: the cycle after it steps two periods. Where the car
    /// moved, x says so (the late cycle itself stepped one); where it
    /// stands, the stamps do, and the skip again goes to the cycle after
    /// the late one. Past the log, a period apiece.
    #[test]
    fn skipped_periods_go_to_the_cycle_after_the_late_one() {
        let ms = 1_000_000u64;
        let step = 2.0e-3;
        // moving: seq 3 woke 0.95 ms late, seq 4 stepped two periods
        let moving = [
            sample(0, 10 * ms + 30_000, 0.0),
            sample(1, 11 * ms + 31_000, step),
            sample(2, 12 * ms + 29_000, 2.0 * step),
            sample(3, 13 * ms + 980_000, 3.0 * step),
            sample(4, 15 * ms + 30_000, 5.0 * step),
            sample(5, 16 * ms + 30_000, 6.0 * step),
        ];
        let t = PlantTimes::new(&moving, ms);
        let got: Vec<_> = (0..8).map(|s| t.at(s)).collect();
        assert_eq!(
            got,
            [
                (10 * ms + 30_000, 0),
                (11 * ms + 31_000, 0),
                (12 * ms + 29_000, 0),
                (13 * ms + 980_000, 0),
                (15 * ms + 30_000, 1),
                (16 * ms + 30_000, 0),
                (17 * ms + 30_000, 0),
                (18 * ms + 30_000, 0),
            ]
        );
        // standing (held): seq 2 woke over a period late
        let held: Vec<_> = [30_000, 1_031_000, 3_040_000, 4_030_000, 5_030_000]
            .iter()
            .enumerate()
            .map(|(s, &t)| GroundTruth {
                v: 0.0,
                ..sample(s as u64, 10 * ms + t, -1.0)
            })
            .collect();
        let t = PlantTimes::new(&held, ms);
        let skipped: Vec<_> = (0..5).map(|s| t.at(s).1).collect();
        assert_eq!(skipped, [0, 0, 0, 1, 0]);
    }

    /// Sequence numbers and stamps at the ends of their range (a damaged
    /// log's, which `check::truth` refuses before a replay; this is what a
    /// caller that did not check gets) map to times without overflow, and
    /// to no more skipped periods than plant-sim counts: every seq + 2^50
    /// overflowed `(q - s) * period` (the audit's panic), stamps at
    /// u64::MAX the time past the log, a stamp far ahead of its seq the
    /// skip.
    #[test]
    fn wild_seq_numbers_and_stamps_map_to_times_without_overflow() {
        let ms = 1_000_000u64;
        let q0 = 1u64 << 50;
        let far = [
            sample(q0, 1_000 * ms, 0.0),
            sample(q0 + 1, 1_001 * ms, 0.002),
        ];
        let t = PlantTimes::new(&far, ms);
        assert_eq!(t.at(0), (0, 0));
        assert_eq!(t.at(q0 + 1), (1_001 * ms, 0));
        assert_eq!(t.at(u64::MAX), (u64::MAX, 0));
        let end = [sample(0, u64::MAX - 5, 0.0), sample(1, u64::MAX, 0.002)];
        let t = PlantTimes::new(&end, ms);
        assert_eq!(t.at(7), (u64::MAX, 0));
        let ahead = [
            sample(0, 0, 0.0),
            sample(1, u64::MAX, 0.0),
            sample(2, u64::MAX, 0.0),
        ];
        let t = PlantTimes::new(&ahead, ms);
        assert_eq!(t.at(2), (u64::MAX, MAX_SKIPPED));
        // no period (a caller's): times, no division by zero
        assert_eq!(PlantTimes::new(&ahead, 0).at(0), (0, 0));
    }
}
