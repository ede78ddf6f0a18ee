//! `tools/apt-install` (every system package grip's scripts install goes
//! through it) adds missing packages and never removes, upgrades or
//! downgrades one the machine has.
//!
//! The machine's own apt is not touched: each test builds a private apt root
//! in a temporary directory (a dpkg status file, a flat `file:` repository,
//! package lists, `APT_CONFIG` pointing apt at them) whose packages have the
//! shape of the case that once went wrong on a fresh machine: a newer
//! `qemu-utils` installed that breaks the older `qemu-system-common` which
//! `qemu-system-x86` needs, so apt's plan for `qemu-system-x86` removed
//! `qemu-utils`. The script runs with `--dry-run` (it installs nothing
//! either way; the refusal is decided before any install).

use std::path::{Path, PathBuf};
use std::process::Command;

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/apt-install")
}

const STATUS: &str = "\
Package: util-a
Status: install ok installed
Priority: optional
Section: misc
Maintainer: grip tests <grip@localhost>
Architecture: amd64
Version: 1:10.0-1
Breaks: sys-common (<< 1:10)
Description: an installed newer utility (like a backported qemu-utils)

Package: libz
Status: install ok installed
Priority: optional
Section: misc
Maintainer: grip tests <grip@localhost>
Architecture: amd64
Version: 1.0
Description: an installed library

";

const PACKAGES: &str = "\
Package: sys-x
Version: 1:7.2-1
Architecture: amd64
Depends: sys-common (= 1:7.2-1), libnew
Filename: sys-x.deb
Size: 1
Description: an emulator (like qemu-system-x86)

Package: sys-common
Version: 1:7.2-1
Architecture: amd64
Filename: sys-common.deb
Size: 1
Description: its common files (like qemu-system-common)

Package: libnew
Version: 1.0
Architecture: amd64
Filename: libnew.deb
Size: 1
Description: a library nobody has yet

Package: wants-newer-libz
Version: 1.0
Architecture: amd64
Depends: libz (>= 2)
Filename: wants-newer-libz.deb
Size: 1
Description: needs a newer libz than the installed one

Package: libz
Version: 2.0
Architecture: amd64
Filename: libz.deb
Size: 1
Description: the newer libz
";

struct AptRoot {
    dir: tempfile::TempDir,
}

