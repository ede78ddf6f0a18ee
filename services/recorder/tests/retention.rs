//! Retention on a real directory: real files (logs of an earlier boot and of
//! this one, the log being written, foreign files, a directory and a
//! symbolic link named like logs) with set modification times, swept by
//! [`Retention`]; and the recorder binary itself deleting the oldest logs
//! of its `out_dir` once recording, keeping everything else.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant, SystemTime};

use grip_recorder::retention::{Limits, Retention, boot_token};
use grip_testkit::svc::{NotifySocket, Service};

const MIB: u64 = 1 << 20;

/// A file of `mib` MiB (sparse: its length is what retention counts)
/// modified at `mtime` seconds after the epoch.
fn file(dir: &Path, name: &str, mib: u64, mtime: u64) {
    let f = std::fs::File::create(dir.join(name)).unwrap();
    f.set_len(mib * MIB).unwrap();
    f.set_modified(SystemTime::UNIX_EPOCH + Duration::from_secs(mtime))
        .unwrap();
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A directory as an ECU's log directory looks after a few boots, plus
/// foreign files. Returns the log being written.
fn populate(dir: &Path) -> std::path::PathBuf {
    let this = boot_token();
    // an earlier boot: the name's seconds say the first is the newer (the
    // clock was set during that drive), the modification time says older
    file(dir, "grip-100-aaaaaaaa-7.mcap", 3, 1_000_000);
    file(dir, "grip-50-aaaaaaaa-7-1.mcap", 3, 2_000_000);
    // this boot, finished (a recorder restarted), its clock not yet set:
    // the oldest modification time, yet newer than every earlier boot's
    file(dir, &format!("grip-60-{this}-4000001.mcap"), 3, 500);
    // foreign: never counted, never deleted
    file(dir, "notes.txt", 50, 1);
    file(dir, "drive.mcap", 50, 1);
    file(dir, "grip-1-aaaaaaaa-7.mcap.bak", 50, 1);
    file(dir, "grip-1-AAAAAAAA-7.mcap", 50, 1);
    std::fs::create_dir(dir.join("grip-2-aaaaaaaa-7.mcap")).unwrap();
    std::os::unix::fs::symlink("notes.txt", dir.join("grip-3-aaaaaaaa-7.mcap")).unwrap();
    // the log being written
    let cur = dir.join(format!("grip-70-{this}-{}.mcap", std::process::id()));
    file(
        dir,
        cur.file_name().unwrap().to_str().unwrap(),
        3,
        3_000_000,
    );
    cur
}

const FOREIGN: [&str; 6] = [
    "drive.mcap",
    "grip-1-AAAAAAAA-7.mcap",
    "grip-1-aaaaaaaa-7.mcap.bak",
    "grip-2-aaaaaaaa-7.mcap",
    "grip-3-aaaaaaaa-7.mcap",
    "notes.txt",
];

#[test]
fn the_budget_deletes_the_oldest_finished_logs_and_nothing_else() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path();
    let cur = populate(dir);
    let cur_name = cur.file_name().unwrap().to_str().unwrap().to_owned();
    let this_boot_log = format!("grip-60-{}-4000001.mcap", boot_token());

    // 12 MiB of grip logs against 7: the earlier boot's two, oldest first
    let mut r = Retention::new(
        dir,
        &cur,
        Limits {
            max_total: 7 * MIB,
            min_free: 0,
        },
    );
    let s = r.sweep();
    let gone: Vec<(&str, u64)> = s.deleted.iter().map(|(n, b)| (n.as_str(), *b)).collect();
    assert_eq!(
        gone,
        [
            ("grip-100-aaaaaaaa-7.mcap", 3 * MIB),
            ("grip-50-aaaaaaaa-7-1.mcap", 3 * MIB)
        ]
    );
    let mut want: Vec<String> = FOREIGN.iter().map(|s| (*s).to_owned()).collect();
    want.extend([cur_name.clone(), this_boot_log.clone()]);
    want.sort();
    assert_eq!(names(dir), want);
    assert!(s.plan.budget_met && s.plan.floor_met, "{:?}", s.plan);
    assert_eq!(r.unmet(), (false, false));

    // a budget below the log being written: this boot's finished log
    // goes, the current one stays, and that the budget is not met is said
    let mut r = Retention::new(
        dir,
        &cur,
        Limits {
            max_total: MIB,
            min_free: 0,
        },
    );
    let s = r.sweep();
    assert_eq!(s.deleted, [(this_boot_log, 3 * MIB)]);
    want.retain(|n| !n.starts_with("grip-60-"));
    assert_eq!(names(dir), want);
    assert_eq!(r.unmet(), (true, false));
    assert_eq!(r.stats().limit_warnings, 1);
    assert!(std::fs::symlink_metadata(dir.join("grip-3-aaaaaaaa-7.mcap")).is_ok());
}

#[test]
fn an_unreachable_floor_deletes_every_finished_log_and_nothing_else() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path();
    let cur = populate(dir);
    let cur_name = cur.file_name().unwrap().to_str().unwrap().to_owned();
    let mut r = Retention::new(
        dir,
        &cur,
        Limits {
            max_total: 0,
            min_free: u64::MAX / 2,
        },
    );
    let s = r.sweep();
    assert_eq!(s.deleted.len(), 3, "{:?}", s.deleted);
    assert_eq!(
        s.deleted[2].0,
        format!("grip-60-{}-4000001.mcap", boot_token())
    );
    let mut want: Vec<String> = FOREIGN.iter().map(|s| (*s).to_owned()).collect();
    want.push(cur_name);
    want.sort();
    assert_eq!(names(dir), want);
    assert!(!s.plan.floor_met);
    assert_eq!(r.unmet(), (false, true));
    // said once: the next sweep finds nothing to delete and stays quiet
    r.sweep();
    assert_eq!(r.stats().limit_warnings, 1);
}

