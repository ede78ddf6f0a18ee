//! The skeleton every grip service's `main` uses, so that the five
//! services start, stop and fail the same way:
//!
//! - [`Service::run`]: `tracing` to stderr (`RUST_LOG`, default `info`;
//!   colours only on a terminal), SIGTERM/SIGINT set the stop flag (and,
//!   with [`Service::with_start_signal`], SIGUSR1 sets a start flag), then
//!   the service's body; exit code 0 on success, after one `error: ...`
//!   line on stderr (a handler that cannot be installed, or the body's
//!   error naming file, field and reason) [`EXIT_CONFIG`] (78) when the
//!   error is the configuration's ([`ServiceError::is_config`]: a
//!   restart cannot mend it, and the units' `RestartPreventExitStatus=78`
//!   leaves the unit failed instead of restarting it every second), 1
//!   otherwise (a CAN interface or microphone not there yet, iceoryx2:
//!   what a restart may find mended).
//! - [`ConfigArgs`]: the `--config-dir DIR` / `--config FILE` pair of
//!   every service's command line; [`ServiceConfig`]: the read → parse →
//!   validate trio of the service's own TOML, whose errors name file,
//!   field and reason. `GRIP_INSTANCE` (an isolated iceoryx2 namespace) is
//!   read where the iceoryx2 node is created ([`crate::ipc`]).
//! - [`monitor`]: the non-real-time helper thread (watchdog through
//!   [`crate::systemd::Watchdog`], transition logging, counters that grew).

pub mod args;
pub mod monitor;

use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use grip_config::{ConfigDir, ConfigError, parse_toml, read_file};
use serde::de::DeserializeOwned;

use crate::can::CanBusConfig;
use crate::rt::RtConfig;

/// The flags the signal handlers set.
#[derive(Debug, Clone)]
pub struct Signals {
    /// Set by SIGTERM and SIGINT: finish the cycle, shut down, exit 0.
    pub stop: Arc<AtomicBool>,
    /// Set by SIGUSR1 if the service asked for it
    /// ([`Service::with_start_signal`]); otherwise never set (and SIGUSR1
    /// keeps its default action).
    pub start: Arc<AtomicBool>,
}

/// How a service's `main` runs its body (see the module docs).
#[derive(Debug, Clone, Copy, Default)]
pub struct Service {
    start_signal: bool,
}

impl Service {
    /// SIGTERM/SIGINT stop the service; no other signal is handled.
    pub fn new() -> Self {
        Self::default()
    }

    /// SIGUSR1 also sets [`Signals::start`] (plant-sim's scenario start).
    pub fn with_start_signal(mut self) -> Self {
        self.start_signal = true;
        self
    }

    /// Sets up tracing and the signal handlers, then runs `body`. Returns
    /// the process's exit code: 0 if `body` succeeded; after printing
    /// `error: {e}`, [`EXIT_CONFIG`] if it failed on its configuration,
    /// else 1 (also when a handler could not be installed).
    pub fn run<E: ServiceError>(self, body: impl FnOnce(&Signals) -> Result<(), E>) -> ExitCode {
        init_tracing();
        let signals = match self.install() {
            Ok(s) => s,
            Err(e) => return fail(e, 1),
        };
        match body(&signals) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                let code = if e.is_config() { EXIT_CONFIG } else { 1 };
                fail(e, code)
            }
        }
    }

    fn install(self) -> Result<Signals, String> {
        use signal_hook::consts::{SIGINT, SIGTERM, SIGUSR1};
        let signals = Signals {
            stop: Arc::new(AtomicBool::new(false)),
            start: Arc::new(AtomicBool::new(false)),
        };
        let mut regs = vec![(SIGTERM, &signals.stop), (SIGINT, &signals.stop)];
        if self.start_signal {
            regs.push((SIGUSR1, &signals.start));
        }
        for (sig, flag) in regs {
            signal_hook::flag::register(sig, Arc::clone(flag))
                .map_err(|e| format!("cannot install the handler for signal {sig}: {e}"))?;
        }
        Ok(signals)
    }
}

fn fail(e: impl Display, code: u8) -> ExitCode {
    eprintln!("error: {e}");
    ExitCode::from(code)
}

