//! `grip drive`: a real-time drive of all five services as separate
//! processes (the command lines of the systemd units), on a scenario, with
//! a summary read back from the MCAP log. See `drive/` for the parts and
//! `services/README.md` ("recorder / drive / inspect / systemd").

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use anyhow::{Context, bail};
use grip_config::ConfigDir;

use super::Ctx;
use crate::drive::{own_model, rates};
use grip_drive::{self as drive, DrivePlan, summary};

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Controller {
    Mfc,
    Src,
    Mtte,
}

#[derive(clap::Args)]
pub struct Args {
    /// Scenario: a name under `<config-dir>/scenarios` or a path to a TOML file.
    #[arg(long, default_value = "paper")]
    scenario: String,
    /// Traction controller of tcs-loop.
    #[arg(long, value_enum, default_value_t = Controller::Mtte)]
    controller: Controller,
    /// Whether the controller uses ARTE's road estimates (arte runs either way).
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    arte: OnOff,
    /// MCAP log to write.
    #[arg(long, default_value = "drive.mcap")]
    out: PathBuf,
    /// Vehicle TOML for plant-sim and tcs-loop (default: `<config-dir>/vehicle.toml`),
    /// e.g. config/vehicles/front-mic.toml.
    #[arg(long)]
    vehicle: Option<PathBuf>,
    /// ARTE model file for arte (default: the `model` of `<config-dir>/arte-svc.toml`), e.g. one
    /// from `grip train`; its sample rate must be audio-acq's `[audio] sample_rate`.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Sensor-noise seed of plant-sim.
    #[arg(long, default_value_t = drive::plan::DEFAULT_SEED)]
    seed: u64,
    /// Seconds each service may take to report READY=1.
    #[arg(long, default_value_t = drive::plan::DEFAULT_READY_TIMEOUT_S)]
    ready_timeout: f64,
    /// Check the configuration as the drive does before any service starts
    /// (vehicle, scenario, model and audio rate, the bus's DBC, tcs-loop's
    /// and the recorder's start-up checks), print each service's command
    /// line (and its systemd ExecStart=) and exit.
    #[arg(long)]
    dry_run: bool,
    /// Forward every line the services write to stderr (default: warnings and errors).
    #[arg(long, short)]
    verbose: bool,
}

/// The scenario's file when `--scenario` names one by path
/// (`grip_config::dir::ScenarioArg::given`; absolute, relative to `cwd`);
/// `None` for a name under `<config-dir>/scenarios`.
fn scenario_file(scenario: &str, cwd: &std::path::Path) -> Option<PathBuf> {
    match grip_config::dir::ScenarioArg::given(scenario) {
        grip_config::dir::ScenarioArg::Path(p) => Some(cwd.join(p)),
        grip_config::dir::ScenarioArg::Name(_) => None,
    }
}

