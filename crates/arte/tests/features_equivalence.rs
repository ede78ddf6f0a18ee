//! The optimised Rich extractor and SVM prediction path against
//! straightforward reference implementations kept here: the loops of the
//! pre-optimisation code (commit 5fe5120), written for clarity. Features and
//! probabilities must agree to floating-point reassociation: relative
//! difference ≤ 1e-9 (absolute for values of magnitude below 1).

use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet};
use grip_arte::model::{Classifier, Model};
use grip_arte::svm::{Kernel, Svm, SvmConfig};
use grip_arte::synth::{NoiseConfig, ROADS, Segment, SynthConfig, render};
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;
use std::path::PathBuf;

const TOL: f64 = 1e-9;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= TOL * b.abs().max(1.0)
}

// ---------------------------------------------------------------------------
// Reference Rich features (the pre-optimisation loops).

fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos())
        .collect()
}

/// Power spectrum |X[k]|², k = 0..=n/2, of real `x` zero-padded to `n`, by
/// a full complex FFT (not the packed real FFT of the crate).
fn power_spectrum(x: &[f64], n: usize, out: &mut [f64]) {
    let mut buf: Vec<Complex<f64>> = (0..n)
        .map(|i| Complex::new(x.get(i).copied().unwrap_or(0.0), 0.0))
        .collect();
    FftPlanner::<f64>::new()
        .plan_fft_forward(n)
        .process(&mut buf);
    for (o, b) in out.iter_mut().zip(&buf) {
        *o = b.norm_sqr();
    }
}

const N_GROUPS: usize = 6;
const MEL_FMIN: f64 = 50.0;
const MEL_FMAX: f64 = 16_000.0;

fn hz_to_mel(f: f64) -> f64 {
    2595.0 * (1.0 + f / 700.0).log10()
}

fn mel_to_hz(m: f64) -> f64 {
    700.0 * (10f64.powf(m / 2595.0) - 1.0)
}

fn biquad(fs: f64, f: f64, highpass: bool) -> [f64; 5] {
    let w0 = 2.0 * std::f64::consts::PI * f.min(0.45 * fs) / fs;
    let (c, al) = (w0.cos(), w0.sin() / (2.0 * std::f64::consts::FRAC_1_SQRT_2));
    let a0 = 1.0 + al;
    let (b0, b1) = if highpass {
        ((1.0 + c) / 2.0, -(1.0 + c))
    } else {
        ((1.0 - c) / 2.0, 1.0 - c)
    };
    [b0 / a0, b1 / a0, b0 / a0, -2.0 * c / a0, (1.0 - al) / a0]
}

fn periodicity(e: &mut [f64], lo: usize, hi: usize) -> f64 {
    let n = e.len();
    let mean = e.iter().sum::<f64>() / n.max(1) as f64;
    let mut e0 = 0.0;
    for v in e.iter_mut() {
        *v -= mean;
        e0 += *v * *v;
    }
    let mut best = 0.0f64;
    if e0 > 0.0 {
        for lag in lo..=hi.max(lo) {
            if lag >= n {
                break;
            }
            let mut acc = 0.0;
            for j in 0..n - lag {
                acc += e[j] * e[j + lag];
            }
            best = best.max(acc / e0);
        }
    }
    best
}

