//! The slip noise of the vehicle's sensors against what the road belief
//! assumes.
//!
//! The road belief ([`crate::fusion`]) compares the measured slip, through a
//! low-pass of `[fusion] tau_slip_s`, with every road's μ-λ curve blurred
//! by `[fusion] sigma_lambda`. That σ is the noise of the shipped sensors
//! (a 16-bit encoder differentiated at 1 kHz, 0.05 rad/s and 0.02 m/s of
//! noise: about 0.004 at 10 km/h after the filter). A coarser wheel speed
//! throws the filtered slip far up the curves, where only ice's flat curve
//! still fits a moderate μ̂: the belief settles on ice and the ARTE
//! variants hold the wheel at ice's torque cap on any road (measured with
//! the front-mic car and a 4096-count encoder over one sample: mean
//! acceleration 0.24-0.31 m/s² against their baselines' 0.85-1.07, 4.2
//! times `sigma_lambda`;
//! `crates/tcs/README.md`, "The sensors' slip noise").
//!
//! [`slip_noise`] puts a wheel rolling without slip through the vehicle
//! file's own sensor model ([`grip_physics::Sensors`]: the encoder, its
//! window, the noise, V's noise and resolution), the belief's slip
//! ([`crate::fusion::measured_slip`]) and its filter, and returns the
//! spread of the result (the true slip is 0). [`sensor_warning`] says when
//! that is more than [`NOISE_TOLERANCE`] times `sigma_lambda` at
//! [`REF_SPEED_MPS`], with the `omega_window` that would bring it within.
//! Start-up only; allocation is allowed.

use grip_physics::{PlantState, SensorParams, Sensors, VehicleParams};

use crate::FusionParams;
use crate::filters::LowPass;
use crate::fusion::measured_slip;

/// The speed the check is made at, m/s: 10 km/h, the launch speed of the
/// shipped scenarios, where `sigma_lambda` was set to the shipped sensors'
/// noise (the slip's noise falls as one over the speed).
pub const REF_SPEED_MPS: f64 = 10.0 / 3.6;

/// How far above `sigma_lambda` the sensors' slip noise may lie before the
/// check warns. The shipped vehicles lie at about 1.0; measured on the
/// front-mic car (`crates/tcs/README.md`, "The sensors' slip noise"): at
/// 1.35 times the ARTE variants drive as with the shipped sensors, at 2
/// and 3 times they give up 1 and 2-4 % more traction on random roads, at
/// 4 times the belief settles on ice.
pub const NOISE_TOLERANCE: f64 = 1.5;

/// Samples measured (after [`WARM_UP`]).
const SAMPLES: usize = 4000;
/// Samples first run to fill the encoder's window, the delay line and the
/// filter.
const WARM_UP: usize = 1200;
/// The noise generator's seed (the figure is the same at every start).
const SEED: u64 = 1;
/// The largest `omega_window` a warning suggests.
const MAX_SUGGESTED_WINDOW: u32 = 64;

/// The spread of the measured slip of a wheel rolling without slip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlipNoise {
    /// Standard deviation after the belief's low-pass (`tau_slip_s`).
    pub filtered: f64,
    /// Standard deviation of the raw slip (what the controllers' own slip
    /// thresholds see before their filters).
    pub raw: f64,
}

