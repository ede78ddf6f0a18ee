//! `grip dataset merge --out DIR SRC...`: one class dataset from several
//! (e.g. the default model's training set: one set at 10 dB and one drawn
//! over -5..20 dB, crate `grip-arte` README "Results").
//!
//! Every WAV of `SRC` (read with [`Dataset::scan`], so a source `grip
//! train` would refuse is refused here too) goes to
//! `DIR/<class>/<tag>/<its path under the class folder>`, where `tag` is
//! the source folder's name: hard-linked where the file system allows,
//! copied otherwise. The manifests are merged: the union of their columns
//! (in order of first appearance), `file` rewritten to the new path, a
//! `recording` value prefixed with the tag (groups of different sources
//! stay apart), or, with `--recording-by COLUMN`, the value of that column
//! (every source's manifest must have it): files of any source with the same
//! value are one recording, so cross-validation keeps them in one fold (the
//! same car rendered at two SNRs has one `seed`). Nothing is overwritten:
//! `DIR` must not exist yet.

use crate::dataset::Dataset;
use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct MergeArgs {
    /// Output folder (must not exist).
    #[arg(long)]
    pub out: PathBuf,
    /// Source class datasets (folders with one sub-folder per class).
    #[arg(required = true, num_args = 2..)]
    pub src: Vec<PathBuf>,
    /// Manifest column whose value names the recording across sources
    /// (e.g. `seed`); default: every source's recordings stay apart.
    #[arg(long)]
    pub recording_by: Option<String>,
}

