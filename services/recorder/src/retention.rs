//! Retention of the logs in `out_dir`: the oldest finished grip logs are
//! deleted while grip's logs together take more than `max_total_mib` or
//! less than `min_free_mib` is free on the directory's file system
//! (`config/recorder.toml`, `services/recorder/README.md`, "Retention").
//!
//! - [`parse_log_name`]: the only files ever deleted are named as
//!   [`crate::run::new_file`] names them, `grip-<unix s>-<boot>-<pid>.mcap`
//!   or `grip-<unix s>-<boot>-<pid>-<n>.mcap`, regular files, never the
//!   log being written and never one another running recorder writes.
//! - [`plan`]: the decision, a pure function of the directory's entries,
//!   the limits and the free space.
//! - [`Retention`]: the directory scan, `statvfs`, the deletions and their
//!   log lines; run once at the start and then at most every
//!   [`SWEEP_PERIOD`] by the writing thread (never the receive thread).
//!
//! Which log is oldest: logs of an earlier boot (the boot id in the name
//! differs from this boot's) before logs of this boot, then by modification
//! time, then by name. Not by the seconds in the name: an ECU without a
//! real-time clock starts every boot at the same wall time, so the names of
//! different boots carry the same seconds; the name's time is stamped when
//! the log starts, often before the clock is set (NTP, GNSS, the vehicle's
//! time), while the modification time is stamped at the log's last write.
//! What no clock can get wrong is that every log of this boot is newer
//! than every log of an earlier one.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

/// Time between two sweeps while recording.
pub const SWEEP_PERIOD: Duration = Duration::from_secs(10);

/// Longest a periodic sweep goes on deleting: a log of an hour's driving
/// took 0.25-0.3 s to delete (`services/recorder/README.md`, "Retention"),
/// and the writer, which sweeps, does not write meanwhile (the queue holds
/// about 12 s of a drive). A sweep that stops here with more to delete
/// goes on after [`CATCH_UP_PERIOD`], once the writer has caught up.
pub const MAX_DELETING: Duration = Duration::from_millis(500);

/// Time to the next sweep after one cut short by [`MAX_DELETING`].
pub const CATCH_UP_PERIOD: Duration = Duration::from_secs(1);

/// Most deletions that failed remembered (each warned about once and not
/// tried again while this recorder runs).
const MAX_FAILED: usize = 4096;

/// What retention keeps to, bytes; 0 switches a limit off.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest total size of grip's logs in the directory (0: none).
    pub max_total: u64,
    /// Least free space on the directory's file system (0: none).
    pub min_free: u64,
}

impl Limits {
    /// Both limits off: nothing is ever deleted.
    pub fn is_off(&self) -> bool {
        self.max_total == 0 && self.min_free == 0
    }

    /// Whether `total` bytes of logs with `free` bytes free keep to both.
    pub fn hold(&self, total: u64, free: u64) -> bool {
        self.budget_holds(total) && self.floor_holds(free)
    }

    fn budget_holds(&self, total: u64) -> bool {
        self.max_total == 0 || total <= self.max_total
    }

    fn floor_holds(&self, free: u64) -> bool {
        self.min_free == 0 || free >= self.min_free
    }
}

/// The parts of a recorder log's name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogName<'a> {
    /// Wall time at the log's start, Unix seconds.
    pub secs: u64,
    /// The first 8 hex digits of the boot id, or `noboot`.
    pub boot: &'a str,
    /// The recorder's process id.
    pub pid: u32,
    /// The `-<n>` appended when the name was taken (0: none).
    pub n: u32,
}

/// `Some` for exactly the names [`crate::run::new_file`] gives
/// [`crate::run::default_out`]'s stems: `grip-<unix s>-<boot>-<pid>.mcap`
/// and `grip-<unix s>-<boot>-<pid>-<n>.mcap`, numbers in plain decimal
/// (no sign, no leading zero), `<boot>` 8 lowercase hex digits or
/// `noboot`, `<n>` ≥ 1.
pub fn parse_log_name(name: &str) -> Option<LogName<'_>> {
    fn number(t: &str) -> Option<u64> {
        if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        let v: u64 = t.parse().ok()?;
        (v.to_string() == t).then_some(v)
    }
    let stem = name.strip_prefix("grip-")?.strip_suffix(".mcap")?;
    let mut parts = stem.split('-');
    let secs = number(parts.next()?)?;
    let boot = parts.next()?;
    let hex8 = boot.len() == 8 && boot.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'));
    if !(hex8 || boot == NO_BOOT) {
        return None;
    }
    let pid = u32::try_from(number(parts.next()?)?).ok()?;
    let n = match parts.next() {
        None => 0,
        Some(t) => match u32::try_from(number(t)?).ok()? {
            0 => return None,
            n => n,
        },
    };
    if parts.next().is_some() {
        return None;
    }
    Some(LogName { secs, boot, pid, n })
}

