//! A real-time step the configuration asks for and the machine cannot
//! apply is said in the service's systemd `STATUS=` line (what `systemctl
//! status` shows), not only in the journal's warning: audio-acq's READY
//! status ends `REAL TIME NOT APPLIED: CPU affinity (see the journal)`
//! when `[rt] cpus` names a CPU the machine does not have (1000).

use grip_testkit::svc::status_with_unapplicable_rt;

#[test]
fn real_time_not_applied_is_in_the_status_line() {
    let status = status_with_unapplicable_rt(
        env!("CARGO_BIN_EXE_audio-acq"),
        &["audio-acq.toml", "roads.toml"],
        "audio-acq.toml",
        &["--source", "synth"],
    );
    assert!(
        status.starts_with("STATUS=capturing: ")
            && status.ends_with(", REAL TIME NOT APPLIED: CPU affinity (see the journal)"),
        "{status}"
    );
}
