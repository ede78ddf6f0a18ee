//! `config/controllers.toml` -> [`ControllersConfig`] (sections `[mfc]`,
//! `[src]`, `[mtte]`, `[arte]`, `[loop]`, optional `[preview]`, `[fusion]`;
//! every field required but those added after the first drive logs, which
//! take the rule from before them and are named by [`old_rule_warning`];
//! unknown fields rejected, ranges checked by `ControllersConfig::validate`).
//!
//! The parameter structs live in `grip-tcs` (the controllers own their
//! parameters); this module only reads and validates the file.

use std::path::Path;

pub use grip_tcs::params::{
    ArteUse, ControllersConfig, LoopParams, MfcParams, MtteParams, SrcParams,
};

use crate::{ConfigError, parse_toml, read_file};

/// Read, parse and validate the controllers file at `path`; when the file
/// leaves out a key that then takes the rule from before it existed rather
/// than the shipped value, says so on stderr ([`old_rule_warning`]).
pub fn load_controllers(path: impl AsRef<Path>) -> Result<ControllersConfig, ConfigError> {
    let path = path.as_ref();
    let text = read_file(path)?;
    let config = parse_controllers(path, &text)?;
    if let Some(w) = old_rule_warning(path, &text, &config) {
        crate::warn_once(&w);
    }
    Ok(config)
}

/// Keys that may be left out of a section that is present, and then take
/// the rule from before the key existed (so that older drive logs' attached
/// files still load and replay as recorded), not the shipped value: (section,
/// key, the value a file without it takes, the shipped value).
fn old_rule_keys(c: &ControllersConfig) -> [(&'static str, &'static str, String); 10] {
    let opt = |v: Option<f64>| v.map_or("none".to_owned(), |v| v.to_string());
    [
        ("src", "v_launch", c.src.v_launch.to_string()),
        ("mtte", "spin_share", c.mtte.spin_share.to_string()),
        (
            "preview",
            "approach_floor",
            c.preview.approach_floor.to_string(),
        ),
        ("preview", "approach_dip", opt(c.preview.approach_dip)),
        ("preview", "approach_hold", opt(c.preview.approach_hold)),
        (
            "preview",
            "recover_landing",
            c.preview.recover_landing.to_string(),
        ),
        ("preview", "spin_dv_min", c.preview.spin_dv_min.to_string()),
        (
            "preview",
            "standstill_mps",
            c.preview.standstill_mps.to_string(),
        ),
        ("fusion", "tau_slip_s", c.fusion.tau_slip_s.to_string()),
        (
            "fusion",
            "min_speed_evidence",
            c.fusion.min_speed_evidence.to_string(),
        ),
    ]
}

/// The keys `text` (already parsed as `config`) leaves out of a section it
/// has, which therefore take the rule from before they existed: `(section.key,
/// taken, shipped)`; a key whose old rule is the shipped value is not named.
pub fn old_rule_keys_left_out(
    text: &str,
    config: &ControllersConfig,
) -> Vec<(String, String, String)> {
    let Ok(table) = text.parse::<toml::Table>() else {
        return Vec::new();
    };
    let shipped = old_rule_keys(&ControllersConfig::default());
    old_rule_keys(config)
        .into_iter()
        .zip(shipped)
        .filter(|((section, key, taken), (_, _, ship))| {
            table
                .get(*section)
                .and_then(toml::Value::as_table)
                .is_some_and(|t| !t.contains_key(*key))
                && taken != ship
        })
        .map(|((section, key, taken), (_, _, ship))| (format!("{section}.{key}"), taken, ship))
        .collect()
}

/// `warning: FILE: leaves out preview.approach_floor, ...: they take the
/// rule from before each existed (approach_floor = 0, ...), not the shipped
/// values (approach_floor = 0.7, ...); ...`. `None` when nothing is left out
/// that matters (the shipped file, a file without `[preview]` at all, whose
/// table then takes the shipped values whole).
pub fn old_rule_warning(file: &Path, text: &str, config: &ControllersConfig) -> Option<String> {
    let left = old_rule_keys_left_out(text, config);
    if left.is_empty() {
        return None;
    }
    let names: Vec<&str> = left.iter().map(|(k, _, _)| k.as_str()).collect();
    let taken: Vec<String> = left.iter().map(|(k, t, _)| format!("{k} = {t}")).collect();
    let shipped: Vec<String> = left.iter().map(|(k, _, s)| format!("{k} = {s}")).collect();
    Some(format!(
        "warning: {}: leaves out {}: a key left out of its section takes the rule from before it existed ({}), \
         not the shipped value ({}), so that older drive logs replay as recorded; set {} in the file to run \
         as shipped (config/controllers.toml documents each)",
        file.display(),
        names.join(", "),
        taken.join(", "),
        shipped.join(", "),
        if names.len() == 1 { "it" } else { "each" },
    ))
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
    fn keys_left_out_that_take_the_old_rule_are_named() {
        let text = std::fs::read_to_string(shipped()).unwrap();
        let f = Path::new("my-controllers.toml");
        let c = parse_controllers(f, &text).unwrap();
        assert_eq!(old_rule_warning(f, &text, &c), None, "the shipped file");
        // a hand-written [preview] without two of the later keys
        for key in ["approach_floor = 0.7\n", "spin_dv_min = 0.15\n"] {
            assert!(text.contains(key), "{key}");
        }
        let partial = text
            .replace("approach_floor = 0.7\n", "")
            .replace("spin_dv_min = 0.15\n", "");
        let c = parse_controllers(f, &partial).unwrap();
        assert_eq!(c.preview.approach_floor, 0.0);
        let w = old_rule_warning(f, &partial, &c).unwrap();
        for says in [
            "my-controllers.toml",
            "leaves out preview.approach_floor, preview.spin_dv_min",
            "preview.approach_floor = 0, preview.spin_dv_min = 0",
            "preview.approach_floor = 0.7, preview.spin_dv_min = 0.15",
        ] {
            assert!(w.contains(says), "{says}: {w}");
        }
        // without the [preview] table at all: the shipped values, nothing to say
        let start = text.find("\n[preview]\n").unwrap() + 1;
        // [preview] and its [preview.src], up to [fusion]
        let end = text.find("\n[fusion]").unwrap() + 1;
        let without = format!("{}{}", &text[..start], &text[end..]);
        assert!(
            !without.lines().any(|l| l.starts_with("approach_floor")),
            "{without}"
        );
        let c = parse_controllers(f, &without).unwrap();
        assert_eq!(c.preview, ControllersConfig::default().preview);
        assert_eq!(old_rule_warning(f, &without, &c), None);
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
