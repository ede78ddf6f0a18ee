//! The road catalogue a drive ran with, for the summary's preview report
//! (each road's μ_peak, by name): the `roads.toml` the recorder attached to
//! the log (with the `roads/*.csv` tables it names, also attached), checked
//! against the SHA-256 `grip.run` records for it; only when the log carries
//! none that can be used, the configuration directory's, with a warning
//! that it may not be the drive's. `grip inspect LOG`, `grip inspect A B`,
//! `grip inspect DIR` and `grip inspect --json` all take it from
//! [`DriveLog::road_catalogue`].

use std::path::Path;

use grip_config::ConfigDir;
use grip_physics::RoadCatalogue;

use crate::log::DriveLog;

/// The attachment the recorder writes the road catalogue to.
pub const ROADS_ATTACHMENT: &str = "roads.toml";

/// Where a log's road catalogue came from ([`DriveLog::road_catalogue`]).
#[derive(Debug, Clone)]
pub struct LogRoads {
    /// The catalogue (None: neither the log's nor the configuration
    /// directory's could be read; no preview report).
    pub catalogue: Option<RoadCatalogue>,
    /// Where it came from, for the report ("roads.toml attached to the
    /// log", or the configuration directory's file).
    pub from: String,
    /// Why the log's own catalogue was not used, each naming the file, the
    /// field where there is one, and the reason.
    pub warnings: Vec<String>,
}

impl DriveLog {
    /// The road catalogue the drive ran with: the attached `roads.toml`
    /// (and its attached `roads/*.csv` tables), each checked against its
    /// SHA-256 in `grip.run` when recorded there; else `config_dir`'s
    /// `roads.toml`, with a warning saying why and that it may differ from
    /// the drive's; else none (a warning; no preview report).
    pub fn road_catalogue(&self, config_dir: &Path) -> LogRoads {
        let mut warnings = Vec::new();
        match attached_roads(self) {
            Ok(Some(c)) => {
                return LogRoads {
                    catalogue: Some(c),
                    from: format!("{ROADS_ATTACHMENT} attached to the log"),
                    warnings,
                };
            }
            Ok(None) => warnings.push(format!(
                "{}: no {ROADS_ATTACHMENT} attached to the log",
                self.path.display()
            )),
            Err(e) => warnings.push(e),
        }
        let dir = ConfigDir::new(config_dir);
        match dir.roads() {
            Ok(c) => {
                let from = format!(
                    "{} (configuration directory: not the log's own, may differ from the drive's)",
                    dir.roads_path().display()
                );
                warnings.push(format!("road catalogue for the preview report: {from}"));
                LogRoads {
                    catalogue: Some(c),
                    from,
                    warnings,
                }
            }
            Err(e) => {
                warnings.push(format!("{e}; no preview report"));
                LogRoads {
                    catalogue: None,
                    from: "none".into(),
                    warnings,
                }
            }
        }
    }
}

/// Checks an attachment against the SHA-256 `grip.run` records for it
/// (`config.NAME`), when it records one.
fn check_hash(log: &DriveLog, name: &str, data: &[u8]) -> Result<(), String> {
    if let Some(want) = log.run.get(&format!("config.{name}")) {
        let got = grip_digest::sha256_hex(data);
        if *want != got {
            return Err(format!(
                "{}: attachment {name}: its SHA-256 {got} is not the one grip.run records ({want}): the attachment is damaged",
                log.path.display()
            ));
        }
    }
    Ok(())
}

