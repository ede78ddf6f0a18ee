//! The rules: measurements against the loop's budget, one line each with
//! its verdict and the reason. `tools/bench/README.md` ("The rules") says
//! where each limit comes from.

use serde::Serialize;

use crate::cyclictest::Stats;
use crate::parse::IpcRow;
use crate::procfs::Usage;

/// What a line says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Verdict {
    /// Within its limit.
    #[serde(rename = "PASS")]
    Pass,
    /// Over its limit.
    #[serde(rename = "FAIL")]
    Fail,
    /// A figure without a limit (context for the others).
    #[serde(rename = "INFO")]
    Info,
    /// A rule that could not be checked (the reason says why).
    #[serde(rename = "NOT MEASURED")]
    NotMeasured,
}

impl Verdict {
    /// As printed.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::Info => "INFO",
            Verdict::NotMeasured => "NOT MEASURED",
        }
    }
}

/// One line of the verdict table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Line {
    /// What is measured.
    pub item: String,
    /// The figure, with its unit.
    pub measured: String,
    /// The limit, with its unit ("" for INFO).
    pub limit: String,
    /// The verdict.
    pub verdict: Verdict,
    /// Why.
    pub reason: String,
    /// The figure as a number (unit in `item`), for the CSV/JSON.
    pub value: Option<f64>,
    /// The limit as a number.
    pub limit_value: Option<f64>,
}

/// The limits. Defaults: see `tools/bench/README.md`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Budget {
    /// The loop's period, µs (controllers.toml `[loop] rate_hz`).
    pub period_us: f64,
    /// Deadline misses allowed per cycle.
    pub max_miss_rate: f64,
    /// cyclictest's p99.9 may take at most this share of the period.
    pub floor_share: f64,
    /// tcs-loop's wake-up p99 may be at most this multiple of cyclictest's.
    pub loop_vs_floor: f64,
    /// One audio block, ms (1024 samples at 44.1 kHz).
    pub audio_block_ms: f64,
    /// The audio block's one-way p99 may take at most this share of a block.
    pub ipc_share: f64,
    /// The recorder must write at least this many times a drive's rate.
    pub recorder_headroom: f64,
    /// ARTE's hop, ms (arte-svc.toml `[stream] hop_s`).
    pub arte_hop_ms: f64,
    /// One ARTE frame may cost at most this share of a hop.
    pub arte_share: f64,
    /// CPU the car's services (all but plant-sim) may use together, cores.
    pub cpu_cores: f64,
    /// Resident memory the car's services may use together, MiB.
    pub rss_mib: f64,
}

impl Default for Budget {
    fn default() -> Self {
        Self {
            period_us: 1000.0,
            max_miss_rate: 1e-3,
            floor_share: 0.5,
            loop_vs_floor: 1.5,
            audio_block_ms: 1024.0 / 44.1,
            ipc_share: 0.1,
            recorder_headroom: 50.0,
            arte_hop_ms: 25.0,
            arte_share: 0.2,
            cpu_cores: 1.0,
            rss_mib: 256.0,
        }
    }
}

/// tcs-loop's own report over the drive, µs.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct LoopTiming {
    /// Cycles logged.
    pub cycles: u64,
    /// Wake-up latency (woken − absolute deadline) p50 / p99 / p99.9 / max, µs.
    pub wakeup_us: [f64; 4],
    /// Compute time per cycle p50 / p99 / p99.9 / max, µs.
    pub compute_us: [f64; 4],
    /// Cycles whose work ended after the next deadline (the loop's counter).
    pub deadline_misses: u64,
    /// Cycles woken more than one period late: the loop's stalls, each of
    /// which may cost several deadlines (compare cyclictest's `over_limit`).
    pub late_wakeups: u64,
    /// Cycles in the safe state.
    pub safe_cycles: u64,
}

/// The recorder's write rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RecorderRate {
    /// Messages/s it sustains.
    pub msg_per_s: f64,
    /// Messages per second of drive (the larger of the bench's drive second
    /// and the drive just measured).
    pub drive_msg_per_s: f64,
    /// Whether `msg_per_s` is criterion's median (else one pass).
    pub criterion: bool,
}