/// The slip noise of `sensors` on the wheel of `v` at `speed` (m/s), at the
/// loop's sample time `dt` (s), after a low-pass of `tau_slip_s` (s; 0: none).
/// `None` where the belief measures no slip (`v_available` false) or the
/// arguments or the sensor file cannot make a measurement.
pub fn slip_noise(
    v: &VehicleParams,
    sensors: &SensorParams,
    tau_slip_s: f64,
    dt: f64,
    speed: f64,
) -> Option<SlipNoise> {
    if !(sensors.v_available && dt.is_finite() && dt > 0.0 && speed.is_finite() && speed > 0.0) {
        return None;
    }
    let mut s = Sensors::new(*sensors, SEED).ok()?;
    let mut lp = (tau_slip_s > 0.0).then(|| LowPass::new(tau_slip_s, dt));
    let (mut raw, mut filtered) = (Moments::default(), Moments::default());
    for k in 0..WARM_UP + SAMPLES {
        // a speed that moves by ±2 % over the run, so that the encoder's
        // counts per sample do not repeat in a short cycle (at a constant
        // speed of a whole number of counts per sample its quantisation
        // would vanish)
        let ramp = k as f64 / (WARM_UP + SAMPLES) as f64;
        let st = PlantState::rolling(speed * (0.98 + 0.04 * ramp), v.r);
        let reading = s.sample(&st, dt);
        let (lambda, _) = measured_slip(v.r, v.v_eps, reading.omega, reading.v?);
        let f = match &mut lp {
            Some(l) => l.step(lambda),
            None => lambda,
        };
        if k >= WARM_UP {
            raw.add(lambda);
            filtered.add(f);
        }
    }
    Some(SlipNoise {
        filtered: filtered.std()?,
        raw: raw.std()?,
    })
}

/// Running mean and variance.
#[derive(Debug, Default)]
struct Moments {
    n: f64,
    sum: f64,
    sq: f64,
}

impl Moments {
    fn add(&mut self, x: f64) {
        self.n += 1.0;
        self.sum += x;
        self.sq += x * x;
    }

    fn std(&self) -> Option<f64> {
        let mean = self.sum / self.n;
        let var = (self.sq / self.n - mean * mean).max(0.0);
        var.sqrt().is_finite().then(|| var.sqrt())
    }
}

