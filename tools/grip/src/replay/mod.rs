//! `grip replay`: a recorded drive's inputs through the services' own code.
//!
//! - arte: every logged audio block through the arte service's
//!   [`ArteLoop::on_block`], built by the service's own start-up
//!   ([`grip_arte_svc::prepare_with_clock`]) from the drive's configuration.
//!   Its inputs besides the block are the tcs-loop cycle record whose speed
//!   it held (found exactly: the record whose odometer extrapolation gives
//!   the logged estimate's `x_from` and `x_to` bit for bit) and the clock
//!   (scripted: the logged estimates' `stamp_ns`).
//! - tcs-loop: every logged cycle through [`TcsLoop::cycle`], built by the
//!   service's own [`grip_tcs_loop::build`], on a scripted clock (`now` =
//!   the cycle's logged TorqueCommand stamp, which is the loop's `now`; the
//!   second reading = wake-up + the logged compute time), with a tick of
//!   the logged deadline, wake-up latency and miss count, an in-memory CAN
//!   bus ([`MemBus`]) fed the RX frames the cycle logged (the frames between
//!   two TorqueCommands of the CAN log), and the road estimate the cycle
//!   took (`CycleRecord::road_taken`).
//!
//! Open loop: the logged wheel speeds, vehicle speed and motor torque are
//! replayed as recorded; they do not react to a replayed torque command.

pub mod check;
mod closed;
pub mod compare;
pub mod config;

pub use closed::{closed_loop, command_races, plant_start};

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::path::Path;

use anyhow::{Context, bail};
use grip_arte_svc::{ArteCounters, ArteLoop, EstimateSink, odometer_at};
use grip_drive::DriveLog;
use grip_io::can::MemBus;
use grip_io::clock::Clock;
use grip_io::mcaplog::{McapRecord, McapWriter, McapWriterOptions};
use grip_msgs::{
    AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, can_dir, can_flags, topics,
};
use grip_tcs_loop::{CycleTick, RecordSink, RoadSource, TcsLoop};

/// A clock that returns the times it was given, in order, then repeats
/// the last one: each reading the replayed code makes is the one the live
/// code made.
#[derive(Debug, Default)]
pub struct ScriptClock {
    times: RefCell<VecDeque<u64>>,
    last: Cell<u64>,
}

impl ScriptClock {
    /// Queues `t` as the next reading.
    pub fn push(&self, t: u64) {
        self.times.borrow_mut().push_back(t);
    }
    /// Forgets unread times; later readings repeat `t`.
    pub fn reset(&self, t: u64) {
        self.times.borrow_mut().clear();
        self.last.set(t);
    }
}

impl Clock for ScriptClock {
    fn now_ns(&self) -> u64 {
        if let Some(t) = self.times.borrow_mut().pop_front() {
            self.last.set(t);
        }
        self.last.get()
    }
    fn sleep_until_ns(&self, deadline_ns: u64) -> u64 {
        self.reset(deadline_ns.max(self.last.get()));
        self.last.get()
    }
}

/// Collects what arte publishes.
#[derive(Debug, Default)]
struct Estimates(Vec<RoadEstimate>);

impl EstimateSink for Estimates {
    fn send(&mut self, e: &RoadEstimate) -> Result<(), grip_io::ipc::IpcError> {
        self.0.push(*e);
        Ok(())
    }
}

/// How the speed record of a block was found.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct SpeedMatch {
    /// Blocks whose record was found exactly (from their estimates' `x_from`/`x_to`).
    pub exact: u64,
    /// Blocks whose estimates had no speed (NaN odometer span).
    pub none: u64,
    /// Blocks with estimates whose record was not found (approximated by
    /// the newest valid record before the estimate: replay may differ).
    pub approximated: u64,
    /// Arte's per-block counters over the replayed blocks.
    pub blocks: BlockCounts,
}

/// What arte's per-block counters said of the replayed blocks (`grip
/// replay`'s report, `--json` and `--out` log carry them; non-zero counts
/// are also printed as a warning by [`replay_arte`]).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct BlockCounts {
    /// Blocks refused for a sample rate other than the model's.
    pub rate_mismatch: u64,
    /// The last refused rate, Hz.
    pub bad_rate: u64,
    /// Blocks not classified: digital silence or near it.
    pub silent: u64,
    /// Blocks not classified: clipped.
    pub clipped: u64,
    /// Blocks not classified: a new capture overrun, or within the hold
    /// after one.
    pub xrun: u64,
    /// Blocks dropped unclassified: their audio older than `[input]
    /// max_lag_s` when arte took them.
    pub stale: u64,
}

