//! `run.toml` in `grip sim --out DIR`: what the directory's figures came
//! from, so that two result directories can be told apart and a figure
//! traced back to its inputs (the simulator is deterministic: the same
//! build, files and command give the same figures). The same set of
//! configuration files that a drive's MCAP log records
//! ([`grip_recorder::config_files`]), each with its SHA-256, plus the
//! files named on the command line from outside the configuration
//! directory.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;

/// The file's name in `--out`.
pub const FILE: &str = "run.toml";

/// What a run is, as `run.toml` states it.
pub struct RunRecord {
    /// The command line as given.
    pub command: Vec<String>,
    /// `--config-dir`.
    pub config_dir: PathBuf,
    /// The vehicle file and its one-line description.
    pub vehicle: (PathBuf, String),
    /// The scenario file, or `random` with its recipe.
    pub scenario: String,
    /// The ARTE source as the report names it.
    pub arte_source: String,
    /// The seeds, as ranges (`1-20`).
    pub seeds: String,
    /// Files named on the command line (vehicle, scenario, ARTE
    /// configuration, model): hashed too when outside the configuration
    /// directory.
    pub named_files: Vec<PathBuf>,
}

impl RunRecord {
    /// The record's text: TOML with a comment saying what it is. Files
    /// that cannot be read are listed with the reason instead of a hash.
    pub fn to_toml(&self) -> String {
        let hash = |path: &Path| match std::fs::read(path) {
            Ok(b) => grip_digest::sha256_hex(&b),
            Err(e) => format!("unreadable: {e}"),
        };
        // keyed by the name in the directory, as a drive log records
        // them, so that `config`, `./config` or an absolute path give the
        // same keys
        let files: BTreeMap<String, String> = grip_recorder::config_files(&self.config_dir)
            .into_iter()
            .map(|f| (f.name, hash(&f.path)))
            .collect();
        let canon = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_owned());
        let dir = canon(&self.config_dir);
        let outside: BTreeMap<String, String> = self
            .named_files
            .iter()
            .filter(|p| p.is_file() && !canon(p).starts_with(&dir))
            .map(|p| (p.display().to_string(), hash(p)))
            .collect();
        let mut t = toml::Table::new();
        let s = |v: &str| toml::Value::String(v.to_owned());
        t.insert("grip_version".into(), s(env!("CARGO_PKG_VERSION")));
        t.insert("git_revision".into(), s(grip_recorder::GIT_REV));
        t.insert(
            "command".into(),
            toml::Value::Array(self.command.iter().map(|a| s(a)).collect()),
        );
        t.insert(
            "config_dir".into(),
            s(&self.config_dir.display().to_string()),
        );
        t.insert("vehicle".into(), s(&self.vehicle.0.display().to_string()));
        t.insert("vehicle_described".into(), s(&self.vehicle.1));
        t.insert("scenario".into(), s(&self.scenario));
        t.insert("arte_source".into(), s(&self.arte_source));
        t.insert("seeds".into(), s(&self.seeds));
        let table = |m: BTreeMap<String, String>| {
            toml::Value::Table(m.into_iter().map(|(k, v)| (k, s(&v))).collect())
        };
        t.insert("sha256".into(), table(files));
        if !outside.is_empty() {
            t.insert("sha256_outside_config_dir".into(), table(outside));
        }
        format!(
            "# What the figures in this directory came from: written by `grip sim --out`.\n\
             # grip sim is deterministic: the same build (git_revision), command and files\n\
             # (sha256: the configuration directory's files by their names in it, as a drive's\n\
             # MCAP log records them; sha256_outside_config_dir: the files named on the command\n\
             # line from outside it) give the same figures.\n{}",
            toml::to_string(&t).unwrap_or_else(|e| format!("# not written: {e}\n"))
        )
    }

    /// Writes [`RunRecord::to_toml`] into `dir`.
    pub fn write(&self, dir: &Path) -> anyhow::Result<()> {
        let path = dir.join(FILE);
        std::fs::write(&path, self.to_toml()).with_context(|| format!("writing {}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
    }

    /// The record parses back as TOML and names the vehicle, the command
    /// and a hash of every configuration file, and of a file named from
    /// outside the directory; a change to a file changes its hash.
    #[test]
    fn the_record_names_the_inputs_and_their_hashes() {
        let d = tempfile::tempdir().unwrap();
        let cfg = d.path().join("cfg");
        std::fs::create_dir(&cfg).unwrap();
        for f in ["vehicle.toml", "controllers.toml", "roads.toml"] {
            std::fs::copy(config().join(f), cfg.join(f)).unwrap();
        }
        let own = d.path().join("my-car.toml");
        std::fs::copy(config().join("vehicles/front-mic.toml"), &own).unwrap();
        let rec = |cfg: &Path| RunRecord {
            command: vec!["grip".into(), "sim".into(), "--vehicle".into()],
            config_dir: cfg.to_owned(),
            vehicle: (own.clone(), "M 1400 kg".into()),
            scenario: "paper".into(),
            arte_source: "confusion".into(),
            seeds: "1..=2".into(),
            named_files: vec![own.clone(), cfg.join("vehicle.toml")],
        };
        let t: toml::Table = toml::from_str(&rec(&cfg).to_toml()).unwrap();
        assert_eq!(
            t["vehicle"].as_str(),
            Some(own.display().to_string().as_str())
        );
        assert_eq!(t["command"].as_array().unwrap().len(), 3);
        assert_eq!(t["git_revision"].as_str(), Some(grip_recorder::GIT_REV));
        let sha = t["sha256"].as_table().unwrap();
        assert_eq!(sha.len(), 3, "{sha:?}");
        let key = "controllers.toml";
        let before = sha[key].as_str().unwrap().to_owned();
        assert_eq!(before.len(), 64);
        let outside = t["sha256_outside_config_dir"].as_table().unwrap();
        assert_eq!(outside.len(), 1, "{outside:?}");
        assert!(outside.contains_key(&own.display().to_string()));
        // the same directory named another way: the same keys
        let other = toml::from_str::<toml::Table>(&rec(&cfg.join(".")).to_toml()).unwrap();
        assert_eq!(other["sha256"], t["sha256"]);
        // one byte more in controllers.toml: another hash, the others kept
        let mut text = std::fs::read_to_string(cfg.join("controllers.toml")).unwrap();
        text.push('\n');
        std::fs::write(cfg.join("controllers.toml"), text).unwrap();
        let t2: toml::Table = toml::from_str(&rec(&cfg).to_toml()).unwrap();
        let sha2 = t2["sha256"].as_table().unwrap();
        assert_ne!(sha2[key].as_str().unwrap(), before);
        assert_eq!(sha2["vehicle.toml"], sha["vehicle.toml"]);
    }
}