/// Runs `cmd` (a tool from `package`) and asserts that it succeeded.
fn succeeds(cmd: &mut Command, package: &str) {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{package} cannot be run: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Builds `NAME.deb` (package NAME, VERSION, Depends DEPENDS) holding one
/// file `path` in `repo`; returns its "Size:" and "SHA256:" lines.
fn build_deb(repo: &Path, name: &str, version: &str, depends: &str, path: &str) -> String {
    let tree = repo.join(format!("{name}.tree"));
    std::fs::create_dir_all(tree.join("DEBIAN")).unwrap();
    let depends = if depends.is_empty() {
        String::new()
    } else {
        format!("Depends: {depends}\n")
    };
    std::fs::write(
        tree.join("DEBIAN/control"),
        format!(
            "Package: {name}\nVersion: {version}\nArchitecture: amd64\n{depends}\
             Maintainer: grip tests <grip@localhost>\nDescription: test package {name}\n"
        ),
    )
    .unwrap();
    let file = tree.join(path.trim_start_matches('/'));
    std::fs::create_dir_all(file.parent().unwrap()).unwrap();
    std::fs::write(&file, format!("{name} {version}\n")).unwrap();
    let deb = repo.join(format!("{name}.deb"));
    succeeds(
        Command::new("dpkg-deb")
            .args(["--root-owner-group", "--build"])
            .arg(&tree)
            .arg(&deb),
        "dpkg-deb (Debian: dpkg)",
    );
    std::fs::remove_dir_all(&tree).unwrap();
    let sum = Command::new("sha256sum").arg(&deb).output().unwrap();
    let sum = String::from_utf8_lossy(&sum.stdout);
    let size = std::fs::metadata(&deb).unwrap().len();
    format!("Size: {size}\nSHA256: {}\n", sum.split(' ').next().unwrap())
}

impl AptRoot {
    fn new() -> Self {
        Self::with_debs(false)
    }

    /// With `debs`, the repository holds real packages for `sys-x`,
    /// `sys-common` and `libnew` (one file each), so that they can be
    /// downloaded and unpacked.
    fn with_debs(debs: bool) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for sub in [
            "lists/partial",
            "cache/archives/partial",
            "repo",
            "parts",
            "prefs",
        ] {
            std::fs::create_dir_all(d.join(sub)).unwrap();
        }
        std::fs::write(d.join("status"), STATUS).unwrap();
        let mut packages = PACKAGES.to_string();
        if debs {
            for (name, version, depends, path) in [
                (
                    "sys-x",
                    "1:7.2-1",
                    "sys-common (= 1:7.2-1), libnew",
                    "/usr/bin/sys-x",
                ),
                ("sys-common", "1:7.2-1", "", "/usr/share/sys-common/data"),
                ("libnew", "1.0", "", "/usr/lib/x86_64-linux-gnu/libnew.so.1"),
            ] {
                let lines = build_deb(&d.join("repo"), name, version, depends, path);
                let stub = format!("Filename: {name}.deb\nSize: 1\n");
                assert!(packages.contains(&stub), "{name} not in PACKAGES");
                packages = packages.replace(&stub, &format!("Filename: {name}.deb\n{lines}"));
            }
        }
        std::fs::write(d.join("repo/Packages"), packages).unwrap();
        std::fs::write(
            d.join("sources.list"),
            format!("deb [trusted=yes] file:{}/repo ./\n", d.display()),
        )
        .unwrap();
        let user = String::from_utf8(Command::new("id").arg("-un").output().unwrap().stdout)
            .unwrap()
            .trim()
            .to_string();
        let conf = format!(
            "Dir::State::status \"{d}/status\";\n\
             Dir::State::lists \"{d}/lists\";\n\
             Dir::Cache \"{d}/cache\";\n\
             Dir::Etc::sourcelist \"{d}/sources.list\";\n\
             Dir::Etc::sourceparts \"{d}/parts\";\n\
             Dir::Etc::preferencesparts \"{d}/prefs\";\n\
             APT::Architecture \"amd64\";\n\
             APT::Architectures {{ \"amd64\"; }};\n\
             Debug::NoLocking \"true\";\n\
             APT::Sandbox::User \"{user}\";\n",
            d = d.display()
        );
        std::fs::write(d.join("apt.conf"), conf).unwrap();
        let root = AptRoot { dir };
        succeeds(
            Command::new("apt-get")
                .args(["update", "-q"])
                .env("APT_CONFIG", root.conf()),
            "apt-get (Debian: apt)",
        );
        root
    }

    fn conf(&self) -> PathBuf {
        self.dir.path().join("apt.conf")
    }

    fn status(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("status")).unwrap()
    }

    /// Runs `tools/apt-install --dry-run ARGS`: (exit code, stderr).
    fn run(&self, args: &[&str]) -> (i32, String) {
        let mut all = vec!["--dry-run"];
        all.extend_from_slice(args);
        self.run_for_real(&all)
    }

    /// Runs `tools/apt-install ARGS` (no `--dry-run` added: only for plans
    /// that never reach `apt-get install`, whose dpkg is the machine's).
    fn run_for_real(&self, args: &[&str]) -> (i32, String) {
        let out = Command::new(script())
            .args(args)
            .env("APT_CONFIG", self.conf())
            .output()
            .unwrap();
        (
            out.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }
}

#[test]
fn a_package_whose_install_would_remove_an_installed_one_is_refused_with_the_reason() {
    let root = AptRoot::new();
    let before = root.status();
    let (rc, err) = root.run(&["--for", "the HIL VM", "sys-x"]);
    assert_eq!(rc, 4, "expected a refusal (exit 4):\n{err}");
    for want in [
        "will not install sys-x (for the HIL VM)",
        "remove  util-a 1:10.0-1",
        // the relation that forces the removal, named
        "util-a (installed) Breaks: sys-common (<< 1:10)",
        // and the commands to resolve it
        "apt-cache policy",
        "apt-get install --no-install-recommends sys-x",
    ] {
        assert!(err.contains(want), "missing {want:?} in:\n{err}");
    }
    assert!(
        !err.contains("would install"),
        "refused, yet a plan was printed:\n{err}"
    );
    assert_eq!(root.status(), before, "the dpkg status changed");
}

