//! The verdict rules on made-up measurements: each rule passes inside its
//! limit, fails outside it, and says "NOT MEASURED" (never PASS) when its
//! measurement is missing.

use grip_bench::cyclictest::Stats;
use grip_bench::parse::IpcRow;
use grip_bench::procfs::Usage;
use grip_bench::verdict::{
    ArteCost, Budget, Line, LoopTiming, Measurements, Overall, RecorderRate, Verdict, judge,
    overall,
};

fn usage(name: &str, cpu: f64, rss: f64) -> Usage {
    Usage {
        name: name.into(),
        samples: 200,
        span_s: 50.0,
        cpu_s: cpu * 50.0,
        cpu_share: cpu,
        rss_mean_mib: rss * 0.9,
        rss_peak_mib: rss,
    }
}

fn ipc(mode: &str, p50: f64, p99: f64, lost: u64) -> IpcRow {
    IpcRow {
        mode: mode.into(),
        n: 10_000,
        p50_us: p50,
        p99_us: p99,
        p999_us: p99 * 2.0,
        max_us: p99 * 4.0,
        lost,
    }
}

/// A machine that meets every limit.
fn good() -> Measurements {
    Measurements {
        loop_timing: Ok(LoopTiming {
            cycles: 60_000,
            wakeup_us: [15.0, 40.0, 90.0, 800.0],
            compute_us: [5.0, 10.0, 20.0, 60.0],
            deadline_misses: 3,
            late_wakeups: 1,
            safe_cycles: 0,
        }),
        cyclictest: Ok(Stats {
            count: 60_000,
            p50_us: 13.0,
            p99_us: 33.0,
            p999_us: 90.0,
            max_us: 700.0,
            over_limit: 0,
            limit_us: 1000,
        }),
        ipc: Ok(vec![
            ipc("iox-poll", 5.0, 40.0, 0),
            ipc("uds-poll", 10.0, 30.0, 0),
            ipc("iox-event", 48.0, 216.0, 0),
            ipc("uds-block", 46.0, 202.0, 0),
        ]),
        recorder: Ok(RecorderRate {
            msg_per_s: 385_000.0,
            drive_msg_per_s: 5253.0,
            criterion: true,
        }),
        arte: Ok(ArteCost {
            frame: Some((
                "frame_features_and_classify/default_speed_changing".into(),
                1.2e-3,
            )),
        }),
        arte_estimates: 2400,
        services: Ok(vec![
            usage("recorder", 0.05, 20.0),
            usage("plant-sim", 0.10, 10.0),
            usage("audio-acq", 0.01, 8.0),
            usage("arte", 0.06, 30.0),
            usage("tcs-loop", 0.03, 12.0),
        ]),
    }
}

fn line<'a>(lines: &'a [Line], item: &str) -> &'a Line {
    lines
        .iter()
        .find(|l| l.item.starts_with(item))
        .unwrap_or_else(|| panic!("no line {item}: {lines:#?}"))
}

#[test]
fn a_good_machine_passes_every_rule() {
    let lines = judge(&good(), &Budget::default());
    for l in &lines {
        assert!(matches!(l.verdict, Verdict::Pass | Verdict::Info), "{l:#?}");
        assert!(!l.reason.is_empty(), "{l:#?}");
    }
    assert_eq!(overall(&lines), Overall::Pass);
    // every rule is there
    for item in [
        "tcs-loop wake-up p99.9 + compute p99.9",
        "tcs-loop deadline misses",
        "cyclictest p99.9",
        "tcs-loop wake-up p99 / cyclictest p99",
        "audio block over iceoryx2",
        "recorder headroom",
        "ARTE frame cost",
        "arte CPU per estimate",
        "car services' CPU",
        "car services' resident memory",
        "tcs-loop CPU share",
    ] {
        line(&lines, item);
    }
    // 0.05 + 0.01 + 0.06 + 0.03 cores: plant-sim is not counted
    let cpu = line(&lines, "car services' CPU");
    assert!((cpu.value.unwrap() - 0.15).abs() < 1e-12, "{cpu:#?}");
    let rss = line(&lines, "car services' resident memory");
    assert!((rss.value.unwrap() - 70.0).abs() < 1e-12, "{rss:#?}");
    // arte: 0.06 x 50 s = 3 CPU s / 2400 estimates = 1250 µs
    let a = line(&lines, "arte CPU per estimate");
    assert!((a.value.unwrap() - 1250.0).abs() < 1e-6, "{a:#?}");
    let r = line(&lines, "recorder headroom");
    assert!((r.value.unwrap() - 385_000.0 / 5253.0).abs() < 1e-9);
}

