//! grip-physics: roads (mu-lambda curves and their catalogue), the
//! quarter-vehicle plant with motor lag and driving resistance, sensors with
//! quantisation, noise and delay, and scenarios. Pure: no I/O, no clock.
//!
//! See `README.md` in this crate ("Plant", "Roads") for the equations.
#![warn(missing_docs)]

pub mod plant;
pub mod road;
pub mod scenario;
pub mod sensors;
pub mod validate;
pub mod vehicle;

pub use plant::{Plant, PlantState};
pub use road::{FrictionModel, Road, RoadCatalogue};
pub use scenario::{Demand, Scenario, Segment, SegmentMode};
pub use sensors::{SensorParams, SensorReading, Sensors};
pub use validate::InvalidField;
pub use vehicle::VehicleParams;

/// Standard gravity, m/s^2.
pub const G: f64 = 9.81;