/// The exit code of a service that refuses its configuration: sysexits'
/// `EX_CONFIG`. The systemd units list it in `RestartPreventExitStatus=`:
/// a file, field or value that is wrong stays wrong on the next start, so
/// the unit is left failed (`systemctl status` shows the error) instead of
/// restarting every second for ever.
pub const EXIT_CONFIG: u8 = 78;

/// A service's fatal error, as [`Service::run`] ends the process on it.
pub trait ServiceError: Display {
    /// Whether the error is the configuration's (a file, field, value or
    /// model the service refuses, or one it cannot read), which a restart
    /// cannot mend: exit [`EXIT_CONFIG`]. Everything else (a CAN interface
    /// or a microphone not there yet, iceoryx2, a thread): exit 1, and the
    /// unit's `Restart=` tries again.
    fn is_config(&self) -> bool;
}

/// `tracing` for a service: human-readable lines on stderr (journald
/// keeps them), the level from `RUST_LOG` (default `info`), ANSI colours
/// only when stderr is a terminal.
pub fn init_tracing() {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .init();
}

/// The configuration options of every service's command line (flatten
/// them into the service's `clap` arguments; the service names its own
/// file's default in the help with `mut_arg("config", ...)`).
#[derive(Debug, Clone, Default, PartialEq, Eq, clap::Args)]
pub struct ConfigArgs {
    /// Shared configuration directory.
    #[arg(long, default_value = "config")]
    pub config_dir: PathBuf,
    /// The service's TOML (default: a file in `<config-dir>` named for the service).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

impl ConfigArgs {
    /// The configuration directory `dir` (`--config-dir`) without `--config`.
    pub fn in_dir(dir: impl Into<PathBuf>) -> Self {
        Self {
            config_dir: dir.into(),
            config: None,
        }
    }

    /// The service's own TOML: `--config`, else [`ServiceConfig::FILE_NAME`]
    /// in `--config-dir`.
    pub fn own_file<C: ServiceConfig>(&self) -> PathBuf {
        C::path(&self.config_dir, self.config.as_deref())
    }
}

/// A service's own TOML file: read, parsed (unknown fields refused, errors
/// naming file, field and line) and range-checked in one place.
pub trait ServiceConfig: DeserializeOwned {
    /// Its name in the configuration directory, e.g. `tcs-loop.toml`.
    const FILE_NAME: &'static str;

    /// Range checks; the error names `file` and the field.
    fn validate(&self, file: &Path) -> Result<(), ConfigError>;

    /// Parses and validates `text`, the contents of `file`.
    fn parse(file: &Path, text: &str) -> Result<Self, ConfigError> {
        let c: Self = parse_toml(file, text)?;
        c.validate(file)?;
        Ok(c)
    }

    /// Reads, parses and validates `file`.
    fn load(file: &Path) -> Result<Self, ConfigError> {
        Self::parse(file, &read_file(file)?)
    }

    /// The file a run reads: `config` (`--config`) if given, else
    /// [`Self::FILE_NAME`] in `config_dir` (`--config-dir`).
    fn path(config_dir: &Path, config: Option<&Path>) -> PathBuf {
        config.map_or_else(|| config_dir.join(Self::FILE_NAME), Path::to_path_buf)
    }
}

/// The checks of a service's `[rt]` table: `rt.fifo_priority` in 1..=99,
/// every CPU of `rt.cpus` below 1024. Errors name `file` and the field.
pub fn validate_rt(rt: &RtConfig, file: &Path) -> Result<(), ConfigError> {
    if let Some(p) = rt.fifo_priority
        && !(1..=99).contains(&p)
    {
        return Err(ConfigError::new(
            file,
            "rt.fifo_priority",
            format!("must be in 1..=99 (got {p}); leave it out to stay SCHED_OTHER"),
        ));
    }
    if let Some(&c) = rt.cpus.iter().find(|&&c| c >= 1024) {
        return Err(ConfigError::new(
            file,
            "rt.cpus",
            format!("CPU {c} out of range 0..1024"),
        ));
    }
    Ok(())
}

/// Reads `can.toml` in `dir` (the bus of tcs-loop and plant-sim); the
/// interface must not be empty.
pub fn load_can(dir: &ConfigDir) -> Result<CanBusConfig, ConfigError> {
    let path = dir.file("can.toml");
    parse_can(&path, &read_file(&path)?)
}

/// Reads the bus protocol `can` names (`dbc`, relative to `dir`; absent:
/// the built-in one) and makes it this process's
/// ([`crate::can::protocol::install`]), so that every frame the service
/// sends, receives, filters and logs is laid out as the bus's DBC says.
/// Called by the services' `load` before anything is built from the
/// protocol. Errors name the DBC file, the message or signal and the reason.
///
/// Without the wheels' radii: a DBC whose wheel speeds are in km/h or m/s
/// is refused; the services, which load the vehicle file, call
/// [`install_protocol_with`].
pub fn install_protocol(
    dir: &ConfigDir,
    can: &crate::can::CanBusConfig,
) -> Result<&'static crate::can::protocol::Protocol, ConfigError> {
    install_protocol_with(dir, can, None)
}

