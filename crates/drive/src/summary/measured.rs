//! What the control loop itself measured ([`Measured`], [`measured`]):
//! slip, spin events, traction and torque computed from tcs-loop's cycle
//! records alone (measured wheel speed ω, vehicle speed V and its
//! validity, reported motor torque, driver demand, torque command, road
//! belief), so a log from the car, which has no ground truth, still shows
//! them. Nothing here is ground truth: the figures carry the sensors'
//! noise and quantisation, and where the log has ground truth the summary
//! prints them after the ground-truth metrics so the two can be compared
//! (`tools/grip/README.md`, "Measured by the loop").
//!
//! - **Window**: the scenario window when the log has one (the ground
//!   truth shows it); else the time the driver demanded torque: every
//!   cycle whose demand is above [`DEMAND_MIN_NM`], in stretches of
//!   consecutive such cycles.
//! - **Measured slip** λ_m = (r ω − V) / max(|r ω|, |V|, v_eps) (the
//!   plant's slip, `grip_physics` `Plant::slip_of`, on the measured ω and
//!   V: the paper's definition, absolute values for reverse motion; r and v_eps
//!   of the vehicle the summary uses) on the window's cycles with a valid,
//!   finite V and a finite ω whose max(|r ω|, |V|) is at least
//!   [`MIN_SPEED_MPS`]; the others are counted and left out.
//! - **Spin events**: |λ_m| above [`SPIN_LAMBDA`] for [`SPIN_MIN_S`] or
//!   longer (dips shorter than [`SPIN_BRIDGE_S`] bridged): a wheel spinning
//!   in reverse counts as one spinning forward.
//! - **Traction**: the mean acceleration from V: per stretch, V at its
//!   last valid sample less V at its first, over the time between them,
//!   each end's V a least-squares line's value there through the valid
//!   samples of the [`ACCEL_END_S`] at that end (at most half the
//!   stretch); ΔV and Δt summed over the stretches. The line keeps the
//!   sensor's noise on one sample (σ 0.02 m/s) from setting the figure
//!   (σ_V √(4/n) at each end, 0.28 σ_V at 50 samples) and leaves the time
//!   base the ground truth's `mean_accel`'s. Also the
//!   command against the demand; the torque withheld ∫ (T_d − T*) dt and
//!   its time-weighted mean (what `grip replay` reports); the motor's
//!   reported torque; of the cycles out of the safe state, how often the
//!   road belief was usable (`used_arte`) and how often
//!   road knowledge's torque cap held the command below the demand.
//! - **The command's smoothness**: `grip_tcs::MetricsAccumulator`'s
//!   `cmd_tv_per_s`, `cmd_hf_rms`, `cmd_hf_share` on the cycles' commands
//!   from the first cycle of each stretch with the driver's demand above
//!   [`DEMAND_MIN_NM`] (in a scenario window the demand reaches the loop a
//!   few ms after the plant starts, and the cycles before carry the
//!   pre-start command, 0: the pedal's step would count, which `grip sim`
//!   does not see), one accumulator per stretch, combined by the time each
//!   one's command figures cover.
//! - **Per believed road**: the loop's road belief (`belief_road`, a
//!   catalogue index, named by the log's road catalogue); its largest
//!   |λ_m|.
//!
//! Every cycle stands for the time to the next cycle record, at most five
//! loop periods (a longer hole in the records is no time the loop
//! measured), clipped to the window's end.

use std::fmt::Write as _;

use grip_msgs::{CycleRecord, NO_CLASS};
use grip_physics::{RoadCatalogue, VehicleParams};
use grip_tcs::{MetricsAccumulator, Sample};

use super::{Percentiles, secs_between};
use crate::log::DriveLog;

/// A cycle belongs to the driver-demand window when its demand is above
/// this, N m. It lies far above the `DriverDemand` signal's resolution
/// (0.1 N m) and a released pedal's reading, and far below any torque that
/// makes measurable slip: 10 N m at the shipped r = 0.28 m is a tyre force
/// of 36 N, 1 % of a driven wheel's 3433 N load, which even ice's or snow's
/// initial slope (μ' about 15-18) turns into a slip under 0.001.
pub const DEMAND_MIN_NM: f64 = 10.0;

/// Measured slip counts only where max(|r ω|, |V|) is at least this, m/s.
/// Below it the sensors' noise dominates λ_m: with the shipped sensor model
/// (ω σ 0.05 rad/s and a 0.096 rad/s encoder step at 1 kHz, so r ω about
/// σ 0.016 m/s; V σ 0.02 m/s) r ω − V has σ about 0.026 m/s, which is 0.026
/// in λ_m at 1 m/s but 0.26 at v_eps's 0.1 m/s (a standing car would show
/// a mean |λ_m| of about 0.2 from noise alone); real wheel-speed sensors
/// also lose their signal near standstill. A wheel spinning up from rest
/// counts as soon as r ω reaches it.
pub const MIN_SPEED_MPS: f64 = 1.0;

/// A spin event: λ_m above this. Above the optimal slip of every shipped
/// road but stone's (asphalt 0.17, snow 0.06, ice 0.02; stone 0.40, where
/// 0.2-0.4 is still the rising side of the curve and an "event" is no
/// spin), and at the speed floor 8 σ of the sensors' noise in λ_m.
pub const SPIN_LAMBDA: f64 = 0.2;

/// A spin event lasts at least this, s: 20 cycles at 1 kHz; sensor noise
/// is independent from cycle to cycle and cannot hold λ_m above
/// [`SPIN_LAMBDA`] that long, while a wheel spinning up on a low-μ road
/// stays there for tens to hundreds of ms.
pub const SPIN_MIN_S: f64 = 0.020;

/// Dips of λ_m under [`SPIN_LAMBDA`] shorter than this do not end a spin
/// event (one or a few noisy cycles), s.
pub const SPIN_BRIDGE_S: f64 = 0.005;

/// Spin events listed in the report (the highest peaks); all are counted.
pub const SPIN_LISTED: usize = 5;

/// The slip levels whose share of the time is reported (|λ_m| above each).
pub const SLIP_LEVELS: [f64; 2] = [0.1, 0.2];

/// A cycle stands for at most this many loop periods.
const MAX_DT_PERIODS: u64 = 5;

/// The mean acceleration from V takes the mean of V over this much at each
/// end of a stretch, s (50 cycles at 1 kHz).
pub const ACCEL_END_S: f64 = 0.050;

