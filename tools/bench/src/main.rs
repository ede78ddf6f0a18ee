//! `grip-bench`: qualifies a machine (an ECU) for grip. Run through
//! `tools/bench/run`, which builds what it needs; `tools/bench/README.md`
//! describes every measurement and rule.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use clap::Parser;
use indicatif::{ProgressBar, ProgressStyle};

use grip_bench::cyclictest;
use grip_bench::parse;
use grip_bench::procfs::{self, Sample};
use grip_bench::report::{self, Report};
use grip_bench::verdict::{self, ArteCost, Budget, LoopTiming, Measurements, RecorderRate};

#[derive(Parser)]
#[command(
    name = "grip-bench",
    about = "ECU qualification: tcs-loop beside cyclictest, audio-block IPC, recorder headroom, ARTE frame cost, each service's CPU and memory during a drive, and a verdict against the loop's budget"
)]
struct Args {
    /// Short run (10 s drive and cyclictest, fewer IPC blocks, criterion's quick mode):
    /// a check that everything runs, not a qualification.
    #[arg(long)]
    quick: bool,
    /// Seconds of drive and of cyclictest (default 60, 10 with --quick).
    #[arg(long)]
    secs: Option<u64>,
    /// Where the table, bench.json, bench.csv and the raw outputs go.
    #[arg(long, default_value = "out/bench")]
    out: PathBuf,
    /// grip's configuration directory.
    #[arg(long, default_value = "config")]
    config_dir: PathBuf,
    /// Directory of the release binaries `grip` and the five services.
    #[arg(long, env = "GRIP_BIN_DIR")]
    bin_dir: PathBuf,
    /// The audio-block IPC bench executable (audio-acq's `ipc_latency`).
    #[arg(long)]
    ipc_bench: Option<PathBuf>,
    /// The recorder's write-rate bench executable (`write_rate`).
    #[arg(long)]
    recorder_bench: Option<PathBuf>,
    /// ARTE's classification bench executable (grip-arte's `classify`).
    #[arg(long)]
    arte_bench: Option<PathBuf>,
    /// CPU the car's services may use together, cores (your ECU's budget).
    #[arg(long, default_value_t = Budget::default().cpu_cores)]
    cpu_cores: f64,
    /// Resident memory the car's services may use together, MiB.
    #[arg(long, default_value_t = Budget::default().rss_mib)]
    rss_mib: f64,
    /// Deadline misses allowed per cycle.
    #[arg(long, default_value_t = Budget::default().max_miss_rate)]
    max_miss_rate: f64,
}

/// A number at `key` ("section.field") of a TOML file, with an error that
/// names the file and the field.
fn toml_number(path: &Path, key: &str) -> anyhow::Result<f64> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let v: toml::Value =
        toml::from_str(&text).with_context(|| format!("{}: not valid TOML", path.display()))?;
    let mut at = &v;
    for part in key.split('.') {
        at = at
            .get(part)
            .with_context(|| format!("{}: field {key} is missing", path.display()))?;
    }
    at.as_float()
        .or_else(|| at.as_integer().map(|i| i as f64))
        .with_context(|| format!("{}: field {key} is not a number", path.display()))
}

fn bar(len: u64, prefix: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{prefix:<22} [{bar:30}] {pos}/{len} s {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_prefix(prefix.to_owned());
    pb
}

fn spinner(prefix: &str) -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    pb.set_style(
        ProgressStyle::with_template("{prefix:<22} {spinner} {elapsed} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    pb.set_prefix(prefix.to_owned());
    pb.enable_steady_tick(Duration::from_millis(200));
    pb
}

/// Runs `cmd` to the end with its stdout and stderr captured (in this
/// order, stderr after stdout) into `log`, ticking `pb` each second.
fn run_captured(mut cmd: Command, log: &Path, pb: &ProgressBar) -> anyhow::Result<(bool, String)> {
    let what = format!("{cmd:?}");
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("starting {what}"))?;
    let mut so = child.stdout.take().context("stdout")?;
    let mut se = child.stderr.take().context("stderr")?;
    let t_out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = so.read_to_string(&mut s);
        s
    });
    let t_err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = se.read_to_string(&mut s);
        s
    });
    let t0 = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait()? {
            break st;
        }
        pb.set_position(t0.elapsed().as_secs());
        std::thread::sleep(Duration::from_millis(200));
    };
    let text = format!(
        "{}{}",
        t_out.join().unwrap_or_default(),
        t_err.join().unwrap_or_default()
    );
    std::fs::write(log, &text).with_context(|| format!("writing {}", log.display()))?;
    Ok((status.success(), text))
}