/// [`install_protocol`] with the wheels' rolling radii (the vehicle file's
/// `r` and `r_ref`), which convert a wheel speed the DBC gives in km/h or
/// m/s to rad/s (ω = v ÷ r). `can.toml`'s `[dbc_valid]` is applied either
/// way. The bus load is judged at the bit rate the interface runs at
/// ([`resolve_protocol`]); the choice and its warnings are logged once.
pub fn install_protocol_with(
    dir: &ConfigDir,
    can: &crate::can::CanBusConfig,
    radii: Option<crate::can::protocol::WheelRadii>,
) -> Result<&'static crate::can::protocol::Protocol, ConfigError> {
    use crate::can::protocol::install;
    let can_toml = dir.file("can.toml");
    let (p, rate) = resolve_protocol(dir, can, radii)?;
    if crate::can::protocol::installed().is_none() {
        for w in &rate.warnings {
            tracing::warn!("{w}");
        }
        tracing::info!(
            dbc = can.dbc.as_deref().unwrap_or("(built in)"),
            messages = %p.describe(),
            bus = %p.describe_bus(),
            bit_rate = %rate.note,
            speeds = %p.describe_speeds(),
            "CAN protocol"
        );
    }
    install(p).map_err(|e| {
        ConfigError::new(
            &can_toml,
            "dbc",
            format!(
                "{e} (one process speaks one bus; {} is not the one already in use)",
                can.dbc.as_deref().unwrap_or("the built-in protocol")
            ),
        )
    })
}

/// The protocol `can` names (its DBC, else the built-in one; see
/// [`install_protocol_with`] for `radii`) on the bus it runs on: the bit
/// rate is the interface's where the kernel reports one (`ip link set can0
/// type can bitrate N`), else the DBC's `Baudrate`, else 1 Mbit/s
/// ([`crate::can::choose_bitrate`]; the choice, with the warnings to log,
/// is returned beside it). A bus load over
/// [`crate::can::protocol::MAX_BUS_LOAD`] at that rate is refused: at the
/// interface's rate naming `can.toml`'s `interface`, the interface and its
/// rate; at the DBC's or the assumed one naming the DBC, as the DBC loader
/// does. Reading the interface's rate never fails (a netlink error is a
/// warning in the choice). Installs nothing: `grip drive`'s check before
/// it starts the services calls it too.
pub fn resolve_protocol(
    dir: &ConfigDir,
    can: &crate::can::CanBusConfig,
    radii: Option<crate::can::protocol::WheelRadii>,
) -> Result<
    (
        crate::can::protocol::Protocol,
        crate::can::bitrate::BitrateChoice,
    ),
    ConfigError,
