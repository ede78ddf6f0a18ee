//! `grip train`: features, cross-validation by recording, final fit, model file.
//!
//! Steps: scan the dataset (one folder per class, see `dataset.rs`), cut
//! every recording into frames (`--frame`, default 0.1 s, hop `--hop`),
//! extract features, run stratified k-fold cross-validation split by
//! recording (for `paper7`, the paper's pruning runs inside each fold), print
//! the report and the confusion matrix (rows predicted, columns actual, as
//! the paper's Tables II/III), fit on all data, print the fitted model's
//! own accuracy on the final fit's training and validation frames
//! ([`FitCheck`]; what the written file does, unlike the cross-validation),
//! refuse a fit not worth writing ([`PoorFit`]: the MLP never left its
//! random initial weights, or the model is no better than always answering
//! the most common class on its own training frames; `--allow-poor-fit`
//! writes it anyway), write the model file
//! (`--out`, required; an existing file only with `--force`, refused before
//! any work otherwise, as are a directory and a folder that does not exist:
//! [`check_output_file`]; `--report` alike), and with `--test DIR` score
//! held-out recordings.
//!
//! SVM: C and γ are chosen by grid search on the same CV folds (macro-F1;
//! `--svm-c`, `--svm-gamma`, γ given as multiples of 1/dim since the
//! features are standardised), with Platt CV switched off during the search
//! for speed; the reported CV uses the final settings.
//!
//! Deterministic for a seed: the same arguments on the same data give the
//! same model bytes (the date defaults to `SOURCE_DATE_EPOCH` when set,
//! else today's UTC date; `--date` fixes it).

use super::Ctx;
use crate::dataset::{self, ChannelArg, Dataset, Excluded, FileJudge, read_wav};
use anyhow::{Context, Result, bail};
use grip_arte::eval::{Confusion, Samples};
use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet, SpeedNorm};
use grip_arte::mlp::{LmConfig, OutputKind};
use grip_arte::model::{
    ClassifierSpec, EvalSummary, FitCheck, FitReport, Model, PoorFit, cross_validate_with,
    fit_with_split, grid_search_svm,
};
use grip_arte::speeds::SpeedRange;
use grip_arte::svm::{Kernel, SvmConfig};
use grip_digest::sha256_hex;
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Clone, Debug)]
pub struct Args {
    /// Dataset folder: one sub-folder of WAV files per class.
    #[arg(long)]
    pub data: PathBuf,
    /// Classifier.
    #[arg(long, default_value = "mlp", value_parser = ["mlp", "svm"])]
    pub classifier: String,
    /// MLP hidden layer sizes (the paper's network: 4,3,2).
    #[arg(long, default_value = "4,3,2", value_delimiter = ',')]
    pub hidden: Vec<usize>,
    /// MLP output units.
    #[arg(long, default_value = "softmax", value_parser = ["softmax", "logistic"])]
    pub output: String,
    /// Feature set: paper7 (the paper's pruned 7), paper20, rich.
    #[arg(long, default_value = "paper7", value_parser = ["paper7", "paper20", "rich"])]
    pub features: String,
    /// Cross-validation folds (split by recording); 0 skips CV.
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Seed of initialisation, subsampling and fold assignment.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output model file (required: a model is never written to a place
    /// you did not name), in a folder that exists. An existing file is not
    /// overwritten unless `--force` is given.
    #[arg(long)]
    pub out: PathBuf,
    /// Overwrite an existing `--out` (and `--report`) file.
    #[arg(long)]
    pub force: bool,
    /// Write the model even when the final fit is useless: the MLP never
    /// improved on its random initial weights (best epoch 0), or on its
    /// own training frames the model is no better than always answering
    /// the most common class. Without it such a fit is an error and
    /// nothing is written.
    #[arg(long)]
    pub allow_poor_fit: bool,
    /// Held-out dataset folder(s) to evaluate the final model on (repeatable).
    #[arg(long)]
    pub test: Vec<PathBuf>,
    /// Frame length (s).
    #[arg(long, default_value_t = 0.1)]
    pub frame: f64,
    /// Hop between frames (s).
    #[arg(long, default_value_t = 0.1)]
    pub hop: f64,
    /// MLP: maximum LM epochs (trainlm: 1000).
    #[arg(long, default_value_t = 1000)]
    pub epochs: usize,
    /// MLP: cap on rows in the LM Jacobian (seeded stratified subsample).
    #[arg(long, default_value_t = 4000)]
    pub lm_max_rows: usize,
    /// MLP: fraction of each class's recordings held out for early stopping.
    #[arg(long, default_value_t = 0.15)]
    pub val_fraction: f64,
    /// SVM: C grid.
    #[arg(long, default_value = "1,10,100", value_delimiter = ',')]
    pub svm_c: Vec<f64>,
    /// SVM: gamma grid, in multiples of 1/dim.
    #[arg(long, default_value = "0.25,0.5,1,2", value_delimiter = ',')]
    pub svm_gamma: Vec<f64>,
    /// SVM: frames per class used for training (seeded subsample).
    #[arg(long, default_value_t = 1000)]
    pub svm_max_per_class: usize,
    /// Profile name stored in the model (e.g. paper, default).
    #[arg(long, default_value = "custom")]
    pub profile: String,
    /// Training date stored in the model, YYYY-MM-DD.
    #[arg(long)]
    pub date: Option<String>,
    /// Also write the report (Markdown, with confusion matrices) here (a
    /// file in a folder that exists; an existing one only with `--force`).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Also report held-out results with class probabilities averaged over
    /// this many consecutive frames of a recording (causal); 1 = off.
    #[arg(long, default_value_t = 5)]
    pub window: usize,
    /// Rich only: speed normalisation exponent (frequencies warped by
    /// (v_ref/v)^EXP; 0.25 holds the tyre's noise hump in place). Needs the
    /// `speed_kmh` of every recording in the manifest of training and
    /// held-out data. Off unless given.
    #[arg(long)]
    pub speed_norm: Option<f64>,
    /// Reference speed of the speed normalisation (km/h).
    #[arg(long, default_value_t = 20.0)]
    pub speed_ref: f64,
    /// Rich only: also the energy shares of three fixed bands (2-4, 4-8,
    /// 8-16 kHz) of the recorded spectrum, which the speed normalisation
    /// does not warp (water spray and rain do not move with speed).
    #[arg(long)]
    pub fixed_bands: bool,
    /// Use only these class folders (comma separated), in training and held-out data.
    #[arg(long, value_delimiter = ',')]
    pub classes: Vec<String>,
    /// Road-change recordings (from `grip dataset synth --changes`) to fit
    /// the streaming estimator's confidence calibration on, after training
    /// (repeatable; other seeds than the training and the evaluation sets).
    /// Without it the model carries no calibration (format v1).
    #[arg(long)]
    pub calib_data: Vec<PathBuf>,
    #[command(flatten)]
    pub calib: super::calibrate::FitArgs,
    #[command(flatten)]
    pub channel: ChannelArg,
}

impl Args {
    /// The command line that reproduces this run (stored in the model).
    fn command_line(&self) -> String {
        let mut s = format!(
            "grip train --data {} --classifier {} --features {} --folds {} --seed {} --frame {} --hop {}",
            self.data.display(),
            self.classifier,
            self.features,
            self.folds,
            self.seed,
            self.frame,
            self.hop
        );
        if self.classifier == "mlp" {
            let h: Vec<String> = self.hidden.iter().map(usize::to_string).collect();
            let _ = write!(
                s,
                " --hidden {} --output {} --epochs {} --lm-max-rows {} --val-fraction {}",
                h.join(","),
                self.output,
                self.epochs,
                self.lm_max_rows,
                self.val_fraction
            );
        } else {
            let j = |v: &[f64]| v.iter().map(f64::to_string).collect::<Vec<_>>().join(",");
            let _ = write!(
                s,
                " --svm-c {} --svm-gamma {} --svm-max-per-class {}",
                j(&self.svm_c),
                j(&self.svm_gamma),
                self.svm_max_per_class
            );
        }
        if !self.classes.is_empty() {
            let _ = write!(s, " --classes {}", self.classes.join(","));
        }
        if let Some(e) = self.speed_norm {
            let _ = write!(s, " --speed-norm {e} --speed-ref {}", self.speed_ref);
        }
        if self.fixed_bands {
            s.push_str(" --fixed-bands");
        }
        s.push_str(&self.channel.command_line());
        if self.allow_poor_fit {
            s.push_str(" --allow-poor-fit");
        }
        let _ = write!(s, " --profile {}", self.profile);
        if !self.calib_data.is_empty() {
            for d in &self.calib_data {
                let _ = write!(s, " --calib-data {}", d.display());
            }
            let _ = write!(s, " {}", self.calib.command_line());
        }
        s
    }
}

/// Today's UTC date, or `SOURCE_DATE_EPOCH`'s.
fn today() -> String {
    let secs = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|v| v.trim().parse::<i64>().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs() as i64)
                .unwrap_or(0)
        });
    civil_date(secs)
}