/// Mel filters as (first bin, weights) per band.
fn mel_filters(fs: f64, n_mel: usize, sub_len: usize) -> Vec<(usize, Vec<f64>)> {
    let nb = sub_len / 2 + 1;
    let df = fs / sub_len as f64;
    let fmax = MEL_FMAX.min(0.5 * fs);
    let (m0, m1) = (hz_to_mel(MEL_FMIN), hz_to_mel(fmax));
    let pts: Vec<f64> = (0..n_mel + 2)
        .map(|i| mel_to_hz(m0 + (m1 - m0) * i as f64 / (n_mel + 1) as f64))
        .collect();
    (0..n_mel)
        .map(|b| {
            let (fl, fc, fh) = (pts[b], pts[b + 1], pts[b + 2]);
            let k0 = (fl / df).floor() as usize;
            let k1 = ((fh / df).ceil() as usize).min(nb - 1);
            let mut w: Vec<f64> = (k0..=k1)
                .map(|k| {
                    let f = k as f64 * df;
                    if f <= fl || f >= fh {
                        0.0
                    } else if f <= fc {
                        (f - fl) / (fc - fl)
                    } else {
                        (fh - f) / (fh - fc)
                    }
                })
                .collect();
            if w.iter().all(|&v| v == 0.0) {
                let kc = ((fc / df).round() as usize).clamp(k0, k1);
                w[kc - k0] = 1.0;
            }
            (k0, w)
        })
        .collect()
}

fn mel_energies(filters: &[(usize, Vec<f64>)], pow: &[f64]) -> Vec<f64> {
    filters
        .iter()
        .map(|(k0, w)| w.iter().enumerate().map(|(j, wj)| wj * pow[k0 + j]).sum())
        .collect()
}