/// Which cycles the measured figures cover.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub enum MeasuredWindow {
    /// The scenario window (the log has ground truth that shows it).
    Scenario,
    /// The time the driver demanded more than [`DEMAND_MIN_NM`].
    Demand,
    /// No cycle record in the log.
    #[default]
    NoCycles,
}

impl MeasuredWindow {
    /// `scenario`, `demand` or `no_cycles` (`grip inspect --json`).
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Scenario => "scenario",
            Self::Demand => "demand",
            Self::NoCycles => "no_cycles",
        }
    }
}

/// λ_m above [`SPIN_LAMBDA`] for [`SPIN_MIN_S`] or longer.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SpinEvent {
    /// Its first cycle, s from [`Measured::origin_ns`].
    pub start_s: f64,
    /// From its first cycle to the end of its last, s.
    pub length_s: f64,
    /// The largest |λ_m| in it.
    pub peak: f64,
    /// When that was, s from [`Measured::origin_ns`].
    pub peak_s: f64,
    /// Cut short by the end of its stretch of the window (the scenario
    /// window's end, the end of the driver's demand, or the log's last
    /// cycle record): |λ_m| was still above [`SPIN_LAMBDA`] there (or had
    /// dipped under it for less than [`SPIN_BRIDGE_S`]), so the event did
    /// not end where `length_s` ends; it lasted at least that long.
    pub cut: bool,
}

/// The window's cycles with one road belief.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BeliefLine {
    /// The road's name (the log's road catalogue), `road #i` when the
    /// catalogue does not have it, `none` for no belief (ARTE off, or no
    /// estimate yet).
    pub road: String,
    /// The catalogue index (None: no belief).
    pub index: Option<u32>,
    /// Time, s.
    pub time_s: f64,
    /// Time with a measured slip, s.
    pub slip_s: f64,
    /// Time-weighted mean |λ_m| (NaN: no measured slip).
    pub mean_abs_slip: f64,
    /// Largest |λ_m| (NaN: no measured slip).
    pub max_slip: f64,
    /// Time-weighted mean torque command, N m (NaN: none finite).
    pub mean_cmd: f64,
}

/// The figures measured by the loop over [`Measured::window`]; NaN where
/// there is nothing to compute from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Measured {
    /// Which cycles are covered.
    pub window: MeasuredWindow,
    /// The origin of the times here, ns: the scenario start (scenario
    /// window), else the first message of the log (`grip inspect --csv`'s
    /// `t_s`, the plots' axis without ground truth).
    pub origin_ns: u64,
    /// Stretches of consecutive cycles in the window (1 for the scenario).
    pub stretches: u64,
    /// The first cycle of the window and the end of its last, s from
    /// `origin_ns` (None: no cycle in it).
    pub span_s: Option<(f64, f64)>,
    /// Cycles in the window.
    pub cycles: u64,
    /// The window's time, s (the cycles' times summed).
    pub time_s: f64,
    /// Cycles without a valid, finite V (or with a non-finite ω): no slip,
    /// no speed; left out of those figures.
    pub no_valid_v: u64,
    /// Cycles with a valid V but max(|r ω|, |V|) under [`MIN_SPEED_MPS`]:
    /// no slip.
    pub slow: u64,
    /// Cycles with a valid V in the loop's safe state: no slip. The loop
    /// is there when its inputs are not valid, and its record's ω is then
    /// 0 for a wheel speed it no longer has (a wheel-speed timeout read as
    /// a locked wheel, slip −1, found in the HIL's bus-deleted drive,
    /// 2026-12-05); its speed V still counts for the acceleration.
    pub safe: u64,
    /// Cycles with a measured slip, and their time, s.
    pub slip_cycles: u64,
    /// Their time, s.
    pub slip_s: f64,
    /// r and v_eps used, m and m/s.
    pub r: f64,
    /// v_eps, m/s.
    pub v_eps: f64,
    /// Time-weighted mean |λ_m|.
    pub mean_abs_slip: f64,
    /// 95th percentile of |λ_m| over the cycles (nearest rank).
    pub p95_abs_slip: f64,
    /// Largest |λ_m|.
    pub max_abs_slip: f64,
    /// When it was, s from `origin_ns` (NaN: no slip cycle).
    pub max_abs_slip_s: f64,
    /// Share of the slip time with |λ_m| above each of [`SLIP_LEVELS`].
    pub share_above: [f64; 2],
    /// Every spin event, in time order.
    pub spins: Vec<SpinEvent>,
    /// Mean acceleration from V, m/s² (Σ ΔV / Σ Δt over the stretches: per
    /// stretch V at its last valid sample less V at its first, each from a
    /// least-squares line through the valid V of the [`ACCEL_END_S`] at
    /// that end, over the time between the two samples).
    pub mean_accel: f64,
    /// Σ ΔV, m/s.
    pub dv: f64,
    /// Σ Δt between each stretch's first and last valid V, s.
    pub accel_s: f64,
    /// Time-weighted mean torque command, N m.
    pub mean_cmd: f64,
    /// Time-weighted mean driver demand, N m.
    pub mean_demand: f64,
    /// mean command / mean demand (NaN: no positive demand).
    pub delivered: f64,
    /// ∫ (demand − command) dt, N m s.
    pub withheld_nms: f64,
    /// Time-weighted mean of (demand − command) over the cycles with both,
    /// N m (the torque taken off the demand, negative where the command
    /// exceeded it; NaN: none).
    pub mean_withheld: f64,
    /// Cycles of the window out of the safe state.
    pub active_cycles: u64,
    /// Of those, cycles whose road belief was usable (the cycle record's
    /// `used_arte`: a decision within `max_age_s`, the belief's probability
    /// at or above `min_confidence`).
    pub used_arte_cycles: u64,
    /// Of those, cycles whose command road knowledge's torque cap held
    /// below the driver's demand ([`super::cap_binding`]).
    pub capped_cycles: u64,
    /// Where the command's smoothness figures start, s from `origin_ns`:
    /// the window's first cycle with the driver's demand above
    /// [`DEMAND_MIN_NM`] (None: none).
    pub cmd_from_s: Option<f64>,
    /// Time-weighted mean of the motor's reported torque, N m.
    pub mean_torque: f64,
    /// The command's total variation per second, N m/s.
    pub cmd_tv_per_s: f64,
    /// The command's RMS above 20 Hz, N m.
    pub cmd_hf_rms: f64,
    /// Share of the command's variance above 20 Hz.
    pub cmd_hf_share: f64,
    /// Per believed road, in catalogue order (no belief last).
    pub per_belief: Vec<BeliefLine>,
}

