//! Labelled audio datasets for `grip train`: one folder per class of WAV files.
//!
//! ```text
//! DIR/
//!   asphalt/  *.wav      one recording per file, class = folder name
//!   gravel/   *.wav
//!   ...
//!   manifest.csv         optional
//! ```
//!
//! Classes are the sub-folders that hold WAV files, in sorted order. Folders
//! and files starting with `.` are ignored. Each WAV file is one recording
//! (one group for cross-validation), unless the optional `manifest.csv`
//! says otherwise: a CSV with a header; column `file` (path relative to
//! `DIR`, required) and optionally `recording` (files with the same value
//! are one recording, e.g. several clips of one drive) and `class` (or
//! `road`, as `grip dataset synth` writes it; if given, must equal the
//! folder name), and `speed_kmh` (the vehicle speed of the recording, needed
//! to train or evaluate a speed-normalised model). Other columns (seed, SNR,
//! ...) are ignored here. Files missing from the manifest are their own
//! recordings; manifest rows naming missing files are an error, and so is
//! a file listed twice (both lines named). Column names are matched in any
//! case ([`column_key`], the rule of every manifest and segments reader).
//!
//! Also here: what the commands that read recordings share: `--channel`
//! ([`ChannelArg`]) and the arte service's audio-quality rule applied to
//! recordings ([`FileJudge`], [`Excluded`]); the WAV files at a path
//! ([`wavs_at`]), a file's rate and length from its header
//! ([`wav_rate_len`]), and how a model names a training file by content
//! ([`file_id`], [`first_known_file`]: held-out folders checked against
//! the training files).
//!
//! Errors name the path and the reason: a class folder without WAV files, a
//! dataset with fewer than two classes, no WAV files at all, an unreadable
//! or malformed WAV, mixed sample rates; and, when the files are read for
//! their features (`grip train`'s `extract_dataset`), the same audio in two
//! files of two roads or two recordings.
//!
//! The dataset hash (stored in model files) is SHA-256 over, for every file
//! in order (class, then path): `class \0 relative/path \0 sha256(file) \n`.

use anyhow::{Context, Result, bail};
use grip_arte::quality::{AudioQuality, BadAudio};
use grip_digest::sha256_hex;
use grip_io::wav::{Audio, Channel, decode_channel};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// `--channel N` of the commands that read recordings for training or
/// evaluation.
#[derive(clap::Args, Clone, Copy, Debug, Default)]
pub struct ChannelArg {
    /// Channel of multi-channel WAV files to use (0-based), as the live
    /// ALSA source publishes one (`[alsa] channel` in audio-acq.toml).
    /// Default: the channels averaged; a stereo pair in opposite phase
    /// then cancels, to silence, which is excluded as the arte service
    /// would refuse it.
    #[arg(long)]
    pub channel: Option<u16>,
}

impl ChannelArg {
    /// The channel selection for `grip_io::wav`.
    pub fn get(self) -> Channel {
        self.channel.map_or(Channel::Average, Channel::One)
    }

    /// Whether the file at `path` has the channel asked for, from its
    /// header (before any long work): the error names the file and its
    /// channel count. A header this cannot read passes (the decoder says
    /// why later).
    pub fn check(self, path: &Path) -> Result<()> {
        if let (Some(channel), Ok(h)) = (self.channel, grip_io::wav::header(path))
            && channel >= h.channels
        {
            return Err(grip_io::wav::WavErrorKind::NoSuchChannel {
                channel,
                channels: h.channels,
            }
            .at(path)
            .into());
        }
        Ok(())
    }

    /// ` --channel N`, or nothing for the default.
    pub fn command_line(self) -> String {
        self.channel
            .map_or(String::new(), |c| format!(" --channel {c}"))
    }
}

/// A CSV column name as every reader here compares it: trimmed, in lower
/// case (`File`, ` speed_KMH` name the columns `file`, `speed_kmh`).
pub fn column_key(name: &str) -> String {
    name.trim().to_ascii_lowercase()
}

/// A CSV header with every name as [`column_key`] gives it, for serde.
pub fn column_keys(headers: &csv::StringRecord) -> csv::StringRecord {
    headers.iter().map(column_key).collect()
}

