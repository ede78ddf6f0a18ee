//! The MCAP drive-log reader (`grip_io::mcaplog::McapLog`: the damage scan
//! on opening, the message stream with the JSON decoding of every grip
//! payload, metadata and attachments), what `grip inspect`, `grip drive`'s
//! summary and the tests read every log with.
//!
//! Then the log as `grip inspect` and `grip drive` take it
//! (`grip_drive::DriveLog`) through the drive summary and its text
//! (`summarize`, `render`): a user's log with messages out of time order,
//! odd stamps or values that are no numbers must not panic them.
//!
//! Checked besides "no panic": every decoded message is counted in the
//! report, and reading is deterministic (a second pass gives the same).
#![no_main]

use std::path::Path;

use grip_drive::{DriveLog, LoadOptions};
use grip_io::mcaplog::McapLog;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let log = McapLog::from_bytes(data.to_vec(), "fuzz.mcap");
    let mut n = 0u64;
    if let Ok(rep) = log.for_each(|_| n += 1) {
        assert_eq!(
            rep.messages, n,
            "report counts differ from the messages delivered"
        );
        let (msgs, rep2) = log.messages().expect("a log read once reads again");
        assert_eq!(msgs.len() as u64, n);
        assert_eq!(rep, rep2);
    }
    let _ = log.metadata();
    let _ = log.attachments();
    if let Ok(d) = DriveLog::from_mcap(&log, Path::new("fuzz.mcap"), LoadOptions { audio: true }) {
        let repo = grip_fuzz::repo();
        let s = grip_drive::summarize(&d, &repo.vehicle, "fuzz", Some(&repo.roads));
        let _ = s.render();
    }
});
