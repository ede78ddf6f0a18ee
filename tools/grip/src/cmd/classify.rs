//! `grip classify FILE.wav`: the road and class probabilities per frame.
//!
//! Loads the model (default `<config-dir>/models/default.model`), cuts the
//! recording into the model's frames (hop `--hop`, default = the frame
//! length), and prints one line per frame: start and end time, the most
//! probable road, and every class probability; then a summary line (frames
//! per road, the majority road and its share).
//!
//! Frames the arte service would refuse (`grip_arte::quality`: silence,
//! clipping) are not classified: they get no line, a warning names the file
//! and the reasons, and the summary counts them; a file of which every
//! frame is refused is an error naming it. `--channel N` reads one channel
//! of a multi-channel file (default: their average).

use super::Ctx;
use crate::dataset::{ChannelArg, Excluded, FileJudge};
use anyhow::{Context, Result, bail};
use grip_arte::features::FeatureExtractor;
use grip_arte::model::Model;
use std::io::Write as _;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Clone, Debug)]
pub struct Args {
    /// WAV recording to classify (mono, or multi-channel: averaged, or one
    /// channel by --channel).
    pub file: PathBuf,
    /// Model file (default: `<config-dir>/models/default.model`).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Hop between frames (s); default: the model's frame length.
    #[arg(long)]
    pub hop: Option<f64>,
    /// Print only the summary line.
    #[arg(long)]
    pub summary: bool,
    /// Vehicle speed of the recording (km/h); required by a speed-normalised
    /// model (the default one), ignored by others.
    #[arg(long)]
    pub speed: Option<f64>,
    #[command(flatten)]
    pub channel: ChannelArg,
}

/// Loads and validates a model file; errors name the path.
pub fn load_model(path: &Path) -> Result<Model> {
    let bytes = std::fs::read(path)
        .with_context(|| format!("cannot read model file {}", path.display()))?;
    Model::from_bytes(&bytes).with_context(|| format!("model file {}", path.display()))
}

/// One frame's decision: start and end time (s), class, probabilities.
pub type FrameDecision = (f64, f64, usize, Vec<f64>);

/// The highest `--speed` taken, km/h: beyond any road vehicle's.
const MAX_SPEED_KMH: f64 = 400.0;

/// Per-frame decisions of the frames `judge` accepts (the arte service's
/// audio-quality rule).
pub fn classify(
    model: &Model,
    samples: &[f32],
    sample_rate: u32,
    (hop_s, speed_kmh): (Option<f64>, Option<f64>),
    judge: &mut FileJudge,
) -> Result<Vec<FrameDecision>> {
    let cfg = model.feature_config();
    if let Some(v) = speed_kmh
        && !(v.is_finite() && (0.0..=MAX_SPEED_KMH).contains(&v))
    {
        bail!("--speed: {v} km/h is not a road vehicle's speed (0 to {MAX_SPEED_KMH} km/h)");
    }
    if cfg.speed_norm.is_some() {
        match speed_kmh {
            Some(_) => {}
            None => bail!(
                "this model is speed-normalised: give the vehicle speed of the recording with --speed KMH"
            ),
        }
    }
    if sample_rate != cfg.sample_rate {
        bail!(
            "recording is sampled at {sample_rate} Hz, the model was trained at {} Hz",
            cfg.sample_rate
        );
    }
    let mut ex = FeatureExtractor::new(cfg).context("model feature config")?;
    ex.set_speed(speed_kmh.map(|v| v / 3.6));
    let frame = ex.frame_len();
    let hop = match hop_s {
        Some(h) if h > 0.0 && h <= 10.0 => ((h * f64::from(sample_rate)).round() as usize).max(1),
        Some(h) => bail!("--hop: {h} s is outside (0, 10]"),
        None => frame,
    };
    if samples.len() < frame {
        bail!(
            "recording has {} samples, shorter than one frame of {frame}",
            samples.len()
        );
    }
    let mut pred = model.predictor();
    let mut feat = vec![0.0; ex.dim()];
    let mut out = Vec::new();
    let fs = f64::from(sample_rate);
    for (k, x) in samples.windows(frame).step_by(hop).enumerate() {
        if !judge.accept(x) {
            continue;
        }
        let start = k * hop;
        ex.extract(x, &mut feat)?;
        let mut p = vec![0.0; model.classes().len()];
        let c = pred.predict_proba(&feat, &mut p)?;
        out.push((start as f64 / fs, (start + frame) as f64 / fs, c, p));
    }
    Ok(out)
}