/// The start-up warning of the road belief against the vehicle's sensors:
/// `None` when their slip noise at [`REF_SPEED_MPS`] (after `tau_slip_s`) is
/// within [`NOISE_TOLERANCE`] times `fusion.sigma_lambda`, or when no slip
/// is measured; else one line naming both files, the noise and the sensor
/// fields it comes from, what it does to the belief, and what to set (the
/// smallest `sensors.omega_window` up to 64 that brings it within, where
/// one does). tcs-loop logs it for an ARTE variant, `grip sim` prints it
/// when it runs one, `grip analyze` shows the figures.
pub fn sensor_warning(
    v: &VehicleParams,
    sensors: &SensorParams,
    vehicle_file: &std::path::Path,
    fusion: &FusionParams,
    controllers_file: &std::path::Path,
    dt: f64,
) -> Option<String> {
    let noise = slip_noise(v, sensors, fusion.tau_slip_s, dt, REF_SPEED_MPS)?;
    let limit = NOISE_TOLERANCE * fusion.sigma_lambda;
    if noise.filtered <= limit {
        return None;
    }
    let window = (sensors.omega_window + 1..=MAX_SUGGESTED_WINDOW).find_map(|w| {
        let s = SensorParams {
            omega_window: w,
            ..*sensors
        };
        let n = slip_noise(v, &s, fusion.tau_slip_s, dt, REF_SPEED_MPS)?;
        (n.filtered <= limit).then_some((w, n.filtered))
    });
    let fix = match window {
        Some((w, n)) => format!(
            "set sensors.omega_window = {w} (σ {n:.4}; {:.0} ms more delay on the wheel speed) if the wheel speed your ECU gets is no smoother, or describe the smoother one it has in [sensors]",
            0.5 * f64::from(w - sensors.omega_window) * dt * 1e3
        ),
        None => "describe a smoother wheel speed in [sensors] if your ECU has one (a finer encoder, a longer omega_window, less noise): no omega_window up to 64 brings the noise within".to_owned(),
    };
    Some(format!(
        "{}: [sensors] give a measured slip whose noise at 10 km/h is σ {:.4} after fusion.tau_slip_s = {} s ({:.4} raw: encoder_ppr {} over omega_window {}, omega_noise_std {} rad/s, v_noise_std {} m/s, v_lsb {} m/s), more than {NOISE_TOLERANCE} times the σ {} that {}'s fusion.sigma_lambda assumes: the road belief of the ARTE variants reads that noise as a tyre slipping on a slippery road, which costs them traction, and from about 4 times it can settle on ice, holding the wheel at ice's torque cap on any road; {fix}. Raising fusion.sigma_lambda instead keeps the belief off ice but leaves the slip tests of the road knowledge in the noise (`grip analyze --vehicle {}` shows the figures; crates/tcs/README.md, \"The sensors' slip noise\")",
        vehicle_file.display(),
        noise.filtered,
        fusion.tau_slip_s,
        noise.raw,
        sensors.encoder_ppr,
        sensors.omega_window,
        sensors.omega_noise_std,
        sensors.v_noise_std,
        sensors.v_lsb,
        fusion.sigma_lambda,
        controllers_file.display(),
        vehicle_file.display(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped() -> (VehicleParams, SensorParams) {
        (VehicleParams::default(), SensorParams::default())
    }

    #[test]
    fn the_shipped_sensors_give_about_the_belief_s_sigma_at_10_km_h() {
        let (v, s) = shipped();
        let f = FusionParams::default();
        let n = slip_noise(&v, &s, f.tau_slip_s, 1e-3, REF_SPEED_MPS).unwrap();
        // the value `sigma_lambda` was set to (controllers.toml's comment):
        // about 0.004 after the 2 ms filter, 0.009-0.01 raw
        assert!(
            (0.003..0.005).contains(&n.filtered),
            "filtered {}",
            n.filtered
        );
        assert!((0.007..0.012).contains(&n.raw), "raw {}", n.raw);
        assert_eq!(
            sensor_warning(&v, &s, "v.toml".as_ref(), &f, "c.toml".as_ref(), 1e-3),
            None
        );
    }

    #[test]
    fn the_noise_falls_with_speed_and_with_a_longer_window() {
        let (v, s) = shipped();
        let coarse = SensorParams {
            encoder_ppr: 4096,
            ..s
        };
        let at = |s: &SensorParams, speed| slip_noise(&v, s, 0.002, 1e-3, speed).unwrap().filtered;
        assert!(at(&coarse, 2.0 * REF_SPEED_MPS) < 0.6 * at(&coarse, REF_SPEED_MPS));
        let wide = SensorParams {
            omega_window: 4,
            ..coarse
        };
        assert!(at(&wide, REF_SPEED_MPS) < 0.5 * at(&coarse, REF_SPEED_MPS));
        // and no measured slip without V
        let no_v = SensorParams {
            v_available: false,
            ..s
        };
        assert_eq!(slip_noise(&v, &no_v, 0.002, 1e-3, REF_SPEED_MPS), None);
    }

    #[test]
    fn a_coarse_encoder_is_named_with_the_window_that_fixes_it() {
        let (v, s) = shipped();
        let coarse = SensorParams {
            encoder_ppr: 4096,
            ..s
        };
        let f = FusionParams::default();
        let w = sensor_warning(
            &v,
            &coarse,
            "my-car.toml".as_ref(),
            &f,
            "controllers.toml".as_ref(),
            1e-3,
        )
        .expect("a 4096-count encoder over 1 ms is far noisier than sigma_lambda");
        for needle in [
            "my-car.toml: [sensors]",
            "encoder_ppr 4096 over omega_window 1",
            "controllers.toml's fusion.sigma_lambda",
            "can settle on ice",
            "set sensors.omega_window = ",
        ] {
            assert!(w.contains(needle), "{needle:?} not in {w}");
        }
        // the window it names does bring the noise within the tolerance
        let named: u32 = w
            .split("set sensors.omega_window = ")
            .nth(1)
            .and_then(|t| t.split(' ').next())
            .and_then(|t| t.parse().ok())
            .unwrap();
        let fixed = SensorParams {
            omega_window: named,
            ..coarse
        };
        assert_eq!(
            sensor_warning(
                &v,
                &fixed,
                "my-car.toml".as_ref(),
                &f,
                "c.toml".as_ref(),
                1e-3
            ),
            None
        );
        let before = SensorParams {
            omega_window: named - 1,
            ..coarse
        };
        assert!(
            sensor_warning(
                &v,
                &before,
                "my-car.toml".as_ref(),
                &f,
                "c.toml".as_ref(),
                1e-3
            )
            .is_some(),
            "the smallest such window"
        );
    }
}
