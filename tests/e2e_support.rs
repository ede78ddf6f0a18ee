//! Helpers of the end-to-end tests (included with `#[path]`, not a test
//! binary of its own): the service binaries, the configuration directory,
//! and how a service is started under grip-drive's supervisor.
//!
//! Binaries: `$GRIP_BIN_DIR` if set; otherwise the test runs
//! `cargo build -p grip -p grip-recorder -p grip-plant-sim -p grip-tcs-loop
//! -p grip-audio-acq -p grip-arte-svc` once per test process, with the
//! profile and target directory the test binary itself was built with, and
//! uses `target/<profile>/` (a no-op when they are up to date).
//! Configuration: the repository's `config/`, or `$GRIP_E2E_CONFIG_DIR`.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

pub const SERVICES: [&str; 5] = ["recorder", "plant-sim", "audio-acq", "arte", "tcs-loop"];

pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

pub fn config_dir() -> PathBuf {
    std::env::var_os("GRIP_E2E_CONFIG_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("config"))
}

/// The directory with `grip` and the five service binaries (built on first
/// use): grip-io's [`grip_io::binaries::bin_dir`], the rule `grip drive`
/// uses; unless `$GRIP_BIN_DIR` names it, the binaries are built there.
pub fn built_bin_dir() -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = grip_io::binaries::bin_dir().expect("locating the binaries");
        if dir.from_env {
            return dir.path;
        }
        // target/<profile>/
        let profile_dir = dir.path;
        let target_dir = profile_dir.parent().unwrap().to_path_buf();
        let profile = profile_dir
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.current_dir(workspace())
            .arg("build")
            .arg("--target-dir")
            .arg(&target_dir);
        match profile.as_str() {
            "debug" => {}
            "release" => {
                cmd.arg("--release");
            }
            p => {
                cmd.args(["--profile", p]);
            }
        }
        for p in [
            "grip",
            "grip-recorder",
            "grip-plant-sim",
            "grip-tcs-loop",
            "grip-audio-acq",
            "grip-arte-svc",
        ] {
            cmd.args(["-p", p]);
        }
        let out = cmd.output().expect("running cargo build");
        assert!(
            out.status.success(),
            "cargo build of the service binaries failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        profile_dir
    })
    .clone()
}

/// A unique `GRIP_INSTANCE`.
pub fn instance(tag: &str) -> String {
    let n = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    format!("e2e-{tag}-{}-{n:x}", std::process::id())
}

/// Reads `key=value` (a number) from a tracing line.
pub fn field(line: &str, key: &str) -> Option<f64> {
    let pat = format!(" {key}=");
    let i = line.find(&pat)? + pat.len();
    let rest = &line[i..];
    let end = rest.find(' ').unwrap_or(rest.len());
    rest[..end].parse().ok()
}

/// How the end-to-end tests start service `name` with `args`: the built
/// binary, its whole stderr kept (tests look for lines in it), under
/// grip-drive's supervisor (the one `grip drive` uses).
pub fn spec(name: &str, args: &[String]) -> grip_drive::ProcSpec {
    grip_drive::ProcSpec::new(name, &built_bin_dir().join(name), args)
        .output(grip_drive::Output::Capture)
}