/// `YYYY-MM-DD` (UTC) of a Unix time, by H. Hinnant's `civil_from_days`.
pub(crate) fn civil_date(secs: i64) -> String {
    let z = secs.div_euclid(86_400) + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

/// Features of every frame of every recording of `ds` (read by `channel`),
/// in `cfg`'s layout, class labels mapped through `class_map` (dataset
/// class -> model class). Frames the arte service would refuse
/// ([`FileJudge`]: silence, clipping) are left out, each file's named in a
/// warning. Returns the samples, the dataset hash (over every file, left
/// out or not) with every file's content hash, and what was left out; a
/// dataset left with no frame is an error naming its folder.
pub fn extract_dataset(
    ds: &Dataset,
    cfg: &FeatureConfig,
    hop_s: f64,
    class_map: &[usize],
    channel: grip_io::wav::Channel,
    role: SetRole,
) -> Result<(Samples, DatasetIdentity, Excluded)> {
    let mut ex = FeatureExtractor::new(cfg).context("feature config")?;
    let hop = ((hop_s * f64::from(cfg.sample_rate)).round() as usize).max(1);
    let frame_len = ex.frame_len();
    let mut s = Samples::new(ex.dim());
    let mut row = vec![0.0; ex.dim()];
    let mut hash_input = String::new();
    let mut files = Vec::with_capacity(ds.entries.len());
    let pb = ProgressBar::new(ds.entries.len() as u64);
    pb.set_style(
        ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} files {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_prefix(format!("features {}", ds.root.display()));
    let mut excluded = Excluded::default();
    // every file's content, to find the same audio listed twice
    let mut seen = SeenAudio::default();
    for (i, e) in ds.entries.iter().enumerate() {
        let (audio, sha256) = read_wav(&e.path, channel)?;
        if let Some(note) = seen.check(ds, i, &sha256, role)? {
            pb.suspend(|| eprintln!("warning: {note}"));
        }
        if audio.sample_rate != cfg.sample_rate {
            bail!(
                "{}: sample rate {} Hz, but the features are configured for {} Hz (all files of a dataset must share one rate)",
                e.path.display(),
                audio.sample_rate,
                cfg.sample_rate
            );
        }
        let _ = writeln!(hash_input, "{}\0{}\0{}", ds.classes[e.class], e.rel, sha256);
        files.push(dataset::file_id(&sha256));
        if audio.samples.len() < frame_len {
            bail!(
                "{}: {} samples, shorter than one {:.3} s frame ({} samples)",
                e.path.display(),
                audio.samples.len(),
                cfg.frame_s,
                frame_len
            );
        }
        if cfg.speed_norm.is_some() {
            let Some(kmh) = e.speed_kmh else {
                bail!(
                    "{}: no vehicle speed: {}; a speed-normalised model needs the vehicle speed of every recording (column speed_kmh of manifest.csv)",
                    e.path.display(),
                    ds.why_no_speed(e)
                );
            };
            ex.set_speed(Some(kmh / 3.6));
        }
        let mut judge = FileJudge::new();
        for frame in good_frames(&audio.samples, frame_len, hop, &mut judge) {
            ex.extract(frame, &mut row)
                .with_context(|| format!("{}: feature extraction", e.path.display()))?;
            s.push(&row, class_map[e.class], e.recording);
        }
        let name = e.path.display().to_string();
        pb.suspend(|| judge.finish(&name, &audio, channel, "frame", &mut excluded));
        pb.inc(1);
    }
    pb.finish_and_clear();
    if s.is_empty() {
        bail!(
            "dataset folder {}: every frame of every file was excluded ({}); nothing is left to train or evaluate on",
            ds.root.display(),
            excluded.summary("frame").unwrap_or_default()
        );
    }
    files.sort();
    files.dedup();
    let id = DatasetIdentity {
        hash: sha256_hex(hash_input.as_bytes()),
        files,
    };
    Ok((s, id, excluded))
}

/// What a dataset is read for ([`extract_dataset`]): training (and its
/// cross-validation), or a held-out evaluation (`--test`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetRole {
    /// `--data`: fitted and cross-validated on.
    Training,
    /// `--test`: evaluated only.
    HeldOut,
}

/// The files of one dataset seen so far, by content: [`Self::check`] gives
/// [`same_audio`]'s verdict on a file whose SHA-256 an earlier one had.
/// Training extraction and the `--test` check before the fit share it.
#[derive(Default)]
struct SeenAudio(std::collections::HashMap<String, usize>);

impl SeenAudio {
    /// Entry `i` of `ds`, of content `sha256`: `Ok(None)` when it is the
    /// first of that content (remembered), else [`same_audio`]'s error or
    /// warning against the first.
    fn check(
        &mut self,
        ds: &Dataset,
        i: usize,
        sha256: &str,
        role: SetRole,
    ) -> Result<Option<String>> {
        match self.0.get(sha256) {
            Some(&j) => same_audio(ds, &ds.entries[j], &ds.entries[i], sha256, role).map(Some),
            None => {
                self.0.insert(sha256.to_owned(), i);
                Ok(None)
            }
        }
    }
}

/// `b` holds byte for byte the audio of `a` (an earlier file of `ds`):
/// an error when the two are labelled different roads (one of the labels
/// is wrong), and, in a training set, when they are different recordings
/// (cross-validation would test on a clip it trained on, and report a
/// better accuracy than the model has); else the warning to print (its
/// frames weigh twice). The same file copied, or one source merged twice,
/// does this.
fn same_audio(
    ds: &Dataset,
    a: &dataset::Entry,
    b: &dataset::Entry,
    sha256: &str,
    role: SetRole,
) -> Result<String> {
    let (pa, pb) = (a.path.display(), b.path.display());
    let digest = &sha256[..16.min(sha256.len())];
    if a.class != b.class {
        bail!(
            "{pb} is the same audio as {pa} (SHA-256 {digest}...), but one is labelled `{}` and the other `{}`: at most one label is right; remove the wrong copy",
            ds.classes[b.class],
            ds.classes[a.class]
        );
    }
    if a.recording != b.recording && role == SetRole::Training {
        bail!(
            "{pb} is the same audio as {pa} (SHA-256 {digest}...) in another recording: cross-validation would test on a clip it trained on and report a better accuracy than the model has; remove one copy, or give both one `recording` in manifest.csv"
        );
    }
    Ok(match role {
        SetRole::Training => format!(
            "{pb} is the same audio as {pa} (SHA-256 {digest}...), one recording: its frames count twice"
        ),
        SetRole::HeldOut => format!(
            "{pb} is the same audio as {pa} (SHA-256 {digest}...): the held-out figures count its frames twice"
        ),
    })
}

/// The slowest and fastest vehicle speed (the manifest's `speed_kmh`) of
/// the recordings of `ds` that gave frames to `data` (a recording whose
/// every frame was excluded did not train the model); Err says why there
/// is none (a recording without a speed, named with
/// [`Dataset::why_no_speed`]).
fn training_speed_range(ds: &Dataset, data: &Samples) -> std::result::Result<SpeedRange, String> {
    let used: std::collections::BTreeSet<usize> = data.group.iter().copied().collect();
    let trained: Vec<_> = ds
        .entries
        .iter()
        .filter(|e| used.contains(&e.recording))
        .collect();
    let missing: Vec<_> = trained.iter().filter(|e| e.speed_kmh.is_none()).collect();
    if let Some(first) = missing.first() {
        return Err(format!(
            "{} of {} training recordings have no vehicle speed (the first: {})",
            missing.len(),
            trained.len(),
            ds.why_no_speed(first)
        ));
    }
    SpeedRange::of(trained.iter().filter_map(|e| e.speed_kmh))
        .ok_or_else(|| "the manifest's speeds give no range".to_owned())
}

/// What identifies a training set in the model: the dataset hash
/// (`meta.dataset_hash`) and its files by content
/// (`meta.training_files`, see [`dataset::file_id`]).
#[derive(Clone, Debug)]
pub struct DatasetIdentity {
    /// SHA-256 over every file's class, path and SHA-256.
    pub hash: String,
    /// [`dataset::file_id`] of every file, sorted, without repeats.
    pub files: Vec<String>,
}

/// The frames of `x` (`frame_len` samples every `hop`) that `judge`
/// accepts (the arte service's audio-quality rule).
fn good_frames<'a>(
    x: &'a [f32],
    frame_len: usize,
    hop: usize,
    judge: &'a mut FileJudge,
) -> impl Iterator<Item = &'a [f32]> + 'a {
    x.windows(frame_len)
        .step_by(hop)
        .filter(move |f| judge.accept(f))
}

/// Whether a file of `ds` (read by `channel`) has a frame the audio-quality
/// rule accepts, read until the first that has: a dataset of nothing but
/// refused audio is an error naming its folder, found before the fit.
fn any_good_frame(
    ds: &Dataset,
    frame_len: usize,
    hop: usize,
    channel: grip_io::wav::Channel,
) -> Result<()> {
    for e in &ds.entries {
        let a = grip_io::wav::read_channel(&e.path, channel)?;
        if good_frames(&a.samples, frame_len, hop, &mut FileJudge::new())
            .next()
            .is_some()
        {
            return Ok(());
        }
    }
    bail!(
        "dataset folder {}: every frame of every file would be excluded (the arte service's audio-quality rule: silence or clipping); nothing is left to evaluate on",
        ds.root.display()
    )
}

/// After the audio-quality rule left frames out: every class of `ds` must
/// keep a frame, and with `folds` ≥ 2 as many recordings as folds; the
/// error names the class folder.
fn classes_left(ds: &Dataset, data: &Samples, folds: usize) -> Result<()> {
    let mut groups = vec![std::collections::BTreeSet::new(); ds.classes.len()];
    for (&c, &g) in data.y.iter().zip(&data.group) {
        groups[c].insert(g);
    }
    for (c, g) in ds.classes.iter().zip(&groups) {
        if g.is_empty() || (folds >= 2 && g.len() < folds) {
            bail!(
                "{}: class folder `{c}` keeps {} recording(s) after the excluded audio (see the warnings), {}",
                ds.root.display(),
                g.len(),
                if g.is_empty() {
                    "none to learn the class from".to_string()
                } else {
                    format!("fewer than the {folds} folds of cross-validation by recording")
                }
            );
        }
    }
    Ok(())
}

/// Sample rate of the first file (all files are checked during extraction).
fn dataset_rate(ds: &Dataset) -> Result<u32> {
    let first = ds.entries.first().context("dataset has no files")?;
    Ok(grip_io::wav::read_mono(&first.path)?.sample_rate)
}

/// Evaluates `model` on a held-out dataset folder (classes matched by
/// name, files read by `channel`): per frame, smoothed over `window`
/// frames, and what the audio-quality rule left out.
pub fn evaluate_folder(
    model: &Model,
    dir: &Path,
    hop_s: f64,
    only: Option<&[String]>,
    window: usize,
    channel: grip_io::wav::Channel,
) -> Result<(Confusion, Confusion, Excluded)> {
    let ds = Dataset::scan_classes(dir, only)?;
    let mut map = Vec::new();
    for c in &ds.classes {
        let Some(i) = model.classes().iter().position(|m| m == c) else {
            bail!(
                "held-out dataset {}: class `{c}` is not one of the model's classes {:?}",
                dir.display(),
                model.classes()
            );
        };
        map.push(i);
    }
    let (samples, _, excluded) = extract_dataset(
        &ds,
        model.feature_config(),
        hop_s,
        &map,
        channel,
        SetRole::HeldOut,
    )?;
    Ok((
        model.evaluate(&samples)?,
        model.evaluate_smoothed(&samples, window)?,
        excluded,
    ))
}

