//! `grip calibrate`: fits the streaming estimator's confidence calibration
//! on road-change recordings and writes the model with it (format v2).
//!
//! The classifier, standardiser, feature config and metadata are kept byte
//! for byte; only the `calibration` field is added (or replaced). The
//! recordings must be neither the training set nor the set the result is
//! evaluated on (other seeds, other cars): a `--data` folder that is, holds
//! or lies in the model's training data (its `--data`, from the command
//! stored in the model) is refused ([`require_held_out`]), and so is one
//! holding a training file by content (`meta.training_files`, written by
//! `grip train` since 2026-12-05: the stored path is relative to where the
//! model was trained; [`require_not_training_files`]). `grip train
//! --calib-data DIR` runs the same step after training.
//!
//! Fitting data: the model, uncalibrated, runs through `StreamEstimator`
//! with the given stream settings (default: the arte service's, hop 0.025 s,
//! HMM stay 0.9, floor 0.01) in blocks of 1024 samples, each segment at its
//! speed; every decision is one sample: the smoothed posterior of the
//! decided road, and whether that road is the true one at the decision's
//! time (`t_end`). That is exactly what a controller receives. A decision
//! whose time lies in a gap between segments (or more than one hop past the
//! last) has no true road: it is left out, and the report says how many.
//!
//! Audio the arte service would refuse (`grip_arte::quality`: silence,
//! clipping) is treated as the service treats it: each 1024-sample block
//! is judged before it is pushed; a refused block gives no decision and the
//! estimator restarts at the next good one. The refused blocks are counted
//! in the report, each file's named in a warning; recordings of which
//! every block is refused are an error naming the folder. `--channel N`
//! reads one channel of multi-channel files (default: their average).

use super::Ctx;
use super::dataset::{ChangeRecording, read_changes, truth_file};
use crate::dataset::{ChannelArg, Excluded, FileJudge};
use anyhow::{Context, Result, bail};
use grip_arte::calib::{Calibration, Method, Reliability, StreamCalibration, gate_stats};
use grip_arte::model::{Model, Predictor};
use grip_arte::stream::{Smoothing, StreamConfig, StreamEstimator};
use grip_arte::stream_eval::{Judged, segment_at};
use grip_digest::sha256_hex;
use grip_io::wav;
use indicatif::ProgressBar;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Bins of the reliability tables and the ECE (equal width over [0, 1]).
pub const ECE_BINS: usize = 10;

#[derive(clap::Args, Clone, Debug)]
pub struct Args {
    /// Model file to calibrate.
    #[arg(long)]
    pub model: PathBuf,
    /// Folder of road-change recordings to fit on (segments.csv + WAVs, from
    /// `grip dataset synth --changes`); repeatable.
    #[arg(long, required = true)]
    pub data: Vec<PathBuf>,
    /// Output model file, in a folder that exists. An existing file (the
    /// input model too: calibrating in place) only with `--force`.
    #[arg(long)]
    pub out: PathBuf,
    /// Overwrite an existing `--out` file (e.g. the input model itself).
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub fit: FitArgs,
    #[command(flatten)]
    pub channel: ChannelArg,
}

/// How the calibration is fitted (shared with `grip train --calib-data`).
#[derive(clap::Args, Clone, Debug)]
pub struct FitArgs {
    /// Calibration map: isotonic, platt or temperature (all three are
    /// fitted and reported; this one is stored).
    #[arg(long, default_value = "isotonic", value_parser = ["isotonic", "platt", "temperature"])]
    pub calib_method: String,
    /// Stream hop (s) the calibration is fitted for (the arte service's).
    #[arg(long, default_value_t = 0.025)]
    pub calib_hop: f64,
    /// Stream HMM stay probability the calibration is fitted for, within
    /// (0, 1); 0 disables smoothing.
    #[arg(long, default_value_t = 0.9)]
    pub calib_stay: f64,
    /// Stream HMM floor the calibration is fitted for.
    #[arg(long, default_value_t = 0.01)]
    pub calib_floor: f64,
}