/// The boot part of a log name when the boot id cannot be read.
pub const NO_BOOT: &str = "noboot";

/// This boot's part of a log name: the first 8 characters of
/// `/proc/sys/kernel/random/boot_id` without dashes, or [`NO_BOOT`].
pub fn boot_token() -> String {
    std::fs::read_to_string("/proc/sys/kernel/random/boot_id")
        .map(|b| b.trim().chars().filter(|c| *c != '-').take(8).collect())
        .unwrap_or_else(|_| String::from(NO_BOOT))
}

/// One entry of the log directory, as the scan saw it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// File name.
    pub name: String,
    /// Size, bytes.
    pub bytes: u64,
    /// Modification time.
    pub modified: SystemTime,
    /// A regular file (not a directory, symbolic link, ...).
    pub regular: bool,
}

/// What [`plan`] decided.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Plan {
    /// Indices into the entries, in the order to delete them (oldest first).
    pub delete: Vec<usize>,
    /// Bytes of grip's logs in the directory before the deletions.
    pub total_before: u64,
    /// Bytes of grip's logs after them.
    pub total_after: u64,
    /// Free bytes expected after them.
    pub free_after: u64,
    /// Bytes of the logs that may not be deleted (the one being written,
    /// those of other running recorders, those whose deletion failed).
    pub kept: u64,
    /// `total_after` within the budget (or no budget).
    pub budget_met: bool,
    /// `free_after` at or above the floor (or no floor).
    pub floor_met: bool,
}

/// Which logs to delete: of the regular files named as the recorder names
/// its logs ([`parse_log_name`]) and not in `keep` (file names), the oldest
/// first (an earlier boot's before `this_boot`'s, then by modification
/// time, then by name), until grip's logs take at most
/// `limits.max_total` and `free` plus the bytes deleted is at least
/// `limits.min_free`, or none is left. Every log, kept ones too, counts
/// toward the total; other files do not. `this_boot`: this boot's part of a
/// log name (`None` when unknown: age by modification time alone).
pub fn plan(
    entries: &[Entry],
    keep: &BTreeSet<String>,
    this_boot: Option<&str>,
    limits: Limits,
    free: u64,
) -> Plan {
    let mut total = 0u64;
    let mut kept = 0u64;
    let mut candidates = Vec::new();
    for (i, e) in entries.iter().enumerate() {
        if !e.regular {
            continue;
        }
        let Some(n) = parse_log_name(&e.name) else {
            continue;
        };
        total = total.saturating_add(e.bytes);
        if keep.contains(&e.name) {
            kept = kept.saturating_add(e.bytes);
            continue;
        }
        let this = this_boot.is_some_and(|b| b == n.boot);
        candidates.push((this, e.modified, e.name.as_str(), i));
    }
    candidates.sort_unstable();
    let (mut total_after, mut free_after) = (total, free);
    let mut delete = Vec::new();
    for (_, _, _, i) in candidates {
        if limits.hold(total_after, free_after) {
            break;
        }
        let b = entries[i].bytes;
        delete.push(i);
        total_after = total_after.saturating_sub(b);
        free_after = free_after.saturating_add(b);
    }
    Plan {
        delete,
        total_before: total,
        total_after,
        free_after,
        kept,
        budget_met: limits.budget_holds(total_after),
        floor_met: limits.floor_holds(free_after),
    }
}

/// Bytes an unprivileged user may still write on `dir`'s file system
/// (`statvfs`: `f_bavail` × `f_frsize`; the blocks reserved for root do
/// not count, the recorder runs as `grip`).
pub fn free_bytes(dir: &Path) -> std::io::Result<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes())
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "NUL in the path"))?;
    let mut st = std::mem::MaybeUninit::<libc::statvfs>::zeroed();
    // SAFETY: `c` is NUL-terminated; `st` is valid for the write of one
    // statvfs.
    let r = unsafe { libc::statvfs(c.as_ptr(), st.as_mut_ptr()) };
    if r != 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: statvfs returned 0, so it filled `st` (and all-zero is a
    // valid statvfs anyway).
    let st = unsafe { st.assume_init() };
    #[allow(clippy::useless_conversion)] // u32 on 32-bit targets
    let (avail, frsize) = (u64::from(st.f_bavail), u64::from(st.f_frsize));
    Ok(avail.saturating_mul(frsize))
}

/// Whether `pid` is a running process named `recorder` (another recorder
/// whose log must not be deleted under it).
fn recorder_running(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/comm")).is_ok_and(|c| c.trim_end() == "recorder")
}

/// One sweep's outcome.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    /// Logs deleted: file name and bytes.
    pub deleted: Vec<(String, u64)>,
    /// Deletions that failed (each warned about).
    pub failed: usize,
    /// The last plan (after the deletions that failed were excluded).
    pub plan: Plan,
    /// Free bytes before the sweep (`None`: `statvfs` failed).
    pub free_before: Option<u64>,
    /// How long the sweep took (scan, `statvfs`, deletions).
    pub took: Duration,
    /// Cut short by [`MAX_DELETING`] with more to delete: the next sweep
    /// follows after [`CATCH_UP_PERIOD`] (and `plan` is not the outcome).
    pub cut_short: bool,
}

