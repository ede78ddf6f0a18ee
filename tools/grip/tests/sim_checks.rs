//! `grip sim` refuses what it cannot honour before running anything, and
//! says what it could not avoid: an unusable `--out` and the files of an
//! earlier run there, a demand above the motor's limit, a scenario too long
//! to hold, a plant sub-step the plant would not take, acoustic options
//! without the acoustic source, an `--entry-plot` with nothing to draw; a
//! longer random run that stays on its roads, a run past the end of its
//! roads, what lies after a scenario's end (a time segment, a demand's
//! change, distance segments never reached) and the confusion source's
//! pass-through roads in the report.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{config_dir, grip, run_ok};

fn sim(args: &[&str]) -> Output {
    grip().arg("sim").args(args).output().unwrap()
}

/// `grip sim` of MTTE alone on `seeds` seeds of `scenario` (a name or a file).
fn mtte_on(seeds: u32, scenario: impl AsRef<std::ffi::OsStr>) -> Output {
    grip()
        .args([
            "sim",
            "--seeds",
            &seeds.to_string(),
            "--variants",
            "mtte",
            "--scenario",
        ])
        .arg(scenario)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A refusal: exit code 1 (not a signal, not success) and stderr.
fn refused(o: &Output) -> String {
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    stderr(o)
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// `config/scenarios/paper.toml` with `key = value` changed, in `dir`.
fn paper_with(dir: &Path, key: &str, value: &str) -> PathBuf {
    let text = std::fs::read_to_string(config_dir().join("scenarios/paper.toml")).unwrap();
    let mut done = false;
    let out: Vec<String> = text
        .lines()
        .map(|l| {
            if !done && l.split('=').next().map(str::trim) == Some(key) {
                done = true;
                format!("{key} = {value}")
            } else {
                l.to_owned()
            }
        })
        .collect();
    assert!(done, "paper.toml has no {key}");
    let p = dir.join(format!("paper-{key}.toml"));
    std::fs::write(&p, out.join("\n")).unwrap();
    p
}

/// The column `name` of summary.csv, per row, with the row's variant.
fn column(dir: &Path, name: &str) -> Vec<(String, f64)> {
    let text = std::fs::read_to_string(dir.join("summary.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let i = head.iter().position(|c| *c == name).unwrap();
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].to_owned(), f[i].parse().unwrap())
        })
        .collect()
}

