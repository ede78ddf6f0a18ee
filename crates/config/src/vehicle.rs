//! `config/vehicle.toml`: `[vehicle]` ([`VehicleParams`]) and `[sensors]`
//! ([`SensorParams`]). A missing field takes the documented default, an
//! unknown field is an error, every value is range-checked (plausible for a
//! real road vehicle: [`VehicleParams::validate`]).
//!
//! A `[vehicle]` that leaves fields out gets the paper's quarter car for
//! them (n_driven = 4, driven_load_share = 1, torque_max = 1000 N m, ...):
//! right for the paper's set-up, silently wrong for someone else's car.
//! Loading stays lenient (old logs carry partial files, and the defaults
//! are documented), but [`load_vehicle`] warns on stderr naming every field
//! that was defaulted and its value, so `grip sim`, `grip drive` and the
//! services (tcs-loop, plant-sim) that load the file show it;
//! [`parse_vehicle_file`] gives the list to callers that print their own
//! warnings. `r_ref` is not among them: left out, it is `r`.

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

/// A vehicle file as loaded: its parameters and which `[vehicle]` fields
/// it left to their defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleLoad {
    /// `[vehicle]`.
    pub vehicle: VehicleParams,
    /// `[sensors]` (the simulated vehicle's sensor model: plant-sim and
    /// `grip sim`; tcs-loop does not use it).
    pub sensors: SensorParams,
    /// The `[vehicle]` fields the file does not set, with the default each
    /// took ([`VehicleParams::defaultable_fields`] order).
    pub defaulted: Vec<(&'static str, f64)>,
}

impl VehicleLoad {
    /// The defaulted fields' names, and `name = value` of each.
    fn defaulted_lists(&self) -> (Vec<&'static str>, Vec<String>) {
        (
            self.defaulted.iter().map(|(n, _)| *n).collect(),
            self.defaulted
                .iter()
                .map(|(n, v)| format!("{n} = {v}"))
                .collect(),
        )
    }

    /// The warning for `file` when fields were defaulted, None otherwise:
    /// `warning: FILE: [vehicle] does not set n_driven, torque_max: they
    /// take the paper's quarter-car defaults (n_driven = 4, torque_max =
    /// 1000); ...`.
    pub fn defaults_warning(&self, file: &Path) -> Option<String> {
        if self.defaulted.is_empty() {
            return None;
        }
        let (names, values) = self.defaulted_lists();
        Some(format!(
            "warning: {}: [vehicle] does not set {}: {} the paper's quarter-car default{} ({}), which may not be your car's; set {} in the file (crates/physics/README.md, \"The vehicle file\")",
            file.display(),
            names.join(", "),
            if names.len() == 1 {
                "it takes"
            } else {
                "they take"
            },
            if names.len() == 1 { "" } else { "s" },
            values.join(", "),
            if names.len() == 1 { "it" } else { "each" },
        ))
    }
}

/// Parse and validate `text` (the contents of `file`), naming the
/// `[vehicle]` fields it left to their defaults. Prints nothing.
pub fn parse_vehicle_file(file: &Path, text: &str) -> Result<VehicleLoad, ConfigError> {
    let f: VehicleFile = parse_toml(file, text)?;
    f.vehicle
        .validate()
        .map_err(|e| ConfigError::invalid(file, "vehicle", e))?;
    f.sensors
        .validate()
        .map_err(|e| ConfigError::invalid(file, "sensors", e))?;
    // the text parsed as a VehicleFile above, so it is a table, and
    // `vehicle`, when there, a table
    let table: toml::Table = parse_toml(file, text)?;
    let set = table.get("vehicle").and_then(toml::Value::as_table);
    let defaulted = f
        .vehicle
        .defaultable_fields()
        .into_iter()
        .filter(|(name, _)| !set.is_some_and(|t| t.contains_key(*name)))
        .collect();
    Ok(VehicleLoad {
        vehicle: f.vehicle,
        sensors: f.sensors,
        defaulted,
    })
}

/// Parse and validate vehicle + sensor parameters from `text` (the contents
/// of `file`). Silent about defaulted fields: [`parse_vehicle_file`] names
/// them.
pub fn parse_vehicle(
    file: &Path,
    text: &str,
) -> Result<(VehicleParams, SensorParams), ConfigError> {
    let l = parse_vehicle_file(file, text)?;
    Ok((l.vehicle, l.sensors))
}