impl BlockCounts {
    /// The counts of `stats`.
    pub fn of(stats: &ArteCounters) -> Self {
        use std::sync::atomic::Ordering::Relaxed;
        Self {
            rate_mismatch: stats.rate_mismatch.load(Relaxed),
            bad_rate: stats.bad_rate.load(Relaxed),
            silent: stats.silent_blocks.load(Relaxed),
            clipped: stats.clipped_blocks.load(Relaxed),
            xrun: stats.xrun_blocks.load(Relaxed),
            stale: stats.stale_blocks.load(Relaxed),
        }
    }

    /// Adds `other`'s counts (several logs' blocks as one: `grip generate`'s
    /// total): every count summed, `bad_rate` the largest rate refused
    /// (it was the last log's, so the line changed with the logs' order). Every
    /// field is named here, so a count added to this type cannot be left out
    /// of a sum.
    pub fn add(&mut self, other: &Self) {
        let Self {
            rate_mismatch,
            bad_rate,
            silent,
            clipped,
            xrun,
            stale,
        } = *other;
        self.rate_mismatch += rate_mismatch;
        if rate_mismatch > 0 {
            self.bad_rate = self.bad_rate.max(bad_rate);
        }
        self.silent += silent;
        self.clipped += clipped;
        self.xrun += xrun;
        self.stale += stale;
    }

    /// The counts for `grip replay --json` (`blocks`: the blocks replayed;
    /// `model_rate`: the model's rate, Hz): every count, zero or not.
    pub fn json(&self, blocks: usize, model_rate: u32) -> serde_json::Value {
        serde_json::json!({
            "blocks": blocks,
            "model_rate_hz": model_rate,
            "rate_mismatch": self.rate_mismatch,
            "refused_rate_hz": (self.rate_mismatch > 0).then_some(self.bad_rate),
            "silent": self.silent,
            "clipped": self.clipped,
            "xrun": self.xrun,
            "stale": self.stale,
        })
    }

    /// The non-zero counts as one line (`None` when all are zero), for a
    /// report (`model_rate`: the model's rate, Hz, when one model).
    pub fn line(&self, blocks: usize, model_rate: Option<u32>) -> Option<String> {
        let mut parts = Vec::new();
        if self.rate_mismatch > 0 {
            parts.push(match model_rate {
                Some(m) => format!(
                    "{} refused for their sample rate ({} Hz; the model expects {m} Hz)",
                    self.rate_mismatch, self.bad_rate
                ),
                None => format!(
                    "{} refused for their sample rate (e.g. {} Hz)",
                    self.rate_mismatch, self.bad_rate
                ),
            });
        }
        if self.silent > 0 {
            parts.push(format!("{} silent", self.silent));
        }
        if self.clipped > 0 {
            parts.push(format!("{} clipped", self.clipped));
        }
        if self.xrun > 0 {
            parts.push(format!("{} at or after a capture overrun", self.xrun));
        }
        if self.stale > 0 {
            parts.push(format!("{} stale (older than max_lag_s)", self.stale));
        }
        (!parts.is_empty()).then(|| {
            format!(
                "arte's blocks not classified, of {blocks}: {}",
                parts.join(", ")
            )
        })
    }
}

/// The recorded estimates by their sequence number as a cycle names the one
/// it took (`road_taken` - 1): index lists in log order. A cycle's estimate
/// is then found among the few of its number (numbers restart with arte)
/// instead of by scanning every estimate for every cycle, which took replay
/// quadratic time in a log's length (about 30 s per pass for an hour of
/// drive at 40 estimates/s, hours for a day).
struct RoadsBySeq(std::collections::HashMap<u32, Vec<usize>>);

impl RoadsBySeq {
    fn new(roads: &[RoadEstimate]) -> Self {
        let mut m: std::collections::HashMap<u32, Vec<usize>> = std::collections::HashMap::new();
        for (i, e) in roads.iter().enumerate() {
            m.entry(e.seq as u32).or_default().push(i);
        }
        Self(m)
    }

    /// The index of the estimate numbered `seq` stamped nearest `now` (the
    /// first in log order among equally near ones), if any.
    fn nearest(&self, roads: &[RoadEstimate], seq: u32, now: u64) -> Option<usize> {
        self.0
            .get(&seq)?
            .iter()
            .copied()
            .min_by_key(|&i| roads[i].stamp_ns.abs_diff(now))
    }
}

/// The newest valid cycle record at or before `t_ns`.
fn newest_valid(cycles: &[CycleRecord], t_ns: u64) -> Option<&CycleRecord> {
    let i = cycles.partition_point(|c| c.stamp_ns <= t_ns);
    cycles[..i]
        .iter()
        .rev()
        .take(2000)
        .find(|c| c.v_valid == 1 && c.v.is_finite())
}