/// Totals over the sweeps of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RetentionStats {
    /// Sweeps run.
    pub sweeps: u64,
    /// Logs deleted.
    pub deleted: u64,
    /// Bytes of the logs deleted.
    pub deleted_bytes: u64,
    /// Deletions that failed.
    pub failed: u64,
    /// The longest sweep.
    pub longest: Duration,
    /// Warnings that a limit cannot be kept (one per time it stops being
    /// kept).
    pub limit_warnings: u64,
}

/// Retention of one log directory while a recorder writes `current` in it.
#[derive(Debug)]
pub struct Retention {
    dir: PathBuf,
    current: String,
    limits: Limits,
    this_boot: Option<String>,
    own_pid: u32,
    failed: BTreeSet<String>,
    next: Option<Instant>,
    over_budget: bool,
    under_floor: bool,
    scan_warned: bool,
    statvfs_warned: bool,
    stats: RetentionStats,
}

impl Retention {
    /// Retention of `dir` around `current`, a file in it (its name is never
    /// deleted), to `limits`.
    pub fn new(dir: &Path, current: &Path, limits: Limits) -> Self {
        let boot = boot_token();
        Self {
            dir: dir.to_path_buf(),
            current: current
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            limits,
            this_boot: (boot != NO_BOOT).then_some(boot),
            own_pid: std::process::id(),
            failed: BTreeSet::new(),
            next: None,
            over_budget: false,
            under_floor: false,
            scan_warned: false,
            statvfs_warned: false,
            stats: RetentionStats::default(),
        }
    }

    /// The log being written is now `current` (a new part of the run:
    /// [`crate::parts`]); the one before is a finished log like any other.
    pub fn set_current(&mut self, current: &Path) {
        self.current = current
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
    }

    /// Totals so far.
    pub fn stats(&self) -> RetentionStats {
        self.stats
    }

    /// Sweeps when [`SWEEP_PERIOD`] has passed since the last sweep (or
    /// none ran yet).
    pub fn maybe_sweep(&mut self, now: Instant) -> Option<Sweep> {
        if self.next.is_some_and(|t| now < t) {
            return None;
        }
        Some(self.sweep())
    }

    /// Scans the directory, measures the free space, deletes what [`plan`]
    /// says (each deletion logged with file and size; a failure is a
    /// warning, that log is then kept and the next one deleted instead),
    /// and says once when a limit cannot be kept (and once when it is kept
    /// again).
    pub fn sweep(&mut self) -> Sweep {
        self.sweep_with(|p| std::fs::remove_file(p))
    }

    /// [`Retention::sweep`] deleting with `remove`.
    pub fn sweep_with(&mut self, remove: impl FnMut(&Path) -> std::io::Result<()>) -> Sweep {
        self.sweep_to(self.limits, Some(MAX_DELETING), remove)
    }

    /// The sweep before the recorder writes its first byte (before
    /// `READY=1`): the free-space floor alone, so that a file system that
    /// filled up does not fail the start, while what the floor asks is
    /// bounded by `min_free_mib` and a start stays short whatever the
    /// budget leaves to delete. The first periodic sweep
    /// ([`Retention::maybe_sweep`]) follows at once and applies both. Not
    /// cut short by [`MAX_DELETING`]: nothing is recorded yet.
    pub fn sweep_start(&mut self) -> Sweep {
        let floor = Limits {
            max_total: 0,
            min_free: self.limits.min_free,
        };
        let s = self.sweep_to(floor, None, |p| std::fs::remove_file(p));
        self.next = None;
        s
    }