pub fn run(ctx: &Ctx, args: Args) -> Result<()> {
    let path = args
        .model
        .clone()
        .unwrap_or_else(|| ctx.config_dir.join("models").join("default.model"));
    let model = load_model(&path)?;
    let channel = args.channel.get();
    let audio = grip_io::wav::read_channel(&args.file, channel)?;
    // several channels averaged: said, since two microphones on two roads
    // average to a sound of neither (a newcomer's gravel + snow file read
    // "snow 95 %" without a word)
    if let Some(n) = averaged_note(audio.file_channels, channel) {
        eprintln!("note: {}: {n}", args.file.display());
    }
    let mut judge = FileJudge::new();
    let rows = classify(
        &model,
        &audio.samples,
        audio.sample_rate,
        (args.hop, args.speed),
        &mut judge,
    )
    .with_context(|| format!("classifying {}", args.file.display()))?;
    let mut excluded = Excluded::default();
    let name = args.file.display().to_string();
    judge.finish(&name, &audio, channel, "frame", &mut excluded);
    if rows.is_empty() {
        bail!(
            "{name}: every frame was excluded ({}); nothing to classify",
            excluded.summary("frame").unwrap_or_default()
        );
    }
    let classes = model.classes();
    let stdout = std::io::stdout();
    let mut o = stdout.lock();
    if !args.summary {
        write!(o, "{:>8} {:>8} {:<12}", "t0_s", "t1_s", "road")?;
        for c in classes {
            write!(o, " {c:>11}")?;
        }
        writeln!(o)?;
        for (t0, t1, c, p) in &rows {
            write!(o, "{t0:>8.3} {t1:>8.3} {:<12}", classes[*c])?;
            for v in p {
                write!(o, " {v:>11.4}")?;
            }
            writeln!(o)?;
        }
    }
    let mut counts = vec![0usize; classes.len()];
    for (_, _, c, _) in &rows {
        counts[*c] += 1;
    }
    let best = (0..classes.len())
        .max_by_key(|&i| (counts[i], std::cmp::Reverse(i)))
        .unwrap_or(0);
    let n = rows.len().max(1);
    let left_out = if excluded.frames() > 0 {
        format!(" ({} more excluded)", excluded.frames())
    } else {
        String::new()
    };
    writeln!(
        o,
        "summary: {} frames{left_out}, majority {} ({:.1} %); {} [model {}]",
        rows.len(),
        classes[best],
        100.0 * counts[best] as f64 / n as f64,
        classes
            .iter()
            .zip(&counts)
            .map(|(c, k)| format!("{c} {k}"))
            .collect::<Vec<_>>()
            .join(", "),
        path.display()
    )?;
    if let Some(note) = speed_note(
        &model,
        args.speed,
        audio.samples.len() as f64 / f64::from(audio.sample_rate),
    ) {
        writeln!(o, "note: {note}")?;
    }
    Ok(())
}

/// `--speed` against the model's training speeds, as `grip inspect`,
/// `grip drive` and `grip sim --arte acoustic` note it: None without
/// `--speed`, for a model that does not record its training speeds, or
/// at a speed inside them.
fn speed_note(model: &Model, speed_kmh: Option<f64>, duration_s: f64) -> Option<String> {
    let range = model.training_speeds().range()?;
    let mut c = grip_arte::speeds::SpeedCheck::new(range);
    c.add(speed_kmh?, duration_s.max(f64::MIN_POSITIVE));
    let notes = c.notes("the recording", "at --speed");
    (!notes.is_empty()).then(|| notes.join("; "))
}

/// The note for a file of `channels` channels read as `channel`: their
/// average is classified (`None` for one channel, or one chosen).
fn averaged_note(channels: u16, channel: grip_io::wav::Channel) -> Option<String> {
    (channels > 1 && channel == grip_io::wav::Channel::Average).then(|| {
        format!(
            "its {channels} channels are averaged and the average classified; --channel N classifies one (0-based)"
        )
    })
}

