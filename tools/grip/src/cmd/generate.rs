//! `grip generate --out DIR --count N`: many realistic drive logs, fast.
//!
//! `grip drive` runs the five services as processes in real time (about
//! 3 s per drive). A fleet needs thousands of logs, so this command runs
//! the services' own per-cycle code in one process, in lock step on a
//! scripted clock (`ManualClock`), as fast as the CPU allows:
//!
//! - plant-sim: `PlantSim::cycle`, built by its start-up
//!   ([`grip_plant_sim::run::load`]) from the log's scenario, seed and vehicle;
//! - tcs-loop: `TcsLoop::cycle`, built by [`grip_tcs_loop::build`], over an
//!   in-memory CAN bus pair ([`MemBus::pair`]) with plant-sim, 1 kHz;
//! - audio-acq: its loop body [`AcqLoop::step`] on its synthetic source
//!   ([`SynthSource`], configured by its own `audio-acq.toml`) fed the
//!   plant's ground truth, one block whenever the scripted clock reaches the
//!   block's end;
//! - arte: [`grip_arte_svc::ArteLoop::on_block`] on every block (built by
//!   the service's start-up, [`grip_arte_svc::prepare_with_clock`]), with
//!   tcs-loop's cycle records as its speed input and the block's end as its
//!   clock; its estimates reach tcs-loop in the next cycle;
//! - recorder: the MCAP writer with the recorder's options, its
//!   [`grip_recorder::write_run_info`] (`grip.run`, every configuration file
//!   attached) and its `grip.recorder` counters.
//!
//! So a generated log has the same topics, schemas, metadata and
//! attachments as a real drive, and `grip inspect` and `grip replay` read it
//! unchanged. It is marked as simulated: `grip.run` carries `source =
//! generated` and `clock = scripted` (the loop-timing fields, wake-up
//! latency, compute time and deadline misses, are those of a scripted clock:
//! zero; they measure nothing).
//!
//! Each log runs on a copy of the configuration directory that holds what
//! varies per log, so the log carries exactly the configuration it ran with
//! (and `grip replay` rebuilds it from the attachments): the scenario (a
//! random road sequence per seed, or the given one, with the start speed and
//! demand drawn per log when asked), `audio-acq.toml`'s `[synth] seed` (the
//! log's seed) and `noise` (`--snr-db`), plant-sim's sensor-noise seed (the
//! log's seed).

use std::cell::Cell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use anyhow::{Context, bail};
use grip_arte_svc::{ArteCounters, EstimateSink};
use grip_audio_acq::synth::{SynthSource, TruthInput, TruthReadError};
use grip_audio_acq::{AcqLoop, AcqStatus, BlockSink};
use grip_io::can::MemBus;
use grip_io::clock::{Clock, ManualClock};
use grip_io::mcaplog::McapWriter;
use grip_io::service::{ConfigArgs, ServiceConfig};
use grip_msgs::{AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};
use grip_sim::random::RandomSpec;
use grip_tcs_loop::{CycleTick, RecordSink, RoadSource};
use rand::{Rng, SeedableRng};

use super::Ctx;
use super::drive::{Controller, OnOff};

#[derive(clap::Args)]
pub struct Args {
    /// Directory for the logs (created); files gen-NNNNN-sSEED.mcap.
    #[arg(long)]
    out: PathBuf,
    /// Replace logs of those names that are already in --out (without it
    /// they are refused before any log is generated).
    #[arg(long)]
    force: bool,
    /// How many logs.
    #[arg(long, default_value_t = 10)]
    count: usize,
    /// `random` (a random road sequence per seed, as `grip sim --scenario
    /// random`), or a scenario name under `<config-dir>/scenarios` (e.g.
    /// `paper`), or a scenario TOML file.
    #[arg(long, default_value = "random")]
    scenario: String,
    /// Seed of the first log; log i has seed SEED0 + i (plant sensor noise,
    /// synthetic audio, random roads, and the per-log draws below).
    #[arg(long, default_value_t = 1)]
    seed0: u64,
    /// Controllers, comma-separated; log i runs the (i mod n)-th.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "mtte")]
    controllers: Vec<Controller>,
    /// ARTE in the controller: on, off, or on,off (log i takes the
    /// (i / number of controllers mod 2)-th).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "on")]
    arte: Vec<OnOff>,
    /// Vehicle TOML for plant-sim and tcs-loop (attached to each log as
    /// `grip drive --vehicle` does); default: `<config-dir>/vehicle.toml`.
    #[arg(long)]
    vehicle: Option<PathBuf>,
    /// Start speed, km/h: one value, or LO:HI drawn uniformly per log
    /// (default: the scenario's; 10 km/h for random).
    #[arg(long, value_parser = parse_range)]
    v0_kmh: Option<(f64, f64)>,
    /// Constant driver demand, N m: one value or LO:HI per log, within
    /// 0..=10000 and the vehicle's torque_max (default: the scenario's;
    /// 300 N m for random). The scenario's demand must be constant.
    #[arg(long, value_parser = parse_torque)]
    torque: Option<TorqueArg>,
    /// The recipe of `--scenario random`, as `grip sim --random`:
    /// KEY=VALUE,... with KEY one of v0_kmh, torque, min_len_m, max_len_m,
    /// cover_m, duration (e.g. min_len_m=3,max_len_m=12). --v0-kmh and
    /// --torque, drawn per log, take the place of its v0_kmh and torque.
    #[arg(long)]
    random: Option<String>,
    /// Rain and car noise mixed into the synthetic audio at this SNR, dB:
    /// one value or LO:HI per log (default: audio-acq.toml's setting).
    #[arg(long, value_parser = parse_snr_range)]
    snr_db: Option<(f64, f64)>,
    /// Seconds the services run before plant-sim is told to start (the
    /// start-up of a live drive: audio and estimates flow, the car waits).
    #[arg(long, default_value_t = 0.5)]
    hold_s: f64,
    /// Logs generated in parallel (threads), at least 1.
    #[arg(long, default_value_t = 1, value_parser = super::at_least_one())]
    jobs: usize,
}

fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let num = |x: &str| {
        x.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{x:?} is not a finite number"))
    };
    let (a, b) = match s.split_once(':') {
        Some((a, b)) => (num(a)?, num(b)?),
        None => {
            let v = num(s)?;
            (v, v)
        }
    };
    if a > b {
        return Err(format!("{s}: LO must not exceed HI"));
    }
    Ok((a, b))
}

// The largest `--torque`, N m: `--random torque=`'s bound (the vehicle's
// own `torque_max` limits it further, checked with each log's scenario).
// Without a bound a range such as `0:1.79e308` drew infinite demands
// (`got inf`).
use grip_sim::random::TORQUE_MAX_NM;

/// `--torque`: [`parse_range`]'s range, with the text as the user typed it
/// for the errors that name it.
#[derive(Debug, Clone)]
struct TorqueArg {
    lo: f64,
    hi: f64,
    given: String,
}

fn parse_torque(s: &str) -> Result<TorqueArg, String> {
    let (lo, hi) = parse_range(s)?;
    Ok(TorqueArg {
        lo,
        hi,
        given: s.to_owned(),
    })
}

/// The logs `specs` would write that are already there, refused without
/// `force` (as `grip train`, `grip dataset synth` and `grip inspect
/// --csv/--plot` refuse to overwrite), naming them.
fn refuse_existing(out: &Path, specs: &[LogSpec], force: bool) -> anyhow::Result<()> {
    let there: Vec<String> = specs
        .iter()
        .filter(|s| s.file.exists())
        .filter_map(|s| s.file.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    if force || there.is_empty() {
        return Ok(());
    }
    let shown = there.iter().take(3).cloned().collect::<Vec<_>>().join(", ");
    bail!(
        "--out {}: {} of the {} logs it would write exist{} ({shown}{}); --force replaces them, or choose another --out",
        out.display(),
        there.len(),
        specs.len(),
        if there.len() == 1 { "s" } else { "" },
        if there.len() > 3 { ", ..." } else { "" }
    )
}

/// `--snr-db`: [`parse_range`] within the SNRs audio-acq accepts
/// ([`super::snr::SNR_LIMITS_DB`], as `grip sim --snr-db`), checked before
/// any log is started.
fn parse_snr_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = parse_range(s)?;
    let l = super::snr::SNR_LIMITS_DB;
    if !(l.contains(&a) && l.contains(&b)) {
        return Err(format!(
            "{s}: outside {}..={} dB (the SNRs audio-acq accepts)",
            l.start(),
            l.end()
        ));
    }
    Ok((a, b))
}

/// What one log is asked to be.
#[derive(Debug, Clone)]
pub struct LogSpec {
    /// Output file.
    pub file: PathBuf,
    /// Seed.
    pub seed: u64,
    /// `random`, a scenario name or a TOML file.
    pub scenario: String,
    /// tcs-loop's controller.
    pub controller: String,
    /// ARTE in the controller.
    pub arte: bool,
    /// Start speed override, km/h.
    pub v0_kmh: Option<f64>,
    /// Constant demand override, N m.
    pub torque: Option<f64>,
    /// The recipe of `--scenario random` (`--random`; the default's
    /// otherwise).
    pub random: RandomSpec,
    /// Audio noise SNR, dB (None: the configuration's).
    pub snr_db: Option<f64>,
    /// Vehicle file.
    pub vehicle: Option<PathBuf>,
    /// Hold before the start, s.
    pub hold_s: f64,
}

/// What one generated log holds.
#[derive(Debug, Clone, Copy, Default)]
pub struct Generated {
    /// Cycle records.
    pub cycles: u64,
    /// Audio blocks.
    pub blocks: u64,
    /// Road estimates.
    pub estimates: u64,
    /// Scripted time covered, s.
    pub span_s: f64,
    /// Blocks arte did not classify (refused for their rate, silent,
    /// clipped, at or after a capture overrun, stale): its counters, as
    /// `grip replay` reports them.
    pub blocks_refused: crate::replay::BlockCounts,
}

const SCENARIO_DRAWS: u64 = 11;

fn controller_name(c: Controller) -> &'static str {
    match c {
        Controller::Mfc => "mfc",
        Controller::Src => "src",
        Controller::Mtte => "mtte",
    }
}