    fn sweep_to(
        &mut self,
        limits: Limits,
        max_deleting: Option<Duration>,
        mut remove: impl FnMut(&Path) -> std::io::Result<()>,
    ) -> Sweep {
        let start = Instant::now();
        let mut out = Sweep::default();
        let mut entries = match self.scan() {
            Ok(e) => {
                self.scan_warned = false;
                e
            }
            Err(e) => {
                if !self.scan_warned {
                    self.scan_warned = true;
                    tracing::warn!(dir = %self.dir.display(), error = %e, "retention: cannot list the log directory; nothing deleted (said once until it can)");
                }
                return self.finish(out, start);
            }
        };
        out.free_before = match free_bytes(&self.dir) {
            Ok(f) => {
                self.statvfs_warned = false;
                Some(f)
            }
            Err(e) => {
                if !self.statvfs_warned && limits.min_free != 0 {
                    self.statvfs_warned = true;
                    tracing::warn!(dir = %self.dir.display(), error = %e, "retention: cannot read the free space (statvfs); min_free_mib is not applied (said once until it can)");
                }
                None
            }
        };
        let mut free = out.free_before.unwrap_or(u64::MAX);
        let mut keep = self.keep(&entries);
        // each round after the first keeps at least one more log, so
        // entries.len() + 1 rounds are enough; the bound holds whatever
        // plan() does
        for _ in 0..=entries.len() {
            let p = plan(&entries, &keep, self.this_boot.as_deref(), limits, free);
            let mut gone = Vec::new();
            let mut any_failed = false;
            for &i in &p.delete {
                if !gone.is_empty() && max_deleting.is_some_and(|m| start.elapsed() >= m) {
                    out.cut_short = true;
                    break;
                }
                let e = &entries[i];
                let path = self.dir.join(&e.name);
                match remove(&path) {
                    Ok(()) => {
                        tracing::info!(
                            file = %path.display(),
                            bytes = e.bytes,
                            "retention: deleted the oldest finished log"
                        );
                        out.deleted.push((e.name.clone(), e.bytes));
                        gone.push(i);
                    }
                    Err(err) if err.kind() == std::io::ErrorKind::NotFound => {
                        // deleted by someone else meanwhile: gone all the same
                        gone.push(i);
                    }
                    Err(err) => {
                        tracing::warn!(
                            file = %path.display(),
                            bytes = e.bytes,
                            error = %err,
                            "retention: cannot delete an old log; it is kept and not tried again while this recorder runs"
                        );
                        out.failed += 1;
                        any_failed = true;
                        if self.failed.len() < MAX_FAILED {
                            self.failed.insert(e.name.clone());
                        }
                        keep.insert(e.name.clone());
                    }
                }
            }
            for &i in &gone {
                free = free.saturating_add(entries[i].bytes);
            }
            gone.sort_unstable();
            for &i in gone.iter().rev() {
                entries.swap_remove(i);
            }
            out.plan = p;
            if !any_failed || out.cut_short {
                break;
            }
            // the plan counted on the failed deletions: plan again without
            // them
        }
        // the plan's totals of the last round are what is on disk now
        if limits == self.limits && !out.cut_short {
            self.report(&out);
        }
        self.finish(out, start)
    }

    fn finish(&mut self, mut out: Sweep, start: Instant) -> Sweep {
        out.took = start.elapsed();
        let wait = if out.cut_short {
            CATCH_UP_PERIOD
        } else {
            SWEEP_PERIOD
        };
        self.next = Some(Instant::now() + wait);
        let s = &mut self.stats;
        s.sweeps += 1;
        s.deleted += out.deleted.len() as u64;
        s.deleted_bytes += out.deleted.iter().map(|(_, b)| b).sum::<u64>();
        s.failed += out.failed as u64;
        s.longest = s.longest.max(out.took);
        tracing::debug!(
            took_us = out.took.as_micros() as u64,
            deleted = out.deleted.len(),
            logs_bytes = out.plan.total_after,
            free_bytes = out.plan.free_after,
            "retention sweep"
        );
        out
    }

    /// The directory's entries named as the recorder's logs (others are
    /// not even looked at).
    fn scan(&self) -> std::io::Result<Vec<Entry>> {
        let mut out = Vec::new();
        for e in std::fs::read_dir(&self.dir)? {
            let Ok(e) = e else { continue };
            let name = e.file_name();
            let Some(name) = name.to_str() else { continue };
            if parse_log_name(name).is_none() {
                continue;
            }
            // not followed: a symbolic link is not a log
            let Ok(m) = std::fs::symlink_metadata(e.path()) else {
                continue;
            };
            out.push(Entry {
                name: name.to_owned(),
                bytes: m.len(),
                modified: m.modified().unwrap_or(SystemTime::UNIX_EPOCH),
                regular: m.file_type().is_file(),
            });
        }
        Ok(out)
    }

    /// Names never to delete: the log being written, the logs of other
    /// recorders running in this boot, the deletions that failed.
    fn keep(&self, entries: &[Entry]) -> BTreeSet<String> {
        let mut keep = self.failed.clone();
        keep.insert(self.current.clone());
        for e in entries {
            if let Some(n) = parse_log_name(&e.name)
                && self.this_boot.as_deref() == Some(n.boot)
                && n.pid != self.own_pid
                && recorder_running(n.pid)
            {
                keep.insert(e.name.clone());
            }
        }
        keep
    }