pub fn run(ctx: &Ctx, args: Args) -> anyhow::Result<()> {
    // `$GRIP_BIN_DIR`, else beside the running `grip` (`target/<profile>/`)
    let bin = grip_io::binaries::bin_dir()?.path;
    if !args.dry_run {
        drive::check_binaries(&bin)?;
    }
    let cwd = std::env::current_dir().context("current directory")?;
    let config_dir = cwd.join(&ctx.config_dir);
    let dir = ConfigDir::new(&config_dir);
    let roads = dir.roads()?;
    let scenario = dir.scenario_with(&args.scenario, &roads)?;
    // a scenario given as a path (not a name under <config-dir>/scenarios,
    // which the recorder attaches with the directory): its file, attached
    // to the log as drive/scenario.toml and read by plant-sim by this path
    let scenario_file = scenario_file(&args.scenario, &cwd);
    // at most an hour: a service that takes longer to come up is not
    // coming (and 1e300 s is no Duration)
    if !(args.ready_timeout.is_finite() && args.ready_timeout > 0.0 && args.ready_timeout <= 3600.0)
    {
        bail!(
            "--ready-timeout {:?}: must be a positive number of seconds, at most 3600",
            args.ready_timeout
        );
    }
    let (vehicle, vehicle_params) = match &args.vehicle {
        Some(v) => {
            let v = cwd.join(v);
            // a bad file fails here, before any service starts
            let (params, _) = grip_config::load_vehicle_complete(&v)?;
            (Some(v), params)
        }
        None => (
            None,
            grip_config::load_vehicle_complete(dir.vehicle_path())?.0,
        ),
    };
    // the scenario against the vehicle and plant-sim's period, as
    // plant-sim's start-up checks it (a demand above torque_max, a
    // duration of too many cycles): refused here, before any service starts
    {
        use grip_io::service::ServiceConfig;
        let own = grip_io::service::ConfigArgs::in_dir(&config_dir)
            .own_file::<grip_plant_sim::PlantSimConfig>();
        let rate_hz = grip_plant_sim::PlantSimConfig::load(&own)?.rate_hz;
        let vehicle_file = vehicle.clone().unwrap_or_else(|| dir.vehicle_path());
        grip_config::check_scenario(
            &dir.scenario_path(&args.scenario),
            &scenario,
            grip_config::RunsOn {
                vehicle: &vehicle_params,
                vehicle_file: &vehicle_file,
                dt: 1.0 / rate_hz,
            },
        )?;
    }
    // arte's model against the audio's rate, before any service starts:
    // arte refuses every block at another rate, and the drive would run to
    // the end and record no road estimate
    let model = args.model.as_ref().map(|m| cwd.join(m));
    let arte_model =
        rates::arte_model(&config_dir, model.as_deref()).with_context(|| match &args.model {
            Some(m) => format!("--model {}", m.display()),
            None => format!(
                "arte's model (the `model` of {})",
                config_dir.join("arte-svc.toml").display()
            ),
        })?;
    let (audio_file, audio_hz) = rates::audio_rate(&config_dir)?;
    let model_named = match &args.model {
        Some(_) => format!("--model {}", arte_model.path.display()),
        None => format!(
            "arte's model {} (the `model` of {})",
            arte_model.path.display(),
            config_dir.join("arte-svc.toml").display()
        ),
    };
    rates::require_one_rate(
        &audio_file,
        audio_hz,
        &model_named,
        arte_model.hz,
        "the drive would run without a single road estimate",
        &format!(
            "drive with a model trained at {audio_hz} Hz: `grip drive --model FILE` (`grip train --data DIR` on recordings at {audio_hz} Hz)"
        ),
    )?;
    // the model's classes against the road catalogue, as arte's start-up
    // checks them (a model arte refuses would fail the drive after the
    // services started, naming the services' temporary copy)
    rates::check_model_classes(&config_dir, &arte_model.path)
        .with_context(|| model_named.clone())?;
    // the bus's DBC, before any service starts: tcs-loop and plant-sim
    // refuse one they cannot speak, and the drive would have started the
    // recorder for nothing and reported an empty drive
    {
        let dir = grip_config::ConfigDir::new(&config_dir);
        let can = grip_io::service::load_can(&dir)?;
        // with the drive's vehicle's wheel radii, and the bus load at the
        // bit rate the interface runs at, as tcs-loop reads them
        let radii = grip_io::can::protocol::WheelRadii::of(&vehicle_params);
        grip_io::service::resolve_protocol(&dir, &can, Some(radii)).map_err(|e| {
            if can.dbc.is_some() {
                anyhow::anyhow!("the CAN bus (can.toml's dbc): {e}")
            } else {
                anyhow::anyhow!("the CAN bus (can.toml): {e}")
            }
        })?;
    }
    // tcs-loop's own start-up checks (its files, the bus against its
    // settings: TorqueRequest carrying torque_max, the periods and
    // timeouts; the loop built from them), before any service starts: a
    // configuration it refuses would otherwise fail the drive after four
    // services started, said twice, and leave an empty log
    let controller_kind = match args.controller {
        Controller::Mfc => grip_tcs::ControllerKind::Mfc,
        Controller::Src => grip_tcs::ControllerKind::Src,
        Controller::Mtte => grip_tcs::ControllerKind::Mtte,
    };
    grip_tcs_loop::check(&grip_tcs_loop::Options {
        config: grip_io::service::ConfigArgs::in_dir(&config_dir),
        controller: Some(controller_kind),
        arte: Some(args.arte == OnOff::On),
        run_for_s: None,
        vehicle: vehicle.clone(),
    })
    .context("tcs-loop's configuration (checked before any service starts)")?;
    // the recorder's start-up checks (recorder.toml, the files it is asked
    // to attach), on the command line the drive gives it: it starts first,
    // and a file it refuses stopped the drive before anything else ran,
    // which then said only "no readable log"
    grip_recorder::check(&recorder_options(
        &config_dir,
        scenario_file.as_deref(),
        vehicle.as_deref(),
    ))
    .context("the recorder's configuration (checked before any service starts)")?;
    // `--model`: the services get a view of the configuration whose
    // arte-svc.toml names the model (the log then carries it)
    let view = match &model {
        Some(m) => Some(own_model::view(&config_dir, m)?),
        None => None,
    };
    let controller = match args.controller {
        Controller::Mfc => "mfc",
        Controller::Src => "src",
        Controller::Mtte => "mtte",
    };
    let out = cwd.join(&args.out);
    if out.is_dir() {
        bail!(
            "--out {}: is a directory; give the log's file name (e.g. {})",
            out.display(),
            out.join("drive.mcap").display()
        );
    }
    if let Some(parent) = out.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    // the recorder writes beside --out and the log takes its name when the
    // drive ran: a drive whose services fail to start never replaces a log
    // that was there
    let recording = partial_path(&out);
    // a .partial left by an earlier failed drive is not this drive's log:
    // gone before the recorder starts, so that it can never be taken for it
    // (dry runs start nothing and leave it)
    if !args.dry_run && recording.exists() {
        std::fs::remove_file(&recording).with_context(|| {
            format!(
                "removing {}, the log of an earlier drive that failed",
                recording.display()
            )
        })?;
        eprintln!(
            "drive: removed {}, the log of an earlier drive that failed",
            recording.display()
        );
    }
    let plan = DrivePlan {
        config_dir: view
            .as_ref()
            .map_or_else(|| config_dir.clone(), |v| v.dir.clone()),
        scenario: args.scenario.clone(),
        scenario_file,
        duration_s: scenario.duration,
        controller: controller.into(),
        arte: args.arte == OnOff::On,
        out: recording.clone(),
        seed: args.seed,
        instance: drive::new_instance(),
        ready_timeout: Duration::from_secs_f64(args.ready_timeout),
        vehicle,
        model: model.clone(),
    };
    if args.dry_run {
        if let Some(v) = &view {
            println!(
                "--model {}: the services' --config-dir is a view of {} made for the drive and removed after it, whose arte-svc.toml has model = \"{}\" (a copy of the file; every other entry linked)",
                arte_model.path.display(),
                config_dir.display(),
                v.name
            );
        }
        for svc in drive::Service::START_ORDER {
            println!("{}:", svc.name());
            println!(
                "  drive:   {} {}",
                bin.join(svc.binary()).display(),
                plan.args(svc).join(" ")
            );
            println!("  systemd: {} ExecStart={}", svc.unit(), svc.exec_start());
        }
        return Ok(());
    }
    eprintln!(
        "drive: services from {}, GRIP_INSTANCE={}, log {}",
        bin.display(),
        plan.instance,
        out.display()
    );
    if let Some(v) = &view {
        eprintln!(
            "drive: arte's model {} ({} Hz), as {} of a temporary view of {}",
            arte_model.path.display(),
            arte_model.hz,
            v.name,
            config_dir.display()
        );
    }
    let interrupt = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&interrupt))
            .context("installing the signal handler")?;
    }
    let outcome = drive::run_services(&plan, &bin, args.verbose, &interrupt, &mut |l| {
        eprintln!("{l}")
    })?;

    eprintln!(
        "drive: services stopped (scenario part {:.2} s wall):",
        outcome.scenario_wall_s
    );
    for (svc, last, st) in &outcome.services {
        eprintln!(
            "  {:<9} {:<22} {}",
            svc.name(),
            st.as_deref().unwrap_or("not reaped"),
            last
        );
    }
    // the log takes --out's name, unless the drive failed and --out held a
    // log already: then that stays and this attempt's is kept beside it
    let kept_old = outcome.failure.is_some() && out.exists();
    let log_path = if kept_old || !recording.exists() {
        recording.clone()
    } else {
        std::fs::rename(&recording, &out).with_context(|| {
            format!(
                "moving the drive's log {} to {}",
                recording.display(),
                out.display()
            )
        })?;
        out.clone()
    };
    if kept_old && recording.exists() {
        eprintln!(
            "drive: the drive failed, so {} (there before it) is left as it was; this attempt's log is {}",
            out.display(),
            recording.display()
        );
    }
    // the summary, from the log (also after a failure: what was recorded)
    let mut control_lost = None;
    let mut saturated: Vec<summary::ShortSignal> = Vec::new();
    match crate::drive::load_log(&log_path, Default::default()) {
        Ok(log) => {
            let (vehicle, from, warnings) = drive::vehicle_for(&log, &config_dir);
            for w in warnings {
                eprintln!("{w}");
            }
            // what `grip inspect LOG` prints, by the same code: the log's
            // own road catalogue (its warnings in the summary), the
            // histogram and the road timeline
            let log_roads = log.road_catalogue(&config_dir);
            let s = summary::summarize_with_roads(&log, &vehicle, &from, &log_roads);
            print!("{}", super::inspect::report(&log, &s));
            control_lost = s.control.filter(summary::ControlHealth::lost);
            saturated = s
                .can
                .short
                .into_iter()
                .filter(|sh| sh.in_window && sh.at_limit > 0)
                .collect();
        }
        Err(e) if outcome.failure.is_some() => eprintln!("drive: no readable log: {e:#}"),
        Err(e) => return Err(e.into()),
    }
    if let Some(f) = outcome.failure {
        bail!("drive failed: {f}");
    }
    // every service ran to the end, but the loop lost control and never
    // regained it (e.g. its bus gone for good): not a successful drive
    // (tools/grip/README.md, "When a drive fails")
    if let Some(c) = control_lost {
        bail!(
            "drive failed: tcs-loop's control during the scenario: {} (log kept: {})",
            c.line(),
            log_path.display()
        );
    }
    // a signal grip controls with sat at the limit of what the bus carries
    // during the scenario: the loop read a larger value as the limit, so
    // the drive's figures are not the controller's (tools/grip/README.md,
    // "When a drive fails")
    if let Some(sh) = saturated.first() {
        bail!(
            "drive failed: {} sat at the limit of what the bus carries in {} of the {} frames received during the scenario ({} signal(s) in all; see the summary's WARNING lines) (log kept: {})",
            sh.name,
            sh.at_limit,
            sh.frames,
            saturated.len(),
            log_path.display()
        );
    }
    Ok(())
}

