//! The inverter as the drive log shows it ([`Inverter`], [`inverter`]):
//! its `MotorStatus` frames on tcs-loop's CAN log (received, accepted by
//! the E2E check, decoded with the log's own protocol,
//! [`DriveLog::protocol`]), read for when it reported `Fault`, `Derating`,
//! `CmdTimeout` and not `Ready`, which `FaultCode`s it sent, and whether
//! the control loop was in its safe state during each fault (tcs-loop
//! enters it while the inverter reports `Fault`,
//! `services/tcs-loop/README.md`, "Safe state"; it does not act on the
//! other three).
//!
//! - **Episode**: consecutive accepted `MotorStatus` frames with the flag
//!   set; it begins at the first of them and ends at the next frame with
//!   the flag clear, or runs to the end of the log's `MotorStatus` frames
//!   (the last one still had it set: the episode then counts one frame
//!   period past that frame). A hole in the frames inside an episode is
//!   part of it: the inverter's last word was the flag.
//! - **Time**: s from the scenario start when the log has a scenario
//!   window (the summary's other sections' clock), else from the log's
//!   first message ([`DriveLog::first_stamp_ns`], `grip inspect --csv`'s
//!   `t_s`). Each episode says whether it lies before, in or after the
//!   scenario window (overlapping it counts as in it), and the section
//!   gives the scenario's episodes and the whole log's apart: a live drive's
//!   inverter (plant-sim) reports `Fault` and `CmdTimeout` with FaultCode
//!   0x01 until the loop's first command reaches it, and again when the
//!   commands stop after the drive.
//! - **From the first frame**: an episode that began at the inverter's
//!   first accepted frame is the state the inverter came up in, not a
//!   change seen during the drive; [`FlagEpisodes::entered`] counts the
//!   others (flag clear → set), what plant-sim counts as its
//!   command-timeout episodes and `grip inspect --json`'s
//!   `command_timeouts`.
//! - **Safe state during a fault**: the cycle records stamped in the
//!   episode, how many of them in the safe state (`safe_state`), from when,
//!   and whether the loop was in it already before the fault began (then
//!   something else put it there first: start-up, an input timeout).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use grip_io::can::protocol::{InverterMsg, MotorStatus, MsgKind, Protocol};
use grip_msgs::{CanFrame, CycleRecord, can_dir, can_flags};

use super::secs_between;
use crate::log::DriveLog;

/// Episodes listed per flag in the report (and in `--json`); all are
/// counted.
pub const LISTED: usize = 10;

/// A `MotorStatus` condition followed in episodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flag {
    /// `Fault` set.
    Fault,
    /// `Derating` set.
    Derating,
    /// `CmdTimeout` set (the inverter zeroed the torque: no valid command).
    CmdTimeout,
    /// `Ready` clear.
    NotReady,
}

impl Flag {
    /// The four, in report order.
    pub const ALL: [Flag; 4] = [
        Flag::Fault,
        Flag::Derating,
        Flag::CmdTimeout,
        Flag::NotReady,
    ];

    /// `fault`, `derating`, `cmd_timeout`, `not_ready` (`--json`'s keys).
    pub fn as_str(self) -> &'static str {
        match self {
            Flag::Fault => "fault",
            Flag::Derating => "derating",
            Flag::CmdTimeout => "cmd_timeout",
            Flag::NotReady => "not_ready",
        }
    }

    /// The report's words.
    pub fn words(self) -> &'static str {
        match self {
            Flag::Fault => "fault",
            Flag::Derating => "derating",
            Flag::CmdTimeout => "command timeout",
            Flag::NotReady => "not ready",
        }
    }

    /// Whether `m` reports it.
    pub fn of(self, m: &MotorStatus) -> bool {
        match self {
            Flag::Fault => m.fault,
            Flag::Derating => m.derating,
            Flag::CmdTimeout => m.cmd_timeout,
            Flag::NotReady => !m.ready,
        }
    }
}

/// Where an episode lies against the scenario window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// It ended at or before the window's start.
    Before,
    /// It overlaps the window.
    Scenario,
    /// It began at or after the window's end.
    After,
}

impl Place {
    /// `before`, `scenario`, `after` (`--json`).
    pub fn as_str(self) -> &'static str {
        match self {
            Place::Before => "before",
            Place::Scenario => "scenario",
            Place::After => "after",
        }
    }

    fn words(self) -> &'static str {
        match self {
            Place::Before => "before the scenario",
            Place::Scenario => "during the scenario",
            Place::After => "after the scenario",
        }
    }
}

/// The control loop during a fault episode (its cycle records stamped in
/// it).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SafeOverlap {
    /// Cycle records in the episode.
    pub cycles: u64,
    /// Of those, in the safe state.
    pub safe: u64,
    /// The cycle record just before the episode was in the safe state
    /// already (something else put the loop there first).
    pub safe_before: bool,
    /// The first safe-state cycle in the episode, s after the cycle that
    /// read its first frame (None: none).
    pub first_safe_after_s: Option<f64>,
}

impl SafeOverlap {
    /// The report's words.
    pub fn words(&self) -> String {
        let before = if self.safe_before {
            "; in it already before the fault began"
        } else {
            ""
        };
        let cyc = |n: u64| format!("{n} {}", if n == 1 { "cycle" } else { "cycles" });
        if self.cycles == 0 {
            "no cycle record of the loop during it".to_owned()
        } else if self.safe == 0 {
            format!("the loop NOT in its safe state ({})", cyc(self.cycles))
        } else if self.safe == self.cycles {
            format!(
                "the loop in its safe state throughout ({}{before})",
                cyc(self.cycles)
            )
        } else {
            format!(
                "the loop in its safe state in {} of its {}{}{before}",
                self.safe,
                cyc(self.cycles),
                self.first_safe_after_s.map_or(String::new(), |t| format!(
                    ", from {t:.3} s after the cycle that read it"
                ))
            )
        }
    }
}

/// One episode of a flag.
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    /// Its first frame, s from [`Inverter::origin_ns`].
    pub start_s: f64,
    /// The first frame with the flag clear again, s (None: still set in the
    /// log's last `MotorStatus` frame).
    pub end_s: Option<f64>,
    /// From its first frame to `end_s` (to one frame period after the last
    /// frame when it runs to the end), s.
    pub duration_s: f64,
    /// Its frames (the flag set).
    pub frames: u64,
    /// It began at the inverter's first accepted frame.
    pub at_first_frame: bool,
    /// Against the scenario window (None: the log has none).
    pub place: Option<Place>,
    /// The non-zero FaultCodes its frames carried, in order of appearance
    /// (fault episodes; empty for the others).
    pub codes: Vec<u8>,
    /// The loop during it (fault episodes only).
    pub safe: Option<SafeOverlap>,
}