/// The per-log specs of `args`; log i has seed `--seed0` + i, refused when
/// that overflows u64.
fn specs(args: &Args, random: &RandomSpec) -> anyhow::Result<Vec<LogSpec>> {
    let nc = args.controllers.len().max(1);
    let na = args.arte.len().max(1);
    (0..args.count)
        .map(|i| {
            let seed = args.seed0.checked_add(i as u64).with_context(|| {
                format!(
                    "--seed0 {} with --count {}: log {i}'s seed (--seed0 + {i}) overflows u64; the largest --seed0 for {} logs is {}",
                    args.seed0,
                    args.count,
                    args.count,
                    u64::MAX - (args.count as u64 - 1)
                )
            })?;
            let mut rng =
                rand_chacha::ChaCha8Rng::seed_from_u64(grip_sim::sub_seed(seed, SCENARIO_DRAWS));
            let mut draw = |r: Option<(f64, f64)>| {
                r.map(|(a, b)| {
                    if b > a {
                        // centi-units, like the shipped scenarios
                        (rng.random_range(a..=b) * 100.0).round() / 100.0
                    } else {
                        a
                    }
                })
            };
            let v0_kmh = draw(args.v0_kmh);
            let torque = draw(args.torque.as_ref().map(|t| (t.lo, t.hi)));
            let snr_db = draw(args.snr_db);
            Ok(LogSpec {
                file: args.out.join(format!("gen-{i:05}-s{seed}.mcap")),
                seed,
                scenario: args.scenario.clone(),
                controller: controller_name(args.controllers[i % nc]).to_owned(),
                arte: args.arte[(i / nc) % na] == OnOff::On,
                v0_kmh,
                torque,
                random: random.clone(),
                snr_db,
                vehicle: args.vehicle.clone(),
                hold_s: args.hold_s,
            })
        })
        .collect()
}

pub fn run(ctx: &Ctx, args: Args) -> anyhow::Result<()> {
    // each log is about 2.4 MB: a million is 2.4 TB (10^11 asked for
    // the specs of all before the first was written)
    if !(1..=1_000_000).contains(&args.count) {
        bail!("--count {}: must be 1 to 1000000", args.count);
    }
    if !(args.hold_s.is_finite() && (0.0..=60.0).contains(&args.hold_s)) {
        bail!("--hold-s must be within 0..=60 s (got {})", args.hold_s);
    }
    // the ranges a scenario allows (0-360 km/h, a torque >= 0), in the
    // flag's own unit, before any road sequence is drawn
    let v0_max = grip_physics::scenario::V0_MAX_KMH;
    if let Some((lo, hi)) = args.v0_kmh
        && !(lo >= 0.0 && hi <= v0_max)
    {
        let given = if lo == hi {
            format!("{lo}")
        } else {
            format!("{lo}:{hi}")
        };
        bail!("--v0-kmh {given}: a start speed must lie within 0..={v0_max} km/h");
    }
    if let Some(t) = &args.torque {
        if t.lo < 0.0 {
            bail!("--torque {}: a driver demand must be >= 0 N m", t.given);
        }
        if t.hi > TORQUE_MAX_NM {
            bail!(
                "--torque {}: a driver demand must lie within 0..={TORQUE_MAX_NM} N m (the demand on one driven wheel; the vehicle's torque_max limits it further)",
                t.given
            );
        }
    }
    let random = super::sim::random_spec(args.random.as_deref(), &args.scenario)?;
    let specs = specs(&args, &random)?;
    let config = std::path::absolute(&ctx.config_dir)
        .with_context(|| format!("resolving {}", ctx.config_dir.display()))?;
    require_one_rate(&config)?;
    // every log's scenario as plant-sim will refuse it, naming the
    // caller's files, before any output
    check_scenarios(&ctx.config_dir, &specs)?;
    refuse_existing(&args.out, &specs, args.force)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let t0 = Instant::now();
    let pb = crate::drive::many::bar(specs.len(), "logs generated");
    let next = AtomicUsize::new(0);
    let results = std::sync::Mutex::new(vec![None; specs.len()]);
    let failed = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|sc| {
        for _ in 0..args.jobs.clamp(1, specs.len()) {
            sc.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(s) = specs.get(i) else { break };
                    match generate(&config, s) {
                        Ok(g) => {
                            if let Ok(mut r) = results.lock() {
                                r[i] = Some(g);
                            }
                        }
                        Err(e) => {
                            pb.suspend(|| eprintln!("{}: {e:#}", s.file.display()));
                            if let Ok(mut f) = failed.lock() {
                                f.push(s.file.display().to_string());
                            }
                        }
                    }
                    pb.inc(1);
                }
            });
        }
    });
    pb.finish_and_clear();
    let wall = t0.elapsed().as_secs_f64();
    let results = results.into_inner().unwrap_or_default();
    let done: Vec<Generated> = results.into_iter().flatten().collect();
    let span: f64 = done.iter().map(|g| g.span_s).fold(0.0, |a, b| a + b);
    let cycles: u64 = done.iter().map(|g| g.cycles).sum();
    // the figures of the logs there are; none when every log failed
    if !done.is_empty() {
        println!(
            "generated {} logs in {} ({} cycles, {:.1} s of scripted time) in {wall:.1} s wall with {} job(s): {:.2} logs/s, {:.0}x real time",
            done.len(),
            args.out.display(),
            cycles,
            span,
            args.jobs.clamp(1, specs.len()),
            done.len() as f64 / wall.max(1e-9),
            span / wall.max(1e-9)
        );
    }
    if let Some(l) = not_classified(&done) {
        println!("{l}");
    }
    let failed = failed.into_inner().unwrap_or_default();
    if !failed.is_empty() {
        bail!(
            "{} of {} logs failed: {}",
            failed.len(),
            specs.len(),
            failed.join(", ")
        );
    }
    Ok(())
}

