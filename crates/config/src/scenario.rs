//! `config/scenarios/<name>.toml`: one drive.
//!
//! ```toml
//! name = "paper"
//! description = "free text"
//! v0_kmh = 10.0              # initial speed, km/h (the wheel starts without slip)
//! segments_by = "time"       # "time": each segment has `duration` (s);
//!                            # "distance": each has `length` (m)
//! duration = 3.0             # run length, s; optional in time mode (default:
//!                            # sum of the segment durations), required by distance;
//!                            # a time segment or a demand change that begins
//!                            # at or after it is never driven: warned of
//!                            # (`scenario_warnings`); a demand that asks for
//!                            # torque only there is refused
//!
//! [demand]                   # driver torque demand, N m (>= 0)
//! kind = "constant"          # constant {torque} | ramp {from, to, start, duration}
//! torque = 300.0             # | stop_and_go {torque, on, off, rise}
//!                            # | steps {times, torques}
//! [[segment]]
//! road = "asphalt"           # a name from roads.toml
//! duration = 0.5             # or length = 20.0 in distance mode
//! grade_pct = 0.0            # optional, percent, positive uphill
//! ```

use std::path::Path;

use grip_physics::{Demand, RoadCatalogue, Scenario, Segment, SegmentMode, VehicleParams};

use crate::error::{ConfigError, parse_toml, read_file};

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SegmentSpec {
    road: String,
    duration: Option<f64>,
    length: Option<f64>,
    #[serde(default)]
    grade_pct: f64,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioFile {
    name: String,
    #[serde(default)]
    description: String,
    duration: Option<f64>,
    v0_kmh: f64,
    segments_by: SegmentMode,
    demand: Demand,
    #[serde(default)]
    segment: Vec<SegmentSpec>,
}

/// Parse a scenario from `text` (the contents of `file`), resolving road
/// names against `roads`.
pub fn parse_scenario(
    file: &Path,
    text: &str,
    roads: &RoadCatalogue,
) -> Result<Scenario, ConfigError> {
    let f: ScenarioFile = parse_toml(file, text)?;
    if f.segment.is_empty() {
        return Err(ConfigError::new(
            file,
            "segment",
            "the road list is empty: give at least one [[segment]]",
        ));
    }
    let (own, other) = match f.segments_by {
        SegmentMode::Time => ("duration", "length"),
        SegmentMode::Distance => ("length", "duration"),
    };
    let mut segments = Vec::with_capacity(f.segment.len());
    for (i, s) in f.segment.into_iter().enumerate() {
        let road = roads.index_of(&s.road).ok_or_else(|| {
            ConfigError::new(
                file,
                format!("segment[{i}].road"),
                format!("unknown road `{}` (known: {})", s.road, roads.names()),
            )
        })?;
        let (mine, theirs) = match f.segments_by {
            SegmentMode::Time => (s.duration, s.length),
            SegmentMode::Distance => (s.length, s.duration),
        };
        if theirs.is_some() {
            return Err(ConfigError::new(
                file,
                format!("segment[{i}].{other}"),
                format!(
                    "not allowed with segments_by = \"{}\" (use `{own}`)",
                    if own == "duration" {
                        "time"
                    } else {
                        "distance"
                    }
                ),
            ));
        }
        let span =
            mine.ok_or_else(|| ConfigError::new(file, format!("segment[{i}].{own}"), "missing"))?;
        segments.push(Segment {
            road_name: s.road,
            road,
            span,
            grade_pct: s.grade_pct,
        });
    }
    let duration = match (f.duration, f.segments_by) {
        (Some(d), _) => d,
        (None, SegmentMode::Time) => segments.iter().map(|s| s.span).sum(),
        (None, SegmentMode::Distance) => {
            return Err(ConfigError::new(
                file,
                "duration",
                "missing (required when segments_by = \"distance\")",
            ));
        }
    };
    let v0 = f.v0_kmh / 3.6;
    Scenario::new(
        f.name,
        f.description,
        duration,
        v0,
        f.segments_by,
        segments,
        f.demand,
        roads.len(),
    )
    .map_err(|mut e| {
        if e.field == "v0" {
            e = grip_physics::InvalidField::new(
                "v0_kmh",
                format!(
                    "must be in [0, {}] km/h (got {})",
                    grip_physics::scenario::V0_MAX_KMH,
                    f.v0_kmh
                ),
            );
        }
        ConfigError::invalid(file, "", e)
    })
}

/// Load a scenario file, resolving road names against `roads`; warns
/// (once per process) of what lies at or after its end
/// ([`scenario_warnings`]).
pub fn load_scenario(
    path: impl AsRef<Path>,
    roads: &RoadCatalogue,
) -> Result<Scenario, ConfigError> {
    let path = path.as_ref();
    let scenario = parse_scenario(path, &read_file(path)?, roads)?;
    warn_past_the_end(path, &scenario);
    Ok(scenario)
}

/// The warnings of `scenario` (read from `file`) about what it has at or
/// after its end, which its run never gets to
/// ([`Scenario::past_the_end`]): a time segment that begins at or after
/// `duration`, a change of the demand (a ramp's `start`, a stop-and-go's
/// first release `on`, a step's `times[i]`) at or after it. One line each,
/// `warning: FILE: field `F`: REASON`. A last segment that merely extends
/// past the end is normal and not warned of.
pub fn scenario_warnings(file: &Path, scenario: &Scenario) -> Vec<String> {
    scenario
        .past_the_end()
        .into_iter()
        .map(|n| format!("warning: {}: {n}", file.display()))
        .collect()
}

/// [`scenario_warnings`] on stderr, each once per process whatever the
/// path and scenario name it comes with: a command that checks the user's
/// file and then loads a renamed copy of it per log (`grip generate`,
/// each log's plant-sim) says it once, of the user's file.
fn warn_past_the_end(file: &Path, scenario: &Scenario) {
    for (note, line) in scenario
        .past_the_end()
        .into_iter()
        .zip(scenario_warnings(file, scenario))
    {
        crate::warn_once_as(&format!("scenario past its end: {note}"), &line);
    }
}

/// Where a scenario is to run: the vehicle that drives it (and its file,
/// named in the reason of a demand above its motor limit) and the period of
/// the loop that runs it (plant-sim's `rate_hz`, `grip sim`'s controller
/// loop).
#[derive(Debug, Clone, Copy)]
pub struct RunsOn<'a> {
    /// The vehicle.
    pub vehicle: &'a VehicleParams,
    /// The file it was read from.
    pub vehicle_file: &'a Path,
    /// The loop's period, s.
    pub dt: f64,
}