#[test]
fn each_rule_fails_over_its_limit_with_its_reason() {
    let b = Budget::default();
    let check = |m: Measurements, item: &str| {
        let lines = judge(&m, &b);
        let l = line(&lines, item);
        assert_eq!(l.verdict, Verdict::Fail, "{l:#?}");
        assert_eq!(overall(&lines), Overall::Fail);
        l.reason.clone()
    };
    let mut m = good();
    if let Ok(t) = &mut m.loop_timing {
        t.wakeup_us[2] = 990.0; // + 20 µs compute > 1000 µs
    }
    check(m, "tcs-loop wake-up p99.9 + compute p99.9");

    let mut m = good();
    if let Ok(t) = &mut m.loop_timing {
        t.deadline_misses = 61; // > 1e-3 of 60 000
        t.late_wakeups = 17;
    }
    if let Ok(c) = &mut m.cyclictest {
        c.over_limit = 23;
    }
    let why = check(m, "tcs-loop deadline misses");
    assert!(why.contains("61 of 60000"), "{why}");
    // whose stalls: the loop's late wake-ups beside the bare scheduler's
    assert!(
        why.contains("woken > 1000 µs late 17 times, cyclictest alone 23 times"),
        "{why}"
    );

    let mut m = good();
    if let Ok(c) = &mut m.cyclictest {
        c.p999_us = 501.0;
    }
    check(m, "cyclictest p99.9");

    let mut m = good();
    if let Ok(t) = &mut m.loop_timing {
        t.wakeup_us[1] = 33.0 * 1.6;
    }
    check(m, "tcs-loop wake-up p99 / cyclictest p99");

    let mut m = good();
    m.ipc = Ok(vec![ipc("iox-event", 48.0, 2400.0, 0)]);
    check(m, "audio block over iceoryx2");
    let mut m = good();
    m.ipc = Ok(vec![ipc("iox-event", 48.0, 100.0, 2)]);
    let why = check(m, "audio block over iceoryx2");
    assert!(why.contains("2 blocks lost"), "{why}");

    let mut m = good();
    m.recorder = Ok(RecorderRate {
        msg_per_s: 49.0 * 5253.0,
        drive_msg_per_s: 5253.0,
        criterion: false,
    });
    check(m, "recorder headroom");

    let mut m = good();
    m.arte = Ok(ArteCost {
        frame: Some(("frame_features_and_classify/default".into(), 5.1e-3)),
    });
    check(m, "ARTE frame cost");

    let mut m = good();
    m.arte_estimates = 500; // 3 CPU s / 500 = 6 ms > 5 ms
    check(m, "arte CPU per estimate");

    let mut m = good();
    m.services = Ok(vec![
        usage("recorder", 0.5, 20.0),
        usage("plant-sim", 0.1, 10.0),
        usage("audio-acq", 0.1, 8.0),
        usage("arte", 0.3, 30.0),
        usage("tcs-loop", 0.2, 200.0),
    ]);
    check(m.clone(), "car services' CPU");
    check(m, "car services' resident memory");
}

#[test]
fn a_missing_measurement_is_never_a_pass() {
    let mut m = good();
    m.cyclictest = Err("cyclictest not found".into());
    m.arte = Err("no --arte-bench given".into());
    let lines = judge(&m, &Budget::default());
    let l = line(&lines, "cyclictest p99.9");
    assert_eq!(l.verdict, Verdict::NotMeasured);
    assert_eq!(l.reason, "cyclictest not found");
    assert_eq!(
        line(&lines, "ARTE frame cost").verdict,
        Verdict::NotMeasured
    );
    // the ratio needs both: left out rather than guessed
    assert!(!lines.iter().any(|l| l.item.contains("/ cyclictest")));
    assert_eq!(overall(&lines), Overall::Incomplete);

    // a service that never ran: the totals are not judged on the others
    let mut m = good();
    if let Ok(s) = &mut m.services {
        s.retain(|u| u.name != "arte");
    }
    let lines = judge(&m, &Budget::default());
    assert_eq!(
        line(&lines, "car services' CPU").verdict,
        Verdict::NotMeasured
    );
    assert_eq!(overall(&lines), Overall::Incomplete);

    // a drive without cycles
    let mut m = good();
    m.loop_timing = Ok(LoopTiming::default());
    let lines = judge(&m, &Budget::default());
    assert_eq!(line(&lines, "tcs-loop cycle").verdict, Verdict::NotMeasured);

    // a failure outweighs a missing line
    let mut m = good();
    m.cyclictest = Err("x".into());
    m.recorder = Ok(RecorderRate {
        msg_per_s: 1.0,
        drive_msg_per_s: 5253.0,
        criterion: false,
    });
    assert_eq!(overall(&judge(&m, &Budget::default())), Overall::Fail);
}

#[test]
fn the_table_and_files_carry_every_line() {
    let lines = judge(&good(), &Budget::default());
    let t = grip_bench::report::table(&lines, Overall::Pass);
    assert!(t.starts_with("| item | measured | limit | verdict | reason |"));
    assert_eq!(
        t.lines().filter(|l| l.starts_with("| ")).count(),
        lines.len() + 1
    );
    assert!(t.contains("verdict: PASS"));
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bench.csv");
    grip_bench::report::write_csv(&p, &lines).unwrap();
    let mut r = csv::Reader::from_path(&p).unwrap();
    assert_eq!(r.records().count(), lines.len());
}
