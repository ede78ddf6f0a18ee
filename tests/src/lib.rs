//! Shared helpers for grip's end-to-end and HIL tests.
#![warn(missing_docs)]
pub mod hil;
pub mod hil_drives;
pub mod wire_check;
