//! grip-physics: roads (mu-lambda curves and their catalogue), the
//! quarter-vehicle plant with motor lag and driving resistance, sensors with
//! quantisation, noise and delay, and scenarios. Pure: no I/O, no clock.
//!
//! See `../../README.md` and MODELS.md §1-§2 for the equations.

pub mod vehicle;

pub use vehicle::VehicleParams;

/// Standard gravity, m/s^2.
pub const G: f64 = 9.81;