/// Before the first byte only the floor is kept (bounded work before
/// `READY=1`); the budget is applied by the first sweep while recording,
/// which is due at once.
#[test]
fn the_start_sweep_keeps_the_floor_and_the_first_periodic_one_the_budget() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path();
    let cur = populate(dir);
    let mut r = Retention::new(
        dir,
        &cur,
        Limits {
            max_total: 7 * MIB,
            min_free: 0,
        },
    );
    assert!(r.sweep_start().deleted.is_empty());
    let s = r.maybe_sweep(Instant::now()).expect("due at once");
    assert_eq!(s.deleted.len(), 2);
    assert!(r.maybe_sweep(Instant::now()).is_none(), "then every 10 s");
}

/// The recorder with `out_dir` holding earlier logs and a budget of 16 MiB:
/// once recording it deletes the two oldest (logged with file and size),
/// keeps this boot's, the foreign files and its own log, and stops cleanly.
#[test]
fn the_recorder_keeps_its_out_dir_within_the_budget() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("logs");
    std::fs::create_dir(&out).unwrap();
    let this = boot_token();
    file(&out, "grip-100-aaaaaaaa-7.mcap", 10, 1_000_000);
    file(&out, "grip-50-aaaaaaaa-7-1.mcap", 10, 2_000_000);
    let this_boot_log = format!("grip-60-{this}-4000001.mcap");
    file(&out, &this_boot_log, 10, 500);
    file(&out, "notes.txt", 100, 1);
    // a configuration directory of the recorder's file alone (its log then
    // holds a few KiB of attachments)
    let cfg = t.path().join("config");
    std::fs::create_dir(&cfg).unwrap();
    let shipped = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/recorder.toml"),
    )
    .unwrap();
    let text = shipped
        .lines()
        .map(|l| {
            if l.starts_with("out_dir") {
                format!("out_dir = {:?}", out.display().to_string())
            } else if l.starts_with("max_total_mib") {
                "max_total_mib = 16".to_owned()
            } else if l.starts_with("min_free_mib") {
                "min_free_mib = 0".to_owned()
            } else if l.starts_with("max_file_mib") {
                // at most half the budget
                "max_file_mib = 8".to_owned()
            } else {
                l.to_owned()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert!(text.contains("max_total_mib = 16") && text.contains("min_free_mib = 0"));
    std::fs::write(cfg.join("recorder.toml"), text).unwrap();

    let sock = NotifySocket::bind(t.path());
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_recorder"));
    cmd.arg("--config-dir")
        .arg(&cfg)
        .env("NOTIFY_SOCKET", sock.path())
        .env(
            "GRIP_INSTANCE",
            format!("rec-retention-{}", std::process::id()),
        );
    let mut child = Service::spawn(cmd);
    assert!(
        sock.wait_for("READY=1", Duration::from_secs(30)),
        "no READY=1 within 30 s"
    );
    let t0 = Instant::now();
    while out.join("grip-50-aaaaaaaa-7-1.mcap").exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "the old logs were not deleted within 20 s of READY: {:?}",
            names(&out)
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.signal(15);
    let (status, err) = child.wait();
    assert_eq!(status.code(), Some(0), "{err}");
    let left = names(&out);
    let own: Vec<&String> = left
        .iter()
        .filter(|n| n.starts_with("grip-") && n.ends_with(&format!("-{}.mcap", child.0.id())))
        .collect();
    assert_eq!(own.len(), 1, "its own log: {left:?}");
    let mut want = vec![own[0].clone(), this_boot_log, "notes.txt".to_owned()];
    want.sort();
    assert_eq!(left, want);
    for gone in ["grip-100-aaaaaaaa-7.mcap", "grip-50-aaaaaaaa-7-1.mcap"] {
        assert!(
            err.lines()
                .any(|l| l.contains("retention: deleted the oldest finished log")
                    && l.contains(gone)
                    && l.contains(&format!("bytes={}", 10 * MIB))),
            "no deletion line for {gone}: {err}"
        );
    }
    assert!(err.contains("retention_deleted=2"), "{err}");
}

/// Rotation: when a new part starts ([`Retention::set_current`]) the part
/// before is a finished log like any other, deleted oldest first for the
/// budget; the part being written never is, even when it alone is over
/// the budget.
#[test]
fn finished_parts_are_deleted_never_the_part_being_written() {
    let t = tempfile::tempdir().unwrap();
    let dir = t.path();
    let this = boot_token();
    let pid = std::process::id();
    let part = |secs: u64| format!("grip-{secs}-{this}-{pid}.mcap");
    file(dir, &part(100), 4, 1000);
    let mut r = Retention::new(
        dir,
        &dir.join(part(100)),
        Limits {
            max_total: 10 * MIB,
            min_free: 0,
        },
    );
    r.sweep();
    assert_eq!(names(dir), vec![part(100)], "the part being written");
    // rotated twice: parts 1 and 2 finished, part 3 written
    file(dir, &part(200), 4, 2000);
    file(dir, &part(300), 4, 3000);
    r.set_current(&dir.join(part(300)));
    r.sweep();
    assert_eq!(
        names(dir),
        vec![part(200), part(300)],
        "the oldest part first"
    );
    // the part being written alone over the budget: the finished ones go,
    // it stays
    file(dir, &part(300), 12, 3000);
    r.sweep();
    assert_eq!(names(dir), vec![part(300)]);
    assert_eq!(r.stats().deleted, 2);
}