struct Manifest {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

fn read_manifest(root: &Path) -> Result<Option<Manifest>> {
    let p = root.join("manifest.csv");
    if !p.is_file() {
        return Ok(None);
    }
    let mut rdr =
        csv::Reader::from_path(&p).with_context(|| format!("cannot read {}", p.display()))?;
    let header: Vec<String> = rdr
        .headers()
        .with_context(|| format!("{}: bad header", p.display()))?
        .iter()
        .map(|h| h.trim().to_string())
        .collect();
    let mut rows = Vec::new();
    for (i, r) in rdr.records().enumerate() {
        let r = r.with_context(|| format!("{} line {}", p.display(), i + 2))?;
        rows.push(r.iter().map(str::to_string).collect());
    }
    Ok(Some(Manifest { header, rows }))
}

fn link_or_copy(from: &Path, to: &Path) -> Result<()> {
    if let Some(dir) = to.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    if std::fs::hard_link(from, to).is_err() {
        std::fs::copy(from, to)
            .with_context(|| format!("cannot copy {} to {}", from.display(), to.display()))?;
    }
    Ok(())
}

/// Merges `a.src` into `a.out`; returns the number of files.
pub fn merge(a: &MergeArgs) -> Result<usize> {
    if a.out.exists() {
        bail!(
            "--out {}: already exists; merge writes a new folder and overwrites nothing",
            a.out.display()
        );
    }
    let mut tags: Vec<String> = Vec::new();
    let mut sets = Vec::new();
    for src in &a.src {
        let ds = Dataset::scan(src)?;
        let tag = std::fs::canonicalize(src)
            .ok()
            .and_then(|p| p.file_name().and_then(|n| n.to_str()).map(str::to_string))
            .with_context(|| format!("{}: cannot name the source folder", src.display()))?;
        if tags.contains(&tag) {
            bail!(
                "{}: another source is also called `{tag}`; give the sources different folder names",
                src.display()
            );
        }
        tags.push(tag);
        let man = read_manifest(src)?;
        if let Some(col) = &a.recording_by
            && !man.as_ref().is_some_and(|m| m.header.contains(col))
        {
            bail!(
                "{}: --recording-by {col}, but its manifest.csv has no `{col}` column",
                src.display()
            );
        }
        sets.push((ds, man));
    }
    let mut header: Vec<String> = vec!["file".into()];
    if a.recording_by.is_some() {
        header.push("recording".into());
    }
    for (_, m) in &sets {
        for h in m.iter().flat_map(|m| &m.header) {
            if !header.contains(h) {
                header.push(h.clone());
            }
        }
    }
    let rec_col = header.iter().position(|h| h == "recording");
    let mut rows: Vec<Vec<String>> = Vec::new();
    let mut files = 0;
    for ((ds, man), tag) in sets.iter().zip(&tags) {
        let new_rel = |rel: &str| -> String {
            match rel.split_once('/') {
                Some((class, rest)) => format!("{class}/{tag}/{rest}"),
                None => format!("{tag}/{rel}"),
            }
        };
        for e in &ds.entries {
            link_or_copy(&e.path, &a.out.join(new_rel(&e.rel)))?;
            files += 1;
        }
        let Some(m) = man else { continue };
        let cols: BTreeMap<&str, usize> = m
            .header
            .iter()
            .enumerate()
            .map(|(i, h)| (h.as_str(), i))
            .collect();
        for r in &m.rows {
            let mut out = vec![String::new(); header.len()];
            for (j, h) in header.iter().enumerate() {
                if let Some(v) = cols.get(h.as_str()).and_then(|&i| r.get(i)) {
                    out[j] = v.clone();
                }
            }
            out[0] = new_rel(out[0].trim());
            if let (Some(rc), Some(by)) = (rec_col, &a.recording_by) {
                let v = cols.get(by.as_str()).and_then(|&i| r.get(i));
                out[rc] = v.map(|v| v.trim().to_string()).unwrap_or_default();
            } else if let Some(rc) = rec_col
                && !out[rc].trim().is_empty()
            {
                out[rc] = format!("{tag}/{}", out[rc].trim());
            }
            rows.push(out);
        }
    }
    if rows.is_empty() {
        return Ok(files);
    }
    let p = a.out.join("manifest.csv");
    let mut w =
        csv::Writer::from_path(&p).with_context(|| format!("cannot write {}", p.display()))?;
    w.write_record(&header)?;
    for r in &rows {
        w.write_record(r)?;
    }
    w.flush()
        .with_context(|| format!("cannot write {}", p.display()))?;
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_io::wav;

    fn tiny(root: &Path, classes: &[&str], manifest: Option<&str>) {
        for c in classes {
            std::fs::create_dir_all(root.join(c)).unwrap();
            for i in 0..2 {
                let x = vec![0.01f32 * (i + 1) as f32; 441];
                wav::write_mono_i16(&root.join(c).join(format!("{c}_{i}.wav")), 44_100, &x)
                    .unwrap();
            }
        }
        if let Some(m) = manifest {
            std::fs::write(root.join("manifest.csv"), m).unwrap();
        }
    }

    #[test]
    fn merged_dataset_keeps_every_file_speed_and_recording_apart() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("a10"), d.path().join("b5"));
        tiny(
            &a,
            &["asphalt", "snow"],
            Some(
                "file,road,speed_kmh\nasphalt/asphalt_0.wav,asphalt,12\nsnow/snow_1.wav,snow,20\n",
            ),
        );
        tiny(
            &b,
            &["asphalt", "snow"],
            Some(
                "file,recording,speed_kmh\nasphalt/asphalt_0.wav,r1,30\nasphalt/asphalt_1.wav,r1,30\n",
            ),
        );
        let out = d.path().join("mix");
        let n = merge(&MergeArgs {
            out: out.clone(),
            src: vec![a.clone(), b.clone()],
            recording_by: None,
        })
        .unwrap();
        assert_eq!(n, 8);
        let ds = Dataset::scan(&out).unwrap();
        assert_eq!(ds.classes, ["asphalt", "snow"]);
        assert_eq!(ds.entries.len(), 8);
        let get = |rel: &str| ds.entries.iter().find(|e| e.rel == rel).unwrap();
        assert_eq!(get("asphalt/a10/asphalt_0.wav").speed_kmh, Some(12.0));
        assert_eq!(get("snow/a10/snow_1.wav").speed_kmh, Some(20.0));
        assert_eq!(get("asphalt/b5/asphalt_1.wav").speed_kmh, Some(30.0));
        assert_eq!(get("snow/b5/snow_0.wav").speed_kmh, None);
        // b5's two asphalt files are one recording; a10's are two.
        assert_eq!(
            get("asphalt/b5/asphalt_0.wav").recording,
            get("asphalt/b5/asphalt_1.wav").recording
        );
        assert_ne!(
            get("asphalt/a10/asphalt_0.wav").recording,
            get("asphalt/a10/asphalt_1.wav").recording
        );
        assert_eq!(ds.recordings_per_class(), [3, 4]);
        let m = std::fs::read_to_string(out.join("manifest.csv")).unwrap();
        assert!(m.starts_with("file,road,speed_kmh,recording\n"), "{m}");
        // The same car in two sources: one recording with --recording-by.
        let (c, e) = (d.path().join("c10"), d.path().join("c0"));
        let man = "file,seed,speed_kmh\nasphalt/asphalt_0.wav,7,10\nasphalt/asphalt_1.wav,8,10\nsnow/snow_0.wav,9,10\nsnow/snow_1.wav,10,10\n";
        tiny(&c, &["asphalt", "snow"], Some(man));
        tiny(&e, &["asphalt", "snow"], Some(man));
        let by = d.path().join("by");
        merge(&MergeArgs {
            out: by.clone(),
            src: vec![c.clone(), e],
            recording_by: Some("seed".into()),
        })
        .unwrap();
        let ds = Dataset::scan(&by).unwrap();
        assert_eq!(ds.recordings_per_class(), [2, 2]);
        let get = |rel: &str| ds.entries.iter().find(|x| x.rel == rel).unwrap().recording;
        assert_eq!(get("snow/c10/snow_1.wav"), get("snow/c0/snow_1.wav"));
        let e = merge(&MergeArgs {
            out: d.path().join("by2"),
            src: vec![c, a],
            recording_by: Some("seed".into()),
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("no `seed` column"), "{e}");
    }

    #[test]
    fn merge_overwrites_nothing_and_names_clashes() {
        let d = tempfile::tempdir().unwrap();
        let a = d.path().join("x").join("set");
        let b = d.path().join("y").join("set");
        tiny(&a, &["asphalt", "snow"], None);
        tiny(&b, &["asphalt", "snow"], None);
        let out = d.path().join("out");
        let e = merge(&MergeArgs {
            out: out.clone(),
            src: vec![a.clone(), b],
            recording_by: None,
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("also called `set`"), "{e}");
        std::fs::create_dir(&out).unwrap();
        let e = merge(&MergeArgs {
            out: out.clone(),
            src: vec![a.clone(), a],
            recording_by: None,
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("already exists"), "{e}");
        let bad = d.path().join("bad");
        std::fs::create_dir_all(bad.join("asphalt")).unwrap();
        let e = merge(&MergeArgs {
            out: d.path().join("out2"),
            src: vec![bad, d.path().join("x").join("set")],
            recording_by: None,
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("no .wav"), "{e}");
    }
}