/// Check `scenario` (read from `file`) against where it is to run
/// ([`Scenario::check_for`]: no time segments under a microphone ahead of
/// the driven wheel, every demand within the vehicle's `torque_max`,
/// 1 ..= 1e9 loop cycles, torque asked for before the last cycle); gives
/// the cycle count, and warns (once per process) of what lies at or after
/// the scenario's end ([`scenario_warnings`]). The error names `file`, the
/// field as written there (`segments_by`, `demand.torque`, `duration`)
/// and, for a microphone lead or a demand above the motor limit, the
/// vehicle file ([`Scenario::involves_vehicle`]).
pub fn check_scenario(file: &Path, scenario: &Scenario, on: RunsOn) -> Result<usize, ConfigError> {
    let cycles = scenario.check_for(on.vehicle, on.dt).map_err(|e| {
        let limit = Scenario::involves_vehicle(&e);
        let mut e = ConfigError::invalid(file, "", e);
        if limit {
            e.reason
                .push_str(&format!(" (vehicle file {})", on.vehicle_file.display()));
        }
        e
    })?;
    warn_past_the_end(file, scenario);
    Ok(cycles)
}

/// [`load_scenario`], then [`check_scenario`] against where it is to run:
/// what every reader that runs a scenario loads it with.
pub fn load_scenario_for(
    path: impl AsRef<Path>,
    roads: &RoadCatalogue,
    on: RunsOn,
) -> Result<Scenario, ConfigError> {
    let path = path.as_ref();
    let scenario = load_scenario(path, roads)?;
    check_scenario(path, &scenario, on)?;
    Ok(scenario)
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_physics::Road;

    fn roads() -> RoadCatalogue {
        RoadCatalogue::new(vec![
            Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap(),
            Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap(),
        ])
        .unwrap()
    }

    fn parse(text: &str) -> Result<Scenario, ConfigError> {
        parse_scenario(Path::new("config/scenarios/t.toml"), text, &roads())
    }

    const HEAD: &str = "name = \"t\"\nv0_kmh = 10.0\nsegments_by = \"time\"\n[demand]\nkind = \"constant\"\ntorque = 300.0\n";

    #[test]
    fn good() {
        let s = parse(&format!("{HEAD}[[segment]]\nroad = \"asphalt\"\nduration = 0.5\n[[segment]]\nroad = \"snow\"\nduration = 1.0\ngrade_pct = 5.0\n")).unwrap();
        assert_eq!(s.duration, 1.5);
        assert!((s.v0 - 2.7778).abs() < 1e-4);
        assert_eq!(s.segments[1].road, 1);
        assert_eq!(s.road_at(0.7, 0.0), 1);
        assert_eq!(s.demand_at(1.0), 300.0);
    }

    #[test]
    fn empty_road_list() {
        let e = parse(HEAD).unwrap_err();
        assert_eq!(e.field, "segment");
        assert!(e.reason.contains("empty"));
    }

    #[test]
    fn unknown_road() {
        let e = parse(&format!(
            "{HEAD}[[segment]]\nroad = \"mud\"\nduration = 0.5\n"
        ))
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "config/scenarios/t.toml: field `segment[0].road`: unknown road `mud` (known: asphalt, snow)"
        );
    }

    #[test]
    fn mode_mismatch_and_bad_values() {
        let e = parse(&format!(
            "{HEAD}[[segment]]\nroad = \"snow\"\nlength = 5.0\n"
        ))
        .unwrap_err();
        assert_eq!(e.field, "segment[0].length", "{e}");
        let e = parse(&format!("{HEAD}[[segment]]\nroad = \"snow\"\n")).unwrap_err();
        assert_eq!(e.field, "segment[0].duration", "{e}");
        let e = parse(&format!(
            "{HEAD}[[segment]]\nroad = \"snow\"\nduration = nan\n"
        ))
        .unwrap_err();
        assert_eq!(e.field, "segment[0].duration", "{e}");
        let e = parse(&format!(
            "{HEAD}[[segment]]\nroad = \"snow\"\nduration = 1.0\nspeed = 3\n"
        ))
        .unwrap_err();
        assert_eq!(e.field, "segment[0].speed", "{e}");
        let bad_demand = "name = \"t\"\nv0_kmh = 10.0\nsegments_by = \"time\"\n[demand]\nkind = \"constant\"\ntorque = -300.0\n[[segment]]\nroad = \"snow\"\nduration = 1.0\n";
        assert_eq!(parse(bad_demand).unwrap_err().field, "demand.torque");
        let bad_v0 = bad_demand
            .replace("torque = -300.0", "torque = 300.0")
            .replace("v0_kmh = 10.0", "v0_kmh = -1.0");
        assert_eq!(parse(&bad_v0).unwrap_err().field, "v0_kmh");
    }

    #[test]
    fn checked_against_the_vehicle_and_the_loop() {
        let vehicle = VehicleParams::default();
        let on = RunsOn {
            vehicle: &vehicle,
            vehicle_file: Path::new("config/vehicle.toml"),
            dt: 1e-3,
        };
        let file = Path::new("config/scenarios/t.toml");
        let s = parse(&format!(
            "{HEAD}[[segment]]\nroad = \"snow\"\nduration = 1.5\n"
        ))
        .unwrap();
        assert_eq!(check_scenario(file, &s, on), Ok(1500));
        let big = parse(&format!(
            "{}[[segment]]\nroad = \"snow\"\nduration = 1.5\n",
            HEAD.replace("torque = 300.0", "torque = 1e300")
        ))
        .unwrap();
        assert_eq!(
            check_scenario(file, &big, on).unwrap_err().to_string(),
            "config/scenarios/t.toml: field `demand.torque`: 1e300 N m is above the motor limit, the vehicle's torque_max = 1000 N m (the plant would clamp the command there while the controllers and the command's metrics see the demand) (vehicle file config/vehicle.toml)"
        );
        let long = parse(&format!(
            "duration = 1e300\n{HEAD}[[segment]]\nroad = \"snow\"\nduration = 1.5\n"
        ))
        .unwrap();
        assert_eq!(
            check_scenario(file, &long, on).unwrap_err().to_string(),
            "config/scenarios/t.toml: field `duration`: 1e300 s gives 1e303 loop cycles at dt = 0.001 s (need 1 ..= 1e9)"
        );
    }

    /// The user's trial: an ice segment that begins exactly at the end of
    /// a 1 s run, said of the file, the segment (index and road) and the
    /// duration.
    #[test]
    fn a_time_segment_after_the_end_is_warned_of() {
        let s = parse(&format!(
            "duration = 1.0\n{HEAD}[[segment]]\nroad = \"asphalt\"\nduration = 0.5\n[[segment]]\nroad = \"snow\"\nduration = 0.5\n[[segment]]\nroad = \"snow\"\nduration = 2.0\n"
        ))
        .unwrap();
        assert_eq!(
            scenario_warnings(Path::new("s1.toml"), &s),
            [
                "warning: s1.toml: field `segment[2]`: road `snow` begins at 1 s, at or after the end of the run (duration = 1 s): it is never driven"
            ]
        );
        // "snow to the end": a last segment past the end is normal
        let s = parse(&format!(
            "duration = 1.0\n{HEAD}[[segment]]\nroad = \"asphalt\"\nduration = 0.5\n[[segment]]\nroad = \"snow\"\nduration = 2.0\n"
        ))
        .unwrap();
        assert!(scenario_warnings(Path::new("s1.toml"), &s).is_empty());
    }

    #[test]
    fn a_demand_change_after_the_end_is_warned_of() {
        let ramp = "name = \"x\"\nv0_kmh = 0\nsegments_by = \"time\"\n[demand]\nkind = \"ramp\"\nfrom = 100\nto = 300\nstart = 5\nduration = 1\n[[segment]]\nroad = \"asphalt\"\nduration = 1\n";
        let s = parse(ramp).unwrap();
        let w = scenario_warnings(Path::new("x.toml"), &s);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("warning: x.toml: field `demand.start`: the ramp from 100 to 300 N m")
                && w[0].contains("(duration = 1 s)"),
            "{w:?}"
        );
    }

    /// The user's trial (c): a ramp from 0 N m that starts after the end
    /// would run 0 N m throughout: refused, naming the file, the field and
    /// why.
    #[test]
    fn a_demand_that_begins_after_the_end_is_refused() {
        let text = "name=\"x\"\nv0_kmh=0\nsegments_by=\"time\"\n[demand]\nkind=\"ramp\"\nfrom=0\nto=300\nstart=5\nduration=1\n[[segment]]\nroad=\"asphalt\"\nduration=1\n";
        let s = parse(text).unwrap();
        assert!(
            scenario_warnings(Path::new("x.toml"), &s).is_empty(),
            "the error says it"
        );
        let vehicle = VehicleParams::default();
        let on = RunsOn {
            vehicle: &vehicle,
            vehicle_file: Path::new("config/vehicle.toml"),
            dt: 1e-3,
        };
        assert_eq!(
            check_scenario(Path::new("c.toml"), &s, on)
                .unwrap_err()
                .to_string(),
            "c.toml: field `demand.start`: the driver first asks for torque at 5 s, at or after the end of the run (duration = 1 s, last loop cycle at 0.999 s): the run would demand 0 N m throughout; start the demand earlier or lengthen `duration`"
        );
    }
}
