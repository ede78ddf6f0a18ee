//! `recorder.toml`: where logs go, MCAP options, queue bounds.
//! Parsed with `grip_config::parse_toml` (unknown fields refused, errors name
//! file, field and line) and range-checked by [`ServiceConfig::validate`].

use std::path::{Path, PathBuf};
use std::time::Duration;

use grip_config::ConfigError;
use grip_io::mcaplog::{Compression, McapWriterOptions};
use grip_io::service::ServiceConfig;
use serde::Deserialize;

/// The recorder's own configuration.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecorderConfig {
    /// Directory of the log when `--out` is not given; the file is
    /// `grip-<unix seconds>-<boot id>-<pid>.mcap` (never an existing file).
    pub out_dir: PathBuf,
    /// Chunk compression: "lz4", "zstd" or "none".
    #[serde(default)]
    pub compression: Compression,
    /// Target uncompressed chunk size, KiB (16 ..= 65536).
    pub chunk_size_kib: u64,
    /// Longest time between durable flushes (chunk closed + fdatasync), ms
    /// (10 ..= 1000: a crash loses at most this much).
    pub flush_interval_ms: u64,
    /// Sleep of the receive thread when every subscriber was empty, ms
    /// (1 ..= 100). The deep subscribers hold 1024 samples (4096 of the
    /// CAN log, ~3.2 kHz, thus ~1.3 s), so this must stay far below that.
    pub poll_interval_ms: u64,
    /// Messages the queue between receiving and writing holds (1024 ..=
    /// 4194304). When the writer falls this far behind, new messages are
    /// dropped and counted (publishers are never slowed).
    pub queue_capacity: usize,
    /// Largest file attached to the log (config files, DBC, models), bytes.
    /// Larger files are hashed but not attached (and say so).
    pub attach_max_bytes: u64,
    /// Budget of grip's own logs in `out_dir`, MiB: the oldest finished
    /// logs are deleted while all of them together take more
    /// ([`crate::retention`]). 0 = no budget; otherwise 16 ..= 16777216
    /// (16 TiB). Absent: [`DEFAULT_MAX_TOTAL_MIB`].
    #[serde(default = "default_max_total_mib")]
    pub max_total_mib: u64,
    /// Free space to keep on `out_dir`'s file system, MiB (what an
    /// unprivileged user may still write): the oldest finished logs are
    /// deleted while less is free. 0 = no floor; at most 16777216.
    /// Absent: [`DEFAULT_MIN_FREE_MIB`].
    #[serde(default = "default_min_free_mib")]
    pub min_free_mib: u64,
    /// Rotation (without `--out`): a new part once the one being written
    /// holds this many MiB on disk ([`crate::parts`]). 0 = no size limit
    /// (only with `max_total_mib = 0`); otherwise 1 ..= 16777216, and at
    /// most half of `max_total_mib` when that budget is on. Absent:
    /// [`DEFAULT_MAX_FILE_MIB`], or half the budget when that is smaller
    /// (an older file with a small budget keeps working):
    /// [`RecorderConfig::max_file_mib`].
    #[serde(default)]
    pub max_file_mib: Option<u64>,
    /// Rotation (without `--out`): a new part once the one being written
    /// has recorded this many seconds, 1 ..= 86400. Absent:
    /// [`DEFAULT_MAX_FILE_S`].
    #[serde(default = "default_max_file_s")]
    pub max_file_s: u64,
    /// What of the vehicle bus (`can.toml`) to log on the MCAP channel
    /// `grip/can/bus` ([`crate::bus`]). Absent: [`BusRecord::Foreign`].
    #[serde(default)]
    pub bus: BusRecord,
}

/// `max_file_mib` when the file does not set it: 1 GiB, about 40 minutes
/// at the ~1.6 GB an hour a drive writes; an eighth of the default budget,
/// so that retention frees it in steps of an eighth and keeps at least
/// 7 GiB of history.
pub const DEFAULT_MAX_FILE_MIB: u64 = 1024;
/// `max_file_s` when the file does not set it: an hour.
pub const DEFAULT_MAX_FILE_S: u64 = 3600;
/// Largest `max_file_s`: a day (a channel's u32 sequence numbers then
/// never wrap within a part: 86400 s at the CAN log's ~3.2 kHz is 2.8e8).
pub const MAX_FILE_S: u64 = 86_400;

fn default_max_file_s() -> u64 {
    DEFAULT_MAX_FILE_S
}

/// `bus` in `recorder.toml`: which frames of the vehicle bus the recorder
/// reads off the bus itself (read-only, every sender) and logs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BusRecord {
    /// Every frame that is not one of grip's protocol messages (11-bit
    /// data frames with an id of the *active* protocol: `can.toml`'s
    /// `dbc`, else the built-in one): those are in tcs-loop's CAN log
    /// already, stamped by the loop. Extended, remote and error frames
    /// are always foreign.
    #[default]
    Foreign,
    /// Every frame, grip's own too (a second, independent copy of them).
    All,
    /// No bus log: the bus is not opened.
    Off,
}

