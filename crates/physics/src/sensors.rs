//! Sensors: what the controller sees instead of the plant's true state.
//!
//! Per controller sample, in this order:
//! 1. **Wheel speed ω** from an angle encoder on the driven wheel (a resolver
//!    with a resolver-to-digital converter on a direct-drive motor). The
//!    sensor integrates the true ω into the wheel angle, quantises the angle
//!    to `encoder_ppr` counts per revolution, and differentiates the count over
//!    `omega_window` samples: ω̂ = Δcount · 2π / (ppr · window · dt). Then
//!    Gaussian noise `omega_noise_std` is added.
//! 2. **Chassis speed V** (when `v_available`; e.g. a non-driven wheel's speed
//!    on CAN): true V + Gaussian noise `v_noise_std`, quantised to `v_lsb`.
//! 3. **Motor torque** as the inverter reports it: true T + Gaussian noise
//!    `torque_noise_std`, quantised to `torque_lsb`.
//! 4. The reading is delayed by `delay_samples` controller samples (a ring
//!    buffer allocated at construction).
//!
//! Noise comes from `rand_chacha::ChaCha8Rng` seeded by the caller: the same
//! seed and the same inputs give bit-identical readings. `sample` allocates
//! nothing.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::plant::PlantState;
use crate::validate::{self, InvalidField};

/// Largest supported delay, controller samples.
pub const MAX_DELAY_SAMPLES: u32 = 1000;
/// Largest supported differentiation window, samples.
pub const MAX_OMEGA_WINDOW: u32 = 1000;

/// Sensor model parameters (`[sensors]` in `config/vehicle.toml`). Defaults
/// describe a realistic EV traction ECU; see the crate README for the reasoning.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorParams {
    /// Encoder counts per wheel revolution; 0 = ideal (no quantisation).
    /// Default 65536: a 16-bit resolver-to-digital converter on a direct-drive
    /// motor (1 motor revolution = 1 wheel revolution).
    pub encoder_ppr: u32,
    /// Samples over which the count is differentiated (>= 1). Default 1.
    pub omega_window: u32,
    /// Standard deviation of additive noise on ω, rad/s. Default 0.05.
    pub omega_noise_std: f64,
    /// Whether a chassis speed V is available to the controller. Default true.
    pub v_available: bool,
    /// Standard deviation of additive noise on V, m/s. Default 0.02.
    pub v_noise_std: f64,
    /// Quantisation step of V, m/s; 0 = none. Default 0.01 km/h = 0.0027778 m/s
    /// (a common CAN vehicle-speed LSB).
    pub v_lsb: f64,
    /// Standard deviation of additive noise on the reported torque, N m. Default 1.0.
    pub torque_noise_std: f64,
    /// Quantisation step of the reported torque, N m; 0 = none. Default 0.1.
    pub torque_lsb: f64,
    /// Transport delay, controller samples. Default 1 (the frame of the
    /// previous cycle on CAN).
    pub delay_samples: u32,
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            encoder_ppr: 65536,
            omega_window: 1,
            omega_noise_std: 0.05,
            v_available: true,
            v_noise_std: 0.02,
            v_lsb: 0.01 / 3.6,
            torque_noise_std: 1.0,
            torque_lsb: 0.1,
            delay_samples: 1,
        }
    }
}

impl SensorParams {
    /// Ideal sensors: no quantisation, noise or delay; V available.
    pub fn ideal() -> Self {
        Self {
            encoder_ppr: 0,
            omega_window: 1,
            omega_noise_std: 0.0,
            v_available: true,
            v_noise_std: 0.0,
            v_lsb: 0.0,
            torque_noise_std: 0.0,
            torque_lsb: 0.0,
            delay_samples: 0,
        }
    }