impl FitArgs {
    fn stream_config(&self) -> StreamConfig {
        StreamConfig {
            hop_s: self.calib_hop,
            smoothing: if self.calib_stay == 0.0 {
                Smoothing::None
            } else {
                Smoothing::Hmm {
                    stay: self.calib_stay,
                    floor: self.calib_floor,
                }
            },
        }
    }

    /// The stream settings as the fit's stream takes them, each refusal
    /// naming its flag, before anything is read or trained (`grip train`
    /// fits the calibration after its model: a `--calib-stay 1` was
    /// refused only then, in the stream's words).
    pub fn check(&self) -> Result<()> {
        if !(self.calib_hop > 0.0 && self.calib_hop <= 10.0) {
            bail!("--calib-hop {}: must be within (0, 10] s", self.calib_hop);
        }
        super::dataset::check_stay("--calib-stay", self.calib_stay)?;
        if self.calib_stay != 0.0 && !(self.calib_floor > 0.0 && self.calib_floor <= 1.0) {
            bail!(
                "--calib-floor {}: must be within (0, 1] (the least probability the HMM gives a class in a frame)",
                self.calib_floor
            );
        }
        Ok(())
    }

    /// The options as they appear on a command line.
    pub fn command_line(&self) -> String {
        format!(
            "--calib-method {} --calib-hop {} --calib-stay {} --calib-floor {}",
            self.calib_method, self.calib_hop, self.calib_stay, self.calib_floor
        )
    }
}

/// The stream's smoothing as a user reads it: `smoothing: HMM, stay 0.9,
/// floor 0.01` or `smoothing: none` (not Rust's `Hmm { stay: .. }`).
pub fn smoothing_text(s: &Smoothing) -> String {
    match s {
        Smoothing::None => "smoothing: none".to_owned(),
        Smoothing::Hmm { stay, floor } => format!("smoothing: HMM, stay {stay}, floor {floor}"),
    }
}

/// The samples of a block, as the arte service receives them.
const BLOCK: usize = 1024;

/// Runs the stream over one change recording (read by `channel`) as the
/// arte service would: its decisions in time order and its length (s).
/// Blocks the service would refuse ([`FileJudge`]) give no decision and
/// restart the estimator; they are added to `excluded`, the file named in
/// a warning.
pub fn stream_recording(
    est: &mut StreamEstimator<Predictor>,
    r: &ChangeRecording,
    sample_rate: u32,
    where_: &Path,
    channel: wav::Channel,
    excluded: &mut Excluded,
) -> Result<(Vec<Judged>, f64)> {
    let audio = wav::read_channel_at(&r.path, sample_rate, channel)?;
    est.reset();
    if est.speed_normalised() && r.segments.iter().any(|s| s.3.is_none()) {
        bail!(
            "{}: a segment of {} has no speed_kmh; the model is speed-normalised and needs the vehicle speed",
            truth_file(where_).display(),
            r.path.display(),
        );
    }
    let fs = f64::from(sample_rate);
    let mut dec: Vec<Judged> = Vec::new();
    let mut judge = FileJudge::new();
    // the recording's time (s) where the estimator last restarted: its
    // decisions' times count from there
    let mut since = 0.0;
    for (bi, b) in audio.samples.chunks(BLOCK).enumerate() {
        let t0 = (bi * BLOCK) as f64 / fs;
        if !judge.accept(b) {
            est.reset();
            since = t0 + b.len() as f64 / fs;
            continue;
        }
        est.set_speed(r.speed_at(t0).map(|v| v / 3.6));
        est.push(b, |d| {
            dec.push(Judged {
                t_start: since + d.t_start,
                t_end: since + d.t_end,
                class: d.class,
                raw_class: d.raw_class,
                confidence: d.confidence,
            });
        });
    }
    let name = r.path.display().to_string();
    judge.finish(&name, &audio, channel, "block", excluded);
    Ok((dec, audio.samples.len() as f64 / fs))
}

