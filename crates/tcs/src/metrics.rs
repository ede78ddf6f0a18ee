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
//! | `mean_accel` | (V_last − V_first) / (T_run − dt_last): speed gained between the first and the last sample over the time between them |
//! | `distance` | Σ V dt |
//! | `energy` | Σ T ω dt (J; motor output energy at the driven wheel, negative while regenerating) |
//! | `kinetic_energy_gain` | ½ (M/n)(V_last² − V_first²) + ½ J_w (ω_last² − ω_first²) (J; one wheel's share, like `energy`) |
//! | `duration` | T_run |
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
    /// Mean acceleration, m/s².
    pub mean_accel: f64,
    /// Distance travelled, m.
    pub distance: f64,
    /// ∫ T ω dt, J.
    pub energy: f64,
    /// Kinetic energy gained (vehicle share + wheel rotation), J.
    pub kinetic_energy_gain: f64,
    /// T_run, s.
    pub duration: f64,
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
    samples: u64,
    rejected: u64,
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
            samples: 0,
            rejected: 0,
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
            return;
        }
        if self.first.is_none() {
            self.first = Some(*s);
        }
        self.last = *s;
        self.samples += 1;
        self.duration += s.dt;
        self.int_abs_lambda += s.lambda.abs() * s.dt;
        self.int_abs_torque += s.torque.abs() * s.dt;
        self.max_torque = self.max_torque.max(s.torque.abs());
        self.distance += s.v * s.dt;
        self.energy += s.torque * s.omega * s.dt;
    }

    /// The metrics so far (the accumulator can keep going afterwards).
    /// An empty run gives all zeros.
    pub fn finish(&self) -> Metrics {
        let Some(first) = self.first else {
            return Metrics {
                rejected: self.rejected,
                ..Metrics::default()
            };
        };
        let t = self.duration;
        let span = t - self.last.dt;
        let last = self.last;
        let mean_accel = if span > 0.0 {
            (last.v - first.v) / span
        } else {
            0.0
        };
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
            },
            Sample {
                dt: 0.1,
                lambda: -0.2,
                torque: -50.0,
                omega: 11.0,
                v: 3.0,
            },
            Sample {
                dt: 0.2,
                lambda: 0.05,
                torque: 200.0,
                omega: 12.0,
                v: 4.0,
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
        assert_eq!(acc.finish(), Metrics::default());
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
        });
        let m = acc.finish();
        assert!(close(m.slip_deviation, 0.2));
        // One sample: no span for an acceleration.
        assert_eq!(m.mean_accel, 0.0);
    }
}