/// The Rich vector of `frame` as `FeatureExtractor::extract` defines it.
fn reference_rich(cfg: &FeatureConfig, frame: &[f32]) -> Vec<f64> {
    let fs = f64::from(cfg.sample_rate);
    let frame_len = cfg.frame_len();
    assert!(frame.len() <= frame_len);
    // Frame as f64: non-finite → 0, zero-padded, mean of the given samples removed.
    let mut x: Vec<f64> = (0..frame_len)
        .map(|i| {
            let v = frame.get(i).copied().unwrap_or(0.0);
            if v.is_finite() { f64::from(v) } else { 0.0 }
        })
        .collect();
    let mean = x.iter().sum::<f64>() / frame.len().max(1) as f64;
    for xi in x.iter_mut().take(frame.len()) {
        *xi -= mean;
    }

    let n_mel = cfg.n_mel;
    let sub_len = ((0.023 * fs).round() as usize).next_power_of_two().max(64);
    let hop = sub_len / 2;
    let starts: Vec<usize> = if frame_len <= sub_len {
        vec![0]
    } else {
        let n = (frame_len - sub_len).div_ceil(hop) + 1;
        (0..n)
            .map(|s| ((s * (frame_len - sub_len)) as f64 / (n - 1) as f64).round() as usize)
            .collect()
    };
    let n_sub = starts.len();
    let nb = sub_len / 2 + 1;
    let df = fs / sub_len as f64;
    let fmax = MEL_FMAX.min(0.5 * fs);
    let k_lo = ((MEL_FMIN / df).ceil() as usize).max(1);
    let k_hi = ((fmax / df).floor() as usize + 1).min(nb);
    let filters = mel_filters(fs, n_mel, sub_len);
    let window = hann(sub_len);

    let mut out = Vec::new();
    let mut sub_pow = vec![vec![0.0; nb]; n_sub];
    let mut mean_pow = vec![0.0; nb];
    for (s, &st) in starts.iter().enumerate() {
        let xs: Vec<f64> = (0..sub_len)
            .map(|i| x.get(st + i).copied().unwrap_or(0.0) * window[i])
            .collect();
        power_spectrum(&xs, sub_len, &mut sub_pow[s]);
        for k in 0..nb {
            mean_pow[k] += sub_pow[s][k] / n_sub as f64;
        }
    }
    let total: f64 = mean_pow[k_lo..k_hi].iter().sum();
    let floor = 1e-10 * total / (k_hi - k_lo) as f64 + 1e-300;

    // 1. Mel shape.
    let mel: Vec<f64> = mel_energies(&filters, &mean_pow)
        .iter()
        .map(|e| (e + floor).ln())
        .collect();
    let mean_log = mel.iter().sum::<f64>() / n_mel as f64;
    out.extend(mel.iter().map(|v| v - mean_log));
    // 2. Group variability.
    let per = n_mel / N_GROUPS;
    let group_log: Vec<Vec<f64>> = sub_pow
        .iter()
        .map(|row| {
            let e = mel_energies(&filters, row);
            (0..N_GROUPS)
                .map(|g| {
                    let hi = if g + 1 == N_GROUPS {
                        n_mel
                    } else {
                        (g + 1) * per
                    };
                    (e[g * per..hi].iter().sum::<f64>() + floor).ln()
                })
                .collect()
        })
        .collect();
    for g in 0..N_GROUPS {
        let m = group_log.iter().map(|r| r[g]).sum::<f64>() / n_sub as f64;
        let v = group_log.iter().map(|r| (r[g] - m).powi(2)).sum::<f64>() / n_sub as f64;
        out.push(v.sqrt());
    }
    // 3. Flux.
    let norm: Vec<Vec<f64>> = sub_pow
        .iter()
        .map(|row| {
            let n2: f64 = row[k_lo..k_hi].iter().sum();
            row[k_lo..k_hi]
                .iter()
                .map(|p| p.sqrt() / (n2 + floor).sqrt())
                .collect()
        })
        .collect();
    let mut flux = 0.0;
    for s in 1..n_sub {
        let d: f64 = norm[s]
            .iter()
            .zip(&norm[s - 1])
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        flux += d / (n_sub - 1) as f64;
    }
    out.push(flux);
    // 4. Spectral descriptors.
    let p: Vec<f64> = mean_pow[k_lo..k_hi].iter().map(|v| v + floor).collect();
    let f: Vec<f64> = (k_lo..k_hi).map(|k| k as f64 * df).collect();
    let p_sum: f64 = p.iter().sum();
    let centroid = p.iter().zip(&f).map(|(p, f)| p * f).sum::<f64>() / p_sum;
    let var = p
        .iter()
        .zip(&f)
        .map(|(p, f)| p * (f - centroid) * (f - centroid))
        .sum::<f64>();
    let mut cum = 0.0;
    let mut rolloff = f[f.len() - 1];
    for (p, f) in p.iter().zip(&f) {
        cum += p;
        if cum >= 0.85 * p_sum {
            rolloff = *f;
            break;
        }
    }
    let nk = p.len() as f64;
    let ln_mean = p.iter().map(|v| v.ln()).sum::<f64>() / nk;
    out.push(centroid / 1000.0);
    out.push((var / p_sum).sqrt() / 1000.0);
    out.push(rolloff / 1000.0);
    out.push(10.0 * (ln_mean - (p_sum / nk).ln()) / std::f64::consts::LN_10);
    // 5. Time domain.
    let l = frame_len;
    let zc = (1..l)
        .filter(|&n| (x[n] >= 0.0) != (x[n - 1] >= 0.0))
        .count();
    let peak = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / l as f64).sqrt();
    let tiny = 1e-30;
    out.push(zc as f64 / (l - 1) as f64 * fs / 1000.0);
    out.push(20.0 * ((peak + tiny) / (rms + tiny)).log10());
    let env_block = ((0.000_725 * fs).round() as usize).max(1);
    let n_env = frame_len / env_block;
    let mut env = vec![0.0; n_env.max(1)];
    let d2: Vec<f64> = (1..l).map(|n| (x[n] - x[n - 1]).powi(2)).collect();
    for (i, v) in d2.iter().enumerate() {
        let j = (i + 1) / env_block;
        if j < env.len() {
            env[j] += v;
        }
    }
    let m2 = d2.iter().sum::<f64>() / (l - 1) as f64;
    let m4 = d2.iter().map(|v| v * v).sum::<f64>() / (l - 1) as f64;
    let env_mean = env.iter().sum::<f64>() / env.len() as f64;
    let env_max = env.iter().fold(0.0f64, |a, &b| a.max(b));
    out.push(10.0 * ((env_max + tiny) / (env_mean + tiny)).log10());
    out.push(if m2 > 0.0 {
        (m4 / (m2 * m2)).max(1e-12).ln()
    } else {
        0.0
    });
    let lag_lo = ((0.004 * fs) / env_block as f64).ceil() as usize;
    let lag_hi = (((0.060 * fs) / env_block as f64).floor() as usize).min(n_env / 2);
    out.push(periodicity(&mut env, lag_lo, lag_hi));
    // Band filters (transposed direct form II biquads).
    let run = |c: [f64; 5]| -> Vec<f64> {
        let (mut s1, mut s2) = (0.0, 0.0);
        x.iter()
            .map(|&v| {
                let y = c[0] * v + s1;
                s1 = c[1] * v - c[3] * y + s2;
                s2 = c[2] * v - c[4] * y;
                y
            })
            .collect()
    };
    let yh = run(biquad(fs, 3000.0, true));
    let yl = run(biquad(fs, 400.0, false));
    let settle = ((0.005 * fs).round() as usize).min(frame_len / 4);
    let eh: Vec<f64> = yh[settle..].iter().map(|v| v * v).collect();
    let cnt = eh.len().max(1) as f64;
    let hm2 = eh.iter().sum::<f64>() / cnt;
    let hm4 = eh.iter().map(|v| v * v).sum::<f64>() / cnt;
    out.push(if hm2 > 0.0 {
        (hm4 / (hm2 * hm2)).max(1e-12).ln()
    } else {
        0.0
    });
    let blocks: Vec<f64> = eh
        .chunks_exact(env_block)
        .map(|b| b.iter().sum::<f64>())
        .collect();
    let hmax_blk = blocks.iter().fold(0.0f64, |a, &b| a.max(b));
    let hmean_blk = blocks.iter().sum::<f64>() / blocks.len().max(1) as f64;
    out.push(10.0 * ((hmax_blk + tiny) / (hmean_blk + tiny)).log10());
    let lf_block = ((0.002 * fs).round() as usize).max(1);
    let n_lf = (frame_len - settle) / lf_block;
    let mut lf_env: Vec<f64> = yl[settle..]
        .chunks_exact(lf_block)
        .map(|b| b.iter().map(|v| v * v).sum())
        .collect();
    if lf_env.is_empty() {
        lf_env.push(0.0);
    }
    let lf_lag_lo = ((0.004 * fs) / lf_block as f64).ceil() as usize;
    let lf_lag_hi = (((0.060 * fs) / lf_block as f64).floor() as usize).min(n_lf / 2);
    out.push(periodicity(&mut lf_env, lf_lag_lo, lf_lag_hi));
    for o in out.iter_mut() {
        if !o.is_finite() {
            *o = 0.0;
        }
    }
    out
}