impl BusRecord {
    /// The value as `recorder.toml` spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Foreign => "foreign",
            Self::All => "all",
            Self::Off => "off",
        }
    }
}

/// `max_total_mib` when the file does not set it: 8 GiB, about five hours
/// of driving at the ~1.6 GB an hour a drive writes.
pub const DEFAULT_MAX_TOTAL_MIB: u64 = 8192;
/// `min_free_mib` when the file does not set it: 1 GiB left to the
/// journal, `/tmp/iceoryx2` and everything else on the file system (and
/// about 40 minutes of driving).
pub const DEFAULT_MIN_FREE_MIB: u64 = 1024;
/// Largest `max_total_mib` / `min_free_mib`: 16 TiB.
pub const MAX_RETENTION_MIB: u64 = 1 << 24;
/// Smallest budget other than 0 (off): a budget smaller than a few chunks
/// would delete every finished log at once.
pub const MIN_BUDGET_MIB: u64 = 16;

fn default_max_total_mib() -> u64 {
    DEFAULT_MAX_TOTAL_MIB
}

fn default_min_free_mib() -> u64 {
    DEFAULT_MIN_FREE_MIB
}

impl ServiceConfig for RecorderConfig {
    const FILE_NAME: &'static str = "recorder.toml";

    /// Range checks (errors name the file and field).
    fn validate(&self, path: &Path) -> Result<(), ConfigError> {
        let range = |field: &str, v: u64, lo: u64, hi: u64| {
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(ConfigError::new(
                    path,
                    field,
                    format!("must be in {lo} ..= {hi} (got {v})"),
                ))
            }
        };
        range("chunk_size_kib", self.chunk_size_kib, 16, 65536)?;
        range("flush_interval_ms", self.flush_interval_ms, 10, 1000)?;
        range("poll_interval_ms", self.poll_interval_ms, 1, 100)?;
        range("queue_capacity", self.queue_capacity as u64, 1024, 4 << 20)?;
        range("attach_max_bytes", self.attach_max_bytes, 0, 1 << 30)?;
        if self.max_total_mib != 0
            && !(MIN_BUDGET_MIB..=MAX_RETENTION_MIB).contains(&self.max_total_mib)
        {
            return Err(ConfigError::new(
                path,
                "max_total_mib",
                format!(
                    "must be 0 (no budget: logs are not deleted for their size) or in {MIN_BUDGET_MIB} ..= {MAX_RETENTION_MIB} (got {})",
                    self.max_total_mib
                ),
            ));
        }
        if self.min_free_mib > MAX_RETENTION_MIB {
            return Err(ConfigError::new(
                path,
                "min_free_mib",
                format!(
                    "must be 0 (no floor: logs are not deleted for free space) or in 1 ..= {MAX_RETENTION_MIB} (got {})",
                    self.min_free_mib
                ),
            ));
        }
        let max_file_mib = self.max_file_mib();
        if max_file_mib > MAX_RETENTION_MIB {
            return Err(ConfigError::new(
                path,
                "max_file_mib",
                format!(
                    "must be 0 (no size limit) or in 1 ..= {MAX_RETENTION_MIB} (got {max_file_mib})"
                ),
            ));
        }
        if self.max_total_mib != 0 && (max_file_mib == 0 || max_file_mib > self.max_total_mib / 2) {
            return Err(ConfigError::new(
                path,
                "max_file_mib",
                format!(
                    "must be in 1 ..= {} (half of max_total_mib = {}) while the budget is on, so that retention can delete finished parts and keep the budget (got {})",
                    self.max_total_mib / 2,
                    self.max_total_mib,
                    max_file_mib
                ),
            ));
        }
        range("max_file_s", self.max_file_s, 1, MAX_FILE_S)?;
        if self.out_dir.as_os_str().is_empty() {
            return Err(ConfigError::new(path, "out_dir", "must not be empty"));
        }
        Ok(())
    }
}

impl RecorderConfig {
    /// MCAP writer options.
    pub fn writer_options(&self) -> McapWriterOptions {
        McapWriterOptions {
            compression: self.compression,
            chunk_size: self.chunk_size_kib * 1024,
            flush_interval: Duration::from_millis(self.flush_interval_ms),
        }
    }

    /// The receive thread's idle sleep.
    pub fn poll_interval(&self) -> Duration {
        Duration::from_millis(self.poll_interval_ms)
    }

