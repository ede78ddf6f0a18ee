//! Shared helpers for grip's end-to-end and HIL tests.
pub mod hil;
