//! Shared by the CLI's integration tests: run the built `grip` on the
//! repository's configuration.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// `grip --config-dir <repo>/config`, quiet logging.
pub fn grip() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_grip"));
    c.arg("--config-dir").arg(config_dir());
    c.env("RUST_LOG", "warn");
    c
}

/// Run `grip --config-dir <repo>/config ARGS` (logging as configured):
/// whether it succeeded, its stdout and its stderr.
pub fn output(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    output_in(&config_dir(), args)
}

/// `grip inspect DIR --csv DIR/table.csv` on the repository's `config/`:
/// (success, stdout, stderr) and the CSV's path.
pub fn inspect_dir(dir: &Path) -> (bool, String, String, std::path::PathBuf) {
    let csv = dir.join("table.csv");
    let (ok, out, err) = output(&[
        "inspect".as_ref(),
        dir.as_os_str(),
        "--csv".as_ref(),
        csv.as_os_str(),
    ]);
    (ok, out, err, csv)
}

/// The same with `--config-dir DIR`.
pub fn output_in(dir: &Path, args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_grip"))
        .arg("--config-dir")
        .arg(dir)
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The repository's `config/`.
pub fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

/// `from` copied to `to` (files and folders, recursively; `to` created).
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let q = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &q);
        } else {
            std::fs::copy(&p, &q).unwrap();
        }
    }
}

/// Run `c`, require success, return its stdout.
pub fn run_ok(c: &mut Command) -> String {
    let out = c.output().expect("run grip");
    assert!(
        out.status.success(),
        "grip failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The repository's reference drive (`tests/data/reference-drive.mcap`).
pub fn reference_drive() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap")
}

/// `grip replay <reference drive> EXTRA`, with no `--config-dir` (the
/// replay's configuration is the log's): success, stdout, stderr.
pub fn replay_reference<S: AsRef<std::ffi::OsStr>>(extra: &[S]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_grip"))
        .arg("replay")
        .arg(reference_drive())
        .args(extra)
        .output()
        .expect("running grip replay");
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The Python of the tests that read logs with Python's `mcap` reader:
/// the virtual environment `tools/setup` makes (`tools/test` puts it first
/// on `PATH`), else `python3`.
pub fn python() -> PathBuf {
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/.venv-mcap/bin/python3");
    if venv.is_file() {
        venv
    } else {
        PathBuf::from("python3")
    }
}

/// Whether `text` names a temporary directory as `tempfile` makes them
/// (`<temp dir>/.tmpXXXXXX`, as `grip replay`'s copy of a drive's
/// configuration): not merely the temporary directory, which a checkout
/// under it (`git clone . /tmp/fresh`) puts in every path of the repository.
pub fn names_a_temporary_copy(text: &str) -> bool {
    text.contains(".tmp")
}
