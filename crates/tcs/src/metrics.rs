//! The metrics (README.md, "Metrics"): one definition for every caller (offline
//! simulation, the live drive summary, MCAP inspection).
//!
//! Feed one [`Sample`] per control cycle to a [`MetricsAccumulator`], then
//! call [`MetricsAccumulator::finish`]. Sample semantics: the values hold
//! for the cycle `[t, t + dt)` (zero-order hold, as the controller sees
//! them), so every integral is the exact sum `Σ x_k dt_k`. With
//! `T_run = Σ dt_k`:
//!
//! | metric | definition |
//! |---|---|
//! | `slip_deviation` | (1/T_run) Σ \|λ\| dt — the paper's "time-averaged slip ratio deviation" |
//! | `max_torque` | max \|T\| |
//! | `torque_effort` | (1/T_run) Σ \|T\| dt — the paper's "normalised area of the torque-time graph" (N m) |
//! | `mean_accel` | (V_last − V_first) / (t_last − t_first): speed gained between the first and the last sample over the time between their starts (the `dt` of rejected samples between them included; NaN with fewer than two samples) |
//! | `distance` | Σ V dt |
//! | `energy` | Σ T ω dt (J; motor output energy at the driven wheel, negative while regenerating) |
//! | `kinetic_energy_gain` | ½ (M/n)(V_last² − V_first²) + ½ J_w (ω_last² − ω_first²) (J; one wheel's share, like `energy`) |
//! | `duration` | T_run |
//! | `cmd_tv_per_s` | Σ \|T*_k − T*_(k−1)\| / T_cmd: the command's total variation per second (N m/s) |
//! | `cmd_hf_rms` | √((1/T_cmd) Σ y² dt), y = T* through a 4th-order Butterworth high-pass at 20 Hz (N m) |
//! | `cmd_hf_share` | (1/T_cmd) Σ y² dt over the command's variance: the share of its (mean-free) power above 20 Hz |
//!
//! `T*` is the torque *command* (`Sample::torque_cmd`, what the controller
//! sends the inverter), T_cmd the summed `dt` of the samples that carry a
//! finite command (a sample without one, NaN, leaves the command's figures
//! alone and is not rejected). The high-pass is designed once, for the
//! stream's nominal period: the first command's `dt` (bilinear transform,
//! cut-off pre-warped). A later `dt` within [`CMD_REDESIGN_TOL`] (10 %) of
//! it, a cycle's timing jitter, uses the same filter; a `dt` further off, a
//! real change of rate, re-designs it for that `dt` with the filter put at
//! rest on that sample's command. The filter starts at rest on the first
//! command, so a constant command gives exactly 0 however its `dt`
//! jitters, and needs about 50 ms to forget a step; a constant command has
//! no variance and a share of 0.
//!
//! Nothing to compute from gives NaN (none), not 0: a run without an
//! accepted sample has NaN means, maximum and command figures; fewer than
//! two samples (no time between the first and the last) a NaN `mean_accel`;
//! no finite command NaN command figures.
//!
//! `T` is the torque actually acting on the wheel (the plant's motor torque
//! after its lag, or the inverter's reported torque live), not the command.
//! Quantities are for the one driven wheel of the quarter-vehicle model (the
//! vehicle share M/n), consistent with `energy`.
//!
//! Samples with a non-finite or non-positive `dt` are ignored (and counted
//! in [`Metrics::rejected`]); non-finite values in a sample are ignored the
//! same way, so one bad record cannot poison a drive summary. The
//! accumulator is `Copy` and never allocates.

use grip_physics::VehicleParams;

/// One control cycle's values.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Cycle length, s.
    pub dt: f64,
    /// Slip ratio λ.
    pub lambda: f64,
    /// Motor torque T acting on the wheel, N m.
    pub torque: f64,
    /// Wheel speed ω, rad/s.
    pub omega: f64,
    /// Vehicle speed V, m/s.
    pub v: f64,
    /// Torque command T* the controller sent this cycle, N m (NaN: unknown;
    /// only the command's figures skip it).
    pub torque_cmd: f64,
}