#[test]
fn out_is_checked_first_and_an_earlier_runs_files_are_removed() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("out");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("notes.txt"), "mine").unwrap();
    std::fs::write(dir.join("trace_of_mine.csv"), "mine").unwrap();
    run_ok(
        grip()
            .args([
                "sim",
                "--scenario",
                "random",
                "--seeds",
                "2",
                "--all-traces",
            ])
            .args(["--variants", "mfc,mfc-arte", "--ideal", "1,0.8", "--out"])
            .arg(&dir),
    );
    assert!(dir.join("scenarios.csv").exists() && dir.join("trace_mfc_seed2.csv").exists());
    assert!(dir.join("ideal.csv").exists());
    // run.toml: what the figures came from (the random recipe, the
    // vehicle, every configuration file's hash), and the report names
    // the vehicle
    let run: toml::Table =
        toml::from_str(&std::fs::read_to_string(dir.join("run.toml")).unwrap()).unwrap();
    assert!(
        run["scenario"].as_str().unwrap().starts_with("random: "),
        "{run:?}"
    );
    assert_eq!(run["seeds"].as_str(), Some("1-2"));
    assert!(
        run["vehicle"].as_str().unwrap().ends_with("vehicle.toml"),
        "{run:?}"
    );
    let sha = run["sha256"].as_table().unwrap();
    assert!(
        sha.keys().any(|k| k.ends_with("controllers.toml")),
        "{sha:?}"
    );
    let table = std::fs::read_to_string(dir.join("table.txt")).unwrap();
    assert!(
        table.contains("no power limit (power_max not set), microphone at the driven wheel"),
        "{table}"
    );
    // the paper's Table V is beside the reference scenario only
    assert!(!table.contains("Table V"), "{table}");
    let o = grip()
        .args([
            "sim",
            "--scenario",
            "paper",
            "--seeds",
            "1",
            "--variants",
            "mfc,mfc-arte",
        ])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{o:?}");
    let err = stderr(&o);
    assert!(err.contains("removed 12 files"), "{err}");
    let table = std::fs::read_to_string(dir.join("table.txt")).unwrap();
    assert!(table.contains("beside the paper's Table V"), "{table}");
    assert_eq!(
        files(&dir),
        [
            "arte_inloop.csv",
            "fig10_without_arte.png",
            "fig11_with_arte.png",
            "notes.txt",
            "run.toml",
            "summary.csv",
            "table.txt",
            "trace_mfc-arte_seed1.csv",
            "trace_mfc_seed1.csv",
            "trace_of_mine.csv",
        ]
    );
    // A sweep leaves its own files only (and the user's).
    run_ok(
        grip()
            .args(["sim", "--seeds", "1", "--variants", "mfc,mfc-arte"])
            .args(["--sweep", "preview.cap_share=0.9", "--out"])
            .arg(&dir),
    );
    assert_eq!(
        files(&dir),
        [
            "notes.txt",
            "run.toml",
            "sweep.csv",
            "sweep.png",
            "sweep.txt",
            "trace_of_mine.csv"
        ]
    );
    // MFC on the reference scenario ends up to 0.26 m past its 12.71 m
    // of road, within the tolerance (its last road, snow, goes on): no note.
    let report = std::fs::read_to_string(dir.join("sweep.txt")).unwrap();
    assert!(
        !report.contains("went past the end of the scenario's roads"),
        "{report}"
    );
    // A file in the way is refused before any run.
    let file = tmp.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let err = refused(&sim(&["--seeds", "1", "--out", file.to_str().unwrap()]));
    assert!(
        err.contains("a-file") && err.contains("not a directory"),
        "{err}"
    );
    assert!(!err.contains("scenario `paper`"), "ran first: {err}");
    assert_eq!(std::fs::read(&file).unwrap(), b"x");
}

#[test]
fn a_demand_above_the_motor_limit_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let p = paper_with(tmp.path(), "torque", "1500.0");
    let err = refused(&sim(&["--seeds", "1", "--scenario", p.to_str().unwrap()]));
    for says in [
        "paper-torque.toml",
        "demand.torque",
        "1500",
        "torque_max = 1000",
        "vehicle.toml",
    ] {
        assert!(err.contains(says), "{says}: {err}");
    }
    let err = refused(&sim(&[
        "--seeds",
        "1",
        "--scenario",
        "random",
        "--random",
        "torque=1e4",
    ]));
    assert!(
        err.contains("demand.torque") && err.contains("10000"),
        "{err}"
    );
}

#[test]
fn a_scenario_too_long_to_hold_is_refused_naming_its_duration() {
    let tmp = tempfile::tempdir().unwrap();
    let p = paper_with(tmp.path(), "duration", "1e6");
    let p = p.to_str().unwrap();
    let out = tmp.path().join("out");
    // Traces of the first seed (written with --out), and ARTE's in-loop
    // record even without --out.
    for args in [
        vec!["--variants", "mfc", "--out", out.to_str().unwrap()],
        vec!["--variants", "mfc-arte", "--threads", "1"],
    ] {
        let mut a = vec!["--seeds", "1", "--scenario", p];
        a.extend(args.iter().copied());
        let err = refused(&sim(&a));
        for says in [
            "paper-duration.toml",
            "`duration`",
            "1000000000 controller cycles",
            " GB",
        ] {
            assert!(err.contains(says), "{args:?}: {says}: {err}");
        }
    }
}

#[test]
fn a_sub_step_the_plant_would_not_take_is_refused() {
    let err = refused(&sim(&["--seeds", "1", "--max-substep", "1e-9"]));
    assert!(
        err.contains("--max-substep") && err.contains("100000 sub-steps") && err.contains("1e-8"),
        "{err}"
    );
}

