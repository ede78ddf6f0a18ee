//! CPU time and resident memory of processes, from `/proc` (Linux).
//!
//! `/proc/PID/stat` gives the parent, the command name and the CPU time of
//! all the process's threads (`utime + stime`, in clock ticks);
//! `/proc/PID/status` gives the resident set (`VmRSS`) and its peak
//! (`VmHWM`). A service's CPU share over a drive is the ticks it used
//! between its first and last sample divided by the wall time between them.

use std::path::Path;

use serde::Serialize;

/// Fields of `/proc/PID/stat` the bench uses.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stat {
    /// Command name (`comm`, at most 15 bytes).
    pub comm: String,
    /// Parent process id.
    pub ppid: u32,
    /// User + system CPU time of all threads, clock ticks.
    pub ticks: u64,
}

/// Parses the text of `/proc/PID/stat`. The command name is in parentheses
/// and may itself hold spaces and parentheses: the fields after it start
/// after the *last* `)`.
pub fn parse_stat(text: &str) -> Result<Stat, String> {
    let open = text.find('(').ok_or("no '(' before the command name")?;
    let close = text.rfind(')').ok_or("no ')' after the command name")?;
    if close < open {
        return Err("')' before '('".into());
    }
    let comm = text[open + 1..close].to_owned();
    // after ")": state(3) ppid(4) ... utime(14) stime(15)
    let rest: Vec<&str> = text[close + 1..].split_whitespace().collect();
    let field = |n: usize| -> Result<u64, String> {
        let s = rest
            .get(n - 3)
            .ok_or_else(|| format!("field {n} missing ({} fields after the name)", rest.len()))?;
        s.parse::<u64>()
            .map_err(|_| format!("field {n} is not a number: {s:?}"))
    };
    Ok(Stat {
        comm,
        ppid: field(4)? as u32,
        ticks: field(14)? + field(15)?,
    })
}

/// `VmRSS` and `VmHWM` of the text of `/proc/PID/status`, KiB (None when
/// absent, as for a zombie).
pub fn parse_status_rss(text: &str) -> (Option<u64>, Option<u64>) {
    let kib = |key: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(key))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse::<u64>().ok())
    };
    (kib("VmRSS:"), kib("VmHWM:"))
}

/// One reading of a process.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Seconds since the start of sampling.
    pub t: f64,
    /// CPU ticks used so far.
    pub ticks: u64,
    /// Resident set, KiB.
    pub rss_kib: u64,
    /// Peak resident set, KiB.
    pub hwm_kib: u64,
}

/// Reads `/proc/<pid>` (under `root`, normally `/proc`) at time `t`.
pub fn sample(root: &Path, pid: u32, t: f64) -> Result<(Stat, Sample), String> {
    let dir = root.join(pid.to_string());
    let stat_text = std::fs::read_to_string(dir.join("stat"))
        .map_err(|e| format!("{}: {e}", dir.join("stat").display()))?;
    let stat =
        parse_stat(&stat_text).map_err(|e| format!("{}: {e}", dir.join("stat").display()))?;
    let status = std::fs::read_to_string(dir.join("status"))
        .map_err(|e| format!("{}: {e}", dir.join("status").display()))?;
    let (rss, hwm) = parse_status_rss(&status);
    let rss = rss.ok_or_else(|| format!("{}: no VmRSS (exited?)", dir.join("status").display()))?;
    Ok((
        stat.clone(),
        Sample {
            t,
            ticks: stat.ticks,
            rss_kib: rss,
            hwm_kib: hwm.unwrap_or(rss),
        },
    ))
}

/// Every descendant of `ancestor` (children, their children, ...) with its
/// command name, from one scan of `root` (normally `/proc`).
pub fn descendants(root: &Path, ancestor: u32) -> Vec<(u32, String)> {
    let mut all: Vec<(u32, Stat)> = Vec::new();
    if let Ok(rd) = std::fs::read_dir(root) {
        for e in rd.flatten() {
            let Some(pid) = e.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else {
                continue;
            };
            if let Ok(t) = std::fs::read_to_string(e.path().join("stat"))
                && let Ok(s) = parse_stat(&t)
            {
                all.push((pid, s));
            }
        }
    }
    let mut found: Vec<(u32, String)> = Vec::new();
    let mut frontier = vec![ancestor];
    while let Some(p) = frontier.pop() {
        for (pid, s) in &all {
            if s.ppid == p && !found.iter().any(|f| f.0 == *pid) {
                found.push((*pid, s.comm.clone()));
                frontier.push(*pid);
            }
        }
    }
    found
}

/// Clock ticks per second (`sysconf(_SC_CLK_TCK)`, 100 on Linux).
pub fn clock_ticks() -> u64 {
    // SAFETY: sysconf has no preconditions; it reads a constant.
    let t = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    if t > 0 { t as u64 } else { 100 }
}

/// The usage of one process over a run: its samples reduced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Usage {
    /// Name (the service).
    pub name: String,
    /// Samples taken.
    pub samples: usize,
    /// Seconds between the first and last sample.
    pub span_s: f64,
    /// CPU seconds used between the first and last sample.
    pub cpu_s: f64,
    /// CPU share: cores used on average (1.0 = one core busy all the time).
    pub cpu_share: f64,
    /// Mean resident set over the samples, MiB.
    pub rss_mean_mib: f64,
    /// Peak resident set (the kernel's VmHWM at the last sample), MiB.
    pub rss_peak_mib: f64,
}

