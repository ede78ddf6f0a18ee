//! The service: configuration, model, road table, ports, real-time set-up,
//! readiness, the loop until stopped.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use grip_arte::stream::{Smoothing, StreamConfig};
use grip_io::clock::{Clock, MonotonicClock};
use grip_io::ipc::{IpcNode, SubscriberMode};
use grip_msgs::{AudioBlock, CycleRecord, RoadEstimate, topics};

use grip_io::service::{ConfigArgs, ServiceConfig};

use crate::{
    ArteCounters, ArteError, ArteLoop, ArteServiceConfig, ModelSource, load_model_from, monitor,
    road_table,
};

/// Command-line choices.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// `--config-dir` and `--config`.
    pub config: ConfigArgs,
    /// Model file override (as given: relative to the working directory).
    pub model: Option<PathBuf>,
    /// Stop by itself after this many seconds (`--run-for` takes 0 to
    /// 3.2e7, [`grip_io::service::args::seconds`]; a longer or infinite
    /// run length never ends the run).
    pub run_for: Option<f64>,
}

/// What a run did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunSummary {
    /// Audio blocks received.
    pub blocks: u64,
    /// Estimates published.
    pub estimates: u64,
    /// Blocks lost (sequence numbers skipped: never taken).
    pub lost_blocks: u64,
    /// Blocks not classified: digital silence or near it (a cut cable, a
    /// muted input).
    pub silent_blocks: u64,
    /// Blocks not classified: clipped.
    pub clipped_blocks: u64,
    /// Blocks not classified: a new capture overrun, or within the hold
    /// after one.
    pub xrun_blocks: u64,
    /// Blocks refused for a sample rate other than the model's.
    pub rate_mismatch: u64,
    /// Blocks given to the estimator with a fresh vehicle speed.
    pub blocks_with_speed: u64,
    /// Blocks given to the estimator without one (none, or stale).
    pub blocks_without_speed: u64,
    /// Cycle records received from tcs-loop.
    pub cycle_records: u64,
    /// The speed the last block was given (m/s; `None`: none or stale).
    pub last_speed_mps: Option<f64>,
}

impl RunSummary {
    /// The totals of `stats` (what [`run`] returns when it stops).
    pub fn from_counters(stats: &ArteCounters) -> Self {
        let n = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
        Self {
            blocks: n(&stats.blocks),
            estimates: n(&stats.estimates),
            lost_blocks: n(&stats.lost_blocks),
            silent_blocks: n(&stats.silent_blocks),
            clipped_blocks: n(&stats.clipped_blocks),
            xrun_blocks: n(&stats.xrun_blocks),
            rate_mismatch: n(&stats.rate_mismatch),
            blocks_with_speed: n(&stats.blocks_with_speed),
            blocks_without_speed: n(&stats.blocks_without_speed),
            cycle_records: n(&stats.cycle_records),
            last_speed_mps: stats.speed_in_use(),
        }
    }
}

/// The `arte stopped` line: `summary` (from `stats`), the estimates per
/// class (`classes`, model order) and the other totals of `stats`. Names a
/// microphone that gave only unusable audio (`silent_blocks`,
/// `clipped_blocks`, `xrun_blocks`) or a rate the model refuses
/// (`rate_mismatch`), so that a run without a road estimate says why.
fn log_stopped(summary: &RunSummary, classes: &[String], stats: &ArteCounters) {
    let per_class: Vec<String> = classes
        .iter()
        .zip(&stats.per_class)
        .map(|(c, n)| format!("{c} {}", n.load(Ordering::Relaxed)))
        .collect();
    tracing::info!(
        per_class = %per_class.join(", "),
        blocks = summary.blocks,
        estimates = summary.estimates,
        lost_blocks = summary.lost_blocks,
        silent_blocks = summary.silent_blocks,
        clipped_blocks = summary.clipped_blocks,
        xrun_blocks = summary.xrun_blocks,
        rate_mismatch = summary.rate_mismatch,
        stale_blocks = stats.stale_blocks.load(Ordering::Relaxed),
        max_stale_lag_ms = stats.max_stale_lag_ns.load(Ordering::Relaxed) as f64 * 1e-6,
        stale_estimates = stats.stale_estimates.load(Ordering::Relaxed),
        resets = stats.resets.load(Ordering::Relaxed),
        blocks_with_speed = summary.blocks_with_speed,
        blocks_without_speed = summary.blocks_without_speed,
        cycle_records = summary.cycle_records,
        bad_speeds = stats.bad_speeds.load(Ordering::Relaxed),
        "arte stopped"
    );
}