    /// `max_file_mib` as set, else [`DEFAULT_MAX_FILE_MIB`] or half of
    /// the budget `max_total_mib` when that is smaller.
    pub fn max_file_mib(&self) -> u64 {
        self.max_file_mib.unwrap_or(match self.max_total_mib {
            0 => DEFAULT_MAX_FILE_MIB,
            b => DEFAULT_MAX_FILE_MIB.min(b / 2),
        })
    }

    /// When the recorder starts a new part (without `--out`).
    pub fn rotation(&self) -> crate::parts::Rotation {
        let mib = self.max_file_mib();
        crate::parts::Rotation {
            max_bytes: (mib != 0).then_some(mib << 20),
            max_age: Duration::from_secs(self.max_file_s),
        }
    }

    /// The retention limits in bytes (`None`: retention off, both keys 0).
    pub fn retention_limits(&self) -> Option<crate::retention::Limits> {
        let l = crate::retention::Limits {
            max_total: self.max_total_mib << 20,
            min_free: self.min_free_mib << 20,
        };
        (!l.is_off()).then_some(l)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_config::parse_toml;

    const GOOD: &str = r#"
out_dir = "/var/log/grip"
compression = "zstd"
chunk_size_kib = 512
flush_interval_ms = 1000
poll_interval_ms = 2
queue_capacity = 65536
attach_max_bytes = 16777216
"#;

    #[test]
    fn shipped_config_loads() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/recorder.toml");
        let c = RecorderConfig::load(&p).unwrap();
        assert!(c.flush_interval_ms <= 1000);
        // the shipped file states the documented defaults
        assert_eq!(
            (c.max_total_mib, c.min_free_mib),
            (DEFAULT_MAX_TOTAL_MIB, DEFAULT_MIN_FREE_MIB)
        );
        assert_eq!(
            (c.max_file_mib, c.max_file_s),
            (Some(DEFAULT_MAX_FILE_MIB), DEFAULT_MAX_FILE_S)
        );
        assert_eq!(
            c.bus,
            BusRecord::Foreign,
            "the shipped file states the default"
        );
    }

    #[test]
    fn good_parses() {
        let p = Path::new("recorder.toml");
        let c: RecorderConfig = parse_toml(p, GOOD).unwrap();
        c.validate(p).unwrap();
        assert_eq!(c.compression, Compression::Zstd);
        assert_eq!(c.writer_options().chunk_size, 512 * 1024);
    }

    #[test]
    fn unknown_field_is_named() {
        let p = Path::new("recorder.toml");
        let e = parse_toml::<RecorderConfig>(p, &format!("{GOOD}\nbogus = 1\n")).unwrap_err();
        assert!(e.to_string().contains("bogus"), "{e}");
    }

    #[test]
    fn flush_interval_over_one_second_is_refused() {
        let p = Path::new("recorder.toml");
        let text = GOOD.replace("flush_interval_ms = 1000", "flush_interval_ms = 5000");
        let c: RecorderConfig = parse_toml(p, &text).unwrap();
        let e = c.validate(p).unwrap_err();
        assert_eq!(e.field, "flush_interval_ms");
        assert!(e.to_string().contains("recorder.toml"), "{e}");
    }

    /// The retention keys: defaults when absent, 0 switches each off, both
    /// 0 switch retention off, out-of-range values named with file, field
    /// and reason.
    #[test]
    fn retention_keys_default_switch_off_and_are_range_checked() {
        let p = Path::new("recorder.toml");
        let c: RecorderConfig = parse_toml(p, GOOD).unwrap();
        c.validate(p).unwrap();
        assert_eq!(
            (c.max_total_mib, c.min_free_mib),
            (DEFAULT_MAX_TOTAL_MIB, DEFAULT_MIN_FREE_MIB)
        );
        let l = c.retention_limits().unwrap();
        assert_eq!((l.max_total, l.min_free), (8192 << 20, 1024 << 20));

        let with = |extra: &str| -> Result<RecorderConfig, ConfigError> {
            let c: RecorderConfig = parse_toml(p, &format!("{GOOD}{extra}"))?;
            c.validate(p)?;
            Ok(c)
        };
        let c = with("max_total_mib = 0\nmin_free_mib = 0\n").unwrap();
        assert_eq!(c.retention_limits(), None, "both 0: off");
        let c = with("max_total_mib = 0\nmin_free_mib = 500\n").unwrap();
        assert_eq!(
            c.retention_limits(),
            Some(crate::retention::Limits {
                max_total: 0,
                min_free: 500 << 20
            })
        );
        for (extra, field) in [
            ("max_total_mib = 5\n", "max_total_mib"),
            ("max_total_mib = 16777217\n", "max_total_mib"),
            ("min_free_mib = 16777217\n", "min_free_mib"),
        ] {
            let e = with(extra).unwrap_err();
            assert_eq!(e.field, field, "{extra}");
            let s = e.to_string();
            assert!(
                s.contains("recorder.toml") && s.contains(field) && s.contains("must be 0"),
                "{s}"
            );
        }
        // a negative or fractional size is a parse error naming the field
        for extra in ["min_free_mib = -1\n", "max_total_mib = 1.5\n"] {
            let e = with(extra).unwrap_err();
            assert!(e.to_string().contains("_mib"), "{extra}: {e}");
        }
    }

