//! `--snr-db`, the one parser of `grip sim` and `grip dataset synth`: the
//! same syntax, limits and error text for both.
//!
//! Accepted: `off` (no noise), a level `X` in dB, or a range `A..B` (dB,
//! A ≤ B; `A..A` is the level A), every value within −30..=80 dB. Each
//! command then says what it does with it: `grip sim` refuses a range (its
//! runs are given one condition), `grip dataset synth` draws a level per
//! recording from a range and treats `off` as `--noise none`.

/// A parsed `--snr-db`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Snr {
    /// `off`: clean road sound, no noise mixed in.
    Off,
    /// A level, dB.
    Db(f64),
    /// `A..B` with A < B: a uniform draw per recording, dB.
    Range(f64, f64),
}

/// The limits of every level, dB (the synthesiser's own).
pub use grip_arte::synth::SNR_LIMITS_DB;

/// Parses `--snr-db` (clap value parser; clap adds the option's name to
/// the error).
pub fn parse_snr(s: &str) -> Result<Snr, String> {
    let t = s.trim();
    if t.eq_ignore_ascii_case("off") {
        return Ok(Snr::Off);
    }
    let num = |v: &str| {
        v.trim()
            .parse::<f64>()
            .map_err(|_| format!("`{s}` is neither `off`, a number of dB nor a range A..B of them"))
    };
    let (a, b) = match t.split_once("..") {
        Some((a, b)) => (num(a)?, num(b)?),
        None => {
            let v = num(t)?;
            (v, v)
        }
    };
    if !(SNR_LIMITS_DB.contains(&a) && SNR_LIMITS_DB.contains(&b)) {
        return Err(format!(
            "`{s}` is outside {}..={} dB",
            SNR_LIMITS_DB.start(),
            SNR_LIMITS_DB.end()
        ));
    }
    if a > b {
        return Err(format!("`{s}`: a range A..B needs A <= B"));
    }
    Ok(if a == b { Snr::Db(a) } else { Snr::Range(a, b) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepted_syntax() {
        assert_eq!(parse_snr("off"), Ok(Snr::Off));
        assert_eq!(parse_snr("OFF"), Ok(Snr::Off));
        assert_eq!(parse_snr("10"), Ok(Snr::Db(10.0)));
        assert_eq!(parse_snr("-5"), Ok(Snr::Db(-5.0)));
        assert_eq!(parse_snr("-5..10"), Ok(Snr::Range(-5.0, 10.0)));
        assert_eq!(parse_snr(" 3 .. 3 "), Ok(Snr::Db(3.0)));
        assert_eq!(parse_snr("-30..80"), Ok(Snr::Range(-30.0, 80.0)));
    }

    #[test]
    fn refusals_say_why() {
        for bad in ["loud", "", "5..x", "..5", "1-5"] {
            let e = parse_snr(bad).unwrap_err();
            assert!(
                e.contains("neither") && e.contains(&format!("`{bad}`")),
                "{e}"
            );
        }
        for bad in ["81", "-31", "nan", "inf", "0..100"] {
            let e = parse_snr(bad).unwrap_err();
            assert!(e.contains("outside -30..=80 dB"), "{bad}: {e}");
        }
        let e = parse_snr("10..5").unwrap_err();
        assert!(e.contains("A <= B"), "{e}");
    }
}
