//! The Debian package's documentation (`tools/grip/Cargo.toml`,
//! `[package.metadata.deb] assets` installed under `/usr/share/doc/grip`):
//! every asset's source exists, and every relative link of a shipped
//! document, and every path ending in `.md` it names in backticks (from the
//! repository's root or from its own folder), is a file of the installed
//! tree. Before, the package shipped the services' READMEs but not the
//! crates' they send the reader to (can.toml's fields are
//! `crates/io/README.md`'s), and put two READMEs in folders other than the
//! repository's, so their relative links led nowhere on an ECU.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

/// Where the package puts its documentation.
const DOC: &str = "usr/share/doc/grip/";

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// `p` with `.` and `..` folded (`None` when it climbs out of its root).
fn normal(p: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::Normal(x) => out.push(x),
            _ => return None,
        }
    }
    Some(out)
}

/// The shipped documentation: installed path (under [`DOC`]) → source file.
fn shipped() -> BTreeMap<PathBuf, PathBuf> {
    let grip = repo().join("tools/grip");
    let manifest = grip.join("Cargo.toml");
    let text = std::fs::read_to_string(&manifest).expect("tools/grip/Cargo.toml reads");
    let v: toml::Table = text.parse().expect("tools/grip/Cargo.toml parses");
    let assets = v["package"]["metadata"]["deb"]["assets"]
        .as_array()
        .expect("[package.metadata.deb] assets");
    let mut out = BTreeMap::new();
    for a in assets {
        let a = a.as_array().expect("an asset is [source, target, mode]");
        let (src, dst) = (a[0].as_str().unwrap(), a[1].as_str().unwrap());
        let Some(rel) = dst.strip_prefix(DOC) else {
            continue;
        };
        let sources: Vec<PathBuf> = match src.strip_suffix("/*") {
            Some(dir) => {
                let dir = grip.join(dir);
                let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
                    .unwrap_or_else(|e| panic!("asset {src}: {}: {e}", dir.display()))
                    .map(|e| e.unwrap().path())
                    .filter(|p| p.is_file())
                    .collect();
                assert!(!v.is_empty(), "asset {src}: no file");
                v.sort();
                v
            }
            None => vec![grip.join(src)],
        };
        for s in sources {
            assert!(s.is_file(), "asset {src}: {} is not a file", s.display());
            let name = s.file_name().unwrap();
            let at = if rel.is_empty() || rel.ends_with('/') {
                Path::new(rel).join(name)
            } else {
                PathBuf::from(rel)
            };
            assert!(
                out.insert(at.clone(), s).is_none(),
                "two assets install {}",
                at.display()
            );
        }
    }
    out
}

/// The relative link targets of a Markdown text (`[text](target)`, the
/// anchor cut), web and mail links and in-page anchors left out.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("](") {
        rest = &rest[i + 2..];
        let Some(end) = rest.find(')') else { break };
        let t = rest[..end].split('#').next().unwrap_or("").trim();
        if !t.is_empty() && !t.contains("://") && !t.starts_with("mailto:") && !t.contains(' ') {
            out.push(t.to_string());
        }
    }
    out
}

/// The paths ending in `.md` a Markdown text names in backticks.
fn named_docs(text: &str) -> Vec<String> {
    text.split('`')
        .skip(1)
        .step_by(2)
        .filter(|s| {
            s.ends_with(".md")
                && !s.contains(char::is_whitespace)
                && !s.contains('*')
                && !s.starts_with('/')
        })
        .map(str::to_string)
        .collect()
}

#[test]
fn every_link_and_named_document_of_the_shipped_docs_is_shipped() {
    let docs = shipped();
    // the documents the units, the README and the services send readers to
    for must in [
        "README.md",
        "services/README.md",
        "crates/io/README.md",
        "config/systemd/README.md",
        "tools/grip/README.md",
    ] {
        assert!(docs.contains_key(Path::new(must)), "{must} is not shipped");
    }
    let mut broken = Vec::new();
    for (at, src) in docs
        .iter()
        .filter(|(a, _)| a.extension().is_some_and(|e| e == "md"))
    {
        let text = std::fs::read_to_string(src).unwrap();
        let dir = at.parent().unwrap_or(Path::new(""));
        for l in links(&text) {
            let ok = normal(&dir.join(&l)).is_some_and(|p| docs.contains_key(&p));
            if !ok {
                broken.push(format!("{}: link ({l})", at.display()));
            }
        }
        for n in named_docs(&text) {
            let ok = [Path::new("").join(&n), dir.join(&n)]
                .iter()
                .any(|p| normal(p).is_some_and(|p| docs.contains_key(&p)));
            if !ok {
                broken.push(format!("{}: `{n}`", at.display()));
            }
        }
    }
    assert!(
        broken.is_empty(),
        "documents the package's docs send the reader to but do not ship ({DOC}; add them to [package.metadata.deb] assets in the repository's layout):\n{}",
        broken.join("\n")
    );
}

#[test]
fn the_link_reader_finds_what_it_must_and_leaves_the_rest() {
    let t = "see [io](../crates/io/README.md#can) and [w](https://x.org/a.md), \
             [here](#top), `crates/sim/README.md`, `a README.md`, `*.md`, `/etc/x.md`";
    assert_eq!(links(t), ["../crates/io/README.md"]);
    assert_eq!(named_docs(t), ["crates/sim/README.md"]);
    assert_eq!(
        normal(Path::new("services/tcs-loop/../../crates/io/README.md")),
        Some(PathBuf::from("crates/io/README.md"))
    );
    assert_eq!(normal(Path::new("../README.md")), None);
}