#[test]
fn a_package_whose_install_would_upgrade_an_installed_one_is_refused() {
    let root = AptRoot::new();
    let (rc, err) = root.run(&["wants-newer-libz"]);
    assert_eq!(rc, 4, "expected a refusal (exit 4):\n{err}");
    for want in [
        "upgrade libz 1.0 -> 2.0",
        "wants-newer-libz (to install) Depends: libz (>= 2)",
    ] {
        assert!(err.contains(want), "missing {want:?} in:\n{err}");
    }
}

#[test]
fn a_missing_package_that_adds_only_new_packages_is_installed() {
    let root = AptRoot::new();
    let (rc, err) = root.run(&["libnew"]);
    assert_eq!(rc, 0, "{err}");
    assert!(err.contains("would install libnew"), "{err}");
    assert!(err.contains("no installed package changed"), "{err}");
}

#[test]
fn installed_packages_are_left_alone_whatever_their_version() {
    // libz 1.0 is installed and 2.0 is available: nothing to do, no upgrade
    let root = AptRoot::new();
    let (rc, err) = root.run(&["libz", "util-a"]);
    assert_eq!(rc, 0, "{err}");
    assert!(err.is_empty(), "expected silence, got:\n{err}");
}

#[test]
fn an_unknown_package_is_a_clear_error() {
    let root = AptRoot::new();
    let (rc, err) = root.run(&["no-such-package"]);
    assert_eq!(rc, 4, "{err}");
    assert!(
        err.contains("apt cannot install no-such-package") && err.contains("Unable to locate"),
        "{err}"
    );
}

#[test]
fn where_installing_would_remove_an_installed_package_the_plan_is_unpacked_instead() {
    let root = AptRoot::with_debs(true);
    let before = root.status();
    let into = root.dir.path().join("unpacked/sys-x");
    let into_s = into.to_str().unwrap();
    let (rc, err) = root.run_for_real(&["--for", "the HIL VM", "--unpack-into", into_s, "sys-x"]);
    assert_eq!(rc, 0, "expected the plan unpacked (exit 0):\n{err}");
    for want in [
        "installing sys-x (for the HIL VM): it would change packages this machine has (util-a)",
        "unpacked 3 package(s) into",
    ] {
        assert!(err.contains(want), "missing {want:?} in:\n{err}");
    }
    // every package of the plan, its file where the package puts it
    for (file, text) in [
        ("usr/bin/sys-x", "sys-x 1:7.2-1\n"),
        ("usr/share/sys-common/data", "sys-common 1:7.2-1\n"),
        ("usr/lib/x86_64-linux-gnu/libnew.so.1", "libnew 1.0\n"),
    ] {
        let got = std::fs::read_to_string(into.join(file))
            .unwrap_or_else(|e| panic!("{file} not unpacked: {e}\n{err}"));
        assert_eq!(got, text, "{file}");
    }
    let listed = std::fs::read_to_string(into.join(".unpacked")).unwrap();
    let mut listed: Vec<&str> = listed.lines().collect();
    listed.sort_unstable();
    assert_eq!(
        listed,
        ["libnew=1.0", "sys-common=1:7.2-1", "sys-x=1:7.2-1"]
    );
    assert!(!root.dir.path().join("unpacked/sys-x.part").exists());
    assert_eq!(root.status(), before, "the dpkg status changed");

    // --dry-run with --unpack-into says what it would unpack, and does not
    let again = root.dir.path().join("unpacked/dry");
    let (rc, err) = root.run(&["--unpack-into", again.to_str().unwrap(), "sys-x"]);
    assert_eq!(rc, 0, "{err}");
    assert!(err.contains("would unpack sys-common"), "{err}");
    assert!(!again.exists(), "a dry run unpacked");
}