/// The line of `text` (1 = the first) where record number `k` (0-based,
/// the header not counted) starts: from its byte position, blank lines and
/// quoted line breaks counted (the reader's own count skips blank lines and
/// is off with CRLF); the record's number + 2 if the reader has none.
pub fn record_line(text: &[u8], rec: &csv::StringRecord, k: usize) -> usize {
    rec.position().map_or(k + 2, |p| {
        // the record's position is where the reader began it, before the
        // blank lines it skipped
        let mut at = (p.byte() as usize).min(text.len());
        while at < text.len() && matches!(text[at], b'\n' | b'\r') {
            at += 1;
        }
        1 + text[..at].iter().filter(|&&c| c == b'\n').count()
    })
}

/// The line each file of a manifest was listed on: a second row for the
/// same file is an error ([`FirstRows::first`]), not a silent override.
#[derive(Default)]
pub struct FirstRows(BTreeMap<String, usize>);

impl FirstRows {
    /// Notes `file` on `line` of `manifest`; an error naming the file and
    /// both lines if it was listed before.
    pub fn first(&mut self, manifest: &Path, file: &str, line: usize) -> Result<()> {
        if let Some(before) = self.0.insert(file.to_owned(), line) {
            bail!(
                "manifest {}: file `{file}` is listed twice, on line {before} and on line {line}; keep one row per file",
                manifest.display()
            );
        }
        Ok(())
    }
}

/// What the arte service's audio-quality rule ([`AudioQuality`]) left out
/// of a command's recordings: the frames (or blocks) it would refuse live,
/// per reason, and the files it refused entirely.
#[derive(Clone, Debug, Default)]
pub struct Excluded {
    /// Frames judged.
    pub judged: usize,
    /// Frames refused, per reason ([`BadAudio::ALL`] order).
    pub refused: [usize; 3],
    /// Files every frame of which was refused.
    pub files: Vec<String>,
}

impl Excluded {
    /// Frames refused.
    pub fn frames(&self) -> usize {
        self.refused.iter().sum()
    }

    /// `silence 3, clipping 1` (the reasons that occurred).
    fn reasons(refused: &[usize; 3]) -> String {
        BadAudio::ALL
            .iter()
            .zip(refused)
            .filter(|(_, n)| **n > 0)
            .map(|(r, n)| format!("{r} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Adds `other`.
    pub fn merge(&mut self, other: Excluded) {
        self.judged += other.judged;
        for (a, b) in self.refused.iter_mut().zip(other.refused) {
            *a += b;
        }
        self.files.extend(other.files);
    }

    /// One line for a report: how many files and frames were excluded and
    /// why; `None` when nothing was.
    pub fn summary(&self, unit: &str) -> Option<String> {
        (self.frames() > 0).then(|| {
            format!(
                "excluded by the arte service's audio-quality rule (it refuses such audio live): {} file(s) entirely{}, {} of {} {unit}s ({})",
                self.files.len(),
                if self.files.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", self.files.join(", "))
                },
                self.frames(),
                self.judged,
                Self::reasons(&self.refused)
            )
        })
    }
}

/// Judges the frames (or blocks) of one file by the arte service's rule
/// and, when done, warns of what it refused, naming the file and why.
pub struct FileJudge {
    quality: AudioQuality,
    counts: Excluded,
}

impl FileJudge {
    /// A judge for one file, by the service's default rule.
    pub fn new() -> Self {
        Self {
            quality: AudioQuality::default(),
            counts: Excluded::default(),
        }
    }

    /// Whether `frame` is fit to classify (counted either way).
    pub fn accept(&mut self, frame: &[f32]) -> bool {
        self.counts.judged += 1;
        match self.quality.judge_f32(frame) {
            None => true,
            Some(why) => {
                self.counts.refused[why as usize] += 1;
                false
            }
        }
    }

    /// Ends the file `name` (read as `audio`, by `channel`): a warning on
    /// stderr naming it and the reasons when a frame was refused; its
    /// counts (with the file among the refused ones when every frame was)
    /// added to `total`. `unit`: "frame" or "block".
    pub fn finish(
        self,
        name: &str,
        audio: &Audio,
        channel: Channel,
        unit: &str,
        total: &mut Excluded,
    ) {
        let mut c = self.counts;
        let n = c.frames();
        if n > 0 {
            let hint = if channel == Channel::Average && audio.file_channels > 1 && c.refused[0] > 0
            {
                format!(
                    "; its {} channels are averaged: a pair in opposite phase cancels, --channel N reads one",
                    audio.file_channels
                )
            } else {
                String::new()
            };
            eprintln!(
                "warning: {name}: {n} of {} {unit}s excluded ({}): the arte service would refuse this audio{hint}",
                c.judged,
                Excluded::reasons(&c.refused)
            );
            if n == c.judged {
                c.files.push(name.to_owned());
            }
        }
        total.merge(c);
    }
}

/// One WAV file of the dataset.
#[derive(Clone, Debug)]
pub struct Entry {
    /// Class index into [`Dataset::classes`].
    pub class: usize,
    /// Full path.
    pub path: PathBuf,
    /// Path relative to the dataset root, `/`-separated.
    pub rel: String,
    /// Recording id (cross-validation group).
    pub recording: usize,
    /// Vehicle speed (km/h) from the manifest's `speed_kmh` column, if given.
    pub speed_kmh: Option<f64>,
    /// The manifest line that lists this file, if one does.
    pub manifest_line: Option<usize>,
}

/// A scanned dataset (audio not loaded yet).
#[derive(Clone, Debug)]
pub struct Dataset {
    /// Root folder.
    pub root: PathBuf,
    /// Class names (sorted folder names).
    pub classes: Vec<String>,
    /// Files, sorted by class then path.
    pub entries: Vec<Entry>,
    /// The manifest read (`root/manifest.csv`), if there is one, and
    /// whether it has a `speed_kmh` column.
    pub manifest: Option<(PathBuf, bool)>,
}

fn is_wav(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("wav"))
}

fn hidden(p: &Path) -> bool {
    p.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with('.'))
}