/// ARTE's frame cost.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArteCost {
    /// Criterion's estimate of the worst `frame_features_and_classify/default*`
    /// benchmark (id, s).
    pub frame: Option<(String, f64)>,
}

/// A measurement, or why it was not made.
pub type Measured<T> = Result<T, String>;

/// Everything one bench run measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Measurements {
    /// tcs-loop over the drive.
    pub loop_timing: Measured<LoopTiming>,
    /// cyclictest, same priority and CPU, same length.
    pub cyclictest: Measured<Stats>,
    /// The audio-block IPC bench.
    pub ipc: Measured<Vec<IpcRow>>,
    /// The recorder's write rate.
    pub recorder: Measured<RecorderRate>,
    /// ARTE's frame cost from criterion.
    pub arte: Measured<ArteCost>,
    /// Estimates arte published during the drive.
    pub arte_estimates: u64,
    /// Each service over the drive.
    pub services: Measured<Vec<Usage>>,
}

/// Services counted in the ECU's budget: all but plant-sim (the simulated
/// vehicle, not on the car).
pub fn on_the_car(name: &str) -> bool {
    name != "plant-sim"
}

fn limit_line(item: &str, value: f64, limit: f64, unit: &str, prec: usize, why: &str) -> Line {
    let ok = value.is_finite() && value <= limit;
    Line {
        item: item.into(),
        measured: format!("{value:.prec$} {unit}").trim_end().to_owned(),
        limit: format!("≤ {limit:.prec$} {unit}").trim_end().to_owned(),
        verdict: if ok { Verdict::Pass } else { Verdict::Fail },
        reason: format!("{} {why}", if ok { "within:" } else { "over:" },),
        value: Some(value),
        limit_value: Some(limit),
    }
}

fn info(item: &str, measured: String, reason: &str, value: Option<f64>) -> Line {
    Line {
        item: item.into(),
        measured,
        limit: String::new(),
        verdict: Verdict::Info,
        reason: reason.into(),
        value,
        limit_value: None,
    }
}

fn missing(item: &str, why: &str) -> Line {
    Line {
        item: item.into(),
        measured: "-".into(),
        limit: String::new(),
        verdict: Verdict::NotMeasured,
        reason: why.into(),
        value: None,
        limit_value: None,
    }
}