impl Episode {
    /// One line of the report (no indent).
    pub fn line(&self) -> String {
        let frames = format!(
            "{} {}",
            self.frames,
            if self.frames == 1 { "frame" } else { "frames" }
        );
        let mut o = match self.end_s {
            Some(e) => format!(
                "{:.3} to {e:.3} s ({:.3} s, {frames})",
                self.start_s, self.duration_s
            ),
            None => format!(
                "{:.3} s to the end of the MotorStatus frames ({:.3} s, {frames}; still set in the last one)",
                self.start_s, self.duration_s
            ),
        };
        if let Some(p) = self.place {
            let _ = write!(o, ", {}", p.words());
        }
        if self.at_first_frame {
            o.push_str(", from the inverter's first frame");
        }
        if !self.codes.is_empty() {
            let c: Vec<String> = self.codes.iter().map(|c| format!("0x{c:02X}")).collect();
            let _ = write!(o, ", FaultCode {}", c.join(", "));
        }
        if let Some(s) = &self.safe {
            let _ = write!(o, ": {}", s.words());
        }
        o
    }
}

/// The episodes of one flag.
#[derive(Debug, Clone, PartialEq)]
pub struct FlagEpisodes {
    /// Which.
    pub flag: Flag,
    /// Episodes in the log.
    pub count: u64,
    /// Of those, the ones that began after the inverter's first frame
    /// (flag clear → set).
    pub entered: u64,
    /// Their time, s.
    pub time_s: f64,
    /// Episodes overlapping the scenario window and their time in it, s
    /// (None: no window).
    pub in_scenario: Option<(u64, f64)>,
    /// Episodes before, in and after the scenario window (zero without
    /// one).
    pub places: [u64; 3],
    /// Fault episodes with the loop in its safe state for all their cycle
    /// records (and at least one).
    pub safe_throughout: u64,
    /// Fault episodes: the loop's cycle records in them and, of those, the
    /// ones in the safe state ([`SafeOverlap`]'s `cycles` and `safe`),
    /// summed over every episode, listed or not (zero for the other flags).
    pub loop_cycles: (u64, u64),
    /// The same over the episodes overlapping the scenario window (each
    /// one's cycle records all counted, as [`SafeOverlap`] counts them;
    /// None: no window).
    pub loop_cycles_in_scenario: Option<(u64, u64)>,
    /// The first [`LISTED`] episodes, in time order.
    pub listed: Vec<Episode>,
}

/// A FaultCode the inverter sent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultCode {
    /// The code (non-zero: 0 is none).
    pub code: u8,
    /// Its first frame, s from [`Inverter::origin_ns`].
    pub first_s: f64,
    /// Frames carrying it.
    pub frames: u64,
}

/// What the log says of the inverter (see the module).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Inverter {
    /// CAN frames in the log (any id, direction, flags).
    pub can_frames: u64,
    /// `MotorStatus` frames tcs-loop received and the E2E check accepted:
    /// the ones read here.
    pub frames: u64,
    /// `MotorStatus` frames it received that the E2E check rejected (not
    /// read).
    pub rejected: u64,
    /// The origin of the times, ns: the scenario start, else the log's
    /// first message.
    pub origin_ns: u64,
    /// `origin_ns` is the scenario start.
    pub from_scenario_start: bool,
    /// The first and the last frame, s (None: no frame).
    pub span_s: Option<(f64, f64)>,
    /// The scenario window, s (None: none).
    pub window_s: Option<(f64, f64)>,
    /// Frames stamped in the scenario window (None: no window).
    pub frames_in_scenario: Option<u64>,
    /// Per flag, in [`Flag::ALL`] order (empty without frames).
    pub flags: Vec<FlagEpisodes>,
    /// The non-zero FaultCodes, by first appearance.
    pub codes: Vec<FaultCode>,
}