#[test]
fn acoustic_options_need_the_acoustic_source() {
    for (args, names) in [
        (vec!["--snr-db", "-20"], "--snr-db"),
        (vec!["--model", "/nonexistent"], "--model"),
        (vec!["--sound-as", "foo=bar"], "--sound-as"),
        (vec!["--arte", "perfect", "--snr-db", "off"], "--snr-db"),
    ] {
        let mut a = vec!["--seeds", "1", "--variants", "mfc"];
        a.extend(args.iter().copied());
        let err = refused(&sim(&a));
        assert!(
            err.contains(names) && err.contains("--arte acoustic"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn an_entry_plot_with_nothing_to_draw_is_refused_before_running() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let out = out.to_str().unwrap();
    let err = refused(&sim(&["--seeds", "1", "--entry-plot", "ice", "--out", out]));
    assert!(err.contains("ice") && err.contains("has no ice"), "{err}");
    assert!(
        !err.contains("scenario `paper` (config"),
        "ran first: {err}"
    );
    let err = refused(&sim(&[
        "--seeds",
        "1",
        "--variants",
        "mfc,src",
        "--entry-plot",
        "snow",
        "--out",
        out,
    ]));
    assert!(err.contains("--variants mfc,src has none"), "{err}");
    assert!(!Path::new(out).join("summary.csv").exists());
}

#[test]
fn a_longer_random_run_stays_on_its_roads() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = grip()
        .args(["sim", "--scenario", "random", "--random", "duration=10"])
        .args(["--seeds", "1", "--variants", "mfc", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{o:?}");
    assert!(!stderr(&o).contains("past the end"), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("scenarios.csv")).unwrap();
    let span: f64 = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(3).unwrap().parse::<f64>().unwrap())
        .sum();
    let (_, distance) = column(&out, "distance")[0].clone();
    // MFC goes from 10 to about 100 km/h, about 155 m.
    assert!(
        distance > 100.0 && distance < span,
        "{distance} m of {span} m"
    );
}

#[test]
fn a_run_past_the_end_of_its_roads_is_warned_about() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = grip()
        .args(["sim", "--scenario", "random", "--random", "cover_m=5"])
        .args(["--seed0", "7", "--seeds", "1", "--variants", "src", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{o:?}");
    let err = stderr(&o);
    assert!(
        err.contains("warning: SRC, seed 7: went up to") && err.contains("past the end"),
        "{err}"
    );
    let table = std::fs::read_to_string(out.join("table.txt")).unwrap();
    assert!(
        table.contains("Note: 1 of 1 runs went past the end of the scenario's roads"),
        "{table}"
    );
}

#[test]
fn the_report_says_which_roads_the_confusion_source_passes_through() {
    let text = run_ok(grip().args([
        "sim",
        "--scenario",
        "random",
        "--seed0",
        "1000",
        "--seeds",
        "3",
        "--variants",
        "mtte-arte",
    ]));
    let note = text
        .lines()
        .find(|l| l.contains("pass through as the true road"))
        .unwrap_or_else(|| panic!("no pass-through note: {text}"));
    assert!(
        note.contains("wet_asphalt") && note.contains("wet_stone") && note.contains("0.858"),
        "{note}"
    );
    assert!(note.contains(" % of the time"), "{note}");
    // The reference scenario has no such road.
    let text = run_ok(grip().args(["sim", "--seeds", "1", "--variants", "mtte-arte"]));
    assert!(!text.contains("pass through"), "{text}");
}

/// A scenario of `body` (after a `name`, `v0_kmh` and a constant 250 N m
/// demand unless `body` has its own `[demand]`) in `dir` as `file`.
fn scenario_file(dir: &Path, file: &str, body: &str) -> PathBuf {
    let demand = if body.contains("[demand]") {
        ""
    } else {
        "[demand]\nkind = \"constant\"\ntorque = 250.0\n"
    };
    let p = dir.join(file);
    std::fs::write(
        &p,
        format!("name = \"mine\"\nv0_kmh = 20.0\n{body}{demand}"),
    )
    .unwrap();
    p
}

const LATE_WORDS: [&str; 4] = [
    "never driven",
    "never reached",
    "at or after the end",
    "ended before reaching",
];

/// A user's trial: what lies after a scenario's end is said, once per
/// command (not per seed), naming the file, the segment and the duration;
/// a demand that would come only after the end is refused; a last segment
/// that merely goes on past the end ("snow to the end") is normal.
#[test]
fn what_lies_after_a_scenario_s_end_is_said() {
    let tmp = tempfile::tempdir().unwrap();
    let time = "segments_by = \"time\"\nduration = 1.0\n[[segment]]\nroad = \"asphalt\"\nduration = 0.5\n[[segment]]\nroad = \"snow\"\nduration = 0.5\n";
    let s1 = scenario_file(
        tmp.path(),
        "s1.toml",
        &format!("{time}[[segment]]\nroad = \"ice\"\nduration = 2.0\n"),
    );
    let o = mtte_on(2, &s1);
    assert!(o.status.success(), "{o:?}");
    let err = stderr(&o);
    let line = format!(
        "warning: {}: field `segment[2]`: road `ice` begins at 1 s, at or after the end of the run (duration = 1 s): it is never driven",
        s1.display()
    );
    assert_eq!(err.matches(&line).count(), 1, "{err}");

    // snow to the end: the last segment goes on past the end
    let s4 = scenario_file(
        tmp.path(),
        "s4.toml",
        &time.replace(
            "duration = 0.5\n[[segment]]\nroad = \"snow\"\nduration = 0.5",
            "duration = 0.5\n[[segment]]\nroad = \"snow\"\nduration = 5.0",
        ),
    );
    let o = mtte_on(1, &s4);
    assert!(o.status.success(), "{o:?}");
    let err = stderr(&o);
    assert!(LATE_WORDS.iter().all(|w| !err.contains(w)), "{err}");

    // distance segments: known after the run
    let s2 = scenario_file(
        tmp.path(),
        "s2.toml",
        "segments_by = \"distance\"\nduration = 1.0\n[[segment]]\nroad = \"asphalt\"\nlength = 2.0\n[[segment]]\nroad = \"snow\"\nlength = 50.0\n[[segment]]\nroad = \"ice\"\nlength = 100.0\n",
    );
    let o = mtte_on(2, &s2);
    assert!(o.status.success(), "{o:?}");
    let err = stderr(&o);
    assert!(
        err.contains(&format!(
            "warning: MTTE, seeds 1-2: never reached segment[2] (ice, from 52.00 m) of scenario `mine` ({}): the runs got only",
        s2.display()
        )),
        "{err}"
    );
    let report = String::from_utf8_lossy(&o.stdout);
    assert!(
        report.contains("Note: 2 of 2 runs ended before reaching all of scenario `mine`'s roads"),
        "{report}"
    );

    // a demand that begins after the end: a run of zeros, refused
    let s3 = scenario_file(
        tmp.path(),
        "s3.toml",
        "segments_by = \"time\"\n[demand]\nkind = \"ramp\"\nfrom = 0\nto = 300\nstart = 5\nduration = 1\n[[segment]]\nroad = \"asphalt\"\nduration = 1\n",
    );
    let err = refused(&mtte_on(1, &s3));
    assert!(
        err.contains(&format!("{}: field `demand.start`: the driver first asks for torque at 5 s, at or after the end of the run (duration = 1 s", s3.display())),
        "{err}"
    );
}

/// The shipped scenarios and `--scenario random` have nothing after their
/// end: no warning, no note.
#[test]
fn the_shipped_scenarios_and_random_ones_have_nothing_after_their_end() {
    let mut names: Vec<String> = std::fs::read_dir(config_dir().join("scenarios"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert!(names.len() >= 3, "{names:?}");
    names.push("random".to_owned());
    for n in &names {
        let o = mtte_on(2, n);
        assert!(o.status.success(), "{n}: {o:?}");
        let all = format!("{}{}", stderr(&o), String::from_utf8_lossy(&o.stdout));
        assert!(LATE_WORDS.iter().all(|w| !all.contains(w)), "{n}: {all}");
    }
}
