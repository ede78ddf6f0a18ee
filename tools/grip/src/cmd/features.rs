//! `grip features`: acoustic features of a WAV file, one row per frame; or,
//! with `--dataset DIR`, the paper's feature pruning and the Kullback-Leibler
//! separability report over a labelled dataset.

use super::Ctx;
use crate::dataset::Dataset;
use anyhow::{Context, Result, bail};
use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet, N_PAPER20, Prefilter};
use grip_arte::select::{kl_report, paper7_config, select_paper7, variance_ratios};
use grip_io::wav;
use std::io::Write;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// WAV file (mono or mixed down; its own sample rate is used).
    file: Option<PathBuf>,
    /// Analyse a labelled dataset folder instead: variance ratios, the fitted
    /// Paper7 selection and symmetric KL distances between classes.
    #[arg(long, conflicts_with = "file")]
    dataset: Option<PathBuf>,
    /// Frame length (s).
    #[arg(long, default_value_t = 0.1)]
    frame: f64,
    /// Hop between frames (s); default: the frame length.
    #[arg(long)]
    hop: Option<f64>,
    /// Feature set: paper20, paper7 or rich.
    #[arg(long, default_value = "paper20")]
    set: String,
    /// Paper7 only: indices into Paper20, comma separated (default 0,1,2,10,11,15,16).
    #[arg(long)]
    selection: Option<String>,
    /// Pre-filter of the paper sets: "LO-HI" in Hz, or "none" (default 150-6000).
    #[arg(long)]
    prefilter: Option<String>,
    /// Print one CSV row per frame (t_start, t_end, features) to stdout.
    #[arg(long)]
    csv: bool,
    /// Write the CSV to this file instead of stdout (in a folder that
    /// exists; an existing file only with `--force`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Overwrite an existing `--out` file.
    #[arg(long)]
    force: bool,
}

fn config(a: &Args, rate: u32) -> Result<FeatureConfig> {
    let set = FeatureSet::from_name(&a.set)
        .with_context(|| format!("--set: `{}` is not one of paper20, paper7, rich", a.set))?;
    let mut cfg = FeatureConfig::new(rate, set);
    cfg.frame_s = a.frame;
    if let Some(sel) = &a.selection {
        cfg.selection = sel
            .split(',')
            .map(|t| {
                t.trim()
                    .parse::<usize>()
                    .with_context(|| format!("--selection: `{t}` is not an index"))
            })
            .collect::<Result<_>>()?;
    }
    if let Some(p) = &a.prefilter {
        cfg.prefilter = if p == "none" {
            Prefilter::NONE
        } else {
            let (lo, hi) = p
                .split_once('-')
                .with_context(|| format!("--prefilter: `{p}` is not LO-HI or none"))?;
            let f = |t: &str| {
                t.trim()
                    .parse::<f64>()
                    .with_context(|| format!("--prefilter: `{t}` is not a number"))
            };
            Prefilter {
                highpass_hz: Some(f(lo)?),
                lowpass_hz: Some(f(hi)?),
            }
        };
    }
    cfg.validate().context("feature options")?;
    Ok(cfg)
}

fn hop_samples(a: &Args, rate: u32) -> Result<usize> {
    let hop = a.hop.unwrap_or(a.frame);
    if !(hop > 0.0 && hop <= 10.0) {
        bail!("--hop: {hop} s is outside (0, 10]");
    }
    Ok(((hop * f64::from(rate)).round() as usize).max(1))
}

