//! `config/vehicle.toml`: `[vehicle]` ([`VehicleParams`]) and `[sensors]`
//! ([`SensorParams`]). A missing field takes the documented default, an
//! unknown field is an error, every value is range-checked.

use std::path::Path;

use grip_physics::{SensorParams, VehicleParams};

use crate::error::{ConfigError, parse_toml, read_file};

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct VehicleFile {
    #[serde(default)]
    vehicle: VehicleParams,
    #[serde(default)]
    sensors: SensorParams,
}

/// Parse and validate vehicle + sensor parameters from `text` (the contents of `file`).
pub fn parse_vehicle(
    file: &Path,
    text: &str,
) -> Result<(VehicleParams, SensorParams), ConfigError> {
    let f: VehicleFile = parse_toml(file, text)?;
    f.vehicle
        .validate()
        .map_err(|e| ConfigError::invalid(file, "vehicle", e))?;
    f.sensors
        .validate()
        .map_err(|e| ConfigError::invalid(file, "sensors", e))?;
    Ok((f.vehicle, f.sensors))
}

/// Load `config/vehicle.toml` (or any file of that shape).
pub fn load_vehicle(path: impl AsRef<Path>) -> Result<(VehicleParams, SensorParams), ConfigError> {
    let path = path.as_ref();
    parse_vehicle(path, &read_file(path)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<(VehicleParams, SensorParams), ConfigError> {
        parse_vehicle(Path::new("config/vehicle.toml"), text)
    }

    #[test]
    fn the_shipped_profiles_load_and_differ_where_they_say() {
        let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let (quarter, _) = load_vehicle(config.join("vehicle.toml")).unwrap();
        let (front, fs) = load_vehicle(config.join("vehicles/front-mic.toml")).unwrap();
        let (rear, rs) = load_vehicle(config.join("vehicles/rear-mic.toml")).unwrap();
        assert_eq!(quarter.mic_lead_m, 0.0);
        assert_eq!(front.mic_lead_m, 2.77);
        // rear-mic is front-mic with the microphone at the driven wheel.
        assert_eq!(
            rear,
            VehicleParams {
                mic_lead_m: 0.0,
                ..front
            }
        );
        assert_eq!(rs, fs);
        assert_eq!(rear.n_driven, 2.0);
    }

    #[test]
    fn empty_file_gives_defaults() {
        assert_eq!(
            parse("").unwrap(),
            (VehicleParams::default(), SensorParams::default())
        );
    }

    #[test]
    fn negative_mass() {
        let e = parse("[vehicle]\nmass = -5.0\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "config/vehicle.toml: field `vehicle.mass`: must be > 0 (got -5)"
        );
    }

    #[test]
    fn nan_mass() {
        let e = parse("[vehicle]\nmass = nan\n").unwrap_err();
        assert_eq!(e.field, "vehicle.mass");
        assert!(e.reason.contains("NaN"), "{e}");
    }

    #[test]
    fn unknown_field() {
        let e = parse("[vehicle]\nmass = 1400.0\nmas = 3\n").unwrap_err();
        assert_eq!(e.field, "vehicle.mas", "{e}");
        assert!(e.reason.starts_with("line 3: unknown field `mas`"), "{e}");
        let e = parse("[vehicel]\n").unwrap_err();
        assert_eq!(e.field, "vehicel", "{e}");
    }

    #[test]
    fn wrong_type_and_sensor_range() {
        let e = parse("[sensors]\nv_available = 1\n").unwrap_err();
        assert_eq!(e.field, "sensors.v_available", "{e}");
        let e = parse("[sensors]\nomega_window = 0\n").unwrap_err();
        assert_eq!(e.field, "sensors.omega_window", "{e}");
        let e = parse("[sensors]\ndelay_samples = -1\n").unwrap_err();
        assert_eq!(e.field, "sensors.delay_samples", "{e}");
    }
}
