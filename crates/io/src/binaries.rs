//! Where grip's binaries are: the one rule `grip drive` and the workspace's
//! end-to-end and HIL tests use to find the five service binaries (and
//! `grip`).
//!
//! `$GRIP_BIN_DIR` if set and not empty; otherwise the folder of the running
//! executable, `target/<profile>/` for `grip` itself, and for a test binary
//! (in `target/<profile>/deps/`) the `target/<profile>/` above it; and for
//! the installed package's `/usr/bin/grip`, whose services are in
//! `/usr/lib/grip/bin` (`tools/package`), that folder: `PREFIX/lib/grip/bin`
//! beside an executable in `PREFIX/bin` when the services are there and not
//! beside it.

use std::path::{Path, PathBuf};

/// The environment variable that overrides [`bin_dir`].
pub const BIN_DIR_ENV: &str = "GRIP_BIN_DIR";

/// The folder of the binaries, and whether `$GRIP_BIN_DIR` named it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BinDir {
    /// The folder.
    pub path: PathBuf,
    /// `true`: from `$GRIP_BIN_DIR`; `false`: beside the running executable.
    pub from_env: bool,
}

/// The running executable cannot be located.
#[derive(Debug, thiserror::Error)]
pub enum BinDirError {
    /// The OS does not say where the running executable is.
    #[error("cannot locate the running executable: {0}")]
    CurrentExe(std::io::Error),
    /// The executable's path has no parent folder.
    #[error("the running executable {} has no parent folder", .0.display())]
    NoParent(PathBuf),
}

/// The folder holding grip's binaries (see the module doc).
pub fn bin_dir() -> Result<BinDir, BinDirError> {
    if let Some(d) = std::env::var_os(BIN_DIR_ENV).filter(|d| !d.is_empty()) {
        return Ok(BinDir {
            path: PathBuf::from(d),
            from_env: true,
        });
    }
    let exe = std::env::current_exe().map_err(BinDirError::CurrentExe)?;
    Ok(BinDir {
        path: packaged_or(beside_exe(&exe)?),
        from_env: false,
    })
}

/// A service binary, to tell where the services are.
const A_SERVICE: &str = "tcs-loop";

/// `beside` (the executable's folder), or for `PREFIX/bin` without the
/// services the package's `PREFIX/lib/grip/bin` when they are there.
fn packaged_or(beside: PathBuf) -> PathBuf {
    if beside.join(A_SERVICE).exists() || beside.file_name().is_none_or(|n| n != "bin") {
        return beside;
    }
    match beside.parent().map(|p| p.join("lib/grip/bin")) {
        Some(lib) if lib.join(A_SERVICE).exists() => lib,
        _ => beside,
    }
}

/// The folder of `exe`, or its parent when that folder is `deps` (a test
/// binary).
fn beside_exe(exe: &Path) -> Result<PathBuf, BinDirError> {
    let dir = exe
        .parent()
        .ok_or_else(|| BinDirError::NoParent(exe.to_owned()))?;
    if dir.file_name().is_some_and(|n| n == "deps") {
        dir.parent()
            .map(Path::to_path_buf)
            .ok_or_else(|| BinDirError::NoParent(dir.to_owned()))
    } else {
        Ok(dir.to_owned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The package's layout: /usr/bin/grip finds its services in
    /// /usr/lib/grip/bin; services beside the executable win, and a
    /// folder not named bin is kept.
    #[test]
    fn the_packages_grip_finds_its_services_in_lib_grip_bin() {
        let d = tempfile::tempdir().unwrap();
        let bin = d.path().join("usr/bin");
        let lib = d.path().join("usr/lib/grip/bin");
        std::fs::create_dir_all(&bin).unwrap();
        std::fs::create_dir_all(&lib).unwrap();
        assert_eq!(packaged_or(bin.clone()), bin, "no services anywhere");
        std::fs::write(lib.join(A_SERVICE), "").unwrap();
        assert_eq!(packaged_or(bin.clone()), lib);
        std::fs::write(bin.join(A_SERVICE), "").unwrap();
        assert_eq!(packaged_or(bin.clone()), bin, "beside the executable first");
        let release = d.path().join("target/release");
        std::fs::create_dir_all(&release).unwrap();
        assert_eq!(packaged_or(release.clone()), release);
    }

    #[test]
    fn binaries_and_test_binaries_map_to_the_profile_folder() {
        assert_eq!(
            beside_exe(Path::new("target/release/grip")).unwrap(),
            Path::new("target/release")
        );
        assert_eq!(
            beside_exe(Path::new("target/debug/deps/e2e_drive-0123")).unwrap(),
            Path::new("target/debug")
        );
        assert_eq!(beside_exe(Path::new("bin/grip")).unwrap(), Path::new("bin"));
        assert!(matches!(
            beside_exe(Path::new("")),
            Err(BinDirError::NoParent(_))
        ));
    }

    #[test]
    fn this_test_binary_resolves_to_its_profile_folder() {
        // Whatever GRIP_BIN_DIR says, the result is consistent with it.
        let d = bin_dir().unwrap();
        match std::env::var_os(BIN_DIR_ENV).filter(|v| !v.is_empty()) {
            Some(v) => assert_eq!((d.path, d.from_env), (PathBuf::from(v), true)),
            None => {
                assert!(!d.from_env);
                let exe = std::env::current_exe().unwrap();
                assert_eq!(Some(d.path.as_path()), exe.parent().and_then(Path::parent));
            }
        }
    }
}
