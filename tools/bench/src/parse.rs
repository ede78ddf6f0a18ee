//! The output of the bench executables `grip-bench` runs rather than
//! re-implementing: the audio-block IPC bench of audio-acq (a Markdown
//! table) and criterion benches (the recorder's write rate, ARTE's frame
//! cost).

use serde::Serialize;

/// One mode of `services/audio-acq/benches/ipc_latency.rs`, µs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IpcRow {
    /// `iox-poll`, `uds-poll`, `iox-event`, `uds-block`.
    pub mode: String,
    /// Blocks measured.
    pub n: u64,
    /// Median, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// 99.9th percentile, µs.
    pub p999_us: f64,
    /// Maximum, µs.
    pub max_us: f64,
    /// Blocks lost (sequence holes).
    pub lost: u64,
}

/// Reads the rows of the IPC bench's table
/// (`| mode | n | p50 | p90 | p99 | p99.9 | max | mean | lost |`).
pub fn ipc_table(text: &str) -> Result<Vec<IpcRow>, String> {
    let mut rows = Vec::new();
    for line in text.lines() {
        let cells: Vec<&str> = line
            .trim()
            .trim_matches('|')
            .split('|')
            .map(str::trim)
            .collect();
        if cells.len() != 9 || cells[0] == "mode" || cells[0].starts_with("---") {
            continue;
        }
        let num = |i: usize, what: &str| -> Result<f64, String> {
            cells[i].parse::<f64>().map_err(|_| {
                format!(
                    "IPC bench, mode {}: {what} {:?} is not a number",
                    cells[0], cells[i]
                )
            })
        };
        rows.push(IpcRow {
            mode: cells[0].to_owned(),
            n: num(1, "n")? as u64,
            p50_us: num(2, "p50")?,
            p99_us: num(4, "p99")?,
            p999_us: num(5, "p99.9")?,
            max_us: num(6, "max")?,
            lost: num(8, "lost")? as u64,
        });
    }
    if rows.is_empty() {
        return Err("IPC bench: no table rows in its output".into());
    }
    Ok(rows)
}

/// One benchmark of a criterion report: the interval of the time per
/// iteration, seconds, and of the throughput, elements/s (when reported).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CriterionResult {
    /// Benchmark id (`group/function`).
    pub id: String,
    /// Lower bound, estimate, upper bound of the time per iteration, s.
    pub time_s: [f64; 3],
    /// The same for the throughput, elements/s.
    pub thrpt_per_s: Option<[f64; 3]>,
}

fn time_unit(u: &str) -> Option<f64> {
    Some(match u {
        "ps" => 1e-12,
        "ns" => 1e-9,
        "µs" | "us" | "μs" => 1e-6,
        "ms" => 1e-3,
        "s" => 1.0,
        _ => return None,
    })
}

fn rate_unit(u: &str) -> Option<f64> {
    let base = u.strip_suffix("elem/s")?;
    Some(match base {
        "" => 1.0,
        "K" => 1e3,
        "M" => 1e6,
        "G" => 1e9,
        _ => return None,
    })
}

/// `[a unit b unit c unit]` after `key:` in `line`.
fn triple(
    line: &str,
    key: &str,
    unit: fn(&str) -> Option<f64>,
) -> Option<Result<[f64; 3], String>> {
    let at = line.find(key)?;
    let rest = &line[at + key.len()..];
    let inner = rest.trim().strip_prefix('[')?.split(']').next()?;
    let t: Vec<&str> = inner.split_whitespace().collect();
    if t.len() != 6 {
        return Some(Err(format!("criterion: cannot read {key} [{inner}]")));
    }
    let mut v = [0.0; 3];
    for k in 0..3 {
        let (num, u) = (t[2 * k], t[2 * k + 1]);
        match (num.parse::<f64>(), unit(u)) {
            (Ok(x), Some(f)) => v[k] = x * f,
            _ => return Some(Err(format!("criterion: cannot read {key} value {num} {u}"))),
        }
    }
    Some(Ok(v))
}