/// Everything checked at start-up, before any port opens; the loop runs
/// on clock `K` (the real one in the service, a scripted one in `grip
/// replay`).
#[derive(Debug)]
pub struct Prepared<K: Clock = MonotonicClock> {
    /// The config file used.
    pub config_file: PathBuf,
    /// Its contents.
    pub cfg: ArteServiceConfig,
    /// The model file used.
    pub model_path: PathBuf,
    /// The loop, ready to run.
    pub lp: ArteLoop<grip_arte::model::Predictor, K>,
    /// Model class names.
    pub classes: Vec<String>,
    /// What every estimate of each class carries (class order): the one
    /// road-knowledge rule applied to the configuration directory.
    pub table: Vec<crate::ClassKnowledge>,
    /// `Some` when the model's confidence calibration was fitted for other
    /// `[stream]` settings than the configuration's
    /// ([`ArteError::CalibrationMismatch`]): [`prepare`], the service's
    /// start-up, refuses with it; [`prepare_with_clock`] keeps it here for
    /// its caller: `grip replay` (a what-if) says it as a warning and runs,
    /// `grip generate` (a drive) refuses it as the service does.
    pub calibration_mismatch: Option<ArteError>,
    /// The vehicle speeds the model was trained at (`meta.speeds`, or its
    /// training note; logged at start-up: estimates at other speeds are
    /// extrapolation, which the drive summary reports).
    pub training_speeds: grip_arte::speeds::TrainingSpeeds,
}

fn resolve(dir: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_owned()
    } else {
        dir.join(p)
    }
}

/// Loads config, model and road catalogue and builds the loop; every
/// start-up error names its file. Refuses a model whose confidence
/// calibration was fitted for other `[stream]` settings than the
/// configuration's ([`ArteError::CalibrationMismatch`]).
pub fn prepare(opts: &Options) -> Result<Prepared, ArteError> {
    let mut p = load(opts, MonotonicClock)?;
    match p.calibration_mismatch.take() {
        Some(e) => Err(e),
        None => Ok(p),
    }
}

fn smoothing_toml(s: Smoothing) -> String {
    match s {
        Smoothing::None => "\"none\"".into(),
        Smoothing::Hmm { stay, floor } => {
            format!("{{ hmm = {{ stay = {stay}, floor = {floor} }} }}")
        }
    }
}

/// The refusal when `model`'s confidence calibration was fitted for other
/// stream settings than `stream` (`[stream]` of `config_file`); `None` when
/// they agree or the model has no calibration.
fn calibration_mismatch(
    config_file: &Path,
    stream: &StreamConfig,
    model_path: &Path,
    model: &grip_arte::model::Model,
) -> Option<ArteError> {
    let fitted = &model.calibration()?.stream;
    if fitted == stream {
        return None;
    }
    let mut fields = Vec::new();
    if fitted.hop_s != stream.hop_s {
        fields.push(format!("`stream.hop_s` = {}", stream.hop_s));
    }
    if fitted.smoothing != stream.smoothing {
        fields.push(format!(
            "`stream.smoothing` = {}",
            smoothing_toml(stream.smoothing)
        ));
    }
    let calib_args = match stream.smoothing {
        Smoothing::None => format!("--calib-hop {} --calib-stay 0", stream.hop_s),
        Smoothing::Hmm { stay, floor } => format!(
            "--calib-hop {} --calib-stay {stay} --calib-floor {floor}",
            stream.hop_s
        ),
    };
    let model_file = model_path.display();
    Some(ArteError::CalibrationMismatch {
        config_file: config_file.to_owned(),
        model_path: model_path.to_owned(),
        reason: format!(
            "field{} {}: the confidence calibration of model file {model_file} was fitted at \
             [stream] hop_s = {}, smoothing = {}, so the confidence arte would publish \
             is not calibrated for these settings. Recalibrate the model for them \
             (`grip calibrate --model {model_file} --data CHANGE-RECORDINGS --out FILE \
             {calib_args}`) or set [stream] back to the settings it was fitted at",
            if fields.len() > 1 { "s" } else { "" },
            fields.join(", "),
            fitted.hop_s,
            smoothing_toml(fitted.smoothing),
        ),
    })
}

