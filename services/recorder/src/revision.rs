//! What "the source tree" is for the build's git revision: the paths whose
//! files are compiled into grip's programs. `build.rs` reads this file
//! (`#[path]`) to watch these paths and to ask git whether they differ
//! from the commit; the recorder's test asks git the same question.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The source paths below the workspace root `root`, as paths relative to
/// it: the workspace's `Cargo.toml`, `Cargo.lock` and `.cargo`, and for
/// every package under `crates/`, `services/` and `tools/grip` its
/// `Cargo.toml`, `build.rs`, `src/` and `assets/` (what exists). Tests,
/// benches, docs and configuration are left out: they are not compiled
/// into the programs (a drive log vouches for its configuration by its
/// attached files' SHA-256).
pub fn source_paths(root: &Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = ["Cargo.toml", "Cargo.lock", ".cargo"]
        .iter()
        .map(PathBuf::from)
        .filter(|p| root.join(p).exists())
        .collect();
    let mut packages = vec![PathBuf::from("tools/grip")];
    for group in ["crates", "services"] {
        if let Ok(rd) = std::fs::read_dir(root.join(group)) {
            let mut dirs: Vec<PathBuf> = rd
                .flatten()
                .filter(|e| e.path().join("Cargo.toml").is_file())
                .map(|e| Path::new(group).join(e.file_name()))
                .collect();
            dirs.sort();
            packages.extend(dirs);
        }
    }
    for p in packages {
        for part in ["Cargo.toml", "build.rs", "src", "assets"] {
            let q = p.join(part);
            if root.join(&q).exists() {
                out.push(q);
            }
        }
    }
    out
}

/// Runs git in `dir`; its trimmed standard output if it succeeded.
pub fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .args(args)
        .current_dir(dir)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    Some(String::from_utf8(out.stdout).ok()?.trim().to_owned())
}

/// Whether any of `paths` (relative to the work tree `root`) differs from
/// the commit checked out: a change staged or not, or a new file git does
/// not ignore. `None` if git cannot tell.
pub fn dirty(root: &Path, paths: &[PathBuf]) -> Option<bool> {
    let mut args = vec!["status", "--porcelain", "--"];
    let specs: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    args.extend(specs.iter().map(String::as_str));
    git(root, &args).map(|s| !s.is_empty())
}

/// The revision string: the commit, with `-dirty` when the source paths
/// differ from it (as `git describe --dirty` marks it); the commit alone
/// when git cannot say whether they do.
pub fn revision(commit: &str, dirty: Option<bool>) -> String {
    match dirty {
        Some(true) => format!("{commit}-dirty"),
        _ => commit.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn git_ok(dir: &Path, args: &[&str]) {
        let st = Command::new("git")
            .args(["-c", "user.name=t", "-c", "user.email=t@example.invalid"])
            .args(args)
            .current_dir(dir)
            .output()
            .expect("git runs");
        assert!(st.status.success(), "git {args:?}: {st:?}");
    }

    fn write(root: &Path, rel: &str, text: &str) {
        let p = root.join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }

    #[test]
    fn the_mark_follows_the_source_files_only() {
        let d = tempfile::tempdir().unwrap();
        let root = d.path();
        git_ok(root, &["init", "-q"]);
        write(root, "Cargo.toml", "[workspace]\n");
        write(root, "crates/a/Cargo.toml", "[package]\n");
        write(root, "crates/a/src/lib.rs", "//! a\n");
        write(root, "crates/a/tests/t.rs", "//! t\n");
        write(root, "config/x.toml", "x = 1\n");
        write(root, "services/b/Cargo.toml", "[package]\n");
        write(root, "services/b/build.rs", "fn main() {}\n");
        write(root, "tools/grip/Cargo.toml", "[package]\n");
        write(root, "tools/grip/src/main.rs", "fn main() {}\n");
        git_ok(root, &["add", "-A"]);
        git_ok(root, &["commit", "-q", "-m", "c"]);

        let paths = source_paths(root);
        let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
        assert_eq!(
            names,
            [
                "Cargo.toml",
                "tools/grip/Cargo.toml",
                "tools/grip/src",
                "crates/a/Cargo.toml",
                "crates/a/src",
                "services/b/Cargo.toml",
                "services/b/build.rs",
            ]
        );
        assert_eq!(dirty(root, &paths), Some(false));
        // tests and configuration are not the programs' source
        write(root, "crates/a/tests/t.rs", "//! changed\n");
        write(root, "config/x.toml", "x = 2\n");
        assert_eq!(dirty(root, &paths), Some(false));
        // a changed source file, a new one, a changed build script
        write(root, "crates/a/src/lib.rs", "//! changed\n");
        assert_eq!(dirty(root, &paths), Some(true));
        git_ok(root, &["checkout", "-q", "--", "crates/a/src/lib.rs"]);
        assert_eq!(dirty(root, &paths), Some(false));
        write(root, "tools/grip/src/new.rs", "//! new\n");
        assert_eq!(dirty(root, &paths), Some(true));
        std::fs::remove_file(root.join("tools/grip/src/new.rs")).unwrap();
        write(root, "services/b/build.rs", "fn main() { }\n");
        assert_eq!(dirty(root, &paths), Some(true));
        // staged counts too
        git_ok(root, &["add", "services/b/build.rs"]);
        assert_eq!(dirty(root, &paths), Some(true));
        // not a git tree: git cannot tell
        let plain = tempfile::tempdir().unwrap();
        assert_eq!(dirty(plain.path(), &[PathBuf::from("src")]), None);

        assert_eq!(revision("abc", Some(true)), "abc-dirty");
        assert_eq!(revision("abc", Some(false)), "abc");
        assert_eq!(revision("abc", None), "abc");
    }

    /// The revision this build carries is what git says of the tree now:
    /// build.rs runs again whenever a source file changes, so a test run
    /// (which builds first) sees the same tree as the build did.
    #[test]
    fn the_build_carries_the_trees_revision() {
        let rev = crate::GIT_REV;
        if let Ok(v) = std::env::var("GRIP_GIT_REV")
            && !v.trim().is_empty()
        {
            assert_eq!(rev, v.trim());
            return;
        }
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        let expected = match git(here, &["rev-parse", "HEAD"]) {
            None => "unknown".to_owned(),
            Some(commit) => {
                let root = PathBuf::from(git(here, &["rev-parse", "--show-toplevel"]).unwrap());
                revision(&commit, dirty(&root, &source_paths(&root)))
            }
        };
        assert_eq!(rev, expected);
    }
}