/// Whether arte, holding cycle record `c`, gives every estimate of
/// `group` (one block's: arte extrapolates them all from the record it
/// held for the block) its `x_from` and `x_to` bit for bit.
fn reproduces(c: &CycleRecord, group: &[RoadEstimate]) -> bool {
    if c.v_valid != 1 || !c.v.is_finite() || !c.odometer.is_finite() {
        return false;
    }
    let v = c.v.abs();
    group.iter().all(|e| {
        odometer_at(c.odometer, v, c.stamp_ns, e.frame_t0_ns).to_bits() == e.x_from.to_bits()
            && odometer_at(c.odometer, v, c.stamp_ns, e.frame_t1_ns).to_bits() == e.x_to.to_bits()
    })
}

/// The cycle record arte held for a block whose estimates are `group`:
/// the one it already holds (`held`, handed for an earlier block) if that
/// gives their spans exactly (arte took no newer valid record meanwhile),
/// else the newest record stamped before the block's first estimate that
/// gives them exactly. Several records may give the same spans bit for bit (a steady speed):
/// the newest of them, taken for every block before 2026-12-06, could be
/// newer than the record arte held for a later block, whose own (older)
/// record `ArteLoop::on_cycle` then refused (it keeps a fresh record
/// against an older one): that block's estimates were extrapolated from
/// the newer record, an ulp off the log.
fn record_of(
    cycles: &[CycleRecord],
    group: &[RoadEstimate],
    held: Option<&CycleRecord>,
) -> Option<CycleRecord> {
    let e = group.first()?;
    if let Some(h) = held
        && reproduces(h, group)
    {
        return Some(*h);
    }
    let i = cycles.partition_point(|c| c.stamp_ns <= e.stamp_ns);
    cycles[..i]
        .iter()
        .rev()
        .take(2000)
        .copied()
        .find(|c| reproduces(c, group))
}

fn block_ns(b: &AudioBlock) -> u64 {
    (u128::from(b.n_samples) * 1_000_000_000 / u128::from(b.sample_rate.max(1))) as u64
}

/// The audio blocks arte processed, `first..last` of the log's: the
/// recorder starts before arte and stops after it, so the log holds blocks
/// arte never saw. Arte's first block is the one from which its estimator,
/// filling its first frame, decides exactly at the first logged estimate's
/// `frame_t1_ns`; its last is the one holding the last logged estimate's
/// frame end (blocks after it produced nothing that was logged). Without
/// estimates: every block.
pub fn arte_window(log: &DriveLog) -> (usize, usize) {
    let blocks = &log.audio_blocks;
    let (Some(e0), Some(e1)) = (log.roads.first(), log.roads.last()) else {
        return (0, blocks.len());
    };
    let last = blocks
        .iter()
        .position(|b| {
            b.stamp_ns < e1.frame_t1_ns && e1.frame_t1_ns <= b.stamp_ns.saturating_add(block_ns(b))
        })
        .map_or(blocks.len(), |i| i + 1);
    let first = (0..last)
        .find(|&i| {
            let fs = u128::from(blocks[i].sample_rate.max(1));
            // the frame length in samples, from the estimate's span
            let frame = (u128::from(e0.frame_t1_ns.saturating_sub(e0.frame_t0_ns)) * fs)
                .div_ceil(1_000_000_000);
            let mut before = 0u128;
            for b in &blocks[i..last] {
                let n = u128::from(b.n_samples);
                if before + n >= frame {
                    let t1 = b
                        .stamp_ns
                        .saturating_add(((frame - before) * 1_000_000_000 / fs) as u64);
                    return t1 == e0.frame_t1_ns;
                }
                before += n;
            }
            false
        })
        .unwrap_or(0);
    (first, last)
}

/// Runs the logged audio blocks arte processed ([`arte_window`]) through
/// `lp` (see the module docs); returns the estimates in publication order.
pub fn replay_arte<C: grip_arte::stream::Classify>(
    lp: &mut ArteLoop<C, &ScriptClock>,
    clock: &ScriptClock,
    log: &DriveLog,
    matched: &mut SpeedMatch,
) -> Vec<RoadEstimate> {
    let stats = ArteCounters::default();
    let mut out = Estimates(Vec::with_capacity(log.roads.len() + 16));
    let mut k = 0usize; // next logged estimate
    let (first, last) = arte_window(log);
    // the cycle record arte holds (the last one handed to it)
    let mut held: Option<CycleRecord> = None;
    for b in &log.audio_blocks[first..last] {
        let end = b.stamp_ns.saturating_add(block_ns(b));
        let first = k;
        while k < log.roads.len() && log.roads[k].frame_t1_ns <= end {
            k += 1;
        }
        let group = &log.roads[first..k];
        clock.reset(end);
        if let Some(e) = group.first() {
            if e.x_from.is_finite() && e.x_to.is_finite() {
                let r = match record_of(&log.cycles, group, held.as_ref()) {
                    Some(r) => {
                        matched.exact += 1;
                        Some(r)
                    }
                    None => {
                        matched.approximated += 1;
                        newest_valid(&log.cycles, e.stamp_ns).copied()
                    }
                };
                if let Some(r) = r {
                    if held.is_some_and(|h| r.stamp_ns < h.stamp_ns) {
                        // older than the record handed before (which was
                        // then a guess too new): `on_cycle` takes it as it
                        // takes any record once the kept one is stale
                        clock.push(u64::MAX / 2);
                    }
                    lp.on_cycle(&r, &stats);
                    held = Some(r);
                    // the reading `current_speed` makes: the record is fresh
                    clock.push(r.stamp_ns);
                }
            } else {
                matched.none += 1;
                // no fresh speed: a reading far from any record's stamp
                clock.push(u64::MAX / 2);
            }
            for e in group {
                clock.push(e.stamp_ns);
            }
        }
        lp.on_block(b, &mut out, &stats);
    }
    matched.blocks = BlockCounts::of(&stats);
    if let Some(l) = matched.blocks.line(last - first, Some(lp.sample_rate())) {
        eprintln!("warning: {}: {l}", log.path.display());
    }
    out.0
}