fn assert_features_match(cfg: &FeatureConfig, frame: &[f32], what: &str) {
    let mut ex = FeatureExtractor::new(cfg).expect("extractor");
    let mut got = vec![0.0; ex.dim()];
    // Twice: the second call must not depend on state left by the first.
    ex.extract(frame, &mut got).expect("extract");
    ex.extract(frame, &mut got).expect("extract");
    let want = reference_rich(cfg, frame);
    assert_eq!(got.len(), want.len(), "{what}: dimension");
    let names = cfg.names();
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        assert!(
            close(*g, *w),
            "{what}: feature {} ({i}): optimised {g:e} vs reference {w:e} (diff {:e})",
            names[i],
            (g - w).abs()
        );
    }
}

fn rich(sample_rate: u32, n_mel: usize) -> FeatureConfig {
    FeatureConfig {
        n_mel,
        // The prefilter only applies to the paper sets, but must be valid.
        prefilter: grip_arte::features::Prefilter::NONE,
        ..FeatureConfig::new(sample_rate, FeatureSet::Rich)
    }
}

fn road_frame(cfg: &FeatureConfig, road: usize, seed: u64, kmh: f64, noisy: bool) -> Vec<f32> {
    let sc = SynthConfig {
        sample_rate: cfg.sample_rate,
        noise: noisy.then_some(NoiseConfig {
            rain: true,
            car: true,
            snr_db: 5.0,
        }),
    };
    let audio = render(
        &sc,
        seed,
        &[Segment {
            road,
            speed_mps: kmh / 3.6,
            duration_s: 0.15 + 2.0 * cfg.frame_s,
        }],
    )
    .expect("synth");
    // A frame from the middle of the recording.
    let st = (audio.len() - cfg.frame_len()) / 2;
    audio[st..st + cfg.frame_len()].to_vec()
}