/// Every decision's confidence and whether it named the true road at its
/// time, over the change recordings in `dirs` (read by `channel`), how many
/// decisions were unjudged (no segment at their time: a gap, or more than
/// `hop_s` past the last segment), and the blocks left out as the arte
/// service would refuse them. `frame_s`: the model's frame (how far past
/// its file's end a segment may end).
pub fn outcomes(
    est: &mut StreamEstimator<Predictor>,
    classes: &[String],
    (sample_rate, frame_s, hop_s): (u32, f64, f64),
    dirs: &[PathBuf],
    channel: wav::Channel,
) -> Result<(Vec<f64>, Vec<bool>, usize, Excluded)> {
    let (mut conf, mut right, mut unjudged) = (Vec::new(), Vec::new(), 0);
    let mut excluded = Excluded::default();
    for dir in dirs {
        let recs = read_changes(dir, classes, frame_s)?;
        let pb = ProgressBar::new(recs.len() as u64);
        let mut here = Excluded::default();
        for r in &recs {
            let (dec, _) =
                pb.suspend(|| stream_recording(est, r, sample_rate, dir, channel, &mut here))?;
            for d in dec {
                if let Some((_, seg)) = segment_at(&r.segments, d.t_end, hop_s) {
                    conf.push(d.confidence);
                    right.push(d.class == seg.2);
                } else {
                    unjudged += 1;
                }
            }
            pb.inc(1);
        }
        pb.finish_and_clear();
        all_refused(dir, &here)?;
        excluded.merge(here);
    }
    Ok((conf, right, unjudged, excluded))
}

/// A recordings folder of which the audio-quality rule refused every block
/// is an error naming it.
pub fn all_refused(dir: &Path, excluded: &Excluded) -> Result<()> {
    if excluded.judged > 0 && excluded.frames() == excluded.judged {
        bail!(
            "{}: every block of every recording was excluded ({}); nothing is left to judge",
            dir.display(),
            excluded.summary("block").unwrap_or_default()
        );
    }
    Ok(())
}

/// The calibration recordings must be held out: a folder of `calib` that
/// is, holds or lies in one of `used` (the training data, a test set; each
/// with the option that named it) is refused, `flag` naming the option of
/// `calib` in the error. A confidence map fitted on what the classifier was
/// trained on is optimistic, and the controller's gate would trust wrong
/// roads. Paths are compared canonicalised (as given when they do not
/// exist).
pub fn require_held_out(flag: &str, calib: &[PathBuf], used: &[(&str, PathBuf)]) -> Result<()> {
    let canon = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let used: Vec<(&str, PathBuf)> = used.iter().map(|(f, u)| (*f, canon(u))).collect();
    for c in calib {
        let cc = canon(c);
        if let Some((what, u)) = used
            .iter()
            .find(|(_, u)| cc.starts_with(u) || u.starts_with(&cc))
        {
            bail!(
                "{flag} {}: it is (or holds, or lies in) {what} {}; the calibration must be fitted on held-out road-change recordings (other seeds: `grip dataset synth --changes N --seed S`), or the confidence it gives is optimistic",
                c.display(),
                u.display()
            );
        }
    }
    Ok(())
}

/// Why a calibration set cannot calibrate: all of its decisions right, or
/// all wrong (none to tell a trusted confidence from an untrusted one).
fn degenerate_set(right: &[bool]) -> Option<String> {
    let n_right = right.iter().filter(|&&r| r).count();
    let why = if n_right == right.len() {
        "every one of its decisions is right"
    } else if n_right == 0 {
        "every one of its decisions is wrong"
    } else {
        return None;
    };
    Some(format!(
        "the calibration set cannot calibrate: {why} ({} decisions), so nothing tells a confidence to trust from one not to, and the fitted map is a bound of its search, not a calibration. Fit on recordings with road changes, where the estimator is wrong for a while after each (`grip dataset synth --changes N`, or your own with a segments.csv)",
        right.len()
    ))
}

