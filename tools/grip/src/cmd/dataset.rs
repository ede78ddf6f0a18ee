//! `grip dataset synth`: writes a labelled synthetic tyre-road dataset; and
//! the reader of road-change recordings (`read_changes`).
//!
//! Layout (also how users bring their own recordings; `grip train` reads it
//! with `crate::dataset::Dataset::scan`):
//!
//! ```text
//! OUT/
//!   asphalt/asphalt_0000.wav ...   one folder per class, 16-bit mono WAV
//!   gravel/ ...                    (the folder name is the class)
//!   manifest.csv                   optional: file,road,speed_kmh,seed,noise,snr_db,duration_s
//! OUT-changes/                     with --changes N (or --changes-out DIR):
//!   change_0000.wav ...            recordings with abrupt road changes
//!   segments.csv                   file,t_start,t_end,road,speed_kmh,seed,noise,snr_db
//! ```
//!
//! The change recordings live in a folder of their own so that a class
//! dataset holds nothing but class folders. With `--recordings-per-class 0`
//! OUT itself is not written (no empty class folders, no manifest without
//! rows), and the summary names the folder the change recordings went to.

use super::Ctx;
use super::snr::{Snr, parse_snr};
use crate::dataset::{FirstRows, column_keys, manifest_file, record_line};
use anyhow::{Context, Result, bail};
use grip_arte::synth::{
    NoiseConfig, ROADS, Segment, SnrScope, SynthConfig, render, render_scoped, road_index,
};
use grip_io::wav;
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    cmd: DatasetCmd,
}

#[derive(clap::Subcommand)]
enum DatasetCmd {
    /// Synthesise a labelled dataset of tyre-road recordings (16-bit mono WAV).
    Synth(SynthArgs),
    /// Run the streaming estimator over road-change recordings: detection
    /// delay (p50/p95/max) and decision accuracy.
    Delay(DelayArgs),
    /// Merge class datasets into a new one (files hard-linked or copied,
    /// manifests merged; each source's files under a folder named after it).
    Merge(super::dataset_merge::MergeArgs),
}

#[derive(clap::Args)]
struct DelayArgs {
    /// Model file (from `grip train`).
    #[arg(long)]
    model: PathBuf,
    /// Folder of change recordings (segments.csv + WAVs, from `grip dataset synth --changes`), or a one-road dataset (manifest.csv: each recording one segment).
    dir: PathBuf,
    /// Time between decisions (s).
    #[arg(long, default_value_t = 0.025)]
    hop: f64,
    /// HMM: probability of staying on the same road per hop, within
    /// (0, 1); 0 disables smoothing.
    #[arg(long, default_value_t = 0.9)]
    stay: f64,
    /// HMM: floor on a frame's class probability.
    #[arg(long, default_value_t = 0.01)]
    floor: f64,
    /// Also print the confusion matrices of the decisions inside one segment.
    #[arg(long)]
    confusion: bool,
    /// A detection counts once the new road persists this long (s).
    #[arg(long, default_value_t = 0.2)]
    hold: f64,
    /// Confidence from which a controller uses a decision; default: the
    /// controllers' `arte.min_confidence` in `<config-dir>/controllers.toml`.
    #[arg(long)]
    min_confidence: Option<f64>,
    #[command(flatten)]
    channel: crate::dataset::ChannelArg,
}

#[derive(clap::Args)]
struct SynthArgs {
    /// Output folder (created). A file it would write that is there
    /// already (manifest.csv, a recording; segments.csv and the change
    /// recordings in --changes-out) is refused, before anything is
    /// rendered, unless `--force` is given.
    #[arg(long)]
    out: PathBuf,
    /// Overwrite the files of an earlier dataset with the same names.
    #[arg(long)]
    force: bool,
    /// Base seed; every recording's seed is derived from it, its class and its index.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Recordings per road class.
    #[arg(long, default_value_t = 20)]
    recordings_per_class: usize,
    /// Duration of each recording (s).
    #[arg(long, default_value_t = 10.0)]
    duration: f64,
    /// Speed range in km/h, "A-B" (uniform per recording) or a single value.
    #[arg(long, default_value = "10-30")]
    speeds: String,
    /// How speeds are drawn within --speeds: "uniform" in km/h, or "log"
    /// (uniform in ln v: as many recordings per octave of speed, since
    /// frequencies and levels of tyre-road sound go with ln v).
    #[arg(long, default_value = "uniform", value_parser = ["uniform", "log"])]
    speed_scale: String,
    /// Noise sources to mix in: "none", a comma list of "rain", "car", or
    /// "random" (each recording draws one of none, rain, car, rain+car).
    #[arg(long, default_value = "none")]
    noise: String,
    /// Signal-to-noise ratio over each recording (dB, -30..=80) when noise is
    /// mixed in: a value, "A..B" for a uniform draw per recording, or "off"
    /// (no noise: the same as --noise none).
    #[arg(long, default_value = "10", allow_hyphen_values = true, value_parser = parse_snr)]
    snr_db: Snr,
    /// Also write this many recordings with abrupt road changes (into --changes-out).
    #[arg(long, default_value_t = 0)]
    changes: usize,
    /// Folder for the change recordings (default: OUT-changes next to OUT).
    #[arg(long)]
    changes_out: Option<PathBuf>,
    /// Segment length range (s) of the change recordings, "A-B".
    #[arg(long, default_value = "1-3")]
    segment: String,
    /// Change recordings: the SNR holds for every road segment ("segment",
    /// as in the one-road recordings) or over the whole recording
    /// ("recording": one noise level, so quiet roads such as snow sit below it)
    /// or against a 1 s running estimate of the road power ("running": as in
    /// the loop, so a quiet road right after a loud one sits below it for
    /// about a second).
    #[arg(long, default_value = "segment", value_parser = ["segment", "recording", "running"])]
    snr_scope: String,
    /// Road classes, comma separated (default: all six).
    #[arg(long)]
    roads: Option<String>,
    /// Sample rate (Hz).
    #[arg(long, default_value_t = 44_100)]
    sample_rate: u32,
}

/// One row of `manifest.csv`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ManifestRow {
    /// Path relative to the dataset folder.
    pub file: String,
    /// Class name.
    pub road: String,
    /// Vehicle speed (km/h), if known.
    pub speed_kmh: Option<f64>,
    /// Synthesis seed, if synthetic.
    pub seed: Option<u64>,
    /// Noise sources mixed in ("none", "rain", "car", "rain+car").
    pub noise: Option<String>,
    /// SNR of the mixed noise (dB).
    pub snr_db: Option<f64>,
    /// Duration (s).
    pub duration_s: Option<f64>,
}

/// One row of `changes/segments.csv`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SegmentRow {
    /// Path relative to the `changes` folder.
    pub file: String,
    /// Segment start (s).
    pub t_start: f64,
    /// Segment end (s).
    pub t_end: f64,
    /// Class name.
    pub road: String,
    /// Speed (km/h).
    pub speed_kmh: Option<f64>,
    /// Recording seed.
    pub seed: Option<u64>,
    /// Noise.
    pub noise: Option<String>,
    /// SNR (dB).
    pub snr_db: Option<f64>,
}