    /// A limit that cannot be kept is said once (and once when it is kept
    /// again), not at every sweep.
    fn report(&mut self, s: &Sweep) {
        let p = &s.plan;
        let mib = |b: u64| b >> 20;
        if !p.budget_met && !self.over_budget {
            self.stats.limit_warnings += 1;
            tracing::warn!(
                logs_mib = mib(p.total_after),
                max_total_mib = mib(self.limits.max_total),
                current_log = %self.dir.join(&self.current).display(),
                undeletable_mib = mib(p.kept),
                "retention: grip's logs exceed max_total_mib and no finished log is left to delete (the log being written, or logs that cannot be deleted, take it alone); recording goes on (said once)"
            );
        } else if p.budget_met && self.over_budget {
            tracing::info!(
                logs_mib = mib(p.total_after),
                max_total_mib = mib(self.limits.max_total),
                "retention: grip's logs are within max_total_mib again"
            );
        }
        self.over_budget = !p.budget_met;
        if !p.floor_met && !self.under_floor {
            self.stats.limit_warnings += 1;
            tracing::warn!(
                free_mib = mib(p.free_after),
                min_free_mib = mib(self.limits.min_free),
                dir = %self.dir.display(),
                "retention: less than min_free_mib is free and no finished grip log is left to delete; recording goes on until the disk is full (a write error then stops it) (said once)"
            );
        } else if p.floor_met && self.under_floor {
            tracing::info!(
                free_mib = mib(p.free_after),
                min_free_mib = mib(self.limits.min_free),
                "retention: min_free_mib is free again"
            );
        }
        self.under_floor = !p.floor_met;
    }

    /// Whether a limit is currently reported as not kept: (budget, floor).
    pub fn unmet(&self) -> (bool, bool) {
        (self.over_budget, self.under_floor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const BOOT: &str = "0123abcd";
    const MIB: u64 = 1 << 20;

    fn t(s: u64) -> SystemTime {
        SystemTime::UNIX_EPOCH + Duration::from_secs(s)
    }

    fn log(name: &str, mib: u64, mtime: u64) -> Entry {
        Entry {
            name: name.into(),
            bytes: mib * MIB,
            modified: t(mtime),
            regular: true,
        }
    }

    fn keep(names: &[&str]) -> BTreeSet<String> {
        names.iter().map(|s| (*s).to_owned()).collect()
    }

    fn deleted<'a>(entries: &'a [Entry], p: &Plan) -> Vec<&'a str> {
        p.delete.iter().map(|&i| entries[i].name.as_str()).collect()
    }

    #[test]
    fn log_names_are_the_recorders_own_and_nothing_else() {
        let ok = [
            (
                "grip-1700000000-0123abcd-4242.mcap",
                (1700000000, "0123abcd", 4242, 0),
            ),
            ("grip-0-noboot-1.mcap", (0, "noboot", 1, 0)),
            ("grip-5-deadbeef-7-1.mcap", (5, "deadbeef", 7, 1)),
            ("grip-5-deadbeef-7-12.mcap", (5, "deadbeef", 7, 12)),
        ];
        for (name, (secs, boot, pid, n)) in ok {
            assert_eq!(
                parse_log_name(name),
                Some(LogName { secs, boot, pid, n }),
                "{name}"
            );
        }
        for name in [
            "grip-5-deadbeef-7.mcap.tmp",
            "grip-5-deadbeef-7.MCAP",
            "drive.mcap",
            "grip-notes.mcap",
            "grip-5-deadbeef.mcap",
            "grip-5-deadbeef-7-0.mcap",
            "grip-5-deadbeef-7-01.mcap",
            "grip-05-deadbeef-7.mcap",
            "grip-5-DEADBEEF-7.mcap",
            "grip-5-deadbee-7.mcap",
            "grip-5-deadbeefa-7.mcap",
            "grip-5-deadbeef-7-1-1.mcap",
            "grip-5-deadbeef--7.mcap",
            "grip-+5-deadbeef-7.mcap",
            "grip-5-deadbeef-99999999999.mcap",
            "grip-2024-notes-1.mcap",
            "xgrip-5-deadbeef-7.mcap",
            ".grip-5-deadbeef-7.mcap",
            "grip-5-deadbeef-7.mcap/",
            "",
        ] {
            assert_eq!(parse_log_name(name), None, "{name}");
        }
    }

