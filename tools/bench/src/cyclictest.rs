//! `cyclictest` (Debian's `rt-tests`): its command line and its histogram.
//!
//! Percentiles come from cyclictest's 1 µs buckets and are the bucket's
//! upper edge, capped at the exact maximum: the convention of
//! `grip_io::rt::LatencyHistogram`, so that tcs-loop's figures and
//! cyclictest's compare on one scale.

use serde::Serialize;

/// Latency figures of one cyclictest run, µs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stats {
    /// Wake-ups measured (buckets plus overflows).
    pub count: u64,
    /// Median, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// 99.9th percentile, µs.
    pub p999_us: f64,
    /// Maximum, µs.
    pub max_us: f64,
    /// Wake-ups later than `limit_us` (with the histogram's overflows).
    pub over_limit: u64,
    /// The limit `over_limit` counts against, µs.
    pub limit_us: u64,
}

/// The arguments of one run: `-m` (mlockall), FIFO `priority`, interval
/// `interval_us`, `loops` wake-ups, one thread pinned to `cpu` (if any),
/// quiet, a histogram of `hist_us` 1 µs buckets.
pub fn args(
    priority: u32,
    interval_us: u64,
    loops: u64,
    cpu: Option<u32>,
    hist_us: u64,
) -> Vec<String> {
    let mut a: Vec<String> = vec![
        "-m".into(),
        "-p".into(),
        priority.to_string(),
        "-i".into(),
        interval_us.to_string(),
        "-l".into(),
        loops.to_string(),
        "-t".into(),
        "1".into(),
    ];
    if let Some(c) = cpu {
        a.push(format!("-a{c}"));
    }
    a.push("-q".into());
    a.push(format!("--histogram={hist_us}"));
    a
}

fn quantile(buckets: &[u64], count: u64, max_us: f64, q: f64) -> f64 {
    let rank = ((q * count as f64).ceil() as u64).max(1);
    let mut seen = 0;
    for (i, &c) in buckets.iter().enumerate() {
        seen += c;
        if seen >= rank {
            return ((i + 1) as f64).min(max_us);
        }
    }
    max_us
}

/// Reads the output of `cyclictest -q --histogram=N` (one thread): bucket
/// lines `INDEX COUNT`, `# Max Latencies:` and `# Histogram Overflows:`.
/// `limit_us` is the latency counted as late (the loop's period).
pub fn parse(text: &str, limit_us: u64) -> Result<Stats, String> {
    let mut buckets: Vec<u64> = Vec::new();
    let mut max_us: Option<f64> = None;
    let mut overflow = 0u64;
    for line in text.lines() {
        let line = line.trim();
        if let Some(v) = line.strip_prefix("# Max Latencies:") {
            let v = v.split_whitespace().next().unwrap_or("");
            max_us = Some(
                v.parse::<f64>()
                    .map_err(|_| format!("cyclictest: bad '# Max Latencies' value {v:?}"))?,
            );
            continue;
        }
        if let Some(v) = line.strip_prefix("# Histogram Overflows:") {
            let v = v.split_whitespace().next().unwrap_or("");
            overflow = v
                .parse::<u64>()
                .map_err(|_| format!("cyclictest: bad '# Histogram Overflows' value {v:?}"))?;
            continue;
        }
        if line.starts_with('#') || line.is_empty() {
            continue;
        }
        let mut it = line.split_whitespace();
        if let (Some(a), Some(b), None) = (it.next(), it.next(), it.next())
            && let (Ok(i), Ok(c)) = (a.parse::<usize>(), b.parse::<u64>())
        {
            if i >= buckets.len() {
                buckets.resize(i + 1, 0);
            }
            buckets[i] += c;
        }
    }
    let max_us = max_us.ok_or("cyclictest: no '# Max Latencies' line (was --histogram given?)")?;
    let count: u64 = buckets.iter().sum::<u64>() + overflow;
    if count == 0 {
        return Err("cyclictest: the histogram is empty".into());
    }
    let limit = limit_us as usize;
    let over = buckets.iter().skip(limit).sum::<u64>() + overflow;
    Ok(Stats {
        count,
        p50_us: quantile(&buckets, count, max_us, 0.5),
        p99_us: quantile(&buckets, count, max_us, 0.99),
        p999_us: quantile(&buckets, count, max_us, 0.999),
        max_us,
        over_limit: over,
        limit_us,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hist(buckets: &[(usize, u64)], max: u64, overflow: u64) -> String {
        let mut s = String::from("# Histogram\n");
        for i in 0..40 {
            let c = buckets.iter().find(|b| b.0 == i).map_or(0, |b| b.1);
            s.push_str(&format!("{i:06} {c:06}\n"));
        }
        s.push_str(&format!(
            "# Total: {:09}\n# Min Latencies: 00003\n# Avg Latencies: 00012\n# Max Latencies: {max:05}\n# Histogram Overflows: {overflow:05}\n# Histogram Overflow at cycle number:\n# Thread 0:\n",
            buckets.iter().map(|b| b.1).sum::<u64>()
        ));
        s
    }

    #[test]
    fn percentiles_are_bucket_upper_edges_capped_at_the_max() {
        // 1000 wake-ups: 900 in bucket 10 (10-11 µs), 95 in 20, 5 in 35
        let text = hist(&[(10, 900), (20, 95), (35, 5)], 35, 0);
        let s = parse(&text, 30).unwrap();
        assert_eq!(s.count, 1000);
        assert_eq!(s.p50_us, 11.0);
        assert_eq!(s.p99_us, 21.0);
        // rank 999 falls in bucket 35, whose upper edge 36 is capped at max 35
        assert_eq!(s.p999_us, 35.0);
        assert_eq!(s.max_us, 35.0);
        assert_eq!(s.over_limit, 5);
    }

    #[test]
    fn overflows_count_as_late_and_push_the_tail_to_the_max() {
        let text = hist(&[(5, 990)], 4200, 10);
        let s = parse(&text, 1000).unwrap();
        assert_eq!(s.count, 1000);
        assert_eq!(s.p50_us, 6.0);
        assert_eq!(s.over_limit, 10);
        assert_eq!(s.p999_us, 4200.0);
    }

    #[test]
    fn output_without_a_histogram_is_an_error_naming_what_is_missing() {
        let e = parse(
            "T: 0 ( 1234) P:80 I:1000 C:   1000 Min: 3 Act: 5 Avg: 6 Max: 30\n",
            1000,
        )
        .unwrap_err();
        assert!(e.contains("Max Latencies"), "{e}");
        let e = parse(&hist(&[], 0, 0), 1000).unwrap_err();
        assert!(e.contains("empty"), "{e}");
        let e = parse("# Max Latencies: x\n", 1000).unwrap_err();
        assert!(e.contains("bad"), "{e}");
    }

    #[test]
    fn args_pin_and_size_the_histogram() {
        let a = args(80, 1000, 60_000, Some(1), 2000).join(" ");
        assert_eq!(a, "-m -p 80 -i 1000 -l 60000 -t 1 -a1 -q --histogram=2000");
        assert!(
            !args(80, 1000, 10, None, 2000)
                .iter()
                .any(|s| s.starts_with("-a"))
        );
    }
}