/// Reduces a process's samples (in time order) with `ticks_per_s`. None
/// with fewer than two samples (no interval to divide by).
pub fn usage(name: &str, samples: &[Sample], ticks_per_s: u64) -> Option<Usage> {
    let (first, last) = (samples.first()?, samples.last()?);
    let span = last.t - first.t;
    if samples.len() < 2 || span <= 0.0 {
        return None;
    }
    let cpu_s = last.ticks.saturating_sub(first.ticks) as f64 / ticks_per_s as f64;
    let mean_kib = samples.iter().map(|s| s.rss_kib as f64).sum::<f64>() / samples.len() as f64;
    let peak_kib = samples
        .iter()
        .map(|s| s.hwm_kib.max(s.rss_kib))
        .max()
        .unwrap_or(0);
    Some(Usage {
        name: name.to_owned(),
        samples: samples.len(),
        span_s: span,
        cpu_s,
        cpu_share: cpu_s / span,
        rss_mean_mib: mean_kib / 1024.0,
        rss_peak_mib: peak_kib as f64 / 1024.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stat_with_a_name_holding_spaces_and_parentheses() {
        let text = "4242 (tcs (loop) x) S 4200 4242 4200 0 -1 4194560 1200 0 0 0 250 75 0 0 -21 0 3 0 12345 1000000 900 18446744073709551615\n";
        let s = parse_stat(text).unwrap();
        assert_eq!(s.comm, "tcs (loop) x");
        assert_eq!(s.ppid, 4200);
        assert_eq!(s.ticks, 325);
    }

    #[test]
    fn bad_stat_says_which_field() {
        let e = parse_stat("1 (a) S 0 1 2").unwrap_err();
        assert!(e.contains("field 14 missing"), "{e}");
        let e = parse_stat("1 (a) S x 1").unwrap_err();
        assert!(e.contains("field 4"), "{e}");
        assert!(parse_stat("no parens").is_err());
    }

    #[test]
    fn status_rss_and_peak() {
        let t = "Name:\tarte\nVmPeak:\t  200000 kB\nVmHWM:\t   30000 kB\nVmRSS:\t   25000 kB\n";
        assert_eq!(parse_status_rss(t), (Some(25000), Some(30000)));
        assert_eq!(parse_status_rss("Name:\tzombie\nState:\tZ\n"), (None, None));
    }

    #[test]
    fn usage_is_ticks_over_wall_time() {
        let s = |t: f64, ticks: u64, rss: u64| Sample {
            t,
            ticks,
            rss_kib: rss,
            hwm_kib: rss,
        };
        // 250 ticks at 100 Hz = 2.5 CPU s over 5 s: half a core
        let u = usage(
            "x",
            &[s(1.0, 100, 1024), s(3.0, 200, 3072), s(6.0, 350, 2048)],
            100,
        )
        .unwrap();
        assert!((u.cpu_s - 2.5).abs() < 1e-12);
        assert!((u.cpu_share - 0.5).abs() < 1e-12);
        assert!((u.rss_mean_mib - 2.0).abs() < 1e-12);
        assert!((u.rss_peak_mib - 3.0).abs() < 1e-12);
        assert!(usage("x", &[s(1.0, 1, 1)], 100).is_none());
    }

    #[test]
    fn this_process_is_sampled_and_its_memory_seen_to_grow() {
        let me = std::process::id();
        let root = Path::new("/proc");
        let (st, a) = sample(root, me, 0.0).unwrap();
        assert!(!st.comm.is_empty());
        // touch 64 MiB: the resident set must grow by at least half of it
        let mut v = vec![0u8; 64 << 20];
        for i in (0..v.len()).step_by(4096) {
            v[i] = 1;
        }
        std::hint::black_box(&v);
        let (_, b) = sample(root, me, 1.0).unwrap();
        assert!(b.ticks >= a.ticks);
        assert!(b.rss_kib >= a.rss_kib + 32 * 1024, "{a:?} -> {b:?}");
        assert!(b.hwm_kib >= b.rss_kib);
        drop(v);
        assert!(sample(root, u32::MAX - 1, 0.0).is_err());
    }

    #[test]
    fn children_and_grandchildren_are_found_by_name() {
        // sh -> sleep: both descendants of this process
        let mut ch = std::process::Command::new("sh")
            .args(["-c", "sleep 30 & wait"])
            .spawn()
            .unwrap();
        let mut found = Vec::new();
        for _ in 0..200 {
            found = descendants(Path::new("/proc"), std::process::id());
            if found.iter().any(|(_, c)| c == "sleep") {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        for (p, c) in &found {
            if c == "sleep" {
                // SAFETY: kill(2) on a pid this test started (sh's child)
                unsafe { libc::kill(*p as i32, libc::SIGKILL) };
            }
        }
        let _ = ch.kill();
        let _ = ch.wait();
        assert!(
            found.iter().any(|(p, c)| *p == ch.id() && c == "sh"),
            "{found:?}"
        );
        assert!(found.iter().any(|(_, c)| c == "sleep"), "{found:?}");
    }
}