#[test]
fn rich_features_match_reference_on_synthesised_roads() {
    let cfg = FeatureConfig::default();
    for road in 0..ROADS.len() {
        for (seed, kmh, noisy) in [(1, 20.0, false), (2, 60.0, true), (3, 8.0, false)] {
            let frame = road_frame(&cfg, road, seed + 10 * road as u64, kmh, noisy);
            assert_features_match(
                &cfg,
                &frame,
                &format!("{} seed {seed} {kmh} km/h noise {noisy}", ROADS[road]),
            );
        }
    }
}

#[test]
fn rich_features_match_reference_at_other_rates_and_band_counts() {
    for (fs, n_mel) in [
        (16_000, 16),
        (22_050, 24),
        (48_000, 40),
        (96_000, 64),
        (8_000, 8),
    ] {
        let cfg = rich(fs, n_mel);
        for road in [1, 3, 4] {
            let frame = road_frame(&cfg, road, 5 + road as u64, 40.0, road == 4);
            assert_features_match(
                &cfg,
                &frame,
                &format!("{fs} Hz, {n_mel} bands, road {road}"),
            );
        }
    }
    // Frame lengths that are not a whole number of sub-frame hops or blocks.
    for frame_s in [0.0731, 0.25, 0.0123] {
        let cfg = FeatureConfig {
            frame_s,
            ..FeatureConfig::default()
        };
        let frame = road_frame(&cfg, 2, 9, 30.0, true);
        assert_features_match(&cfg, &frame, &format!("frame_s {frame_s}"));
    }
}

#[test]
fn rich_features_match_reference_on_edge_cases() {
    let cfg = FeatureConfig::default();
    let l = cfg.frame_len();
    assert_features_match(&cfg, &vec![0.0; l], "silence");
    assert_features_match(&cfg, &[], "empty frame");
    // A lone impulse leaves, after DC removal, a constant offset whose
    // Hann-windowed spectra above bin 1 are pure FFT rounding noise in the
    // sub-frames without the impulse; features of rounding noise cannot be
    // compared across any two implementations. So the impulses sit on a
    // quiet noise floor (uniform, ±5e-6), and one case is a zero-mean doublet
    // (exactly zero elsewhere, no offset).
    let mut state = 12_345u64;
    let floor: Vec<f32> = (0..l)
        .map(|_| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) as f32 * 1e-5
        })
        .collect();
    for at in [l / 2, 1, 0, l - 1] {
        let mut imp = floor.clone();
        imp[at] = 1.0;
        assert_features_match(
            &cfg,
            &imp,
            &format!("impulse at sample {at} on a noise floor"),
        );
    }
    let mut doublet = vec![0.0f32; l];
    doublet[1000] = 0.5;
    doublet[1001] = -0.5;
    assert_features_match(&cfg, &doublet, "zero-mean doublet");
    assert_features_match(&cfg, &vec![0.25; l], "DC");
    assert_features_match(&cfg, &vec![0.3; 1000], "short DC frame (zero-padded)");
    let short = road_frame(&cfg, 3, 4, 50.0, false);
    assert_features_match(&cfg, &short[..1500], "short road frame");
    assert_features_match(&cfg, &short[..1], "one sample");
    let sine: Vec<f32> = (0..l)
        .map(|i| (2.0 * std::f64::consts::PI * 1000.0 * i as f64 / 44_100.0).sin() as f32)
        .collect();
    assert_features_match(&cfg, &sine, "1 kHz sine");
    let mut bad = short.clone();
    bad[17] = f32::NAN;
    bad[900] = f32::INFINITY;
    bad[901] = f32::NEG_INFINITY;
    assert_features_match(&cfg, &bad, "non-finite samples");
    let tiny: Vec<f32> = short.iter().map(|v| v * 1e-30).collect();
    assert_features_match(&cfg, &tiny, "very quiet (1e-30 gain)");
    let loud: Vec<f32> = short
        .iter()
        .map(|v| (v * 1e30).clamp(-1e30, 1e30))
        .collect();
    assert_features_match(&cfg, &loud, "very loud (1e30 gain)");
}