/// The recorder's options as the drive starts it (`DrivePlan::args`): the
/// configuration directory, and the files it attaches (a `--scenario`
/// given as a path, the `--vehicle` file), for [`grip_recorder::check`].
/// Its `--out` and `--meta` are left out: the check creates no file, and
/// the metadata is not checked.
fn recorder_options(
    config_dir: &std::path::Path,
    scenario_file: Option<&std::path::Path>,
    vehicle: Option<&std::path::Path>,
) -> grip_recorder::Options {
    let attach = drive::plan::recorder_attachments(scenario_file, vehicle)
        .into_iter()
        .map(|(name, file)| (name.to_owned(), file.to_path_buf()))
        .collect();
    grip_recorder::Options {
        config: grip_io::service::ConfigArgs::in_dir(config_dir),
        out: None,
        meta: Vec::new(),
        attach,
    }
}

/// Where the recorder writes a drive's log until the drive has run:
/// `--out` with `.partial` added (`out/drive.mcap` → `out/drive.mcap.partial`).
fn partial_path(out: &std::path::Path) -> PathBuf {
    let mut name = out.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    out.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drive_records_beside_its_out() {
        assert_eq!(
            partial_path(std::path::Path::new("/d/out/drive.mcap")),
            PathBuf::from("/d/out/drive.mcap.partial")
        );
    }

    /// A scenario given as a path is attached to the log (its file,
    /// absolute); a name under the configuration directory is not (the
    /// recorder attaches the directory's scenarios).
    #[test]
    fn a_scenario_path_is_the_drive_s_own_file() {
        let cwd = std::path::Path::new("/drives/trial");
        assert_eq!(scenario_file("paper", cwd), None);
        assert_eq!(
            scenario_file("scen/suv.toml", cwd),
            Some(PathBuf::from("/drives/trial/scen/suv.toml"))
        );
        assert_eq!(
            scenario_file("/abs/suv.toml", cwd),
            Some(PathBuf::from("/abs/suv.toml"))
        );
    }
}