/// Feeds the loop the estimates a cycle took, in the order taken.
#[derive(Debug, Default)]
struct Road(std::collections::VecDeque<RoadEstimate>);

impl Road {
    /// The estimates `taken` names (indices into `roads`), in order.
    fn of(taken: &[usize], roads: &[RoadEstimate]) -> Self {
        Self(
            taken
                .iter()
                .filter_map(|&i| roads.get(i))
                .copied()
                .collect(),
        )
    }
}

impl RoadSource for Road {
    fn poll_next(&mut self) -> Option<RoadEstimate> {
        self.0.pop_front()
    }
}

/// Collects the loop's outputs.
#[derive(Debug, Default)]
pub struct Outputs {
    /// Cycle records.
    pub cycles: Vec<CycleRecord>,
    /// CAN log copies (RX and TX), in publication order.
    pub can: Vec<CanFrame>,
}

impl RecordSink for Outputs {
    fn cycle(&mut self, rec: &CycleRecord) {
        self.cycles.push(*rec);
    }
    fn can(&mut self, frame: &CanFrame) {
        self.can.push(*frame);
    }
}

/// How the cycles' road estimates were found.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct RoadMatch {
    /// Estimates that a cycle's `road_taken` and `roads_taken` named and
    /// the log holds.
    pub recorded: u64,
    /// Cycles of a log without `road_taken` given the newest estimate
    /// stamped since the previous cycle (the live poll raced the stamp).
    pub inferred: u64,
    /// Estimates a cycle named that the log does not hold.
    pub missing: u64,
}

/// The logged CAN log split per cycle: the RX frames each cycle drained,
/// each cycle's TorqueCommand, and the frames after the last cycle (the
/// shutdown command).
#[derive(Debug, Default)]
pub struct CanPerCycle {
    /// RX frames of each cycle.
    pub rx: Vec<Vec<CanFrame>>,
    /// TX frame of each cycle.
    pub tx: Vec<CanFrame>,
    /// TX frames after the last cycle.
    pub tail_tx: Vec<CanFrame>,
}

/// Splits `log.can` at the TX frames: cycle k drained the RX frames logged
/// between its predecessor's TorqueCommand and its own (the rule of
/// [`grip_drive::log::commands_before`]). RX frames after the last cycle's
/// command were drained by no cycle of the log and are left out. A log
/// whose cycles cannot be aligned with its commands, or whose cycle
/// records or commands carry a time no drive logs ([`check::cycles`],
/// [`check::commands`]), is refused.
pub fn split_can(log: &DriveLog) -> anyhow::Result<CanPerCycle> {
    check::cycles(log)?;
    let n = log.cycles.len();
    let drained_by = grip_drive::log::commands_before(&log.can);
    let mut s = CanPerCycle {
        rx: vec![Vec::new(); n],
        ..CanPerCycle::default()
    };
    for (f, k) in log.can.iter().zip(drained_by) {
        if f.direction == can_dir::TX {
            if k < n {
                s.tx.push(*f);
            } else {
                s.tail_tx.push(*f);
            }
        } else if k < n {
            s.rx[k].push(*f);
        }
    }
    // one list per command (an incomplete log is refused below)
    s.rx.truncate(s.tx.len());
    if s.tx.len() != log.cycles.len() {
        bail!(
            "{}: {} cycle records but {} transmitted frames: the CAN log is incomplete, the cycles cannot be aligned",
            log.path.display(),
            log.cycles.len(),
            s.tx.len()
        );
    }
    check::commands(log, &s)?;
    Ok(s)
}

