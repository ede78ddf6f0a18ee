//! The CAN log's alive counters are read where the bus's DBC puts them:
//! with `tests/data/own-bus.dbc` installed (as the recorder's start-up does
//! from `can.toml`), WheelSpeeds' counter is in bits 0-3 of byte 0, and a
//! gap-free stream of its frames counts no gap (read at bits 8-11, as
//! before, its speed bits made ~ every frame a "gap"). Its own process:
//! the protocol is per process.

use grip_io::can::protocol::{MsgKind, Protocol, WheelSpeeds, encode_in, install};
use grip_recorder::CanCounterTracker;

#[test]
fn counters_follow_the_installed_dbc() {
    let (path, names) = (
        grip_testkit::own_bus::dbc_path(),
        grip_testkit::own_bus::names(),
    );
    let p = install(Protocol::load_dbc(&path, &names).unwrap()).unwrap();
    let spec = p.spec(MsgKind::WheelSpeeds);
    let mut t = CanCounterTracker::default();
    for k in 0..200u64 {
        let w = WheelSpeeds {
            driven_valid: true,
            ref_valid: true,
            omega_driven: 20.0 + k as f64 * 0.37,
            omega_ref: 20.0,
        };
        t.push(&encode_in(spec, &w, (k % 16) as u8, k));
    }
    assert_eq!((t.gaps, t.repeats), (0, 0));
    // one frame left out: one gap
    let w = WheelSpeeds::default();
    t.push(&encode_in(spec, &w, 201 % 16, 201));
    assert_eq!(t.gaps, 1);
}