fn summary(what: String, conf: Confusion) -> EvalSummary {
    EvalSummary {
        what,
        metrics: conf.metrics(),
        confusion: conf,
    }
}

fn print_eval(report: &mut String, title: &str, e: &EvalSummary) {
    println!("\n{title}: {}", e.metrics);
    let per: Vec<String> = e
        .confusion
        .classes()
        .iter()
        .enumerate()
        .map(|(i, c)| {
            recall_precision(
                c,
                (e.metrics.recall[i], e.confusion.actual_total(i)),
                (e.metrics.precision[i], e.confusion.predicted_total(i)),
            )
        })
        .collect();
    println!("recall/precision %: {}", per.join(", "));
    let low = low_recall(&e.confusion);
    for l in &low {
        println!("{l}");
    }
    print!("{}", e.confusion);
    let _ = writeln!(report, "\n**{title}**: {}\n", e.metrics);
    let _ = writeln!(report, "recall/precision (%): {}\n", per.join(", "));
    for l in &low {
        let _ = writeln!(report, "{l}\n");
    }
    report.push_str(&e.confusion.to_markdown());
}

/// A class named in under half of its own frames: said under the
/// recall/precision line with what it is most often taken for (a model
/// that seldom says snow hands the loop a grippier road's curve on
/// snow; the macro figures above can hide one class's miss).
fn low_recall(c: &Confusion) -> Vec<String> {
    let n = c.classes().len();
    (0..n)
        .filter_map(|a| {
            let total = c.actual_total(a);
            let right = c.get(a, a);
            if total == 0 || 2 * right >= total {
                return None;
            }
            let (taken, k) = (0..n)
                .filter(|&p| p != a)
                .map(|p| (p, c.get(p, a)))
                .max_by_key(|&(p, k)| (k, std::cmp::Reverse(p)))?;
            Some(format!(
                "low recall: `{}` named in {:.1} % of its {total} frames, most often taken for `{}` ({k} frames)",
                c.classes()[a],
                100.0 * right as f64 / total as f64,
                c.classes()[taken]
            ))
        })
        .collect()
}

/// One class's "recall/precision" cell: `-` for a figure with nothing to
/// count (recall of a class with no frames in the set, precision of one
/// never decided), which the metrics give as 0 (a held-out set without
/// stone read "stone 0.0/0.0" beside a macro recall of 100 %).
fn recall_precision(class: &str, recall: (f64, u64), precision: (f64, u64)) -> String {
    let pct = |(x, n): (f64, u64)| {
        if n == 0 {
            "-".to_owned()
        } else {
            format!("{:.1}", 100.0 * x)
        }
    };
    let none = if recall.1 == 0 { " (no frames)" } else { "" };
    format!("{class} {}/{}{none}", pct(recall), pct(precision))
}

