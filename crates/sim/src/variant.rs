//! The six variants of the paper's Table V: each controller with and without ARTE.

use grip_tcs::ControllerKind;
use std::fmt;
use std::str::FromStr;

/// A controller and whether it receives ARTE's road knowledge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Variant {
    /// Which controller.
    pub kind: ControllerKind,
    /// True: the controller gets [`grip_tcs::RoadKnowledge`] from the road
    /// estimator; false: it always gets `None` (its no-ARTE behaviour).
    pub arte: bool,
}

impl Variant {
    /// The six variants in the paper's Table V order:
    /// mfc, src, mtte, mfc-arte, src-arte, mtte-arte.
    pub const ALL: [Variant; 6] = [
        Variant::new(ControllerKind::Mfc, false),
        Variant::new(ControllerKind::Src, false),
        Variant::new(ControllerKind::Mtte, false),
        Variant::new(ControllerKind::Mfc, true),
        Variant::new(ControllerKind::Src, true),
        Variant::new(ControllerKind::Mtte, true),
    ];

    /// A variant.
    pub const fn new(kind: ControllerKind, arte: bool) -> Self {
        Self { kind, arte }
    }

    /// Lower-case name: `mfc`, `src-arte`, ...
    pub fn name(&self) -> &'static str {
        match (self.kind, self.arte) {
            (ControllerKind::Mfc, false) => "mfc",
            (ControllerKind::Src, false) => "src",
            (ControllerKind::Mtte, false) => "mtte",
            (ControllerKind::Mfc, true) => "mfc-arte",
            (ControllerKind::Src, true) => "src-arte",
            (ControllerKind::Mtte, true) => "mtte-arte",
        }
    }

    /// The paper's spelling: `MFC`, `SRC-ARTE`, ...
    pub fn label(&self) -> &'static str {
        match (self.kind, self.arte) {
            (ControllerKind::Mfc, false) => "MFC",
            (ControllerKind::Src, false) => "SRC",
            (ControllerKind::Mtte, false) => "MTTE",
            (ControllerKind::Mfc, true) => "MFC-ARTE",
            (ControllerKind::Src, true) => "SRC-ARTE",
            (ControllerKind::Mtte, true) => "MTTE-ARTE",
        }
    }

    /// The same controller without ARTE.
    pub fn baseline(&self) -> Variant {
        Variant::new(self.kind, false)
    }

    /// Parse a comma-separated list (`mfc,src-arte`); `all` gives the six.
    /// Duplicates are dropped, order kept.
    pub fn parse_list(s: &str) -> Result<Vec<Variant>, UnknownVariant> {
        let mut out = Vec::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            if part.eq_ignore_ascii_case("all") {
                for v in Variant::ALL {
                    if !out.contains(&v) {
                        out.push(v);
                    }
                }
                continue;
            }
            let v: Variant = part.parse()?;
            if !out.contains(&v) {
                out.push(v);
            }
        }
        if out.is_empty() {
            return Err(UnknownVariant(s.to_owned()));
        }
        Ok(out)
    }
}

impl fmt::Display for Variant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A variant name that is not one of the six.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown variant `{0}` (expected a comma-separated list of: mfc, src, mtte, mfc-arte, src-arte, mtte-arte, or all)"
)]
pub struct UnknownVariant(pub String);

impl FromStr for Variant {
    type Err = UnknownVariant;
    /// Case-insensitive `mfc`, `src`, `mtte`, optionally with `-arte` (or `_arte`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let l = s.trim().to_ascii_lowercase().replace('_', "-");
        let (base, arte) = match l.strip_suffix("-arte") {
            Some(b) => (b, true),
            None => (l.as_str(), false),
        };
        let kind = base
            .parse::<ControllerKind>()
            .map_err(|_| UnknownVariant(s.to_owned()))?;
        Ok(Variant::new(kind, arte))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for v in Variant::ALL {
            assert_eq!(v.name().parse::<Variant>().unwrap(), v);
            assert_eq!(v.label().parse::<Variant>().unwrap(), v);
        }
        assert!("abs".parse::<Variant>().is_err());
        assert!("mfc-arte-arte".parse::<Variant>().is_err());
    }

    #[test]
    fn lists() {
        assert_eq!(Variant::parse_list("all").unwrap(), Variant::ALL.to_vec());
        assert_eq!(
            Variant::parse_list("src, src-arte,src").unwrap(),
            vec![Variant::ALL[1], Variant::ALL[4]]
        );
        let e = Variant::parse_list("mfc,foo").unwrap_err();
        assert!(e.to_string().contains("foo"));
        assert!(Variant::parse_list(" , ").is_err());
    }
}