/// The verdict lines of `m` against `b`.
pub fn judge(m: &Measurements, b: &Budget) -> Vec<Line> {
    let mut out = Vec::new();
    let period = b.period_us;
    // 1-2: the loop's own report
    match &m.loop_timing {
        Ok(t) if t.cycles > 0 => {
            let cycle = t.wakeup_us[2] + t.compute_us[2];
            out.push(limit_line(
                "tcs-loop wake-up p99.9 + compute p99.9",
                cycle,
                period,
                "µs",
                0,
                &format!(
                    "a cycle's work (woken {:.0} µs late, {:.0} µs of compute at p99.9) must end within the {period:.0} µs period",
                    t.wakeup_us[2], t.compute_us[2]
                ),
            ));
            let rate = t.deadline_misses as f64 / t.cycles as f64;
            // Whose stalls: the loop's late wake-ups beside those of the
            // bare scheduler (cyclictest, same CPU, priority and period).
            let floor = match &m.cyclictest {
                Ok(c) => format!(
                    "; woken > {period:.0} µs late {} times, cyclictest alone {} times in as long",
                    t.late_wakeups, c.over_limit
                ),
                Err(_) => format!("; woken > {period:.0} µs late {} times", t.late_wakeups),
            };
            let mut l = limit_line(
                "tcs-loop deadline misses per cycle",
                rate,
                b.max_miss_rate,
                "",
                4,
                &format!(
                    "{} of {} cycles ended after the next deadline (max wake-up {:.0} µs){floor}",
                    t.deadline_misses, t.cycles, t.wakeup_us[3]
                ),
            );
            l.measured = format!("{rate:.4} ({} / {})", t.deadline_misses, t.cycles);
            out.push(l);
        }
        Ok(_) => {
            out.push(missing("tcs-loop cycle", "the drive log holds no cycles"));
        }
        Err(e) => out.push(missing("tcs-loop cycle", e)),
    }
    // 3-4: the machine's floor
    match &m.cyclictest {
        Ok(c) => {
            out.push(limit_line(
                "cyclictest p99.9 (machine floor)",
                c.p999_us,
                b.floor_share * period,
                "µs",
                0,
                &format!(
                    "the scheduler alone must leave at least {:.0}% of the period for work ({} of {} wake-ups > {} µs, max {:.0} µs)",
                    (1.0 - b.floor_share) * 100.0,
                    c.over_limit,
                    c.count,
                    c.limit_us,
                    c.max_us
                ),
            ));
            if let Ok(t) = &m.loop_timing
                && t.cycles > 0
            {
                let ratio = t.wakeup_us[1] / c.p99_us.max(1.0);
                let mut l = limit_line(
                    "tcs-loop wake-up p99 / cyclictest p99",
                    ratio,
                    b.loop_vs_floor,
                    "",
                    2,
                    &format!(
                        "the loop wakes as promptly as the bare scheduler allows ({:.0} vs {:.0} µs)",
                        t.wakeup_us[1], c.p99_us
                    ),
                );
                l.measured = format!("{ratio:.2}");
                l.limit = format!("≤ {:.2}", b.loop_vs_floor);
                out.push(l);
            }
        }
        Err(e) => out.push(missing("cyclictest p99.9 (machine floor)", e)),
    }
    // 5: the audio block
    match &m.ipc {
        Ok(rows) => {
            let find = |mode: &str| rows.iter().find(|r| r.mode == mode);
            match find("iox-event") {
                Some(r) => {
                    let lim = b.ipc_share * b.audio_block_ms * 1000.0;
                    let mut l = limit_line(
                        "audio block over iceoryx2 (event wake-up), p99",
                        r.p99_us,
                        lim,
                        "µs",
                        0,
                        &format!(
                            "one-way latency against {:.0}% of a {:.1} ms block; {} lost",
                            b.ipc_share * 100.0,
                            b.audio_block_ms,
                            r.lost
                        ),
                    );
                    if r.lost > 0 {
                        l.verdict = Verdict::Fail;
                        l.reason = format!("{} blocks lost", r.lost);
                    }
                    out.push(l);
                }
                None => out.push(missing("audio block over iceoryx2", "no iox-event row")),
            }
            for (iox, uds) in [("iox-event", "uds-block"), ("iox-poll", "uds-poll")] {
                if let (Some(a), Some(u)) = (find(iox), find(uds)) {
                    out.push(info(
                        &format!("audio block {iox} vs {uds}, p50 / p99"),
                        format!(
                            "{:.1} / {:.0} µs vs {:.1} / {:.0} µs",
                            a.p50_us, a.p99_us, u.p50_us, u.p99_us
                        ),
                        &format!(
                            "iceoryx2 / Unix socket median ratio {:.2}",
                            a.p50_us / u.p50_us.max(1e-9)
                        ),
                        Some(a.p50_us / u.p50_us.max(1e-9)),
                    ));
                }
            }
        }
        Err(e) => out.push(missing("audio block over iceoryx2", e)),
    }
    // 6: the recorder
    match &m.recorder {
        Ok(r) => {
            let h = r.msg_per_s / r.drive_msg_per_s;
            let mut l = limit_line(
                "recorder headroom (write rate / drive rate)",
                h,
                f64::INFINITY,
                "x",
                0,
                "",
            );
            let ok = h >= b.recorder_headroom;
            l.limit = format!("≥ {:.0} x", b.recorder_headroom);
            l.limit_value = Some(b.recorder_headroom);
            l.verdict = if ok { Verdict::Pass } else { Verdict::Fail };
            l.reason = format!(
                "{}: {:.0} msg/s written ({}) against {:.0} msg/s a drive produces",
                if ok { "enough" } else { "too little" },
                r.msg_per_s,
                if r.criterion {
                    "criterion median"
                } else {
                    "one pass"
                },
                r.drive_msg_per_s
            );
            out.push(l);
        }
        Err(e) => out.push(missing("recorder headroom", e)),
    }
    // 7: ARTE
    let hop_us = b.arte_hop_ms * 1000.0;
    match &m.arte {
        Ok(ArteCost {
            frame: Some((id, s)),
        }) => out.push(limit_line(
            "ARTE frame cost (features + classifier, worst case)",
            s * 1e6,
            b.arte_share * hop_us,
            "µs",
            0,
            &format!(
                "{id}: one frame per {:.0} ms hop may use {:.0}% of a core",
                b.arte_hop_ms,
                b.arte_share * 100.0
            ),
        )),
        Ok(_) => out.push(missing(
            "ARTE frame cost",
            "no frame_features_and_classify/default benchmark in the output",
        )),
        Err(e) => out.push(missing("ARTE frame cost", e)),
    }
    // 8: services
    match &m.services {
        Ok(us) => {
            if let Some(a) = us.iter().find(|u| u.name == "arte")
                && m.arte_estimates > 0
            {
                let per = a.cpu_s / m.arte_estimates as f64 * 1e6;
                out.push(limit_line(
                    "arte CPU per estimate during the drive",
                    per,
                    b.arte_share * hop_us,
                    "µs",
                    0,
                    &format!(
                        "{:.2} CPU s for {} estimates, polling included",
                        a.cpu_s, m.arte_estimates
                    ),
                ));
            }
            for u in us {
                out.push(info(
                    &format!("{} CPU share / RSS mean / RSS peak", u.name),
                    format!(
                        "{:.1}% / {:.1} MiB / {:.1} MiB",
                        u.cpu_share * 100.0,
                        u.rss_mean_mib,
                        u.rss_peak_mib
                    ),
                    &format!(
                        "{:.2} CPU s over {:.1} s, {} samples{}",
                        u.cpu_s,
                        u.span_s,
                        u.samples,
                        if on_the_car(&u.name) {
                            ""
                        } else {
                            " (simulated vehicle: not counted)"
                        }
                    ),
                    Some(u.cpu_share),
                ));
            }
            let car: Vec<&Usage> = us.iter().filter(|u| on_the_car(&u.name)).collect();
            let cpu: f64 = car.iter().map(|u| u.cpu_share).sum();
            let rss: f64 = car.iter().map(|u| u.rss_peak_mib).sum();
            let names = car
                .iter()
                .map(|u| u.name.as_str())
                .collect::<Vec<_>>()
                .join(", ");
            let mut l = limit_line(
                "car services' CPU together",
                cpu,
                b.cpu_cores,
                "cores",
                3,
                &format!("sum of {names}"),
            );
            if car.len() < 4 {
                l.verdict = Verdict::NotMeasured;
                l.reason = format!("only {names} sampled (4 expected)");
            }
            out.push(l);
            let mut l = limit_line(
                "car services' resident memory together (peaks)",
                rss,
                b.rss_mib,
                "MiB",
                1,
                &format!("sum of VmHWM of {names}"),
            );
            if car.len() < 4 {
                l.verdict = Verdict::NotMeasured;
                l.reason = format!("only {names} sampled (4 expected)");
            }
            out.push(l);
        }
        Err(e) => out.push(missing("services' CPU and memory", e)),
    }
    out
}

/// The whole run's verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Overall {
    /// Every rule measured and within its limit.
    #[serde(rename = "PASS")]
    Pass,
    /// At least one rule over its limit.
    #[serde(rename = "FAIL")]
    Fail,
    /// None over, but some not measured.
    #[serde(rename = "INCOMPLETE")]
    Incomplete,
}

/// FAIL if any line fails; else INCOMPLETE if any was not measured; else PASS.
pub fn overall(lines: &[Line]) -> Overall {
    if lines.iter().any(|l| l.verdict == Verdict::Fail) {
        Overall::Fail
    } else if lines.iter().any(|l| l.verdict == Verdict::NotMeasured) {
        Overall::Incomplete
    } else {
        Overall::Pass
    }
}
