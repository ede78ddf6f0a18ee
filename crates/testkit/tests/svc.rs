//! The service-test helpers: config copies, the `[rt]` cut, a one-shot run.

use grip_testkit::svc::{copy_config, run, shipped_config_dir, strip_rt};

#[test]
fn copies_files_and_folders_and_cuts_rt() {
    let t = copy_config(&["tcs-loop.toml", "roads", "scenarios/paper.toml"]);
    let n_roads = std::fs::read_dir(shipped_config_dir().join("roads"))
        .unwrap()
        .count();
    assert!(n_roads > 0);
    assert_eq!(
        std::fs::read_dir(t.path().join("roads")).unwrap().count(),
        n_roads
    );
    assert!(t.path().join("scenarios/paper.toml").is_file());
    let p = t.path().join("tcs-loop.toml");
    assert!(std::fs::read_to_string(&p).unwrap().contains("[rt]"));
    strip_rt(&p);
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(!text.contains("[rt]") && !text.is_empty(), "{text}");
}

#[test]
fn run_reports_exit_code_and_stderr() {
    let (code, err) = run("sh", "testkit", &["-c", "echo oops >&2; exit 3"]);
    assert_eq!((code, err.as_str()), (3, "oops\n"));
}