/// λ_m of one (ω, V): (r ω − V) / max(|r ω|, |V|, v_eps); None when
/// either is not finite or max(|r ω|, |V|) is under [`MIN_SPEED_MPS`].
pub fn slip(r: f64, v_eps: f64, omega: f64, v: f64) -> Option<f64> {
    let u = r * omega;
    if !(u.is_finite() && v.is_finite()) || u.abs().max(v.abs()) < MIN_SPEED_MPS {
        return None;
    }
    Some((u - v) / u.abs().max(v.abs()).max(v_eps))
}

/// The cycle's V when it holds a valid, finite one.
fn valid_v(c: &CycleRecord) -> Option<f64> {
    (c.v_valid != 0 && c.v.is_finite()).then_some(c.v)
}

/// The median of the positive steps between successive `stamps`, ns (what
/// one record stands for); 1 ms when there is none.
pub(crate) fn median_period_ns(stamps: impl Iterator<Item = u64>) -> u64 {
    let stamps: Vec<u64> = stamps.collect();
    let mut periods: Vec<i64> = stamps
        .windows(2)
        .filter_map(|w| i64::try_from(w[1].checked_sub(w[0])?).ok())
        .filter(|&p| p > 0)
        .collect();
    u64::try_from(Percentiles::of(&mut periods).p50)
        .ok()
        .filter(|&p| p > 0)
        .unwrap_or(1_000_000)
}

/// Why a cycle record measures no slip ([`cycle_slip`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoSlip {
    /// No valid, finite V, or ω no number.
    NoValidV,
    /// The loop was in its safe state: its record then holds ω = 0 for a
    /// wheel speed it no longer has (a wheel-speed timeout), no locked wheel.
    SafeState,
    /// max(r ω, V) below [`MIN_SPEED_MPS`].
    Slow,
}

/// The slip a cycle record measures, or why it has none: the one rule of the
/// measured section, the drive summary's plots and every other reader of a
/// log's measured slip.
pub fn cycle_slip(r: f64, v_eps: f64, c: &CycleRecord) -> Result<f64, NoSlip> {
    let v = valid_v(c)
        .filter(|_| c.omega.is_finite())
        .ok_or(NoSlip::NoValidV)?;
    if c.safe_state != 0 {
        return Err(NoSlip::SafeState);
    }
    slip(r, v_eps, c.omega, v).ok_or(NoSlip::Slow)
}

/// Time-weighted sums.
#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    t: f64,
    x: f64,
}

impl Acc {
    fn add(&mut self, x: f64, dt: f64) {
        if x.is_finite() {
            self.t += dt;
            self.x += x * dt;
        }
    }
    fn mean(&self) -> f64 {
        if self.t > 0.0 {
            self.x / self.t
        } else {
            f64::NAN
        }
    }
}

