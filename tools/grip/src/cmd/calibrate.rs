//! `grip calibrate`: fits the streaming estimator's confidence calibration
//! on road-change recordings and writes the model with it (format v2).
//!
//! The classifier, standardiser, feature config and metadata are kept byte
//! for byte; only the `calibration` field is added (or replaced). The
//! recordings must be neither the training set nor the set the result is
//! evaluated on (other seeds, other cars). `grip train --calib-data DIR`
//! runs the same step after training.
//!
//! Fitting data: the model, uncalibrated, runs through `StreamEstimator`
//! with the given stream settings (default: the arte service's, hop 0.025 s,
//! HMM stay 0.9, floor 0.01) in blocks of 1024 samples, each segment at its
//! speed; every decision is one sample: the smoothed posterior of the
//! decided road, and whether that road is the true one at the decision's
//! time (`t_end`). That is exactly what a controller receives.

use super::Ctx;
use super::dataset::{ChangeRecording, read_changes, truth_file};
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
    /// Output model file (may be the input).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub fit: FitArgs,
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
    /// Stream HMM stay probability the calibration is fitted for.
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

    /// The options as they appear on a command line.
    pub fn command_line(&self) -> String {
        format!(
            "--calib-method {} --calib-hop {} --calib-stay {} --calib-floor {}",
            self.calib_method, self.calib_hop, self.calib_stay, self.calib_floor
        )
    }
}

/// Runs the stream over one change recording; its decisions in time order
/// and its length (s).
pub fn stream_recording(
    est: &mut StreamEstimator<Predictor>,
    r: &ChangeRecording,
    sample_rate: u32,
    where_: &Path,
) -> Result<(Vec<Judged>, f64)> {
    let audio = wav::read_mono_at(&r.path, sample_rate)?;
    est.reset();
    if est.speed_normalised() && r.segments.iter().any(|s| s.3.is_none()) {
        bail!(
            "{}: a segment of {} has no speed_kmh; the model is speed-normalised and needs the vehicle speed",
            truth_file(where_).display(),
            r.path.display(),
        );
    }
    let block = 1024;
    let fs = f64::from(sample_rate);
    let mut dec: Vec<Judged> = Vec::new();
    for (bi, b) in audio.samples.chunks(block).enumerate() {
        est.set_speed(r.speed_at((bi * block) as f64 / fs).map(|v| v / 3.6));
        est.push(b, |d| {
            dec.push(Judged {
                t_start: d.t_start,
                t_end: d.t_end,
                class: d.class,
                raw_class: d.raw_class,
                confidence: d.confidence,
            });
        });
    }
    Ok((dec, audio.samples.len() as f64 / fs))
}

/// Every decision's confidence and whether it named the true road at its
/// time, over the change recordings in `dirs`.
pub fn outcomes(
    est: &mut StreamEstimator<Predictor>,
    classes: &[String],
    sample_rate: u32,
    dirs: &[PathBuf],
) -> Result<(Vec<f64>, Vec<bool>)> {
    let (mut conf, mut right) = (Vec::new(), Vec::new());
    for dir in dirs {
        let recs = read_changes(dir, classes)?;
        let pb = ProgressBar::new(recs.len() as u64);
        for r in &recs {
            let (dec, _) = stream_recording(est, r, sample_rate, dir)?;
            for d in dec {
                if let Some((_, seg)) = segment_at(&r.segments, d.t_end) {
                    conf.push(d.confidence);
                    right.push(d.class == seg.2);
                }
            }
            pb.inc(1);
        }
        pb.finish_and_clear();
    }
    Ok((conf, right))
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

/// Fits the calibration of `model` on the change recordings in `dirs`;
/// returns it and a Markdown report (also printed). `command` is stored in
/// the calibration's notes.
pub fn fit_calibration(
    model: &Model,
    dirs: &[PathBuf],
    fit: &FitArgs,
    command: &str,
) -> Result<(StreamCalibration, String)> {
    let method = Method::from_name(&fit.calib_method)
        .with_context(|| format!("--calib-method: `{}` is unknown", fit.calib_method))?;
    let scfg = fit.stream_config();
    let uncalibrated = model.clone().with_calibration(None)?;
    let fcfg = uncalibrated.feature_config().clone();
    let classes = uncalibrated.classes().to_vec();
    let mut est = StreamEstimator::new(Predictor::new(uncalibrated), &fcfg, &scfg)
        .context("--calib-hop / --calib-stay / --calib-floor")?;
    let (p, right) = outcomes(&mut est, &classes, fcfg.sample_rate, dirs)?;
    if p.is_empty() {
        bail!("the calibration recordings gave no decisions");
    }
    let names: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    let mut report = String::new();
    let _ = writeln!(
        report,
        "\n**Confidence calibration** (stream hop {} s, {:?}), fitted on {} decisions of {} \
         (every decision against the true road at its time; in-sample figures, the held-out ones come from `grip dataset delay`):\n",
        scfg.hop_s,
        scfg.smoothing,
        p.len(),
        names.join(", ")
    );
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
        format!("fitted on {} ({} decisions)", names.join(", "), p.len()),
        format!("before: {}", summary_line(&p, &right)),
        format!("after (in-sample): {}", summary_line(&c, &right)),
        format!("command: {command}"),
    ];
    Ok((
        StreamCalibration {
            map,
            stream: scfg,
            notes,
        },
        report,
    ))
}

pub fn run(_ctx: &Ctx, a: Args) -> Result<()> {
    let bytes = std::fs::read(&a.model)
        .with_context(|| format!("reading model file {}", a.model.display()))?;
    let model =
        Model::from_bytes(&bytes).with_context(|| format!("model file {}", a.model.display()))?;
    let data: Vec<String> = a
        .data
        .iter()
        .map(|d| format!("--data {}", d.display()))
        .collect();
    let command = format!(
        "grip calibrate --model {} {} {}",
        a.model.display(),
        data.join(" "),
        a.fit.command_line()
    );
    let (cal, _) = fit_calibration(&model, &a.data, &a.fit, &command)?;
    let model = model.with_calibration(Some(cal))?;
    let out = model.to_bytes()?;
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