/// The inverter's `MotorStatus` frames of `log` in `protocol` (the log's
/// own, [`DriveLog::protocol`]); `window_ns` is the summary's scenario
/// window (None: none; the times are then from the log's first message).
pub fn inverter(log: &DriveLog, protocol: &Protocol, window_ns: Option<(u64, u64)>) -> Inverter {
    let spec = protocol.spec(MsgKind::MotorStatus);
    let origin_ns = window_ns.map_or_else(|| log.first_stamp_ns(), |w| w.0);
    let rel = |ns: u64| secs_between(origin_ns, ns);
    let mut inv = Inverter {
        can_frames: log.can.len() as u64,
        origin_ns,
        from_scenario_start: window_ns.is_some(),
        window_s: window_ns.map(|(a, b)| (rel(a), rel(b))),
        frames_in_scenario: window_ns.map(|_| 0),
        ..Inverter::default()
    };
    let other = can_flags::EXTENDED | can_flags::RTR | can_flags::ERROR;
    let mine = |f: &CanFrame| f.direction == can_dir::RX && f.id == spec.id && f.flags & other == 0;
    let drained_by = drained_by(&log.can, &log.cycles);
    // (stamp, content, the cycle that drained it when the log says)
    let frames: Vec<(u64, MotorStatus, Option<usize>)> = log
        .can
        .iter()
        .enumerate()
        .filter(|(_, f)| mine(f))
        .filter(|(_, f)| {
            let rejected = f.flags & can_flags::E2E_REJECTED != 0;
            inv.rejected += u64::from(rejected);
            !rejected
        })
        .filter_map(|(i, f)| match InverterMsg::decode_as(spec, &f.data) {
            InverterMsg::MotorStatus(m) => Some((f.stamp_ns, m, drained_by.as_ref().map(|d| d[i]))),
            _ => None,
        })
        .collect();
    // the cycle that read frame i: the log's own word, else from its stamp
    let reader = |i: usize| {
        frames[i]
            .2
            .unwrap_or_else(|| reader_by_stamp(&log.cycles, frames[i].0))
    };
    let (Some(first), Some(last)) = (frames.first(), frames.last()) else {
        return inv;
    };
    inv.frames = frames.len() as u64;
    inv.span_s = Some((rel(first.0), rel(last.0)));
    if let (Some(n), Some((ws, we))) = (inv.frames_in_scenario.as_mut(), window_ns) {
        *n = frames.iter().filter(|(t, ..)| (ws..we).contains(t)).count() as u64;
    }
    // the frames' period: what the last frame stands for
    let period = super::measured::median_period_ns(frames.iter().map(|(t, ..)| *t));
    let end_of_log = last.0.saturating_add(period);

    for flag in Flag::ALL {
        let mut fe = FlagEpisodes {
            flag,
            count: 0,
            entered: 0,
            time_s: 0.0,
            in_scenario: window_ns.map(|_| (0, 0.0)),
            places: [0; 3],
            safe_throughout: 0,
            loop_cycles: (0, 0),
            loop_cycles_in_scenario: window_ns.map(|_| (0, 0)),
            listed: Vec::new(),
        };
        // the open episode: (index of its first frame, frames, codes)
        let mut open: Option<(usize, u64, Vec<u8>)> = None;
        // `end`: the index of the first clear frame (None: still set in the
        // last one)
        let close =
            |fe: &mut FlagEpisodes, i0: usize, n: u64, codes: Vec<u8>, end_i: Option<usize>| {
                let s_ns = frames[i0].0;
                let end = end_i.map(|j| frames[j].0);
                let e_ns = end.unwrap_or(end_of_log);
                let duration_s = secs_between(s_ns, e_ns);
                fe.count += 1;
                fe.entered += u64::from(i0 > 0);
                fe.time_s += duration_s;
                let place = window_ns.map(|(ws, we)| {
                    if e_ns <= ws {
                        Place::Before
                    } else if s_ns >= we {
                        Place::After
                    } else {
                        Place::Scenario
                    }
                });
                if let Some(p) = place {
                    fe.places[p as usize] += 1;
                }
                if let (Some((n_in, t_in)), Some((ws, we))) = (fe.in_scenario.as_mut(), window_ns)
                    && place == Some(Place::Scenario)
                {
                    *n_in += 1;
                    *t_in += secs_between(s_ns.max(ws), e_ns.min(we)).max(0.0);
                }
                let last_i = (i0 + n as usize).saturating_sub(1).min(frames.len() - 1);
                let safe = (flag == Flag::Fault).then(|| {
                    let to = end_i.map_or_else(|| reader(last_i) + 1, reader);
                    safe_overlap(&log.cycles, reader(i0), to)
                });
                fe.safe_throughout +=
                    u64::from(safe.is_some_and(|s| s.cycles > 0 && s.safe == s.cycles));
                if let Some(s) = safe {
                    fe.loop_cycles.0 += s.cycles;
                    fe.loop_cycles.1 += s.safe;
                    if let Some(c) = fe.loop_cycles_in_scenario.as_mut()
                        && place == Some(Place::Scenario)
                    {
                        c.0 += s.cycles;
                        c.1 += s.safe;
                    }
                }
                if fe.listed.len() < LISTED {
                    fe.listed.push(Episode {
                        start_s: rel(s_ns),
                        end_s: end.map(rel),
                        duration_s,
                        frames: n,
                        at_first_frame: i0 == 0,
                        place,
                        codes,
                        safe,
                    });
                }
            };
        for (i, (_, m, _)) in frames.iter().enumerate() {
            let set = flag.of(m);
            if set {
                match open.as_mut() {
                    Some((_, n, _)) => *n += 1,
                    None => open = Some((i, 1, Vec::new())),
                }
            } else if let Some((i0, n, codes)) = open.take() {
                close(&mut fe, i0, n, codes, Some(i));
            }
            if flag == Flag::Fault
                && set
                && m.fault_code != 0
                && let Some((_, _, codes)) = open.as_mut()
                && !codes.contains(&m.fault_code)
            {
                codes.push(m.fault_code);
            }
        }
        if let Some((i0, n, codes)) = open.take() {
            close(&mut fe, i0, n, codes, None);
        }
        inv.flags.push(fe);
    }

    let mut codes: BTreeMap<u8, (usize, u64)> = BTreeMap::new();
    for (i, (_, m, _)) in frames.iter().enumerate() {
        if m.fault_code != 0 {
            codes.entry(m.fault_code).or_insert((i, 0)).1 += 1;
        }
    }
    let mut codes: Vec<(usize, FaultCode)> = codes
        .into_iter()
        .map(|(code, (i, n))| {
            (
                i,
                FaultCode {
                    code,
                    first_s: rel(frames[i].0),
                    frames: n,
                },
            )
        })
        .collect();
    codes.sort_by_key(|(i, _)| *i);
    inv.codes = codes.into_iter().map(|(_, c)| c).collect();
    inv
}

/// For each frame of the CAN log `can`, the cycle (index into `cycles`)
/// that drained it, when the log says: tcs-loop logs each cycle's received
/// frames and then its command (direction TX), so the frames before the
/// k-th command were drained by the k-th cycle (those after the last
/// cycle's, before the shutdown frames, by none: `cycles.len()`). Only
/// when the cycle records are contiguous (no lost record), there is a
/// command for each, and each is stamped between its cycle's deadline and
/// the next cycle's wake-up (tcs-loop stamps it with the cycle's clock,
/// and the next cycle wakes after it: a log whose commands are shifted by
/// a lost one fails this), else `None` (a log with lost messages, or not
/// tcs-loop's: the stamps must say).
fn drained_by(can: &[CanFrame], cycles: &[CycleRecord]) -> Option<Vec<usize>> {
    let first_seq = cycles.first()?.seq;
    let contiguous = cycles
        .iter()
        .enumerate()
        .all(|(k, c)| c.seq == first_seq.wrapping_add(k as u64));
    let mut commands = can.iter().filter(|f| f.direction == can_dir::TX);
    let aligned = cycles.iter().enumerate().all(|(k, c)| {
        commands.next().is_some_and(|tx| {
            tx.stamp_ns >= c.stamp_ns && cycles.get(k + 1).is_none_or(|n| tx.stamp_ns < woke(n))
        })
    });
    if !contiguous || !aligned {
        return None;
    }
    Some(
        crate::log::commands_before(can)
            .map(|k| k.min(cycles.len()))
            .collect(),
    )
}

/// The cycle that read a frame stamped `t` where the log does not say
/// ([`drained_by`]): a received frame is stamped with its arrival (the
/// kernel's receive time, the simulated bus's publish time), and a cycle
/// drains the bus right after it wakes (its record's deadline plus its
/// wake-up latency), so it is the first cycle woken at or after `t` (one
/// woken after a stall of the loop read what arrived during it); the
/// number of cycles if none woke after it. (Logs written before 2026-12-07
/// stamp a received frame when the loop read it, just after its cycle
/// woke: there it falls one cycle late.)
fn reader_by_stamp(cycles: &[CycleRecord], t: u64) -> usize {
    // log order is time order; a log out of order gives an odd count,
    // never a panic
    cycles.partition_point(|c| woke(c) < t)
}

/// When a cycle woke (and drained the bus): its deadline plus its wake-up
/// latency.
fn woke(c: &CycleRecord) -> u64 {
    c.stamp_ns.saturating_add_signed(c.wakeup_latency_ns)
}

