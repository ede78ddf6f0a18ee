//! grip-config: TOML (and CSV) configuration into the pure crates' types, with
//! validation and one clear error per problem ([`ConfigError`]: file, field,
//! reason).
//!
//! - [`load_vehicle`]: `config/vehicle.toml` -> ([`VehicleParams`], [`SensorParams`]);
//!   [`parse_vehicle_file`] also names the `[vehicle]` fields left to their defaults
//! - [`load_roads`]: `config/roads.toml` (+ CSV tables relative to it) -> [`RoadCatalogue`]
//! - [`load_scenario`]: `config/scenarios/<name>.toml` -> [`Scenario`];
//!   [`load_scenario_for`] also checks it against where it runs ([`RunsOn`]:
//!   the vehicle's motor limit, the loop's cycle count)
//! - [`ConfigDir`]: finds the standard files under one directory.
//! - [`parse_toml`]: the helper every loader uses (also `controllers.rs`).
//!
//! [`VehicleParams`]: grip_physics::VehicleParams
//! [`SensorParams`]: grip_physics::SensorParams
//! [`RoadCatalogue`]: grip_physics::RoadCatalogue
//! [`Scenario`]: grip_physics::Scenario
#![warn(missing_docs)]

pub mod controllers;
pub mod dir;
pub mod error;
pub mod knowledge;
pub mod roads;
pub mod scenario;
pub mod vehicle;
pub mod warn;

pub use controllers::{load_controllers, parse_controllers};
pub use dir::ConfigDir;
pub use error::{ConfigError, line_of, parse_toml, read_file};
pub use knowledge::{load_knowledge, load_road_table, parse_knowledge};
pub use roads::{load_roads, parse_roads};
pub use scenario::{RunsOn, check_scenario, load_scenario, load_scenario_for, parse_scenario};
pub use vehicle::{
    VehicleLoad, VehicleUse, load_vehicle, load_vehicle_complete, load_vehicle_for, parse_vehicle,
    parse_vehicle_file,
};
pub use warn::{first_time, warn_once, warn_once_as};