#[cfg(test)]
mod tests {
    /// A multi-channel file read as the average is said to be; a mono one
    /// or one channel chosen is not.
    #[test]
    fn averaged_channels_are_said() {
        use grip_io::wav::Channel;
        assert!(
            super::averaged_note(2, Channel::Average)
                .unwrap()
                .starts_with("its 2 channels are averaged")
        );
        assert_eq!(super::averaged_note(1, Channel::Average), None);
        assert_eq!(super::averaged_note(2, Channel::One(1)), None);
    }

    use super::*;
    use grip_arte::synth::{Segment, SynthConfig, render};

    /// A `--speed` outside the shipped model's training speeds gets the
    /// note the other commands give; one inside, or none, gets none.
    #[test]
    fn a_speed_outside_the_training_speeds_is_noted() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/default.model");
        let m = load_model(&p).unwrap();
        let r = m
            .training_speeds()
            .range()
            .expect("the shipped model records its speeds");
        let note = speed_note(&m, Some(r.max_kmh + 50.0), 2.0).unwrap();
        assert!(
            note.contains("above the model's training speeds") && note.contains("extrapolation"),
            "{note}"
        );
        assert_eq!(
            speed_note(&m, Some(0.5 * (r.min_kmh + r.max_kmh)), 2.0),
            None
        );
        assert_eq!(speed_note(&m, None, 2.0), None);
    }

    /// The shipped paper model and `x` seconds of road sound at its rate.
    fn model_and_road(x: f64) -> (Model, Vec<f32>) {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/paper.model");
        let m = load_model(&p).unwrap();
        let cfg = SynthConfig {
            sample_rate: m.feature_config().sample_rate,
            noise: None,
        };
        let seg = Segment {
            road: 0,
            speed_mps: 5.0,
            duration_s: x,
        };
        let road = render(&cfg, 1, &[seg]).unwrap();
        (m, road)
    }

    /// Frames of digital silence get no decision (they were classified as
    /// a road, with confidence): only the road's frames are, and the
    /// judge counts the silent ones.
    #[test]
    fn silent_frames_are_not_classified() {
        let (m, mut x) = model_and_road(1.0);
        let fs = m.feature_config().sample_rate;
        let n_road = x.len();
        x.extend(std::iter::repeat_n(0.0, n_road));
        let mut judge = FileJudge::new();
        let rows = classify(&m, &x, fs, (None, Some(20.0)), &mut judge).unwrap();
        let frame = m.feature_config().frame_s;
        assert!(!rows.is_empty());
        assert!(
            rows.iter().all(|r| r.1 <= 1.0 + 1e-9),
            "{:?}",
            rows.last().map(|r| r.1)
        );
        let mut ex = Excluded::default();
        let a = grip_io::wav::Audio {
            sample_rate: fs,
            samples: x,
            file_rate: fs,
            file_channels: 1,
            clamped: 0,
            non_finite: 0,
            data_declared: None,
        };
        judge.finish(
            "f.wav",
            &a,
            grip_io::wav::Channel::Average,
            "frame",
            &mut ex,
        );
        assert_eq!(ex.frames(), (1.0 / frame).round() as usize);
        assert_eq!(ex.judged, ex.frames() + rows.len());
        assert!(ex.files.is_empty());
    }

    /// `--speed` is a road vehicle's speed: 2000 km/h, a negative or a
    /// non-finite speed is refused whatever the model (it was taken
    /// silently, found in review); 0 (standing) and 400 are taken.
    #[test]
    fn a_speed_no_vehicle_drives_is_refused() {
        let (m, x) = model_and_road(0.3);
        let fs = m.feature_config().sample_rate;
        for bad in [2000.0, -1.0, f64::NAN] {
            let e = classify(&m, &x, fs, (None, Some(bad)), &mut FileJudge::new()).unwrap_err();
            assert!(
                e.to_string().contains("is not a road vehicle's speed"),
                "{e}"
            );
        }
        for ok in [0.0, 400.0] {
            assert!(classify(&m, &x, fs, (None, Some(ok)), &mut FileJudge::new()).is_ok());
        }
    }
}