/// [`prepare`] with the loop on `clock`, for what replays the service's
/// work offline (`grip replay`, `grip generate`): a calibration fitted for
/// other `[stream]` settings is not refused here (a what-if may change
/// them) but kept in [`Prepared::calibration_mismatch`] for the caller to
/// refuse or say, in the words of its own files (a replay's configuration
/// is a temporary copy of the log's).
pub fn prepare_with_clock<K: Clock>(opts: &Options, clock: K) -> Result<Prepared<K>, ArteError> {
    load(opts, clock)
}

/// Config, model, road table and loop, with any calibration mismatch.
fn load<K: Clock>(opts: &Options, clock: K) -> Result<Prepared<K>, ArteError> {
    let config_file = opts.config.own_file::<ArteServiceConfig>();
    let cfg = ArteServiceConfig::load(&config_file)?;
    // a model that cannot be read or is not one names what named it
    let (model_path, from) = match &opts.model {
        Some(p) => (p.clone(), ModelSource::Option("--model")),
        None => (
            resolve(&opts.config.config_dir, &cfg.model),
            ModelSource::Config {
                file: config_file.clone(),
                field: "model",
            },
        ),
    };
    let model = load_model_from(&model_path, from)?;
    let roads_file = opts.config.config_dir.join("roads.toml");
    let roads = grip_config::load_roads(&roads_file)?;
    let rule = grip_tcs::RoadTable::new(&roads, &cfg.knowledge)
        .map_err(|e| grip_config::ConfigError::invalid(&config_file, "knowledge", e))?;
    let table = road_table(model.classes(), &roads, &rule, &model_path, &roads_file)?;
    let lp = ArteLoop::from_model(
        &model,
        &cfg.stream,
        table.clone(),
        cfg.input.resync_gap_s,
        clock,
    )?
    .with_speed_timeout(cfg.input.speed_timeout_s)
    .with_max_lag(cfg.input.max_lag_s);
    let calibration_mismatch = calibration_mismatch(&config_file, &cfg.stream, &model_path, &model);
    Ok(Prepared {
        calibration_mismatch,
        training_speeds: model.training_speeds(),
        config_file,
        model_path,
        classes: model.classes().to_vec(),
        cfg,
        lp,
        table,
    })
}

