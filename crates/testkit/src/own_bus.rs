//! `tests/data/own-bus.dbc`, the test bus whose DBC is not grip's (other
//! ids and names, Motorola, rpm/km/h/g): its path and the `[dbc_names]`
//! a `can.toml` gives it, in one place for every test and bench that loads
//! it.

use std::collections::BTreeMap;
use std::path::PathBuf;

/// The DBC file.
pub fn dbc_path() -> PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/own-bus.dbc")
}

/// grip's names mapped to the ones `own-bus.dbc` gives them.
pub fn names() -> BTreeMap<String, String> {
    [
        ("TorqueCommand", "MCU_TrqCmd"),
        ("TorqueCommand.TorqueRequest", "TrqReq"),
        ("DriverDemand", "VCU_Demand"),
        ("DriverDemand.TorqueDemand", "TrqDmd"),
    ]
    .into_iter()
    .map(|(a, b)| (a.to_owned(), b.to_owned()))
    .collect()
}