fn wavs_under(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    let rd =
        std::fs::read_dir(dir).with_context(|| format!("cannot read folder {}", dir.display()))?;
    for e in rd {
        let p = e
            .with_context(|| format!("cannot list folder {}", dir.display()))?
            .path();
        if hidden(&p) {
            continue;
        }
        if p.is_dir() {
            wavs_under(&p, out)?;
        } else if is_wav(&p) {
            out.push(p);
        }
    }
    Ok(())
}

/// Every `.wav` at `p` (itself, when it is one) or under it, hidden
/// entries skipped; an error names the folder that cannot be listed.
pub fn wavs_at(p: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    if p.is_file() {
        if is_wav(p) {
            out.push(p.to_path_buf());
        }
        return Ok(());
    }
    wavs_under(p, out)
}

/// How a model names a training file by content: the first 16 hex digits
/// (64 bits) of its SHA-256 (`sha256`: the full hex digest).
pub fn file_id(sha256: &str) -> String {
    sha256.chars().take(16).collect()
}

/// The [`file_id`]s of every `.wav` under `dirs` (hidden ones skipped),
/// sorted, without repeats; a folder or file that cannot be read is left
/// out (its reader says why).
pub fn file_ids(dirs: &[PathBuf]) -> Vec<String> {
    let mut files = Vec::new();
    for d in dirs {
        let _ = wavs_at(d, &mut files);
    }
    let mut ids: Vec<String> = files
        .iter()
        .filter_map(|f| std::fs::read(f).ok())
        .map(|b| file_id(&sha256_hex(&b)))
        .collect();
    ids.sort();
    ids.dedup();
    ids
}

/// The first `.wav` under one of `dirs` (its folder and the file; files
/// in name order, hidden ones skipped) whose content is one of `known`
/// (sorted [`file_id`]s of training files); `None` when there is none or
/// `known` is empty. A folder that cannot be listed or a file that cannot
/// be read is left to the reader of the recordings. `grip calibrate`'s
/// `--data` and `grip train`'s `--test` are checked so against the
/// training files.
pub fn first_known_file(dirs: &[PathBuf], known: &[String]) -> Option<(PathBuf, PathBuf)> {
    if known.is_empty() {
        return None;
    }
    for dir in dirs {
        let mut files = Vec::new();
        if wavs_at(dir, &mut files).is_err() {
            continue;
        }
        files.sort();
        for f in files {
            let Ok(bytes) = std::fs::read(&f) else {
                continue;
            };
            if known.binary_search(&file_id(&sha256_hex(&bytes))).is_ok() {
                return Some((dir.clone(), f));
            }
        }
    }
    None
}

/// Sample rate (Hz) and length (frames) of the WAV file `path`: from its
/// header (RIFF chunks `fmt ` and `data`) without decoding it, else by
/// decoding it (whose error names the file).
pub fn wav_rate_len(path: &Path) -> Result<(u32, u64)> {
    if let Ok(h) = grip_io::wav::header(path) {
        return Ok((h.sample_rate, h.frames));
    }
    let a = grip_io::wav::read_mono(path)?;
    Ok((a.sample_rate, a.samples.len() as u64))
}