/// The calibration folders `calib` (each with every `.wav` under it,
/// hidden ones skipped) against the model's training files by content
/// (`meta.training_files`, from `grip train`): a file among them is
/// refused, naming it, wherever the folder lies (another working
/// directory, a copy, a moved folder). A model without the field (written
/// before it existed) passes; a folder that cannot be listed is left to
/// the reader of the recordings.
pub fn require_not_training_files(flag: &str, calib: &[PathBuf], model: &Model) -> Result<()> {
    if let Some((dir, f)) = crate::dataset::first_known_file(calib, &model.meta.training_files) {
        bail!(
            "{flag} {}: {} is one of the model's training recordings (same content; the model stores its training files' SHA-256); the calibration must be fitted on held-out road-change recordings (other seeds: `grip dataset synth --changes N --seed S`), or the confidence it gives is optimistic",
            dir.display(),
            f.display()
        );
    }
    Ok(())
}

/// The training data folder of a model, from the command stored in it
/// (`grip train --data DIR --classifier ...`); `None` when not recorded.
pub fn training_data(model: &Model) -> Option<PathBuf> {
    let cmd = &model.meta.command;
    let rest = &cmd[cmd.find(" --data ")? + " --data ".len()..];
    // the path may hold spaces: it ends where the next option starts
    let end = rest.find(" --").unwrap_or(rest.len());
    let dir = rest[..end].trim();
    (!dir.is_empty()).then(|| PathBuf::from(dir))
}

/// Reliability table of confidences against outcomes.
pub fn reliability(conf: &[f64], right: &[bool]) -> Reliability {
    let mut t = Reliability::new(ECE_BINS);
    for (&c, &r) in conf.iter().zip(right) {
        t.add(c, r);
    }
    t
}

/// One line: ECE and what gates 0.6 and 0.9 let through.
pub fn summary_line(conf: &[f64], right: &[bool]) -> String {
    let ece = reliability(conf, right).ece().unwrap_or(f64::NAN);
    let gate = |g: f64| match gate_stats(conf, right, g) {
        Some((share, Some(acc))) => format!(
            "gate {g}: {:.1} % pass, {:.2} % of them right",
            100.0 * share,
            100.0 * acc
        ),
        _ => format!("gate {g}: none pass"),
    };
    format!(
        "ECE ({ECE_BINS} equal-width bins) {ece:.4}; {}; {}",
        gate(0.6),
        gate(0.9)
    )
}

/// Fits the calibration of `model` on the change recordings in `dirs`
/// (read by `channel`); returns it and a Markdown report (also printed).
/// `command` is stored in the calibration's notes.
pub fn fit_calibration(
    model: &Model,
    dirs: &[PathBuf],
    fit: &FitArgs,
    command: &str,
    channel: wav::Channel,
) -> Result<(StreamCalibration, String)> {
    let method = Method::from_name(&fit.calib_method)
        .with_context(|| format!("--calib-method: `{}` is unknown", fit.calib_method))?;
    let scfg = fit.stream_config();
    let uncalibrated = model.clone().with_calibration(None)?;
    let fcfg = uncalibrated.feature_config().clone();
    let classes = uncalibrated.classes().to_vec();
    let mut est = StreamEstimator::new(Predictor::new(uncalibrated), &fcfg, &scfg)
        .context("--calib-hop / --calib-stay / --calib-floor")?;
    let (p, right, unjudged, excluded) = outcomes(
        &mut est,
        &classes,
        (fcfg.sample_rate, fcfg.frame_s, scfg.hop_s),
        dirs,
        channel,
    )?;
    if p.is_empty() {
        bail!(
            "the calibration recordings gave no decisions{}",
            if unjudged > 0 {
                format!(" with a labelled road ({unjudged} in gaps between segments)")
            } else {
                String::new()
            }
        );
    }
    let names: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    let mut report = String::new();
    let _ = writeln!(
        report,
        "\n**Confidence calibration** (stream hop {} s, {}), fitted on {} decisions of {} \
         (every decision against the true road at its time; in-sample figures, the held-out ones come from `grip dataset delay`):\n",
        scfg.hop_s,
        smoothing_text(&scfg.smoothing),
        p.len(),
        names.join(", ")
    );
    if unjudged > 0 {
        let _ = writeln!(
            report,
            "{unjudged} decisions unjudged (their time lies in a gap between segments or past the last one: no road is labelled there) and left out.\n"
        );
    }
    if let Some(n) = excluded.summary("block") {
        let _ = writeln!(report, "{n}; their blocks give no decision.\n");
    }
    // a set whose decisions are all right (or all wrong) says nothing of
    // how far to trust a confidence: the fit runs to a bound (one-road
    // recordings gave "temperature T = 0.0100, isotonic 1 knot")
    if let Some(w) = degenerate_set(&right) {
        eprintln!("warning: {w}");
        let _ = writeln!(report, "**Warning**: {w}\n");
    }
    let _ = writeln!(report, "- uncalibrated: {}", summary_line(&p, &right));
    let mut chosen = None;
    for m in Method::ALL {
        let map = Calibration::fit(m, &p, &right)?;
        let c: Vec<f64> = p.iter().map(|&v| map.apply(v)).collect();
        let _ = writeln!(
            report,
            "- {}{}: {}",
            map.describe(),
            if m == method { " (stored)" } else { "" },
            summary_line(&c, &right)
        );
        if m == method {
            chosen = Some((map, c));
        }
    }
    let (map, c) = chosen.context("the chosen method was not fitted")?;
    let _ = writeln!(
        report,
        "\nreliability before calibration ({ECE_BINS} equal-width bins):\n\n{}\nafter ({}):\n\n{}",
        reliability(&p, &right).to_markdown(),
        map.describe(),
        reliability(&c, &right).to_markdown()
    );
    print!("{report}");
    let notes = vec![
        format!(
            "fitted on {} ({} decisions{})",
            names.join(", "),
            p.len(),
            if unjudged > 0 {
                format!(", {unjudged} unjudged left out")
            } else {
                String::new()
            }
        ),
        format!("before: {}", summary_line(&p, &right)),
        format!("after (in-sample): {}", summary_line(&c, &right)),
        format!("command: {command}"),
    ];
    Ok((
        StreamCalibration {
            map,
            stream: scfg,
            notes,
            files: crate::dataset::file_ids(dirs),
        },
        report,
    ))
}

