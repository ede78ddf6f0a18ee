//! One road-knowledge rule: a drive and a simulation given the same
//! configuration directory hand the controller the same road knowledge
//! (λ_opt, μ_peak, α) for every road the ARTE model can name, including a
//! per-road α override in `[knowledge]` of arte-svc.toml.
//!
//! The drive side is the arte service's own start-up (`prepare`: the table
//! every `RoadEstimate` carries, which tcs-loop hands to the controller);
//! the simulation side is `grip sim`'s `SimSetup` built from the same files.

use std::path::{Path, PathBuf};

use grip_config::ConfigDir;

fn shipped() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../config")
}

/// A copy of the shipped configuration with `snow`'s α overridden.
fn with_override(alpha: f64) -> tempfile::TempDir {
    let t = tempfile::tempdir().unwrap();
    copy_dir(&shipped(), t.path());
    let f = t.path().join("arte-svc.toml");
    let text = std::fs::read_to_string(&f).unwrap();
    let text = text.replace("alpha = {}", &format!("alpha = {{ snow = {alpha} }}"));
    assert!(text.contains("snow = "), "the override was written");
    std::fs::write(&f, text).unwrap();
    t
}

fn copy_dir(from: &Path, to: &Path) {
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let p = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            std::fs::create_dir_all(&p).unwrap();
            copy_dir(&e.path(), &p);
        } else {
            std::fs::copy(e.path(), &p).unwrap();
        }
    }
}

fn check(dir: &Path) -> usize {
    // Drive: the arte service's start-up.
    let prepared = grip_arte_svc::run::prepare(&grip_arte_svc::Options {
        config: grip_io::service::ConfigArgs::in_dir(dir),
        model: None,
        run_for: None,
    })
    .unwrap();
    // Simulation: grip sim's setup from the same directory.
    let cd = ConfigDir::new(dir);
    let roads = cd.roads().unwrap();
    let table = cd.road_table(&roads).unwrap();
    let mut checked = 0;
    for (class, live) in prepared.classes.iter().zip(&prepared.table) {
        let i = roads.index_of(class).unwrap();
        let sim = table.info(i);
        assert_eq!(
            (live.lambda_opt, live.mu_peak, live.alpha),
            (sim.lambda_opt, sim.mu_peak, sim.alpha),
            "{class}"
        );
        // And what the controller is handed from either side is the same.
        let k_sim = table.knowledge(i, 0.9, 0.01);
        let k_live = grip_tcs::RoadInfo {
            lambda_opt: live.lambda_opt,
            mu_peak: live.mu_peak,
            alpha: live.alpha,
        }
        .knowledge(0.9, 0.01);
        assert_eq!(k_sim, k_live, "{class}");
        checked += 1;
    }
    checked
}

#[test]
fn drive_and_simulation_hand_the_controller_the_same_knowledge() {
    assert!(
        check(&shipped()) >= 4,
        "the default model names at least 4 roads"
    );
    let t = with_override(0.8);
    assert!(check(t.path()) >= 4);
    // The override reached both sides.
    let cd = ConfigDir::new(t.path());
    let roads = cd.roads().unwrap();
    let snow = roads.index_of("snow").unwrap();
    assert_eq!(cd.road_table(&roads).unwrap().info(snow).alpha, 0.8);
}