/// Runs every logged cycle through `lp` (see the module docs) with the road
/// estimates `roads` (the logged ones, or arte's replayed ones: same
/// positions); returns the outputs.
pub fn replay_tcs(
    lp: &mut TcsLoop,
    log: &DriveLog,
    can: &CanPerCycle,
    roads: &[RoadEstimate],
    matched: &mut RoadMatch,
) -> Outputs {
    let clock = ScriptClock::default();
    let mut bus = MemBus::new();
    let mut out = Outputs {
        cycles: Vec::with_capacity(log.cycles.len()),
        can: Vec::with_capacity(log.can.len()),
    };
    let taken = taken_per_cycle(log);
    *matched = taken.matched;
    for (k, c) in log.cycles.iter().enumerate() {
        let now = can.tx[k].stamp_ns;
        // saturating (`split_can` refuses a log whose times overflow here)
        let woke = c.stamp_ns.saturating_add_signed(c.wakeup_latency_ns);
        clock.reset(now);
        clock.push(now);
        clock.push(woke.saturating_add(c.compute_ns));
        for f in &can.rx[k] {
            let mut f = *f;
            f.flags &= !can_flags::E2E_REJECTED;
            bus.inject(f);
        }
        let mut road = Road::of(taken.of(k), roads);
        let tick = CycleTick {
            deadline_ns: c.stamp_ns,
            woke_ns: woke,
            deadline_misses: c.deadline_misses,
        };
        lp.cycle(&tick, &&clock, &mut bus, &mut road, &mut out);
        bus.clear_sent();
    }
    for f in &can.tail_tx {
        lp.shutdown(f.stamp_ns, &mut bus, &mut out);
    }
    out
}

/// The estimates each logged cycle took: indices into `log.roads`, in the
/// order taken.
#[derive(Debug, Default, Clone)]
pub struct Taken {
    /// Every cycle's indices, one after another.
    flat: Vec<usize>,
    /// Where each cycle's indices end in `flat`.
    ends: Vec<usize>,
    /// How they were found.
    pub matched: RoadMatch,
}

impl Taken {
    /// The estimates cycle `k` took (none past the last cycle).
    pub fn of(&self, k: usize) -> &[usize] {
        let Some(&end) = self.ends.get(k) else {
            return &[];
        };
        let start = if k == 0 { 0 } else { self.ends[k - 1] };
        &self.flat[start..end]
    }

    /// Whether the log predates `CycleRecord::roads_taken`: a cycle took an
    /// estimate but none says how many (that loop took the newest only).
    pub fn predates_count(log: &DriveLog) -> bool {
        log.cycles.iter().any(|c| c.road_taken != 0)
            && log.cycles.iter().all(|c| c.roads_taken == 0)
    }
}

/// For each logged cycle, the estimates it took: `roads_taken` of them
/// ending at the one `road_taken` names (its sequence number and those
/// before it, each the one of its number stamped nearest the cycle; in a
/// log from before `roads_taken` the named one alone); in a log from
/// before `road_taken` the newest estimate stamped since the previous
/// cycle.
pub fn taken_per_cycle(log: &DriveLog) -> Taken {
    let recorded = log.cycles.iter().any(|c| c.road_taken != 0);
    let split = split_can(log).ok();
    let now_of = |k: usize| {
        split
            .as_ref()
            .and_then(|s| s.tx.get(k))
            .map_or(log.cycles[k].stamp_ns, |f| f.stamp_ns)
    };
    let by_seq = RoadsBySeq::new(&log.roads);
    let mut out = Taken {
        flat: Vec::with_capacity(log.roads.len()),
        ends: Vec::with_capacity(log.cycles.len()),
        matched: RoadMatch::default(),
    };
    let mut next = 0usize;
    for (k, c) in log.cycles.iter().enumerate() {
        let now = now_of(k);
        if recorded {
            if c.road_taken != 0 {
                let newest = c.road_taken - 1;
                let n = u32::from(c.roads_taken.max(1));
                for back in (0..n).rev() {
                    match by_seq.nearest(&log.roads, newest.wrapping_sub(back), now) {
                        Some(i) => {
                            out.flat.push(i);
                            out.matched.recorded += 1;
                        }
                        None => out.matched.missing += 1,
                    }
                }
            }
        } else {
            let mut newest = None;
            while next < log.roads.len() && log.roads[next].stamp_ns <= now {
                newest = Some(next);
                next += 1;
            }
            if let Some(i) = newest {
                out.flat.push(i);
                out.matched.inferred += 1;
            }
        }
        out.ends.push(out.flat.len());
    }
    out
}

/// [`write_log_with`] without extra attachments (the tests' writer).
#[cfg(test)]
pub fn write_log(
    path: &Path,
    log: &DriveLog,
    truth: &[GroundTruth],
    cycles: &[CycleRecord],
    can: &[CanFrame],
    roads: &[RoadEstimate],
    replay: &std::collections::BTreeMap<String, String>,
) -> anyhow::Result<()> {
    write_log_with(path, log, (truth, cycles, can, roads), replay, &[])
}