    /// Table: each row a directory, the limits and the free space, and the
    /// logs deleted, in order.
    #[test]
    fn table_of_decisions() {
        let cur = "grip-9-0123abcd-50.mcap";
        let dir = vec![
            log("grip-3-aaaaaaaa-10.mcap", 100, 300), // earlier boot, newest mtime
            log("grip-1-bbbbbbbb-10.mcap", 100, 100), // earlier boot, oldest
            log("grip-1-bbbbbbbb-10-1.mcap", 100, 200),
            log("grip-2-0123abcd-40.mcap", 100, 50), // this boot: after every earlier boot
            log(cur, 100, 400),
            log("notes.txt", 5000, 0),
            log("grip-1-bbbbbbbb-11.mcap.bak", 5000, 0),
        ];
        let k = keep(&[cur]);
        let gib = 1024;
        // (what, limits, free, deleted in order, budget met, floor met)
        type Row<'a> = (&'a str, Limits, u64, &'a [&'a str], bool, bool);
        let rows: &[Row] = &[
            (
                "within both",
                Limits {
                    max_total: 500 * MIB,
                    min_free: MIB,
                },
                gib * MIB,
                &[],
                true,
                true,
            ),
            (
                "budget: 500 MiB of logs against 300",
                Limits {
                    max_total: 300 * MIB,
                    min_free: 0,
                },
                0,
                &["grip-1-bbbbbbbb-10.mcap", "grip-1-bbbbbbbb-10-1.mcap"],
                true,
                true,
            ),
            (
                "budget exactly met stops",
                Limits {
                    max_total: 400 * MIB,
                    min_free: 0,
                },
                0,
                &["grip-1-bbbbbbbb-10.mcap"],
                true,
                true,
            ),
            (
                "floor: 150 MiB free against 350",
                Limits {
                    max_total: 0,
                    min_free: 350 * MIB,
                },
                150 * MIB,
                &["grip-1-bbbbbbbb-10.mcap", "grip-1-bbbbbbbb-10-1.mcap"],
                true,
                true,
            ),
            (
                "floor needs more than the budget",
                Limits {
                    max_total: 400 * MIB,
                    min_free: 400 * MIB,
                },
                100 * MIB,
                &[
                    "grip-1-bbbbbbbb-10.mcap",
                    "grip-1-bbbbbbbb-10-1.mcap",
                    "grip-3-aaaaaaaa-10.mcap",
                ],
                true,
                true,
            ),
            (
                "this boot's finished log goes last, whatever its mtime",
                Limits {
                    max_total: 100 * MIB,
                    min_free: 0,
                },
                0,
                &[
                    "grip-1-bbbbbbbb-10.mcap",
                    "grip-1-bbbbbbbb-10-1.mcap",
                    "grip-3-aaaaaaaa-10.mcap",
                    "grip-2-0123abcd-40.mcap",
                ],
                true,
                true,
            ),
            (
                "the current log alone over the budget: all finished deleted, not met",
                Limits {
                    max_total: 50 * MIB,
                    min_free: 0,
                },
                0,
                &[
                    "grip-1-bbbbbbbb-10.mcap",
                    "grip-1-bbbbbbbb-10-1.mcap",
                    "grip-3-aaaaaaaa-10.mcap",
                    "grip-2-0123abcd-40.mcap",
                ],
                false,
                true,
            ),
            (
                "floor out of reach: all finished deleted, not met",
                Limits {
                    max_total: 0,
                    min_free: 10 * gib * MIB,
                },
                0,
                &[
                    "grip-1-bbbbbbbb-10.mcap",
                    "grip-1-bbbbbbbb-10-1.mcap",
                    "grip-3-aaaaaaaa-10.mcap",
                    "grip-2-0123abcd-40.mcap",
                ],
                true,
                false,
            ),
            (
                "off",
                Limits {
                    max_total: 0,
                    min_free: 0,
                },
                0,
                &[],
                true,
                true,
            ),
        ];
        for (what, limits, free, want, budget, floor) in rows {
            let p = plan(&dir, &k, Some(BOOT), *limits, *free);
            assert_eq!(deleted(&dir, &p), *want, "{what}");
            assert_eq!((p.budget_met, p.floor_met), (*budget, *floor), "{what}");
            assert_eq!(
                p.total_before,
                500 * MIB,
                "{what}: foreign files do not count"
            );
            let freed: u64 = p.delete.iter().map(|&i| dir[i].bytes).sum();
            assert_eq!(p.total_after, p.total_before - freed, "{what}");
            assert_eq!(p.free_after, free + freed, "{what}");
            assert_eq!(p.kept, 100 * MIB, "{what}");
        }
        // the boot unknown: by modification time alone
        let p = plan(
            &dir,
            &k,
            None,
            Limits {
                max_total: 300 * MIB,
                min_free: 0,
            },
            0,
        );
        assert_eq!(
            deleted(&dir, &p),
            ["grip-2-0123abcd-40.mcap", "grip-1-bbbbbbbb-10.mcap"]
        );
        // a directory or symbolic link named like a log is neither counted nor deleted
        let mut odd = log("grip-1-bbbbbbbb-12.mcap", 900, 1);
        odd.regular = false;
        let p = plan(
            &[odd],
            &BTreeSet::new(),
            Some(BOOT),
            Limits {
                max_total: 16 * MIB,
                min_free: 0,
            },
            0,
        );
        assert_eq!((p.delete.len(), p.total_before), (0, 0));
    }

    fn arb_entry() -> impl Strategy<Value = Entry> {
        let name = prop_oneof![
            // the recorder's own, of this boot or another
            (
                0u64..50,
                prop_oneof![Just(BOOT), Just("ffff0000"), Just("noboot")],
                1u32..5,
                0u32..3
            )
                .prop_map(|(s, b, pid, n)| if n == 0 {
                    format!("grip-{s}-{b}-{pid}.mcap")
                } else {
                    format!("grip-{s}-{b}-{pid}-{n}.mcap")
                }),
            // foreign, some close to the pattern
            "[a-z0-9.-]{0,24}",
            (0u64..50, 1u32..5).prop_map(|(s, pid)| format!("grip-{s}-{BOOT}-{pid}.mcap.old")),
            (0u64..50).prop_map(|s| format!("grip-{s}-xyz-1.mcap")),
        ];
        (name, 0u64..2000, 0u64..100, prop::bool::weighted(0.9)).prop_map(
            |(name, kib, m, regular)| Entry {
                name,
                bytes: kib * 1024,
                modified: t(m),
                regular,
            },
        )
    }

    fn age_key(e: &Entry) -> (bool, SystemTime, &str) {
        let n = parse_log_name(&e.name).unwrap();
        (n.boot == BOOT, e.modified, e.name.as_str())
    }

    proptest! {
        /// Whatever the directory: only the recorder's own finished logs
        /// are deleted (never the current one, a kept one, a foreign file
        /// or a non-regular one), oldest first, and deleting stops as soon
        /// as both limits hold: without the last deletion a limit would
        /// not hold, and a log is left undeleted only when both hold.
        #[test]
        fn only_own_finished_logs_oldest_first_and_no_more_than_needed(
            raw in prop::collection::vec(arb_entry(), 0..40),
            current in 0usize..40,
            max_total_kib in prop_oneof![Just(0u64), 1u64..40_000],
            min_free_kib in prop_oneof![Just(0u64), 1u64..40_000],
            free_kib in 0u64..40_000,
        ) {
            // one entry per name, as in a directory
            let mut seen = BTreeSet::new();
            let entries: Vec<Entry> = raw.into_iter().filter(|e| seen.insert(e.name.clone())).collect();
            let mut k = BTreeSet::new();
            if let Some(c) = entries.get(current) {
                k.insert(c.name.clone());
            }
            let limits = Limits { max_total: max_total_kib * 1024, min_free: min_free_kib * 1024 };
            let free = free_kib * 1024;
            let p = plan(&entries, &k, Some(BOOT), limits, free);

            let ours = |e: &Entry| e.regular && parse_log_name(&e.name).is_some();
            let deletable: Vec<usize> = (0..entries.len())
                .filter(|&i| ours(&entries[i]) && !k.contains(&entries[i].name))
                .collect();
            let dels: BTreeSet<usize> = p.delete.iter().copied().collect();
            prop_assert_eq!(dels.len(), p.delete.len(), "no index twice");
            for &i in &p.delete {
                let e = &entries[i];
                prop_assert!(e.regular, "non-regular deleted: {}", e.name);
                prop_assert!(parse_log_name(&e.name).is_some(), "foreign deleted: {}", e.name);
                prop_assert!(!k.contains(&e.name), "current deleted: {}", e.name);
            }
            // oldest first: in age order, and nothing left is older than a deleted one
            for w in p.delete.windows(2) {
                prop_assert!(age_key(&entries[w[0]]) < age_key(&entries[w[1]]));
            }
            if let Some(&last) = p.delete.last() {
                for &i in deletable.iter().filter(|i| !dels.contains(i)) {
                    prop_assert!(age_key(&entries[i]) > age_key(&entries[last]),
                        "{} kept but older than deleted {}", entries[i].name, entries[last].name);
                }
            }
            // the totals
            let total: u64 = entries.iter().filter(|e| ours(e)).map(|e| e.bytes).sum();
            let freed: u64 = p.delete.iter().map(|&i| entries[i].bytes).sum();
            prop_assert_eq!(p.total_before, total);
            prop_assert_eq!(p.total_after, total - freed);
            prop_assert_eq!(p.free_after, free + freed);
            prop_assert_eq!(p.budget_met, limits.max_total == 0 || p.total_after <= limits.max_total);
            prop_assert_eq!(p.floor_met, limits.min_free == 0 || p.free_after >= limits.min_free);
            // stops as soon as both hold
            if let Some(&last) = p.delete.last() {
                let b = entries[last].bytes;
                prop_assert!(!limits.hold(p.total_after + b, p.free_after - b),
                    "the last deletion was not needed");
            }
            if p.delete.len() < deletable.len() {
                prop_assert!(p.budget_met && p.floor_met, "a log left while a limit fails");
            }
            if limits.is_off() {
                prop_assert!(p.delete.is_empty());
            }
        }
    }

    /// A deletion that fails is a warning, not an error: that log is kept
    /// (and not tried again) and the next oldest is deleted instead.
    #[test]
    fn a_failed_deletion_is_skipped_and_the_next_log_deleted_instead() {
        let dir = tempfile::tempdir().unwrap();
        let mk = |name: &str, mtime: u64| {
            let p = dir.path().join(name);
            std::fs::write(&p, vec![0u8; 1 << 20]).unwrap();
            std::fs::File::options()
                .write(true)
                .open(&p)
                .unwrap()
                .set_modified(t(mtime))
                .unwrap();
        };
        mk("grip-1-bbbbbbbb-1.mcap", 100);
        mk("grip-2-bbbbbbbb-1.mcap", 200);
        mk("grip-3-bbbbbbbb-1.mcap", 300);
        mk("grip-4-bbbbbbbb-1.mcap", 400);
        let cur = dir.path().join("grip-4-bbbbbbbb-1.mcap");
        let mut r = Retention::new(
            dir.path(),
            &cur,
            Limits {
                max_total: 2 * MIB,
                min_free: 0,
            },
        );
        let oldest = dir.path().join("grip-1-bbbbbbbb-1.mcap");
        let mut tried = Vec::new();
        let s = r.sweep_with(|p| {
            tried.push(p.to_path_buf());
            if p == oldest {
                Err(std::io::Error::from(std::io::ErrorKind::PermissionDenied))
            } else {
                std::fs::remove_file(p)
            }
        });
        assert_eq!(s.failed, 1);
        let names: Vec<&str> = s.deleted.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["grip-2-bbbbbbbb-1.mcap", "grip-3-bbbbbbbb-1.mcap"]);
        assert!(oldest.exists() && cur.exists());
        assert!(s.plan.budget_met, "{:?}", s.plan);
        // not tried again
        tried.clear();
        let s = r.sweep_with(|p| {
            tried.push(p.to_path_buf());
            Ok(())
        });
        assert!(tried.is_empty() && s.deleted.is_empty(), "{tried:?}");
        assert_eq!(r.stats().deleted, 2);
        assert_eq!(r.stats().failed, 1);
    }

    /// A periodic sweep stops deleting after [`MAX_DELETING`] (the writer
    /// waits meanwhile) and goes on after [`CATCH_UP_PERIOD`].
    #[test]
    fn a_long_sweep_is_cut_short_and_resumed_soon() {
        let dir = tempfile::tempdir().unwrap();
        for k in 1..=6 {
            std::fs::write(dir.path().join(format!("grip-{k}-bbbbbbbb-1.mcap")), b"x").unwrap();
        }
        let cur = dir.path().join("grip-9-bbbbbbbb-1.mcap");
        std::fs::write(&cur, b"").unwrap();
        let mut r = Retention::new(
            dir.path(),
            &cur,
            Limits {
                max_total: 0,
                min_free: u64::MAX,
            },
        );
        let slow = |p: &Path| {
            std::thread::sleep(Duration::from_millis(200));
            std::fs::remove_file(p)
        };
        let s = r.sweep_with(slow);
        assert!(s.cut_short);
        assert_eq!(s.deleted.len(), 3, "started at 0, 200, 400 ms; not at 600");
        assert_eq!(r.unmet(), (false, false), "not judged on a cut sweep");
        let now = Instant::now();
        assert!(r.maybe_sweep(now).is_none());
        let s = r.maybe_sweep(now + CATCH_UP_PERIOD).unwrap();
        assert_eq!(s.deleted.len(), 3);
        assert!(!s.cut_short);
        assert_eq!(r.unmet(), (false, true), "the floor is out of reach");
        assert!(cur.exists());
    }

    /// A limit that cannot be kept is reported once, not at every sweep,
    /// and again after it was kept in between.
    #[test]
    fn an_unreachable_limit_is_reported_once() {
        let dir = tempfile::tempdir().unwrap();
        let cur = dir.path().join("grip-4-bbbbbbbb-1.mcap");
        std::fs::write(&cur, vec![0u8; 2 << 20]).unwrap();
        let mut r = Retention::new(
            dir.path(),
            &cur,
            Limits {
                max_total: MIB,
                min_free: 0,
            },
        );
        assert_eq!(r.unmet(), (false, false));
        let s = r.sweep();
        assert!(!s.plan.budget_met);
        assert_eq!(r.unmet(), (true, false));
        assert_eq!(r.stats().limit_warnings, 1);
        // the periodic check: not due again within the period
        assert!(r.maybe_sweep(Instant::now()).is_none());
        assert!(r.maybe_sweep(Instant::now() + SWEEP_PERIOD).is_some());
        r.sweep();
        assert_eq!(r.stats().limit_warnings, 1, "not said again");
        std::fs::write(&cur, b"small").unwrap();
        r.sweep();
        assert_eq!(r.unmet(), (false, false));
        std::fs::write(&cur, vec![0u8; 2 << 20]).unwrap();
        r.sweep();
        assert_eq!(r.stats().limit_warnings, 2, "said again after it was kept");
        assert_eq!(r.stats().sweeps, 5);
    }

    #[test]
    fn free_space_is_read() {
        let dir = tempfile::tempdir().unwrap();
        assert!(free_bytes(dir.path()).unwrap() > 0);
        assert!(free_bytes(&dir.path().join("missing")).is_err());
    }
}
