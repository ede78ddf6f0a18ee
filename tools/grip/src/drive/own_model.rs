//! `grip drive --model FILE`: the drive's services run on a temporary view
//! of the configuration directory in which arte-svc.toml's `model` names
//! FILE, the way arte's configuration gives it its model. Every entry of
//! the directory is linked, not copied, except arte-svc.toml (a copy with
//! the one line changed) and `models/` (links to the directory's models
//! plus a copy of FILE). The recorder attaches the view's files as any
//! configuration's, so the log carries the model it ran and its hash, and
//! `grip replay` of the log runs that model. The view's
//! `.grip-view-paths` (`grip_drive::supervisor::ViewPaths`) names the
//! user's files its paths stand for: a service's `warning: VIEW/vehicle.toml:
//! ...` reaches the user as the warning of their own file, and once.

use std::path::{Path, PathBuf};

use anyhow::Context;
use grip_drive::supervisor::{VIEW_PATHS_FILE, ViewPaths};

/// The view; removed when dropped.
#[derive(Debug)]
pub struct ModelView {
    _tmp: tempfile::TempDir,
    /// The directory the services get as `--config-dir`.
    pub dir: PathBuf,
    /// The model's name in it (`models/NAME`), as arte-svc.toml now gives it.
    pub name: String,
}

/// `text` (an arte-svc.toml) with its top-level `model` set to `value` (a
/// file name relative to the configuration directory), comments and every
/// other line kept; the key is added at the top if the file has none.
pub fn set_model(text: &str, value: &str, comment: &str) -> String {
    let line = format!(
        "model = {}  # {comment}",
        toml::Value::String(value.to_owned())
    );
    let mut out = Vec::new();
    let mut done = false;
    let mut top = true;
    for l in text.lines() {
        let t = l.trim_start();
        if t.starts_with('[') {
            top = false;
        }
        let is_model = top
            && !done
            && t.strip_prefix("model")
                .is_some_and(|r| r.trim_start().starts_with('='));
        if is_model {
            out.push(line.clone());
            done = true;
        } else {
            out.push(l.to_owned());
        }
    }
    if !done {
        out.insert(0, line);
    }
    let mut s = out.join("\n");
    s.push('\n');
    s
}

