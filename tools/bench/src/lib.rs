//! grip's ECU qualification bench (`tools/bench/run`, binary `grip-bench`):
//! the parts that can be checked without a machine's timing.
//!
//! - [`cyclictest`]: running Debian's `cyclictest` and reading its histogram;
//! - [`procfs`]: CPU time and resident memory of processes from `/proc`;
//! - [`parse`]: the output of the bench executables the bench reuses
//!   (the audio-block IPC bench, criterion's report);
//! - [`verdict`]: the rules that turn the measurements into PASS/FAIL lines;
//! - [`report`]: the tables, JSON and CSV.
//!
//! `tools/bench/README.md` describes the measurements and the rules.

pub mod cyclictest;
pub mod parse;
pub mod procfs;
pub mod report;
pub mod verdict;
