//! The CLI's own parts of `grip drive` and `grip inspect`: CSV export and
//! plots of a drive log. The log reader, the summary, the service
//! supervisor and the drive's command lines are the `grip-drive` crate.
//!
//! - [`export`]: CSV; [`plot`]: PNGs; [`many`]: a directory of logs;
//!   [`json`]: `grip inspect --json`.
//! - [`rates`]: arte's model and the audio at one sample rate (the check
//!   `grip drive` makes before any service starts, `grip replay`'s model);
//!   [`own_model`]: `grip drive --model`'s configuration view.

pub mod export;
pub mod json;
pub mod many;
pub mod own_model;
pub mod plot;
pub mod rates;
