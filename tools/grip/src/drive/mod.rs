//! The CLI's own parts of `grip drive` and `grip inspect`: CSV export and
//! plots of a drive log. The log reader, the summary, the service
//! supervisor and the drive's command lines are the `grip-drive` crate.
//!
//! - [`export`]: CSV; [`plot`]: PNGs; [`many`]: a directory of logs;
//!   [`json`]: `grip inspect --json`.

pub mod export;
pub mod json;
pub mod many;
pub mod plot;