/// The attached catalogue: Ok(None) when there is no `roads.toml`
/// attachment, Err (the reason, naming the log, the attachment and the
/// field) when it cannot be used.
fn attached_roads(log: &DriveLog) -> Result<Option<RoadCatalogue>, String> {
    let Some(data) = log.attachments.get(ROADS_ATTACHMENT) else {
        return Ok(None);
    };
    check_hash(log, ROADS_ATTACHMENT, data)?;
    let text = std::str::from_utf8(data).map_err(|e| {
        format!(
            "{}: attachment {ROADS_ATTACHMENT}: not UTF-8 text ({e})",
            log.path.display()
        )
    })?;
    // The catalogue's CSV tables are resolved relative to roads.toml: the
    // attached ones (roads/NAME.csv) go into a private directory, so a
    // table the log lacks is an error, never a file of the current one.
    let tmp = tempfile::tempdir().map_err(|e| {
        format!(
            "{}: attachment {ROADS_ATTACHMENT}: cannot create a temporary directory for its tables: {e}",
            log.path.display()
        )
    })?;
    for (name, data) in &log.attachments {
        let Some(rest) = name.strip_prefix("roads/") else {
            continue;
        };
        // only plain file names: nothing is written outside the directory
        if rest.is_empty() || rest.contains('/') || rest.starts_with('.') {
            continue;
        }
        check_hash(log, name, data)?;
        let p = tmp.path().join(name);
        let written = std::fs::create_dir_all(tmp.path().join("roads"))
            .and_then(|()| std::fs::write(&p, data));
        if let Err(e) = written {
            return Err(format!(
                "{}: attachment {name}: cannot write it to {}: {e}",
                log.path.display(),
                p.display()
            ));
        }
    }
    let file = tmp.path().join(ROADS_ATTACHMENT);
    grip_config::parse_roads(&file, text)
        .map(Some)
        .map_err(|e| {
            // name the log's attachments, not the private directory
            let dir = format!("{}/", tmp.path().display());
            let at = format!("{}: attachment ", log.path.display());
            e.to_string().replace(&dir, &at)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
    }

    fn with_roads(text: &str) -> DriveLog {
        let mut log = DriveLog {
            path: "drive.mcap".into(),
            ..DriveLog::default()
        };
        log.attachments
            .insert(ROADS_ATTACHMENT.into(), text.as_bytes().to_vec());
        log
    }

    /// The log's own catalogue wins over the configuration directory's;
    /// a changed, damaged or missing one falls back with a warning naming
    /// the file and the reason.
    #[test]
    fn the_logs_own_catalogue_is_used() {
        let shipped = std::fs::read_to_string(cfg().join("roads.toml")).unwrap();
        let changed = shipped.replacen("c1 = 0.1946", "c1 = 0.1500", 1);
        assert_ne!(shipped, changed, "snow's c1 is in roads.toml");
        let mut log = with_roads(&changed);
        log.attachments.insert(
            "roads/gravel_table.csv".into(),
            std::fs::read(cfg().join("roads/gravel_table.csv")).unwrap(),
        );
        let r = log.road_catalogue(&cfg());
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert_eq!(r.from, "roads.toml attached to the log");
        let c = r.catalogue.unwrap();
        let snow = c.get("snow").unwrap();
        let b = grip_physics::Road::burckhardt("snow", 0.15, 94.129, 0.0646).unwrap();
        assert!((snow.mu_peak() - b.mu_peak()).abs() < 1e-12);
        assert!(c.get("gravel_table").is_some());

        // grip.run's hash does not match: damaged, the directory's instead
        log.run.insert(
            "config.roads.toml".into(),
            grip_digest::sha256_hex(shipped.as_bytes()),
        );
        let r = log.road_catalogue(&cfg());
        let w = r.warnings.join("\n");
        assert!(
            w.contains("drive.mcap: attachment roads.toml: its SHA-256")
                && w.contains("configuration directory"),
            "{w}"
        );
        assert!(r.from.contains("configuration directory"), "{}", r.from);
        let snow = r.catalogue.unwrap().get("snow").unwrap().mu_peak();
        let shipped_snow = grip_physics::Road::burckhardt("snow", 0.1946, 94.129, 0.0646)
            .unwrap()
            .mu_peak();
        assert!((snow - shipped_snow).abs() < 1e-12);

        // a table the log does not carry is an error naming it, never a
        // file of the current directory
        let log = with_roads(&shipped);
        let r = log.road_catalogue(&cfg());
        let w = r.warnings.join("\n");
        assert!(
            w.contains("drive.mcap: attachment roads/gravel_table.csv") && w.contains("csv"),
            "{w}"
        );

        // a bad field names file, field and reason
        let log =
            with_roads("[[road]]\nname = \"x\"\nmodel = \"burckhardt\"\nc1 = 1.0\nc2 = 2.0\n");
        let w = log.road_catalogue(&cfg()).warnings.join("\n");
        assert!(
            w.contains("drive.mcap: attachment roads.toml: field `road[0].c3`: road `x`: missing"),
            "{w}"
        );

        // none attached, no configuration: no catalogue, said so
        let log = DriveLog::default();
        let r = log.road_catalogue(Path::new("/nonexistent-grip-config"));
        assert!(r.catalogue.is_none());
        let w = r.warnings.join("\n");
        assert!(
            w.contains("no roads.toml attached") && w.contains("no preview report"),
            "{w}"
        );
    }
}
