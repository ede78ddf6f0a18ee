//! Stand-ins for the five service binaries (`GRIP_BIN_DIR`), for tests of
//! what `grip drive` does before and as it starts a drive, without a real
//! drive: each records its command line and what its `--config-dir` gives
//! arte (arte-svc.toml, the files of `models/`) in a spy directory, then
//! exits 3, so the drive stops at the first service it starts (the
//! recorder). Include with `#[path = "common/fake_services.rs"] mod
//! fake_services;`.
#![allow(dead_code)]

use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The services' binaries, in `grip drive`'s start order.
pub const SERVICES: [&str; 5] = ["recorder", "plant-sim", "audio-acq", "arte", "tcs-loop"];

const SCRIPT: &str = r#"#!/bin/sh
name=$(basename "$0")
echo "$name $*" >> "$GRIP_TEST_SPY/started"
if [ "$1" = --config-dir ]; then
    mkdir -p "$GRIP_TEST_SPY/$name/models"
    echo "$2" > "$GRIP_TEST_SPY/$name/config-dir"
    cp "$2/arte-svc.toml" "$GRIP_TEST_SPY/$name/"
    cp "$2"/models/* "$GRIP_TEST_SPY/$name/models/"
fi
exit 3
"#;

/// A directory of fake service binaries and the spy directory they write.
pub struct Fakes {
    bin: tempfile::TempDir,
    spy: tempfile::TempDir,
}

impl Fakes {
    pub fn new() -> Self {
        let bin = tempfile::tempdir().unwrap();
        for s in SERVICES {
            let p = bin.path().join(s);
            std::fs::write(&p, SCRIPT).unwrap();
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
        }
        Self {
            bin,
            spy: tempfile::tempdir().unwrap(),
        }
    }

    /// `grip --config-dir CONFIG drive ARGS` with these binaries: success,
    /// stdout, stderr.
    pub fn drive(&self, config: &Path, args: &[&std::ffi::OsStr]) -> (bool, String, String) {
        self.run_drive(config, args, None)
    }

    /// `grip --config-dir CONFIG drive ARGS` with these binaries, and
    /// `GRIP_TEST_LOG` set to `log` when given.
    fn run_drive(
        &self,
        config: &Path,
        args: &[&std::ffi::OsStr],
        log: Option<&Path>,
    ) -> (bool, String, String) {
        let mut c = Command::new(env!("CARGO_BIN_EXE_grip"));
        c.arg("--config-dir")
            .arg(config)
            .arg("drive")
            .args(args)
            .env("GRIP_BIN_DIR", self.bin.path())
            .env("GRIP_TEST_SPY", self.spy.path())
            .env("RUST_LOG", "warn");
        if let Some(log) = log {
            c.env("GRIP_TEST_LOG", log);
        }
        let o = c.output().unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    }

    /// The command lines of the services started (`NAME ARGS...`), in order.
    pub fn started(&self) -> Vec<String> {
        std::fs::read_to_string(self.spy.path().join("started"))
            .map(|t| t.lines().map(str::to_owned).collect())
            .unwrap_or_default()
    }

    /// The `--config-dir` service `name` was given.
    pub fn config_dir(&self, name: &str) -> PathBuf {
        let t = std::fs::read_to_string(self.spy.path().join(name).join("config-dir")).unwrap();
        PathBuf::from(t.trim_end())
    }

    /// File `rel` (`arte-svc.toml`, `models/NAME`) as service `name` saw it
    /// in its `--config-dir`.
    pub fn seen(&self, name: &str, rel: &str) -> Option<Vec<u8>> {
        std::fs::read(self.spy.path().join(name).join(rel)).ok()
    }
}

/// A stand-in recorder that writes `log` (a copy) to its `--out` before it
/// exits 3: the drive fails at it and prints the summary of that log.
const RECORDER_COPYING: &str = r#"#!/bin/sh
echo "recorder $*" >> "$GRIP_TEST_SPY/started"
while [ $# -gt 0 ]; do
    if [ "$1" = --out ]; then cp "$GRIP_TEST_LOG" "$2"; fi
    shift
done
exit 3
"#;

impl Fakes {
    /// `grip --config-dir CONFIG drive ARGS` whose stand-in recorder writes
    /// a copy of `log` to its `--out`: success, stdout, stderr.
    pub fn drive_recording(
        &self,
        config: &Path,
        log: &Path,
        args: &[&std::ffi::OsStr],
    ) -> (bool, String, String) {
        let p = self.bin.path().join("recorder");
        std::fs::write(&p, RECORDER_COPYING).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
        self.run_drive(config, args, Some(log))
    }
}

impl Fakes {
    /// Service `name` the real binary (beside `grip`: `cargo build
    /// --workspace` first), the others stand-ins.
    pub fn real(&self, name: &str) {
        let real = Path::new(env!("CARGO_BIN_EXE_grip")).with_file_name(name);
        assert!(
            real.is_file(),
            "{}: build the workspace first",
            real.display()
        );
        let p = self.bin.path().join(name);
        std::fs::remove_file(&p).unwrap();
        std::os::unix::fs::symlink(&real, &p).unwrap();
    }
}