/// A recording with road changes and its ground truth.
#[derive(Clone, Debug)]
pub struct ChangeRecording {
    /// Full path.
    pub path: PathBuf,
    /// (t_start, t_end, class index, vehicle speed in km/h if given) in
    /// time order.
    pub segments: Vec<(f64, f64, usize, Option<f64>)>,
}

impl ChangeRecording {
    /// The vehicle speed (km/h) at time `t` (s): that of the last segment
    /// starting at or before `t`.
    pub fn speed_at(&self, t: f64) -> Option<f64> {
        self.segments
            .iter()
            .take_while(|s| s.0 <= t + 1e-9)
            .last()
            .or(self.segments.first())
            .and_then(|s| s.3)
    }
}

/// One row of a one-road dataset's `manifest.csv`, as far as
/// [`read_changes`] needs it.
#[derive(Clone, Debug, Deserialize)]
struct OneRoadRow {
    file: String,
    road: String,
    speed_kmh: Option<f64>,
    duration_s: Option<f64>,
}

/// Reads a folder of road-change recordings (`segments.csv` plus the WAV
/// files it names). `classes` maps road names to class indices (e.g. a
/// model's classes); a road not in it is an error naming the file, the
/// record and the field. A one-road dataset (`manifest.csv`, no
/// `segments.csv`, as `grip dataset synth` without `--changes` writes) is
/// read as one segment per recording, its whole length (`duration_s`, which
/// must be the file's length within one frame, or, left out, the length
/// its WAV header gives; each file listed once): the
/// stream's decisions on it are then its accuracy on roads that do not
/// change. Column names are matched in any case (`crate::dataset::column_key`).
///
/// The segments of each file of `segments.csv` must be in time order, must
/// not overlap, and must end by the file's length (from its WAV header)
/// plus one frame (`frame_s`, the model's); otherwise the error names the
/// file, the csv line and the reason (times in ms, overlapping labels).
/// Gaps between segments are allowed: audio there is unjudged.
pub fn read_changes(dir: &Path, classes: &[String], frame_s: f64) -> Result<Vec<ChangeRecording>> {
    let truth = truth_file(dir);
    if truth.ends_with("manifest.csv") {
        return read_one_road(dir, &truth, classes, frame_s);
    }
    if !truth.is_file() {
        bail!(
            "{} does not exist (expected a folder written by `grip dataset synth --changes N`, or a one-road dataset with a manifest.csv){}",
            truth.display(),
            changes_sibling_hint(dir)
        );
    }
    let text = std::fs::read(&truth).with_context(|| format!("opening {}", truth.display()))?;
    let mut rd = csv::Reader::from_reader(text.as_slice());
    let mut by_file: Vec<ChangeRecording> = Vec::new();
    // per file (same order as `by_file`): its length (s) and the csv line
    // of its last segment
    let mut checked: Vec<(f64, usize)> = Vec::new();
    let headers = column_keys(
        rd.headers()
            .with_context(|| format!("reading {}", truth.display()))?,
    );
    for (k, rec) in rd.records().enumerate() {
        let i = k + 1;
        let rec = rec.with_context(|| format!("{}: record {i}", truth.display()))?;
        let line = record_line(&text, &rec, k);
        let at = || format!("{}: record {i} (line {line})", truth.display());
        let row: SegmentRow = rec.deserialize(Some(&headers)).with_context(at)?;
        let (class, p) = checked_row(dir, &at, &row.road, &row.file, row.speed_kmh, classes)?;
        if !(row.t_start.is_finite() && row.t_start >= 0.0 && row.t_end > row.t_start) {
            bail!(
                "{}: fields `t_start`/`t_end`: need 0 <= t_start < t_end",
                at()
            );
        }
        let k = match by_file.iter().position(|c| c.path == p) {
            Some(k) => k,
            None => {
                let len = wav_duration_s(&p).with_context(at)?;
                by_file.push(ChangeRecording {
                    path: p,
                    segments: Vec::new(),
                });
                checked.push((len, line));
                by_file.len() - 1
            }
        };
        let (len, prev_line) = checked[k];
        let c = &mut by_file[k];
        if let Some(last) = c.segments.last() {
            if row.t_start < last.0 {
                bail!(
                    "{}: file {}: segment {} - {} s starts before the one on line {prev_line} ({} - {} s): the segments of a file must be in time order",
                    at(),
                    row.file,
                    row.t_start,
                    row.t_end,
                    last.0,
                    last.1
                );
            }
            if row.t_start < last.1 - 1e-9 {
                bail!(
                    "{}: file {}: segment {} - {} s overlaps the one on line {prev_line} ({} - {} s): a time can have only one road",
                    at(),
                    row.file,
                    row.t_start,
                    row.t_end,
                    last.0,
                    last.1
                );
            }
        }
        if row.t_end > len + frame_s.max(0.0) + 1e-9 {
            bail!(
                "{}: file {}: segment {} - {} s ends past the end of the recording: the file is {len} s long: are the times in seconds?",
                at(),
                row.file,
                row.t_start,
                row.t_end
            );
        }
        c.segments
            .push((row.t_start, row.t_end, class, row.speed_kmh));
        checked[k].1 = line;
    }
    if by_file.is_empty() {
        bail!("{} lists no segments", truth.display());
    }
    Ok(by_file)
}

/// Length (s) of a WAV file from its header: the `data` chunk's size over
/// the `fmt ` chunk's block size and rate (the rest of the file when the
/// size is unset or larger, as a stream that was cut off writes).
fn wav_duration_s(path: &Path) -> Result<f64> {
    Ok(grip_io::wav::header(path)?.duration_s())
}

/// The file that holds a recordings folder's ground truth for
/// [`read_changes`]: `segments.csv`, or a one-road dataset's `manifest.csv`
/// when there is no `segments.csv` (the path of `segments.csv` when there is
/// neither).
pub fn truth_file(dir: &Path) -> PathBuf {
    let seg = dir.join("segments.csv");
    let manifest = dir.join("manifest.csv");
    if !seg.is_file() && manifest.is_file() {
        manifest
    } else {
        seg
    }
}

/// What both ground-truth files say of a recording, checked: its road (a
/// class index), its file (which must exist) and its speed (km/h, if
/// given). `at` names the file and record for the error.
fn checked_row(
    dir: &Path,
    at: &dyn Fn() -> String,
    road: &str,
    file: &str,
    speed_kmh: Option<f64>,
    classes: &[String],
) -> Result<(usize, PathBuf)> {
    let Some(class) = classes.iter().position(|c| c == road) else {
        bail!(
            "{}: field `road`: `{road}` is not one of the classes ({})",
            at(),
            classes.join(", ")
        );
    };
    let p = dir.join(file);
    if !p.is_file() {
        bail!("{}: field `file`: {} does not exist", at(), p.display());
    }
    if let Some(v) = speed_kmh
        && !(v.is_finite() && v >= 0.0)
    {
        bail!("{}: field `speed_kmh`: {v} is not a speed in km/h", at());
    }
    Ok((class, p))
}