pub fn run(_ctx: &Ctx, a: Args) -> Result<()> {
    a.fit.check()?;
    // said before the fit, naming the input when it is the output
    if !a.force && same_file(&a.model, &a.out) {
        bail!(
            "--out {}: the input model (--model {}); calibrating in place replaces its model file: pass --force to do so, or name another file",
            a.out.display(),
            a.model.display()
        );
    }
    super::train::check_output_file("--out", &a.out, a.force)?;
    let bytes = std::fs::read(&a.model)
        .with_context(|| format!("reading model file {}", a.model.display()))?;
    let model =
        Model::from_bytes(&bytes).with_context(|| format!("model file {}", a.model.display()))?;
    let by_content = !model.meta.training_files.is_empty();
    if let Some(train) = training_data(&model) {
        if !train.exists() && !by_content {
            eprintln!(
                "warning: the model's training data folder `{}` (as `grip train --data` was given, relative to where it was trained) does not exist from here, and the model predates the check by content: --data cannot be checked to be held out",
                train.display()
            );
        }
        require_held_out(
            "--data",
            &a.data,
            &[("the model's training data (grip train --data)", train)],
        )?;
    }
    require_not_training_files("--data", &a.data, &model)?;
    let data: Vec<String> = a
        .data
        .iter()
        .map(|d| format!("--data {}", d.display()))
        .collect();
    let command = format!(
        "grip calibrate --model {} {} {}{}",
        a.model.display(),
        data.join(" "),
        a.fit.command_line(),
        a.channel.command_line()
    );
    let (cal, _) = fit_calibration(&model, &a.data, &a.fit, &command, a.channel.get())?;
    let model = model.with_calibration(Some(cal))?;
    let out = model.to_bytes()?;
    // the check again (a file may have appeared during the fit)
    super::train::check_output_file("--out", &a.out, a.force)?;
    std::fs::write(&a.out, &out)
        .with_context(|| format!("cannot write model {}", a.out.display()))?;
    println!(
        "wrote {} (format v{}, {} bytes, file sha256 {}...)",
        a.out.display(),
        model.format_version(),
        out.len(),
        &sha256_hex(&out)[..16]
    );
    Ok(())
}