fn one_file(a: &Args, file: &std::path::Path) -> Result<()> {
    if let Some(p) = &a.out {
        super::train::check_output_file("--out", p, a.force)?;
    }
    let audio = wav::read_mono(file)?;
    let cfg = config(a, audio.sample_rate)?;
    let hop = hop_samples(a, audio.sample_rate)?;
    let mut ex = FeatureExtractor::new(&cfg)?;
    let m = ex.extract_all(&audio.samples, hop)?;
    let dim = ex.dim();
    let names = ex.names();
    let n = m.len() / dim.max(1);
    if n == 0 {
        bail!(
            "{}: {:.3} s of audio is shorter than one frame ({} s)",
            file.display(),
            audio.duration_s(),
            a.frame
        );
    }
    let fs = f64::from(audio.sample_rate);
    if a.csv || a.out.is_some() {
        let sink: Box<dyn Write> = match &a.out {
            Some(p) => Box::new(
                std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
            ),
            None => Box::new(std::io::stdout().lock()),
        };
        let mut w = csv::Writer::from_writer(sink);
        let mut header = vec!["t_start".to_string(), "t_end".to_string()];
        header.extend(names.iter().cloned());
        w.write_record(&header)?;
        for (i, row) in m.chunks_exact(dim).enumerate() {
            let t0 = (i * hop) as f64 / fs;
            let t1 = t0 + ex.frame_len() as f64 / fs;
            let mut rec = vec![format!("{t0:.6}"), format!("{t1:.6}")];
            rec.extend(row.iter().map(|v| format!("{v:.6e}")));
            w.write_record(&rec)?;
        }
        w.flush()?;
        return Ok(());
    }
    println!(
        "{}: {:.2} s at {} Hz ({} channel(s)), {} frames of {} s, hop {} s, set {}",
        file.display(),
        audio.duration_s(),
        audio.sample_rate,
        audio.file_channels,
        n,
        a.frame,
        hop as f64 / fs,
        cfg.set.name()
    );
    println!(
        "{:<18} {:>12} {:>12} {:>12} {:>12}",
        "feature", "mean", "std", "min", "max"
    );
    for (j, name) in names.iter().enumerate() {
        let col: Vec<f64> = m.chunks_exact(dim).map(|r| r[j]).collect();
        let mean = col.iter().sum::<f64>() / n as f64;
        let std = (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        let min = col.iter().copied().fold(f64::INFINITY, f64::min);
        let max = col.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        println!("{name:<18} {mean:>12.4} {std:>12.4} {min:>12.4} {max:>12.4}");
    }
    println!("(use --csv for every frame)");
    Ok(())
}

fn dataset_report(a: &Args, dir: &std::path::Path) -> Result<()> {
    let ds = Dataset::scan(dir)?;
    let rate = wav::read_mono(&ds.entries[0].path)?.sample_rate;
    let k = ds.classes.len();
    let mut p20 = config(a, rate)?;
    p20.set = FeatureSet::Paper20;
    let mut rich = config(a, rate)?;
    rich.set = FeatureSet::Rich;
    let hop = hop_samples(a, rate)?;
    let mut ex20 = FeatureExtractor::new(&p20)?;
    let mut exr = FeatureExtractor::new(&rich)?;
    let (mut x20, mut xr, mut y) = (Vec::new(), Vec::new(), Vec::new());
    let frame_len = ex20.frame_len();
    // recordings without a whole frame give none: named, with their
    // lengths (a dataset of only such files once said "0 values for 0
    // rows of 20 columns")
    let mut short: Vec<(&crate::dataset::Entry, usize)> = Vec::new();
    let pb = indicatif::ProgressBar::new(ds.entries.len() as u64);
    for r in &ds.entries {
        let audio = wav::read_mono_at(&r.path, rate)?;
        if audio.samples.len() < frame_len {
            short.push((r, audio.samples.len()));
            pb.inc(1);
            continue;
        }
        let m20 = ex20.extract_all(&audio.samples, hop)?;
        let mr = exr.extract_all(&audio.samples, hop)?;
        y.extend(std::iter::repeat_n(r.class, m20.len() / N_PAPER20));
        x20.extend(m20);
        xr.extend(mr);
        pb.inc(1);
    }
    pb.finish_and_clear();
    if !short.is_empty() {
        let what = short_recordings(&short, ds.entries.len(), a.frame, frame_len, rate);
        // a class left without a frame has no statistics: refused, as a
        // dataset left without any
        let empty: Vec<&str> = (0..k)
            .filter(|c| !y.contains(c))
            .map(|c| ds.classes[c].as_str())
            .collect();
        if !empty.is_empty() {
            bail!(
                "dataset folder {}: {what}; {} no frame to analyse: give longer recordings, or a shorter --frame",
                dir.display(),
                match empty.len() {
                    n if n == k => "the dataset has".to_owned(),
                    1 => format!("class folder {} has", empty[0]),
                    _ => format!("class folders {} have", empty.join(", ")),
                }
            );
        }
        eprintln!(
            "warning: dataset folder {}: {what}; {} left out",
            dir.display(),
            if short.len() == 1 {
                "it is"
            } else {
                "they are"
            }
        );
    }
    println!(
        "dataset {}: {} recordings, {} frames, classes: {}",
        dir.display(),
        ds.entries.len(),
        y.len(),
        ds.classes.join(", ")
    );
    let rho = variance_ratios(&x20, N_PAPER20, &y, k)?;
    println!(
        "\nPaper20 intra-class variance ratio (pooled within-class / total; smaller is more class-coherent):"
    );
    for (name, r) in p20.names().iter().zip(&rho) {
        println!("  {name:<8} {r:.4}");
    }
    let sel = select_paper7(&x20, &y, k)?;
    let p7 = paper7_config(&p20, sel.clone());
    println!(
        "\nfitted Paper7 selection: {:?} = {}",
        sel,
        p7.names().join(", ")
    );
    let x7: Vec<f64> = x20
        .chunks_exact(N_PAPER20)
        .flat_map(|r| sel.iter().map(move |&i| r[i]))
        .collect();
    for (label, x, dim) in [
        ("Paper7 (fitted)", &x7, sel.len()),
        ("Paper20", &x20, N_PAPER20),
        ("Rich", &xr, exr.dim()),
    ] {
        let kl = kl_report(x, dim, &y, k)?;
        println!(
            "\nsymmetric KL divergence between Gaussian class models, {label}:\n{}",
            kl.to_markdown(&ds.classes)
        );
        if let Some((a, b, d)) = kl.closest_pair() {
            println!(
                "closest pair: {} / {} ({d:.1})",
                ds.classes[a], ds.classes[b]
            );
        }
    }
    Ok(())
}

/// How many of `total` recordings are shorter than one frame of `frame_s`
/// s (`frame_len` samples at `rate` Hz), the first few named with their
/// lengths.
fn short_recordings(
    short: &[(&crate::dataset::Entry, usize)],
    total: usize,
    frame_s: f64,
    frame_len: usize,
    rate: u32,
) -> String {
    const SHOWN: usize = 5;
    let named: Vec<String> = short
        .iter()
        .take(SHOWN)
        .map(|(e, n)| {
            format!(
                "{} ({:.3} s, {n} samples)",
                e.path.display(),
                *n as f64 / f64::from(rate)
            )
        })
        .collect();
    format!(
        "{} shorter than one {frame_s} s frame ({frame_len} samples at {rate} Hz): {}{}",
        match (short.len(), total) {
            (1, 1) => "the one recording is".to_owned(),
            (n, t) if n == t => format!("all {t} recordings are"),
            (1, t) => format!("1 of the {t} recordings is"),
            (n, t) => format!("{n} of the {t} recordings are"),
        },
        named.join(", "),
        if short.len() > SHOWN {
            format!(", and {} more", short.len() - SHOWN)
        } else {
            String::new()
        }
    )
}

pub fn run(_ctx: &Ctx, args: Args) -> Result<()> {
    match (&args.file, &args.dataset) {
        (Some(f), None) => one_file(&args, f),
        (None, Some(d)) => dataset_report(&args, d),
        _ => bail!("give a WAV file, or --dataset DIR"),
    }
}