impl Dataset {
    /// Scans `root`: class folders, their WAV files (recursively), the manifest.
    pub fn scan(root: &Path) -> Result<Self> {
        Self::scan_classes(root, None)
    }

    /// As [`Dataset::scan`], keeping only the class folders named in `only`
    /// (each must exist); manifest rows of other classes are ignored.
    pub fn scan_classes(root: &Path, only: Option<&[String]>) -> Result<Self> {
        if !root.is_dir() {
            bail!(
                "dataset folder {} does not exist or is not a folder",
                root.display()
            );
        }
        let mut class_dirs: Vec<PathBuf> = std::fs::read_dir(root)
            .with_context(|| format!("cannot read dataset folder {}", root.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_dir() && !hidden(p))
            .collect();
        class_dirs.sort();
        if let Some(only) = only {
            for want in only {
                if !class_dirs
                    .iter()
                    .any(|d| d.file_name().is_some_and(|n| n == want.as_str()))
                {
                    bail!(
                        "dataset folder {} has no class folder `{want}`",
                        root.display()
                    );
                }
            }
            class_dirs.retain(|d| {
                d.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| only.iter().any(|w| w == n))
            });
        }
        let mut classes = Vec::new();
        let mut entries = Vec::new();
        for dir in &class_dirs {
            let name = dir
                .file_name()
                .and_then(|n| n.to_str())
                .with_context(|| format!("class folder {} has a non-UTF-8 name", dir.display()))?
                .to_string();
            let mut files = Vec::new();
            wavs_under(dir, &mut files)?;
            if files.is_empty() {
                bail!(
                    "class folder {} holds no .wav files; put the recordings of class `{name}` there or remove the folder",
                    dir.display()
                );
            }
            files.sort();
            let class = classes.len();
            classes.push(name);
            for path in files {
                let rel = path
                    .strip_prefix(root)
                    .unwrap_or(&path)
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect::<Vec<_>>()
                    .join("/");
                entries.push(Entry {
                    class,
                    path,
                    rel,
                    recording: 0,
                    speed_kmh: None,
                    manifest_line: None,
                });
            }
        }
        if entries.is_empty() {
            bail!(
                "dataset folder {} has no .wav files; expected one sub-folder per class (e.g. {}/asphalt/*.wav)",
                root.display(),
                root.display()
            );
        }
        if classes.len() < 2 {
            bail!(
                "dataset folder {} has only one class (`{}`); a classifier needs at least two class folders",
                root.display(),
                classes[0]
            );
        }
        let mut ds = Self {
            root: root.to_path_buf(),
            classes,
            entries,
            manifest: None,
        };
        ds.assign_recordings()?;
        Ok(ds)
    }

