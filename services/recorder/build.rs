//! Stamps the build with its git revision for the MCAP `grip.run` metadata:
//! `GRIP_GIT_REV` from the environment if set (release builds from a
//! tarball, CI), else `git rev-parse HEAD` of the source tree, with
//! `-dirty` appended when grip's source files (`src/revision.rs`) differ
//! from that commit, else "unknown" (a tarball without `.git`, or no git
//! installed). Never fails the build.
//!
//! It runs again when HEAD moves and when any of those source files
//! changes, so the mark is that of the tree the programs were built from.

#[path = "src/revision.rs"]
mod revision;

use std::path::{Path, PathBuf};

fn main() {
    println!("cargo:rerun-if-env-changed=GRIP_GIT_REV");
    let rev = match std::env::var("GRIP_GIT_REV") {
        Ok(v) if !v.trim().is_empty() => v.trim().to_owned(),
        _ => from_git().unwrap_or_else(|| "unknown".to_owned()),
    };
    println!("cargo:rustc-env=GRIP_GIT_REV={rev}");
}

fn from_git() -> Option<String> {
    let here = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").ok()?);
    let rev = revision::git(&here, &["rev-parse", "HEAD"]).filter(|s| !s.is_empty());
    // Rebuild when HEAD moves: watch HEAD and the ref it points to (only
    // if they exist, so a tarball build is not re-run forever).
    if let Some(gd) = revision::git(&here, &["rev-parse", "--absolute-git-dir"]) {
        let watch = |p: &Path| {
            if p.exists() {
                println!("cargo:rerun-if-changed={}", p.display());
            }
        };
        let gd = Path::new(&gd);
        watch(&gd.join("HEAD"));
        if let Some(r) = revision::git(&here, &["symbolic-ref", "-q", "HEAD"]) {
            watch(&gd.join(&r));
            watch(&gd.join("packed-refs"));
        }
    }
    let rev = rev?;
    let Some(root) = revision::git(&here, &["rev-parse", "--show-toplevel"]).map(PathBuf::from)
    else {
        return Some(rev);
    };
    let paths = revision::source_paths(&root);
    for p in &paths {
        println!("cargo:rerun-if-changed={}", root.join(p).display());
    }
    Some(revision::revision(&rev, revision::dirty(&root, &paths)))
}