/// The view of `dir` whose arte runs `model` (see the module's text).
pub fn view(dir: &Path, model: &Path) -> anyhow::Result<ModelView> {
    use std::os::unix::fs::symlink;
    let name = model
        .file_name()
        .with_context(|| format!("--model {}: not a file name", model.display()))?
        .to_string_lossy()
        .into_owned();
    let tmp = tempfile::Builder::new()
        .prefix("grip-drive-config-")
        .tempdir()
        .context("creating a temporary configuration directory")?;
    let to = tmp.path().to_path_buf();
    let entries = std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))?;
    for e in entries {
        let e = e.with_context(|| format!("reading {}", dir.display()))?;
        let file = e.file_name();
        // the view's own VIEW_PATHS_FILE is written below: a user's file
        // of that name is neither linked nor written through
        if file == "arte-svc.toml" || file == "models" || file == VIEW_PATHS_FILE {
            continue;
        }
        symlink(e.path(), to.join(&file))
            .with_context(|| format!("linking {}", e.path().display()))?;
    }
    let models = to.join("models");
    std::fs::create_dir(&models).with_context(|| format!("creating {}", models.display()))?;
    if let Ok(entries) = std::fs::read_dir(dir.join("models")) {
        for e in entries.flatten() {
            if e.file_name().to_string_lossy() != name {
                symlink(e.path(), models.join(e.file_name()))
                    .with_context(|| format!("linking {}", e.path().display()))?;
            }
        }
    }
    std::fs::copy(model, models.join(&name))
        .with_context(|| format!("--model {}: copying it", model.display()))?;
    let own = dir.join("arte-svc.toml");
    let text =
        std::fs::read_to_string(&own).with_context(|| format!("reading {}", own.display()))?;
    let rel = format!("models/{name}");
    let text = set_model(
        &text,
        &rel,
        &format!("grip drive --model {}", model.display()),
    );
    std::fs::write(to.join("arte-svc.toml"), text)
        .with_context(|| format!("writing {}", to.join("arte-svc.toml").display()))?;
    // the user's files the view's paths stand for: the copy of the model
    // for --model's file, every other path for the same one in `dir`
    // (arte-svc.toml for the user's, which it is but for `model`)
    ViewPaths::new(&[
        (models.join(&name), model.to_path_buf()),
        (to.clone(), dir.to_path_buf()),
    ])
    .write(&to)
    .with_context(|| format!("writing {}", to.join(VIEW_PATHS_FILE).display()))?;
    Ok(ModelView {
        _tmp: tmp,
        dir: to,
        name: rel,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The top-level `model` line is replaced, a `model` key of a table
    /// and the comments are kept; a file without one gets it at the top.
    #[test]
    fn set_model_changes_the_one_top_level_line() {
        let text = "# arte\n# model = \"old\" in a comment\nmodel = \"models/default.model\"\n\n[stream]\nhop_s = 0.025\n[x]\nmodel = 3\n";
        let new = set_model(text, "models/my \"1\".model", "grip drive --model m");
        let (a, b): (Vec<_>, Vec<_>) = (text.lines().collect(), new.lines().collect());
        assert_eq!(a.len(), b.len(), "{new}");
        for (k, (a, b)) in a.iter().zip(&b).enumerate() {
            if k == 2 {
                assert!(
                    b.starts_with("model = ") && b.ends_with("  # grip drive --model m"),
                    "{b}"
                );
            } else {
                assert_eq!(a, b);
            }
        }
        let t: toml::Table = new.parse().unwrap();
        assert_eq!(t["model"].as_str(), Some("models/my \"1\".model"));
        assert_eq!(t["x"]["model"].as_integer(), Some(3));
        let new = set_model("[stream]\nhop_s = 0.025\n", "models/m", "c");
        let t: toml::Table = new.parse().unwrap();
        assert_eq!(t["model"].as_str(), Some("models/m"));
        assert_eq!(t["stream"]["hop_s"].as_float(), Some(0.025));
    }

    /// The repository's configuration seen with another model: arte's
    /// start-up (its own code) loads that model from it, everything else
    /// reads as in the directory, the directory itself is untouched.
    #[test]
    fn the_view_gives_arte_the_model_and_keeps_the_rest() {
        let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let before = std::fs::read(cfg.join("arte-svc.toml")).unwrap();
        let d = tempfile::tempdir().unwrap();
        let mine = d.path().join("mine.model");
        std::fs::copy(cfg.join("models/default.model"), &mine).unwrap();
        let v = view(&cfg, &mine).unwrap();
        assert_eq!(v.name, "models/mine.model");
        let p = grip_arte_svc::prepare(&grip_arte_svc::Options {
            config: grip_io::service::ConfigArgs::in_dir(&v.dir),
            model: None,
            run_for: None,
        })
        .unwrap();
        assert_eq!(p.model_path, v.dir.join("models/mine.model"));
        assert!(v.dir.join("models/default.model").is_file());
        assert_eq!(
            std::fs::read(v.dir.join("roads.toml")).unwrap(),
            std::fs::read(cfg.join("roads.toml")).unwrap()
        );
        assert!(v.dir.join("scenarios/paper.toml").is_file());
        assert_eq!(std::fs::read(cfg.join("arte-svc.toml")).unwrap(), before);
        // the view's paths said as the user's files
        let paths = ViewPaths::read(&v.dir);
        let said = |p: &Path| paths.map(&p.display().to_string());
        assert_eq!(
            said(&v.dir.join("vehicle.toml")),
            cfg.join("vehicle.toml").display().to_string()
        );
        assert_eq!(
            said(&v.dir.join("models/mine.model")),
            mine.display().to_string()
        );
        let dir = v.dir.clone();
        drop(v);
        assert!(!dir.exists());
    }

    /// A `.grip-view-paths` in the user's directory (left there by
    /// anything) is neither linked into the view nor written through: the
    /// user's file keeps its text, the view's file is the view's own.
    #[test]
    fn a_user_s_view_paths_file_is_left_untouched() {
        let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let d = tempfile::tempdir().unwrap();
        let user = d.path().join("cfg");
        std::fs::create_dir(&user).unwrap();
        std::fs::copy(cfg.join("arte-svc.toml"), user.join("arte-svc.toml")).unwrap();
        std::fs::copy(cfg.join("vehicle.toml"), user.join("vehicle.toml")).unwrap();
        let theirs = user.join(VIEW_PATHS_FILE);
        std::fs::write(&theirs, "# user's own file\n").unwrap();
        let mine = d.path().join("mine.model");
        std::fs::copy(cfg.join("models/default.model"), &mine).unwrap();
        let v = view(&user, &mine).unwrap();
        assert_eq!(
            std::fs::read_to_string(&theirs).unwrap(),
            "# user's own file\n"
        );
        let own = v.dir.join(VIEW_PATHS_FILE);
        assert!(!own.symlink_metadata().unwrap().is_symlink());
        let paths = ViewPaths::read(&v.dir);
        assert_eq!(
            paths.map(&v.dir.join("vehicle.toml").display().to_string()),
            user.join("vehicle.toml").display().to_string()
        );
        // a link of that name in a view is replaced, not written through
        std::fs::remove_file(&own).unwrap();
        std::os::unix::fs::symlink(&theirs, &own).unwrap();
        ViewPaths::new(&[(v.dir.clone(), user.clone())])
            .write(&v.dir)
            .unwrap();
        assert_eq!(
            std::fs::read_to_string(&theirs).unwrap(),
            "# user's own file\n"
        );
        assert!(!own.symlink_metadata().unwrap().is_symlink());
    }
}