> {
    use crate::can::bitrate::{BitrateSource, choose_bitrate, read_interface_bitrate};
    use crate::can::protocol::Protocol;
    let can_toml = dir.file("can.toml");
    let p = match &can.dbc {
        None if !can.dbc_names.is_empty() => {
            return Err(ConfigError::new(
                &can_toml,
                "dbc_names",
                "names a DBC's messages but no dbc = \"FILE\" is set",
            ));
        }
        None if !can.dbc_valid.is_empty() => {
            return Err(ConfigError::new(
                &can_toml,
                "dbc_valid",
                "gives a DBC's validity values but no dbc = \"FILE\" is set (the built-in protocol's flags are valid when 1)",
            ));
        }
        None => Protocol::builtin().clone(),
        Some(f) => {
            let path = dir.file(f);
            let mut settings = crate::can::DbcSettings::from_can(can, radii);
            // judged below, at the rate the bus runs at
            settings.skip_bus_load = true;
            Protocol::load_dbc_with(&path, &settings).map_err(|e| {
                // a [dbc_names] key is can.toml's: named by its path
                let file = if e.file == "can.toml" {
                    can_toml.clone()
                } else {
                    std::path::PathBuf::from(&e.file)
                };
                ConfigError::new(file, &e.what, &e.reason)
            })?
        }
    };
    let read = read_interface_bitrate(can);
    let rate = choose_bitrate(&can.interface, &read, p.bus().dbc_bitrate);
    let p = p.with_bitrate(&rate);
    if let Some((what, reason)) = p.bus_load_refusal() {
        let file = match (&rate.source, &can.dbc) {
            (BitrateSource::Interface(_), _) | (_, None) => can_toml,
            (_, Some(f)) => dir.file(f),
        };
        return Err(ConfigError::new(file, what, reason));
    }
    Ok((p, rate))
}