const SERVICES: [&str; 5] = ["recorder", "plant-sim", "audio-acq", "arte", "tcs-loop"];

/// The bench's drive: stop-and-go demand (220 N m, 1 s on, 2 s off) from
/// rest over 5 s segments of five roads in turn, `secs` long.
fn scenario_toml(secs: u64) -> String {
    let roads = ["asphalt", "snow", "gravel", "wet_asphalt", "stone"];
    let mut s = format!(
        "# written by grip-bench: the load of a drive for the ECU bench\nname = \"bench\"\ndescription = \"stop-and-go 220 N m over five roads in turn, {secs} s\"\nv0_kmh = 0.0\nsegments_by = \"time\"\nduration = {secs}.0\n\n[demand]\nkind = \"stop_and_go\"\ntorque = 220.0\non = 1.0\noff = 2.0\nrise = 0.3\n"
    );
    let mut left = secs as f64;
    let mut k = 0;
    while left > 1e-9 {
        let d = left.min(5.0);
        s.push_str(&format!(
            "\n[[segment]]\nroad = \"{}\"\nduration = {d:.1}\n",
            roads[k % roads.len()]
        ));
        left -= d;
        k += 1;
    }
    s
}

struct DriveResult {
    timing: Result<LoopTiming, String>,
    services: Result<Vec<procfs::Usage>, String>,
    estimates: u64,
    msg_per_s: Option<f64>,
}

fn drive(
    a: &Args,
    cfg: &Path,
    out: &Path,
    secs: u64,
    period_us: f64,
) -> anyhow::Result<DriveResult> {
    let scen = out.join("bench-scenario.toml");
    std::fs::write(&scen, scenario_toml(secs))
        .with_context(|| format!("writing {}", scen.display()))?;
    let mcap = out.join("drive.mcap");
    let grip = a.bin_dir.join("grip");
    let log_path = out.join("drive.txt");
    let log = std::fs::File::create(&log_path)
        .with_context(|| format!("creating {}", log_path.display()))?;
    let mut child = Command::new(&grip)
        .arg("--config-dir")
        .arg(cfg)
        .args(["drive", "--scenario"])
        .arg(&scen)
        .arg("--out")
        .arg(&mcap)
        .env("GRIP_BIN_DIR", &a.bin_dir)
        .stdout(log.try_clone()?)
        .stderr(log)
        .spawn()
        .with_context(|| format!("starting {} drive", grip.display()))?;
    let root = Path::new("/proc");
    let pb = bar(secs + 5, "drive (5 services)");
    let t0 = Instant::now();
    // per service: (pid, samples)
    let mut seen: BTreeMap<String, (u32, Vec<Sample>)> = BTreeMap::new();
    let mut all_since: Option<f64> = None;
    let status = loop {
        if let Some(st) = child.try_wait()? {
            break st;
        }
        let t = t0.elapsed().as_secs_f64();
        let procs = procfs::descendants(root, child.id());
        let mut present = 0;
        for (pid, comm) in &procs {
            if !SERVICES.contains(&comm.as_str()) {
                continue;
            }
            present += 1;
            if let Ok((_, s)) = procfs::sample(root, *pid, t) {
                let e = seen.entry(comm.clone()).or_insert((*pid, Vec::new()));
                if e.0 != *pid {
                    // restarted: keep the new process's samples only
                    *e = (*pid, Vec::new());
                }
                e.1.push(s);
            }
        }
        if present == SERVICES.len() && all_since.is_none() {
            all_since = Some(t);
        }
        pb.set_position(t as u64);
        pb.set_message(format!("{present} of 5 services running"));
        std::thread::sleep(Duration::from_millis(250));
    };
    pb.finish_and_clear();
    let ticks = procfs::clock_ticks();
    // steady state: from 2 s after all five run (start-up left out)
    let services = match all_since {
        None => Err(format!(
            "the five services never ran together (grip drive: {status}; see {})",
            log_path.display()
        )),
        Some(t_all) => Ok(SERVICES
            .iter()
            .filter_map(|name| {
                let (_, v) = seen.get(*name)?;
                let steady: Vec<Sample> =
                    v.iter().copied().filter(|s| s.t >= t_all + 2.0).collect();
                procfs::usage(name, &steady, ticks)
            })
            .collect()),
    };
    if !status.success() {
        let msg = format!("grip drive failed ({status}); see {}", log_path.display());
        return Ok(DriveResult {
            timing: Err(msg),
            services,
            estimates: 0,
            msg_per_s: None,
        });
    }
    let dlog = grip_drive::DriveLog::load(&mcap).map_err(|e| anyhow::anyhow!(e.full()))?;
    let (vehicle, from, _) = grip_drive::vehicle_for(&dlog, cfg);
    let s = grip_drive::summarize(&dlog, &vehicle, &from, None);
    let tm = &s.timing;
    let us = |p: &grip_drive::summary::Percentiles| {
        [p.p50, p.p99, p.p999, p.max].map(|v| v as f64 / 1e3)
    };
    let timing = LoopTiming {
        cycles: tm.cycles,
        wakeup_us: us(&tm.wakeup),
        compute_us: us(&tm.compute),
        deadline_misses: tm.deadline_misses,
        late_wakeups: tm
            .wakeup_ns
            .iter()
            .filter(|&&w| w as f64 > period_us * 1e3)
            .count() as u64,
        safe_cycles: tm.safe_cycles,
    };
    let span = match (dlog.cycles.first(), dlog.cycles.last()) {
        (Some(a), Some(b)) if b.stamp_ns > a.stamp_ns => {
            Some((b.stamp_ns - a.stamp_ns) as f64 / 1e9)
        }
        _ => None,
    };
    let total: u64 = dlog.counts.values().sum();
    Ok(DriveResult {
        timing: Ok(timing),
        services,
        estimates: dlog.roads.len() as u64,
        msg_per_s: span.map(|s| total as f64 / s),
    })
}

