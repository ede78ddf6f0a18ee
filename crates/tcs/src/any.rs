//! Static dispatch over the three controllers.

use crate::mfc::Mfc;
use crate::mtte::Mtte;
use crate::params::ControllersConfig;
use crate::slip_control::Src;
use crate::types::{ControlOutput, Controller, Measurement, RoadKnowledge};
use grip_physics::{InvalidField, VehicleParams};
use std::fmt;
use std::str::FromStr;

/// Which traction controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ControllerKind {
    /// Model following control (Hori).
    Mfc,
    /// Slip ratio control with the fuzzy optimal-slip estimator.
    Src,
    /// Maximum transmissible torque estimation (Yin, Oh, Hori).
    Mtte,
}

impl ControllerKind {
    /// All kinds, in the paper's order.
    pub const ALL: [ControllerKind; 3] = [
        ControllerKind::Mfc,
        ControllerKind::Src,
        ControllerKind::Mtte,
    ];

    /// Lower-case name: "mfc", "src", "mtte".
    pub fn as_str(&self) -> &'static str {
        match self {
            ControllerKind::Mfc => "mfc",
            ControllerKind::Src => "src",
            ControllerKind::Mtte => "mtte",
        }
    }
}

impl fmt::Display for ControllerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// An unknown controller name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown controller `{0}` (expected one of: mfc, src, mtte)")]
pub struct UnknownController(pub String);

impl FromStr for ControllerKind {
    type Err = UnknownController;
    /// Case-insensitive "mfc", "src" or "mtte".
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "mfc" => Ok(ControllerKind::Mfc),
            "src" => Ok(ControllerKind::Src),
            "mtte" => Ok(ControllerKind::Mtte),
            _ => Err(UnknownController(s.to_owned())),
        }
    }
}

/// One of the three controllers, dispatched statically.
#[derive(Debug, Clone)]
pub enum AnyController {
    /// MFC.
    Mfc(Mfc),
    /// SRC.
    Src(Src),
    /// MTTE.
    Mtte(Mtte),
}

impl AnyController {
    /// Build `kind` from the configuration for `vehicle` at sample time `dt`
    /// (s; normally `config.loop_.dt()`). Errors name the offending field
    /// (prefixed with the section, e.g. `mfc.tau_hpf`, `vehicle.mass`, `dt`).
    pub fn new(
        kind: ControllerKind,
        config: &ControllersConfig,
        vehicle: &VehicleParams,
        dt: f64,
    ) -> Result<Self, InvalidField> {
        vehicle.validate().map_err(|e| e.prefixed("vehicle"))?;
        config.arte.validate().map_err(|e| e.prefixed("arte"))?;
        crate::valid_dt(dt)?;
        Ok(match kind {
            ControllerKind::Mfc => {
                config.mfc.validate().map_err(|e| e.prefixed("mfc"))?;
                AnyController::Mfc(Mfc::new(config.mfc, config.arte, vehicle, dt)?)
            }
            ControllerKind::Src => {
                config.src.validate().map_err(|e| e.prefixed("src"))?;
                AnyController::Src(Src::new(config.src, config.arte, vehicle, dt)?)
            }
            ControllerKind::Mtte => {
                config.mtte.validate().map_err(|e| e.prefixed("mtte"))?;
                AnyController::Mtte(Mtte::new(config.mtte, config.arte, vehicle, dt)?)
            }
        })
    }

    /// Which controller this is.
    pub fn kind(&self) -> ControllerKind {
        match self {
            AnyController::Mfc(_) => ControllerKind::Mfc,
            AnyController::Src(_) => ControllerKind::Src,
            AnyController::Mtte(_) => ControllerKind::Mtte,
        }
    }
}

impl Controller for AnyController {
    #[inline]
    fn step(&mut self, m: &Measurement, road: Option<&RoadKnowledge>) -> ControlOutput {
        match self {
            AnyController::Mfc(c) => c.step(m, road),
            AnyController::Src(c) => c.step(m, road),
            AnyController::Mtte(c) => c.step(m, road),
        }
    }

    fn reset(&mut self) {
        match self {
            AnyController::Mfc(c) => c.reset(),
            AnyController::Src(c) => c.reset(),
            AnyController::Mtte(c) => c.reset(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for k in ControllerKind::ALL {
            assert_eq!(k.to_string().parse::<ControllerKind>().unwrap(), k);
        }
        assert_eq!(
            "MTTE".parse::<ControllerKind>().unwrap(),
            ControllerKind::Mtte
        );
        let e = "abs".parse::<ControllerKind>().unwrap_err();
        assert!(e.to_string().contains("abs"));
    }

    #[test]
    fn one_wheel_speed_that_is_no_number_latches_no_controller() {
        // A gripping wheel (rω 1 % above V) at 300 N m, one NaN wheel speed
        // at 0.2 s: 50 ms later every controller commands what it did
        // before it.
        let c = ControllersConfig::default();
        let v = VehicleParams::default();
        let dt = c.loop_.dt();
        for k in ControllerKind::ALL {
            let mut a = AnyController::new(k, &c, &v, dt).unwrap();
            let (mut speed, mut before) = (5.0, f64::NAN);
            for i in 0..400u32 {
                let omega = if i == 200 {
                    f64::NAN
                } else {
                    1.01 * speed / v.r
                };
                let m = Measurement {
                    t: f64::from(i) * dt,
                    omega,
                    v: Some(speed),
                    torque: 300.0,
                    demand: 300.0,
                };
                let cmd = a.step(&m, None).torque_cmd;
                if i == 199 {
                    before = cmd;
                }
                if i == 250 {
                    assert!(before > 250.0, "{k}: {before} N m on a gripping wheel");
                }
                if i >= 250 {
                    assert!(
                        cmd >= before - 1.0,
                        "{k} at {i}: {cmd} N m, {before} before"
                    );
                }
                speed += dt * 1.0;
            }
        }
    }

    #[test]
    fn builds_each_kind_and_rejects_bad_dt() {
        let c = ControllersConfig::default();
        let v = VehicleParams::default();
        for k in ControllerKind::ALL {
            let a = AnyController::new(k, &c, &v, c.loop_.dt()).unwrap();
            assert_eq!(a.kind(), k);
            assert_eq!(AnyController::new(k, &c, &v, 0.0).unwrap_err().field, "dt");
        }
        let mut bad = c;
        bad.mfc.k_mfc = f64::NAN;
        assert_eq!(
            AnyController::new(ControllerKind::Mfc, &bad, &v, 1e-3)
                .unwrap_err()
                .field,
            "mfc.k_mfc"
        );
        let bad_v = VehicleParams { mass: -1.0, ..v };
        assert_eq!(
            AnyController::new(ControllerKind::Src, &c, &bad_v, 1e-3)
                .unwrap_err()
                .field,
            "vehicle.mass"
        );
    }
}