/// Whether `a` and `b` name the same existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    std::fs::canonicalize(a).is_ok_and(|a| std::fs::canonicalize(b).is_ok_and(|b| a == b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped model, its training command pointing at `train`.
    fn model_trained_on(train: &Path, out: &Path) {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/paper.model");
        let mut m = Model::from_bytes(&std::fs::read(shipped).unwrap()).unwrap();
        m.meta.command = format!(
            "grip train --data {} --classifier mlp --features paper7 --folds 5",
            train.display()
        );
        std::fs::write(out, m.to_bytes().unwrap()).unwrap();
    }

    fn args(model: &Path, data: Vec<PathBuf>, out: PathBuf) -> Args {
        Args {
            model: model.to_path_buf(),
            data,
            out,
            fit: FitArgs {
                calib_method: "isotonic".into(),
                calib_hop: 0.025,
                calib_stay: 0.9,
                calib_floor: 0.01,
            },
            channel: ChannelArg::default(),
            force: false,
        }
    }

    #[test]
    fn calibrating_on_the_training_data_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let train = dir.path().join("my data");
        std::fs::create_dir_all(train.join("snow")).unwrap();
        let model = dir.path().join("m.model");
        model_trained_on(&train, &model);
        let ctx = Ctx {
            config_dir: Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config"),
            config_dir_given: false,
        };
        let out = dir.path().join("out.model");
        // the training folder itself, a folder in it, or one holding it
        for data in [train.clone(), train.join("snow"), dir.path().to_path_buf()] {
            let e = format!(
                "{:#}",
                run(&ctx, args(&model, vec![data.clone()], out.clone())).unwrap_err()
            );
            assert!(
                e.contains("held-out")
                    && e.contains("training data")
                    && e.contains(&data.display().to_string()),
                "{e}"
            );
            assert!(!out.exists());
        }
        // another folder passes this check (and then fails on its contents)
        let other = dir.path().join("../other-calib-not-there");
        let e = format!(
            "{:#}",
            run(&ctx, args(&model, vec![other], out.clone())).unwrap_err()
        );
        assert!(!e.contains("held-out"), "{e}");
    }

    /// A recording with 0.5 s of digital silence between two road
    /// stretches runs as in the arte service: the silent blocks give no
    /// decision (they were judged as the road), the estimator restarts
    /// after them, and the later decisions keep the recording's time.
    #[test]
    fn silent_blocks_give_no_decision_and_time_runs_on() {
        use grip_arte::synth::{Segment, SynthConfig, render};
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/paper.model");
        let m = Model::from_bytes(&std::fs::read(shipped).unwrap()).unwrap();
        let fs = m.feature_config().sample_rate;
        let seg = Segment {
            road: 0,
            speed_mps: 5.0,
            duration_s: 1.0,
        };
        let cfg = SynthConfig {
            sample_rate: fs,
            noise: None,
        };
        let road = render(&cfg, 3, &[seg]).unwrap();
        let mut x = road.clone();
        x.extend(std::iter::repeat_n(0.0, fs as usize / 2));
        x.extend(&road);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("gap.wav");
        wav::write_mono_i16(&path, fs, &x).unwrap();
        let r = ChangeRecording {
            path,
            segments: vec![(0.0, 2.5, 0, Some(18.0))],
        };
        let fit = args(Path::new("m"), vec![], PathBuf::new()).fit;
        let mut est = StreamEstimator::new(
            Predictor::new(m.clone()),
            m.feature_config(),
            &fit.stream_config(),
        )
        .unwrap();
        let mut ex = Excluded::default();
        let (dec, len) =
            stream_recording(&mut est, &r, fs, dir.path(), wav::Channel::Average, &mut ex).unwrap();
        assert!((len - 2.5).abs() < 1e-3);
        let ends: Vec<f64> = dec.iter().map(|d| d.t_end).collect();
        assert!(ends.iter().all(|&t| !(1.1..1.55).contains(&t)), "{ends:?}");
        assert!(ends.last().unwrap() > &2.45, "{ends:?}");
        assert!(ends.windows(2).all(|w| w[0] < w[1]));
        // 0.5 s of silence: 20 whole blocks of 1024 samples at 44.1 kHz
        assert!((20..=22).contains(&ex.frames()), "{:?}", ex);
        assert!(ex.files.is_empty());
        // a folder of nothing but silence: an error naming it
        let silent = dir.path().join("silent");
        std::fs::create_dir(&silent).unwrap();
        wav::write_mono_i16(&silent.join("s.wav"), fs, &vec![0.0; fs as usize]).unwrap();
        std::fs::write(
            silent.join("segments.csv"),
            "file,t_start,t_end,road,speed_kmh\ns.wav,0,1,asphalt,18\n",
        )
        .unwrap();
        let classes = m.classes().to_vec();
        let settings = (fs, m.feature_config().frame_s, 0.025);
        let dirs = [silent.clone()];
        let e = outcomes(&mut est, &classes, settings, &dirs, wav::Channel::Average)
            .map(|_| ())
            .unwrap_err();
        let e = format!("{e:#}");
        assert!(
            e.contains(&silent.display().to_string()) && e.contains("every block"),
            "{e}"
        );
    }

    #[test]
    fn a_set_without_wrong_decisions_cannot_calibrate() {
        let w = degenerate_set(&[true; 40]).unwrap();
        assert!(
            w.contains("every one of its decisions is right (40 decisions)"),
            "{w}"
        );
        assert!(
            degenerate_set(&[false; 3])
                .unwrap()
                .contains("is wrong (3 decisions)")
        );
        assert_eq!(degenerate_set(&[true, false, true]), None);
    }

    #[test]
    fn smoothing_reads_as_words() {
        let hmm = Smoothing::Hmm {
            stay: 0.9,
            floor: 0.01,
        };
        assert_eq!(smoothing_text(&hmm), "smoothing: HMM, stay 0.9, floor 0.01");
        assert_eq!(smoothing_text(&Smoothing::None), "smoothing: none");
    }

    /// The training files by content: a copy of one of them in the
    /// calibration folder is refused wherever it lies (the stored training
    /// path is relative to where the model was trained); a model without
    /// the field (an old file) keeps the check by path alone.
    #[test]
    fn a_training_file_is_refused_by_content() {
        let dir = tempfile::tempdir().unwrap();
        let calib = dir.path().join("calib/sub");
        std::fs::create_dir_all(&calib).unwrap();
        wav::write_mono_i16(&calib.join("x.wav"), 16_000, &[0.1, -0.2, 0.3]).unwrap();
        let model = dir.path().join("m.model");
        model_trained_on(Path::new("somewhere/train"), &model);
        let mut m = Model::from_bytes(&std::fs::read(&model).unwrap()).unwrap();
        let data = vec![dir.path().join("calib")];
        assert!(require_not_training_files("--data", &data, &m).is_ok());
        let sha = sha256_hex(&std::fs::read(calib.join("x.wav")).unwrap());
        m.meta.training_files = vec![crate::dataset::file_id(&sha)];
        let e = format!(
            "{:#}",
            require_not_training_files("--data", &data, &m).unwrap_err()
        );
        assert!(
            e.contains("x.wav") && e.contains("training recordings") && e.contains("held-out"),
            "{e}"
        );
        // stored and read back: the field survives the file
        let back = Model::from_bytes(&m.to_bytes().unwrap()).unwrap();
        assert_eq!(back.meta.training_files, m.meta.training_files);
    }

    #[test]
    fn the_training_folder_is_read_from_the_stored_command() {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/paper.model");
        let mut m = Model::from_bytes(&std::fs::read(shipped).unwrap()).unwrap();
        m.meta.command = "grip train --data /x/my data --classifier mlp".into();
        assert_eq!(training_data(&m), Some(PathBuf::from("/x/my data")));
        m.meta.command = "grip train --data d".into();
        assert_eq!(training_data(&m), Some(PathBuf::from("d")));
        m.meta.command = String::new();
        assert_eq!(training_data(&m), None);
    }
}
