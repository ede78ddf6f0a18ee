//! `config/controllers.toml` -> [`ControllersConfig`] (sections `[mfc]`,
//! `[src]`, `[mtte]`, `[arte]`, `[loop]`; every field required, unknown
//! fields rejected, ranges checked by `ControllersConfig::validate`).
//!
//! The parameter structs live in `grip-tcs` (the controllers own their
//! parameters); this module only reads and validates the file.

use std::path::Path;

pub use grip_tcs::params::{
    ArteUse, ControllersConfig, LoopParams, MfcParams, MtteParams, SrcParams,
};

use crate::{ConfigError, parse_toml, read_file};

/// Read, parse and validate the controllers file at `path`.
pub fn load_controllers(path: impl AsRef<Path>) -> Result<ControllersConfig, ConfigError> {
    let path = path.as_ref();
    let text = read_file(path)?;
    parse_controllers(path, &text)
}

/// Parse and validate controllers TOML `text` (the contents of `file`).
pub fn parse_controllers(file: &Path, text: &str) -> Result<ControllersConfig, ConfigError> {
    let config: ControllersConfig = parse_toml(file, text)?;
    config
        .validate()
        .map_err(|e| ConfigError::invalid(file, "", e))?;
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn shipped() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/controllers.toml")
    }

    #[test]
    fn the_shipped_file_loads_and_equals_the_documented_defaults() {
        let c = load_controllers(shipped()).unwrap();
        assert_eq!(c, ControllersConfig::default());
        assert_eq!(c.loop_.rate_hz, 1000.0);
    }

    #[test]
    fn a_file_without_the_launch_keys_loads_as_the_papers_law() {
        // Files (and drive logs) from before `[src] v_launch` and `[mtte]
        // spin_share`: both 0, the controllers as they were.
        let text = std::fs::read_to_string(shipped()).unwrap();
        let old = text
            .replace("v_launch = 2.0\n", "")
            .replace("spin_share = 0.1\n", "");
        let c = parse_controllers(Path::new("controllers.toml"), &old).unwrap();
        assert_eq!(c.src.v_launch, 0.0);
        assert_eq!(c.mtte.spin_share, 0.0);
        let shipped = ControllersConfig::default();
        assert_eq!(shipped.src.v_launch, 2.0);
        assert_eq!(shipped.mtte.spin_share, 0.1);
    }

    #[test]
    fn errors_name_file_field_and_reason() {
        let text = std::fs::read_to_string(shipped()).unwrap();
        let f = Path::new("controllers.toml");
        // The shipped file with `from` replaced by `to`, which must be refused.
        let refused = |from: &str, to: &str| {
            assert!(text.contains(from), "{from}");
            parse_controllers(f, &text.replace(from, to)).unwrap_err()
        };
        // (replace, by, field named, reason contains)
        for (from, to, field, reason) in [
            ("tau_hpf = 1.0", "tau_hpf = -1.0", "mfc.tau_hpf", "> 0"),
            (
                "alpha = 0.9",
                "alpha = 0.9\nbeta = 1.0",
                "mtte.beta",
                "unknown field",
            ),
            (
                "tau_noise = 0.004",
                "tau_noise = 0.5",
                "mfc.tau_noise",
                "[0, 0.1]",
            ),
            (
                "v_launch = 2.0",
                "v_launch = -1.0",
                "src.v_launch",
                "[0, 10]",
            ),
            (
                "spin_share = 0.1",
                "spin_share = 2.0",
                "mtte.spin_share",
                "[0, 1]",
            ),
            ("rate_hz = 1000.0", "rate_hz = nan", "loop.rate_hz", ""),
        ] {
            let e = refused(from, to);
            assert_eq!(e.field, field, "{e}");
            assert!(e.reason.contains(reason), "{e}");
            assert_eq!(e.file, f);
        }
        for key in ["kp = 6.0\n", "tau_noise = 0.004\n"] {
            let e = refused(key, "");
            let name = key.split(' ').next().unwrap();
            assert!(e.reason.contains(&format!("missing field `{name}`")), "{e}");
        }

        let e = load_controllers("/nonexistent/controllers.toml").unwrap_err();
        assert!(e.reason.contains("cannot read"), "{e}");
    }
}