/// Load `config/vehicle.toml` (or any file of that shape); when the file
/// leaves `[vehicle]` fields to their defaults, says so on stderr
/// ([`VehicleLoad::defaults_warning`]).
pub fn load_vehicle(path: impl AsRef<Path>) -> Result<(VehicleParams, SensorParams), ConfigError> {
    let path = path.as_ref();
    let l = parse_vehicle_file(path, &read_file(path)?)?;
    if let Some(w) = l.defaults_warning(path) {
        crate::warn_once(&w);
    }
    Ok((l.vehicle, l.sensors))
}

/// Who loads a vehicle file, and so how strictly ([`load_vehicle_for`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VehicleUse {
    /// What drives a car or a rig (tcs-loop, plant-sim as services, `grip
    /// drive`): a `[vehicle]` field left out is an error
    /// ([`load_vehicle_complete`]).
    Drive,
    /// An offline reader (`grip replay` and `grip generate` through the
    /// services' library `load`, of logs whose attached vehicle files may
    /// predate a field): a field left out takes its default with a warning
    /// ([`load_vehicle`]).
    Offline,
}

/// [`load_vehicle_complete`] for [`VehicleUse::Drive`], [`load_vehicle`]
/// for [`VehicleUse::Offline`].
pub fn load_vehicle_for(
    path: impl AsRef<Path>,
    use_: VehicleUse,
) -> Result<(VehicleParams, SensorParams), ConfigError> {
    match use_ {
        VehicleUse::Drive => load_vehicle_complete(path),
        VehicleUse::Offline => load_vehicle(path),
    }
}