/// Parses `text`, the contents of `can.toml` at `file` (see [`load_can`]).
pub fn parse_can(file: &Path, text: &str) -> Result<CanBusConfig, ConfigError> {
    let c: CanBusConfig = parse_toml(file, text)?;
    if c.interface.trim().is_empty() {
        return Err(ConfigError::new(file, "interface", "must not be empty"));
    }
    // the iceoryx2 service `grip/canbus/<sim_bus>`: a name, or left out
    // (the interface's)
    if let Some(b) = &c.sim_bus
        && b.trim().is_empty()
    {
        return Err(ConfigError::new(
            file,
            "sim_bus",
            "must not be empty (leave it out to use the interface's name)",
        ));
    }
    if let Some(d) = &c.dbc {
        let plain = !d.contains('/') && !d.contains('\\') && d != ".dbc";
        if !plain || !d.ends_with(".dbc") {
            return Err(ConfigError::new(
                file,
                "dbc",
                format!(
                    "{d:?}: must be a file name ending in \".dbc\" (lower case), without a directory: a file in the configuration directory (the recorder attaches that directory's *.dbc files to every drive log, so that `grip inspect` and `grip replay` read the frames as the services did)"
                ),
            ));
        }
    }
    if let Some((k, _)) = c.dbc_names.iter().find(|(_, v)| v.trim().is_empty()) {
        return Err(ConfigError::new(
            file,
            format!("dbc_names.{k}"),
            "must name the DBC's message or signal (not empty)",
        ));
    }
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Demo {
        rate_hz: f64,
    }

    impl ServiceConfig for Demo {
        const FILE_NAME: &'static str = "demo.toml";
        fn validate(&self, file: &Path) -> Result<(), ConfigError> {
            if self.rate_hz > 0.0 {
                Ok(())
            } else {
                Err(ConfigError::new(file, "rate_hz", "must be > 0"))
            }
        }
    }

    #[test]
    fn path_defaults_to_the_file_in_the_directory() {
        assert_eq!(
            Demo::path(Path::new("cfg"), None),
            Path::new("cfg/demo.toml")
        );
        assert_eq!(
            Demo::path(Path::new("cfg"), Some(Path::new("x/own.toml"))),
            Path::new("x/own.toml")
        );
    }

    #[test]
    fn parse_validates_and_names_file_and_field() {
        let f = Path::new("dir/demo.toml");
        assert_eq!(Demo::parse(f, "rate_hz = 5.0").unwrap().rate_hz, 5.0);
        let e = Demo::parse(f, "rate_hz = -1.0").unwrap_err();
        assert_eq!(e.field, "rate_hz");
        assert!(e.to_string().starts_with("dir/demo.toml"), "{e}");
        let e = Demo::parse(f, "rate_hz = 5.0\nbogus = 1").unwrap_err();
        assert!(e.to_string().contains("bogus"), "{e}");
    }

    #[test]
    fn load_names_a_missing_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("demo.toml");
        let e = Demo::load(&p).unwrap_err();
        assert!(e.to_string().contains("demo.toml"), "{e}");
        std::fs::write(&p, "rate_hz = 2.0").unwrap();
        assert_eq!(Demo::load(&p).unwrap().rate_hz, 2.0);
    }

    #[test]
    fn rt_checks_name_the_field() {
        let f = Path::new("svc.toml");
        assert!(validate_rt(&RtConfig::default(), f).is_ok());
        let rt = RtConfig {
            fifo_priority: Some(0),
            ..RtConfig::default()
        };
        let e = validate_rt(&rt, f).unwrap_err();
        assert_eq!(e.field, "rt.fifo_priority");
        assert!(e.to_string().starts_with("svc.toml"), "{e}");
        let rt = RtConfig {
            fifo_priority: Some(80),
            cpus: vec![1, 4096],
            ..RtConfig::default()
        };
        assert_eq!(validate_rt(&rt, f).unwrap_err().field, "rt.cpus");
    }

    #[test]
    fn can_toml_interface_must_not_be_empty() {
        let dir = tempfile::tempdir().unwrap();
        let d = ConfigDir::new(dir.path());
        assert!(load_can(&d).unwrap_err().to_string().contains("can.toml"));
        let good = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/can.toml"),
        )
        .unwrap();
        std::fs::write(dir.path().join("can.toml"), &good).unwrap();
        assert!(!load_can(&d).unwrap().interface.is_empty());
        let interface = good
            .lines()
            .find(|l| l.trim_start().starts_with("interface"))
            .unwrap();
        std::fs::write(
            dir.path().join("can.toml"),
            good.replace(interface, "interface = \" \""),
        )
        .unwrap();
        assert_eq!(load_can(&d).unwrap_err().field, "interface");
    }

    /// `dbc` is a `.dbc` file in the configuration directory (so the
    /// recorder attaches it); a missing file, or a name map without a DBC,
    /// is refused naming the file and field; the shipped one installs the
    /// built-in protocol.
    #[test]
    fn the_bus_dbc_is_a_file_of_the_configuration_directory() {
        let f = Path::new("can.toml");
        let base = "interface = \"vcan0\"\n";
        for bad in [
            "bus/car.dbc",
            "/etc/car.dbc",
            "car.txt",
            ".dbc",
            "..\\car.dbc",
        ] {
            let e = parse_can(f, &format!("{base}dbc = {bad:?}\n")).unwrap_err();
            assert_eq!(e.field, "dbc", "{bad}: {e}");
        }
        assert!(parse_can(f, &format!("{base}dbc = \"car.dbc\"\n")).is_ok());
        let e = parse_can(f, &format!("{base}sim_bus = \" \"\n")).unwrap_err();
        assert_eq!(e.field, "sim_bus", "{e}");
        assert!(e.to_string().contains("must not be empty"), "{e}");
        let e = parse_can(
            f,
            &format!("{base}dbc = \"car.dbc\"\n[dbc_names]\nTorqueCommand = \" \"\n"),
        )
        .unwrap_err();
        assert_eq!(e.field, "dbc_names.TorqueCommand", "{e}");

        let dir = tempfile::tempdir().unwrap();
        let d = ConfigDir::new(dir.path());
        let names = parse_can(f, &format!("{base}[dbc_names]\nTorqueCommand = \"X\"\n")).unwrap();
        assert_eq!(install_protocol(&d, &names).unwrap_err().field, "dbc_names");
        let missing = parse_can(f, &format!("{base}dbc = \"car.dbc\"\n")).unwrap();
        let e = install_protocol(&d, &missing).unwrap_err();
        assert!(e.file.ends_with("car.dbc") && e.field == "file", "{e}");
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let can = load_can(&ConfigDir::new(&shipped)).unwrap();
        assert_eq!(can.dbc.as_deref(), Some("inverter.dbc"));
        let p = install_protocol(&ConfigDir::new(&shipped), &can).unwrap();
        assert_eq!(p, crate::can::protocol::Protocol::builtin());
    }

    #[test]
    fn config_args_parse_and_default() {
        use clap::Parser;
        #[derive(Debug, Parser)]
        struct A {
            #[command(flatten)]
            c: ConfigArgs,
        }
        let a = A::try_parse_from(["x"]).unwrap();
        assert_eq!(a.c.config_dir, Path::new("config"));
        assert_eq!(a.c.config, None);
        let a =
            A::try_parse_from(["x", "--config-dir", "/etc/grip", "--config", "o.toml"]).unwrap();
        assert_eq!(a.c.config_dir, Path::new("/etc/grip"));
        assert_eq!(a.c.config.as_deref(), Some(Path::new("o.toml")));
    }
}
