//! `grip drive`'s summary is `grip inspect`'s, by the same code: the road
//! catalogue line, the model arte ran, the histogram, the road timeline
//! and the inverter's episodes included. The services are stand-ins
//! (`common/fake_services.rs`) whose recorder writes a copy of the
//! reference drive as the drive's log.

mod common;
#[path = "common/fake_services.rs"]
mod fake_services;

use std::path::Path;

use fake_services::Fakes;

#[test]
fn the_drive_prints_what_inspect_prints() {
    let reference =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap");
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("drive.mcap");
    let f = Fakes::new();
    let (ok, drive_out, err) = f.drive_recording(
        &common::config_dir(),
        &reference,
        &["--out".as_ref(), out.as_os_str()],
    );
    // the stand-in recorder exits 3: the drive fails, after its summary
    assert!(!ok, "{drive_out}{err}");
    assert!(out.exists(), "{err}");
    let (ok, inspect_out, err2) = common::output(&["inspect".as_ref(), out.as_os_str()]);
    assert!(ok, "{inspect_out}{err2}");
    for want in [
        "road catalogue: roads.toml attached to the log",
        "model: models/default.model (sha256 4a6ce5407aaf, ",
        "loop wake-up latency histogram:",
        "road timeline (every 0.1 s; ",
        // the inverter's episodes (the reference drive's start-up fault)
        "\ninverter (its MotorStatus frames tcs-loop received and the E2E check accepted: 1675, ",
        "  whole log: fault 1 (0.001 s), derating 0, command timeout 1 (0.001 s), not ready 0\n",
    ] {
        assert!(
            drive_out.contains(want),
            "{want:?} not in\n{drive_out}\n{err}"
        );
    }
    assert_eq!(
        drive_out, inspect_out,
        "the drive's summary is not inspect's"
    );
}