/// Writes a log with the same topics: the replayed cycles, CAN log and
/// road estimates, `truth` (the logged or the re-simulated) and the logged
/// audio; `grip.run` and the
/// attachments copied, `replay` as the `grip.replay` metadata record (none
/// when it is empty), and `extra` attached after the log's own
/// attachments (`grip replay --out`: its vehicle file when it is not the
/// source's, [`grip_drive::plan::REPLAY_VEHICLE_ATTACHMENT`]).
pub fn write_log_with(
    path: &Path,
    log: &DriveLog,
    (truth, cycles, can, roads): (&[GroundTruth], &[CycleRecord], &[CanFrame], &[RoadEstimate]),
    replay: &std::collections::BTreeMap<String, String>,
    extra: &[(String, Vec<u8>)],
) -> anyhow::Result<()> {
    let mut w = McapWriter::create(path, McapWriterOptions::default())
        .with_context(|| format!("creating {}", path.display()))?;
    for (name, map) in &log.metadata {
        if name != "grip.clock" && name != "grip.recorder" {
            w.write_metadata(name, map)?;
        }
    }
    // an empty record would mark a rewritten log (a test's fixture) as a
    // replay's output, which `grip replay` refuses; a replay always has
    // its source and mode
    if !replay.is_empty() {
        w.write_metadata("grip.replay", replay)?;
    }
    for (name, data) in &log.attachments {
        w.attach_bytes(name, "application/octet-stream", data)?;
    }
    for (name, data) in extra {
        if !log.attachments.contains_key(name) {
            w.attach_bytes(name, "application/octet-stream", data)?;
        }
    }
    // merge by stamp, keeping each topic's own order
    let mut heads = [0usize; 5];
    let lens = [
        cycles.len(),
        can.len(),
        roads.len(),
        truth.len(),
        log.audio_blocks.len(),
    ];
    let stamp = |t: usize, i: usize| match t {
        0 => cycles[i].stamp_ns,
        1 => can[i].stamp_ns,
        2 => roads[i].stamp_ns,
        3 => truth[i].stamp_ns,
        _ => log.audio_blocks[i].stamp_ns,
    };
    loop {
        let next = (0..5)
            .filter(|&t| heads[t] < lens[t])
            .min_by_key(|&t| stamp(t, heads[t]));
        let Some(t) = next else { break };
        let i = heads[t];
        match t {
            0 => w.write(topics::CYCLE, &cycles[i])?,
            1 => w.write(topics::CAN_LOG, &can[i])?,
            2 => w.write(topics::ROAD, &roads[i])?,
            3 => w.write(topics::TRUTH, &truth[i])?,
            _ => w.write(topics::AUDIO, &log.audio_blocks[i])?,
        }
        heads[t] += 1;
    }
    w.finish()?;
    Ok(())
}