/// The measured figures of `log` (see the module). `window_ns` is the
/// summary's scenario window (None: use the driver's demand); `vehicle`
/// gives r and v_eps; `roads` names the believed roads.
pub fn measured(
    log: &DriveLog,
    vehicle: &VehicleParams,
    window_ns: Option<(u64, u64)>,
    roads: Option<&RoadCatalogue>,
) -> Measured {
    let cycles = &log.cycles;
    let mut m = Measured {
        r: vehicle.r,
        v_eps: vehicle.v_eps,
        max_abs_slip_s: f64::NAN,
        ..Measured::default()
    };
    let nan = f64::NAN;
    (
        m.mean_abs_slip,
        m.p95_abs_slip,
        m.max_abs_slip,
        m.mean_accel,
        m.mean_cmd,
        m.mean_demand,
        m.delivered,
        m.mean_torque,
    ) = (nan, nan, nan, nan, nan, nan, nan, nan);
    (
        m.mean_withheld,
        m.cmd_tv_per_s,
        m.cmd_hf_rms,
        m.cmd_hf_share,
    ) = (nan, nan, nan, nan);
    m.share_above = [nan, nan];
    if cycles.is_empty() {
        return m;
    }
    let period = median_period_ns(cycles.iter().map(|c| c.stamp_ns));
    let max_dt = period.saturating_mul(MAX_DT_PERIODS);
    // each cycle's time, ns: to the next record, at most `max_dt`, clipped
    // to the scenario window's end
    let dt_ns = |i: usize| -> u64 {
        let s = cycles[i].stamp_ns;
        let next = cycles.get(i + 1).map_or(s.saturating_add(period), |n| {
            n.stamp_ns.max(s).min(s.saturating_add(max_dt))
        });
        let next = window_ns.map_or(next, |(_, we)| next.min(we.max(s)));
        next - s
    };
    // the window as stretches of consecutive cycle indices
    let mut stretches: Vec<(usize, usize)> = Vec::new();
    let inside: Box<dyn Fn(&CycleRecord) -> bool> = match window_ns {
        Some((ws, we)) => {
            m.window = MeasuredWindow::Scenario;
            m.origin_ns = ws;
            Box::new(move |c: &CycleRecord| (ws..we).contains(&c.stamp_ns))
        }
        None => {
            m.window = MeasuredWindow::Demand;
            m.origin_ns = log.first_stamp_ns();
            Box::new(|c: &CycleRecord| c.demand.is_finite() && c.demand > DEMAND_MIN_NM)
        }
    };
    let mut open: Option<usize> = None;
    for (i, c) in cycles.iter().enumerate() {
        match (inside(c), open) {
            (true, None) => open = Some(i),
            (false, Some(a)) => {
                stretches.push((a, i));
                open = None;
            }
            _ => {}
        }
    }
    if let Some(a) = open {
        stretches.push((a, cycles.len()));
    }
    m.stretches = stretches.len() as u64;
    let origin = m.origin_ns;
    let rel = |ns: u64| secs_between(origin, ns);
    if let (Some(&(a, _)), Some(&(_, b))) = (stretches.first(), stretches.last()) {
        let end = cycles[b - 1].stamp_ns + dt_ns(b - 1);
        m.span_s = Some((rel(cycles[a].stamp_ns), rel(end)));
    }

    let (r, v_eps) = (vehicle.r, vehicle.v_eps);
    let mut abs_slip = Acc::default();
    let mut abs_all: Vec<f64> = Vec::new();
    // the largest |λ_m| and when (the first of equals)
    let mut max_at = (f64::NEG_INFINITY, f64::NAN);
    let mut above = [0.0f64; 2];
    let (mut cmd, mut demand, mut torque) = (Acc::default(), Acc::default(), Acc::default());
    let mut cut = Acc::default();
    let mut withheld = 0.0;
    let (mut tv, mut hf2, mut hf_share_w, mut cmd_t) = (0.0, 0.0, 0.0, 0.0);
    // per belief: (time, slip time, Σ|λ|dt, max λ, command acc)
    let mut beliefs: std::collections::BTreeMap<u32, (f64, f64, f64, f64, Acc)> =
        std::collections::BTreeMap::new();
    for &(a, b) in &stretches {
        let mut acc = MetricsAccumulator::new(vehicle);
        // the spin event being followed: (start ns, end ns, peak, peak ns)
        let mut spin: Option<(u64, u64, f64, u64)> = None;
        // `cut`: closed by the stretch's end, not by a dip
        let close =
            |spin: &mut Option<(u64, u64, f64, u64)>, spins: &mut Vec<SpinEvent>, cut: bool| {
                if let Some((s0, s1, peak, at)) = spin.take() {
                    let length_s = secs_between(s0, s1);
                    if length_s >= SPIN_MIN_S - 1e-9 {
                        spins.push(SpinEvent {
                            start_s: rel(s0),
                            length_s,
                            peak,
                            peak_s: rel(at),
                            cut,
                        });
                    }
                }
            };
        // the command's smoothness from the first cycle with the driver's
        // demand on (the cycles before carry the pre-start command)
        let mut had_demand = false;
        let mut vs: Vec<(u64, f64)> = Vec::new();
        for (i, c) in cycles.iter().enumerate().take(b).skip(a) {
            let dtn = dt_ns(i);
            let dt = dtn as f64 * 1e-9;
            m.cycles += 1;
            m.time_s += dt;
            cmd.add(c.torque_cmd, dt);
            demand.add(c.demand, dt);
            torque.add(c.torque, dt);
            if c.demand.is_finite() && c.torque_cmd.is_finite() {
                withheld += (c.demand - c.torque_cmd) * dt;
                cut.add(c.demand - c.torque_cmd, dt);
            }
            if c.safe_state == 0 {
                m.active_cycles += 1;
                m.used_arte_cycles += u64::from(c.used_arte != 0);
                m.capped_cycles += u64::from(super::cap_binding(c));
            }
            had_demand |= c.demand.is_finite() && c.demand > DEMAND_MIN_NM;
            if had_demand && m.cmd_from_s.is_none() {
                m.cmd_from_s = Some(rel(c.stamp_ns));
            }
            acc.push(&Sample {
                dt,
                lambda: 0.0,
                torque: 0.0,
                omega: 0.0,
                v: 0.0,
                torque_cmd: if had_demand { c.torque_cmd } else { f64::NAN },
            });
            let belief =
                beliefs
                    .entry(c.belief_road)
                    .or_insert((0.0, 0.0, 0.0, f64::NAN, Acc::default()));
            belief.0 += dt;
            belief.4.add(c.torque_cmd, dt);
            if let Some(v) = valid_v(c).filter(|_| c.omega.is_finite()) {
                // V counts for the acceleration in the safe state too
                vs.push((c.stamp_ns, v));
            }
            let l = match cycle_slip(r, v_eps, c) {
                Ok(l) => l,
                Err(NoSlip::NoValidV) => {
                    m.no_valid_v += 1;
                    continue;
                }
                Err(NoSlip::SafeState) => {
                    m.safe += 1;
                    continue;
                }
                Err(NoSlip::Slow) => {
                    m.slow += 1;
                    continue;
                }
            };
            m.slip_cycles += 1;
            m.slip_s += dt;
            abs_slip.add(l.abs(), dt);
            abs_all.push(l.abs());
            if l.abs() > max_at.0 {
                max_at = (l.abs(), rel(c.stamp_ns));
            }
            for (k, lvl) in SLIP_LEVELS.iter().enumerate() {
                if l.abs() > *lvl {
                    above[k] += dt;
                }
            }
            belief.1 += dt;
            belief.2 += l.abs() * dt;
            belief.3 = if belief.3.is_nan() {
                l.abs()
            } else {
                belief.3.max(l.abs())
            };
            // spin events: cycles with |λ_m| above the threshold (a wheel
            // spinning forward or in reverse), dips shorter than the
            // bridge joined
            let la = l.abs();
            if la > SPIN_LAMBDA {
                let end = c.stamp_ns + dtn;
                match &mut spin {
                    Some((_, s1, peak, at))
                        if secs_between(*s1, c.stamp_ns) < SPIN_BRIDGE_S - 1e-12 =>
                    {
                        *s1 = end;
                        if la > *peak {
                            (*peak, *at) = (la, c.stamp_ns);
                        }
                    }
                    _ => {
                        close(&mut spin, &mut m.spins, false);
                        spin = Some((c.stamp_ns, end, la, c.stamp_ns));
                    }
                }
            } else if spin
                .as_ref()
                .is_some_and(|s| secs_between(s.1, c.stamp_ns) >= SPIN_BRIDGE_S - 1e-12)
            {
                close(&mut spin, &mut m.spins, false);
            }
        }
        // a spin still open where the stretch ends (above the threshold
        // there, or in a dip shorter than the bridge) is cut by the
        // window's end, not ended
        let stretch_end = cycles[b - 1].stamp_ns + dt_ns(b - 1);
        let cut_short = spin
            .as_ref()
            .is_some_and(|s| secs_between(s.1, stretch_end) < SPIN_BRIDGE_S - 1e-12);
        close(&mut spin, &mut m.spins, cut_short);
        if let Some((dv, ds)) = end_means_dv(&vs) {
            m.dv += dv;
            m.accel_s += ds;
        }
        let f = acc.finish();
        if f.cmd_duration > 0.0 && f.cmd_tv_per_s.is_finite() {
            tv += f.cmd_tv_per_s * f.cmd_duration;
            hf2 += f.cmd_hf_rms * f.cmd_hf_rms * f.cmd_duration;
            hf_share_w += f.cmd_hf_share * f.cmd_duration;
            cmd_t += f.cmd_duration;
        }
    }
    m.spins.sort_by(|x, y| x.start_s.total_cmp(&y.start_s));
    m.mean_abs_slip = abs_slip.mean();
    if !abs_all.is_empty() {
        abs_all.sort_unstable_by(f64::total_cmp);
        let n = abs_all.len();
        let at = ((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1;
        m.p95_abs_slip = abs_all[at];
        m.max_abs_slip = abs_all[n - 1];
        m.max_abs_slip_s = max_at.1;
    }
    if m.slip_s > 0.0 {
        m.share_above = [above[0] / m.slip_s, above[1] / m.slip_s];
    }
    if m.accel_s > 0.0 {
        m.mean_accel = m.dv / m.accel_s;
    }
    m.mean_cmd = cmd.mean();
    m.mean_demand = demand.mean();
    m.mean_torque = torque.mean();
    m.withheld_nms = withheld;
    m.mean_withheld = cut.mean();
    if m.mean_demand.is_finite() && m.mean_demand > 0.0 {
        m.delivered = m.mean_cmd / m.mean_demand;
    }
    if cmd_t > 0.0 {
        m.cmd_tv_per_s = tv / cmd_t;
        m.cmd_hf_rms = (hf2 / cmd_t).sqrt();
        m.cmd_hf_share = hf_share_w / cmd_t;
    }
    let name = |i: u32| {
        if i == NO_CLASS {
            "none".to_owned()
        } else {
            roads
                .and_then(|c| c.by_index(i as usize))
                .map_or_else(|| format!("road #{i}"), |r| r.name().to_owned())
        }
    };
    m.per_belief = beliefs
        .into_iter()
        .map(|(i, (t, st, sl, mx, c))| BeliefLine {
            road: name(i),
            index: (i != NO_CLASS).then_some(i),
            time_s: t,
            slip_s: st,
            mean_abs_slip: if st > 0.0 { sl / st } else { f64::NAN },
            max_slip: mx,
            mean_cmd: c.mean(),
        })
        .collect();
    m
}

/// (ΔV, Δt) of one stretch's valid V samples `vs` (stamp ns, V, in time
/// order): V at the stretch's first and last valid sample, each estimated
/// by a least-squares line through the samples of the [`ACCEL_END_S`] at
/// that end (at most half the stretch), over the time between those two
/// samples. The sensor's noise on a single end sample then does not set
/// the acceleration (at n samples the line's end value has σ_V √(4/n):
/// 0.28 σ_V at 50), the time base stays the ground truth's `mean_accel`'s
/// (first to last sample), and a V linear over the ends gives its slope
/// exactly. None with fewer than two samples or no time between the ends.
fn end_means_dv(vs: &[(u64, f64)]) -> Option<(f64, f64)> {
    let (&(t0, _), &(t1, _)) = (vs.first()?, vs.last()?);
    if t1 <= t0 {
        return None;
    }
    let w = ((ACCEL_END_S * 1e9) as u64).min((t1 - t0) / 2);
    // the line's value at `at` through the samples of `it`
    let end_value = |at: u64, it: &mut dyn Iterator<Item = &(u64, f64)>| {
        let (mut n, mut st, mut sv, mut stt, mut stv) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &(t, v) in it {
            let x = secs_between(at, t);
            n += 1.0;
            st += x;
            sv += v;
            stt += x * x;
            stv += x * v;
        }
        let (mt, mv) = (st / n, sv / n);
        let var = stt / n - mt * mt;
        if var > 1e-18 {
            let slope = (stv / n - mt * mv) / var;
            mv - slope * mt
        } else {
            mv
        }
    };
    let va = end_value(t0, &mut vs.iter().take_while(|(t, _)| *t <= t0 + w));
    let vb = end_value(t1, &mut vs.iter().rev().take_while(|(t, _)| *t >= t1 - w));
    Some((vb - va, secs_between(t0, t1)))
}

/// `{:.prec$}` of a finite number, else `-`.
fn f(x: f64, prec: usize) -> String {
    if x.is_finite() {
        format!("{x:.prec$}")
    } else {
        "-".to_owned()
    }
}

impl SpinEvent {
    /// One line of the report.
    pub fn line(&self) -> String {
        format!(
            "at {:.3} s for {:.3} s, peak |λ_m| {:.3} at {:.3} s{}",
            self.start_s,
            self.length_s,
            self.peak,
            self.peak_s,
            if self.cut {
                format!(
                    "; cut short by the window's end (the spin still going there: |λ_m| above {SPIN_LAMBDA}, or in a dip shorter than the bridge): it lasted at least this long"
                )
            } else {
                String::new()
            }
        )
    }
}

impl Measured {
    /// What the window is, in words.
    pub fn window_words(&self) -> String {
        let span = self.span_s.map_or("no cycle in it".to_owned(), |(a, b)| {
            format!("{a:.3}-{b:.3} s")
        });
        match self.window {
            MeasuredWindow::Scenario => format!(
                "the scenario window ({span} from the scenario start; {} cycles, {:.3} s)",
                self.cycles, self.time_s
            ),
            MeasuredWindow::Demand => format!(
                "the time the driver demanded more than {DEMAND_MIN_NM} N m (no scenario window in the log): {} {}, {:.3} s in all, {} cycles, first to last {span} from the log's first message",
                self.stretches,
                if self.stretches == 1 {
                    "stretch"
                } else {
                    "stretches"
                },
                self.time_s,
                self.cycles
            ),
            MeasuredWindow::NoCycles => "none: no cycle record in the log".to_owned(),
        }
    }

    /// The report's section (a blank line, then the lines).
    pub fn render(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(
            o,
            "\nmeasured by the loop (tcs-loop's cycle records: its measured ω and V, the motor's reported torque, demand and command; NOT ground truth)"
        );
        let _ = writeln!(o, "  window: {}", self.window_words());
        if self.cycles == 0 {
            return o;
        }
        let _ = writeln!(
            o,
            "  slip λ_m = (r ω − V) / max(r ω, V, v_eps), r {:.3} m, v_eps {:.2} m/s: {} cycles ({:.3} s) with a valid V and max(r ω, V) at or above {MIN_SPEED_MPS} m/s, the loop out of its safe state; left out: {} without a valid V, {} below {MIN_SPEED_MPS} m/s, {} in the safe state (its ω then not a measurement)",
            self.r,
            self.v_eps,
            self.slip_cycles,
            self.slip_s,
            self.no_valid_v,
            self.slow,
            self.safe
        );
        if self.slip_cycles > 0 {
            let _ = writeln!(
                o,
                "  measured slip |λ_m|: mean {}  p95 {}  max {} at {} s; above {}: {} % of that time, above {}: {} %",
                f(self.mean_abs_slip, 4),
                f(self.p95_abs_slip, 4),
                f(self.max_abs_slip, 4),
                f(self.max_abs_slip_s, 3),
                SLIP_LEVELS[0],
                f(100.0 * self.share_above[0], 1),
                SLIP_LEVELS[1],
                f(100.0 * self.share_above[1], 1)
            );
        }
        let cut = self.spins.iter().filter(|e| e.cut).count();
        let _ = writeln!(
            o,
            "  spin events (|λ_m| above {SPIN_LAMBDA} for {:.0} ms or more; dips under {:.0} ms bridged): {}{}",
            SPIN_MIN_S * 1e3,
            SPIN_BRIDGE_S * 1e3,
            self.spins.len(),
            if cut > 0 {
                format!(" ({cut} cut short by the window's end)")
            } else {
                String::new()
            }
        );
        let mut by_peak: Vec<&SpinEvent> = self.spins.iter().collect();
        by_peak.sort_by(|a, b| b.peak.total_cmp(&a.peak));
        for e in by_peak.iter().take(SPIN_LISTED) {
            let _ = writeln!(o, "    {}", e.line());
        }
        if self.spins.len() > SPIN_LISTED {
            let _ = writeln!(
                o,
                "    ({} more; the {SPIN_LISTED} highest peaks listed)",
                self.spins.len() - SPIN_LISTED
            );
        }
        let _ = writeln!(
            o,
            "  mean acceleration from V        {} m/s² (ΔV {} m/s over {:.3} s of valid V; V at each end from a line through its first or last {:.0} ms)",
            f(self.mean_accel, 3),
            f(self.dv, 3),
            self.accel_s,
            ACCEL_END_S * 1e3
        );
        let _ = writeln!(
            o,
            "  command / demand                {} (mean command {} N m, mean demand {} N m); withheld ∫(T_d − T*)dt {} N m s",
            f(self.delivered, 3),
            f(self.mean_cmd, 1),
            f(self.mean_demand, 1),
            f(self.withheld_nms, 1)
        );
        let _ = writeln!(
            o,
            "  motor torque (reported) mean    {} N m",
            f(self.mean_torque, 1)
        );
        let _ = writeln!(
            o,
            "  command total variation Σ|ΔT*|/T {} N m/s; above 20 Hz (RMS, share) {} N m, {} of its variance (from {}: the first cycle with the driver's demand above {DEMAND_MIN_NM} N m)",
            f(self.cmd_tv_per_s, 0),
            f(self.cmd_hf_rms, 2),
            f(self.cmd_hf_share, 3),
            self.cmd_from_s
                .map_or("- (no such cycle)".to_owned(), |t| format!("{t:.3} s"))
        );
        if !self.per_belief.is_empty() {
            let _ = writeln!(
                o,
                "  per believed road (the loop's road belief; none: ARTE off or no belief yet):"
            );
            let _ = writeln!(
                o,
                "    {:<14} {:>9} {:>11} {:>8} {:>19}",
                "road", "time (s)", "mean |λ_m|", "max |λ_m|", "mean command (N m)"
            );
            for b in &self.per_belief {
                let _ = writeln!(
                    o,
                    "    {:<14} {:>9.3} {:>11} {:>8} {:>19}",
                    b.road,
                    b.time_s,
                    f(b.mean_abs_slip, 4),
                    f(b.max_slip, 3),
                    f(b.mean_cmd, 1)
                );
            }
        }
        o
    }
}

/// The measured rows of `grip inspect A B` (after the ground-truth
/// metrics): a heading, then each figure of A and B with A / B.
pub fn compare_rows(a: &Measured, b: &Measured) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "measured by the loop (cycle records; NOT ground truth; window: A {}, B {})",
        a.window.as_str(),
        b.window.as_str()
    );
    if a.window != b.window || (a.time_s - b.time_s).abs() > 0.005 {
        let _ = writeln!(
            o,
            "NOTE: the measured windows differ (A {} {:.3} s, B {} {:.3} s): these rows cover different times",
            a.window.as_str(),
            a.time_s,
            b.window.as_str(),
            b.time_s
        );
    }
    let rows: [(&str, f64, f64, usize); 12] = [
        ("window (s)", a.time_s, b.time_s, 3),
        ("mean |λ_m|", a.mean_abs_slip, b.mean_abs_slip, 4),
        ("p95 |λ_m|", a.p95_abs_slip, b.p95_abs_slip, 4),
        ("max |λ_m|", a.max_abs_slip, b.max_abs_slip, 4),
        (
            "time |λ_m| > 0.1 (%)",
            100.0 * a.share_above[0],
            100.0 * b.share_above[0],
            1,
        ),
        (
            "time |λ_m| > 0.2 (%)",
            100.0 * a.share_above[1],
            100.0 * b.share_above[1],
            1,
        ),
        ("spin events", a.spins.len() as f64, b.spins.len() as f64, 0),
        ("mean accel. from V (m/s²)", a.mean_accel, b.mean_accel, 3),
        ("command / demand", a.delivered, b.delivered, 3),
        ("torque withheld (N m s)", a.withheld_nms, b.withheld_nms, 1),
        ("motor torque mean (N m)", a.mean_torque, b.mean_torque, 1),
        (
            "command TV Σ|ΔT*|/T (N m/s)",
            a.cmd_tv_per_s,
            b.cmd_tv_per_s,
            0,
        ),
    ];
    for (name, x, y, p) in rows {
        let ratio = super::ratio_cell(x, y);
        let _ = writeln!(o, "{name:<34} {:>12} {:>12} {ratio:>8}", f(x, p), f(y, p));
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    /// `n` cycles at 1 kHz from 1 s: V 5 m/s, r ω = V (no slip), demand
    /// 200 N m, command 150 N m; `each(k, record)` sets the rest.
    fn log(n: u64, mut each: impl FnMut(u64, &mut CycleRecord)) -> DriveLog {
        let r = VehicleParams::default().r;
        let cycles = (0..n)
            .map(|k| {
                let mut c = CycleRecord::zeroed();
                c.seq = k;
                c.stamp_ns = 1_000 * MS + k * MS;
                c.v = 5.0;
                c.v_valid = 1;
                c.omega = 5.0 / r;
                c.demand = 200.0;
                c.torque_cmd = 150.0;
                c.torque = 140.0;
                each(k, &mut c);
                c
            })
            .collect();
        DriveLog {
            cycles,
            ..DriveLog::default()
        }
    }

    /// λ_m of `lambda` at V: r ω = V / (1 − λ).
    fn omega_for(lambda: f64, v: f64) -> f64 {
        v / (1.0 - lambda) / VehicleParams::default().r
    }

    #[test]
    fn a_spin_is_one_event_with_its_start_length_and_peak() {
        // 0.3 for 80 ms from cycle 200, its peak 0.35 at cycle 240, a
        // one-cycle dip at cycle 230
        let l = log(1000, |k, c| {
            if (200..280).contains(&k) {
                let lam = if k == 240 {
                    0.35
                } else if k == 230 {
                    0.1
                } else {
                    0.3
                };
                c.omega = omega_for(lam, c.v);
            }
            // a noise spike: one cycle, no event
            if k == 600 {
                c.omega = omega_for(0.5, c.v);
            }
        });
        let v = VehicleParams::default();
        let m = measured(&l, &v, None, None);
        assert_eq!(m.window, MeasuredWindow::Demand);
        assert_eq!(m.spins.len(), 1, "{:?}", m.spins);
        let e = m.spins[0];
        assert!((e.start_s - 0.200).abs() < 1e-9, "{e:?}");
        assert!((e.length_s - 0.080).abs() < 1e-9, "{e:?}");
        assert!((e.peak - 0.35).abs() < 1e-9, "{e:?}");
        assert!((e.peak_s - 0.240).abs() < 1e-9, "{e:?}");
        assert_eq!(m.cycles, 1000);
        assert!((m.time_s - 1.0).abs() < 1e-9);
        assert!((m.max_abs_slip - 0.5).abs() < 1e-9);
        // 79 cycles at 0.3 or more, one at 0.5: above 0.2 for 80 ms
        assert!(
            (m.share_above[1] - 0.080).abs() < 1e-9,
            "{:?}",
            m.share_above
        );
        assert!((m.delivered - 0.75).abs() < 1e-12);
        assert!((m.withheld_nms - 50.0).abs() < 1e-9);
        assert!(
            m.render()
                .contains("spin events (|λ_m| above 0.2 for 20 ms or more")
        );
        // 15 ms above: no event
        let short = log(300, |k, c| {
            if (100..115).contains(&k) {
                c.omega = omega_for(0.3, c.v);
            }
        });
        assert!(measured(&short, &v, None, None).spins.is_empty());
    }

    /// A spin still going at the window's end (a drive without ARTE
    /// spinning on the snow it ends on) is flagged as cut there, in the
    /// report and the event, not reported as if it had ended; one that
    /// ended inside the window is not.
    #[test]
    fn a_spin_cut_by_the_windows_end_says_so() {
        // 0.3 from cycle 100 to 140 (ended), and from cycle 900 to the
        // scenario window's end at cycle 1000 (the log goes on spinning)
        let l = log(1100, |k, c| {
            if (100..140).contains(&k) || k >= 900 {
                c.omega = omega_for(0.3, c.v);
            }
        });
        let v = VehicleParams::default();
        let (ws, we) = (1_000 * MS, 2_000 * MS);
        let m = measured(&l, &v, Some((ws, we)), None);
        assert_eq!(m.spins.len(), 2, "{:?}", m.spins);
        let (ended, cut) = (m.spins[0], m.spins[1]);
        assert!(!ended.cut, "{ended:?}");
        assert!(cut.cut, "{cut:?}");
        assert!((cut.start_s - 0.900).abs() < 1e-9, "{cut:?}");
        assert!((cut.length_s - 0.100).abs() < 1e-9, "{cut:?}");
        let r = m.render();
        assert!(
            r.contains("or more; dips under 5 ms bridged): 2 (1 cut short by the window's end)"),
            "{r}"
        );
        assert!(
            r.contains(
                "at 0.900 s for 0.100 s, peak |λ_m| 0.300 at 0.900 s; cut short by the window's end (the spin still going there: |λ_m| above 0.2, or in a dip shorter than the bridge): it lasted at least this long"
            ),
            "{r}"
        );
        assert!(
            r.contains("at 0.100 s for 0.040 s, peak |λ_m| 0.300 at 0.100 s\n"),
            "{r}"
        );
        // the same spin in a dip shorter than the bridge at the window's
        // end: still not ended there
        let dip = log(1000, |k, c| {
            if (900..997).contains(&k) {
                c.omega = omega_for(0.3, c.v);
            }
        });
        assert!(measured(&dip, &v, Some((ws, we)), None).spins[0].cut);
        // over the whole log (the driver's demand to its last cycle) the
        // first log's spin runs to the last record: cut there too
        let m = measured(&l, &v, None, None);
        assert!(
            m.spins[1].cut && (m.spins[1].length_s - 0.200).abs() < 1e-9,
            "{:?}",
            m.spins
        );
        // ended 10 ms before the window's end: not cut
        let ended = log(1000, |k, c| {
            if (900..990).contains(&k) {
                c.omega = omega_for(0.3, c.v);
            }
        });
        assert!(!measured(&ended, &v, Some((ws, we)), None).spins[0].cut);
    }

    #[test]
    fn the_demand_window_leaves_out_released_pedal_and_invalid_speeds() {
        let l = log(1000, |k, c| {
            if !(100..900).contains(&k) {
                c.demand = 0.0;
                // a wheel spinning while the pedal is released is not counted
                c.omega = omega_for(0.5, c.v);
            }
            if (400..450).contains(&k) {
                c.v_valid = 0;
                c.v = f64::NAN;
            }
            if (500..510).contains(&k) {
                c.v = 0.5;
                c.omega = 0.5 / VehicleParams::default().r;
            }
            // accelerating at 1 m/s² while demanded
            c.v += (k as f64 * 1e-3).min(0.9) - 0.1;
            if (500..510).contains(&k) {
                c.v = 0.5;
            }
        });
        let m = measured(&l, &VehicleParams::default(), None, None);
        assert_eq!((m.stretches, m.cycles), (1, 800));
        assert_eq!((m.no_valid_v, m.slow), (50, 10));
        assert_eq!(m.slip_cycles, 740);
        assert!(m.spins.is_empty());
        let (a, b) = m.span_s.unwrap();
        assert!((a - 0.1).abs() < 1e-9 && (b - 0.9).abs() < 1e-9, "{a} {b}");
        // V from 5.0 to 5.798 over 0.799 s
        assert!((m.mean_accel - 1.0).abs() < 1e-9, "{}", m.mean_accel);
        let r = m.render();
        assert!(
            r.contains("left out: 50 without a valid V, 10 below 1 m/s"),
            "{r}"
        );
        assert!(r.contains("1 stretch, 0.800 s in all"), "{r}");
    }

    /// The one rule, each reason apart (the measured section counts them,
    /// the car-log plot draws only the slips).
    #[test]
    fn a_cycle_measures_slip_or_says_why_not() {
        let mut c = CycleRecord {
            omega: 20.0,
            v: 5.0,
            v_valid: 1,
            ..Default::default()
        };
        let l = cycle_slip(0.28, 0.1, &c).unwrap();
        assert!((l - (5.6 - 5.0) / 5.6).abs() < 1e-12, "{l}");
        c.safe_state = 1;
        assert_eq!(cycle_slip(0.28, 0.1, &c), Err(NoSlip::SafeState));
        c.safe_state = 0;
        c.v_valid = 0;
        assert_eq!(cycle_slip(0.28, 0.1, &c), Err(NoSlip::NoValidV));
        c.v_valid = 1;
        c.omega = f64::NAN;
        assert_eq!(cycle_slip(0.28, 0.1, &c), Err(NoSlip::NoValidV));
        c.omega = 1.0;
        c.v = 0.5;
        assert_eq!(cycle_slip(0.28, 0.1, &c), Err(NoSlip::Slow));
    }

    /// A wheel-speed timeout: the loop enters its safe state and records
    /// ω = 0 for the wheel speed it no longer has, while V (VehicleSpeed)
    /// is still valid. That is no locked wheel: the safe state's cycles
    /// are left out of the slip (they read slip −1 before, a 39-cycle
    /// "spin" in the HIL's bus-deleted drive), their V still counts.
    #[test]
    fn the_safe_states_stale_wheel_speed_is_no_locked_wheel() {
        let l = log(1000, |k, c| {
            if k >= 600 {
                c.safe_state = 1;
                c.omega = 0.0;
            }
        });
        let m = measured(&l, &VehicleParams::default(), None, None);
        assert_eq!((m.safe, m.slip_cycles), (400, 600));
        assert!(m.max_abs_slip < 0.1, "{}", m.max_abs_slip);
        assert!(m.spins.is_empty(), "{:?}", m.spins);
        let r = m.render();
        assert!(r.contains("400 in the safe state"), "{r}");
    }

    #[test]
    fn bad_input_gives_no_panic_and_no_figure() {
        let v = VehicleParams::default();
        let empty = measured(&DriveLog::default(), &v, None, None);
        assert_eq!(empty.window, MeasuredWindow::NoCycles);
        assert!(empty.render().contains("no cycle record"));
        // NaN speeds, V never valid, NaN demand
        let l = log(200, |k, c| {
            c.omega = f64::NAN;
            c.v_valid = u8::from(k % 2 == 0);
            c.v = f64::NAN;
            if k == 50 {
                c.demand = f64::NAN;
            }
        });
        let m = measured(&l, &v, None, None);
        assert_eq!(m.slip_cycles, 0);
        assert_eq!(m.no_valid_v, 199);
        assert!(m.mean_abs_slip.is_nan() && m.mean_accel.is_nan());
        assert_eq!(m.stretches, 2);
        let _ = m.render();
        let _ = compare_rows(&m, &empty);
        // no demand at all: an empty window
        let idle = log(100, |_, c| c.demand = 0.0);
        let m = measured(&idle, &v, None, None);
        assert_eq!((m.cycles, m.stretches), (0, 0));
        assert!(m.render().contains("no cycle in it"), "{}", m.render());
        // stamps at the ends of the clock: no overflow
        let mut l = log(4, |_, _| {});
        l.cycles[1].stamp_ns = u64::MAX;
        l.cycles[2].stamp_ns = 0;
        l.cycles[3].stamp_ns = 1 << 63;
        let _ = measured(&l, &v, None, None).render();
        let _ = measured(&l, &v, Some((0, u64::MAX)), None).render();
        // cycles out of time order: no negative time
        let mut l = log(100, |_, _| {});
        l.cycles.swap(10, 60);
        let m = measured(&l, &v, None, None);
        assert!(m.time_s > 0.0 && m.time_s < 0.2, "{}", m.time_s);
    }

    #[test]
    fn per_believed_road_and_scenario_window() {
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let l = log(1000, |k, c| {
            c.belief_road = if k < 500 { 0 } else { 1 };
            if k >= 500 {
                c.torque_cmd = 100.0;
                c.omega = omega_for(0.05, c.v);
            }
        });
        let v = VehicleParams::default();
        // the scenario window: 200..800 ms of the cycles
        let m = measured(&l, &v, Some((1_200 * MS, 1_800 * MS)), Some(&roads));
        assert_eq!(m.window, MeasuredWindow::Scenario);
        assert_eq!(m.cycles, 600);
        let (a, b) = m.span_s.unwrap();
        assert!(a.abs() < 1e-9 && (b - 0.6).abs() < 1e-9, "{a} {b}");
        let b = &m.per_belief;
        assert_eq!(b.len(), 2, "{b:?}");
        assert_eq!(
            (b[0].road.as_str(), b[1].road.as_str()),
            ("asphalt", "snow")
        );
        assert!((b[0].time_s - 0.3).abs() < 1e-9 && (b[1].time_s - 0.3).abs() < 1e-9);
        assert!(b[0].mean_abs_slip.abs() < 1e-9);
        assert!((b[1].mean_abs_slip - 0.05).abs() < 1e-9);
        assert!((b[1].max_slip - 0.05).abs() < 1e-9);
        assert!((b[1].mean_cmd - 100.0).abs() < 1e-9);
        assert!((m.mean_abs_slip - 0.025).abs() < 1e-9);
        // without the catalogue: by index
        let m = measured(&l, &v, None, None);
        assert_eq!(m.per_belief[1].road, "road #1");
        assert!(m.render().contains("road #1"));
    }
}