    /// Range checks: noise std and LSBs finite and >= 0, `omega_window` in
    /// 1..=1000, `delay_samples` <= 1000.
    pub fn validate(&self) -> Result<(), InvalidField> {
        if self.omega_window == 0 || self.omega_window > MAX_OMEGA_WINDOW {
            return Err(InvalidField::new(
                "omega_window",
                format!(
                    "must be in 1..={MAX_OMEGA_WINDOW} (got {})",
                    self.omega_window
                ),
            ));
        }
        validate::non_negative("omega_noise_std", self.omega_noise_std)?;
        validate::non_negative("v_noise_std", self.v_noise_std)?;
        validate::non_negative("v_lsb", self.v_lsb)?;
        validate::non_negative("torque_noise_std", self.torque_noise_std)?;
        validate::non_negative("torque_lsb", self.torque_lsb)?;
        if self.delay_samples > MAX_DELAY_SAMPLES {
            return Err(InvalidField::new(
                "delay_samples",
                format!(
                    "must be <= {MAX_DELAY_SAMPLES} (got {})",
                    self.delay_samples
                ),
            ));
        }
        Ok(())
    }
}

/// One sensor sample, as the controller receives it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorReading {
    /// Measured wheel speed, rad/s.
    pub omega: f64,
    /// Measured chassis speed, m/s; `None` when `v_available` is false.
    pub v: Option<f64>,
    /// Reported motor torque, N m.
    pub torque: f64,
}

/// The sensor model: stateful (encoder angle, differentiation window, delay
/// line, random generator). Construct once per run.
#[derive(Debug, Clone)]
pub struct Sensors {
    params: SensorParams,
    rng: ChaCha8Rng,
    /// Integrated true wheel angle, rad.
    angle: f64,
    /// Previous true ω for trapezoidal angle integration.
    prev_omega: Option<f64>,
    /// Ring of the last `omega_window + 1` counts.
    counts: Vec<i64>,
    count_head: usize,
    count_filled: usize,
    /// Delay line of `delay_samples + 1` readings.
    delay: Vec<SensorReading>,
    delay_head: usize,
    delay_filled: usize,
}

