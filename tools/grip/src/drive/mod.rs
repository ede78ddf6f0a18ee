//! The CLI's own parts of `grip drive` and `grip inspect`: CSV export and
//! plots of a drive log. The log reader, the summary, the service
//! supervisor and the drive's command lines are the `grip-drive` crate.
//!
//! - [`export`]: CSV; [`plot`]: PNGs; [`many`]: a directory of logs;
//!   [`json`]: `grip inspect --json`.
//! - [`rates`]: arte's model and the audio at one sample rate (the check
//!   `grip drive` makes before any service starts, `grip replay`'s model);
//!   [`own_model`]: `grip drive --model`'s configuration view.
//! - [`load_log`]: a drive log read with a spinner when it is large.

pub mod export;
pub mod json;
pub mod many;
pub mod own_model;
pub mod plot;
pub mod rates;

use std::path::Path;
use std::time::Duration;

use grip_drive::{DriveLog, LoadOptions, LogError};

/// Logs at least this large get a spinner while they are read, bytes.
/// Reading took about 16 s for a 20-minute drive's 495 MB log in a
/// release build (2-core AMD EPYC VM, 2026-12-05, before the bus log;
/// about 0.9 GB resident):
/// a recorder part of `max_file_mib` 1024 takes about half a minute.
pub const SPINNER_FROM_BYTES: u64 = 64 << 20;

/// [`DriveLog::load_with`], with a spinner on stderr (elapsed time, the
/// file's size) while a log of [`SPINNER_FROM_BYTES`] or more is read;
/// nothing is drawn when stderr is not a terminal.
pub fn load_log(path: &Path, opts: LoadOptions) -> Result<DriveLog, LogError> {
    let size = std::fs::metadata(path).map_or(0, |m| m.len());
    if size < SPINNER_FROM_BYTES {
        return DriveLog::load_with(path, opts);
    }
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {msg} {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    bar.set_message(format!(
        "reading {} ({} MB)",
        path.display(),
        size / 1_000_000
    ));
    bar.enable_steady_tick(Duration::from_millis(200));
    let log = DriveLog::load_with(path, opts);
    bar.finish_and_clear();
    log
}