/// Runs the service until `stop` is set or `run_for` passes.
pub fn run(opts: &Options, stop: Arc<AtomicBool>) -> Result<RunSummary, ArteError> {
    let Prepared {
        config_file,
        cfg,
        model_path,
        mut lp,
        classes,
        training_speeds,
        ..
    } = prepare(opts)?;
    let rate = lp.sample_rate();
    tracing::info!(
        config = %config_file.display(),
        model = %model_path.display(),
        classes = %classes.join(", "),
        training_speeds = %training_speeds.describe(),
        rate,
        hop_s = cfg.stream.hop_s,
        speed_normalised = lp.speed_normalised(),
        speed_timeout_s = cfg.input.speed_timeout_s,
        max_lag_s = cfg.input.max_lag_s,
        "arte starting"
    );
    let node = IpcNode::create(topics::node::ARTE)?;
    let sub = node.subscriber::<AudioBlock>(topics::AUDIO, SubscriberMode::Deep)?;
    // the newest cycle record is all that matters (1 kHz, one per ms)
    let cycles = node.subscriber::<CycleRecord>(topics::CYCLE, SubscriberMode::Latest)?;
    let mut publisher = node.publisher::<RoadEstimate>(topics::ROAD)?;
    let stats = Arc::new(ArteCounters::default());
    let done = Arc::new(AtomicBool::new(false));
    let helper = monitor::spawn_helper(
        Arc::clone(&stats),
        rate,
        lp.speed_normalised(),
        Arc::clone(&done),
    )?;
    let rt = grip_io::rt::apply(&cfg.rt);
    rt.log();
    let clock = MonotonicClock;
    let poll_ns = (cfg.input.poll_interval_ms * 1e6) as u64;
    // saturating: a run length beyond the clock's range never ends the run
    let deadline = opts
        .run_for
        .map(|s| grip_io::service::args::deadline_ns(clock.now_ns(), s));
    grip_io::systemd::notify_ready(&format!(
        "estimating: {} classes at {rate} Hz from {}{}",
        classes.len(),
        topics::AUDIO,
        rt.status_note()
    ));
    let mut beat = 0u64;
    loop {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let now = clock.now_ns();
        if deadline.is_some_and(|d| now >= d) {
            break;
        }
        beat += 1;
        stats.heartbeat.store(beat, Ordering::Relaxed);
        let mut got = 0;
        loop {
            match sub.recv() {
                Ok(Some(b)) => {
                    lp.poll_cycles(&cycles, &stats);
                    lp.on_live_block(&b, clock.now_ns(), &mut publisher, &stats);
                    got += 1;
                    // the heartbeat moves with every block as well as once
                    // per iteration: an iteration that drains a backlog (a
                    // restarted instance, a starved CPU) is progress, and
                    // must not read as a stall to the watchdog
                    beat += 1;
                    stats.heartbeat.store(beat, Ordering::Relaxed);
                    if stop.load(Ordering::Relaxed) {
                        break;
                    }
                }
                Ok(None) => break,
                Err(_) => {
                    stats.receive_errors.fetch_add(1, Ordering::Relaxed);
                    break;
                }
            }
        }
        if got == 0 {
            clock.sleep_until_ns(now + poll_ns);
        }
    }
    grip_io::systemd::notify_stopping();
    done.store(true, Ordering::Relaxed);
    let _ = helper.join();
    drop(rt);
    let summary = RunSummary::from_counters(&stats);
    log_stopped(&summary, &classes, &stats);
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use std::io::Write;
    use std::sync::Mutex;

    use super::*;

    #[derive(Clone, Default)]
    struct Logs(Arc<Mutex<Vec<u8>>>);
    impl Write for Logs {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// A microphone that gave only silence (every block refused, no road
    /// estimate), clipped and overrun blocks, and blocks at another rate:
    /// each count is in the summary and named in `arte stopped`.
    #[test]
    fn the_stop_line_names_the_blocks_not_classified() {
        let stats = ArteCounters::default();
        for (c, n) in [
            (&stats.blocks, 120),
            (&stats.estimates, 103),
            (&stats.lost_blocks, 4),
            (&stats.silent_blocks, 97),
            (&stats.clipped_blocks, 5),
            (&stats.xrun_blocks, 3),
            (&stats.rate_mismatch, 11),
        ] {
            c.store(n, Ordering::Relaxed);
        }
        let summary = RunSummary::from_counters(&stats);
        assert_eq!(
            (
                summary.blocks,
                summary.estimates,
                summary.lost_blocks,
                summary.silent_blocks,
                summary.clipped_blocks,
                summary.xrun_blocks,
                summary.rate_mismatch
            ),
            (120, 103, 4, 97, 5, 3, 11)
        );
        let logs = Logs::default();
        let w = logs.clone();
        let sub = tracing_subscriber::fmt()
            .with_writer(move || w.clone())
            .with_ansi(false)
            .finish();
        let classes = vec!["asphalt".to_string(), "snow".to_string()];
        tracing::subscriber::with_default(sub, || log_stopped(&summary, &classes, &stats));
        let text = String::from_utf8(logs.0.lock().unwrap().clone()).unwrap();
        let line = text
            .lines()
            .find(|l| l.contains("arte stopped"))
            .unwrap_or_else(|| panic!("no stop line: {text}"));
        for want in [
            "blocks=120",
            "estimates=103",
            "lost_blocks=4",
            "silent_blocks=97",
            "clipped_blocks=5",
            "xrun_blocks=3",
            "rate_mismatch=11",
            "per_class=asphalt 0, snow 0",
        ] {
            assert!(line.contains(want), "{want} missing: {line}");
        }
    }
}