/// Load a vehicle file for what drives a car or a rig (tcs-loop,
/// plant-sim, `grip drive`): as [`load_vehicle`], but a `[vehicle]` field
/// the file leaves out is an error naming them all, not the paper's
/// quarter-car default with a warning (which an offline reader of an old
/// log or a `grip sim` study may take). A fail-safe trial (2026-12-07):
/// an empty vehicle file ran the live loop on a 1400 kg quarter car with
/// one warning line.
pub fn load_vehicle_complete(
    path: impl AsRef<Path>,
) -> Result<(VehicleParams, SensorParams), ConfigError> {
    let path = path.as_ref();
    let l = parse_vehicle_file(path, &read_file(path)?)?;
    if let Some(first) = l.defaulted.first() {
        let (names, values) = l.defaulted_lists();
        return Err(ConfigError::new(
            path,
            format!("vehicle.{}", first.0),
            format!(
                "{}: a drive (tcs-loop, plant-sim, grip drive) takes every [vehicle] field from the file, not the paper's quarter-car defaults ({}), which may not be your car's; set {} (crates/physics/README.md, \"The vehicle file\")",
                if names.len() == 1 {
                    "not set (the only [vehicle] field the file leaves out)".to_owned()
                } else {
                    format!("not set; also left out: {}", names[1..].join(", "))
                },
                values.join(", "),
                if names.len() == 1 { "it" } else { "each" }
            ),
        ));
    }
    Ok((l.vehicle, l.sensors))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drive refuses a vehicle file that leaves `[vehicle]` fields out,
    /// naming them; a complete one loads as [`load_vehicle`] loads it.
    #[test]
    fn a_drive_needs_every_vehicle_field() {
        let d = tempfile::tempdir().unwrap();
        let empty = d.path().join("empty.toml");
        std::fs::write(&empty, "").unwrap();
        let e = load_vehicle_complete(&empty).unwrap_err().to_string();
        assert!(
            e.contains("empty.toml: field `vehicle.mass`: not set; also left out: n_driven, j_w"),
            "{e}"
        );
        assert!(e.contains("mic_lead_m = 0"), "{e}");
        let full = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/vehicles/front-mic.toml"
        ))
        .unwrap();
        let one_out = d.path().join("one-out.toml");
        std::fs::write(&one_out, full.replace("tau_m = 0.05\n", "")).unwrap();
        let e = load_vehicle_complete(&one_out).unwrap_err().to_string();
        assert!(
            e.contains(
                "field `vehicle.tau_m`: not set (the only [vehicle] field the file leaves out)"
            ),
            "{e}"
        );
        let ok = d.path().join("full.toml");
        std::fs::write(&ok, &full).unwrap();
        assert_eq!(
            load_vehicle_complete(&ok).unwrap(),
            load_vehicle(&ok).unwrap()
        );
    }

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
        assert!(
            e.to_string().starts_with(
                "config/vehicle.toml: field `vehicle.mass`: -5 kg is outside [20, 300000] kg"
            ),
            "{e}"
        );
    }

    /// The review's `r = 334.0` (millimetres typed as metres) was accepted
    /// and the drive "worked" with a snow limit of 287 983 N m; the error
    /// names the file, the field, the value, the range and the unit.
    #[test]
    fn a_radius_in_millimetres_is_refused_naming_file_field_range_and_unit() {
        let e = parse_vehicle(Path::new("my-car.toml"), "[vehicle]\nr = 334.0\n").unwrap_err();
        let s = e.to_string();
        for says in [
            "my-car.toml: field `vehicle.r`: ",
            "334 m is outside [0.1, 1] m",
            "334 mm is 0.334 m",
        ] {
            assert!(s.contains(says), "{says}: {s}");
        }
        for (field, text) in [
            ("vehicle.tau_m", "tau_m = 50"),
            ("vehicle.j_w", "j_w = 600"),
            ("vehicle.v_eps", "v_eps = 100"),
            ("vehicle.c_rr", "c_rr = 0.9"),
            ("vehicle.n_driven", "n_driven = 2.5"),
            ("vehicle.r_ref", "r_ref = 291.2"),
        ] {
            let e = parse(&format!("[vehicle]\n{text}\n")).unwrap_err();
            assert_eq!(e.field, field, "{e}");
        }
    }

    #[test]
    fn r_ref_is_optional_and_r_when_left_out() {
        let (v, _) = parse("[vehicle]\nr = 0.3\n").unwrap();
        assert_eq!(v.r_ref, None);
        assert_eq!(v.ref_radius(), 0.3);
        let (v, _) = parse("[vehicle]\nr = 0.3\nr_ref = 0.288\n").unwrap();
        assert_eq!(v.r_ref, Some(0.288));
        assert_eq!(v.ref_radius(), 0.288);
        assert_eq!(v.r, 0.3);
    }

    /// The shipped files set every field: no warning. A partial file (an
    /// old log's attachment, a user's first try) loads, with the defaulted
    /// fields named with their values.
    #[test]
    fn defaulted_fields_are_named() {
        let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        for f in [
            "vehicle.toml",
            "vehicles/front-mic.toml",
            "vehicles/rear-mic.toml",
        ] {
            let p = config.join(f);
            let l = parse_vehicle_file(&p, &std::fs::read_to_string(&p).unwrap()).unwrap();
            assert_eq!(l.defaulted, vec![], "{f}");
            assert_eq!(l.defaults_warning(&p), None, "{f}");
        }
        let file = Path::new("my-car.toml");
        let text = "[vehicle]\nmass = 1800.0\nj_w = 0.9\nr = 0.33\nm_wheel = 20.0\ntau_m = 0.02\nc_rr = 0.01\nrho = 1.2\nc_d_a = 0.6\nv_eps = 0.1\n";
        let l = parse_vehicle_file(file, text).unwrap();
        assert_eq!(
            l.defaulted,
            vec![
                ("n_driven", 4.0),
                ("torque_max", 1000.0),
                ("driven_load_share", 1.0),
                ("mic_lead_m", 0.0)
            ]
        );
        assert_eq!(
            l.defaults_warning(file).unwrap(),
            "warning: my-car.toml: [vehicle] does not set n_driven, torque_max, driven_load_share, mic_lead_m: they take the paper's quarter-car defaults (n_driven = 4, torque_max = 1000, driven_load_share = 1, mic_lead_m = 0), which may not be your car's; set each in the file (crates/physics/README.md, \"The vehicle file\")"
        );
        // one field: singular
        let all_but_one = "[vehicle]\nmass = 1400.0\nn_driven = 4.0\nj_w = 0.6\nr = 0.28\nm_wheel = 10.0\ntau_m = 0.05\nc_rr = 0.015\nrho = 1.2\nc_d_a = 0.7\nv_eps = 0.1\ndriven_load_share = 1.0\nmic_lead_m = 0.0\n";
        let w = parse_vehicle_file(file, all_but_one)
            .unwrap()
            .defaults_warning(file)
            .unwrap();
        assert!(
            w.contains("does not set torque_max: it takes the paper's quarter-car default (torque_max = 1000)"),
            "{w}"
        );
        // an old log's attachment (crates/drive, `vehicle_for`) still loads
        let (v, _) =
            parse_vehicle(Path::new("vehicle.toml (attached)"), "[vehicle]\nr = 0.3\n").unwrap();
        assert_eq!(v.r, 0.3);
        // no [vehicle] at all: every field named
        assert_eq!(parse_vehicle_file(file, "").unwrap().defaulted.len(), 13);
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
