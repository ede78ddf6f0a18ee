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
//!
//! The manifests are read by the rules of every manifest reader
//! (`crate::dataset`): column names in any case ([`column_key`]: `File`,
//! `Speed_kmh` and `file`, `speed_kmh` are one column, merged as one, and
//! `--recording-by` finds its column so too), `file` as a path relative to
//! the source, `./asphalt/a1.wav` or a path under the source naming the
//! same file as `asphalt/a1.wav` ([`manifest_file`]), and a file listed
//! twice is an error naming it and both lines ([`FirstRows`]): the merged
//! manifest has one row per file.
//!
//! Before anything is written, every file of every source is read
//! ([`check_sources`]): all at one sample rate (a model's features are
//! computed at one rate; `grip train` would refuse the mix only after the
//! merge), and no audio in two sources (byte-equal files: one source
//! merged twice under another folder name, or sources sharing files),
//! which the merged set would hold twice, as two recordings `grip train`
//! refuses. Each error names both files.

use crate::dataset::{
    Dataset, FirstRows, column_key, column_keys, manifest_file, record_line, wav_rate_len,
};
use anyhow::{Context, Result, bail};
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

/// A source's manifest, read as every manifest reader reads one.
struct Manifest {
    /// Column names as written (trimmed).
    header: Vec<String>,
    /// Their [`column_key`]s.
    keys: Vec<String>,
    /// Rows: the `file` as a path relative to the source ([`manifest_file`])
    /// and the fields.
    rows: Vec<(String, Vec<String>)>,
}

impl Manifest {
    /// The column named `name` in any case.
    fn col(&self, name: &str) -> Option<usize> {
        let key = column_key(name);
        self.keys.iter().position(|k| *k == key)
    }
}

