//! Errors of grip-io say their reason in their message and do not also
//! return it as their source: a service prints the message alone, and
//! `{:#}` of an `anyhow::Error` (grip's `error:` line) prints the message
//! and every source, which said the reason twice ("x.mcap: No such file or
//! directory (os error 2): No such file or directory (os error 2)").

use grip_io::can::CanError;
use grip_io::mcaplog::{McapLog, McapLogError};
use grip_io::service::monitor::HelperError;

/// `e` as grip prints it: the message and its chain.
fn chain(e: impl std::error::Error + Send + Sync + 'static) -> String {
    format!("{:#}", anyhow::Error::from(e))
}

#[test]
fn a_missing_log_says_its_path_and_reason_once() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("missing.mcap");
    let e = McapLog::open(&p).unwrap_err();
    assert!(std::error::Error::source(&e).is_none());
    assert_eq!(
        chain(e),
        format!("{}: No such file or directory (os error 2)", p.display())
    );
}

#[test]
fn an_mcap_error_says_its_cause_once_and_in_its_message() {
    // the mcap crate's I/O error names no reason in its own message: the
    // message carries its cause
    let e = McapLogError::Mcap {
        path: "x.mcap".into(),
        error: mcap::McapError::Io(std::io::Error::other("No space left on device")),
    };
    let msg = e.to_string();
    assert!(msg.starts_with("x.mcap: MCAP error: I/O error"), "{msg}");
    assert!(msg.ends_with(": No space left on device"), "{msg}");
    assert_eq!(chain(e), msg);
}

#[test]
fn can_and_helper_errors_say_their_reason_once() {
    let e = CanError::Io {
        iface: "vcan0".into(),
        error: std::io::Error::other("Network is down"),
    };
    assert_eq!(chain(e), "CAN interface \"vcan0\": Network is down");
    let e = HelperError(std::io::Error::other("Resource temporarily unavailable"));
    assert_eq!(
        chain(e),
        "cannot start the helper thread: Resource temporarily unavailable"
    );
}
