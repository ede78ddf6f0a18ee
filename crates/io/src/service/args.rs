//! Command-line values every service parses the same way.
//!
//! - [`seconds`]: the `clap` value parser of `--run-for SECONDS` (arte,
//!   audio-acq, tcs-loop), so that each refuses the same values with the
//!   same message. Give the argument `allow_negative_numbers = true` as
//!   well: `--run-for -1` then reaches the parser and gets its range
//!   message instead of clap's "unexpected argument '-1'".
//! - [`deadline_ns`]: when such a run ends on the service's clock,
//!   saturating, so that no run length (a library caller's `inf` included)
//!   can wrap the deadline into the past.

/// `--run-for SECONDS`, flattened into a service's `clap` arguments
/// (arte, audio-acq, tcs-loop): one option, one parser ([`seconds`]), one
/// help text for all.
#[derive(Debug, Clone, Copy, Default, PartialEq, clap::Args)]
pub struct RunFor {
    /// Stop by itself after this many seconds (0 to 3.2e7; default: run
    /// until SIGTERM/SIGINT).
    #[arg(long = "run-for", value_name = "SECONDS", value_parser = seconds, allow_negative_numbers = true)]
    pub seconds: Option<f64>,
}

/// The longest `--run-for`, s: about a year (370 days).
pub const MAX_RUN_FOR_S: f64 = 3.2e7;

/// `--run-for SECONDS`: a finite number of seconds, at least 0 and at most
/// [`MAX_RUN_FOR_S`]. The error quotes the value as given.
///
/// ```
/// use grip_io::service::args::seconds;
/// assert_eq!(seconds("2.5"), Ok(2.5));
/// assert!(seconds("inf").is_err());
/// assert!(seconds("-1").is_err());
/// ```
pub fn seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number of seconds"))?;
    if v.is_finite() && (0.0..=MAX_RUN_FOR_S).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{s:?}: seconds from 0 to {MAX_RUN_FOR_S:e} (a year) expected"
        ))
    }
}

/// The clock reading `run_for_s` seconds after `now_ns` (ns): the end of a
/// `--run-for` run. Saturating: a run length beyond the clock's range
/// (infinite, or 1e300 s from a library caller that skipped [`seconds`])
/// gives `u64::MAX`, a deadline never reached, instead of wrapping to a
/// moment already past (or panicking in a debug build). Negative or NaN:
/// `now_ns`.
pub fn deadline_ns(now_ns: u64, run_for_s: f64) -> u64 {
    // `as` saturates: +inf and anything above u64::MAX ns give u64::MAX,
    // NaN gives 0 (and `max` has already turned it into 0.0)
    now_ns.saturating_add((run_for_s.max(0.0) * 1e9) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Svc {
        #[command(flatten)]
        run_for: RunFor,
    }

    /// `--run-for` as every service takes it: `inf` or `1e300` is a usage
    /// error, not a deadline that wraps into the past; `-1` reaches the
    /// parser in either spelling (not clap's "unexpected argument").
    #[test]
    fn run_for_is_one_option_with_one_parser() {
        let a = Svc::try_parse_from(["svc", "--run-for", "2.5"]).unwrap();
        assert_eq!(a.run_for.seconds, Some(2.5));
        assert_eq!(Svc::try_parse_from(["svc"]).unwrap().run_for.seconds, None);
        for bad in ["inf", "NaN", "-1", "1e300", "soon"] {
            for argv in [
                vec!["svc".to_string(), format!("--run-for={bad}")],
                vec!["svc".into(), "--run-for".into(), bad.into()],
            ] {
                let e = Svc::try_parse_from(&argv).unwrap_err();
                assert_eq!(
                    e.kind(),
                    clap::error::ErrorKind::ValueValidation,
                    "{argv:?}: {e}"
                );
                let msg = e.to_string();
                assert!(msg.contains("--run-for") && msg.contains(bad), "{msg}");
            }
        }
        let e = Svc::try_parse_from(["svc", "--run-for", "-1"]).unwrap_err();
        assert!(e.to_string().contains("seconds from 0 to 3.2e7"), "{e}");
    }

    #[test]
    fn seconds_takes_a_finite_run_length_up_to_a_year() {
        assert_eq!(seconds("0"), Ok(0.0));
        assert_eq!(seconds("1"), Ok(1.0));
        assert_eq!(seconds("0.25"), Ok(0.25));
        assert_eq!(seconds("3.2e7"), Ok(MAX_RUN_FOR_S));
        for bad in [
            "inf", "-inf", "Infinity", "NaN", "-1", "-0.5", "1e300", "3.3e7", "soon", "",
        ] {
            let e = seconds(bad).unwrap_err();
            assert!(e.contains(&format!("{bad:?}")), "{bad}: {e}");
        }
        assert!(seconds("-1").unwrap_err().contains("from 0 to 3.2e7"));
        assert!(seconds("soon").unwrap_err().contains("not a number"));
    }

    #[test]
    fn the_deadline_saturates_instead_of_wrapping() {
        assert_eq!(deadline_ns(5, 1.0), 1_000_000_005);
        assert_eq!(deadline_ns(5, 0.0), 5);
        assert_eq!(deadline_ns(5, -3.0), 5);
        assert_eq!(deadline_ns(5, f64::NAN), 5);
        // what `now + (s * 1e9) as u64` wrapped to a moment already past
        for huge in [f64::INFINITY, 1e300, 1.9e10] {
            assert_eq!(deadline_ns(1_000, huge), u64::MAX, "{huge}");
        }
        assert_eq!(deadline_ns(u64::MAX - 1, 1.0), u64::MAX);
        // the longest run --run-for allows, from a clock years past boot
        let now = 10 * 365 * 86_400 * 1_000_000_000u64;
        assert_eq!(
            deadline_ns(now, MAX_RUN_FOR_S),
            now + 32_000_000 * 1_000_000_000
        );
    }
}