/// The one rule of `crate::drive::rates` before any log is generated: arte's
/// model (the `model` of `config`'s `arte-svc.toml`; every log runs it)
/// must be at audio-acq's `[audio] sample_rate` (every log's audio: only
/// `[synth]` changes per log), else arte would refuse every block and the
/// logs would carry no road estimate. The error names both files, both
/// rates and the ways out.
fn require_one_rate(config: &Path) -> anyhow::Result<()> {
    use crate::drive::rates;
    let arte_file = config.join("arte-svc.toml");
    let model = rates::arte_model(config, None)
        .with_context(|| format!("arte's model (the `model` of {})", arte_file.display()))?;
    let (audio_file, audio_hz) = rates::audio_rate(config)?;
    rates::require_one_rate(
        &audio_file,
        audio_hz,
        &format!(
            "arte's model {} (the `model` of {})",
            model.path.display(),
            arte_file.display()
        ),
        model.hz,
        "the logs would carry no road estimate",
        &format!(
            "set `model` in {} to a model trained at {audio_hz} Hz (`grip train --data DIR` on recordings at {audio_hz} Hz)",
            arte_file.display()
        ),
    )
}

/// The blocks arte did not classify in the logs `done`, all counts summed
/// as one (`crate::replay::BlockCounts::add`), as one line; `None` when
/// there were none.
fn not_classified(done: &[Generated]) -> Option<String> {
    let mut refused = crate::replay::BlockCounts::default();
    let mut blocks = 0u64;
    for g in done {
        refused.add(&g.blocks_refused);
        blocks += g.blocks;
    }
    refused.line(blocks as usize, None)
}

/// Copies what the services and the recorder read from `from` into `to`:
/// the top-level files and the roads, scenarios, vehicles and models
/// directories (the recorder attaches exactly these).
fn copy_config(from: &Path, to: &Path) -> anyhow::Result<()> {
    fn copy_files(from: &Path, to: &Path, recurse: bool) -> anyhow::Result<()> {
        std::fs::create_dir_all(to).with_context(|| format!("creating {}", to.display()))?;
        for e in std::fs::read_dir(from).with_context(|| format!("reading {}", from.display()))? {
            let p = e?.path();
            let Some(name) = p.file_name() else { continue };
            if p.is_file() {
                std::fs::copy(&p, to.join(name))
                    .with_context(|| format!("copying {}", p.display()))?;
            } else if recurse && p.is_dir() {
                copy_files(&p, &to.join(name), true)?;
            }
        }
        Ok(())
    }
    copy_files(from, to, false)?;
    for sub in ["roads", "scenarios", "vehicles", "models"] {
        let d = from.join(sub);
        if d.is_dir() {
            copy_files(&d, &to.join(sub), true)?;
        }
    }
    Ok(())
}

fn read_table(path: &Path) -> anyhow::Result<toml::Table> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    text.parse::<toml::Table>()
        .with_context(|| format!("{}: not valid TOML", path.display()))
}

fn write_table(path: &Path, head: &str, t: &toml::Table) -> anyhow::Result<()> {
    let body = toml::to_string(t).with_context(|| format!("serialising {}", path.display()))?;
    std::fs::write(path, format!("{head}{body}"))
        .with_context(|| format!("writing {}", path.display()))
}

/// The scenario one log runs, as the TOML plant-sim reads: its name, the
/// file's head comment, the table, and what to name in an error about it
/// (the user's file, with the per-log flags that changed it, or `--scenario
/// random (seed N)`). A scenario name is looked up in `user`, the caller's
/// configuration directory, a path as given.
struct LogScenario {
    name: String,
    head: String,
    table: toml::Table,
    named: PathBuf,
}