/// The result of a run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Metrics {
    /// (1/T_run) ∫ |λ| dt.
    pub slip_deviation: f64,
    /// max |T|, N m.
    pub max_torque: f64,
    /// (1/T_run) ∫ |T| dt, N m (the paper's "normalised area").
    pub torque_effort: f64,
    /// Mean acceleration, m/s² (NaN with fewer than two samples).
    pub mean_accel: f64,
    /// Distance travelled, m.
    pub distance: f64,
    /// ∫ T ω dt, J.
    pub energy: f64,
    /// Kinetic energy gained (vehicle share + wheel rotation), J.
    pub kinetic_energy_gain: f64,
    /// T_run, s.
    pub duration: f64,
    /// Total variation of the command per second, Σ |ΔT*| / T_cmd, N m/s
    /// (this and the other two command figures NaN without a finite
    /// command).
    pub cmd_tv_per_s: f64,
    /// RMS of the command above 20 Hz (4th-order Butterworth high-pass), N m.
    pub cmd_hf_rms: f64,
    /// Share of the command's mean-free power above 20 Hz, [0, 1].
    pub cmd_hf_share: f64,
    /// T_cmd: the time of the samples with a finite command, s (what the
    /// command's figures are per).
    pub cmd_duration: f64,
    /// Number of samples accumulated.
    pub samples: u64,
    /// Number of samples ignored (non-finite values or dt <= 0).
    pub rejected: u64,
}

/// Accumulates [`Sample`]s into [`Metrics`]; allocation-free.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MetricsAccumulator {
    mass_share: f64,
    j_w: f64,
    duration: f64,
    int_abs_lambda: f64,
    int_abs_torque: f64,
    max_torque: f64,
    distance: f64,
    energy: f64,
    first: Option<Sample>,
    last: Sample,
    /// Σ dt of every sample with a valid dt from the first accepted one on
    /// (rejected ones included: they are time that passed).
    elapsed: f64,
    /// `elapsed` at the start of the last accepted sample.
    last_at: f64,
    samples: u64,
    rejected: u64,
    cmd: CommandStats,
}

/// Cut-off of the command's high-frequency figures, Hz.
pub const CMD_HF_CUTOFF_HZ: f64 = 20.0;

/// The command's high-pass is re-designed only when a sample's `dt` is more
/// than this fraction off the period it was designed for (a change of the
/// stream's rate, not a cycle's timing jitter).
pub const CMD_REDESIGN_TOL: f64 = 0.1;

/// One biquad section, transposed direct form II.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    s1: f64,
    s2: f64,
}

impl Biquad {
    fn step(&mut self, x: f64) -> f64 {
        let y = self.b[0] * x + self.s1;
        self.s1 = self.b[1] * x - self.a[0] * y + self.s2;
        self.s2 = self.b[2] * x - self.a[1] * y;
        y
    }
    /// At rest on a constant input `x` (a high-pass: output 0).
    fn rest_on(&mut self, x: f64) {
        self.s1 = -self.b[0] * x;
        self.s2 = self.b[2] * x;
    }
}

/// The command's smoothness figures: total variation, and a 4th-order
/// Butterworth high-pass at [`CMD_HF_CUTOFF_HZ`] (two biquads, Q = 1/(2
/// cos(π/8)) and 1/(2 cos(3π/8))), with a weighted running mean and
/// variance (West's update) for the share. Allocation-free.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct CommandStats {
    design_dt: f64,
    hp: [Biquad; 2],
    prev: Option<f64>,
    duration: f64,
    tv: f64,
    int_hf2: f64,
    mean: f64,
    m2: f64,
}

impl CommandStats {
    fn design(&mut self, dt: f64) {
        // Bilinear transform of s² / (s² + (w/Q) s + w²) with w pre-warped.
        let k = (std::f64::consts::PI * CMD_HF_CUTOFF_HZ * dt).tan();
        for (sec, q) in self.hp.iter_mut().zip([
            0.5 / (std::f64::consts::PI / 8.0).cos(),
            0.5 / (3.0 * std::f64::consts::PI / 8.0).cos(),
        ]) {
            let n = 1.0 / (1.0 + k / q + k * k);
            sec.b = [n, -2.0 * n, n];
            sec.a = [2.0 * (k * k - 1.0) * n, (1.0 - k / q + k * k) * n];
        }
        self.design_dt = dt;
    }

