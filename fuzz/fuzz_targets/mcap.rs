//! The MCAP drive-log reader (`grip_io::mcaplog::McapLog`: the damage scan
//! on opening, the message stream with the JSON decoding of every grip
//! payload, metadata and attachments), what `grip inspect`, `grip drive`'s
//! summary and the tests read every log with.
//!
//! Checked besides "no panic": every decoded message is counted in the
//! report, and reading is deterministic (a second pass gives the same).
#![no_main]

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
});
