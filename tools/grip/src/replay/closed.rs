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

use std::collections::VecDeque;

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
}

/// plant-sim's cycles as the log's ground truth shows them.
struct PlantTimes {
    /// `(seq, stamp, periods skipped before it in all)` of every logged
    /// sample while the sequence numbers rise (a restarted plant ends it).
    cycles: Vec<(u64, u64, u64)>,
    period_ns: u64,
}

impl PlantTimes {
    fn new(truth: &[GroundTruth], period_ns: u64) -> Self {
        let mut seqs: Vec<&GroundTruth> = Vec::with_capacity(truth.len());
        for g in truth {
            if seqs.last().is_some_and(|p| g.seq <= p.seq) {
                break;
            }
            seqs.push(g);
        }
        let p = i128::from(period_ns);
        let dt = period_ns as f64 * 1e-9;
        // Each stamp less its seq's periods: the timer's phase plus the
        // wake-up latency plus a period per deadline skipped so far; above
        // the smallest, in whole periods, how late a cycle woke.
        let base = seqs
            .iter()
            .map(|g| i128::from(g.stamp_ns) - i128::from(g.seq) * p)
            .min()
            .unwrap_or(0);
        let late = |g: &GroundTruth| -> u64 {
            let x = i128::from(g.stamp_ns) - i128::from(g.seq) * p - base;
            u64::try_from(x / p).unwrap_or(0)
        };
        let mut cycles = Vec::with_capacity(seqs.len());
        let mut skipped = 0u64;
        for (i, g) in seqs.iter().enumerate() {
            if i > 0 {
                let prev = seqs[i - 1];
                // where the car moved, the periods it was stepped are on
                // record: x advanced by about V dt a period
                let v = 0.5 * (prev.v + g.v);
                let steps = (g.x - prev.x) / (v * dt);
                let n = steps.round();
                skipped =
                    if g.seq == prev.seq + 1 && v > 0.1 && n >= 1.0 && (steps - n).abs() < 0.25 {
                        skipped + n as u64 - 1
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
    /// (past the logged cycles: a period apiece, none skipped).
    fn at(&self, s: u64) -> (u64, u64) {
        let i = self.cycles.partition_point(|&(q, _, _)| q <= s);
        if i == 0 {
            let Some(&(q, t, _)) = self.cycles.first() else {
                return (s * self.period_ns, 0);
            };
            return (t.saturating_sub((q - s) * self.period_ns), 0);
        }
        let (q, t, k) = self.cycles[i - 1];
        if q == s {
            let before = if i >= 2 { self.cycles[i - 2].2 } else { k };
            return (t, k - before);
        }
        (t + (s - q) * self.period_ns, 0)
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
/// (module docs); the plant is asked to start in the cycle the logged
/// plant started (the first ground-truth sample that moved; it then also
/// waits for valid commands, as in the drive). The road estimates are the
/// logged (or arte's replayed) ones, handed over in the cycle the drive
/// took them: what the microphone heard on the logged drive (the acoustics
/// stay open loop). Runs until plant-sim ends the scenario, then the
/// logged cycles left and the shutdown command; at most twice the logged
/// cycles.
pub fn closed_loop(
    lp: &mut TcsLoop,
    plant: &mut PlantSim,
    log: &DriveLog,
    roads: &[RoadEstimate],
    period_ns: u64,
) -> ClosedLoop {
    let can = split_can(log).ok();
    let taken = taken_per_cycle(log);
    let plant_t = PlantTimes::new(&log.truth, period_ns);
    let nk = log.cycles.len();
    let last = log.cycles.last().copied().unwrap_or_default();
    let loop_at = |k: usize| -> LoopCycle {
        if let Some(c) = log.cycles.get(k) {
            let woke = c.stamp_ns.wrapping_add_signed(c.wakeup_latency_ns);
            let now = can.as_ref().map_or(woke, |can| can.tx[k].stamp_ns);
            LoopCycle {
                tick: CycleTick {
                    deadline_ns: c.stamp_ns,
                    woke_ns: woke,
                    deadline_misses: c.deadline_misses,
                },
                now,
                done: woke + c.compute_ns,
                rx: can.as_ref().map(|can| can.rx[k].as_slice()),
            }
        } else {
            let d = last.stamp_ns + (k + 1 - nk) as u64 * period_ns;
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
    // the cycle the live plant started: its first sample that moved
    let start_seq = log.truth.first().and_then(|f| {
        log.truth
            .iter()
            .find(|g| g.x != f.x || g.v != f.v || g.omega != f.omega)
            .map(|g| g.seq)
    });

    let pclock = ScriptClock::default();
    let tclock = ScriptClock::default();
    let mut bus_p = MemBus::new();
    let mut bus_t = MemBus::new();
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
        *s += 1;
        o == Outcome::Finished
    };

    let mut k = 0usize;
    while k < nk * 2 && (!finished || k < nk) {
        let c = loop_at(k);
        let rx_logged = c.rx;
        // the plant cycles that ran before this loop cycle's drain
        while !finished && plant_t.at(s).0 < c.now {
            finished = plant_cycle(&mut s, &mut commands, &mut frames);
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
        for f in bus_t.take_sent() {
            commands.push_back((c.done, f));
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
}