// ---------------------------------------------------------------------------
// Reference SVM prediction: per support vector |u − v|², exp, Platt, coupling.

fn reference_proba(svm: &Svm, x: &[f64]) -> Vec<f64> {
    let json = serde_json::to_value(svm).expect("svm to json");
    let sv: Vec<f64> = serde_json::from_value(json["sv"].clone()).expect("sv");
    let dim = svm.dim();
    let gamma = match svm.kernel() {
        Kernel::Rbf { gamma } => gamma,
        Kernel::Linear => f64::NAN,
    };
    let kvals: Vec<f64> = sv
        .chunks_exact(dim)
        .map(|s| match svm.kernel() {
            Kernel::Rbf { .. } => {
                let d2: f64 = s.iter().zip(x).map(|(a, b)| (a - b) * (a - b)).sum();
                (-gamma * d2).exp()
            }
            Kernel::Linear => s.iter().zip(x).map(|(a, b)| a * b).sum(),
        })
        .collect();
    let k = svm.n_classes();
    let mut r = vec![0.0; k * k];
    for p in svm.pairs() {
        let d: f64 =
            p.sv.iter()
                .zip(&p.coef)
                .map(|(&i, c)| c * kvals[i as usize])
                .sum::<f64>()
                - p.rho;
        let fab = d * p.prob_a + p.prob_b;
        let prob = if fab >= 0.0 {
            (-fab).exp() / (1.0 + (-fab).exp())
        } else {
            1.0 / (1.0 + fab.exp())
        };
        let prob = prob.clamp(1e-7, 1.0 - 1e-7);
        r[p.a * k + p.b] = prob;
        r[p.b * k + p.a] = 1.0 - prob;
    }
    couple(k, &r)
}

/// Wu, Lin & Weng (2004) method 2, as LIBSVM `multiclass_probability`.
fn couple(k: usize, r: &[f64]) -> Vec<f64> {
    let mut q = vec![0.0; k * k];
    let mut qp = vec![0.0; k];
    let mut p = vec![1.0 / k as f64; k];
    for t in 0..k {
        for j in 0..k {
            if j != t {
                q[t * k + t] += r[j * k + t] * r[j * k + t];
                q[t * k + j] = -r[j * k + t] * r[t * k + j];
            }
        }
    }
    let eps = 0.005 / k as f64;
    for _ in 0..100.max(k) {
        let mut pqp = 0.0;
        for t in 0..k {
            qp[t] = (0..k).map(|j| q[t * k + j] * p[j]).sum();
            pqp += p[t] * qp[t];
        }
        if (0..k).map(|t| (qp[t] - pqp).abs()).fold(0.0, f64::max) < eps {
            break;
        }
        for t in 0..k {
            let diff = (-qp[t] + pqp) / q[t * k + t];
            p[t] += diff;
            pqp = (pqp + diff * (diff * q[t * k + t] + 2.0 * qp[t])) / (1.0 + diff) / (1.0 + diff);
            for j in 0..k {
                qp[j] = (qp[j] + diff * q[t * k + j]) / (1.0 + diff);
                p[j] /= 1.0 + diff;
            }
        }
    }
    p
}

