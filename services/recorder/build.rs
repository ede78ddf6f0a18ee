//! Stamps the build with its git revision for the MCAP `grip.run` metadata:
//! `GRIP_GIT_REV` from the environment if set (release builds from a
//! tarball, CI), else `git rev-parse HEAD` in the source tree, else
//! "unknown" (a tarball without `.git`, or no git installed). Never fails
//! the build.

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let dir = std::env::var("CARGO_MANIFEST_DIR").ok()?;
    let out = Command::new("git")
        .args(args)
        .current_dir(dir)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let s = String::from_utf8(out.stdout).ok()?.trim().to_owned();
    (!s.is_empty()).then_some(s)
}

fn main() {
    println!("cargo:rerun-if-env-changed=GRIP_GIT_REV");
    let rev = match std::env::var("GRIP_GIT_REV") {
        Ok(v) if !v.trim().is_empty() => v.trim().to_owned(),
        _ => {
            let rev = git(&["rev-parse", "HEAD"]);
            // Rebuild when HEAD moves: watch HEAD and the ref it points to
            // (only if they exist, so a tarball build is not re-run forever).
            if let Some(gd) = git(&["rev-parse", "--absolute-git-dir"]) {
                let head = std::path::Path::new(&gd).join("HEAD");
                if head.exists() {
                    println!("cargo:rerun-if-changed={}", head.display());
                }
                if let Some(r) = git(&["symbolic-ref", "-q", "HEAD"]) {
                    let p = std::path::Path::new(&gd).join(&r);
                    if p.exists() {
                        println!("cargo:rerun-if-changed={}", p.display());
                    }
                    let packed = std::path::Path::new(&gd).join("packed-refs");
                    if packed.exists() {
                        println!("cargo:rerun-if-changed={}", packed.display());
                    }
                }
            }
            rev.unwrap_or_else(|| "unknown".to_owned())
        }
    };
    println!("cargo:rustc-env=GRIP_GIT_REV={rev}");
}
