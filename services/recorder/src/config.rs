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