/// A record as its JSON fields (the log's own encoding): what the
/// comparison walks, so new fields are compared without code here.
pub fn fields<T: McapRecord>(r: &T) -> serde_json::Map<String, serde_json::Value> {
    let mut buf = Vec::new();
    r.write_json(&mut buf);
    match serde_json::from_slice(&buf) {
        Ok(serde_json::Value::Object(m)) => m,
        _ => serde_json::Map::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The index finds what scanning every estimate found: the estimate of
    /// the number stamped nearest, the first in log order among equally
    /// near ones, also when numbers restart (arte restarted).
    #[test]
    fn estimates_by_number_find_what_the_scan_found() {
        let mut seed: u64 = 9;
        let mut next = |m: u64| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) % m
        };
        // three arte runs: numbers 0.. restart; stamps 10 ms apart, some equal
        let mut roads = Vec::new();
        let mut t = 0u64;
        for run in 0..3 {
            for k in 0..(40 + run * 7) {
                t += 10 * next(3);
                roads.push(RoadEstimate {
                    seq: k,
                    stamp_ns: t,
                    ..RoadEstimate::zeroed()
                });
            }
        }
        let idx = RoadsBySeq::new(&roads);
        let scan = |seq: u32, now: u64| {
            roads
                .iter()
                .enumerate()
                .filter(|(_, e)| e.seq as u32 == seq)
                .min_by_key(|(_, e)| e.stamp_ns.abs_diff(now))
                .map(|(i, _)| i)
        };
        let mut found = 0;
        for _ in 0..5000 {
            let (seq, now) = (next(60) as u32, next(t + 50));
            let got = idx.nearest(&roads, seq, now);
            assert_eq!(got, scan(seq, now), "seq {seq} at {now}");
            found += usize::from(got.is_some());
        }
        assert!(found > 3000, "{found}");
        assert_eq!(idx.nearest(&roads, 1000, 5), None);
    }

    /// Summed counts keep every kind of refusal, the overrun and stale
    /// blocks included, and the line names each.
    #[test]
    fn block_counts_add_up_every_count() {
        let a = BlockCounts {
            rate_mismatch: 2,
            bad_rate: 48_000,
            silent: 1,
            clipped: 0,
            xrun: 3,
            stale: 0,
        };
        let b = BlockCounts {
            rate_mismatch: 0,
            bad_rate: 0,
            silent: 0,
            clipped: 4,
            xrun: 1,
            stale: 5,
        };
        let mut sum = BlockCounts::default();
        sum.add(&a);
        sum.add(&b);
        assert_eq!(
            sum,
            BlockCounts {
                rate_mismatch: 2,
                bad_rate: 48_000,
                silent: 1,
                clipped: 4,
                xrun: 4,
                stale: 5,
            }
        );
        assert_eq!(
            sum.line(100, None).unwrap(),
            "arte's blocks not classified, of 100: 2 refused for their sample rate (e.g. 48000 Hz), 1 silent, 4 clipped, 4 at or after a capture overrun, 5 stale (older than max_lag_s)"
        );
    }

    /// A cycle that took a burst names its newest estimate and how many:
    /// the replay hands it all of them, in order, each the one of its
    /// number stamped nearest the cycle (numbers restart with arte); a log
    /// from before the count hands the named one alone; an estimate the
    /// log lacks is counted missing.
    #[test]
    fn a_cycle_that_took_a_burst_is_handed_the_whole_burst() {
        let est = |seq: u64, stamp_ms: u64| RoadEstimate {
            seq,
            stamp_ns: stamp_ms * 1_000_000,
            ..RoadEstimate::zeroed()
        };
        let cyc = |stamp_ms: u64, taken: Option<u64>, n: u8| CycleRecord {
            stamp_ns: stamp_ms * 1_000_000,
            road_taken: taken.map_or(0, |s| s as u32 + 1),
            roads_taken: n,
            ..CycleRecord::zeroed()
        };
        let mut log = DriveLog {
            // seq 1..=6 in a first arte run, then 1..=3 after a restart
            roads: vec![
                est(1, 10),
                est(2, 20),
                est(3, 400),
                est(4, 400),
                est(5, 400),
                est(6, 400),
                est(1, 2_000),
                est(2, 2_000),
                est(3, 2_000),
            ],
            cycles: vec![
                cyc(10, Some(1), 1),
                cyc(20, Some(2), 1),
                cyc(30, None, 0),
                cyc(400, Some(6), 4),
                cyc(2_000, Some(3), 3),
                cyc(2_001, Some(9), 2),
            ],
            ..DriveLog::default()
        };
        let t = taken_per_cycle(&log);
        let got: Vec<&[usize]> = (0..7).map(|k| t.of(k)).collect();
        assert_eq!(
            got,
            [&[0][..], &[1], &[], &[2, 3, 4, 5], &[6, 7, 8], &[], &[]]
        );
        // seq 9 and 8 are not in the log
        assert_eq!(
            t.matched,
            RoadMatch {
                recorded: 9,
                inferred: 0,
                missing: 2
            }
        );
        assert!(!Taken::predates_count(&log));
        // the same log from before roads_taken: the named estimate alone
        for c in &mut log.cycles {
            c.roads_taken = 0;
        }
        let t = taken_per_cycle(&log);
        assert_eq!(t.of(3), &[5]);
        assert_eq!(t.of(4), &[8]);
        assert!(Taken::predates_count(&log));
    }

    /// A stand-in classifier with fixed class probabilities.
    struct Toy {
        dim: usize,
    }

    impl grip_arte::stream::Classify for Toy {
        fn n_classes(&self) -> usize {
            2
        }
        fn n_features(&self) -> usize {
            self.dim
        }
        fn predict_proba(&mut self, _x: &[f64], out: &mut [f64]) {
            out.copy_from_slice(&[0.3, 0.7]);
        }
    }

    fn toy_arte(clock: &ScriptClock) -> ArteLoop<Toy, &ScriptClock> {
        use grip_arte::features::{FeatureConfig, FeatureSet};
        let fcfg = FeatureConfig::new(44_100, FeatureSet::Rich);
        let road = |name: &str| grip_arte_svc::ClassKnowledge {
            name: grip_msgs::name_to_bytes(name),
            lambda_opt: 0.1,
            mu_peak: 1.0,
            alpha: 0.9,
        };
        ArteLoop::new(
            Toy { dim: fcfg.dim() },
            &fcfg,
            &grip_arte::stream::StreamConfig::default(),
            vec![road("a"), road("b")],
            0.2,
            clock,
        )
        .unwrap()
    }

    /// Arte extrapolates a block's estimates from the cycle record it holds,
    /// and holds it until a newer one comes (`ArteLoop::on_cycle`); at a
    /// steady speed several records give an estimate's span bit for bit.
    /// A live arte that took a new record only every sixth block (its
    /// subscription drained late, as on a loaded machine), and held the
    /// last valid one while the loop's V was invalid, is replayed bit for
    /// bit: the replay keeps the record it handed while that still
    /// gives the spans. Taking the newest record that gives them for every
    /// block (before 2026-12-06) handed a newer record than arte held
    /// where an older one gave the same span, and then the older record a
    /// later block needed was refused: that block's `x_to` came out an ulp
    /// off (`grip replay` of a drive of a heavy car, `--arte off`, at the
    /// end of the drive).
    #[test]
    fn arte_holding_a_record_over_blocks_replays_bit_for_bit() {
        const T0: u64 = 5_000_000_000;
        const BLOCK: u64 = 441; // 10 ms at 44.1 kHz
        let mut ambiguous = 0;
        for (run, &v) in [4.28, 2.5, 7.77, 10.01, 13.9].iter().enumerate() {
            // tcs-loop's records: every 1 ms, a steady V, its odometer
            // summed a period at a time as the loop sums it; V invalid
            // for 40 ms in every 150 (its frames missing: the loop's safe
            // state), arte then holding the last valid record
            let mut cycles = Vec::new();
            let mut x = 1.5 * run as f64;
            for k in 0..2400u64 {
                let valid = k % 150 < 110;
                cycles.push(CycleRecord {
                    seq: k,
                    stamp_ns: T0 - 300_000_000 + k * 1_000_000 + 17_000,
                    v: if valid { v } else { f64::NAN },
                    v_valid: u8::from(valid),
                    odometer: x,
                    ..CycleRecord::zeroed()
                });
                x += v * 1e-3;
            }
            let blocks: Vec<AudioBlock> = (0..200u64)
                .map(|k| {
                    let mut b = AudioBlock::zeroed();
                    b.seq = k;
                    b.sample_rate = 44_100;
                    b.n_samples = BLOCK as u32;
                    b.stamp_ns = T0 + k * 10_000_000;
                    for (i, s) in b.samples[..BLOCK as usize].iter_mut().enumerate() {
                        *s = (((k * BLOCK + i as u64) * 7919) % 2000) as i16 - 1000;
                    }
                    b
                })
                .collect();
            // the live arte: a new record every sixth block, taken 3 ms
            // after the block ended
            let live_clock = ScriptClock::default();
            let mut live = toy_arte(&live_clock);
            let stats = ArteCounters::default();
            let mut sent = Estimates::default();
            let mut held_live = Vec::new();
            let mut held = None;
            for b in &blocks {
                let end = b.stamp_ns + block_ns(b);
                live_clock.reset(end + 3_000_000);
                if b.seq % 6 == 0 {
                    let r = *newest_valid(&cycles, b.stamp_ns).unwrap();
                    live.on_cycle(&r, &stats);
                    held = Some(r);
                }
                let before = sent.0.len();
                live.on_block(b, &mut sent, &stats);
                for e in &sent.0[before..] {
                    held_live.push((e.seq, held.unwrap()));
                }
            }
            let roads = sent.0;
            assert!(roads.len() > 50, "{} estimates", roads.len());
            // a newer record than the one held gives the span too
            for (seq, h) in &held_live {
                let e = &roads[*seq as usize];
                let span = |c: &CycleRecord| {
                    [e.frame_t0_ns, e.frame_t1_ns]
                        .map(|t| odometer_at(c.odometer, c.v, c.stamp_ns, t).to_bits())
                };
                ambiguous += usize::from(cycles.iter().any(|c| {
                    c.v_valid == 1
                        && c.stamp_ns > h.stamp_ns
                        && c.stamp_ns <= e.stamp_ns
                        && span(c) == [e.x_from.to_bits(), e.x_to.to_bits()]
                }));
            }
            let log = DriveLog {
                cycles,
                roads: roads.clone(),
                audio_blocks: blocks,
                ..DriveLog::default()
            };
            let clock = ScriptClock::default();
            let mut lp = toy_arte(&clock);
            let mut matched = SpeedMatch::default();
            let replayed = replay_arte(&mut lp, &clock, &log, &mut matched);
            assert_eq!(replayed.len(), roads.len(), "v {v}");
            assert_eq!(matched.approximated, 0, "v {v}");
            for (a, b) in roads.iter().zip(&replayed) {
                assert_eq!(
                    fields(a),
                    fields(b),
                    "v {v}: estimate {} replayed differently",
                    a.seq
                );
            }
        }
        // the case the test is about came up
        assert!(ambiguous > 10, "{ambiguous} ambiguous spans");
    }
}