fn read_manifest(root: &Path) -> Result<Option<Manifest>> {
    let p = root.join("manifest.csv");
    if !p.is_file() {
        return Ok(None);
    }
    let text = std::fs::read(&p).with_context(|| format!("cannot read {}", p.display()))?;
    let mut rdr = csv::Reader::from_reader(text.as_slice());
    let headers = rdr
        .headers()
        .with_context(|| format!("{}: bad header", p.display()))?
        .clone();
    let header: Vec<String> = headers.iter().map(|h| h.trim().to_string()).collect();
    let keys: Vec<String> = column_keys(&headers).iter().map(str::to_owned).collect();
    let Some(fcol) = keys.iter().position(|k| k == "file") else {
        bail!(
            "manifest {}: no `file` column (header: {header:?})",
            p.display()
        );
    };
    let root_abs = std::fs::canonicalize(root).ok();
    let mut first = FirstRows::default();
    let mut rows = Vec::new();
    for (k, r) in rdr.records().enumerate() {
        let r = r.with_context(|| format!("manifest {}: record {}", p.display(), k + 1))?;
        let line = record_line(&text, &r, k);
        let file = manifest_file(r.get(fcol).unwrap_or(""), root, root_abs.as_deref());
        first.first(&p, &file, line)?;
        rows.push((file, r.iter().map(str::to_string).collect()));
    }
    Ok(Some(Manifest { header, keys, rows }))
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

/// Reads every file of `sets` (its header, then its bytes; one progress
/// bar): refuses a file whose
/// sample rate is not the first file's, and a file whose content (SHA-256)
/// is that of a file of another source, naming both files. Copies within
/// one source are left to `grip train`, which tells a copy under two roads
/// (refused), as two recordings (refused) and within one recording (a
/// warning).
fn check_sources(sets: &[(Dataset, Option<Manifest>)]) -> Result<()> {
    let n: usize = sets.iter().map(|(ds, _)| ds.entries.len()).sum();
    let bar = crate::drive::many::bar(n, "files read");
    let mut first: Option<(u32, &Path)> = None;
    let mut seen: std::collections::HashMap<String, (usize, &Path)> =
        std::collections::HashMap::new();
    for (k, (ds, _)) in sets.iter().enumerate() {
        for e in &ds.entries {
            let (rate, _) = wav_rate_len(&e.path)?;
            match first {
                None => first = Some((rate, &e.path)),
                Some((r0, f0)) if r0 != rate => bail!(
                    "{}: {rate} Hz, but {} is at {r0} Hz: a merged dataset must have one sample rate (a model's features are computed at one; `grip train` refuses a mix); resample one source first (nothing written)",
                    e.path.display(),
                    f0.display()
                ),
                Some(_) => {}
            }
            let bytes = std::fs::read(&e.path)
                .with_context(|| format!("cannot read {}", e.path.display()))?;
            let sha = grip_digest::sha256_hex(&bytes);
            match seen.get(&sha) {
                Some(&(j, f)) if j != k => bail!(
                    "{}: the same audio (equal byte for byte) as {} of another source: the merged set would hold it twice, as two recordings, and cross-validation would test on what it trained on; merge each source once, or remove the copy (nothing written)",
                    e.path.display(),
                    f.display()
                ),
                Some(_) => {}
                None => {
                    seen.insert(sha, (k, &e.path));
                }
            }
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
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
            && man.as_ref().is_none_or(|m| m.col(col).is_none())
        {
            bail!(
                "{}: --recording-by {col}, but its manifest.csv has no `{col}` column",
                src.display()
            );
        }
        sets.push((ds, man));
    }
    check_sources(&sets)?;
    // the union of the columns, one per name in any case, as first written
    let mut header: Vec<String> = vec!["file".into()];
    if a.recording_by.is_some() {
        header.push("recording".into());
    }
    let mut keys: Vec<String> = header.clone();
    for (_, m) in &sets {
        for (h, k) in m.iter().flat_map(|m| m.header.iter().zip(&m.keys)) {
            if !keys.contains(k) {
                header.push(h.clone());
                keys.push(k.clone());
            }
        }
    }
    let rec_col = keys.iter().position(|k| k == "recording");
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
        for (file, r) in &m.rows {
            let mut out = vec![String::new(); header.len()];
            for (j, k) in keys.iter().enumerate() {
                if let Some(v) = m.col(k).and_then(|i| r.get(i)) {
                    out[j] = v.clone();
                }
            }
            out[0] = new_rel(file);
            if let (Some(rc), Some(by)) = (rec_col, &a.recording_by) {
                let v = m.col(by).and_then(|i| r.get(i));
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

    /// Two WAVs per class under `root`, at 44.1 kHz, every file's audio
    /// its own (by the call, the class and the index).
    fn tiny(root: &Path, classes: &[&str], manifest: Option<&str>) {
        tiny_at(root, classes, manifest, 44_100);
    }

    fn tiny_at(root: &Path, classes: &[&str], manifest: Option<&str>, rate: u32) {
        // one value per call in this process: no two calls write the same
        // audio (tests run as threads of one process)
        static CALLS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(1);
        let salt = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        assert!(salt < 1000, "more calls than distinct first samples");
        for (ci, c) in classes.iter().enumerate() {
            std::fs::create_dir_all(root.join(c)).unwrap();
            for i in 0..2 {
                let mut x = vec![0.01f32 * (i + 1) as f32; 441];
                x[0] = salt as f32 / 2000.0;
                x[1] = ci as f32 / 20.0;
                wav::write_mono_i16(&root.join(c).join(format!("{c}_{i}.wav")), rate, &x).unwrap();
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

    /// Manifests as users write them (column names in any case, `./` and
    /// paths under the source) merge into one column per name and one row
    /// per file with the right new paths: they were merged as separate
    /// columns (`File` beside `file`), the rows' `file` left empty or
    /// mangled (`./a10/asphalt/...`), so the merged dataset could not be
    /// read and its speeds and recordings were lost.
    #[test]
    fn manifests_merge_by_column_name_in_any_case_and_by_file() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("a10"), d.path().join("b5"));
        tiny(&a, &["asphalt", "snow"], None);
        let a_abs = std::fs::canonicalize(&a).unwrap();
        std::fs::write(
            a.join("manifest.csv"),
            format!(
                "File,Recording,Speed_KMH,SEED\n./asphalt/asphalt_0.wav,r1,12,7\n{}/asphalt/asphalt_1.wav,r1,14,8\n",
                a_abs.display()
            ),
        )
        .unwrap();
        tiny(
            &b,
            &["asphalt", "snow"],
            Some("file,recording,speed_kmh,seed\nasphalt/asphalt_0.wav,r1,30,7\n"),
        );
        let out = d.path().join("mix");
        merge(&MergeArgs {
            out: out.clone(),
            src: vec![a.clone(), b.clone()],
            recording_by: None,
        })
        .unwrap();
        let m = std::fs::read_to_string(out.join("manifest.csv")).unwrap();
        assert_eq!(
            m,
            "file,Recording,Speed_KMH,SEED\n\
             asphalt/a10/asphalt_0.wav,a10/r1,12,7\n\
             asphalt/a10/asphalt_1.wav,a10/r1,14,8\n\
             asphalt/b5/asphalt_0.wav,b5/r1,30,7\n"
        );
        let ds = Dataset::scan(&out).unwrap();
        let get = |rel: &str| ds.entries.iter().find(|e| e.rel == rel).unwrap();
        assert_eq!(get("asphalt/a10/asphalt_0.wav").speed_kmh, Some(12.0));
        assert_eq!(get("asphalt/a10/asphalt_1.wav").speed_kmh, Some(14.0));
        assert_eq!(get("asphalt/b5/asphalt_0.wav").speed_kmh, Some(30.0));
        assert_eq!(
            get("asphalt/a10/asphalt_0.wav").recording,
            get("asphalt/a10/asphalt_1.wav").recording
        );
        assert_ne!(
            get("asphalt/a10/asphalt_0.wav").recording,
            get("asphalt/b5/asphalt_0.wav").recording
        );
        // --recording-by in another case than either manifest writes it
        let by = d.path().join("by");
        merge(&MergeArgs {
            out: by.clone(),
            src: vec![a, b],
            recording_by: Some("Seed".into()),
        })
        .unwrap();
        let ds = Dataset::scan(&by).unwrap();
        let get = |rel: &str| ds.entries.iter().find(|e| e.rel == rel).unwrap().recording;
        assert_eq!(
            get("asphalt/a10/asphalt_0.wav"),
            get("asphalt/b5/asphalt_0.wav")
        );
        assert_ne!(
            get("asphalt/a10/asphalt_0.wav"),
            get("asphalt/a10/asphalt_1.wav")
        );
    }

    /// A source listing a file twice (here once as `./`) is refused naming
    /// the file and both lines, before anything is written: the merged
    /// manifest never carries a file twice.
    #[test]
    fn a_file_listed_twice_is_refused_before_anything_is_written() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("a"), d.path().join("b"));
        tiny(
            &a,
            &["asphalt", "snow"],
            Some("file,speed_kmh\nasphalt/asphalt_0.wav,10\n\n./asphalt/asphalt_0.wav,20\n"),
        );
        tiny(&b, &["asphalt", "snow"], None);
        let out = d.path().join("out");
        let e = format!(
            "{:#}",
            merge(&MergeArgs {
                out: out.clone(),
                src: vec![b, a],
                recording_by: None,
            })
            .unwrap_err()
        );
        assert!(
            e.contains("file `asphalt/asphalt_0.wav` is listed twice, on line 2 and on line 4"),
            "{e}"
        );
        assert!(!out.exists());
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

    /// Sources at two sample rates, and one source's audio again under
    /// another folder name, are refused before anything is written, each
    /// error naming both files: the mix used to be merged and refused only
    /// by `grip train`, and the copy trained on as two recordings.
    #[test]
    fn mixed_rates_and_audio_in_two_sources_are_refused_before_writing() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("a44"), d.path().join("b48"));
        tiny(&a, &["asphalt", "snow"], None);
        tiny_at(&b, &["asphalt", "snow"], None, 48_000);
        let out = d.path().join("mix");
        let refused = |src: Vec<PathBuf>| {
            merge(&MergeArgs {
                out: out.clone(),
                src,
                recording_by: None,
            })
            .unwrap_err()
            .to_string()
        };
        let e = refused(vec![a.clone(), b]);
        assert!(e.contains("48000 Hz") && e.contains("44100 Hz"), "{e}");
        assert!(
            e.contains(&b48_file(d.path())) && e.contains("a44"),
            "both files named: {e}"
        );
        assert!(!out.exists(), "nothing written");
        // a44 again, copied under another name
        let copy = d.path().join("again");
        for c in ["asphalt", "snow"] {
            std::fs::create_dir_all(copy.join(c)).unwrap();
            for i in 0..2 {
                let f = format!("{c}/{c}_{i}.wav");
                std::fs::copy(a.join(&f), copy.join(&f)).unwrap();
            }
        }
        let e = refused(vec![a.clone(), copy]);
        assert!(e.contains("the same audio (equal byte for byte) as"), "{e}");
        assert!(
            e.contains("again") && e.contains("a44") && e.contains("asphalt_0.wav"),
            "both files named: {e}"
        );
        assert!(!out.exists(), "nothing written");
        // a source of its own audio merges (the check is not a false alarm)
        let c = d.path().join("c44");
        tiny(&c, &["asphalt", "snow"], None);
        assert_eq!(
            merge(&MergeArgs {
                out: out.clone(),
                src: vec![a, c],
                recording_by: None,
            })
            .unwrap(),
            8
        );
    }

    fn b48_file(root: &Path) -> String {
        root.join("b48")
            .join("asphalt")
            .join("asphalt_0.wav")
            .display()
            .to_string()
    }
}