fn have(cmd: &str) -> bool {
    Command::new(cmd)
        .arg("--help")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

fn cyclictest_run(
    cfg: &Path,
    out: &Path,
    secs: u64,
    period_us: u64,
) -> Result<cyclictest::Stats, String> {
    if !have("cyclictest") {
        return Err("cyclictest not found (Debian: rt-tests; tools/bench/run installs it)".into());
    }
    let tcs = cfg.join("tcs-loop.toml");
    let prio = toml_number(&tcs, "rt.fifo_priority").map_err(|e| format!("{e:#}"))? as u32;
    let cpu = std::fs::read_to_string(&tcs)
        .ok()
        .and_then(|t| toml::from_str::<toml::Value>(&t).ok())
        .and_then(|v| v.get("rt")?.get("cpus")?.as_array()?.first()?.as_integer())
        .map(|c| c as u32)
        .filter(|c| (*c as usize) < std::thread::available_parallelism().map_or(1, |n| n.get()));
    let loops = secs * 1_000_000 / period_us;
    let mut cmd = Command::new("cyclictest");
    cmd.args(cyclictest::args(prio, period_us, loops, cpu, 10_000));
    let pb = bar(secs, "cyclictest");
    pb.set_message(format!("FIFO {prio}, CPU {cpu:?}"));
    let r = run_captured(cmd, &out.join("cyclictest.txt"), &pb).map_err(|e| format!("{e:#}"));
    pb.finish_and_clear();
    let (ok, text) = r?;
    if !ok {
        return Err(format!(
            "cyclictest failed (see {})",
            out.join("cyclictest.txt").display()
        ));
    }
    cyclictest::parse(&text, period_us)
}

fn ipc_run(exe: Option<&Path>, out: &Path, quick: bool) -> Result<Vec<parse::IpcRow>, String> {
    let exe = exe.ok_or("no --ipc-bench given")?;
    let n = if quick { 2000 } else { 10_000 };
    let mut cmd = Command::new(exe);
    cmd.env("GRIP_BENCH_N", n.to_string());
    let pb = spinner("audio block IPC");
    pb.set_message(format!("4 modes x {n} blocks at 1 ms"));
    let r = run_captured(cmd, &out.join("ipc.txt"), &pb).map_err(|e| format!("{e:#}"));
    pb.finish_and_clear();
    let (ok, text) = r?;
    if !ok {
        return Err(format!(
            "IPC bench failed (see {})",
            out.join("ipc.txt").display()
        ));
    }
    parse::ipc_table(&text)
}

fn criterion_cmd(exe: &Path, out: &Path, filter: &str, quick: bool) -> Command {
    let mut cmd = Command::new(exe);
    cmd.arg("--bench").arg(filter);
    if quick {
        cmd.arg("--quick");
    }
    cmd.env("CRITERION_HOME", out.join("criterion"));
    cmd
}

fn recorder_run(
    exe: Option<&Path>,
    out: &Path,
    quick: bool,
    drive_rate: Option<f64>,
) -> Result<RecorderRate, String> {
    let exe = exe.ok_or("no --recorder-bench given")?;
    // quick: only the one pass the bench makes before criterion (a filter
    // that selects no criterion benchmark)
    let filter = if quick {
        "^one-pass-only$"
    } else {
        "recorder/"
    };
    let pb = spinner("recorder write rate");
    let r = run_captured(
        criterion_cmd(exe, out, filter, false),
        &out.join("recorder.txt"),
        &pb,
    )
    .map_err(|e| format!("{e:#}"));
    pb.finish_and_clear();
    let (ok, text) = r?;
    if !ok {
        return Err(format!(
            "recorder bench failed (see {})",
            out.join("recorder.txt").display()
        ));
    }
    let (per_second, one_pass, _) = parse::recorder_one_pass(&text)
        .ok_or("recorder bench: no 'write_rate:' line in its output")?;
    let crit = parse::criterion(&text)?
        .into_iter()
        .find(|c| c.id.starts_with("recorder/"))
        .and_then(|c| c.thrpt_per_s);
    Ok(RecorderRate {
        msg_per_s: crit.map_or(one_pass, |t| t[1]),
        drive_msg_per_s: per_second.max(drive_rate.unwrap_or(0.0)),
        criterion: crit.is_some(),
    })
}

fn arte_run(exe: Option<&Path>, out: &Path, quick: bool) -> Result<ArteCost, String> {
    let exe = exe.ok_or("no --arte-bench given")?;
    let pb = spinner("ARTE frame cost");
    let r = run_captured(
        criterion_cmd(exe, out, "frame_features_and_classify/default", quick),
        &out.join("arte.txt"),
        &pb,
    )
    .map_err(|e| format!("{e:#}"));
    pb.finish_and_clear();
    let (ok, text) = r?;
    if !ok {
        return Err(format!(
            "ARTE bench failed (see {})",
            out.join("arte.txt").display()
        ));
    }
    let frame = parse::criterion(&text)?
        .into_iter()
        .filter(|c| c.id.starts_with("frame_features_and_classify/default"))
        .map(|c| (c.id, c.time_s[1]))
        .max_by(|a, b| a.1.total_cmp(&b.1));
    Ok(ArteCost { frame })
}

/// The 1, 5 and 15 min load averages (`/proc/loadavg`).
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

fn conditions(quick: bool, secs: u64) -> Vec<(String, String)> {
    let read = |p: &str| {
        std::fs::read_to_string(p)
            .map(|s| s.trim().to_owned())
            .unwrap_or_default()
    };
    let cpu = read("/proc/cpuinfo")
        .lines()
        .find_map(|l| {
            l.strip_prefix("model name")
                .map(|v| v.trim_start_matches([' ', '\t', ':']).to_owned())
        })
        .unwrap_or_default();
    let version = read("/proc/sys/kernel/version");
    let date = Command::new("date")
        .args(["-u", "+%Y-%m-%dT%H:%M:%SZ"])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .unwrap_or_default();
    vec![
        ("date".into(), date),
        ("kernel".into(), read("/proc/sys/kernel/osrelease")),
        (
            "preempt_rt".into(),
            (version.contains("PREEMPT_RT") || Path::new("/sys/kernel/realtime").exists())
                .to_string(),
        ),
        (
            "cpus".into(),
            std::thread::available_parallelism()
                .map_or(1, |n| n.get())
                .to_string(),
        ),
        ("cpu".into(), cpu),
        ("load_average_at_start".into(), load_average()),
        ("mode".into(), if quick { "quick" } else { "full" }.into()),
        ("drive_and_cyclictest_s".into(), secs.to_string()),
    ]
}

fn main() -> ExitCode {
    match run() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn run() -> anyhow::Result<ExitCode> {
    let a = Args::parse();
    let secs = a.secs.unwrap_or(if a.quick { 10 } else { 60 });
    if secs < 3 {
        bail!("--secs must be at least 3");
    }
    let cwd = std::env::current_dir()?;
    let cfg = cwd.join(&a.config_dir);
    let out = cwd.join(&a.out);
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let rate = grip_config::load_controllers(cfg.join("controllers.toml"))?
        .loop_
        .rate_hz;
    let sr = toml_number(&cfg.join("audio-acq.toml"), "audio.sample_rate")?;
    let block = toml_number(&cfg.join("audio-acq.toml"), "audio.block_samples")?;
    let hop = toml_number(&cfg.join("arte-svc.toml"), "stream.hop_s")?;
    let budget = Budget {
        period_us: 1e6 / rate,
        audio_block_ms: block / sr * 1e3,
        arte_hop_ms: hop * 1e3,
        cpu_cores: a.cpu_cores,
        rss_mib: a.rss_mib,
        max_miss_rate: a.max_miss_rate,
        ..Budget::default()
    };
    let mut cond = conditions(a.quick, secs);
    eprintln!(
        "grip-bench: {} mode, {secs} s drive + {secs} s cyclictest, loop period {:.0} µs; output in {}",
        if a.quick { "quick" } else { "full" },
        budget.period_us,
        out.display()
    );
    eprintln!("[1/5] drive: the five services, sampled from /proc every 0.25 s");
    let d = drive(&a, &cfg, &out, secs, budget.period_us)?;
    eprintln!("[2/5] cyclictest at tcs-loop's priority and CPU, {secs} s");
    let ct = cyclictest_run(&cfg, &out, secs, budget.period_us.round() as u64);
    eprintln!("[3/5] audio block: iceoryx2 vs Unix socket");
    let ipc = ipc_run(a.ipc_bench.as_deref(), &out, a.quick);
    eprintln!("[4/5] recorder write rate");
    let rec = recorder_run(a.recorder_bench.as_deref(), &out, a.quick, d.msg_per_s);
    eprintln!("[5/5] ARTE frame cost");
    let arte = arte_run(a.arte_bench.as_deref(), &out, a.quick);
    cond.push(("load_average_at_end".into(), load_average()));
    let m = Measurements {
        loop_timing: d.timing,
        cyclictest: ct,
        ipc,
        recorder: rec,
        arte,
        arte_estimates: d.estimates,
        services: d.services,
    };
    let lines = verdict::judge(&m, &budget);
    let overall = verdict::overall(&lines);
    let table = report::table(&lines, overall);
    let mut head = String::new();
    for (k, v) in &cond {
        head.push_str(&format!("{k}: {v}\n"));
    }
    let text = format!("{head}\n{table}");
    println!("{text}");
    std::fs::write(out.join("bench.txt"), &text)?;
    report::write_csv(&out.join("bench.csv"), &lines)?;
    report::write_json(
        &out.join("bench.json"),
        &Report {
            conditions: &cond,
            budget: &budget,
            measurements: &m,
            lines: &lines,
            overall,
        },
    )?;
    eprintln!(
        "written: {} (table), bench.json, bench.csv, raw outputs beside them",
        out.join("bench.txt").display()
    );
    Ok(match overall {
        verdict::Overall::Pass => ExitCode::SUCCESS,
        verdict::Overall::Fail => ExitCode::from(2),
        verdict::Overall::Incomplete => ExitCode::from(3),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bench_scenario_parses_and_lasts_what_was_asked() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = grip_config::ConfigDir::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../config"));
        let roads = cfg.roads().unwrap();
        for secs in [3u64, 10, 12, 60] {
            let p = dir.path().join(format!("s{secs}.toml"));
            std::fs::write(&p, scenario_toml(secs)).unwrap();
            let s = cfg.scenario_with(p.to_str().unwrap(), &roads).unwrap();
            assert!(
                (s.duration - secs as f64).abs() < 1e-9,
                "{secs}: {}",
                s.duration
            );
        }
    }

    #[test]
    fn toml_numbers_name_file_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.toml");
        std::fs::write(&p, "[rt]\nfifo_priority = 80\nname = \"a\"\n").unwrap();
        assert_eq!(toml_number(&p, "rt.fifo_priority").unwrap(), 80.0);
        let e = format!("{:#}", toml_number(&p, "rt.cpus").unwrap_err());
        assert!(
            e.contains("x.toml") && e.contains("rt.cpus") && e.contains("missing"),
            "{e}"
        );
        let e = format!("{:#}", toml_number(&p, "rt.name").unwrap_err());
        assert!(e.contains("not a number"), "{e}");
    }
}