fn assert_proba_match(svm: &Svm, x: &[f64], what: &str) {
    let mut s = svm.scratch();
    let mut got = vec![0.0; svm.n_classes()];
    svm.predict_proba(x, &mut s, &mut got);
    let want = reference_proba(svm, x);
    for (c, (g, w)) in got.iter().zip(&want).enumerate() {
        assert!(
            (g - w).abs() <= TOL,
            "{what}: class {c}: optimised {g:e} vs reference {w:e}"
        );
    }
}

#[test]
fn svm_probabilities_match_reference_on_the_shipped_default_model() {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/models/default.model");
    let bytes = std::fs::read(&p).expect("default model");
    let model = Model::from_bytes(&bytes).expect("model");
    let Classifier::Svm(svm) = model.classifier() else {
        panic!("the default model is expected to be an SVM");
    };
    // A model that has not made a scratch itself (fresh from the file) with
    // another model's scratch takes the row-major fallback path.
    let fresh = svm.clone();
    let cfg = model.feature_config();
    let mut ex = FeatureExtractor::new(cfg).expect("extractor");
    let mut feat = vec![0.0; ex.dim()];
    let mut z = vec![0.0; ex.dim()];
    let mut n = 0;
    for road in 0..ROADS.len() {
        for (seed, kmh, noisy) in [(21, 15.0, false), (22, 70.0, true), (23, 35.0, false)] {
            let frame = road_frame(cfg, road, seed, kmh, noisy);
            ex.extract(&frame, &mut feat).expect("extract");
            model.standardiser().apply(&feat, &mut z);
            assert_proba_match(svm, &z, &format!("{} seed {seed}", ROADS[road]));
            let mut s = svm.scratch();
            let mut got = vec![0.0; svm.n_classes()];
            fresh.predict_proba(&z, &mut s, &mut got);
            let want = reference_proba(svm, &z);
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() <= TOL, "fallback path: {g:e} vs {w:e}");
            }
            n += 1;
        }
    }
    // A support vector itself (|u − v|² = 0 for that one) and far-away inputs.
    let json = serde_json::to_value(svm).expect("json");
    let sv: Vec<f64> = serde_json::from_value(json["sv"].clone()).expect("sv");
    let d = svm.dim();
    assert_proba_match(svm, &sv[3 * d..4 * d], "support vector 3");
    assert_proba_match(svm, &vec![0.0; d], "origin");
    assert_proba_match(svm, &vec![50.0; d], "far away");
    assert!(n == 18);
}

#[test]
fn svm_probabilities_match_reference_on_trained_models() {
    // Small trained machines with odd dimensions (no multiple of the
    // unrolling width), both kernels.
    for (dim, kernel) in [
        (3, Kernel::Rbf { gamma: 0.7 }),
        (7, Kernel::Rbf { gamma: 0.05 }),
        (5, Kernel::Linear),
    ] {
        let n_classes = 4;
        let n = 120;
        let mut x = Vec::with_capacity(n * dim);
        let mut y = Vec::with_capacity(n);
        for i in 0..n {
            let c = i % n_classes;
            y.push(c);
            for j in 0..dim {
                let h = ((i * 7919 + j * 104_729) % 1000) as f64 / 1000.0 - 0.5;
                x.push(c as f64 * 0.8 * ((j % 2) as f64 - 0.5) + h);
            }
        }
        let cfg = SvmConfig {
            kernel,
            c: 5.0,
            ..SvmConfig::default()
        };
        let (svm, _) = Svm::train(&cfg, n_classes, dim, &x, &y).expect("train");
        for i in (0..n).step_by(13) {
            let mut q = x[i * dim..(i + 1) * dim].to_vec();
            q[0] += 0.123;
            assert_proba_match(&svm, &q, &format!("dim {dim} {kernel:?} query {i}"));
        }
    }
}