/// Trains and returns the model and the Markdown report (no file written).
/// `pb` styled by `template` with `prefix`, redrawn twice a second (a fold
/// or a fit takes long and reports nothing in between).
fn busy(pb: ProgressBar, template: &str, prefix: String) -> ProgressBar {
    pb.set_style(
        ProgressStyle::with_template(template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_prefix(prefix);
    pb.enable_steady_tick(std::time::Duration::from_millis(500));
    pb
}

/// `--calib-data` must be held out: a folder that is, holds or lies in the
/// training data (`--data`) or a `--test` folder is refused (a confidence
/// map fitted on what the classifier was trained on is optimistic, and
/// the controller's gate would trust wrong roads).
fn held_out_calibration(args: &Args) -> Result<()> {
    let used: Vec<(&str, PathBuf)> = std::iter::once(("--data", args.data.clone()))
        .chain(args.test.iter().map(|t| ("--test", t.clone())))
        .collect();
    super::calibrate::require_held_out("--calib-data", &args.calib_data, &used)
}

/// Checks the `--test` and `--calib-data` folders against what their
/// evaluation after the fit will need, BEFORE anything is trained (a bad
/// held-out folder used to throw away the training): each `--test` folder
/// scans, its classes are the training set's (`classes`), every file has
/// the training set's rate (`rate`, the model's: no resampling there) and
/// at least one frame (`frame_len` samples), and with `speed_norm` every
/// recording has its `speed_kmh`; each `--calib-data` folder reads
/// (segments.csv or manifest.csv, roads among the classes, files present,
/// speeds when speed-normalised) and its files can be brought to `rate`.
fn check_held_out(
    args: &Args,
    classes: &[String],
    rate: u32,
    frame_len: usize,
    speed_norm: bool,
    only: Option<&[String]>,
) -> Result<()> {
    for dir in &args.test {
        let ds = Dataset::scan_classes(dir, only)
            .with_context(|| format!("--test {}: held-out dataset", dir.display()))?;
        for c in &ds.classes {
            if !classes.contains(c) {
                bail!(
                    "--test {}: class folder `{c}` is not one of the training set's classes {:?} ({}); remove it, or pass --classes to use only the shared ones",
                    dir.display(),
                    classes,
                    args.data.display()
                );
            }
        }
        for e in &ds.entries {
            let (fs, n) = dataset::wav_rate_len(&e.path)
                .with_context(|| format!("--test {}: held-out dataset", dir.display()))?;
            args.channel
                .check(&e.path)
                .with_context(|| format!("--test {}: --channel", dir.display()))?;
            if fs != rate {
                bail!(
                    "--test {}: {}: held-out set at {fs} Hz, training set ({}) at {rate} Hz: the model's features are computed at {rate} Hz and held-out audio is not resampled; use a held-out set recorded at {rate} Hz (e.g. `grip dataset synth --sample-rate {rate}`), or train on {fs} Hz data",
                    dir.display(),
                    e.path.display(),
                    args.data.display()
                );
            }
            if n < frame_len as u64 {
                bail!(
                    "--test {}: {}: {n} samples, shorter than one {:.3} s frame ({frame_len} samples)",
                    dir.display(),
                    e.path.display(),
                    args.frame
                );
            }
            if speed_norm && e.speed_kmh.is_none() {
                bail!(
                    "--test {}: {}: no vehicle speed: {}; the model is speed-normalised (--speed-norm) and its evaluation needs the vehicle speed of every held-out recording (column speed_kmh of manifest.csv)",
                    dir.display(),
                    e.path.display(),
                    ds.why_no_speed(e)
                );
            }
        }
        let hop = ((args.hop * f64::from(rate)).round() as usize).max(1);
        any_good_frame(&ds, frame_len, hop, args.channel.get())
            .with_context(|| format!("--test {}: held-out dataset", dir.display()))?;
        // the same audio under two roads, before the fit (the evaluation
        // after it would refuse it too)
        let mut seen = SeenAudio::default();
        for (i, e) in ds.entries.iter().enumerate() {
            let bytes = std::fs::read(&e.path).with_context(|| {
                format!("--test {}: cannot read {}", dir.display(), e.path.display())
            })?;
            seen.check(&ds, i, &sha256_hex(&bytes), SetRole::HeldOut)
                .with_context(|| format!("--test {}: held-out dataset", dir.display()))?;
        }
    }
    for dir in &args.calib_data {
        let at = || format!("--calib-data {}", dir.display());
        let recs = super::dataset::read_changes(dir, classes, args.frame).with_context(at)?;
        for r in &recs {
            if speed_norm && r.segments.iter().any(|s| s.3.is_none()) {
                bail!(
                    "{}: a segment of {} has no speed_kmh in {}; the model is speed-normalised (--speed-norm) and the calibration needs the vehicle speed",
                    at(),
                    r.path.display(),
                    super::dataset::truth_file(dir).display()
                );
            }
            let (fs, _) = dataset::wav_rate_len(&r.path).with_context(at)?;
            args.channel.check(&r.path).with_context(at)?;
            if fs == 0 || u64::from(rate) > grip_io::wav::MAX_UPSAMPLE * u64::from(fs) {
                bail!(
                    "{}: {}: recorded at {fs} Hz, training set ({}) at {rate} Hz: too low a rate to resample to the model's (at most {}x up)",
                    at(),
                    r.path.display(),
                    args.data.display(),
                    grip_io::wav::MAX_UPSAMPLE
                );
            }
        }
    }
    Ok(())
}

/// Refuses, before any feature is extracted, a class set that arte would
/// refuse at start-up (`grip_arte_svc::road_table`, the code arte runs):
/// more classes than a road estimate carries, or a class that is not a road
/// of the configuration's catalogue (the estimate carries the road's μ-λ
/// curve). Without a readable catalogue the classes are not checked (a
/// warning says so).
fn arte_would_take(config_dir: &Path, out: &Path, ds: &Dataset) -> Result<()> {
    let cfg = grip_config::ConfigDir::new(config_dir);
    let table = cfg
        .roads()
        .and_then(|roads| Ok((cfg.road_table(&roads)?, roads)));
    let (rule, roads) = match table {
        Ok(t) => t,
        Err(e) => {
            eprintln!(
                "warning: the classes are not checked against a road catalogue ({e}); arte refuses a model with a class that is not a road of its roads.toml"
            );
            return Ok(());
        }
    };
    grip_arte_svc::road_table(&ds.classes, &roads, &rule, out, &cfg.roads_path()).map_err(|e| {
        // the class folders are at fault, not the model file (not yet
        // written): named by the folder
        let what = match e {
            grip_arte_svc::ArteError::Classes { reason, .. } => reason,
            e => e.to_string(),
        };
        anyhow::anyhow!(
            "--data {}: {what}: arte would refuse a model of these classes (the class folders of {}; --out {} not written); add the road to roads.toml first, or choose the classes with --classes",
            ds.root.display(),
            ds.root.display(),
            out.display()
        )
    })?;
    Ok(())
}

/// `--hidden` against Levenberg-Marquardt's limit as the fit refuses it
/// ([`grip_arte::mlp::check_lm_size`], the fit's own check and words), but
/// before any feature is extracted (`--hidden 256,256` was refused only
/// after the extraction, minutes on a large set): `dim` is the model's
/// feature count (`FeatureConfig::dim`: paper7's 7 after the pruning,
/// paper20's 20, rich's with its options).
fn check_lm_size(hidden: &[usize], dim: usize, n_classes: usize) -> Result<()> {
    if let Err(e) = grip_arte::mlp::check_lm_size(dim, hidden, n_classes) {
        let h: Vec<String> = hidden.iter().map(usize::to_string).collect();
        bail!("--hidden {}: {e}", h.join(","));
    }
    Ok(())
}

pub fn train(ctx_config: &Path, args: &Args) -> Result<(Model, String)> {
    if !(args.hop > 0.0 && args.hop <= 10.0) {
        bail!("--hop: {} s is outside (0, 10]", args.hop);
    }
    args.calib.check()?;
    held_out_calibration(args)?;
    let only = (!args.classes.is_empty()).then_some(args.classes.as_slice());
    let ds = Dataset::scan_classes(&args.data, only)?;
    arte_would_take(ctx_config, &args.out, &ds)?;
    for e in &ds.entries {
        args.channel.check(&e.path).context("--channel")?;
    }
    let per_class = ds.recordings_per_class();
    println!(
        "dataset {}: {} classes, {} files, recordings per class: {}",
        ds.root.display(),
        ds.classes.len(),
        ds.entries.len(),
        ds.classes
            .iter()
            .zip(&per_class)
            .map(|(c, n)| format!("{c} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    // folds by recording need as many recordings of every class: said
    // before any feature is extracted, naming the class folder
    if args.folds >= 2
        && let Some((c, n)) = ds
            .classes
            .iter()
            .zip(&per_class)
            .find(|(_, n)| **n < args.folds)
    {
        bail!(
            "{}: class folder `{c}` has {n} recording(s), fewer than the {} folds of cross-validation by recording; add recordings, group fewer files per `recording` in manifest.csv, or lower --folds",
            ds.root.display(),
            args.folds
        );
    }
    let set = FeatureSet::from_name(&args.features).context("--features")?;
    let rate = dataset_rate(&ds)?;
    let mut model_cfg = FeatureConfig::new(rate, set);
    model_cfg.frame_s = args.frame;
    model_cfg.speed_norm = args.speed_norm.map(|exponent| SpeedNorm {
        ref_kmh: args.speed_ref,
        exponent,
    });
    model_cfg.fixed_bands = args.fixed_bands;
    // The feature config's own validation refuses both options for the
    // paper sets (and bad exponents or reference speeds).
    model_cfg
        .validate()
        .context("--features / --speed-norm / --speed-ref / --fixed-bands")?;
    if args.classifier == "mlp" {
        check_lm_size(&args.hidden, model_cfg.dim(), ds.classes.len())?;
    }
    // Paper7: extract Paper20; the pruning runs in `fit` on each training set.
    let extract_cfg = if set == FeatureSet::Paper7 {
        FeatureConfig {
            set: FeatureSet::Paper20,
            ..model_cfg.clone()
        }
    } else {
        model_cfg.clone()
    };
    extract_cfg.validate().context("feature config")?;
    // the held-out folders, checked before the long part
    let frame_len = FeatureExtractor::new(&extract_cfg)
        .context("feature config")?
        .frame_len();
    check_held_out(
        args,
        &ds.classes,
        rate,
        frame_len,
        model_cfg.speed_norm.is_some(),
        only,
    )?;
    let identity: Vec<usize> = (0..ds.classes.len()).collect();
    let (data, dataset_id, excluded) = extract_dataset(
        &ds,
        &extract_cfg,
        args.hop,
        &identity,
        args.channel.get(),
        SetRole::Training,
    )?;
    // a held-out folder holding a training file (the training folder
    // itself, a copy of one of its files) is no held-out set
    if let Some((dir, f)) = dataset::first_known_file(&args.test, &dataset_id.files) {
        bail!(
            "--test {}: {} is also in the training set {} (same content): the held-out accuracy would count audio the model was trained on; hold out other recordings",
            dir.display(),
            f.display(),
            args.data.display()
        );
    }
    println!(
        "{} frames of {} features ({} at {} Hz, hop {} s)",
        data.len(),
        data.dim,
        args.features,
        rate,
        args.hop
    );
    classes_left(&ds, &data, args.folds)?;
    let classes = ds.classes.clone();
    let dim = model_cfg.dim();
    let mut notes = Vec::new();
    if let Some(n) = excluded.summary("frame") {
        println!("{n}");
        notes.push(n);
    }
    // the vehicle speeds of the recordings that gave frames (the
    // manifest's `speed_kmh`), stored in the model (`meta.speeds`): the
    // drive summary and `grip sim` say when a drive runs outside them
    let training_speeds = training_speed_range(&ds, &data);
    match &training_speeds {
        Ok(r) => {
            let n = r.note();
            println!("{n} (written to the model)");
            notes.push(n);
        }
        Err(why) => println!(
            "{}: {why}; the drive summary and grip sim cannot say when a drive runs outside them",
            grip_arte::speeds::NOT_RECORDED
        ),
    }
    if let Some(n) = &model_cfg.speed_norm {
        let n = format!(
            "speed normalisation: frequencies warped by ({} km/h / v)^{}",
            n.ref_kmh, n.exponent
        );
        println!("{n}");
        notes.push(n);
    }
    let spec = match args.classifier.as_str() {
        "mlp" => {
            let lm = LmConfig {
                hidden: args.hidden.clone(),
                output: if args.output == "logistic" {
                    OutputKind::Logistic
                } else {
                    OutputKind::Softmax
                },
                epochs: args.epochs,
                max_rows: args.lm_max_rows,
                seed: args.seed,
                ..Default::default()
            };
            ClassifierSpec::Mlp {
                lm,
                val_fraction: args.val_fraction,
            }
        }
        _ => {
            let base = SvmConfig {
                seed: args.seed,
                ..Default::default()
            };
            let gammas: Vec<f64> = args.svm_gamma.iter().map(|g| g / dim as f64).collect();
            let chosen = if args.svm_c.len() * gammas.len() > 1 && args.folds >= 2 {
                println!(
                    "SVM grid search over C {:?} x gamma {:?} ({}-fold CV by recording)",
                    args.svm_c, gammas, args.folds
                );
                let fast = SvmConfig {
                    prob_folds: 0,
                    ..base.clone()
                };
                let (best, _) = grid_search_svm(
                    &classes,
                    &model_cfg,
                    &fast,
                    args.svm_max_per_class,
                    &args.svm_c,
                    &gammas,
                    &data,
                    args.folds,
                    args.seed,
                    |p| println!("  C {:>8} gamma {:>10.5}: {}", p.c, p.gamma, p.metrics),
                )?;
                best
            } else {
                let gamma = gammas.first().copied().unwrap_or(1.0 / dim as f64);
                SvmConfig {
                    c: args.svm_c.first().copied().unwrap_or(10.0),
                    kernel: Kernel::Rbf { gamma },
                    ..base.clone()
                }
            };
            let cfg = SvmConfig {
                prob_folds: base.prob_folds,
                ..chosen
            };
            if let Kernel::Rbf { gamma } = cfg.kernel {
                notes.push(format!("svm: C = {}, gamma = {gamma}", cfg.c));
                println!("SVM: C = {}, gamma = {gamma}", cfg.c);
            }
            ClassifierSpec::Svm {
                cfg,
                max_per_class: args.svm_max_per_class,
            }
        }
    };
    let mut report = String::new();
    let _ = writeln!(report, "`{}`\n", args.command_line());
    if let Some(n) = excluded.summary("frame") {
        let _ = writeln!(report, "{n}\n");
    }
    let cv = if args.folds >= 2 {
        let pb = busy(
            ProgressBar::new(args.folds as u64),
            "{prefix} [{bar:30}] {pos}/{len} folds, {elapsed}",
            format!("{}-fold cross-validation by recording", args.folds),
        );
        let conf = cross_validate_with(
            &classes,
            &model_cfg,
            &spec,
            &data,
            args.folds,
            args.seed,
            |k, _| pb.set_position(k as u64),
        );
        pb.finish_and_clear();
        let conf = conf?;
        let e = summary(
            format!("{}-fold cross-validation by recording", args.folds),
            conf,
        );
        print_eval(&mut report, &e.what.clone(), &e);
        Some(e)
    } else {
        None
    };
    let pb = busy(
        ProgressBar::new_spinner(),
        "{prefix} {spinner} {elapsed}",
        format!("fitting the model on all {} frames", data.len()),
    );
    let fitted = fit_with_split(&classes, &model_cfg, &spec, &data);
    pb.finish_and_clear();
    let (mut model, fit_report, split) = fitted?;
    match &fit_report {
        FitReport::Mlp(r) => {
            let n = format!(
                "lm: {} epochs, stopped at {}, best epoch {}, train MSE {:.5}, rows {}",
                r.epochs,
                r.stop,
                r.best_epoch,
                r.train_mse.last().copied().unwrap_or(f64::NAN),
                r.rows_used
            );
            println!("\nfinal fit: {n}");
            notes.push(n);
        }
        FitReport::Svm(r) => {
            let n = format!(
                "svm: {} support vectors, {} SMO iterations, {} capped pairs",
                r.n_sv, r.iterations, r.capped_pairs
            );
            println!("\nfinal fit: {n}");
            notes.push(n);
        }
    }
    if model.feature_config().set == FeatureSet::Paper7 {
        let names = model.feature_config().names();
        let n = format!(
            "paper7 selection: features {} = {}",
            model
                .feature_config()
                .selection
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", "),
            names.join(", ")
        );
        println!("{n}");
        notes.push(n);
    }
    println!("classifier: {}", model.classifier().describe());
    // what the file written does, on the final fit's own frames (the
    // cross-validation above scored other models); a useless fit is
    // refused before anything is written
    let check = FitCheck::new(&model, &fit_report, &data, &split)
        .context("the final model on its own frames")?;
    let (lines, note) = own_frames(&check, args);
    for l in &lines {
        println!("{l}");
    }
    let _ = writeln!(report, "\n{}\n", lines.join("\n"));
    notes.push(note);
    let problems = check.problems();
    if !problems.is_empty() {
        let what = problems
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("; and ");
        if !args.allow_poor_fit {
            bail!("{}", poor_fit_error(args, &ds, &check, &problems, &what));
        }
        let n = format!("written with --allow-poor-fit although {what}");
        eprintln!("warning: {n}");
        let _ = writeln!(report, "\n**warning**: {n}\n");
        notes.push(n);
    }
    let _ = writeln!(
        report,
        "\nclassifier: {}; {}\n",
        model.classifier().describe(),
        notes.join("; ")
    );
    model.meta.seed = args.seed;
    model.meta.dataset_hash = dataset_id.hash;
    model.meta.training_files = dataset_id.files;
    model.meta.date = args.date.clone().unwrap_or_else(today);
    model.meta.profile = args.profile.clone();
    model.meta.command = args.command_line();
    model.meta.notes = notes;
    model.meta.cv = cv;
    model.meta.speeds = training_speeds.ok();
    for dir in &args.test {
        let (conf, smooth, excluded) =
            evaluate_folder(&model, dir, args.hop, only, args.window, args.channel.get())?;
        if let Some(n) = excluded.summary("frame") {
            println!("\nheld-out {}: {n}", dir.display());
            let _ = writeln!(report, "\nheld-out {}: {n}", dir.display());
        }
        let e = summary(format!("held-out {}, per frame", dir.display()), conf);
        print_eval(&mut report, &e.what.clone(), &e);
        if args.window > 1 {
            let e = summary(
                format!(
                    "held-out {}, probabilities averaged over {} frames",
                    dir.display(),
                    args.window
                ),
                smooth,
            );
            print_eval(&mut report, &e.what.clone(), &e);
        }
    }
    if !args.calib_data.is_empty() {
        let (cal, rep) = super::calibrate::fit_calibration(
            &model,
            &args.calib_data,
            &args.calib,
            &args.command_line(),
            args.channel.get(),
        )?;
        report.push_str(&rep);
        model = model.with_calibration(Some(cal))?;
    }
    Ok((model, report))
}

/// The lines `grip train` prints about the final model on its own frames
/// (training and validation, with what always answering the most common
/// class scores), and the note stored in the model.
fn own_frames(check: &FitCheck, args: &Args) -> (Vec<String>, String) {
    let classes = check.train.classes();
    let tm = check.train.metrics();
    let share = 100.0 * check.majority.1 as f64 / check.train.total().max(1) as f64;
    let mut lines = vec![
        format!(
            "the written model on the final fit's own frames (not the cross-validation{}):",
            if args.folds >= 2 {
                " above, which scores models fitted without the test recordings"
            } else {
                ""
            }
        ),
        format!(
            "  training frames ({} recordings): {tm} (always answering the most common class, `{}`: {share:.2} %)",
            check.train_recordings, classes[check.majority.0]
        ),
    ];
    let mut note = format!(
        "written model on its own frames: training accuracy {:.2} % (n = {})",
        100.0 * tm.accuracy,
        tm.n
    );
    match &check.val {
        Some(v) => {
            let vm = v.metrics();
            lines.push(format!(
                "  validation frames ({} recordings held out for early stopping): {vm}",
                check.val_recordings
            ));
            let _ = write!(
                note,
                ", validation accuracy {:.2} % (n = {})",
                100.0 * vm.accuracy,
                vm.n
            );
        }
        None => lines.push(format!(
            "  validation frames: none ({})",
            if args.classifier != "mlp" {
                "the SVM fit holds no recordings out"
            } else if args.val_fraction > 0.0 {
                "every class has a single recording, none held out"
            } else {
                "--val-fraction 0"
            }
        )),
    }
    (lines, note)
}

/// The error for a final fit not worth writing (`what`: its
/// [`PoorFit`]s): what happened, the data it had, and the ways out (the
/// options that change the written model; `--folds` does not).
fn poor_fit_error(
    args: &Args,
    ds: &Dataset,
    check: &FitCheck,
    problems: &[PoorFit],
    what: &str,
) -> String {
    let per_class = ds.recordings_per_class();
    let (lo, hi) = (
        per_class.iter().copied().min().unwrap_or(0),
        per_class.iter().copied().max().unwrap_or(0),
    );
    let recs = if lo == hi {
        format!("{lo}")
    } else {
        format!("{lo}-{hi}")
    };
    let frames = check.train.total() + check.val.as_ref().map_or(0, |v| v.total());
    let mut ways = vec![
        "more recordings per class (`grip dataset synth --recordings-per-class`)".to_owned(),
        "longer recordings (`--duration`)".to_owned(),
    ];
    let kept = problems
        .iter()
        .any(|p| matches!(p, PoorFit::KeptInitialWeights(_)));
    if args.classifier == "mlp" {
        if kept && check.val.is_some() {
            ways.push(format!(
                "--val-fraction 0 (no early stopping: every recording trains, up to --epochs; the validation held out {} of the {} recordings)",
                check.val_recordings,
                check.val_recordings + check.train_recordings
            ));
        }
        if args.epochs == 0 {
            ways.push("--epochs above 0".to_owned());
        } else {
            ways.push(format!(
                "another --seed (initial weights, {} now) or --hidden, --epochs ({} now)",
                args.seed, args.epochs
            ));
        }
        ways.push("--classifier svm".to_owned());
    } else {
        ways.push("other --svm-c / --svm-gamma, or --features rich".to_owned());
    }
    let data = if args.classifier == "mlp" && args.epochs == 0 {
        String::new()
    } else {
        format!(
            " The data has {recs} recording(s) per class, {frames} frames: likely too few, or too alike, for this fit."
        )
    };
    format!(
        "--data {}: {what}. Not writing --out {}.{data} Ways out: {}; --folds changes only the cross-validation, not the written model. --allow-poor-fit writes the model anyway",
        ds.root.display(),
        args.out.display(),
        ways.join(", ")
    )
}

/// An output file named by `flag` (`--out`, `--report`, `--candump`, ...),
/// checked before any work: refused, naming the file and the reason, when
/// it is a directory, when the folder it would go in does not exist (or is
/// no folder: nothing is created on the way), and, unless `force`, when
/// something is there already. Every subcommand's output file goes
/// through it.
pub(crate) fn check_output_file(flag: &str, path: &Path, force: bool) -> Result<()> {
    if path.as_os_str().is_empty() {
        bail!("{flag}: the path is empty; name a file");
    }
    if path.is_dir() {
        bail!(
            "{flag} {}: is a directory, not a file; name a file (e.g. {})",
            path.display(),
            path.join("NAME").display()
        );
    }
    let folder = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    match std::fs::metadata(folder) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => bail!(
            "{flag} {}: {} is not a folder",
            path.display(),
            folder.display()
        ),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!(
            "{flag} {}: the folder {} does not exist; create it first, or name a file in an existing folder",
            path.display(),
            folder.display()
        ),
        Err(e) => bail!(
            "{flag} {}: the folder {}: {e}",
            path.display(),
            folder.display()
        ),
    }
    if !force && std::fs::symlink_metadata(path).is_ok() {
        bail!(
            "{flag} {}: the file already exists; pass --force to overwrite it, or name another file",
            path.display()
        );
    }
    Ok(())
}

/// `--out` and `--report` (said before the training, not after it; a
/// report at the model's own path would replace the model).
fn check_out(args: &Args) -> Result<()> {
    check_output_file("--out", &args.out, args.force)?;
    if let Some(r) = &args.report {
        if r == &args.out
            || std::fs::canonicalize(r)
                .is_ok_and(|r| std::fs::canonicalize(&args.out).is_ok_and(|o| o == r))
        {
            bail!(
                "--report {}: the same file as --out: the report would replace the model; name another file",
                r.display()
            );
        }
        check_output_file("--report", r, args.force)?;
    }
    Ok(())
}

pub fn run(ctx: &Ctx, args: Args) -> Result<()> {
    check_out(&args)?;
    let out = args.out.clone();
    let (model, report) = train(&ctx.config_dir, &args)?;
    let bytes = model.to_bytes()?;
    // the check again (a file may have appeared, or the folder gone,
    // during the training)
    let replaced = std::fs::symlink_metadata(&out).is_ok();
    check_output_file("--out", &out, args.force)?;
    std::fs::write(&out, &bytes)
        .with_context(|| format!("cannot write model {}", out.display()))?;
    let full = std::fs::canonicalize(&out).unwrap_or_else(|_| out.clone());
    println!(
        "\nwrote model {}{}{} ({} bytes, file sha256 {}...)",
        out.display(),
        if full != out {
            format!(" ({})", full.display())
        } else {
            String::new()
        },
        if replaced {
            ", replacing the file there (--force)"
        } else {
            ""
        },
        bytes.len(),
        &sha256_hex(&bytes)[..16]
    );
    if let Some(r) = &args.report {
        check_output_file("--report", r, args.force)?;
        std::fs::write(r, &report)
            .with_context(|| format!("cannot write report {}", r.display()))?;
        println!("wrote report {}", r.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use grip_arte::synth::{ROADS, Segment, SynthConfig, render};

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    impl Cli {
        /// The trainer's arguments from `argv`, with `--out` (required) set
        /// to a file these tests never write (they call `train`, not `run`)
        /// unless `argv` gives one.
        fn parse_from<I, T>(argv: I) -> Self
        where
            I: IntoIterator<Item = T>,
            T: Into<std::ffi::OsString>,
        {
            let mut v: Vec<std::ffi::OsString> = argv.into_iter().map(Into::into).collect();
            if !v.iter().any(|a| a == "--out") {
                v.extend(["--out".into(), "never-written.model".into()]);
            }
            <Self as Parser>::parse_from(v)
        }
    }

    /// The frames of [`make_dataset`]'s set at `dir` as a training set
    /// (16 kHz, `paper20`, 0.1 s frames and hop, three classes).
    fn extract_test_set(dir: &Path) -> Result<Samples> {
        let ds = Dataset::scan(dir).unwrap();
        let mut cfg = FeatureConfig::new(16_000, FeatureSet::Paper20);
        cfg.frame_s = 0.1;
        let map: Vec<usize> = (0..3).collect();
        extract_dataset(
            &ds,
            &cfg,
            0.1,
            &map,
            grip_io::wav::Channel::Average,
            SetRole::Training,
        )
        .map(|(s, _, _)| s)
    }

    /// 3 roads × 5 recordings × 1 s at 16 kHz.
    fn make_dataset(dir: &Path) {
        make_dataset_seeded(dir, 0);
    }

    /// [`make_dataset`] with the synthesis seeds moved by `seed0` (other
    /// audio of the same roads).
    fn make_dataset_seeded(dir: &Path, seed0: u64) {
        let cfg = SynthConfig {
            sample_rate: 16_000,
            noise: None,
        };
        for road in ["asphalt", "gravel", "snow"] {
            let r = ROADS.iter().position(|n| *n == road).unwrap();
            std::fs::create_dir_all(dir.join(road)).unwrap();
            for k in 0..5u64 {
                let speed = (10.0 + 4.0 * k as f64) / 3.6;
                let x = render(
                    &cfg,
                    100 * r as u64 + k + seed0,
                    &[Segment {
                        road: r,
                        speed_mps: speed,
                        duration_s: 1.0,
                    }],
                )
                .unwrap();
                let spec = hound::WavSpec {
                    channels: 1,
                    sample_rate: 16_000,
                    bits_per_sample: 16,
                    sample_format: hound::SampleFormat::Int,
                };
                let mut w =
                    hound::WavWriter::create(dir.join(road).join(format!("r{k}.wav")), spec)
                        .unwrap();
                for v in x {
                    w.write_sample((v * 32767.0) as i16).unwrap();
                }
                w.finalize().unwrap();
            }
        }
    }

    #[test]
    fn training_twice_gives_identical_model_bytes() {
        let d = tempfile::tempdir().unwrap();
        make_dataset(d.path());
        for extra in [
            &["--classifier", "mlp", "--features", "paper7"][..],
            &[
                "--classifier",
                "svm",
                "--features",
                "rich",
                "--svm-c",
                "1,10",
            ],
        ] {
            let mut argv = vec![
                "t",
                "--data",
                d.path().to_str().unwrap(),
                "--folds",
                "5",
                "--date",
                "2026-01-01",
                "--hop",
                "0.05",
            ];
            argv.extend_from_slice(extra);
            let args = Cli::parse_from(&argv).args;
            let (a, _) = train(d.path(), &args).unwrap();
            let (b, _) = train(d.path(), &args).unwrap();
            let (ba, bb) = (a.to_bytes().unwrap(), b.to_bytes().unwrap());
            assert_eq!(ba, bb, "{extra:?}: model bytes differ between two runs");
            assert_eq!(a.classes(), ["asphalt", "gravel", "snow"]);
            let cv = a.meta.cv.as_ref().unwrap();
            assert_eq!(cv.metrics.n as usize, 3 * 5 * 19);
            let back = Model::from_bytes(&ba).unwrap();
            assert_eq!(back, a);
        }
    }

    /// The arguments of a quick training run on `data`: no
    /// cross-validation, a fixed date.
    fn no_cv(data: &Path) -> Vec<&str> {
        let data = data.to_str().unwrap();
        vec!["t", "--data", data, "--folds", "0", "--date", "2026-01-01"]
    }

    /// Two change recordings (asphalt, gravel, snow segments) at 16 kHz.
    fn make_changes(dir: &Path) {
        let cfg = SynthConfig {
            sample_rate: 16_000,
            noise: None,
        };
        std::fs::create_dir_all(dir).unwrap();
        let mut csv = String::from("file,t_start,t_end,road,speed_kmh,seed,noise,snr_db\n");
        for k in 0..2u64 {
            let roads = ["asphalt", "gravel", "snow"];
            let segs: Vec<Segment> = roads
                .iter()
                .map(|r| Segment {
                    road: ROADS.iter().position(|n| n == r).unwrap(),
                    speed_mps: 4.0,
                    duration_s: 0.6,
                })
                .collect();
            let x = render(&cfg, 900 + k, &segs).unwrap();
            let name = format!("c{k}.wav");
            grip_io::wav::write_mono_i16(&dir.join(&name), 16_000, &x).unwrap();
            for (i, r) in roads.iter().enumerate() {
                let t = 0.6 * i as f64;
                csv.push_str(&format!("{name},{t},{},{r},14.4,,,\n", t + 0.6));
            }
        }
        std::fs::write(dir.join("segments.csv"), csv).unwrap();
    }

    #[test]
    fn training_with_calib_data_stores_a_calibration_and_keeps_the_classifier() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data);
        let changes = d.path().join("changes");
        make_changes(&changes);
        let mut base = no_cv(&data);
        base.extend_from_slice(&["--hop", "0.05", "--classifier", "mlp"]);
        base.extend_from_slice(&["--features", "paper7"]);
        let plain = train(d.path(), &Cli::parse_from(&base).args).unwrap().0;
        assert_eq!(plain.format_version(), 1);
        let mut argv = base.to_vec();
        argv.extend_from_slice(&["--calib-data", changes.to_str().unwrap()]);
        argv.extend_from_slice(&["--calib-method", "platt"]);
        let args = Cli::parse_from(&argv).args;
        let (a, report) = train(d.path(), &args).unwrap();
        let (b, _) = train(d.path(), &args).unwrap();
        assert_eq!(a.to_bytes().unwrap(), b.to_bytes().unwrap());
        assert_eq!(a.format_version(), 2);
        let cal = a.calibration().unwrap();
        assert!(
            matches!(cal.map, grip_arte::calib::Calibration::Platt { .. }),
            "{:?}",
            cal.map
        );
        assert!(report.contains("ECE (10 equal-width bins)"), "{report}");
        // the stream settings as a user reads them (not `Hmm { stay: .. }`)
        assert!(
            report.contains("smoothing: HMM, stay 0.9, floor 0.01") && !report.contains("Hmm {"),
            "{report}"
        );
        // the training files by content, for `grip calibrate`'s check
        assert_eq!(a.meta.training_files.len(), 15);
        let r0 = std::fs::read(data.join("asphalt/r0.wav")).unwrap();
        assert!(
            a.meta
                .training_files
                .binary_search(&dataset::file_id(&sha256_hex(&r0)))
                .is_ok()
        );
        assert!(report.contains("| confidence | decisions |"), "{report}");
        assert!(
            a.meta.command.contains("--calib-data"),
            "{}",
            a.meta.command
        );
        // The classifier is the one trained without --calib-data.
        assert_eq!(a.classifier(), plain.classifier());
        assert_eq!(a.standardiser(), plain.standardiser());
        let back = Model::from_bytes(&a.to_bytes().unwrap()).unwrap();
        assert_eq!(back, a);
        // A calibration folder that is not one is a clear error.
        let not_changes = d.path().join("not-changes");
        make_dataset(&not_changes);
        let mut argv = base.to_vec();
        argv.extend_from_slice(&["--calib-data", not_changes.to_str().unwrap()]);
        let e = format!(
            "{:#}",
            train(d.path(), &Cli::parse_from(&argv).args).unwrap_err()
        );
        assert!(e.contains("segments.csv"), "{e}");
        // The training data (or a folder in it) as calibration data is
        // refused before anything is trained: it is not held out.
        for calib in [data.clone(), data.join("asphalt")] {
            let mut argv = base.to_vec();
            argv.extend_from_slice(&["--calib-data", calib.to_str().unwrap()]);
            let e = format!(
                "{:#}",
                train(d.path(), &Cli::parse_from(&argv).args).unwrap_err()
            );
            assert!(e.contains("held-out") && e.contains("--data"), "{e}");
        }
    }

    /// Too few recordings of a class for the folds: refused up front,
    /// naming the class folder (it was "class 2", after every feature).
    #[test]
    fn too_few_recordings_for_the_folds_names_the_class_folder() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data); // 5 recordings per class
        let a = Cli::parse_from(["t", "--data", data.to_str().unwrap(), "--folds", "6"]).args;
        let e = format!("{:#}", train(d.path(), &a).unwrap_err());
        assert!(
            e.contains("class folder `asphalt` has 5 recording(s)") && e.contains("6 folds"),
            "{e}"
        );
    }

    /// `--out` is required (it defaulted to `<config-dir>/models/trained.model`,
    /// in the repository's config when run from its root); an existing file
    /// is refused before any training unless `--force`, naming the file and
    /// the option.
    #[test]
    fn an_existing_out_is_refused_without_force() {
        let d = tempfile::tempdir().unwrap();
        let e = Cli::try_parse_from(["t", "--data", "x"])
            .map(|_| ())
            .unwrap_err();
        assert!(e.to_string().contains("--out"), "{e}");
        let out = d.path().join("my.model");
        std::fs::write(&out, b"mine").unwrap();
        let ctx = Ctx {
            config_dir: d.path().join("config"),
            config_dir_given: false,
        };
        let no_data = d.path().join("no-data");
        let argv = ["t", "--data", no_data.to_str().unwrap()];
        let argv = [&argv[..], &["--out", out.to_str().unwrap()]].concat();
        let e = format!("{:#}", run(&ctx, Cli::parse_from(&argv).args).unwrap_err());
        assert!(
            e.contains(&out.display().to_string())
                && e.contains("already exists")
                && e.contains("--force"),
            "{e}"
        );
        assert_eq!(std::fs::read(&out).unwrap(), b"mine");
        // with --force the file is no reason to stop (the data folder is)
        let argv = [&argv[..], &["--force"]].concat();
        let e = format!("{:#}", run(&ctx, Cli::parse_from(&argv).args).unwrap_err());
        assert!(e.contains("no-data") && !e.contains("--force"), "{e}");
        assert!(!ctx.config_dir.exists());
    }

    /// A speed-normalised model on recordings without speeds: the error
    /// says why (no manifest, no column, a blank field on line N).
    #[test]
    fn a_missing_speed_names_the_manifest_line_and_field() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data);
        let mut argv = no_cv(&data);
        argv.extend_from_slice(&["--features", "rich", "--speed-norm", "0.25"]);
        argv.extend_from_slice(&["--classifier", "svm"]);
        let e = |d: &Path| format!("{:#}", train(d, &Cli::parse_from(&argv).args).unwrap_err());
        assert!(
            e(d.path()).contains("has no manifest.csv"),
            "{}",
            e(d.path())
        );
        std::fs::write(
            data.join("manifest.csv"),
            "file,recording\nasphalt/r0.wav,1\n",
        )
        .unwrap();
        let m = data.join("manifest.csv").display().to_string();
        let got = e(d.path());
        assert!(
            got.contains(&format!("manifest {m} has no `speed_kmh` column")),
            "{got}"
        );
        std::fs::write(
            data.join("manifest.csv"),
            "file,speed_kmh\nasphalt/r0.wav,\n",
        )
        .unwrap();
        let got = e(d.path());
        assert!(
            got.contains("asphalt/r0.wav")
                && got.contains(&format!("manifest {m} line 2, field `speed_kmh`: blank")),
            "{got}"
        );
    }

    /// A class named in under half its frames is said, with what it is
    /// most often taken for; half or more, or no frames, is not.
    #[test]
    fn low_recall_names_the_class_and_what_it_is_taken_for() {
        let mut c = Confusion::new(vec!["asphalt".into(), "snow".into(), "gravel".into()]);
        // asphalt 9 of 10 right; snow 2 of 5 right, 3 taken for asphalt;
        // gravel 2 of 4 right (half: not low)
        for (p, a, n) in [
            (0, 0, 9),
            (2, 0, 1),
            (1, 1, 2),
            (0, 1, 3),
            (2, 2, 2),
            (1, 2, 2),
        ] {
            for _ in 0..n {
                c.add(p, a);
            }
        }
        assert_eq!(
            low_recall(&c),
            vec!["low recall: `snow` named in 40.0 % of its 5 frames, most often taken for `asphalt` (3 frames)".to_owned()]
        );
        assert!(low_recall(&Confusion::new(vec!["a".into(), "b".into()])).is_empty());
    }

    /// A held-out set without a class: its recall is `-`, not 0.0.
    #[test]
    fn a_class_without_frames_is_no_zero() {
        assert_eq!(
            recall_precision("stone", (0.0, 0), (0.0, 0)),
            "stone -/- (no frames)"
        );
        assert_eq!(recall_precision("snow", (0.0, 12), (0.0, 0)), "snow 0.0/-");
        assert_eq!(
            recall_precision("snow", (0.5, 12), (0.25, 4)),
            "snow 50.0/25.0"
        );
        // a class with no frames that was decided (wrongly): its precision
        assert_eq!(
            recall_precision("ice", (0.0, 0), (0.0, 3)),
            "ice -/0.0 (no frames)"
        );
    }

    /// The model records its training speeds (`meta.speeds`) from the
    /// manifest's `speed_kmh` of every training recording, and notes them;
    /// without a manifest it records none, and says so.
    #[test]
    fn the_model_records_the_training_speeds_of_the_manifest() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data);
        let mut argv = no_cv(&data);
        argv.extend_from_slice(&["--hop", "0.05", "--classifier", "mlp"]);
        let args = Cli::parse_from(&argv).args;
        let (m, _) = train(d.path(), &args).unwrap();
        assert_eq!(m.meta.speeds, None);
        assert_eq!(
            m.training_speeds(),
            grip_arte::speeds::TrainingSpeeds::NotRecorded
        );
        let mut csv = String::from("file,road,speed_kmh\n");
        for road in ["asphalt", "gravel", "snow"] {
            for k in 0..5 {
                csv.push_str(&format!("{road}/r{k}.wav,{road},{}\n", 10 + 4 * k));
            }
        }
        std::fs::write(data.join("manifest.csv"), csv).unwrap();
        let (m, report) = train(d.path(), &args).unwrap();
        assert_eq!(m.meta.speeds, SpeedRange::new(10.0, 26.0));
        assert!(
            m.meta
                .notes
                .contains(&"training speeds: 10.0-26.0 km/h".to_owned()),
            "{:?}",
            m.meta.notes
        );
        assert!(
            report.contains("training speeds: 10.0-26.0 km/h"),
            "{report}"
        );
        let back = Model::from_bytes(&m.to_bytes().unwrap()).unwrap();
        assert_eq!(back.meta.speeds, m.meta.speeds);
        // a recording without a speed: none recorded
        std::fs::write(
            data.join("manifest.csv"),
            "file,road,speed_kmh\nasphalt/r0.wav,asphalt,12\n",
        )
        .unwrap();
        let (m, _) = train(d.path(), &args).unwrap();
        assert_eq!(m.meta.speeds, None);
    }

    /// A hop past 10 s is refused by name (1e20 s wrapped the frame's end
    /// and panicked on the slice).
    #[test]
    fn a_hop_beyond_ten_seconds_is_refused() {
        for hop in ["1e20", "0", "-1", "NaN"] {
            let hop = format!("--hop={hop}");
            let a = Cli::parse_from(["t", "--data", "no-such-dir", &hop]).args;
            let e = format!("{:#}", train(Path::new("."), &a).unwrap_err());
            assert!(
                e.contains("--hop") && e.contains("outside (0, 10]"),
                "{hop}: {e}"
            );
        }
    }

    /// Writes `x` (mono) or the pair (`x`, −`x`) as 16-bit at 16 kHz.
    fn write_16k(path: &Path, x: &[f32], opposite_pair: bool) {
        let spec = hound::WavSpec {
            channels: if opposite_pair { 2 } else { 1 },
            sample_rate: 16_000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        for &v in x {
            let s = (v * 32767.0) as i16;
            w.write_sample(s).unwrap();
            if opposite_pair {
                w.write_sample(-s).unwrap();
            }
        }
        w.finalize().unwrap();
    }

    /// A silent file and a stereo pair in opposite phase (silence when
    /// averaged) are left out of training as the arte service would refuse
    /// them, named in the report; `--channel 0` reads the pair's first
    /// channel, which is road sound; a channel the files lack is an error
    /// naming the file and its channel count; a dataset of nothing but
    /// refused audio is an error naming the folder. (Before, the silent
    /// frames were trained on as asphalt.)
    #[test]
    fn audio_the_service_would_refuse_is_left_out_of_training() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data);
        write_16k(&data.join("asphalt/silent.wav"), &[0.0; 16_000], false);
        let road = grip_io::wav::read_mono(&data.join("gravel/r0.wav")).unwrap();
        write_16k(&data.join("gravel/pair.wav"), &road.samples, true);
        let base = no_cv(&data);
        let (m, report) = train(d.path(), &Cli::parse_from(&base).args).unwrap();
        // 3 roads x 5 recordings x 10 frames: the two added files add none
        assert!(report.contains("2 file(s) entirely"), "{report}");
        assert!(
            report.contains("asphalt/silent.wav") && report.contains("gravel/pair.wav"),
            "{report}"
        );
        assert!(report.contains("20 of 170 frames (silence 20)"), "{report}");
        assert!(m.meta.notes.iter().any(|n| n.contains("silent.wav")));
        // a held-out folder of nothing but silence: refused before the fit
        let quiet = d.path().join("quiet");
        for c in ["asphalt", "gravel"] {
            std::fs::create_dir_all(quiet.join(c)).unwrap();
            write_16k(&quiet.join(c).join("q.wav"), &[0.0; 16_000], false);
        }
        let mut argv = base.clone();
        argv.extend_from_slice(&["--test", quiet.to_str().unwrap()]);
        let e = format!(
            "{:#}",
            train(d.path(), &Cli::parse_from(&argv).args).unwrap_err()
        );
        assert!(
            e.contains("--test") && e.contains("quiet") && e.contains("would be excluded"),
            "{e}"
        );
        let mut argv = base.to_vec();
        argv.extend_from_slice(&["--channel", "1"]);
        let e = format!(
            "{:#}",
            train(d.path(), &Cli::parse_from(&argv).args).unwrap_err()
        );
        assert!(
            e.contains("asphalt/r0.wav") && e.contains("has 1 channel(s); channel 1"),
            "{e}"
        );
        // the pair by its first channel: all 10 frames kept
        let ds = Dataset::scan(&data).unwrap();
        let cfg = FeatureConfig::new(16_000, FeatureSet::Paper20);
        let map: Vec<usize> = (0..3).collect();
        let pair = |c| {
            let only = Dataset {
                entries: ds
                    .entries
                    .iter()
                    .filter(|e| e.rel == "gravel/pair.wav")
                    .cloned()
                    .collect(),
                ..ds.clone()
            };
            extract_dataset(&only, &cfg, 0.1, &map, c, SetRole::Training)
                .map_err(|e| format!("{e:#}"))
        };
        let (s, _, ex) = pair(grip_io::wav::Channel::One(0)).unwrap();
        assert_eq!((s.len(), ex.frames()), (10, 0));
        // averaged, nothing is left: an error naming the folder
        let e = pair(grip_io::wav::Channel::Average).unwrap_err();
        assert!(
            e.contains(&data.display().to_string())
                && e.contains("every frame of every file was excluded")
                && e.contains("gravel/pair.wav"),
            "{e}"
        );
    }

    /// `grip dataset synth ARGS` in-process.
    fn dataset_synth(argv: &[&str]) {
        #[derive(Parser)]
        struct DatasetCli {
            #[command(flatten)]
            args: super::super::dataset::Args,
        }
        let ctx = Ctx {
            config_dir: PathBuf::from("config"),
            config_dir_given: false,
        };
        let argv = [&["t", "synth"][..], argv].concat();
        super::super::dataset::run(&ctx, DatasetCli::parse_from(argv).args).unwrap();
    }

    /// The user trial: `grip dataset synth --recordings-per-class 2
    /// --duration 2 --roads asphalt,snow,gravel,stone`, then `grip train
    /// --epochs 100`: the final fit's validation error never fell (`best
    /// epoch 0`) and the random initial network was written (it called
    /// every asphalt frame snow), while the cross-validation printed
    /// 70.6 %. Now an error naming what happened and the ways out, and
    /// nothing written (model or report); `--allow-poor-fit` writes it,
    /// noted in the model. And recordings that are all the same sound: no
    /// model can beat always answering the most common class, refused too.
    #[test]
    fn a_fit_that_never_left_its_initial_weights_is_refused_and_nothing_written() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("ds");
        let roads = "asphalt,snow,gravel,stone";
        let tiny = [
            "--recordings-per-class",
            "2",
            "--duration",
            "2",
            "--roads",
            roads,
        ];
        dataset_synth(&[&["--out", data.to_str().unwrap()][..], &tiny].concat());
        let out = d.path().join("m2.model");
        let report = d.path().join("m2-report.txt");
        let ctx = Ctx {
            config_dir: d.path().to_path_buf(),
            config_dir_given: true,
        };
        let mut argv = no_cv(&data);
        argv.extend_from_slice(&["--epochs", "100", "--out", out.to_str().unwrap()]);
        argv.extend_from_slice(&["--report", report.to_str().unwrap()]);
        let e = match run(&ctx, Cli::parse_from(&argv).args) {
            Err(e) => format!("{e:#}"),
            Ok(()) => panic!(
                "the user trial's data trained (synthesis, features or LM changed since): choose a --seed of `grip dataset synth` whose final fit keeps its initial weights; grip-arte's tests/model.rs tests the rule itself"
            ),
        };
        for want in [
            "never improved on its random initial weights",
            "best epoch 0",
            "untrained initial network",
            &format!("Not writing --out {}", out.display()),
            "2 recording(s) per class",
            "--recordings-per-class",
            "--duration",
            "--val-fraction 0",
            "--folds changes only the cross-validation",
            "--allow-poor-fit",
        ] {
            assert!(e.contains(want), "{want:?} not in: {e}");
        }
        assert!(e.contains(&data.display().to_string()), "{e}");
        assert!(!out.exists() && !report.exists(), "something was written");
        // written on request, and the model says so
        argv.push("--allow-poor-fit");
        run(&ctx, Cli::parse_from(&argv).args).unwrap();
        let m = Model::from_bytes(&std::fs::read(&out).unwrap()).unwrap();
        assert!(
            m.meta.notes.iter().any(|n| n.starts_with(
                "written with --allow-poor-fit although the final fit never improved"
            )),
            "{:?}",
            m.meta.notes
        );
        assert!(m.meta.command.contains("--allow-poor-fit"));
        // every recording the same sound: nothing to learn, whatever the
        // numbers of synthesis and training. Byte-identical copies are
        // refused as such (the same audio under two roads); so each file
        // is the sound less a few samples of its end (n-th file: n fewer),
        // a different file with the same frames.
        let same = d.path().join("same");
        let src = data.join("gravel/gravel_0000.wav");
        let mut reader = hound::WavReader::open(&src).unwrap();
        let spec = reader.spec();
        let samples: Vec<i32> = reader.samples::<i32>().map(Result::unwrap).collect();
        let mut n = 0;
        for road in roads.split(',') {
            std::fs::create_dir_all(same.join(road)).unwrap();
            for k in 0..2 {
                let to = same.join(road).join(format!("{road}_{k}.wav"));
                if n == 0 {
                    std::fs::copy(&src, &to).unwrap();
                } else {
                    let mut w = hound::WavWriter::create(&to, spec).unwrap();
                    for &v in &samples[..samples.len() - n] {
                        w.write_sample(v).unwrap();
                    }
                    w.finalize().unwrap();
                }
                n += 1;
            }
        }
        let out = d.path().join("same.model");
        let mut argv = no_cv(&same);
        argv.extend_from_slice(&["--out", out.to_str().unwrap()]);
        // a byte-for-byte copy under another road is refused first
        let copy = same.join("snow/copy.wav");
        std::fs::copy(&src, &copy).unwrap();
        let e = format!("{:#}", run(&ctx, Cli::parse_from(&argv).args).unwrap_err());
        assert!(
            e.contains("is the same audio as") && e.contains("at most one label is right"),
            "{e}"
        );
        std::fs::remove_file(&copy).unwrap();
        let e = format!("{:#}", run(&ctx, Cli::parse_from(&argv).args).unwrap_err());
        assert!(
            e.contains("no better than always answering `asphalt`, the most common class")
                && e.contains("--allow-poor-fit"),
            "{e}"
        );
        assert!(!out.exists());
    }

    /// A normal training writes the model, and the figures of the written
    /// model on its own training and validation frames (printed; the
    /// report has the same lines, the model a note).
    #[test]
    fn a_normal_training_writes_the_model_and_its_own_accuracy() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data);
        let out = d.path().join("m.model");
        let report = d.path().join("m-report.txt");
        let ctx = Ctx {
            config_dir: d.path().to_path_buf(),
            config_dir_given: true,
        };
        let mut argv = no_cv(&data);
        argv.extend_from_slice(&["--out", out.to_str().unwrap()]);
        argv.extend_from_slice(&["--report", report.to_str().unwrap()]);
        run(&ctx, Cli::parse_from(&argv).args).unwrap();
        let m = Model::from_bytes(&std::fs::read(&out).unwrap()).unwrap();
        let note = m
            .meta
            .notes
            .iter()
            .find(|n| n.starts_with("written model on its own frames: training accuracy"))
            .unwrap_or_else(|| panic!("{:?}", m.meta.notes));
        assert!(note.contains(", validation accuracy"), "{note}");
        let r = std::fs::read_to_string(&report).unwrap();
        assert!(
            r.contains(
                "the written model on the final fit's own frames (not the cross-validation)"
            ) && r.contains("training frames (12 recordings): n = 120, accuracy")
                && r.contains(
                    "validation frames (3 recordings held out for early stopping): n = 30"
                )
                && r.contains("(always answering the most common class, `asphalt`: 33.33 %)"),
            "{r}"
        );
        // the figures are the written model's own
        let all = extract_test_set(&data).unwrap();
        let acc = m.evaluate(&all).unwrap().metrics().accuracy;
        assert!(acc > 0.8, "accuracy {acc}");
    }

    /// The same audio twice: under two labels, or as two recordings
    /// (cross-validation would test on what it trained on), is refused
    /// naming both files; as one recording of one road it is a warning.
    #[test]
    fn the_same_audio_twice_is_refused_unless_one_recording() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data);
        let extract = || {
            extract_test_set(&data)
                .map(|_| ())
                .map_err(|e| format!("{e:#}"))
        };
        extract().unwrap();
        let orig = data.join("asphalt/r0.wav");
        let copy = data.join("snow/r0-copy.wav");
        std::fs::copy(&orig, &copy).unwrap();
        let e = extract().unwrap_err();
        assert!(
            e.contains("snow/r0-copy.wav is the same audio as")
                && e.contains("asphalt/r0.wav")
                && e.contains("labelled `snow` and the other `asphalt`"),
            "{e}"
        );
        std::fs::remove_file(&copy).unwrap();
        let copy = data.join("asphalt/r0-copy.wav");
        std::fs::copy(&orig, &copy).unwrap();
        let e = extract().unwrap_err();
        assert!(
            e.contains("asphalt/r0.wav is the same audio as")
                && e.contains("asphalt/r0-copy.wav")
                && e.contains(
                    "in another recording: cross-validation would test on a clip it trained on"
                ),
            "{e}"
        );
        // one recording: allowed (a warning)
        std::fs::write(
            data.join("manifest.csv"),
            "file,recording\nasphalt/r0.wav,a\nasphalt/r0-copy.wav,a\n",
        )
        .unwrap();
        extract().unwrap();
    }

    /// A `--test` folder holding a training file (the training folder
    /// itself, or a copy of one file elsewhere) is refused before the fit,
    /// naming the file: its "held-out" accuracy would not be.
    #[test]
    fn a_test_folder_holding_training_audio_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data);
        let ctx = Ctx {
            config_dir: d.path().to_path_buf(),
            config_dir_given: true,
        };
        let out = d.path().join("m.model");
        let other = d.path().join("other");
        std::fs::create_dir_all(other.join("snow")).unwrap();
        std::fs::create_dir_all(other.join("asphalt")).unwrap();
        // a recording of its own, and a copy of a training file
        let tone: Vec<f32> = (0..16_000).map(|k| 0.3 * (k as f32 * 0.07).sin()).collect();
        grip_io::wav::write_mono_i16(&other.join("asphalt/new.wav"), 16_000, &tone).unwrap();
        std::fs::copy(data.join("snow/r3.wav"), other.join("snow/mine.wav")).unwrap();
        for (test, file) in [(&data, "asphalt/r0.wav"), (&other, "snow/mine.wav")] {
            let mut argv = no_cv(&data);
            argv.extend_from_slice(&["--out", out.to_str().unwrap()]);
            argv.extend_from_slice(&["--test", test.to_str().unwrap()]);
            let e = format!("{:#}", run(&ctx, Cli::parse_from(&argv).args).unwrap_err());
            assert!(
                e.contains(file)
                    && e.contains("is also in the training set")
                    && e.contains("held-out accuracy would count audio the model was trained on"),
                "{e}"
            );
            assert!(!out.exists(), "nothing written");
        }
    }

    /// Copies inside a held-out folder: under two roads refused before
    /// the fit, naming both; within one road (two recordings: no
    /// cross-validation runs on it) a warning, and the model is written.
    #[test]
    fn copies_inside_a_held_out_folder() {
        let d = tempfile::tempdir().unwrap();
        let data = d.path().join("data");
        make_dataset(&data);
        let held = d.path().join("held");
        make_dataset_seeded(&held, 50);
        let ctx = Ctx {
            config_dir: d.path().to_path_buf(),
            config_dir_given: true,
        };
        let out = d.path().join("m.model");
        let argv = |out: &Path| {
            let mut a = no_cv(&data);
            a.extend_from_slice(&["--out", out.to_str().unwrap()]);
            a.extend_from_slice(&["--test", held.to_str().unwrap()]);
            a.iter().map(|s| s.to_string()).collect::<Vec<_>>()
        };
        let copy = held.join("snow/copy.wav");
        std::fs::copy(held.join("asphalt/r0.wav"), &copy).unwrap();
        let e = format!(
            "{:#}",
            run(&ctx, Cli::parse_from(argv(&out)).args).unwrap_err()
        );
        assert!(
            e.contains("--test")
                && e.contains("snow/copy.wav is the same audio as")
                && e.contains("at most one label is right"),
            "{e}"
        );
        assert!(!out.exists());
        std::fs::remove_file(&copy).unwrap();
        std::fs::copy(
            held.join("asphalt/r0.wav"),
            held.join("asphalt/r0-copy.wav"),
        )
        .unwrap();
        run(&ctx, Cli::parse_from(argv(&out)).args).unwrap();
        assert!(out.exists());
    }

    #[test]
    fn civil_dates() {
        assert_eq!(civil_date(0), "1970-01-01");
        assert_eq!(civil_date(951_782_400), "2000-02-29");
        assert_eq!(civil_date(1_767_225_599), "2025-12-31");
        assert_eq!(civil_date(1_767_225_600), "2026-01-01");
        assert_eq!(today().len(), 10);
    }
}