/// The loop's cycles `[from, to)` that read an episode's frames: from the
/// one that read its first frame up to (not including) the one that read
/// the first clear frame, or, for an episode still open at the end, up to
/// and including the one that read its last frame.
fn safe_overlap(cycles: &[CycleRecord], from: usize, to: usize) -> SafeOverlap {
    let i0 = from.min(cycles.len());
    let i1 = to.max(i0).min(cycles.len());
    let inside = &cycles[i0..i1];
    let first_safe = inside.iter().find(|c| c.safe_state != 0);
    SafeOverlap {
        cycles: inside.len() as u64,
        safe: inside.iter().filter(|c| c.safe_state != 0).count() as u64,
        safe_before: i0 > 0 && cycles[i0 - 1].safe_state != 0,
        first_safe_after_s: first_safe
            .zip(inside.first())
            .map(|(c, f)| secs_between(f.stamp_ns, c.stamp_ns)),
    }
}

impl Inverter {
    /// No episode of any flag (and at least one frame).
    pub fn clean(&self) -> bool {
        self.frames > 0 && self.flags.iter().all(|f| f.count == 0)
    }

    /// The flag's episodes.
    pub fn flag(&self, flag: Flag) -> Option<&FlagEpisodes> {
        self.flags.iter().find(|f| f.flag == flag)
    }