    fn push(&mut self, dt: f64, x: f64) {
        if !x.is_finite() {
            return;
        }
        // The filter is designed once, for the stream's nominal period (the
        // first command's dt); a drive log's cycles jitter by tens of µs
        // around it, and re-designing for each cycle's dt with the state
        // carried over would inject spurious high-frequency power (a
        // constant command would not give 0). Only a real change of rate,
        // a dt more than [`CMD_REDESIGN_TOL`] off the design's, re-designs it,
        // with the state put at rest on the current command.
        let redesign =
            self.prev.is_none() || (dt - self.design_dt).abs() > CMD_REDESIGN_TOL * self.design_dt;
        if redesign {
            self.design(dt);
        }
        let y = match self.prev {
            None => {
                self.hp[0].rest_on(x);
                self.hp[1].rest_on(0.0);
                0.0
            }
            Some(p) => {
                self.tv += (x - p).abs();
                if redesign {
                    self.hp[0].rest_on(x);
                    self.hp[1].rest_on(0.0);
                    0.0
                } else {
                    let y = self.hp[0].step(x);
                    self.hp[1].step(y)
                }
            }
        };
        self.prev = Some(x);
        self.int_hf2 += y * y * dt;
        // Weighted mean and variance (weights dt), West 1979.
        self.duration += dt;
        let d = x - self.mean;
        self.mean += d * dt / self.duration;
        self.m2 += dt * d * (x - self.mean);
    }

    /// (TV per second, HF RMS, HF share); NaN without a command.
    fn finish(&self) -> (f64, f64, f64) {
        if self.duration <= 0.0 {
            return (f64::NAN, f64::NAN, f64::NAN);
        }
        let t = self.duration;
        let hf_ms = self.int_hf2 / t;
        let var = self.m2 / t;
        let share = if var > 0.0 {
            (hf_ms / var).min(1.0)
        } else {
            0.0
        };
        (self.tv / t, hf_ms.sqrt(), share)
    }
}

impl MetricsAccumulator {
    /// An empty accumulator for `vehicle` (its M/n and J_w enter the
    /// kinetic-energy gain).
    pub fn new(vehicle: &VehicleParams) -> Self {
        Self {
            mass_share: vehicle.mass_share(),
            j_w: vehicle.j_w,
            duration: 0.0,
            int_abs_lambda: 0.0,
            int_abs_torque: 0.0,
            max_torque: 0.0,
            distance: 0.0,
            energy: 0.0,
            first: None,
            last: Sample::default(),
            elapsed: 0.0,
            last_at: 0.0,
            samples: 0,
            rejected: 0,
            cmd: CommandStats::default(),
        }
    }

    /// Add one cycle.
    pub fn push(&mut self, s: &Sample) {
        let ok = s.dt.is_finite()
            && s.dt > 0.0
            && s.lambda.is_finite()
            && s.torque.is_finite()
            && s.omega.is_finite()
            && s.v.is_finite();
        if !ok {
            self.rejected += 1;
            // a rejected sample's time still passes between the first and
            // the last sample (the acceleration's time base)
            if self.first.is_some() && s.dt.is_finite() && s.dt > 0.0 {
                self.elapsed += s.dt;
            }
            return;
        }
        if self.first.is_none() {
            self.first = Some(*s);
        }
        self.last = *s;
        self.elapsed += s.dt;
        // `elapsed − dt`, not the sum before this sample: with no rejected
        // sample it is bit for bit `T_run − dt_last`
        self.last_at = self.elapsed - s.dt;
        self.samples += 1;
        self.duration += s.dt;
        self.int_abs_lambda += s.lambda.abs() * s.dt;
        self.int_abs_torque += s.torque.abs() * s.dt;
        self.max_torque = self.max_torque.max(s.torque.abs());
        self.distance += s.v * s.dt;
        self.energy += s.torque * s.omega * s.dt;
        self.cmd.push(s.dt, s.torque_cmd);
    }