/// A one-road dataset as change recordings of one segment each, from 0 to
/// its `duration_s` (left out: the WAV's own length). A file listed twice is an error naming both lines; a
/// `duration_s` that differs from the WAV's own length (its header) by
/// more than one frame (`frame_s`) is an error naming the file, the line
/// and both durations.
fn read_one_road(
    dir: &Path,
    manifest: &Path,
    classes: &[String],
    frame_s: f64,
) -> Result<Vec<ChangeRecording>> {
    let text =
        std::fs::read(manifest).with_context(|| format!("opening {}", manifest.display()))?;
    let mut rd = csv::Reader::from_reader(text.as_slice());
    let headers = column_keys(
        rd.headers()
            .with_context(|| format!("reading {}", manifest.display()))?,
    );
    let mut rows = FirstRows::default();
    let mut out = Vec::new();
    for (k, rec) in rd.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: record {}", manifest.display(), k + 1))?;
        let line = record_line(&text, &rec, k);
        let at = || format!("{}: record {} (line {line})", manifest.display(), k + 1);
        let row: OneRoadRow = rec.deserialize(Some(&headers)).with_context(at)?;
        let (class, p) = checked_row(dir, &at, &row.road, &row.file, row.speed_kmh, classes)?;
        rows.first(manifest, &manifest_file(&row.file, dir, None), line)?;
        let d = one_road_duration(&at, &row, &p, frame_s)?;
        out.push(ChangeRecording {
            path: p,
            segments: vec![(0.0, d, class, row.speed_kmh)],
        });
    }
    if out.is_empty() {
        bail!(
            "{} lists no recordings{}",
            manifest.display(),
            changes_sibling_hint(dir)
        );
    }
    Ok(out)
}

/// The `duration_s` of a one-road manifest row whose file is `path`: the
/// WAV's own length (its header) when the row leaves it out; when given,
/// checked: a duration > 0 within one frame (`frame_s`) of that length.
/// `at` names the manifest and line.
fn one_road_duration(
    at: &dyn Fn() -> String,
    row: &OneRoadRow,
    path: &Path,
    frame_s: f64,
) -> Result<f64> {
    let len = wav_duration_s(path).with_context(at)?;
    let Some(d) = row.duration_s else {
        // the manifest's column is optional: the recording is one segment
        // of its whole length
        return Ok(len);
    };
    if !(d.is_finite() && d > 0.0) {
        bail!(
            "{}: field `duration_s`: needs a duration in seconds > 0 to read the recording as one segment (got {d}; or leave it out: the WAV's own length)",
            at()
        );
    }
    if (d - len).abs() > frame_s.max(0.0) + 1e-9 {
        bail!(
            "{}: file {}: duration_s {d} s, but the recording is {len} s long (more than one {frame_s} s frame apart): correct duration_s",
            at(),
            row.file
        );
    }
    Ok(d)
}

fn parse_range(s: &str, what: &str) -> Result<(f64, f64)> {
    let parse = |t: &str| {
        t.trim()
            .parse::<f64>()
            .with_context(|| format!("--{what}: `{t}` is not a number"))
    };
    let (a, b) = match s.split_once('-') {
        Some((a, b)) => (parse(a)?, parse(b)?),
        None => {
            let v = parse(s)?;
            (v, v)
        }
    };
    if !(a.is_finite() && b.is_finite() && a >= 0.0 && b >= a) {
        bail!("--{what}: `{s}` is not a range A-B with 0 <= A <= B");
    }
    Ok((a, b))
}

/// The SNR range (dB) a recording's level is drawn from; `off` is allowed
/// only without noise (its level is then never used).
fn snr_range(snr: Snr, noise: &str) -> Result<(f64, f64)> {
    Ok(match snr {
        Snr::Db(x) => (x, x),
        Snr::Range(a, b) => (a, b),
        Snr::Off if noise.trim() == "none" => (0.0, 0.0),
        Snr::Off => {
            bail!("--snr-db off means no noise, but --noise is `{noise}`; use --noise none")
        }
    })
}

fn parse_noise(s: &str, snr_db: f64) -> Result<(Option<NoiseConfig>, String)> {
    let mut rain = false;
    let mut car = false;
    for t in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        match t {
            "none" => {}
            "rain" => rain = true,
            "car" => car = true,
            other => bail!("--noise: `{other}` is not one of none, rain, car"),
        }
    }
    let label = match (rain, car) {
        (false, false) => "none",
        (true, false) => "rain",
        (false, true) => "car",
        (true, true) => "rain+car",
    };
    Ok((
        (rain || car).then_some(NoiseConfig { rain, car, snr_db }),
        label.to_string(),
    ))
}

