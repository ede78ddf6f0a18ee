//! The one error type of grip's configuration loading, and the TOML helper
//! every loader (including `controllers.rs`) goes through.

use std::fmt;
use std::path::{Path, PathBuf};

use grip_physics::InvalidField;
use serde::de::DeserializeOwned;

/// A configuration problem: which file, which field, and why.
///
/// Display: ``config/vehicle.toml: field `vehicle.mass`: must be > 0 (got -5)``;
/// when no single field is to blame (unreadable file, TOML syntax error) the
/// field part is left out. Parse errors carry the line in the reason
/// (`line 3: unknown field ...`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub struct ConfigError {
    /// The file at fault (as given to the loader).
    pub file: PathBuf,
    /// Dotted key path of the offending field (`vehicle.mass`,
    /// `road[3].c1`, `segment[0].road`), or empty.
    pub field: String,
    /// What is wrong, with the offending value where there is one.
    pub reason: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.field.is_empty() {
            write!(f, "{}: {}", self.file.display(), self.reason)
        } else {
            write!(
                f,
                "{}: field `{}`: {}",
                self.file.display(),
                self.field,
                self.reason
            )
        }
    }
}

impl ConfigError {
    /// A new error.
    pub fn new(
        file: impl Into<PathBuf>,
        field: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        Self {
            file: file.into(),
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// From a validation error of a struct loaded from `file` at TOML table
    /// `prefix` (e.g. `vehicle`; empty for the top level).
    pub fn invalid(file: &Path, prefix: &str, e: InvalidField) -> Self {
        let e = e.prefixed(prefix);
        Self::new(file, e.field, e.reason)
    }

    /// The file could not be read.
    pub fn io(file: &Path, e: &std::io::Error) -> Self {
        // a file missing because its whole directory is: say so (a
        // mistyped --config-dir, or a command run where there is no
        // ./config), not only that the file is
        let dir_missing = (e.kind() == std::io::ErrorKind::NotFound)
            .then(|| file.parent())
            .flatten()
            .filter(|d| !d.as_os_str().is_empty() && !d.exists());
        match dir_missing {
            Some(d) => Self::new(
                file,
                "",
                format!(
                    "cannot read: {e}: the directory {} does not exist (if it is meant as the configuration directory: that is chosen with --config-dir, default ./config{})",
                    d.display(),
                    if Path::new(INSTALLED).is_dir() {
                        format!("; the installed package's is {INSTALLED}")
                    } else {
                        String::new()
                    }
                ),
            ),
            None => Self::new(file, "", format!("cannot read: {e}")),
        }
    }
}

/// Where the Debian package installs the configuration (`tools/package`).
const INSTALLED: &str = "/etc/grip";

/// Read `file` to a string, mapping I/O errors to [`ConfigError`].
pub fn read_file(file: &Path) -> Result<String, ConfigError> {
    std::fs::read_to_string(file).map_err(|e| ConfigError::io(file, &e))
}

/// 1-based line of byte offset `pos` in `text`.
pub fn line_of(text: &str, pos: usize) -> usize {
    let pos = pos.min(text.len());
    text.as_bytes()[..pos]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Deserialize `text` (the contents of `file`) into `T`, mapping every TOML
/// syntax or type error (unknown field, wrong type, missing field) to a
/// [`ConfigError`] with the key path as `field` and `line N: ...` in the reason.
/// Values are not range-checked here: call the struct's `validate` after.
pub fn parse_toml<T: DeserializeOwned>(file: &Path, text: &str) -> Result<T, ConfigError> {
    let de = toml::Deserializer::parse(text).map_err(|e| {
        let line = e
            .span()
            .map(|s| format!("line {}: ", line_of(text, s.start)))
            .unwrap_or_default();
        ConfigError::new(
            file,
            "",
            format!("{line}TOML syntax error: {}", e.message().trim()),
        )
    })?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        let field = if path == "." { String::new() } else { path };
        let inner = e.into_inner();
        let line = inner
            .span()
            .map(|s| format!("line {}: ", line_of(text, s.start)))
            .unwrap_or_default();
        ConfigError::new(file, field, format!("{line}{}", inner.message().trim()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Inner {
        a: f64,
        #[serde(default)]
        b: Vec<f64>,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Outer {
        inner: Inner,
        #[serde(default)]
        item: Vec<Inner>,
    }

    fn err(text: &str) -> ConfigError {
        parse_toml::<Outer>(Path::new("x.toml"), text).unwrap_err()
    }

    #[test]
    fn unknown_field_names_path_and_line() {
        let e = err("[inner]\na = 1.0\nc = 2\n");
        assert_eq!(e.field, "inner.c", "{e}");
        assert!(e.reason.starts_with("line 3: unknown field `c`"), "{e}");
    }

    #[test]
    fn wrong_type_names_path_and_line() {
        let e = err("[inner]\na = \"fast\"\n");
        assert_eq!(e.field, "inner.a", "{e}");
        assert!(
            e.reason.starts_with("line 2:") && e.reason.contains("string"),
            "{e}"
        );
        let e = err("[inner]\na = 1.0\n[[item]]\na = 1.0\n[[item]]\na = 2.0\nb = [1.0, \"x\"]\n");
        assert_eq!(e.field, "item[1].b[1]", "{e}");
        assert!(e.reason.starts_with("line 7:"), "{e}");
    }

    #[test]
    fn missing_field_and_syntax_error() {
        let e = err("[inner]\n");
        assert!(e.reason.contains("missing field `a`"), "{e}");
        let e = err("[inner\na = 1\n");
        assert_eq!(e.field, "");
        assert!(e.reason.starts_with("line 1: TOML syntax error"), "{e}");
    }

    #[test]
    fn display_shape() {
        let e = ConfigError::new(
            "config/vehicle.toml",
            "vehicle.mass",
            "must be > 0 (got -5)",
        );
        assert_eq!(
            e.to_string(),
            "config/vehicle.toml: field `vehicle.mass`: must be > 0 (got -5)"
        );
        let e = ConfigError::new("a.toml", "", "cannot read: gone");
        assert_eq!(e.to_string(), "a.toml: cannot read: gone");
        // a file whose directory is missing says so; one missing from a
        // directory that exists does not
        let d = tempfile::tempdir().unwrap();
        let gone = d.path().join("nope").join("vehicle.toml");
        let e = read_file(&gone).unwrap_err().to_string();
        assert!(
            e.contains("cannot read: ")
                && e.contains(&format!(
                    "the directory {} does not exist",
                    d.path().join("nope").display()
                ))
                && e.contains("--config-dir"),
            "{e}"
        );
        let e = read_file(&d.path().join("vehicle.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            !e.contains("does not exist") && !e.contains("--config-dir"),
            "{e}"
        );
    }
}