    fn assign_recordings(&mut self) -> Result<()> {
        let manifest = self.root.join("manifest.csv");
        let mut rec_of_file: BTreeMap<String, String> = BTreeMap::new();
        let mut speed_of_file: BTreeMap<String, f64> = BTreeMap::new();
        let mut line_of_file: BTreeMap<String, usize> = BTreeMap::new();
        if manifest.is_file() {
            let mut rdr = csv::Reader::from_path(&manifest)
                .with_context(|| format!("cannot read manifest {}", manifest.display()))?;
            let headers = rdr
                .headers()
                .with_context(|| format!("manifest {}: bad header", manifest.display()))?
                .clone();
            // column names as written or in another case (`Speed_kmh`)
            let keys = column_keys(&headers);
            let col = |n: &str| keys.iter().position(|h| h == n);
            let Some(fcol) = col("file") else {
                bail!(
                    "manifest {}: no `file` column (header: {:?})",
                    manifest.display(),
                    headers.iter().collect::<Vec<_>>()
                );
            };
            let (rcol, ccol) = (col("recording"), col("class").or_else(|| col("road")));
            let scol = col("speed_kmh");
            self.manifest = Some((manifest.clone(), scol.is_some()));
            let by_rel: BTreeMap<&str, &Entry> =
                self.entries.iter().map(|e| (e.rel.as_str(), e)).collect();
            let root_abs = std::fs::canonicalize(&self.root).ok();
            // for the line numbers of errors (the reader skips blank lines
            // and does not count them)
            let text = std::fs::read(&manifest).unwrap_or_default();
            let mut rows = FirstRows::default();
            for (k, rec) in rdr.records().enumerate() {
                let rec = rec.with_context(|| {
                    format!("manifest {}: record {}", manifest.display(), k + 1)
                })?;
                let line = record_line(&text, &rec, k);
                let file =
                    manifest_file(rec.get(fcol).unwrap_or(""), &self.root, root_abs.as_deref());
                rows.first(&manifest, &file, line)?;
                let Some(entry) = by_rel.get(file.as_str()) else {
                    let top = file.split('/').next().unwrap_or("");
                    if !matches!(top, "" | "." | "..")
                        && self.root.join(top).is_dir()
                        && !self.classes.iter().any(|c| c == top)
                    {
                        continue; // a class left out by `scan_classes`
                    }
                    bail!(
                        "manifest {} line {}, field `file`: `{file}` {}",
                        manifest.display(),
                        line,
                        self.why_not_listed(&file)
                    );
                };
                line_of_file.insert(file.clone(), line);
                if let Some(c) = ccol.and_then(|c| rec.get(c)).map(str::trim)
                    && !c.is_empty()
                    && c != self.classes[entry.class]
                {
                    bail!(
                        "manifest {} line {}: file `{file}` is labelled `{c}` but lies in class folder `{}`",
                        manifest.display(),
                        line,
                        self.classes[entry.class]
                    );
                }
                if let Some(v) = scol.and_then(|c| rec.get(c)).map(str::trim)
                    && !v.is_empty()
                {
                    match v.parse::<f64>() {
                        Ok(kmh) if kmh.is_finite() && kmh >= 0.0 => {
                            speed_of_file.insert(file.clone(), kmh);
                        }
                        _ => bail!(
                            "manifest {} line {}: speed_kmh `{v}` of file `{file}` is not a speed in km/h (a number >= 0)",
                            manifest.display(),
                            line
                        ),
                    }
                }
                if let Some(r) = rcol.and_then(|c| rec.get(c)).map(str::trim)
                    && !r.is_empty()
                {
                    rec_of_file.insert(file, format!("{}\0{r}", self.classes[entry.class]));
                }
            }
        }
        let mut ids: BTreeMap<String, usize> = BTreeMap::new();
        for e in &mut self.entries {
            let key = rec_of_file
                .get(&e.rel)
                .cloned()
                .unwrap_or_else(|| format!("file\0{}", e.rel));
            let next = ids.len();
            e.recording = *ids.entry(key).or_insert(next);
            e.speed_kmh = speed_of_file.get(&e.rel).copied();
            e.manifest_line = line_of_file.get(&e.rel).copied();
        }
        Ok(())
    }

    /// Why a manifest's `file` (relative to the root, `/`-separated, as
    /// [`manifest_file`] gives it) names none of the dataset's recordings.
    fn why_not_listed(&self, file: &str) -> String {
        let root = self.root.display();
        let p = Path::new(file);
        let hidden_part = file
            .split('/')
            .any(|c| c.starts_with('.') && c != "." && c != "..");
        if file.is_empty() {
            "is empty; name the recording's WAV file (relative to the dataset folder)".to_owned()
        } else if p.is_absolute() || file.split('/').any(|c| c == "..") {
            format!("lies outside the dataset folder {root}")
        } else if !self.root.join(p).exists() {
            format!("does not exist (no such file in {root})")
        } else if !is_wav(p) {
            "is not a .wav file".to_owned()
        } else if hidden_part {
            "is hidden (a name starting with `.`, which the dataset leaves out)".to_owned()
        } else if !file.contains('/') {
            format!("lies in {root} itself, not inside a class folder")
        } else {
            format!("is not a .wav inside a class folder of {root}")
        }
    }

    /// Why `e` has no `speed_kmh`, naming the manifest, its line and the
    /// field (for the error of a speed-normalised model).
    pub fn why_no_speed(&self, e: &Entry) -> String {
        let field = "field `speed_kmh`";
        match &self.manifest {
            None => format!(
                "{} has no manifest.csv, so no {field} (the vehicle speed) for `{}`",
                self.root.display(),
                e.rel
            ),
            Some((m, false)) => format!(
                "manifest {} has no `speed_kmh` column (the vehicle speed of each recording)",
                m.display()
            ),
            Some((m, true)) => match e.manifest_line {
                Some(line) => format!(
                    "manifest {} line {line}, {field}: blank for `{}`",
                    m.display(),
                    e.rel
                ),
                None => format!(
                    "manifest {}: `{}` is not listed, so it has no {field}",
                    m.display(),
                    e.rel
                ),
            },
        }
    }