fn log_scenario(
    user: &grip_config::ConfigDir,
    s: &LogSpec,
    roads: &grip_physics::RoadCatalogue,
    vehicle: &grip_physics::VehicleParams,
) -> anyhow::Result<LogScenario> {
    if s.scenario == super::sim::RANDOM {
        let spec = RandomSpec {
            v0_kmh: s.v0_kmh.unwrap_or(s.random.v0_kmh),
            torque: s.torque.unwrap_or(s.random.torque),
            ..s.random.clone()
        };
        // A start speed of this log's own reaches as far as `--random`'s
        // would (`RandomSpec::parse` raised the cover for its own speed).
        let spec = if s.v0_kmh.is_some() {
            spec.covering_travel()
        } else {
            spec
        };
        // ... and as far as this car can cover in the run (as `grip sim`)
        let spec = spec.sized_for(vehicle, roads);
        let sc = spec
            .scenario(s.seed, roads)
            .map_err(|e| anyhow::anyhow!("--scenario random (seed {}): {e}", s.seed))?;
        let name = format!("random-s{}", s.seed);
        let mut t = toml::Table::new();
        t.insert("name".into(), name.clone().into());
        t.insert("description".into(), sc.description.clone().into());
        t.insert("v0_kmh".into(), spec.v0_kmh.into());
        t.insert("segments_by".into(), "distance".into());
        t.insert("duration".into(), sc.duration.into());
        let mut demand = toml::Table::new();
        demand.insert("kind".into(), "constant".into());
        demand.insert("torque".into(), spec.torque.into());
        t.insert("demand".into(), demand.into());
        let segs: Vec<toml::Value> = sc
            .segments
            .iter()
            .map(|g| {
                let mut m = toml::Table::new();
                m.insert("road".into(), g.road_name.clone().into());
                m.insert("length".into(), g.span.into());
                m.into()
            })
            .collect();
        t.insert("segment".into(), segs.into());
        return Ok(LogScenario {
            name,
            head: "# written by grip generate (grip_sim::random::RandomSpec, this seed)\n".into(),
            table: t,
            named: PathBuf::from(format!("--scenario random (seed {})", s.seed)),
        });
    }
    // a name under the caller's configuration directory, or a file
    let path = user.scenario_path(&s.scenario);
    let text = grip_config::read_file(&path)?;
    let mut t = text
        .parse::<toml::Table>()
        .with_context(|| format!("{}: not valid TOML", path.display()))?;
    let stem = path.file_stem().map_or_else(
        || "scenario".to_owned(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut flags = String::new();
    if let Some(v) = s.v0_kmh {
        t.insert("v0_kmh".into(), v.into());
        flags.push_str(&format!(" --v0-kmh {v}"));
    }
    if let Some(tq) = s.torque {
        let kind = t
            .get("demand")
            .and_then(|d| d.get("kind"))
            .and_then(toml::Value::as_str)
            .unwrap_or("?")
            .to_owned();
        if kind != "constant" {
            bail!(
                "{}: field demand.kind is {kind:?}: --torque sets a constant demand's torque only",
                path.display()
            );
        }
        if let Some(d) = t.get_mut("demand").and_then(toml::Value::as_table_mut) {
            d.insert("torque".into(), tq.into());
        }
        flags.push_str(&format!(" --torque {tq}"));
    }
    let name = if flags.is_empty() {
        stem
    } else {
        format!("{stem}-s{}", s.seed)
    };
    t.insert("name".into(), name.clone().into());
    let named = if flags.is_empty() {
        path.clone()
    } else {
        PathBuf::from(format!("{} with{flags}", path.display()))
    };
    Ok(LogScenario {
        name,
        head: format!(
            "# written by grip generate from {} (start speed / demand drawn per log)\n",
            path.file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        ),
        table: t,
        named,
    })
}

/// Before any log: the configuration plant-sim reads for every log, read
/// from the caller's directory `user` (so an error names the user's files,
/// not a log's temporary copy), and each log's scenario checked as
/// plant-sim's start-up checks it (`ConfigDir::scenario_for`: the roads,
/// the demand within the vehicle's motor limit, 1 ..= 1e9 cycles of
/// plant-sim's loop), named by its file and the flags that changed it.
fn check_scenarios(user: &Path, specs: &[LogSpec]) -> anyhow::Result<()> {
    let cdir = grip_config::ConfigDir::new(user);
    let roads = cdir.roads()?;
    let own = ConfigArgs::in_dir(user).own_file::<grip_plant_sim::PlantSimConfig>();
    let rate_hz = grip_plant_sim::PlantSimConfig::load(&own)?.rate_hz;
    let mut vehicles: Vec<(PathBuf, grip_physics::VehicleParams)> = Vec::new();
    for s in specs {
        let vehicle_file = s.vehicle.clone().unwrap_or_else(|| cdir.vehicle_path());
        let vehicle = match vehicles.iter().find(|(p, _)| *p == vehicle_file) {
            Some((_, v)) => *v,
            None => {
                let (v, _) = grip_config::load_vehicle(&vehicle_file)?;
                vehicles.push((vehicle_file.clone(), v));
                v
            }
        };
        let ls = log_scenario(&cdir, s, &roads, &vehicle)?;
        let text = toml::to_string(&ls.table)
            .with_context(|| format!("serialising {}", ls.named.display()))?;
        let sc = grip_config::parse_scenario(&ls.named, &text, &roads)?;
        grip_config::check_scenario(
            &ls.named,
            &sc,
            grip_config::RunsOn {
                vehicle: &vehicle,
                vehicle_file: &vehicle_file,
                dt: 1.0 / rate_hz,
            },
        )?;
    }
    Ok(())
}

/// Writes the log's scenario into `dir/scenarios` (a name looked up in
/// `user`, the caller's configuration directory); returns its name.
fn write_scenario(dir: &Path, user: &Path, s: &LogSpec) -> anyhow::Result<String> {
    let cdir = grip_config::ConfigDir::new(dir);
    let roads = cdir.roads()?;
    let (vehicle, _) = match &s.vehicle {
        Some(v) => grip_config::load_vehicle(v)?,
        None => cdir.vehicle()?,
    };
    let ls = log_scenario(&grip_config::ConfigDir::new(user), s, &roads, &vehicle)?;
    write_table(
        &cdir.scenarios_path().join(format!("{}.toml", ls.name)),
        &ls.head,
        &ls.table,
    )?;
    Ok(ls.name)
}

/// Sets `[synth] seed` and, with `snr_db`, `[synth] noise` in `audio-acq.toml`.
fn write_audio_config(dir: &Path, s: &LogSpec) -> anyhow::Result<()> {
    let p = dir.join("audio-acq.toml");
    let mut t = read_table(&p)?;
    let synth = t
        .entry("synth")
        .or_insert_with(|| toml::Table::new().into())
        .as_table_mut()
        .with_context(|| format!("{}: field synth: not a table", p.display()))?;
    synth.insert(
        "seed".into(),
        i64::try_from(s.seed)
            .context("the seed must fit in a TOML integer")?
            .into(),
    );
    if let Some(snr) = s.snr_db {
        let mut n = toml::Table::new();
        n.insert("rain".into(), true.into());
        n.insert("car".into(), true.into());
        n.insert("snr_db".into(), snr.into());
        synth.insert("noise".into(), n.into());
    }
    write_table(
        &p,
        "# written by grip generate: [synth] seed and noise set per log\n",
        &t,
    )
}

/// The newest ground truth, for the synthetic audio source.
#[derive(Clone, Default)]
struct SharedTruth(Rc<Cell<Option<GroundTruth>>>);

impl TruthInput for SharedTruth {
    fn poll_latest(&mut self) -> Result<Option<GroundTruth>, TruthReadError> {
        Ok(self.0.take())
    }
}

/// Collects plant-sim's ground truth and hands the newest to the audio source.
struct Truths {
    new: Vec<GroundTruth>,
    latest: SharedTruth,
}

impl grip_plant_sim::TruthSink for Truths {
    fn truth(&mut self, g: &GroundTruth) {
        self.new.push(*g);
        self.latest.0.set(Some(*g));
    }
}

/// Collects audio-acq's blocks.
#[derive(Default)]
struct Blocks(Vec<AudioBlock>);

impl BlockSink for Blocks {
    fn send(&mut self, b: &AudioBlock) -> Result<(), grip_io::ipc::IpcError> {
        self.0.push(*b);
        Ok(())
    }
}

/// Collects arte's estimates.
#[derive(Default)]
struct Estimates(Vec<RoadEstimate>);

impl EstimateSink for Estimates {
    fn send(&mut self, e: &RoadEstimate) -> Result<(), grip_io::ipc::IpcError> {
        self.0.push(*e);
        Ok(())
    }
}

/// Collects tcs-loop's records.
#[derive(Default)]
struct Records {
    cycles: Vec<CycleRecord>,
    can: Vec<CanFrame>,
}

impl RecordSink for Records {
    fn cycle(&mut self, r: &CycleRecord) {
        self.cycles.push(*r);
    }
    fn can(&mut self, f: &CanFrame) {
        self.can.push(*f);
    }
}

/// The newest estimate for tcs-loop.
#[derive(Default)]
struct Road(Option<RoadEstimate>);

impl RoadSource for Road {
    fn poll_next(&mut self) -> Option<RoadEstimate> {
        self.0.take()
    }
}

/// Writes messages and counts them as the recorder's receive side does.
struct Rec {
    w: McapWriter,
    recv: grip_recorder::RecvStats,
    written: BTreeMap<&'static str, u64>,
}

impl Rec {
    fn put<T: grip_io::mcaplog::McapRecord>(
        &mut self,
        topic: &'static str,
        m: &T,
        seq: Option<u64>,
    ) -> anyhow::Result<()> {
        let st = self.recv.topic(topic);
        st.received += 1;
        if let Some(s) = seq {
            st.seq.push(s);
        }
        self.w.write(topic, m)?;
        *self.written.entry(topic).or_default() += 1;
        Ok(())
    }
}

/// Generates one log (see the module docs). An error that names a file of
/// the log's temporary copy of the configuration names the caller's file
/// (`config`) instead.
pub fn generate(config: &Path, s: &LogSpec) -> anyhow::Result<Generated> {
    let tmp = tempfile::tempdir().context("creating a temporary configuration directory")?;
    generate_in(config, tmp.path(), s).map_err(|e| {
        anyhow::anyhow!(
            "{}",
            format!("{e:#}").replace(
                &tmp.path().display().to_string(),
                &config.display().to_string()
            )
        )
    })
}

fn generate_in(config: &Path, dir: &Path, s: &LogSpec) -> anyhow::Result<Generated> {
    copy_config(config, dir)?;
    let scenario = write_scenario(dir, config, s)?;
    write_audio_config(dir, s)?;
    let cargs = ConfigArgs::in_dir(dir);
    let vehicle = match &s.vehicle {
        Some(v) => {
            Some(std::path::absolute(v).with_context(|| format!("resolving {}", v.display()))?)
        }
        None => None,
    };

    // the services' own start-up
    let (_, mut plant, _) = grip_plant_sim::run::load(&grip_plant_sim::Options {
        config: cargs.clone(),
        scenario: Some(scenario.clone()),
        seed: Some(s.seed),
        exit_at_end: true,
        start_on: Some(grip_plant_sim::StartOn::Signal),
        vehicle: vehicle.clone(),
    })
    .context("plant-sim's start-up")?;
    let duration_s = plant.scenario().duration;
    let v0_kmh = plant.scenario().v0 * 3.6;
    let loaded = grip_tcs_loop::load(&grip_tcs_loop::Options {
        config: cargs.clone(),
        controller: Some(
            s.controller
                .parse()
                .map_err(|e| anyhow::anyhow!("controller {}: {e}", s.controller))?,
        ),
        arte: Some(s.arte),
        run_for_s: None,
        vehicle: vehicle.clone(),
    })
    .context("tcs-loop's configuration")?;
    let mut lp = grip_tcs_loop::build(&loaded).context("tcs-loop's start-up")?;
    let period_ns = (1e9 / loaded.controllers.loop_.rate_hz).round() as u64;
    let t0: u64 = 1_000_000_000;
    let clock = ManualClock::new(t0);
    let arte_clock = ManualClock::new(t0);
    let mut arte = grip_arte_svc::prepare_with_clock(
        &grip_arte_svc::Options {
            config: cargs.clone(),
            model: None,
            run_for: None,
        },
        arte_clock.clone(),
    )
    .context("arte's start-up")?;
    // a generated drive is a drive: arte's start-up refuses what the
    // service refuses (a calibration fitted for other stream settings)
    if let Some(e) = arte.calibration_mismatch.take() {
        return Err(anyhow::Error::new(e).context("arte's start-up"));
    }
    let (_, acfg) = grip_audio_acq::run::effective_config(&grip_audio_acq::Options {
        config: cargs.clone(),
        ..grip_audio_acq::Options::default()
    })
    .context("audio-acq's configuration")?;
    if acfg.audio.source != grip_audio_acq::SourceKind::Synth {
        bail!(
            "{}: field audio.source is {:?}: grip generate needs the synthetic source",
            dir.join("audio-acq.toml").display(),
            acfg.audio.source.name()
        );
    }
    // at arte's model's rate: `run` checked it before any log
    // (`require_one_rate`)
    let rate = acfg.audio.sample_rate;
    let block = acfg
        .audio
        .block_samples
        .clamp(1, grip_msgs::AUDIO_MAX_SAMPLES);
    let truth = SharedTruth::default();
    let audio_clock = ManualClock::new(t0);
    let src = SynthSource::new(
        &acfg.synth,
        rate,
        block,
        truth.clone(),
        audio_clock,
        grip_audio_acq::run::PACER_SLACK_NS,
    )?;
    let mut acq = AcqLoop::new(src, block, 0, Arc::new(AcqStatus::default()));

    // the recorder's file, grip.run and attachments
    let rcfg =
        grip_recorder::RecorderConfig::load(&cargs.own_file::<grip_recorder::RecorderConfig>())?;
    let mut w = McapWriter::create(&s.file, rcfg.writer_options())
        .with_context(|| format!("creating {}", s.file.display()))?;
    let mut meta: Vec<(String, String)> = vec![
        ("scenario".into(), scenario.clone()),
        ("scenario_duration_s".into(), format!("{duration_s}")),
        ("controller".into(), s.controller.clone()),
        ("arte".into(), (if s.arte { "on" } else { "off" }).into()),
        ("seed".into(), s.seed.to_string()),
        ("instance".into(), "generated".into()),
        ("source".into(), "generated".into()),
        ("clock".into(), "scripted".into()),
        (
            "generator".into(),
            "grip generate: plant-sim, tcs-loop, audio-acq (synth) and arte in lock step at the loop rate on a scripted clock; loop timing fields are not measured".into(),
        ),
        ("v0_kmh".into(), format!("{v0_kmh}")),
        ("hold_s".into(), format!("{}", s.hold_s)),
        (
            "snr_db".into(),
            s.snr_db
                .map_or_else(|| "config".to_owned(), |x| format!("{x}")),
        ),
        (
            "config_dir".into(),
            format!("{} (a per-log copy)", config.display()),
        ),
    ];
    if let grip_physics::Demand::Constant { torque } = plant.scenario().demand {
        meta.push(("torque_nm".into(), format!("{torque}")));
    }
    let mut extra = Vec::new();
    if let Some(v) = &vehicle {
        meta.push(("vehicle".into(), v.display().to_string()));
        extra.push((grip_drive::plan::VEHICLE_ATTACHMENT.to_owned(), v.clone()));
    }
    grip_recorder::write_run_info(&mut w, dir, rcfg.attach_max_bytes, &meta, &extra)?;
    let mut rec = Rec {
        w,
        recv: grip_recorder::RecvStats::default(),
        written: BTreeMap::new(),
    };
    for t in grip_recorder::RECORDED {
        rec.recv.topic(t);
    }

    // lock step
    let (mut bus_p, bus_t) = MemBus::pair();
    // received frames numbered as the loop numbers what it sends
    let mut bus_t = bus_t.with_bus_id(lp.bus_id());
    let mut truths = Truths {
        new: Vec::new(),
        latest: truth,
    };
    let mut blocks = Blocks::default();
    let mut ests = Estimates::default();
    let mut outs = Records::default();
    let mut road = Road::default();
    let stats = ArteCounters::default();
    let hold = (s.hold_s * 1e9 / period_ns as f64).round() as u64;
    // plant-sim ends the drive; a bound in case it never starts
    let max_cycles = hold + ((duration_s + 30.0) * 1e9 / period_ns as f64) as u64;
    let mut samples: u64 = 0;
    let span = |n: u64| (u128::from(n) * 1_000_000_000 / u128::from(rate.max(1))) as u64;
    let mut g = Generated::default();
    let mut finished = false;
    let mut non_finite = None;
    for k in 0..max_cycles {
        let now = clock.now_ns();
        // audio blocks due by now, each through arte
        while t0 + span(samples + block as u64) <= now {
            blocks.0.clear();
            acq.step(&mut blocks)?;
            samples += block as u64;
            let end = t0 + span(samples);
            arte_clock.set_ns(end);
            for b in &blocks.0 {
                ests.0.clear();
                arte.lp.on_block(b, &mut ests, &stats);
                rec.put(topics::AUDIO, b, Some(b.seq))?;
                g.blocks += 1;
                for e in &ests.0 {
                    rec.put(topics::ROAD, e, Some(e.seq))?;
                    road.0 = Some(*e);
                    g.estimates += 1;
                }
            }
        }
        if k >= hold {
            plant.request_start();
        }
        truths.new.clear();
        let o = plant.cycle(
            &grip_plant_sim::PlantTick::at(now),
            &clock,
            &mut bus_p,
            &mut truths,
        );
        for t in &truths.new {
            rec.put(topics::TRUTH, t, Some(t.seq))?;
        }
        // a plant state that is no number: the log would be no drive
        if let Some(t) = truths
            .new
            .iter()
            .find(|t| !(t.v.is_finite() && t.omega.is_finite() && t.x.is_finite()))
        {
            non_finite = Some((plant.scenario_time(), t.v, t.omega, t.x));
            break;
        }
        if o == grip_plant_sim::Outcome::Finished {
            finished = true;
            break;
        }
        outs.cycles.clear();
        outs.can.clear();
        lp.cycle(
            &CycleTick::at(now),
            &clock,
            &mut bus_t,
            &mut road,
            &mut outs,
        );
        for f in &outs.can {
            rec.recv.can.push(f);
            rec.put(topics::CAN_LOG, f, None)?;
        }
        for c in &outs.cycles {
            arte.lp.on_cycle(c, &stats);
            rec.put(topics::CYCLE, c, Some(c.seq))?;
            g.cycles += 1;
        }
        clock.advance_ns(period_ns);
    }
    if let Some((t, v, omega, x)) = non_finite {
        // not left behind as a log a fleet would read
        drop(rec);
        let _ = std::fs::remove_file(&s.file);
        bail!(
            "the plant state went non-finite {t:.3} s into scenario {scenario} (v = {v} m/s, omega = {omega} rad/s, x = {x} m): no log written"
        );
    }
    if !finished {
        bail!(
            "plant-sim did not end scenario {scenario} within {max_cycles} cycles; log {} is incomplete",
            s.file.display()
        );
    }
    // the stop: tcs-loop's last command (disable), as on SIGTERM
    outs.can.clear();
    lp.shutdown(clock.now_ns(), &mut bus_t, &mut outs);
    for f in &outs.can {
        rec.recv.can.push(f);
        rec.put(topics::CAN_LOG, f, None)?;
    }
    g.span_s = (clock.now_ns() - t0) as f64 * 1e-9;
    g.blocks_refused = crate::replay::BlockCounts::of(&stats);
    let summary = grip_recorder::Summary {
        path: s.file.clone(),
        recv: rec.recv,
        written: rec.written,
        not_written: Default::default(),
        queue_high_water: 0,
        write_errors: 0,
    };
    let mut w = rec.w;
    w.write_metadata("grip.recorder", &summary.metadata())?;
    w.finish()?;
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::replay::BlockCounts;

    /// `--snr-db` outside what audio-acq accepts is refused when the
    /// arguments are read, naming the option's value (it was refused per
    /// log, under the name of the configuration's audio-acq.toml).
    #[test]
    fn an_snr_audio_acq_refuses_is_refused_with_the_arguments() {
        assert_eq!(parse_snr_range("10").unwrap(), (10.0, 10.0));
        assert_eq!(parse_snr_range("0:20").unwrap(), (0.0, 20.0));
        for bad in ["500", "0:81", "-31:0"] {
            let e = parse_snr_range(bad).unwrap_err();
            assert!(
                e.starts_with(bad) && e.contains("outside -30..=80 dB"),
                "{e}"
            );
        }
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            _args: Args,
        }
        let cli =
            <Cli as clap::Parser>::try_parse_from(["generate", "--out", "x", "--snr-db", "500"]);
        let e = cli.err().expect("--snr-db 500 refused").to_string();
        assert!(
            e.contains("--snr-db") && e.contains("outside -30..=80 dB"),
            "{e}"
        );
    }

    /// The logs' refused blocks are summed as `grip replay` counts them:
    /// blocks at or after a capture overrun and stale ones included (they
    /// were left out of the total).
    #[test]
    fn not_classified_counts_every_kind_over_the_logs() {
        let log = |blocks, refused| Generated {
            blocks,
            blocks_refused: refused,
            ..Generated::default()
        };
        assert_eq!(not_classified(&[log(10, BlockCounts::default())]), None);
        let done = [
            log(
                10,
                BlockCounts {
                    silent: 1,
                    xrun: 2,
                    ..BlockCounts::default()
                },
            ),
            log(
                20,
                BlockCounts {
                    clipped: 3,
                    stale: 4,
                    ..BlockCounts::default()
                },
            ),
            log(
                5,
                BlockCounts {
                    xrun: 1,
                    ..BlockCounts::default()
                },
            ),
        ];
        assert_eq!(
            not_classified(&done).as_deref(),
            Some(
                "arte's blocks not classified, of 35: 1 silent, 3 clipped, 3 at or after a capture overrun, 4 stale (older than max_lag_s)"
            )
        );
        // logs at two refused rates: the largest is named, in either order
        let at = |rate| BlockCounts {
            rate_mismatch: 2,
            bad_rate: rate,
            ..BlockCounts::default()
        };
        let a = not_classified(&[log(10, at(48_000)), log(10, at(22_050))]);
        let b = not_classified(&[log(10, at(22_050)), log(10, at(48_000))]);
        assert_eq!(a, b);
        assert!(a.as_deref().unwrap_or("").contains("48000"), "{a:?}");
    }
}