    /// The rotation keys: defaults when absent, ranges, and a part size
    /// that leaves retention room in its budget.
    #[test]
    fn rotation_keys_default_and_are_checked_against_the_budget() {
        let p = Path::new("recorder.toml");
        let c: RecorderConfig = parse_toml(p, GOOD).unwrap();
        c.validate(p).unwrap();
        assert_eq!(
            (c.max_file_mib(), c.max_file_s),
            (DEFAULT_MAX_FILE_MIB, DEFAULT_MAX_FILE_S)
        );
        let r = c.rotation();
        assert_eq!(r.max_bytes, Some(1024 << 20));
        assert_eq!(r.max_age, Duration::from_secs(3600));
        let with = |extra: &str| -> Result<RecorderConfig, ConfigError> {
            let c: RecorderConfig = parse_toml(p, &format!("{GOOD}{extra}"))?;
            c.validate(p)?;
            Ok(c)
        };
        with("max_total_mib = 16\nmax_file_mib = 8\nmax_file_s = 1\n").unwrap();
        // absent: the default, or half a smaller budget (an older file
        // with a small budget keeps working)
        let c = with("max_total_mib = 16\n").unwrap();
        assert_eq!(c.rotation().max_bytes, Some(8 << 20));
        let c = with("max_total_mib = 0\n").unwrap();
        assert_eq!(c.rotation().max_bytes, Some(1024 << 20));
        let c = with("max_total_mib = 0\nmin_free_mib = 0\nmax_file_mib = 0\n").unwrap();
        assert_eq!(
            c.rotation().max_bytes,
            None,
            "no budget: no size limit allowed"
        );
        for (extra, field, why) in [
            (
                "max_total_mib = 16\nmax_file_mib = 9\n",
                "max_file_mib",
                "half of max_total_mib",
            ),
            (
                "max_file_mib = 0\n",
                "max_file_mib",
                "half of max_total_mib",
            ),
            ("max_file_mib = 4097\n", "max_file_mib", "1 ..= 4096"),
            (
                "max_total_mib = 0\nmax_file_mib = 16777217\n",
                "max_file_mib",
                "no size limit",
            ),
            ("max_file_s = 0\n", "max_file_s", "1 ..= 86400"),
            ("max_file_s = 86401\n", "max_file_s", "1 ..= 86400"),
        ] {
            let e = with(extra).unwrap_err();
            assert_eq!(e.field, field, "{extra}");
            let s = e.to_string();
            assert!(
                s.contains("recorder.toml") && s.contains(why),
                "{extra}: {s}"
            );
        }
    }

    /// `bus`: "foreign" when absent, the three values parse, anything else
    /// is refused naming the file, the key and the values it takes.
    #[test]
    fn bus_key_defaults_to_foreign_and_names_bad_values() {
        let p = Path::new("recorder.toml");
        let c: RecorderConfig = parse_toml(p, GOOD).unwrap();
        assert_eq!(c.bus, BusRecord::Foreign);
        for (v, want) in [
            ("foreign", BusRecord::Foreign),
            ("all", BusRecord::All),
            ("off", BusRecord::Off),
        ] {
            let c: RecorderConfig = parse_toml(p, &format!("{GOOD}bus = \"{v}\"\n")).unwrap();
            c.validate(p).unwrap();
            assert_eq!(c.bus, want);
            assert_eq!(want.as_str(), v);
        }
        for bad in [
            "bus = \"everything\"\n",
            "bus = true\n",
            "bus = \"Foreign\"\n",
        ] {
            let e = parse_toml::<RecorderConfig>(p, &format!("{GOOD}{bad}")).unwrap_err();
            let s = e.to_string();
            assert_eq!(e.field, "bus", "{bad}: {s}");
            assert!(s.contains("recorder.toml"), "{s}");
            assert!(s.contains("line 9"), "{s}");
        }
        let e = parse_toml::<RecorderConfig>(p, &format!("{GOOD}bus = \"everything\"\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("everything") && e.contains("foreign") && e.contains("off"),
            "{e}"
        );
    }

    #[test]
    fn bad_compression_is_refused() {
        let p = Path::new("recorder.toml");
        let text = GOOD.replace("\"zstd\"", "\"brotli\"");
        let e = parse_toml::<RecorderConfig>(p, &text).unwrap_err();
        assert!(
            e.to_string().contains("brotli") || e.to_string().contains("compression"),
            "{e}"
        );
    }
}