/// Reads every benchmark of criterion's report. The id is on the `time:`
/// line when it is short, else on the line before.
pub fn criterion(text: &str) -> Result<Vec<CriterionResult>, String> {
    let mut out: Vec<CriterionResult> = Vec::new();
    let mut last_name: Option<String> = None;
    for line in text.lines() {
        if let Some(t) = triple(line, "time:", time_unit) {
            let before = line[..line.find("time:").unwrap_or(0)].trim();
            let id = if before.is_empty() {
                last_name
                    .clone()
                    .ok_or("criterion: a time: line without a benchmark id")?
            } else {
                before.to_owned()
            };
            out.push(CriterionResult {
                id,
                time_s: t?,
                thrpt_per_s: None,
            });
            continue;
        }
        if let Some(r) = triple(line, "thrpt:", rate_unit) {
            if let Some(last) = out.last_mut() {
                last.thrpt_per_s = Some(r?);
            }
            continue;
        }
        let l = line.trim();
        if !l.is_empty()
            && !l.starts_with("Benchmarking")
            && !l.starts_with("Found")
            && !l.starts_with("change:")
            && !l.contains(':')
            && !line.starts_with(' ')
        {
            last_name = Some(l.to_owned());
        }
    }
    Ok(out)
}

/// The one-pass figure the recorder's write-rate bench prints before
/// criterion runs: (messages per drive second, messages/s, MB/s of file).
pub fn recorder_one_pass(text: &str) -> Option<(f64, f64, f64)> {
    let l = text.lines().find(|l| l.starts_with("write_rate:"))?;
    let num_before = |key: &str| -> Option<f64> {
        let at = l.find(key)?;
        l[..at].split_whitespace().last()?.parse::<f64>().ok()
    };
    Some((
        num_before("messages per drive second")?,
        num_before("msg/s")?,
        num_before("MB/s")?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ipc_table_rows() {
        let text = "AudioBlock 8224 B (1024 valid samples), ...\n| mode | n | p50 µs | p90 µs | p99 µs | p99.9 µs | max µs | mean µs | lost |\n|---|---|---|---|---|---|---|---|---|\n| iox-poll | 10000 | 5.11 | 7.52 | 39733.00 | 49068.00 | 51331.00 | 412.00 | 0 |\n| uds-block | 10000 | 45.68 | 87.68 | 202.00 | 772.00 | 2704.00 | 60.10 | 3 |\n";
        let r = ipc_table(text).unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].mode, "iox-poll");
        assert_eq!(r[0].p99_us, 39733.0);
        assert_eq!(r[1].p50_us, 45.68);
        assert_eq!(r[1].lost, 3);
        assert!(ipc_table("nothing").unwrap_err().contains("no table rows"));
        let e = ipc_table("| iox-poll | 1 | x | 1 | 1 | 1 | 1 | 1 | 0 |").unwrap_err();
        assert!(e.contains("p50") && e.contains("iox-poll"), "{e}");
    }

    #[test]
    fn criterion_report_long_and_short_ids_and_units() {
        let text = "\
Benchmarking frame_features_and_classify/default: Warming up for 3.0000 s
frame_features_and_classify/default
                        time:   [412.10 µs 415.20 us 420.00 µs]
Found 3 outliers among 100 measurements (3.00%)
classify_vector/paper   time:   [1.2000 µs 1.2500 µs 1.3000 µs]
                        change: [-1.0% +0.5% +2.0%] (p = 0.50 > 0.05)
recorder/write_5_drive_seconds
                        time:   [64.000 ms 68.000 ms 71.000 ms]
                        thrpt:  [369.93 Kelem/s 386.25 Kelem/s 410.39 Kelem/s]
";
        let r = criterion(text).unwrap();
        assert_eq!(r.len(), 3);
        assert_eq!(r[0].id, "frame_features_and_classify/default");
        assert!((r[0].time_s[1] - 415.2e-6).abs() < 1e-12);
        assert_eq!(r[1].id, "classify_vector/paper");
        assert!(r[1].thrpt_per_s.is_none());
        assert_eq!(r[2].id, "recorder/write_5_drive_seconds");
        assert!((r[2].time_s[1] - 0.068).abs() < 1e-12);
        assert!((r[2].thrpt_per_s.unwrap()[1] - 386_250.0).abs() < 1e-6);
        let e = criterion("x\n   time:   [1 furlong 2 ms 3 ms]\n").unwrap_err();
        assert!(e.contains("furlong"), "{e}");
    }

    #[test]
    fn recorder_one_pass_line() {
        let l = "write_rate: 5253 messages per drive second, 450123 bytes per drive second in the file (lz4), one pass: 380000 msg/s, 32.1 MB/s of file, 72x real time\n";
        assert_eq!(recorder_one_pass(l), Some((5253.0, 380000.0, 32.1)));
        assert_eq!(recorder_one_pass("other"), None);
    }
}