    /// "fault 1 (0.200 s), derating 0, ..." from (flag, count, time).
    fn counts(items: impl Iterator<Item = (Flag, u64, f64)>) -> String {
        items
            .map(|(f, n, t)| {
                if n == 0 {
                    format!("{} 0", f.words())
                } else {
                    format!("{} {n} ({t:.3} s)", f.words())
                }
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The episode counts over the whole log, one line (no indent):
    /// `fault 1 (0.001 s), derating 0, command timeout 1 (0.001 s), not
    /// ready 0`.
    pub fn counts_whole_log(&self) -> String {
        Self::counts(self.flags.iter().map(|f| (f.flag, f.count, f.time_s)))
    }

    /// The episode counts overlapping the scenario window and their time
    /// in it (None: no window).
    pub fn counts_in_scenario(&self) -> Option<String> {
        let v: Option<Vec<(Flag, u64, f64)>> = self
            .flags
            .iter()
            .map(|f| f.in_scenario.map(|(n, t)| (f.flag, n, t)))
            .collect();
        v.map(|v| Self::counts(v.into_iter()))
    }

    /// `no MotorStatus frames in the log (why)` when it has none (None:
    /// it has some).
    pub fn absent(&self) -> Option<String> {
        if self.frames > 0 {
            return None;
        }
        let why = if self.can_frames == 0 {
            "no CAN frame logged".to_owned()
        } else if self.rejected > 0 {
            format!("{} received, all rejected by the E2E check", self.rejected)
        } else {
            format!(
                "{} CAN frames logged, none a MotorStatus frame tcs-loop received",
                self.can_frames
            )
        };
        Some(format!("no MotorStatus frames in the log ({why})"))
    }

    /// The report's section (a blank line, then the lines).
    pub fn render(&self) -> String {
        const CLEAN: &str = "ready throughout, no fault, derating or command timeout";
        let mut o = String::new();
        let rejected = if self.rejected > 0 {
            format!(
                "; {} more rejected by the E2E check, not read",
                self.rejected
            )
        } else {
            String::new()
        };
        if let Some(none) = self.absent() {
            let _ = writeln!(o, "\ninverter: {none}");
            return o;
        }
        if self.clean() {
            let _ = writeln!(
                o,
                "\ninverter: {CLEAN} in {} MotorStatus frames{rejected}",
                self.frames
            );
            return o;
        }
        let (a, b) = self.span_s.unwrap_or_default();
        let _ = writeln!(
            o,
            "\ninverter (its MotorStatus frames tcs-loop received and the E2E check accepted: {}, {a:.3} to {b:.3} s{rejected}; t from {})",
            self.frames,
            if self.from_scenario_start {
                "the scenario start"
            } else {
                "the log's first message (no scenario window)"
            }
        );
        if let (Some((w0, w1)), Some(n), Some(c)) = (
            self.window_s,
            self.frames_in_scenario,
            self.counts_in_scenario(),
        ) {
            let clean_in = self
                .flags
                .iter()
                .all(|f| f.in_scenario.is_none_or(|(n, _)| n == 0));
            let _ = writeln!(
                o,
                "  during the scenario ({w0:.3}-{w1:.3} s, {n} frames): {}",
                if n == 0 {
                    "no MotorStatus frame in it".to_owned()
                } else if clean_in {
                    CLEAN.to_owned()
                } else {
                    c
                }
            );
        }
        let _ = writeln!(o, "  whole log: {}", self.counts_whole_log());
        for f in self.flags.iter().filter(|f| f.count > 0) {
            let places = if self.window_s.is_some() {
                let p: Vec<String> = [Place::Before, Place::Scenario, Place::After]
                    .into_iter()
                    .filter(|p| f.places[*p as usize] > 0)
                    .map(|p| format!("{} {}", f.places[p as usize], p.words()))
                    .collect();
                format!(" ({})", p.join(", "))
            } else {
                String::new()
            };
            let _ = writeln!(
                o,
                "  {}: {} {}{places}",
                f.flag.words(),
                f.count,
                if f.count == 1 { "episode" } else { "episodes" }
            );
            for e in &f.listed {
                let _ = writeln!(o, "    {}", e.line());
            }
            if f.count > f.listed.len() as u64 {
                let _ = writeln!(o, "    and {} more", f.count - f.listed.len() as u64);
            }
        }
        if !self.codes.is_empty() {
            let c: Vec<String> = self
                .codes
                .iter()
                .map(|c| {
                    format!(
                        "0x{:02X} first at {:.3} s ({} {})",
                        c.code,
                        c.first_s,
                        c.frames,
                        if c.frames == 1 { "frame" } else { "frames" }
                    )
                })
                .collect();
            let _ = writeln!(o, "  fault codes: {}", c.join(", "));
        } else {
            let _ = writeln!(o, "  fault codes: none (FaultCode 0 in every frame)");
        }
        o
    }
}

/// What makes two drives' inverters unlike for `grip inspect A B`
/// ([`super::comparability`]): a different number of fault or derating
/// episodes during the scenario (not said where a side has no scenario
/// window: that side is named incomplete already). A drive whose inverter faulted or derated while the other's did
/// not differs in the torque the motor could give, whatever the
/// controllers did. A side without `MotorStatus` frames beside one whose
/// inverter faulted or derated is named as unknown, not as clean.
pub fn comparability(a: &Inverter, b: &Inverter) -> Vec<String> {
    // None: no scenario window (that side is named incomplete already)
    let in_scenario =
        |inv: &Inverter, flag: Flag| inv.flag(flag).and_then(|f| f.in_scenario).map(|(n, _)| n);
    let count = |inv: &Inverter, flag: Flag| in_scenario(inv, flag).unwrap_or(0);
    let episodes = |inv: &Inverter| {
        [Flag::Fault, Flag::Derating]
            .map(|flag| format!("{} {}", count(inv, flag), flag.words()))
            .join(", ")
    };
    let troubled = |inv: &Inverter| count(inv, Flag::Fault) + count(inv, Flag::Derating) > 0;
    match (a.frames == 0, b.frames == 0) {
        (true, true) => Vec::new(),
        (true, false) | (false, true) => {
            let (none, other, seen) = if a.frames == 0 { ("A", "B", b) } else { ("B", "A", a) };
            if troubled(seen) {
                vec![format!(
                    "{none} has no MotorStatus frames: whether its inverter faulted or derated during the scenario is not known ({other}: {} episodes)",
                    episodes(seen)
                )]
            } else {
                Vec::new()
            }
        }
        (false, false) => [Flag::Fault, Flag::Derating]
            .into_iter()
            .filter_map(|flag| {
                let (Some(na), Some(nb)) = (in_scenario(a, flag), in_scenario(b, flag)) else {
                    return None;
                };
                (na != nb).then(|| {
                    format!(
                        "the inverters' {} episodes during the scenario differ: A {na}, B {nb} (the torque the motor could give differed, whatever the controllers did)",
                        flag.words()
                    )
                })
            })
            .collect(),
    }
}

/// `grip inspect A B`'s inverter rows ([`super::compare`], in its
/// columns): the `MotorStatus` frames read, each flag's episodes, the
/// loop's cycle records during the fault episodes and how many of them in
/// the safe state, each as "during the scenario / over the whole log"
/// (the scenario's: the episodes overlapping the window, `-` without one),
/// and the FaultCodes sent over the whole log. A side without
/// `MotorStatus` frames has `-` in every row and a line that says so (as
/// [`Inverter::render`] does); when neither has any, the two lines alone.
pub fn compare_rows(a: &Inverter, b: &Inverter) -> String {
    let mut o = String::new();
    if a.frames > 0 || b.frames > 0 {
        let _ = writeln!(
            o,
            "inverter (MotorStatus frames tcs-loop received and the E2E check accepted; during the scenario / whole log)"
        );
        let pair = |scn: Option<u64>, all: u64| {
            format!("{} / {all}", scn.map_or("-".to_owned(), |n| n.to_string()))
        };
        let mut row = |name: &str, cell: &dyn Fn(&Inverter) -> String| {
            let side = |s: &Inverter| {
                if s.frames == 0 {
                    "-".to_owned()
                } else {
                    cell(s)
                }
            };
            let _ = writeln!(o, "{name:<34} {:>12} {:>12}", side(a), side(b));
        };
        row("MotorStatus frames", &|s| {
            pair(s.frames_in_scenario, s.frames)
        });
        for flag in Flag::ALL {
            row(&format!("{} episodes", flag.words()), &|s| {
                s.flag(flag).map_or("-".to_owned(), |f| {
                    pair(f.in_scenario.map(|(n, _)| n), f.count)
                })
            });
        }
        let fault = |s: &Inverter, which: fn((u64, u64)) -> u64| {
            s.flag(Flag::Fault).map_or("-".to_owned(), |f| {
                pair(f.loop_cycles_in_scenario.map(which), which(f.loop_cycles))
            })
        };
        row("loop cycles in fault episodes", &|s| fault(s, |c| c.0));
        row("  of them in the safe state", &|s| fault(s, |c| c.1));
        row("fault codes (whole log)", &|s| {
            if s.codes.is_empty() {
                "none".to_owned()
            } else {
                let c: Vec<String> = s
                    .codes
                    .iter()
                    .map(|c| format!("0x{:02X}", c.code))
                    .collect();
                c.join(", ")
            }
        });
    }
    for (tag, s) in [("A", a), ("B", b)] {
        if let Some(none) = s.absent() {
            let _ = writeln!(o, "inverter {tag}: {none}");
        }
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_io::can::protocol::encode_in;

    const MS: u64 = 1_000_000;

    /// A MotorStatus frame at `t_ms` in `p`: ready, no flag, unless `each`
    /// says otherwise.
    fn status(p: &Protocol, t_ms: u64, each: impl FnOnce(&mut MotorStatus)) -> CanFrame {
        let mut m = MotorStatus {
            ready: true,
            ..MotorStatus::default()
        };
        each(&mut m);
        // as tcs-loop logs it: received, stamped with its arrival, 50 µs
        // after a cycle's deadline (the next cycle drains it)
        let mut f = encode_in(
            p.spec(MsgKind::MotorStatus),
            &m,
            (t_ms & 15) as u8,
            t_ms * MS + 50_000,
        );
        f.direction = can_dir::RX;
        f
    }

    /// A second of MotorStatus frames every 1 ms (scenario window 100-900
    /// ms): the inverter comes up in Fault + CmdTimeout with FaultCode 0x01
    /// (0-4 ms, as plant-sim does before the first command), faults with
    /// code 0x2A from 300 to 350 ms, derates from 500 to 600 ms, times out
    /// the commands from 700 to 720 ms and is not ready from 950 ms to the
    /// end. A fault frame the E2E check rejected (at 400 ms) and a sent
    /// frame with MotorStatus's id are not read. The loop's cycle records
    /// (every 1 ms, each reading the frames that arrived since the one
    /// before) are in the safe state at start-up (0-55 ms) and from 301 to
    /// 400 ms (the fault read at 301, then recover_ms after its clearing was
    /// read at 351).
    fn faulty_log() -> DriveLog {
        let p = Protocol::builtin();
        let mut can = Vec::new();
        for k in 0..1000u64 {
            can.push(status(p, k, |m| {
                if k < 5 {
                    (m.fault, m.cmd_timeout, m.fault_code) = (true, true, 0x01);
                }
                if (300..350).contains(&k) {
                    (m.fault, m.fault_code) = (true, 0x2A);
                }
                m.derating = (500..600).contains(&k);
                m.cmd_timeout |= (700..720).contains(&k);
                m.ready = k < 950;
            }));
            if k == 400 {
                let mut f = status(p, k, |m| (m.fault, m.fault_code) = (true, 0x33));
                f.flags |= can_flags::E2E_REJECTED;
                can.push(f);
                let mut f = status(p, k, |m| m.fault = true);
                f.direction = can_dir::TX;
                can.push(f);
            }
        }
        let cycles = (0..1000u64)
            .map(|k| {
                let mut c = CycleRecord::zeroed();
                c.seq = k;
                c.stamp_ns = k * MS;
                // as tcs-loop does: safe in the cycle that read the fault
                // (301: the frame of 300 arrived after it woke), and
                // recover_ms after it read it cleared (at 351)
                c.safe_state = u8::from(k < 56 || (301..401).contains(&k));
                c
            })
            .collect();
        DriveLog {
            can,
            cycles,
            ..DriveLog::default()
        }
    }

    #[test]
    fn episodes_codes_and_the_safe_state_during_a_fault() {
        let log = faulty_log();
        let inv = inverter(&log, Protocol::builtin(), Some((100 * MS, 900 * MS)));
        assert_eq!((inv.frames, inv.rejected), (1000, 1));
        assert!(inv.from_scenario_start);
        assert_eq!(inv.frames_in_scenario, Some(800));
        // the frames are read 50 µs after their cycle's deadline
        let close = |a: f64, b: f64| (a - b).abs() < 1e-4;
        let (a, b) = inv.span_s.unwrap();
        assert!(close(a, -0.100) && close(b, 0.899), "{a} {b}");

        let fault = inv.flag(Flag::Fault).unwrap();
        assert_eq!((fault.count, fault.entered), (2, 1), "{fault:?}");
        assert_eq!(fault.places, [1, 1, 0]);
        assert_eq!(fault.in_scenario.map(|x| x.0), Some(1));
        assert!(close(fault.in_scenario.unwrap().1, 0.050));
        let up = &fault.listed[0];
        assert!(
            up.at_first_frame && up.place == Some(Place::Before),
            "{up:?}"
        );
        assert_eq!(up.codes, [0x01]);
        let e = &fault.listed[1];
        assert!(close(e.start_s, 0.200), "{e:?}");
        assert!(close(e.end_s.unwrap(), 0.250), "{e:?}");
        assert!(close(e.duration_s, 0.050), "{e:?}");
        assert_eq!((e.frames, e.at_first_frame), (50, false));
        assert_eq!(e.place, Some(Place::Scenario));
        assert_eq!(e.codes, [0x2A], "the rejected frame's 0x33 is not read");
        let s = e.safe.unwrap();
        assert_eq!((s.cycles, s.safe, s.safe_before), (50, 50, false), "{s:?}");
        assert!(close(s.first_safe_after_s.unwrap(), 0.0), "{s:?}");
        // the start-up fault: safe throughout too (the loop starts safe);
        // both count as safe throughout
        assert_eq!(up.safe.map(|s| (s.cycles, s.safe)), Some((5, 5)));
        assert_eq!(fault.safe_throughout, 2);
        // a loop that stepped on through a fault is reported so: the same
        // log with the loop out of its safe state from cycle 320
        let mut late = faulty_log();
        for c in &mut late.cycles[321..401] {
            c.safe_state = 0;
        }
        let inv2 = inverter(&late, Protocol::builtin(), Some((100 * MS, 900 * MS)));
        let s2 = inv2.flag(Flag::Fault).unwrap().listed[1].safe.unwrap();
        assert_eq!((s2.cycles, s2.safe), (50, 20), "{s2:?}");
        assert_eq!(inv2.flag(Flag::Fault).unwrap().safe_throughout, 1);

        let der = inv.flag(Flag::Derating).unwrap();
        assert_eq!((der.count, der.entered), (1, 1));
        let d = &der.listed[0];
        assert!(
            close(d.start_s, 0.400) && close(d.end_s.unwrap(), 0.500),
            "{d:?}"
        );
        assert!(d.codes.is_empty() && d.safe.is_none());

        let to = inv.flag(Flag::CmdTimeout).unwrap();
        assert_eq!((to.count, to.entered), (2, 1), "{to:?}");
        let t = &to.listed[1];
        assert!(
            close(t.start_s, 0.600) && close(t.duration_s, 0.020),
            "{t:?}"
        );

        // not ready to the end: one frame period past the last frame, after
        // the scenario window
        let nr = inv.flag(Flag::NotReady).unwrap();
        assert_eq!(nr.count, 1);
        let n = &nr.listed[0];
        assert_eq!(n.end_s, None);
        assert!(
            close(n.start_s, 0.850) && close(n.duration_s, 0.050),
            "{n:?}"
        );
        assert_eq!(n.place, Some(Place::After));
        assert_eq!(nr.in_scenario, Some((0, 0.0)));

        let codes: Vec<(u8, u64)> = inv.codes.iter().map(|c| (c.code, c.frames)).collect();
        assert_eq!(codes, [(0x01, 5), (0x2A, 50)]);
        assert!(close(inv.codes[1].first_s, 0.200));

        let r = inv.render();
        for want in [
            "t from the scenario start",
            "during the scenario (0.000-0.800 s, 800 frames): fault 1 (0.050 s), derating 1 (0.100 s), command timeout 1 (0.020 s), not ready 0",
            "whole log: fault 2 (0.055 s), derating 1 (0.100 s), command timeout 2 (0.025 s), not ready 1 (0.050 s)",
            "fault: 2 episodes (1 before the scenario, 1 during the scenario)",
            "-0.100 to -0.095 s (0.005 s, 5 frames), before the scenario, from the inverter's first frame, FaultCode 0x01: the loop in its safe state throughout (5 cycles; in it already before the fault began)",
            "0.200 to 0.250 s (0.050 s, 50 frames), during the scenario, FaultCode 0x2A: the loop in its safe state throughout (50 cycles)",
            "not ready: 1 episode (1 after the scenario)",
            "0.850 s to the end of the MotorStatus frames (0.050 s, 50 frames; still set in the last one), after the scenario",
            "fault codes: 0x01 first at -0.100 s (5 frames), 0x2A first at 0.200 s (50 frames)",
            "1 more rejected by the E2E check",
        ] {
            assert!(r.contains(want), "{want:?} not in\n{r}");
        }
        assert!(!r.contains("ready throughout"), "{r}");
    }

    /// A fault that came while the loop was stalled: its frames are
    /// stamped when they arrived, so the episode lasts what the inverter
    /// said (180 ms), and the loop's cycles that read it begin with the
    /// first one after the stall, which read them all, not the last one
    /// before it (which read none of them).
    #[test]
    fn a_fault_during_a_loop_stall_is_read_by_the_cycle_after_it() {
        let p = Protocol::builtin();
        let can = (0..1000u64)
            .map(|k| status(p, k, |m| m.fault = (220..400).contains(&k)))
            .collect();
        // no cycle from 200 to 379 ms; the first after the stall woke 300
        // µs late and entered the safe state on what it read
        let cycles = (0..1000u64)
            .filter(|k| !(200..380).contains(k))
            .map(|k| {
                let mut c = CycleRecord::zeroed();
                c.seq = k;
                c.stamp_ns = k * MS;
                c.wakeup_latency_ns = if k == 380 { 300_000 } else { 0 };
                c.safe_state = u8::from((380..451).contains(&k));
                c
            })
            .collect();
        let log = DriveLog {
            can,
            cycles,
            ..DriveLog::default()
        };
        let inv = inverter(&log, p, None);
        let f = inv.flag(Flag::Fault).unwrap();
        assert_eq!(f.count, 1, "{f:?}");
        let e = &f.listed[0];
        assert!((e.duration_s - 0.180).abs() < 1e-6, "{e:?}");
        let s = e.safe.unwrap();
        // cycles 380..=400 (the one woken at 400 ms read the frame of 399,
        // the one of 401 the first clear frame)
        assert_eq!((s.cycles, s.safe, s.safe_before), (21, 21, false), "{s:?}");
        assert_eq!(s.first_safe_after_s, Some(0.0), "{s:?}");
    }

    /// Where the CAN log has one command per cycle record, as tcs-loop
    /// writes it (each cycle's received frames, then its command), the
    /// cycle that drained a frame is the one whose command follows it,
    /// whatever the stamps: the same answer for a log that stamps a frame
    /// with its arrival and for one written before 2026-12-07 that stamps
    /// it when the loop read it (from the stamps alone, the second would
    /// fall one cycle late and report the loop already safe before).
    #[test]
    fn the_cycle_that_drained_a_frame_is_the_one_whose_command_follows_it() {
        let p = Protocol::builtin();
        // the inverter sends at k ms + 0.5; cycle k + 1 drains it and
        // enters the safe state on the first fault frame (300) until 100
        // ms after it
        let log = |read_stamps: bool, commands: bool| {
            let mut can = Vec::new();
            for k in 0..1000u64 {
                if k > 0 {
                    let j = k - 1;
                    let mut f = status(p, j, |m| m.fault = (300..350).contains(&j));
                    f.stamp_ns = if read_stamps {
                        k * MS + 50_000
                    } else {
                        j * MS + 500_000
                    };
                    can.push(f);
                }
                if commands {
                    let mut c = CanFrame::new(0x100, &[0; 8]);
                    c.direction = can_dir::TX;
                    c.stamp_ns = k * MS + 60_000;
                    can.push(c);
                }
            }
            let cycles = (0..1000u64)
                .map(|k| {
                    let mut c = CycleRecord::zeroed();
                    c.seq = k;
                    c.stamp_ns = k * MS;
                    c.wakeup_latency_ns = 40_000;
                    c.safe_state = u8::from((301..401).contains(&k));
                    c
                })
                .collect();
            DriveLog {
                can,
                cycles,
                ..DriveLog::default()
            }
        };
        let overlap = |l: &DriveLog| {
            let inv = inverter(l, p, None);
            let f = inv.flag(Flag::Fault).unwrap();
            assert_eq!(f.count, 1, "{f:?}");
            let s = f.listed[0].safe.unwrap();
            (s.cycles, s.safe, s.safe_before)
        };
        for read_stamps in [false, true] {
            assert_eq!(
                overlap(&log(read_stamps, true)),
                (50, 50, false),
                "{read_stamps}"
            );
        }
        // without the commands, the stamps say: right for arrival stamps,
        // one cycle late for read stamps
        assert_eq!(overlap(&log(false, false)), (50, 50, false));
        assert_eq!(overlap(&log(true, false)), (50, 50, true));
        // a command lost (cycle 200's) and a shutdown frame after the last
        // cycle: as many commands as cycles, but shifted by one from 200
        // on; the log's structure is not believed (it would put the fault
        // one cycle early, "49 of 50 safe"), the stamps say
        let mut lost = log(true, true);
        let tx200 = lost
            .can
            .iter()
            .position(|f| f.direction == can_dir::TX && f.stamp_ns == 200 * MS + 60_000)
            .unwrap();
        lost.can.remove(tx200);
        let mut shutdown = CanFrame::new(0x100, &[0; 8]);
        shutdown.direction = can_dir::TX;
        shutdown.stamp_ns = 1000 * MS + 100_000;
        lost.can.push(shutdown);
        assert_eq!(overlap(&lost), (50, 50, true));
    }

    /// Without a scenario window the times are from the log's first
    /// message, and no episode is placed against a window.
    #[test]
    fn without_a_window_the_times_are_from_the_first_message() {
        let mut log = faulty_log();
        for f in &mut log.can {
            f.stamp_ns += 5_000 * MS;
        }
        for c in &mut log.cycles {
            c.stamp_ns += 5_000 * MS;
        }
        let inv = inverter(&log, Protocol::builtin(), None);
        assert!(!inv.from_scenario_start);
        assert_eq!(inv.origin_ns, 5_000 * MS);
        let e = &inv.flag(Flag::Fault).unwrap().listed[1];
        assert!(
            (e.start_s - 0.300).abs() < 1e-4 && e.place.is_none(),
            "{e:?}"
        );
        let r = inv.render();
        assert!(r.contains("t from the log's first message"), "{r}");
        assert!(!r.contains("during the scenario"), "{r}");
    }

    /// A clean drive is one line; a flapping flag lists its first
    /// [`LISTED`] episodes and counts the rest; a log without MotorStatus
    /// frames says so.
    #[test]
    fn clean_drive_one_line_and_caps() {
        let p = Protocol::builtin();
        let clean = DriveLog {
            can: (0..300).map(|k| status(p, k, |_| {})).collect(),
            ..DriveLog::default()
        };
        let inv = inverter(&clean, p, None);
        assert!(inv.clean());
        assert_eq!(
            inv.render(),
            "\ninverter: ready throughout, no fault, derating or command timeout in 300 MotorStatus frames\n"
        );
        let flapping = DriveLog {
            can: (0..300)
                .map(|k| status(p, k, |m| m.derating = k % 10 < 3))
                .collect(),
            ..DriveLog::default()
        };
        let inv = inverter(&flapping, p, None);
        let d = inv.flag(Flag::Derating).unwrap();
        assert_eq!((d.count, d.listed.len()), (30, LISTED));
        assert!(
            inv.render().contains("    and 20 more\n"),
            "{}",
            inv.render()
        );

        let none = inverter(&DriveLog::default(), p, None);
        assert_eq!(
            none.render(),
            "\ninverter: no MotorStatus frames in the log (no CAN frame logged)\n"
        );
        let mut only_cmd = DriveLog::default();
        only_cmd.can.push(CanFrame::new(0x100, &[0; 8]));
        assert!(
            inverter(&only_cmd, p, None)
                .render()
                .contains("1 CAN frames logged, none a MotorStatus frame tcs-loop received")
        );
    }

    /// A drive whose inverter faulted and derated in the scenario beside
    /// one whose did not is named unlike, once per flag; two alike are not;
    /// a side without MotorStatus frames is unknown.
    #[test]
    fn inverters_that_faulted_differently_make_drives_unlike() {
        let p = Protocol::builtin();
        let window = Some((100 * MS, 900 * MS));
        let faulty = inverter(&faulty_log(), p, window);
        let clean = inverter(
            &DriveLog {
                can: (0..1000).map(|k| status(p, k, |_| {})).collect(),
                ..DriveLog::default()
            },
            p,
            window,
        );
        let w = comparability(&faulty, &clean);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[0].starts_with("the inverters' fault episodes during the scenario differ: A 1, B 0"),
            "{w:?}"
        );
        assert!(
            w[1].starts_with(
                "the inverters' derating episodes during the scenario differ: A 1, B 0"
            ),
            "{w:?}"
        );
        assert!(comparability(&faulty, &faulty).is_empty());
        assert!(comparability(&clean, &clean).is_empty());
        // no MotorStatus frames beside a fault: unknown, not clean
        let none = inverter(&DriveLog::default(), p, window);
        assert_eq!(
            comparability(&none, &faulty),
            [
                "A has no MotorStatus frames: whether its inverter faulted or derated during the scenario is not known (B: 1 fault, 1 derating episodes)"
            ]
        );
        assert!(comparability(&none, &clean).is_empty());
        assert!(comparability(&none, &none).is_empty());
        // a side without a scenario window: its count is not known (the
        // side is named incomplete elsewhere), nothing said of it here
        let windowless = inverter(&faulty_log(), p, None);
        assert!(comparability(&windowless, &clean).is_empty());
    }

    /// `grip inspect A B`'s rows: the faulty log (scenario window 100-900
    /// ms) against a clean one without a window, each flag's episodes and
    /// the loop's cycles in the faults as "scenario / whole log", the
    /// FaultCodes; a side without MotorStatus frames is `-` and says so.
    #[test]
    fn compare_rows_put_the_two_inverters_side_by_side() {
        let p = Protocol::builtin();
        let window = Some((100 * MS, 900 * MS));
        let faulty = inverter(&faulty_log(), p, window);
        let clean = inverter(
            &DriveLog {
                can: (0..300).map(|k| status(p, k, |_| {})).collect(),
                ..DriveLog::default()
            },
            p,
            None,
        );
        let row = |name: &str, a: &str, b: &str| format!("\n{name:<34} {a:>12} {b:>12}\n");
        let c = compare_rows(&faulty, &clean);
        assert!(
            c.starts_with("inverter (MotorStatus frames tcs-loop received and the E2E check accepted; during the scenario / whole log)\n"),
            "{c}"
        );
        for want in [
            row("MotorStatus frames", "800 / 1000", "- / 300"),
            row("fault episodes", "1 / 2", "- / 0"),
            row("derating episodes", "1 / 1", "- / 0"),
            row("command timeout episodes", "1 / 2", "- / 0"),
            row("not ready episodes", "0 / 1", "- / 0"),
            // the scenario's fault (50 cycles) and the start-up's (5)
            row("loop cycles in fault episodes", "50 / 55", "- / 0"),
            row("  of them in the safe state", "50 / 55", "- / 0"),
            row("fault codes (whole log)", "0x01, 0x2A", "none"),
        ] {
            assert!(c.contains(&want), "{want:?} not in\n{c}");
        }
        assert!(!c.contains("no MotorStatus frames"), "{c}");
        // the loop out of its safe state from cycle 321: 20 of the
        // scenario fault's 50 cycles safe
        let mut late = faulty_log();
        for c in &mut late.cycles[321..401] {
            c.safe_state = 0;
        }
        let c = compare_rows(&clean, &inverter(&late, p, window));
        assert!(
            c.contains(&row("  of them in the safe state", "- / 0", "20 / 25")),
            "{c}"
        );
        // no MotorStatus frames: `-` and the reason, not zeros
        let none = inverter(&DriveLog::default(), p, window);
        let c = compare_rows(&faulty, &none);
        for want in [
            row("fault episodes", "1 / 2", "-"),
            row("fault codes (whole log)", "0x01, 0x2A", "-"),
        ] {
            assert!(c.contains(&want), "{want:?} not in\n{c}");
        }
        assert!(
            c.ends_with("\ninverter B: no MotorStatus frames in the log (no CAN frame logged)\n"),
            "{c}"
        );
        assert_eq!(
            compare_rows(&none, &none),
            "inverter A: no MotorStatus frames in the log (no CAN frame logged)\ninverter B: no MotorStatus frames in the log (no CAN frame logged)\n"
        );
    }

    /// Through the summary: the section is in the report, read with the
    /// log's own DBC (here MotorStatus moved to 0x111: a frame on the
    /// built-in id 0x110 is not the inverter's), on the summary's clock.
    #[test]
    fn the_summary_reads_the_logs_own_protocol() {
        let dbc = include_str!("../../../../config/inverter.dbc").replace("BO_ 272 ", "BO_ 273 ");
        let mut log = DriveLog::default();
        log.attachments.insert(
            "can.toml".into(),
            b"transport = \"sim\"\ninterface = \"vcan0\"\ndbc = \"mine.dbc\"\n".to_vec(),
        );
        log.attachments.insert("mine.dbc".into(), dbc.into_bytes());
        let own = log.protocol().unwrap();
        assert_eq!(own.spec(MsgKind::MotorStatus).id, 0x111);
        let builtin = Protocol::builtin();
        for k in 0..100 {
            log.can
                .push(status(&own, k, |m| m.fault = (20..30).contains(&k)));
            // the built-in id: another message on this bus
            log.can.push(status(builtin, k, |m| m.fault = true));
        }
        let v = grip_physics::VehicleParams::default();
        let s = super::super::summarize(&log, &v, "test", None);
        let f = s.inverter.flag(Flag::Fault).unwrap();
        assert_eq!((s.inverter.frames, f.count), (100, 1), "{:?}", s.inverter);
        assert!((f.listed[0].start_s - 0.020).abs() < 1e-9);
        let r = s.render();
        assert!(
            r.contains("\ninverter (its MotorStatus frames tcs-loop received and the E2E check accepted: 100, 0.000 to 0.099 s; t from the log's first message (no scenario window))\n"),
            "{r}"
        );
        assert!(
            r.contains(
                "0.020 to 0.030 s (0.010 s, 10 frames): no cycle record of the loop during it"
            ),
            "{r}"
        );
        let empty = super::super::summarize(&DriveLog::default(), &v, "test", None);
        assert!(
            empty
                .render()
                .contains("inverter: no MotorStatus frames in the log"),
            "{}",
            empty.render()
        );
    }
}
