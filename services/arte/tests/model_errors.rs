//! A model file that cannot be read, or is not a model, names what named
//! it: `arte-svc.toml`'s field `model` (the file and the field), or the
//! option `--model`; the service refuses it as a configuration (exit 78).
//! Until 2026-12-07 the error named the model's path only, not the file
//! and field that gave it.

mod common;

use std::path::{Path, PathBuf};

use common::config_dir;
use grip_arte_svc::{ArteError, ModelSource, Options, prepare};
use grip_io::service::{ConfigArgs, EXIT_CONFIG, ServiceError};

/// Options for the configuration file `cfg` (its directory is `dir`) and
/// the `--model` override `model`.
fn opts(dir: &Path, cfg: &Path, model: Option<PathBuf>) -> Options {
    Options {
        config: ConfigArgs {
            config_dir: dir.to_owned(),
            config: Some(cfg.to_owned()),
        },
        model,
        run_for: None,
    }
}

#[test]
fn a_model_that_cannot_be_read_names_the_config_field_or_the_option() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path();
    std::fs::copy(config_dir().join("roads.toml"), dir.join("roads.toml")).unwrap();
    let cfg = dir.join("arte-svc.toml");
    std::fs::create_dir(dir.join("models")).unwrap();
    std::fs::write(dir.join("models/text.model"), b"hello\nworld").unwrap();

    // the configuration's `model`: a missing file, a directory, not a model
    for (model, reason) in [
        ("models/none.model", "cannot read: "),
        ("models", "cannot read: "),
        ("models/text.model", "not a grip ARTE model"),
    ] {
        std::fs::write(&cfg, format!("model = {model:?}\n")).unwrap();
        let e = prepare(&opts(dir, &cfg, None)).unwrap_err();
        assert!(
            matches!(
                &e,
                ArteError::ModelIo {
                    from: ModelSource::Config { field: "model", .. },
                    ..
                } | ArteError::Model {
                    from: ModelSource::Config { field: "model", .. },
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.is_config(), "{e}");
        let msg = e.to_string();
        let want = format!(
            "{}: field `model`: model file {}: ",
            cfg.display(),
            dir.join(model).display()
        );
        assert!(
            msg.starts_with(&want) && msg.contains(reason),
            "{model}: {msg}\nwanted it to begin {want}"
        );
    }

    // `--model` (relative to the working directory, not the config's):
    // names the option, not the configuration's field
    std::fs::write(&cfg, "model = \"models/default.model\"\n").unwrap();
    let missing = dir.join("gone.model");
    let e = prepare(&opts(dir, &cfg, Some(missing.clone()))).unwrap_err();
    assert!(e.is_config(), "{e}");
    let msg = e.to_string();
    assert!(
        msg.starts_with(&format!(
            "option `--model`: model file {}: cannot read: ",
            missing.display()
        )),
        "{msg}"
    );
    assert!(!msg.contains("arte-svc.toml"), "{msg}");

    // the service: one `error:` line naming the file and field, exit 78
    std::fs::write(&cfg, "model = \"models/none.model\"\n").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_arte"))
        .arg("--config-dir")
        .arg(dir)
        .arg("--config")
        .arg(&cfg)
        .env(
            grip_io::ipc::INSTANCE_ENV,
            format!("arte_model_errors_{}", std::process::id()),
        )
        .env_remove("NOTIFY_SOCKET")
        .env_remove("INVOCATION_ID")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(i32::from(EXIT_CONFIG)), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "error: {}: field `model`: model file {}: cannot read: ",
            cfg.display(),
            dir.join("models/none.model").display()
        )),
        "{stderr}"
    );
}