    /// The metrics so far (the accumulator can keep going afterwards).
    /// An empty run gives NaN for every mean, ratio and the acceleration
    /// (none: nothing to compute them from) and zeros for the sums and
    /// counts; see [`Metrics`] for the other NaNs.
    pub fn finish(&self) -> Metrics {
        let Some(first) = self.first else {
            let nan = f64::NAN;
            return Metrics {
                slip_deviation: nan,
                max_torque: nan,
                torque_effort: nan,
                mean_accel: nan,
                cmd_tv_per_s: nan,
                cmd_hf_rms: nan,
                cmd_hf_share: nan,
                rejected: self.rejected,
                ..Metrics::default()
            };
        };
        let t = self.duration;
        // from the first sample's start to the last's, rejected samples'
        // time included
        let span = self.last_at;
        let last = self.last;
        let mean_accel = if span > 0.0 {
            (last.v - first.v) / span
        } else {
            f64::NAN
        };
        let (cmd_tv_per_s, cmd_hf_rms, cmd_hf_share) = self.cmd.finish();
        let kinetic_energy_gain = 0.5 * self.mass_share * (last.v * last.v - first.v * first.v)
            + 0.5 * self.j_w * (last.omega * last.omega - first.omega * first.omega);
        Metrics {
            slip_deviation: self.int_abs_lambda / t,
            max_torque: self.max_torque,
            torque_effort: self.int_abs_torque / t,
            mean_accel,
            distance: self.distance,
            energy: self.energy,
            kinetic_energy_gain,
            duration: t,
            cmd_tv_per_s,
            cmd_hf_rms,
            cmd_hf_share,
            cmd_duration: self.cmd.duration,
            samples: self.samples,
            rejected: self.rejected,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * (1.0 + b.abs())
    }

    #[test]
    fn hand_worked_three_cycles() {
        let v = VehicleParams::default(); // M/n = 350 kg, J_w = 0.6
        let mut acc = MetricsAccumulator::new(&v);
        let s = [
            Sample {
                dt: 0.1,
                lambda: 0.1,
                torque: 100.0,
                omega: 10.0,
                v: 2.0,
                torque_cmd: 0.0,
            },
            Sample {
                dt: 0.1,
                lambda: -0.2,
                torque: -50.0,
                omega: 11.0,
                v: 3.0,
                torque_cmd: 0.0,
            },
            Sample {
                dt: 0.2,
                lambda: 0.05,
                torque: 200.0,
                omega: 12.0,
                v: 4.0,
                torque_cmd: 0.0,
            },
        ];
        for x in &s {
            acc.push(x);
        }
        let m = acc.finish();
        // T_run = 0.4
        assert!(close(m.duration, 0.4));
        // ∫|λ| = 0.01 + 0.02 + 0.01 = 0.04 → 0.1
        assert!(close(m.slip_deviation, 0.1));
        assert!(close(m.max_torque, 200.0));
        // ∫|T| = 10 + 5 + 40 = 55 → 137.5
        assert!(close(m.torque_effort, 137.5));
        // Δv = 2 over 0.2 s
        assert!(close(m.mean_accel, 10.0));
        // 0.2 + 0.3 + 0.8
        assert!(close(m.distance, 1.3));
        // 100 − 55 + 480
        assert!(close(m.energy, 525.0));
        // ½·350·(16 − 4) + ½·0.6·(144 − 100) = 2100 + 13.2
        assert!(close(m.kinetic_energy_gain, 2113.2));
        assert_eq!(m.samples, 3);
        assert_eq!(m.rejected, 0);
    }

    #[test]
    fn constant_cruise() {
        let v = VehicleParams::default();
        let mut acc = MetricsAccumulator::new(&v);
        for _ in 0..1000 {
            acc.push(&Sample {
                dt: 1e-3,
                lambda: 0.0,
                torque: 20.0,
                omega: 10.0,
                v: 2.8,
                torque_cmd: 0.0,
            });
        }
        let m = acc.finish();
        assert!(close(m.duration, 1.0));
        assert!((m.distance - 2.8).abs() < 1e-9);
        assert!((m.energy - 200.0).abs() < 1e-9);
        assert_eq!(m.mean_accel, 0.0);
        assert_eq!(m.kinetic_energy_gain, 0.0);
        assert_eq!(m.slip_deviation, 0.0);
        assert!((m.torque_effort - 20.0).abs() < 1e-9);
    }

    #[test]
    fn empty_and_bad_samples() {
        let v = VehicleParams::default();
        let mut acc = MetricsAccumulator::new(&v);
        let e = acc.finish();
        // nothing to compute from: none (NaN), not 0
        assert!(
            [
                e.slip_deviation,
                e.max_torque,
                e.torque_effort,
                e.mean_accel,
                e.cmd_tv_per_s,
                e.cmd_hf_rms,
                e.cmd_hf_share
            ]
            .iter()
            .all(|x| x.is_nan()),
            "{e:?}"
        );
        assert_eq!((e.duration, e.distance, e.samples), (0.0, 0.0, 0));
        acc.push(&Sample {
            dt: 0.0,
            ..Sample::default()
        });
        acc.push(&Sample {
            dt: 1e-3,
            lambda: f64::NAN,
            ..Sample::default()
        });
        let m = acc.finish();
        assert_eq!(m.rejected, 2);
        assert_eq!(m.samples, 0);
        acc.push(&Sample {
            dt: 0.5,
            lambda: 0.2,
            torque: 10.0,
            omega: 1.0,
            v: 1.0,
            torque_cmd: 0.0,
        });
        let m = acc.finish();
        assert!(close(m.slip_deviation, 0.2));
        // One sample: no span for an acceleration.
        assert!(m.mean_accel.is_nan());
    }

    #[test]
    fn rejected_samples_mid_run_keep_the_acceleration_time_base() {
        // 1 m/s² at 1 kHz for 1 s; every 10th sample carries a NaN slip
        // (rejected). V goes from 0 to 0.999 m/s over 0.999 s whatever is
        // rejected between.
        let v = VehicleParams::default();
        let mut acc = MetricsAccumulator::new(&v);
        for k in 0..1000 {
            acc.push(&Sample {
                dt: 1e-3,
                lambda: if k % 10 == 5 { f64::NAN } else { 0.0 },
                torque: 10.0,
                omega: 1.0,
                v: k as f64 * 1e-3,
                torque_cmd: 0.0,
            });
        }
        let m = acc.finish();
        assert_eq!(m.rejected, 100);
        assert!((m.mean_accel - 1.0).abs() < 1e-9, "{}", m.mean_accel);
        // a rejected sample after the last accepted one is not in the span
        acc.push(&Sample {
            dt: 1e-3,
            lambda: f64::NAN,
            ..Sample::default()
        });
        assert!((acc.finish().mean_accel - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_constant_command_with_jittered_dt_has_no_high_frequency() {
        // 300 N m for 2 s at a nominal 1 kHz, each cycle's dt off by up to
        // ±20 µs (a drive log's stamps): exactly 0, as for a fixed step.
        let v = VehicleParams::default();
        let mut acc = MetricsAccumulator::new(&v);
        let mut seed = 12345u64;
        for _ in 0..2000 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
            acc.push(&Sample {
                dt: 1e-3 + (u - 0.5) * 40e-6,
                torque: 300.0,
                omega: 10.0,
                v: 2.8,
                torque_cmd: 300.0,
                ..Sample::default()
            });
        }
        let m = acc.finish();
        assert_eq!(
            (m.cmd_tv_per_s, m.cmd_hf_rms, m.cmd_hf_share),
            (0.0, 0.0, 0.0)
        );
        // a jittered 50 Hz sine stays what it is at a fixed step
        let sine = |k: usize| 200.0 + 10.0 * (2.0 * std::f64::consts::PI * 0.05 * k as f64).sin();
        let fixed = command_run(1e-3, 2000, sine);
        let mut acc = MetricsAccumulator::new(&v);
        for k in 0..2000 {
            let j = if k % 2 == 0 { 15e-6 } else { -15e-6 };
            acc.push(&Sample {
                dt: 1e-3 + j,
                torque: 100.0,
                omega: 10.0,
                v: 2.8,
                torque_cmd: sine(k),
                ..Sample::default()
            });
        }
        let m = acc.finish();
        assert!(
            (m.cmd_hf_rms - fixed.cmd_hf_rms).abs() < 0.01 * fixed.cmd_hf_rms,
            "{} {}",
            m.cmd_hf_rms,
            fixed.cmd_hf_rms
        );
    }

    #[test]
    fn a_real_change_of_rate_redesigns_the_filter_at_rest() {
        // 1 kHz, then 500 Hz: a constant command still gives 0, and a
        // 5 Hz sine stays under the 20 Hz cut-off after the change.
        let v = VehicleParams::default();
        let mut acc = MetricsAccumulator::new(&v);
        let mut t = 0.0;
        for k in 0..3000 {
            let dt = if k < 1000 { 1e-3 } else { 2e-3 };
            acc.push(&Sample {
                dt,
                torque: 100.0,
                omega: 10.0,
                v: 2.8,
                torque_cmd: 100.0 + 50.0 * (2.0 * std::f64::consts::PI * 5.0 * t).sin(),
                ..Sample::default()
            });
            t += dt;
        }
        let m = acc.finish();
        assert!(m.cmd_hf_share < 0.01, "{}", m.cmd_hf_share);
    }

    fn command_run(dt: f64, n: usize, cmd: impl Fn(usize) -> f64) -> Metrics {
        let v = VehicleParams::default();
        let mut acc = MetricsAccumulator::new(&v);
        for k in 0..n {
            acc.push(&Sample {
                dt,
                torque: 100.0,
                omega: 10.0,
                v: 2.8,
                torque_cmd: cmd(k),
                ..Sample::default()
            });
        }
        acc.finish()
    }

    #[test]
    fn square_wave_command() {
        // 0/100 N m at 10 Hz for 10 s at 1 kHz: 199 edges of 100 N m.
        let m = command_run(
            1e-3,
            10_000,
            |k| if (k / 50) % 2 == 0 { 100.0 } else { 0.0 },
        );
        assert!(close(m.cmd_tv_per_s, 1990.0), "{}", m.cmd_tv_per_s);
        // A square wave's power in its odd harmonics n is 8/(π² n²) of the
        // mean-free power: all but the fundamental (10 Hz) lie above 20 Hz,
        // 1 − 8/π² = 0.189 (the Butterworth edge moves it by < 0.005).
        let hand = 1.0 - 8.0 / std::f64::consts::PI.powi(2);
        assert!((m.cmd_hf_share - hand).abs() < 0.005, "{}", m.cmd_hf_share);
        // mean-free RMS 50 N m
        assert!(
            (m.cmd_hf_rms - 50.0 * hand.sqrt()).abs() < 0.5,
            "{}",
            m.cmd_hf_rms
        );
    }

    #[test]
    fn a_50_hz_sine_is_high_frequency_a_slow_ramp_is_not() {
        // 200 ± 10 N m at 50 Hz, 2 s: TV = 4 A per period (20 samples a
        // period, the peaks on samples), 100 periods less the last step
        // (A sin(2π/20)) not taken: (4000 − 3.09) / 2 s = 1998.45 N m/s;
        // all of its power above 20 Hz.
        let sine = command_run(1e-3, 2000, |k| {
            200.0 + 10.0 * (2.0 * std::f64::consts::PI * 50.0 * k as f64 * 1e-3).sin()
        });
        let hand = (4000.0 - 10.0 * (std::f64::consts::PI / 10.0).sin()) / 2.0;
        assert!(close(sine.cmd_tv_per_s, hand), "{}", sine.cmd_tv_per_s);
        assert!(sine.cmd_hf_share > 0.99, "{}", sine.cmd_hf_share);
        // RMS 10/√2 = 7.07 N m
        assert!((sine.cmd_hf_rms - 7.071).abs() < 0.1, "{}", sine.cmd_hf_rms);
        // 0 → 300 N m in 3 s: TV 299.9 N m over 3 s, nothing above 20 Hz
        // but the high-pass's start-up transient.
        let ramp = command_run(1e-3, 3000, |k| 100.0 * k as f64 * 1e-3);
        assert!(
            close(ramp.cmd_tv_per_s, 299.9 / 3.0),
            "{}",
            ramp.cmd_tv_per_s
        );
        assert!(ramp.cmd_hf_share < 1e-4, "{}", ramp.cmd_hf_share);
        assert!(ramp.cmd_hf_rms < 0.5, "{}", ramp.cmd_hf_rms);
    }

    #[test]
    fn constant_or_missing_command() {
        let m = command_run(1e-3, 1000, |_| 250.0);
        assert_eq!(
            (m.cmd_tv_per_s, m.cmd_hf_rms, m.cmd_hf_share),
            (0.0, 0.0, 0.0)
        );
        // no finite command at all: none
        let m = command_run(1e-3, 100, |_| f64::NAN);
        assert!(m.cmd_tv_per_s.is_nan() && m.cmd_hf_rms.is_nan() && m.cmd_hf_share.is_nan());
        // Samples without a command are skipped by the command's figures
        // only: the rest of the metrics take them.
        let m = command_run(1e-3, 1000, |k| if k % 2 == 0 { 100.0 } else { f64::NAN });
        assert_eq!(m.samples, 1000);
        assert_eq!(m.rejected, 0);
        assert_eq!(m.cmd_tv_per_s, 0.0);
        // 0 → 10 → 0 ... every cycle: 999 changes of 10 N m in 1 s.
        let m = command_run(1e-3, 1000, |k| if k % 2 == 0 { 0.0 } else { 10.0 });
        assert!(close(m.cmd_tv_per_s, 9990.0), "{}", m.cmd_tv_per_s);
        assert!(m.cmd_hf_share > 0.99, "{}", m.cmd_hf_share);
    }
}