    /// Number of recordings per class.
    pub fn recordings_per_class(&self) -> Vec<usize> {
        let mut sets = vec![std::collections::BTreeSet::new(); self.classes.len()];
        for e in &self.entries {
            sets[e.class].insert(e.recording);
        }
        sets.iter().map(|s| s.len()).collect()
    }
}

/// Reads a WAV file of a dataset (PCM 1..32-bit integer or 32-bit float,
/// any channel count: `channel` of them, or their average; `grip_io::wav`
/// decodes it) at its own rate, and the SHA-256 of its bytes (for the
/// dataset hash): the file is read once for both.
pub fn read_wav(path: &Path, channel: Channel) -> Result<(Audio, String)> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let sha256 = sha256_hex(&bytes);
    Ok((decode_channel(&bytes, path, channel)?, sha256))
}

/// A manifest's `file` as a path relative to the dataset `root`, with `/`:
/// `./asphalt/a1.wav` (what `find .` prints) and a path under the root,
/// absolute or not, name the same file as `asphalt/a1.wav`.
pub fn manifest_file(raw: &str, root: &Path, root_abs: Option<&Path>) -> String {
    let mut f = raw.trim().replace('\\', "/");
    let p = Path::new(&f);
    let under = |base: &Path| {
        p.strip_prefix(base)
            .ok()
            .map(|r| r.to_string_lossy().replace('\\', "/"))
    };
    if let Some(r) = under(root).or_else(|| root_abs.and_then(under)) {
        f = r;
    }
    while let Some(rest) = f.strip_prefix("./") {
        f = rest.trim_start_matches('/').to_owned();
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_wav(path: &Path, n: usize) {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let spec = hound::WavSpec {
            channels: 1,
            sample_rate: 8000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        for i in 0..n {
            w.write_sample(((i * 37 % 200) as i16 - 100) * 50).unwrap();
        }
        w.finalize().unwrap();
    }

    #[test]
    fn scans_classes_and_recordings() {
        let d = tempfile::tempdir().unwrap();
        for (c, f) in [
            ("snow", "a.wav"),
            ("asphalt", "x.wav"),
            ("asphalt", "y.WAV"),
            ("asphalt", "sub/z.wav"),
        ] {
            write_wav(&d.path().join(c).join(f), 100);
        }
        std::fs::write(d.path().join("asphalt/notes.txt"), "ignored").unwrap();
        let ds = Dataset::scan(d.path()).unwrap();
        assert_eq!(ds.classes, ["asphalt", "snow"]);
        assert_eq!(ds.entries.len(), 4);
        assert_eq!(ds.recordings_per_class(), [3, 1]);
        write_wav(&d.path().join("gravel/g.wav"), 100);
        let only =
            Dataset::scan_classes(d.path(), Some(&["snow".to_string(), "gravel".to_string()]))
                .unwrap();
        assert_eq!(only.classes, ["gravel", "snow"]);
        let e = format!(
            "{:#}",
            Dataset::scan_classes(d.path(), Some(&["snow".to_string()])).unwrap_err()
        );
        assert!(e.contains("only one class"), "{e}");
        let e = format!(
            "{:#}",
            Dataset::scan_classes(d.path(), Some(&["ice".to_string()])).unwrap_err()
        );
        assert!(e.contains("no class folder `ice`"), "{e}");
        assert_eq!(ds.entries[0].rel, "asphalt/sub/z.wav");
        let (a, sha) = read_wav(&ds.entries[0].path, Channel::Average).unwrap();
        assert_eq!((a.sample_rate, a.samples.len()), (8000, 100));
        assert!(a.samples.iter().all(|v| v.abs() <= 1.0));
        assert_eq!(
            sha,
            sha256_hex(&std::fs::read(&ds.entries[0].path).unwrap())
        );
    }

    #[test]
    fn manifest_groups_files_into_recordings() {
        let d = tempfile::tempdir().unwrap();
        for f in [
            "asphalt/a1.wav",
            "asphalt/a2.wav",
            "asphalt/a3.wav",
            "gravel/g1.wav",
        ] {
            write_wav(&d.path().join(f), 10);
        }
        std::fs::write(
            d.path().join("manifest.csv"),
            "file,recording,speed_kmh\nasphalt/a1.wav,drive1,10\nasphalt/a2.wav,drive1,20\n",
        )
        .unwrap();
        let ds = Dataset::scan(d.path()).unwrap();
        assert_eq!(ds.entries[0].recording, ds.entries[1].recording);
        assert_ne!(ds.entries[0].recording, ds.entries[2].recording);
        assert_eq!(ds.recordings_per_class(), [2, 1]);
        assert_eq!(ds.entries[0].speed_kmh, Some(10.0));
        assert_eq!(ds.entries[1].speed_kmh, Some(20.0));
        assert_eq!(ds.entries[2].speed_kmh, None);
        // The scan error for this manifest text.
        let scan_err = |manifest: &str| {
            std::fs::write(d.path().join("manifest.csv"), manifest).unwrap();
            format!("{:#}", Dataset::scan(d.path()).unwrap_err())
        };
        let e = scan_err("file,speed_kmh\nasphalt/a1.wav,fast\n");
        assert!(
            e.contains("speed_kmh `fast`") && e.contains("manifest.csv line 2"),
            "{e}"
        );

        let e = scan_err("file,class\nasphalt/a1.wav,gravel\n");
        assert!(
            e.contains("labelled `gravel`") && e.contains("manifest.csv line 2"),
            "{e}"
        );
        let e = scan_err("file\nasphalt/nope.wav\n");
        assert!(e.contains("nope.wav"), "{e}");
        let e = scan_err("path\nasphalt/a1.wav\n");
        assert!(e.contains("no `file` column"), "{e}");
        // the line of the file, blank lines counted
        let e = scan_err("file,speed_kmh\n\nasphalt/a1.wav,fast\n");
        assert!(e.contains("manifest.csv line 3"), "{e}");
        // a file listed twice (here once as ./): both lines, not the last
        // row winning in silence
        let e =
            scan_err("file,recording\nasphalt/a1.wav,d1\nasphalt/a2.wav,d1\n./asphalt/a1.wav,d2\n");
        assert!(
            e.contains("asphalt/a1.wav")
                && e.contains("listed twice")
                && e.contains("line 2")
                && e.contains("line 4"),
            "{e}"
        );
    }

    /// A manifest written with `find .` (`./asphalt/a1.wav`), with paths
    /// under the dataset (absolute or not), or with column names in another
    /// case names the same files: none of its rows is skipped in silence
    /// (they were: the recordings then fell apart into single files and
    /// cross-validation mixed one drive's clips into both sides of a fold).
    #[test]
    fn manifest_paths_and_column_names_as_users_write_them() {
        let d = tempfile::tempdir().unwrap();
        for f in ["asphalt/a1.wav", "asphalt/a2.wav", "gravel/g1.wav"] {
            write_wav(&d.path().join(f), 10);
        }
        let abs = std::fs::canonicalize(d.path()).unwrap();
        let manifest = format!(
            "File,Recording,Speed_kmh\n./asphalt/a1.wav,drive1,10\n{}/asphalt/a2.wav,drive1,20\n",
            abs.display()
        );
        std::fs::write(d.path().join("manifest.csv"), manifest).unwrap();
        let ds = Dataset::scan(d.path()).unwrap();
        assert_eq!(ds.entries[0].recording, ds.entries[1].recording);
        assert_eq!(ds.recordings_per_class(), [1, 1]);
        assert_eq!(ds.entries[0].speed_kmh, Some(10.0));
        assert_eq!(ds.entries[1].speed_kmh, Some(20.0));
        // a path outside the dataset is an error naming it, not skipped
        std::fs::write(
            d.path().join("manifest.csv"),
            "file\n/elsewhere/asphalt/a1.wav\n",
        )
        .unwrap();
        let e = format!("{:#}", Dataset::scan(d.path()).unwrap_err());
        assert!(e.contains("/elsewhere/asphalt/a1.wav"), "{e}");
    }

    /// A manifest row's error names the manifest, the line, the field and
    /// the real reason: a listed file that does not exist (it said "is not
    /// a .wav inside a class folder"), one that is not a .wav, one outside
    /// the class folders; a blank `speed_kmh` names its line, and a
    /// manifest without the column says so (it said "no speed_kmh for this
    /// recording").
    #[test]
    fn manifest_errors_name_line_field_and_reason() {
        let d = tempfile::tempdir().unwrap();
        for f in ["asphalt/a1.wav", "gravel/g1.wav"] {
            write_wav(&d.path().join(f), 10);
        }
        std::fs::write(d.path().join("asphalt/notes.txt"), "x").unwrap();
        write_wav(&d.path().join("top.wav"), 10);
        let manifest = d.path().join("manifest.csv");
        let m = manifest.display().to_string();
        let scan_err = |rows: &str| {
            std::fs::write(&manifest, rows).unwrap();
            format!("{:#}", Dataset::scan(d.path()).unwrap_err())
        };
        for (row, reason) in [
            ("asphalt/zzz.wav", "does not exist"),
            ("asphalt/notes.txt", "is not a .wav file"),
            ("top.wav", "not inside a class folder"),
        ] {
            let e = scan_err(&format!("file,speed_kmh\ngravel/g1.wav,10\n{row},12\n"));
            assert!(
                e.contains(&format!("manifest {m} line 3, field `file`: `{row}` "))
                    && e.contains(reason),
                "{row}: {e}"
            );
        }
        // a blank speed: the line and the field, when the speed is needed
        std::fs::write(
            &manifest,
            "file,speed_kmh\ngravel/g1.wav,10\nasphalt/a1.wav, \n",
        )
        .unwrap();
        let ds = Dataset::scan(d.path()).unwrap();
        let a1 = &ds.entries[0];
        assert_eq!(
            (a1.rel.as_str(), a1.manifest_line),
            ("asphalt/a1.wav", Some(3))
        );
        let why = ds.why_no_speed(a1);
        assert!(
            why.contains(&format!("manifest {m} line 3, field `speed_kmh`: blank")),
            "{why}"
        );
        // not listed in the manifest
        std::fs::write(&manifest, "file,speed_kmh\ngravel/g1.wav,10\n").unwrap();
        let ds = Dataset::scan(d.path()).unwrap();
        let why = ds.why_no_speed(&ds.entries[0]);
        assert!(
            why.contains(&m) && why.contains("`asphalt/a1.wav` is not listed"),
            "{why}"
        );
        // no speed_kmh column at all
        std::fs::write(&manifest, "file,recording\ngravel/g1.wav,d1\n").unwrap();
        let ds = Dataset::scan(d.path()).unwrap();
        let why = ds.why_no_speed(&ds.entries[1]);
        assert!(
            why.contains(&format!("manifest {m} has no `speed_kmh` column")),
            "{why}"
        );
        // no manifest
        std::fs::remove_file(&manifest).unwrap();
        let ds = Dataset::scan(d.path()).unwrap();
        let why = ds.why_no_speed(&ds.entries[1]);
        assert!(why.contains("has no manifest.csv"), "{why}");
    }

    #[test]
    fn errors_name_the_path_and_reason() {
        let d = tempfile::tempdir().unwrap();
        let e = format!(
            "{:#}",
            Dataset::scan(&d.path().join("missing")).unwrap_err()
        );
        assert!(e.contains("missing") && e.contains("does not exist"), "{e}");

        let e = format!("{:#}", Dataset::scan(d.path()).unwrap_err());
        assert!(e.contains("has no .wav files"), "{e}");

        write_wav(&d.path().join("asphalt/a.wav"), 10);
        let e = format!("{:#}", Dataset::scan(d.path()).unwrap_err());
        assert!(e.contains("only one class") && e.contains("asphalt"), "{e}");

        std::fs::create_dir_all(d.path().join("gravel")).unwrap();
        let e = format!("{:#}", Dataset::scan(d.path()).unwrap_err());
        assert!(
            e.contains("gravel") && e.contains("holds no .wav files"),
            "{e}"
        );

        write_wav(&d.path().join("gravel/g.wav"), 10);
        std::fs::write(d.path().join("gravel/bad.wav"), b"RIFF....not a wav").unwrap();
        let ds = Dataset::scan(d.path()).unwrap();
        let bad = ds
            .entries
            .iter()
            .find(|e| e.rel == "gravel/bad.wav")
            .unwrap();
        let e = format!("{:#}", read_wav(&bad.path, Channel::Average).unwrap_err());
        assert!(
            e.contains("bad.wav") && e.contains("not a valid WAV"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            read_wav(&d.path().join("gravel/none.wav"), Channel::Average).unwrap_err()
        );
        assert!(e.contains("cannot read") && e.contains("none.wav"), "{e}");
    }
}