/// SplitMix64 of the base seed, a stream id and an index: independent
/// per-recording seeds.
fn derive_seed(base: u64, stream: u64, index: u64) -> u64 {
    let mut z = base
        ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A uniform draw in [0, 1) from a derived seed.
fn unit(base: u64, stream: u64, index: u64) -> f64 {
    (derive_seed(base, stream, index) >> 11) as f64 / (1u64 << 53) as f64
}

/// Counter-based uniform draws: `next()` gives the next value of the stream.
struct Draws {
    base: u64,
    stream: u64,
    i: u64,
}

impl Draws {
    fn next(&mut self) -> f64 {
        self.i += 1;
        unit(self.base, self.stream, self.i)
    }
    fn index(&mut self, n: usize) -> usize {
        ((self.next() * n as f64) as usize).min(n - 1)
    }
}

/// The noise of one recording: the fixed choice, or a random one; the SNR
/// drawn from its range.
fn recording_noise(
    base: &SynthConfig,
    label: &str,
    random: bool,
    snr: (f64, f64),
    rng: &mut Draws,
) -> (SynthConfig, String) {
    let snr_db = snr.0 + (snr.1 - snr.0) * rng.next();
    let (noise, label) = if random {
        match rng.index(4) {
            0 => (None, "none".to_string()),
            1 => (
                Some(NoiseConfig {
                    rain: true,
                    car: false,
                    snr_db,
                }),
                "rain".to_string(),
            ),
            2 => (
                Some(NoiseConfig {
                    rain: false,
                    car: true,
                    snr_db,
                }),
                "car".to_string(),
            ),
            _ => (
                Some(NoiseConfig {
                    rain: true,
                    car: true,
                    snr_db,
                }),
                "rain+car".to_string(),
            ),
        }
    } else {
        (
            base.noise.clone().map(|n| NoiseConfig { snr_db, ..n }),
            label.to_string(),
        )
    };
    (
        SynthConfig {
            sample_rate: base.sample_rate,
            noise,
        },
        label,
    )
}

fn synth(a: SynthArgs) -> Result<()> {
    let (v0, v1) = parse_range(&a.speeds, "speeds")?;
    if v1 > 250.0 {
        bail!("--speeds: {v1} km/h is above 250");
    }
    let log_speeds = a.speed_scale == "log";
    if log_speeds && v0 <= 0.0 {
        bail!("--speeds: a log speed scale needs speeds above 0 km/h, got {v0}");
    }
    let draw_kmh = |u: f64| {
        if log_speeds {
            v0 * (v1 / v0).powf(u)
        } else {
            v0 + (v1 - v0) * u
        }
    };
    let (s0, s1) = parse_range(&a.segment, "segment")?;
    // a segment shorter than an acoustic frame is no road segment, and
    // 1e-9 s made a change recording of 10^9 segments
    if s0 < MIN_SEGMENT_S {
        bail!("--segment: segments must be at least {MIN_SEGMENT_S} s long (got {s0} s)");
    }
    // counts a machine can write: 10^11 recordings asked for 2.4 TB of
    // file names before the first was written
    for (flag, n) in [
        ("--recordings-per-class", a.recordings_per_class),
        ("--changes", a.changes),
    ] {
        if n > MAX_RECORDINGS {
            bail!("{flag} {n}: at most {MAX_RECORDINGS}");
        }
    }
    if !(a.duration > 0.0 && a.duration <= 3600.0) {
        bail!("--duration: {} s is outside (0, 3600]", a.duration);
    }
    let (snr0, snr1) = snr_range(a.snr_db, &a.noise)?;
    let random_noise = a.noise.trim() == "random";
    let (noise, noise_label) = if random_noise {
        (None, String::new())
    } else {
        parse_noise(&a.noise, snr0)?
    };
    let roads: Vec<usize> = match &a.roads {
        None => (0..ROADS.len()).collect(),
        Some(list) => list
            .split(',')
            .map(|r| {
                road_index(r.trim()).with_context(|| {
                    format!("--roads: `{}` is not one of {}", r.trim(), ROADS.join(", "))
                })
            })
            .collect::<Result<_>>()?,
    };
    if roads.len() < 2 && a.changes > 0 {
        bail!("--changes needs at least two roads");
    }
    let base_cfg = SynthConfig {
        sample_rate: a.sample_rate,
        noise,
    };
    base_cfg.validate().context("synth config")?;
    if a.recordings_per_class == 0 && a.changes == 0 {
        bail!("nothing to write: --recordings-per-class 0 and no --changes");
    }
    // the class dataset (folders and manifest) only when it has recordings:
    // empty class folders and a manifest without rows are no dataset
    let classes = a.recordings_per_class > 0;
    let cdir = a.changes_out.clone().unwrap_or_else(|| changes_dir(&a.out));
    check_synth_outputs(&a, &roads, &cdir)?;
    if classes {
        std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    }
    let total = (roads.len() * a.recordings_per_class + a.changes) as u64;
    let pb = ProgressBar::new(total);
    pb.set_style(ProgressStyle::with_template(
        "{bar:40} {pos}/{len} recordings, {elapsed} elapsed, eta {eta} {msg}",
    )?);
    let mut rng = Draws {
        base: a.seed,
        stream: 0xDA7A,
        i: 0,
    };
    let mut manifest = Vec::new();
    for &r in roads.iter().filter(|_| classes) {
        let name = ROADS[r];
        let sub = a.out.join(name);
        std::fs::create_dir_all(&sub).with_context(|| format!("creating {}", sub.display()))?;
        for i in 0..a.recordings_per_class {
            let seed = derive_seed(a.seed, r as u64 + 1, i as u64);
            let kmh = draw_kmh(rng.next());
            let (cfg, noise_label) = recording_noise(
                &base_cfg,
                &noise_label,
                random_noise,
                (snr0, snr1),
                &mut rng,
            );
            let snr = cfg.noise.as_ref().map(|n| n.snr_db);
            let x = render(
                &cfg,
                seed,
                &[Segment {
                    road: r,
                    speed_mps: kmh / 3.6,
                    duration_s: a.duration,
                }],
            )?;
            let file = format!("{name}/{name}_{i:04}.wav");
            wav::write_mono_i16(&a.out.join(&file), a.sample_rate, &x)?;
            manifest.push(ManifestRow {
                file,
                road: name.to_string(),
                speed_kmh: Some((kmh * 1000.0).round() / 1000.0),
                seed: Some(seed),
                noise: Some(noise_label.clone()),
                snr_db: snr,
                duration_s: Some(a.duration),
            });
            pb.inc(1);
        }
    }
    if classes {
        let mpath = a.out.join("manifest.csv");
        let mut w = csv::Writer::from_path(&mpath)
            .with_context(|| format!("creating {}", mpath.display()))?;
        for row in &manifest {
            w.serialize(row)?;
        }
        w.flush()?;
    }
    if a.changes > 0 {
        std::fs::create_dir_all(&cdir).with_context(|| format!("creating {}", cdir.display()))?;
        let spath = cdir.join("segments.csv");
        let mut sw = csv::Writer::from_path(&spath)
            .with_context(|| format!("creating {}", spath.display()))?;
        for i in 0..a.changes {
            let seed = derive_seed(a.seed, 0xC4A6, i as u64);
            let kmh = draw_kmh(rng.next());
            let (cfg, noise_label) = recording_noise(
                &base_cfg,
                &noise_label,
                random_noise,
                (snr0, snr1),
                &mut rng,
            );
            let snr = cfg.noise.as_ref().map(|n| n.snr_db);
            let mut segs = Vec::new();
            let mut t = 0.0;
            let mut prev = usize::MAX;
            while t < a.duration - 1e-9 {
                let mut r = roads[rng.index(roads.len())];
                while r == prev {
                    r = roads[rng.index(roads.len())];
                }
                let d = (s0 + (s1 - s0) * rng.next()).min(a.duration - t);
                segs.push(Segment {
                    road: r,
                    speed_mps: kmh / 3.6,
                    duration_s: d,
                });
                prev = r;
                t += d;
            }
            let scope = match a.snr_scope.as_str() {
                "recording" => SnrScope::Recording,
                "running" => SnrScope::Running,
                _ => SnrScope::Segment,
            };
            let x = render_scoped(&cfg, seed, &segs, scope)?;
            let file = format!("change_{i:04}.wav");
            wav::write_mono_i16(&cdir.join(&file), a.sample_rate, &x)?;
            let mut t = 0.0;
            for s in &segs {
                // Segment boundaries at whole samples, as rendered.
                let t1 = t
                    + (s.duration_s * f64::from(a.sample_rate)).round() / f64::from(a.sample_rate);
                sw.serialize(SegmentRow {
                    file: file.clone(),
                    t_start: t,
                    t_end: t1,
                    road: ROADS[s.road].to_string(),
                    speed_kmh: Some((kmh * 1000.0).round() / 1000.0),
                    seed: Some(seed),
                    noise: Some(noise_label.clone()),
                    snr_db: snr,
                })?;
                t = t1;
            }
            pb.inc(1);
        }
        sw.flush()?;
    }
    pb.finish_with_message("done");
    eprintln!("{}", synth_summary(&a, manifest.len(), roads.len(), &cdir));
    Ok(())
}

/// The folders and files `grip dataset synth` would write: refused,
/// naming them, when a folder is a file, or when files are there already
/// and not `--force` (an earlier dataset's manifest replaced by a shorter
/// one would leave recordings no manifest lists).
fn check_synth_outputs(a: &SynthArgs, roads: &[usize], cdir: &Path) -> Result<()> {
    let mut files = Vec::new();
    let mut dirs = Vec::new();
    if a.recordings_per_class > 0 {
        dirs.push(("--out", a.out.clone()));
        files.push(a.out.join("manifest.csv"));
        for &r in roads {
            let name = ROADS[r];
            dirs.push(("--out", a.out.join(name)));
            files.extend(
                (0..a.recordings_per_class)
                    .map(|i| a.out.join(format!("{name}/{name}_{i:04}.wav"))),
            );
        }
    }
    if a.changes > 0 {
        let flag = if a.changes_out.is_some() {
            "--changes-out"
        } else {
            "--changes (OUT-changes)"
        };
        dirs.push((flag, cdir.to_path_buf()));
        files.push(cdir.join("segments.csv"));
        files.extend((0..a.changes).map(|i| cdir.join(format!("change_{i:04}.wav"))));
    }
    for (flag, d) in &dirs {
        if std::fs::symlink_metadata(d).is_ok() && !d.is_dir() {
            bail!("{flag}: {} is a file, not a folder", d.display());
        }
    }
    let there: Vec<&PathBuf> = files
        .iter()
        .filter(|f| std::fs::symlink_metadata(f).is_ok())
        .collect();
    if let Some(first) = there.first()
        && !a.force
    {
        bail!(
            "{} of the {} files this would write are there already (the first: {}); pass --force to overwrite them, or name another --out{}",
            there.len(),
            files.len(),
            first.display(),
            if a.changes > 0 {
                " / --changes-out"
            } else {
                ""
            }
        );
    }
    Ok(())
}

/// Where the change recordings of `grip dataset synth --out OUT` go
/// without `--changes-out`: `OUT-changes`, next to `OUT`.
pub fn changes_dir(out: &Path) -> PathBuf {
    let mut p = out.to_path_buf().into_os_string();
    p.push("-changes");
    PathBuf::from(p)
}

/// What `grip dataset synth` wrote, naming each folder it wrote to.
fn synth_summary(a: &SynthArgs, n: usize, n_roads: usize, cdir: &Path) -> String {
    let classes = format!(
        "{n} recordings ({} per class, {n_roads} roads) to {}",
        a.recordings_per_class,
        a.out.display()
    );
    let changes = format!("{} change recordings to {}", a.changes, cdir.display());
    match (a.recordings_per_class > 0, a.changes > 0) {
        (true, true) => format!("wrote {classes} and {changes}"),
        (true, false) => format!("wrote {classes}"),
        _ => format!(
            "wrote {changes} (no class recordings: --recordings-per-class 0, so nothing in {})",
            a.out.display()
        ),
    }
}

/// A hint for a folder that holds no recordings when the change
/// recordings of `grip dataset synth --out DIR --changes N` lie next to it
/// in `DIR-changes`; empty otherwise.
pub fn changes_sibling_hint(dir: &Path) -> String {
    let sib = changes_dir(dir);
    if sib.join("segments.csv").is_file() {
        format!(
            "; the change recordings of `grip dataset synth --out {} --changes N` are in {}: pass that folder",
            dir.display(),
            sib.display()
        )
    } else {
        String::new()
    }
}

/// `grip dataset synth`: the shortest change-recording segment, s (an
/// acoustic frame is 0.1 s).
const MIN_SEGMENT_S: f64 = 0.01;
/// `grip dataset synth`: the most recordings per class, and change
/// recordings (a million 10 s recordings are about a terabyte).
const MAX_RECORDINGS: usize = 1_000_000;

/// An HMM stay flag (`grip dataset delay --stay`, `grip calibrate
/// --calib-stay`): 0 (no smoothing, as their help says), or the HMM's
/// probability of staying on the same road per hop, within (0, 1) as the
/// stream estimator takes it. Checked before the model and the recordings
/// are read; the stream's own error named neither the flag nor 0
/// (`smoothing.stay: 1 is not in (0, 1)`, while 0 ran).
pub(crate) fn check_stay(flag: &str, stay: f64) -> Result<()> {
    if stay == 0.0 || (stay > 0.0 && stay < 1.0) {
        return Ok(());
    }
    bail!(
        "{flag} {stay}: must be 0 (no smoothing) or within (0, 1) (the probability that the stream's HMM stays on the same road from one hop to the next)"
    )
}

fn delay(a: DelayArgs, config_dir: &Path) -> Result<()> {
    use grip_arte::model::{Model, Predictor};
    use grip_arte::stream::{Smoothing, StreamConfig, StreamEstimator};
    use grip_arte::stream_eval::ChangeEval;
    check_stay("--stay", a.stay)?;
    let bytes = std::fs::read(&a.model)
        .with_context(|| format!("reading model file {}", a.model.display()))?;
    let model =
        Model::from_bytes(&bytes).with_context(|| format!("model file {}", a.model.display()))?;
    let fcfg = model.feature_config().clone();
    let classes = model.classes().to_vec();
    let recs = read_changes(&a.dir, &classes, fcfg.frame_s)?;
    let smoothing = if a.stay == 0.0 {
        Smoothing::None
    } else {
        Smoothing::Hmm {
            stay: a.stay,
            floor: a.floor,
        }
    };
    let scfg = StreamConfig {
        hop_s: a.hop,
        smoothing,
    };
    let calibration = model.calibration().map(|c| c.map.describe());
    // measured on the recordings the model was fitted on: said, since its
    // figures are then in-sample (a newcomer measured on the calibration
    // set and read its ECE as held out)
    for (known, what) in [
        (
            model.calibration().map_or(&[][..], |c| &c.files[..]),
            "its confidence calibration was fitted on (grip calibrate / grip train --calib-data)",
        ),
        (
            &model.meta.training_files[..],
            "its classifier was trained on (grip train --data)",
        ),
    ] {
        if let Some((_, f)) = crate::dataset::first_known_file(std::slice::from_ref(&a.dir), known)
        {
            println!(
                "warning: {} holds {}, one of the recordings {what} (same content): the figures below are in-sample there, not held out; measure on recordings the model has not seen",
                a.dir.display(),
                f.display()
            );
        }
    }
    let mut est = StreamEstimator::new(Predictor::new(model), &fcfg, &scfg)?;
    match &calibration {
        None => println!(
            "model {} has no confidence calibration (format v1): the confidence is the raw smoothed posterior",
            a.model.display()
        ),
        Some(c) if est.calibration_mismatch() => println!(
            "confidence calibration: {c}, but fitted for other stream settings than hop {} s, {}: \
             the confidence is not calibrated for these",
            a.hop,
            super::calibrate::smoothing_text(&smoothing)
        ),
        Some(c) => println!("confidence calibration: {c}"),
    }
    let cfg_dir = grip_config::ConfigDir::new(config_dir);
    // The gate a controller applies: the configured one, or --min-confidence
    // checked by the same rule.
    let mut gate = grip_config::load_controllers(cfg_dir.file("controllers.toml"))
        .context("reading the controllers' configuration (--config-dir)")?
        .arte;
    if let Some(m) = a.min_confidence {
        gate.min_confidence = m;
        gate.validate()
            .map_err(|e| anyhow::anyhow!("--min-confidence: {e}"))?;
    }
    let min_confidence = gate.min_confidence;
    // Peak friction of each class from roads.toml, to tell optimistic
    // mistakes from cautious ones (only if every class is a road there).
    let roads = cfg_dir
        .roads()
        .with_context(|| "reading the road catalogue (--config-dir)")?;
    let mu_peak: Vec<f64> = classes
        .iter()
        .map(|c| roads.get(c).map(|r| r.mu_peak()))
        .collect::<Option<_>>()
        .unwrap_or_default();
    let mut ev = ChangeEval::new(classes.clone(), mu_peak, min_confidence, a.hold, a.hop);
    let pb = ProgressBar::new(recs.len() as u64);
    let mut excluded = crate::dataset::Excluded::default();
    let channel = a.channel.get();
    for r in &recs {
        let (dec, duration_s) = pb
            .suspend(|| {
                super::calibrate::stream_recording(
                    &mut est,
                    r,
                    fcfg.sample_rate,
                    &a.dir,
                    channel,
                    &mut excluded,
                )
            })
            .with_context(|| format!("model {}", a.model.display()))?;
        ev.add_recording(&dec, &r.segments, duration_s);
        pb.inc(1);
    }
    pb.finish_and_clear();
    super::calibrate::all_refused(&a.dir, &excluded)?;
    if let Some(n) = excluded.summary("block") {
        println!("{n}; their blocks give no decision and count in no figure below");
    }
    print_delay_report(&a, &ev, smoothing, recs.len(), min_confidence);
    Ok(())
}

/// Prints what `grip dataset delay` measured.
fn print_delay_report(
    a: &DelayArgs,
    ev: &grip_arte::stream_eval::ChangeEval,
    smoothing: grip_arte::stream::Smoothing,
    n_recordings: usize,
    min_confidence: f64,
) {
    use grip_arte::stream::percentile;
    use grip_arte::stream_eval::{CONFIDENCE_BINS, bootstrap_percentile};
    let ms = |v: Option<f64>| match v {
        None => "-".to_string(),
        Some(v) if v.is_finite() => format!("{:.0} ms", v * 1000.0),
        Some(_) => "missed".to_string(),
    };
    let (n_changes, missed) = (ev.n_changes, ev.missed);
    // Percentiles over all changes: a missed change counts as longer than any.
    let all = ev.all_delays();
    println!(
        "{} recordings, {n_changes} road changes, hop {} s, {}, hold {} s",
        n_recordings,
        a.hop,
        super::calibrate::smoothing_text(&smoothing),
        a.hold
    );
    if ev.unjudged > 0 {
        println!(
            "{} decisions unjudged (their time lies in a gap between segments or past the last one: \
             no road is labelled there); they count in no accuracy or calibration figure",
            ev.unjudged
        );
    }
    println!(
        "detection delay over all {n_changes} changes (a missed one counts as longer than any): \
         p50 {}, p95 {}; max of the detected {}; missed {missed}",
        ms(percentile(&all, 50.0)),
        ms(percentile(&all, 95.0)),
        ms(percentile(&ev.delays, 100.0))
    );
    if let Some((lo, hi)) = bootstrap_percentile(&ev.per_recording, 95.0, 2000, 1) {
        println!(
            "p95 95 % interval (bootstrap over recordings, 2000 resamples): {} - {}",
            ms(Some(lo)),
            ms(Some(hi))
        );
    }
    if let Some((inside, near)) = ev.false_switches_per_minute() {
        println!(
            "false switches (the smoothed decision changes to a road that is not the true one): \
             {:.2} per minute of audio inside segments ({}), \
             {:.2} per minute within {} s after a true change ({})",
            inside, ev.false_inside, near, a.hold, ev.false_near
        );
    }
    if let (Some(w100), Some(w150), Some(w200)) = (
        ev.percent_within(0.1),
        ev.percent_within(0.15),
        ev.percent_within(0.2),
    ) {
        println!(
            "detected within 100 ms: {w100:.1} %, within 150 ms: {w150:.1} %, within 200 ms: {w200:.1} % of the changes"
        );
    }
    let used = &ev.used;
    if used.decisions > 0 {
        let pc = |n: usize, of: usize| 100.0 * n as f64 / of.max(1) as f64;
        let wrong = used.used_wrong();
        println!(
            "what a controller with min_confidence {} is given: {:.1} % of the {} decisions \
             (the rest falls back to no ARTE); {:.2} % of those name the true road at the decision's time; \
             a wrong road is in use {:.2} % of the time ({:.2} % within {} s after a true change, \
             {:.2} % elsewhere)",
            min_confidence,
            pc(used.used, used.decisions),
            used.decisions,
            pc(used.used_right, used.used),
            pc(wrong, used.decisions),
            pc(used.used_wrong_near, used.decisions),
            a.hold,
            pc(wrong - used.used_wrong_near, used.decisions),
        );
        let bins: Vec<String> = CONFIDENCE_BINS
            .iter()
            .zip(used.bins)
            .enumerate()
            .filter(|(_, (_, (n, _)))| *n > 0)
            .map(|(i, (lo, (n, right)))| {
                let hi = CONFIDENCE_BINS
                    .get(i + 1)
                    .map_or("1".to_string(), |h| format!("{h}"));
                format!(
                    "{lo}-{hi}: {:.1} % of decisions, {:.2} % right",
                    pc(n, used.decisions),
                    pc(right, n)
                )
            })
            .collect();
        println!(
            "calibration (confidence bin: share, accuracy): {}",
            bins.join("; ")
        );
        println!(
            "confidence against the true road at each decision's time: {}",
            super::calibrate::summary_line(&ev.confidence, &ev.right)
        );
        println!(
            "reliability ({} equal-width bins):\n\n{}",
            super::calibrate::ECE_BINS,
            super::calibrate::reliability(&ev.confidence, &ev.right).to_markdown()
        );
        if ev.mu_peak_known() {
            println!(
                "of the wrong road in use: {:.2} % of the time a road with more peak friction than the true one \
                 (optimistic: the controller expects grip that is not there), {:.2} % one with less (cautious)",
                pc(used.used_wrong_optimistic, used.decisions),
                pc(wrong - used.used_wrong_optimistic, used.decisions),
            );
        } else {
            println!(
                "(a class of the model is not a road of the catalogue: optimistic and cautious mistakes not told apart)"
            );
        }
    }
    let (conf, conf_raw) = (&ev.smoothed, &ev.single_frame);
    if conf.total() > 0 {
        let (m, mr) = (conf.metrics(), conf_raw.metrics());
        println!(
            "decisions inside one segment: {}; smoothed: accuracy {:.2} %, macro recall {:.2} %; \
             single-frame: accuracy {:.2} %, macro recall {:.2} %",
            conf.total(),
            100.0 * m.accuracy,
            100.0 * m.macro_recall,
            100.0 * mr.accuracy,
            100.0 * mr.macro_recall
        );
        if a.confusion {
            println!("\nsmoothed decisions (rows predicted, columns actual):\n");
            println!("{}", conf.to_markdown());
            println!("single frames (rows predicted, columns actual):\n");
            println!("{}", conf_raw.to_markdown());
        }
    }
}

pub fn run(ctx: &Ctx, args: Args) -> Result<()> {
    match args.cmd {
        DatasetCmd::Synth(a) => synth(a),
        DatasetCmd::Delay(a) => delay(a, &ctx.config_dir),
        DatasetCmd::Merge(a) => {
            let n = super::dataset_merge::merge(&a)?;
            println!("wrote {} ({n} files)", a.out.display());
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Dataset;

    fn args(out: PathBuf) -> SynthArgs {
        SynthArgs {
            out,
            seed: 3,
            recordings_per_class: 2,
            duration: 0.3,
            speeds: "10-30".into(),
            speed_scale: "uniform".into(),
            noise: "rain,car".into(),
            snr_db: Snr::Range(5.0, 15.0),
            changes: 2,
            changes_out: None,
            segment: "0.1-0.2".into(),
            snr_scope: "segment".into(),
            roads: None,
            sample_rate: 44_100,
            force: false,
        }
    }

    #[test]
    fn synth_then_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("ds");
        synth(args(out.clone())).unwrap();
        let ds = Dataset::scan(&out).unwrap();
        assert_eq!(ds.classes, ROADS);
        assert_eq!(ds.entries.len(), 12);
        let a = wav::read_mono(&ds.entries[0].path).unwrap();
        assert_eq!(
            (a.sample_rate, a.file_channels, a.samples.len()),
            (44_100, 1, 13_230)
        );
        let mut rd = csv::Reader::from_path(out.join("manifest.csv")).unwrap();
        let rows: Vec<ManifestRow> = rd.deserialize().map(|r| r.unwrap()).collect();
        assert_eq!(rows.len(), 12);
        assert_eq!(rows[0].noise.as_deref(), Some("rain+car"));
        assert!(
            rows.iter()
                .all(|r| (10.0..=30.0).contains(&r.speed_kmh.unwrap()))
        );
        let changes = read_changes(&dir.path().join("ds-changes"), &ds.classes, 0.1).unwrap();
        assert_eq!(changes.len(), 2);
        for c in &changes {
            assert!(c.segments.len() >= 2);
            assert!(
                c.segments
                    .windows(2)
                    .all(|w| w[0].2 != w[1].2 && (w[0].1 - w[1].0).abs() < 1e-9)
            );
            let a = wav::read_mono(&c.path).unwrap();
            assert!((a.duration_s() - 0.3).abs() < 1e-3);
        }
        // Same seed, same files.
        let out2 = dir.path().join("ds2");
        synth(args(out2.clone())).unwrap();
        assert_eq!(
            std::fs::read(out.join("snow/snow_0001.wav")).unwrap(),
            std::fs::read(out2.join("snow/snow_0001.wav")).unwrap()
        );
    }

    /// Change recordings alone (`--recordings-per-class 0`): the summary
    /// names `OUT-changes`, where they are (it said OUT); OUT gets no empty
    /// class folders and no empty manifest; reading OUT as change
    /// recordings points at OUT-changes.
    #[test]
    fn changes_alone_leave_no_empty_dataset_and_name_their_folder() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("chcal");
        let mut a = args(out.clone());
        a.recordings_per_class = 0;
        let cdir = super::changes_dir(&out);
        let said = synth_summary(&a, 0, 6, &cdir);
        assert!(
            said.contains(&format!("2 change recordings to {}", cdir.display())),
            "{said}"
        );
        synth(a).unwrap();
        assert!(!out.exists(), "class folders or a manifest were written");
        assert_eq!(
            read_changes(&cdir, &ROADS.map(String::from), 0.1)
                .unwrap()
                .len(),
            2
        );
        let classes: Vec<String> = ROADS.iter().map(|r| r.to_string()).collect();
        let e = format!("{:#}", read_changes(&out, &classes, 0.1).unwrap_err());
        assert!(e.contains(&cdir.display().to_string()), "{e}");
        // leftovers of an older run: the empty manifest's error points there too
        std::fs::create_dir_all(out.join("asphalt")).unwrap();
        std::fs::write(out.join("manifest.csv"), b"").unwrap();
        let e = format!("{:#}", read_changes(&out, &classes, 0.1).unwrap_err());
        assert!(
            e.contains("lists no recordings") && e.contains(&cdir.display().to_string()),
            "{e}"
        );
        // both kinds: both folders named
        let mut a = args(dir.path().join("ds"));
        a.recordings_per_class = 1;
        let said = synth_summary(&a, 6, 6, &super::changes_dir(&a.out));
        assert!(
            said.contains("to ") && said.contains("ds-changes") && said.contains("6 recordings"),
            "{said}"
        );
        // nothing at all to write is refused
        let mut a = args(dir.path().join("none"));
        (a.recordings_per_class, a.changes) = (0, 0);
        assert!(synth(a).is_err());
    }

    #[test]
    fn bad_arguments_and_folders_are_clear_errors() {
        assert!(parse_range("30-10", "speeds").is_err());
        assert!(
            parse_range("x", "speeds")
                .unwrap_err()
                .to_string()
                .contains("--speeds")
        );
        assert!(
            parse_noise("rain,snow", 10.0)
                .unwrap_err()
                .to_string()
                .contains("snow")
        );
        assert_eq!(
            snr_range(Snr::Range(-5.0, 10.0), "rain").unwrap(),
            (-5.0, 10.0)
        );
        assert_eq!(snr_range(Snr::Db(10.0), "car").unwrap(), (10.0, 10.0));
        assert!(snr_range(Snr::Off, "none").is_ok());
        let e = snr_range(Snr::Off, "rain,car").unwrap_err().to_string();
        assert!(e.contains("--snr-db off") && e.contains("rain,car"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let classes = vec!["asphalt".to_string()];
        let e = read_changes(dir.path(), &classes, 0.1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("segments.csv"), "{e}");
        std::fs::write(
            dir.path().join("segments.csv"),
            "file,t_start,t_end,road,speed_kmh,seed,noise,snr_db\nmissing.wav,0,1,asphalt,,,,\n",
        )
        .unwrap();
        let e = format!("{:#}", read_changes(dir.path(), &classes, 0.1).unwrap_err());
        assert!(
            e.contains("segments.csv") && e.contains("missing.wav"),
            "{e}"
        );
        std::fs::write(
            dir.path().join("segments.csv"),
            "file,t_start,t_end,road,speed_kmh,seed,noise,snr_db\nmissing.wav,0,1,ice,,,,\n",
        )
        .unwrap();
        let e = format!("{:#}", read_changes(dir.path(), &classes, 0.1).unwrap_err());
        assert!(e.contains("`road`") && e.contains("ice"), "{e}");
    }

    #[test]
    fn a_one_road_dataset_reads_as_one_segment_per_recording() {
        let dir = tempfile::tempdir().unwrap();
        let classes = vec!["asphalt".to_string(), "snow".to_string()];
        std::fs::create_dir(dir.path().join("snow")).unwrap();
        let wav4 = dir.path().join("snow/snow_0000.wav");
        wav::write_mono_i16(&wav4, 1000, &vec![0.1; 4000]).unwrap();
        let manifest = dir.path().join("manifest.csv");
        std::fs::write(
            &manifest,
            "file,road,speed_kmh,seed,noise,snr_db,duration_s\nsnow/snow_0000.wav,snow,12.5,7,rain+car,10.0,4.0\n",
        )
        .unwrap();
        let c = read_changes(dir.path(), &classes, 0.1).unwrap();
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].path, dir.path().join("snow/snow_0000.wav"));
        assert_eq!(c[0].segments, vec![(0.0, 4.0, 1, Some(12.5))]);
        // without a duration (or without the column: a user's own
        // recordings) the WAV's own length, from its header
        for text in [
            "file,road,speed_kmh,seed,noise,snr_db,duration_s\nsnow/snow_0000.wav,snow,12.5,7,rain+car,10.0,\n",
            "file,road,speed_kmh\nsnow/snow_0000.wav,snow,12.5\n",
        ] {
            std::fs::write(&manifest, text).unwrap();
            let c = read_changes(dir.path(), &classes, 0.1).unwrap();
            assert_eq!(c[0].segments, vec![(0.0, 4.0, 1, Some(12.5))], "{text}");
        }
        // a duration that is none: the error says where
        std::fs::write(
            &manifest,
            "file,road,speed_kmh,seed,noise,snr_db,duration_s\nsnow/snow_0000.wav,snow,12.5,7,rain+car,10.0,0\n",
        )
        .unwrap();
        let e = format!("{:#}", read_changes(dir.path(), &classes, 0.1).unwrap_err());
        assert!(
            e.contains("manifest.csv")
                && e.contains("record 1 (line 2)")
                && e.contains("`duration_s`"),
            "{e}"
        );
        // segments.csv, when present, decides
        wav::write_mono_i16(
            &dir.path().join("snow/snow_0000.wav"),
            1000,
            &vec![0.0; 2000],
        )
        .unwrap();
        std::fs::write(
            dir.path().join("segments.csv"),
            "file,t_start,t_end,road,speed_kmh,seed,noise,snr_db\nsnow/snow_0000.wav,0,1,asphalt,,,,\nsnow/snow_0000.wav,1,2,snow,,,,\n",
        )
        .unwrap();
        let c = read_changes(dir.path(), &classes, 0.1).unwrap();
        assert_eq!(c[0].segments.len(), 2);
    }

    /// A one-road manifest: column names in any case (as `grip train`
    /// reads them); a file listed twice is an error naming both lines (the
    /// second row used to win in silence); a `duration_s` more than one
    /// frame off the WAV's length is an error naming the file, the line
    /// and both durations (it used to be taken as the truth).
    #[test]
    fn one_road_manifests_are_checked_row_by_row() {
        let dir = tempfile::tempdir().unwrap();
        let classes = vec!["asphalt".to_string(), "snow".to_string()];
        std::fs::create_dir(dir.path().join("snow")).unwrap();
        for f in ["snow/a.wav", "snow/b.wav"] {
            wav::write_mono_i16(&dir.path().join(f), 1000, &vec![0.1; 2000]).unwrap();
        }
        let read = |rows: &str| {
            std::fs::write(dir.path().join("manifest.csv"), rows).unwrap();
            read_changes(dir.path(), &classes, 0.1).map_err(|e| format!("{e:#}"))
        };
        // upper case, within one frame of the 2 s files
        let c = read(
            "File,Road,Speed_KMH,Duration_S\nsnow/a.wav,snow,10,2.05\nsnow/b.wav,snow,,1.95\n",
        )
        .unwrap();
        assert_eq!(c[0].segments, vec![(0.0, 2.05, 1, Some(10.0))]);
        let e = read(
            "file,road,duration_s\nsnow/a.wav,snow,2\nsnow/b.wav,snow,2\n./snow/a.wav,snow,2\n",
        )
        .unwrap_err();
        assert!(
            e.contains("snow/a.wav")
                && e.contains("listed twice")
                && e.contains("line 2")
                && e.contains("line 4"),
            "{e}"
        );
        let e = read("file,road,duration_s\nsnow/a.wav,snow,2\nsnow/b.wav,snow,20\n").unwrap_err();
        assert!(
            e.contains("snow/b.wav")
                && e.contains("line 3")
                && e.contains("duration_s 20 s")
                && e.contains("is 2 s long"),
            "{e}"
        );
    }

    /// segments.csv with its column names in another case reads as
    /// written in lower case (it was refused: `missing field file`).
    #[test]
    fn segment_column_names_in_any_case() {
        let d = changes_dir("");
        std::fs::write(
            d.path().join("segments.csv"),
            "File,T_Start,T_END,Road,speed_kmh\na.wav,0,1,asphalt,\na.wav,1,2,snow,\n",
        )
        .unwrap();
        let classes = vec!["asphalt".to_string(), "snow".to_string()];
        let c = read_changes(d.path(), &classes, 0.1).unwrap();
        assert_eq!(c[0].segments.len(), 2);
    }

    /// A folder with two 2 s WAVs (1 kHz) and the given segments.csv rows.
    fn changes_dir(rows: &str) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for f in ["a.wav", "b.wav"] {
            wav::write_mono_i16(&dir.path().join(f), 1000, &vec![0.0; 2000]).unwrap();
        }
        std::fs::write(
            dir.path().join("segments.csv"),
            format!("file,t_start,t_end,road,speed_kmh,seed,noise,snr_db\n{rows}"),
        )
        .unwrap();
        dir
    }

    #[test]
    fn read_changes_refuses_overlap_disorder_and_times_past_the_end() {
        let classes = vec!["asphalt".to_string(), "snow".to_string()];
        let read = |rows: &str| {
            let d = changes_dir(rows);
            read_changes(d.path(), &classes, 0.1).map_err(|e| format!("{e:#}"))
        };
        // good: sorted, touching or with a gap, ending within one frame
        // past the end (2.05 s of a 2 s file)
        let c =
            read("a.wav,0,1,asphalt,,,,\nb.wav,0,2,snow,,,,\na.wav,1.5,2.05,snow,,,,\n").unwrap();
        assert_eq!(c.len(), 2);
        assert_eq!(c[0].segments.len(), 2);
        // overlapping segments: file, line and the other segment's line
        let e =
            read("a.wav,0,1.2,asphalt,,,,\nb.wav,0,2,snow,,,,\na.wav,1,2,snow,,,,\n").unwrap_err();
        assert!(
            e.contains("segments.csv")
                && e.contains("a.wav")
                && e.contains("line 4")
                && e.contains("line 2")
                && e.contains("overlaps"),
            "{e}"
        );
        // out of order
        let e = read("a.wav,1,2,snow,,,,\na.wav,0,1,asphalt,,,,\n").unwrap_err();
        assert!(
            e.contains("a.wav") && e.contains("line 3") && e.contains("time order"),
            "{e}"
        );
        // times in ms
        let e = read("b.wav,0,1000,asphalt,,,,\nb.wav,1000,2000,snow,,,,\n").unwrap_err();
        assert!(
            e.contains("b.wav")
                && e.contains("line 2")
                && e.contains("the file is 2 s long: are the times in seconds?"),
            "{e}"
        );
        // past the end by more than a frame
        let e = read("a.wav,0,2.2,asphalt,,,,\n").unwrap_err();
        assert!(
            e.contains("a.wav") && e.contains("are the times in seconds?"),
            "{e}"
        );
    }
}