impl Sensors {
    /// A sensor model with validated `params` and noise `seed`.
    pub fn new(params: SensorParams, seed: u64) -> Result<Self, InvalidField> {
        params.validate()?;
        Ok(Self {
            params,
            rng: ChaCha8Rng::seed_from_u64(seed),
            angle: 0.0,
            prev_omega: None,
            counts: vec![0; params.omega_window as usize + 1],
            count_head: 0,
            count_filled: 0,
            delay: vec![SensorReading::default(); params.delay_samples as usize + 1],
            delay_head: 0,
            delay_filled: 0,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &SensorParams {
        &self.params
    }

    fn gauss(&mut self, std: f64) -> f64 {
        if std > 0.0 {
            let z: f64 = StandardNormal.sample(&mut self.rng);
            std * z
        } else {
            0.0
        }
    }

    fn quantise(x: f64, lsb: f64) -> f64 {
        if lsb > 0.0 {
            (x / lsb).round() * lsb
        } else {
            x
        }
    }

    /// Sample the plant state once per controller period `dt` (s). Until the
    /// delay line has filled, the oldest available reading is returned (the
    /// first reading repeats). Allocation-free.
    pub fn sample(&mut self, state: &PlantState, dt: f64) -> SensorReading {
        let p = self.params;
        let dt_ok = dt.is_finite() && dt > 0.0;
        let omega_true = if state.omega.is_finite() {
            state.omega
        } else {
            0.0
        };

        // 1. Encoder.
        let omega_meas = if p.encoder_ppr == 0 || !dt_ok {
            omega_true
        } else {
            if let Some(prev) = self.prev_omega {
                self.angle += 0.5 * (prev + omega_true) * dt;
            }
            let counts_per_rad = p.encoder_ppr as f64 / std::f64::consts::TAU;
            let count = (self.angle * counts_per_rad).floor() as i64;
            let len = self.counts.len();
            self.counts[self.count_head] = count;
            self.count_filled = (self.count_filled + 1).min(len);
            let w = self.count_filled - 1; // samples spanned by the window so far
            let oldest = (self.count_head + len - w) % len;
            self.count_head = (self.count_head + 1) % len;
            if w == 0 {
                omega_true // first sample: no difference yet; report the start value
            } else {
                (count - self.counts[oldest]) as f64 / (counts_per_rad * w as f64 * dt)
            }
        };
        self.prev_omega = Some(omega_true);
        let omega = omega_meas + self.gauss(p.omega_noise_std);

        // 2. Chassis speed.
        let v = if p.v_available {
            let n = self.gauss(p.v_noise_std);
            Some(Self::quantise(state.v + n, p.v_lsb))
        } else {
            None
        };

        // 3. Torque.
        let n = self.gauss(p.torque_noise_std);
        let torque = Self::quantise(state.torque + n, p.torque_lsb);

        // 4. Delay line.
        let len = self.delay.len();
        self.delay[self.delay_head] = SensorReading { omega, v, torque };
        self.delay_filled = (self.delay_filled + 1).min(len);
        let back = self.delay_filled - 1;
        let out = self.delay[(self.delay_head + len - back) % len];
        self.delay_head = (self.delay_head + 1) % len;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn states() -> Vec<PlantState> {
        (0..500)
            .map(|k| {
                let t = k as f64 * 1e-3;
                PlantState {
                    omega: 10.0 + 5.0 * t,
                    v: 2.8 + 1.2 * t,
                    torque: 300.0 * (1.0 - (-t / 0.05).exp()),
                    x: 0.0,
                }
            })
            .collect()
    }

    #[test]
    fn same_seed_same_output_different_seed_different() {
        let run = |seed| {
            let mut s = Sensors::new(SensorParams::default(), seed).unwrap();
            states()
                .iter()
                .map(|x| s.sample(x, 1e-3))
                .collect::<Vec<_>>()
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
    }

    #[test]
    fn ideal_sensors_are_transparent() {
        let mut s = Sensors::new(SensorParams::ideal(), 1).unwrap();
        for x in states() {
            let r = s.sample(&x, 1e-3);
            assert_eq!(
                r,
                SensorReading {
                    omega: x.omega,
                    v: Some(x.v),
                    torque: x.torque
                }
            );
        }
    }

    #[test]
    fn delay_shifts_by_the_configured_samples() {
        let p = SensorParams {
            delay_samples: 3,
            ..SensorParams::ideal()
        };
        let mut s = Sensors::new(p, 1).unwrap();
        let xs = states();
        let out: Vec<_> = xs.iter().map(|x| s.sample(x, 1e-3)).collect();
        for k in 3..xs.len() {
            assert_eq!(out[k].omega, xs[k - 3].omega);
        }
        // Before the line fills, the first reading repeats.
        assert_eq!(out[1].omega, xs[0].omega);
    }

    #[test]
    fn encoder_quantisation_resolution() {
        // 1024 ppr at 1 kHz: one count = 2π/1024/1e-3 = 6.136 rad/s.
        let p = SensorParams {
            encoder_ppr: 1024,
            ..SensorParams::ideal()
        };
        let mut s = Sensors::new(p, 1).unwrap();
        let lsb = std::f64::consts::TAU / 1024.0 / 1e-3;
        let mut sum = 0.0;
        let n = 2000;
        for k in 0..n {
            let r = s.sample(
                &PlantState {
                    omega: 20.0,
                    ..Default::default()
                },
                1e-3,
            );
            if k > 0 {
                let q = r.omega / lsb;
                assert!(
                    (q - q.round()).abs() < 1e-9,
                    "not a multiple of the count: {}",
                    r.omega
                );
                sum += r.omega;
            }
        }
        // Unbiased on average.
        assert!((sum / (n - 1) as f64 - 20.0).abs() < 0.05);
    }

    #[test]
    fn v_unavailable_gives_none_and_noise_has_the_right_size() {
        let p = SensorParams {
            v_available: false,
            torque_lsb: 0.0,
            ..SensorParams::default()
        };
        let mut s = Sensors::new(p, 3).unwrap();
        let x = PlantState {
            omega: 10.0,
            v: 3.0,
            torque: 100.0,
            x: 0.0,
        };
        let mut sq = 0.0;
        let n = 20_000;
        for _ in 0..n {
            let r = s.sample(&x, 1e-3);
            assert!(r.v.is_none());
            sq += (r.torque - 100.0).powi(2);
        }
        let std = (sq / n as f64).sqrt();
        assert!((std - 1.0).abs() < 0.03, "torque noise std {std}");
    }

    #[test]
    fn validation() {
        let bad = SensorParams {
            omega_window: 0,
            ..Default::default()
        };
        assert_eq!(Sensors::new(bad, 0).unwrap_err().field, "omega_window");
        let bad = SensorParams {
            v_noise_std: f64::NAN,
            ..Default::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "v_noise_std");
    }
}
