//! Roads: friction-vs-slip (mu-lambda) curves and the road catalogue
//! (README.md, "Roads").
//!
//! Every curve is defined for driving slip λ >= 0 and extended odd-symmetrically
//! to braking (λ < 0): mu(-λ) = -mu(λ), so dmu/dλ is even.
//!
//! `lambda_opt` and `mu_peak` are computed once at construction, over
//! λ ∈ [0, 1]:
//! - Burckhardt: closed form λ_opt = ln(c1 c2 / c3) / c2 when that lies in (0, 1].
//! - Pacejka with E = 0: closed form λ_opt = tan(π / (2C)) / B, mu_peak = D,
//!   when C > 1 and that λ lies in (0, 1].
//! - Otherwise numerically: a 2001-point grid over [0, 1], then golden-section
//!   refinement around the best grid point (for tables: the best knot, exact
//!   for a piecewise-linear curve).
//!
//! **Monotonic curves** (ice with c3 = 0, or any curve whose maximum over
//! [0, 1] is at λ = 1): mu_peak is mu(1), the largest friction the road
//! offers on [0, 1], and λ_opt is the *smallest slip reaching 99 % of
//! mu_peak* ([`PLATEAU_FRACTION`]). Reporting λ_opt = 1 would tell a slip
//! controller to spin the wheel at full slip for the last 1 % of traction;
//! the 99 % point is where extra slip stops buying traction. For Burckhardt
//! with c3 = 0 this is ln(100)/c2 in closed form (ice: 0.0150).

use crate::validate::{self, InvalidField};

/// Fraction of mu_peak that defines λ_opt on monotonic curves (see the module docs).
pub const PLATEAU_FRACTION: f64 = 0.99;

/// Number of grid intervals for numerical maximisation over λ ∈ [0, 1].
const GRID: usize = 2000;

/// A friction-vs-slip model. All are odd-symmetric in λ.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum FrictionModel {
    /// Burckhardt: mu(λ) = c1 (1 - e^(-c2 λ)) - c3 λ for λ >= 0.
    Burckhardt {
        /// Saturation level.
        c1: f64,
        /// Shape (initial rise).
        c2: f64,
        /// Linear decrease after the peak.
        c3: f64,
    },
    /// Pacejka's Magic Formula: mu(λ) = D sin(C atan(B λ - E (B λ - atan(B λ)))).
    Pacejka {
        /// Stiffness factor.
        b: f64,
        /// Shape factor.
        c: f64,
        /// Peak value.
        d: f64,
        /// Curvature factor.
        e: f64,
    },
    /// Measured table, linear interpolation between knots; `slip` strictly
    /// increasing from 0 with mu(0) = 0; beyond the last knot mu stays at the
    /// last value.
    Table {
        /// Slip knots, strictly increasing, first = 0.
        slip: Vec<f64>,
        /// Friction at each knot, first = 0.
        mu: Vec<f64>,
    },
}

impl FrictionModel {
    /// Short name of the model kind: `burckhardt`, `pacejka` or `table`.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Burckhardt { .. } => "burckhardt",
            Self::Pacejka { .. } => "pacejka",
            Self::Table { .. } => "table",
        }
    }

    /// Check that the parameters describe a usable traction curve
    /// (finite, positive initial slope, positive friction somewhere on (0, 1]).
    pub fn validate(&self) -> Result<(), InvalidField> {
        match *self {
            Self::Burckhardt { c1, c2, c3 } => {
                validate::positive("c1", c1)?;
                validate::positive("c2", c2)?;
                validate::non_negative("c3", c3)?;
                if c1 * c2 <= c3 {
                    return Err(InvalidField::new(
                        "c3",
                        format!(
                            "initial slope c1*c2 - c3 must be > 0 (got {})",
                            c1 * c2 - c3
                        ),
                    ));
                }
                Ok(())
            }
            Self::Pacejka { b, c, d, e } => {
                validate::positive("b", b)?;
                if !(c.is_finite() && c > 0.0 && c < 3.0) {
                    return Err(InvalidField::new(
                        "c",
                        format!("must be in (0, 3) (got {c})"),
                    ));
                }
                validate::positive("d", d)?;
                // E <= 1 keeps B λ - E (B λ - atan B λ) increasing in λ.
                if !(e.is_finite() && e <= 1.0) {
                    return Err(InvalidField::new(
                        "e",
                        format!("must be finite and <= 1 (got {e})"),
                    ));
                }
                // With C > 2 the sine can turn negative at large slip: reject
                // curves that do so on (0, 1] (not a traction curve).
                for i in 1..=GRID {
                    let l = i as f64 / GRID as f64;
                    if self.mu_pos(l) <= 0.0 {
                        return Err(InvalidField::new(
                            "c",
                            format!(
                                "mu(λ) <= 0 at λ = {l} with C = {c}, E = {e}: not a traction curve"
                            ),
                        ));
                    }
                }
                Ok(())
            }
            Self::Table { ref slip, ref mu } => {
                if slip.len() != mu.len() {
                    return Err(InvalidField::new(
                        "mu",
                        format!("has {} values but slip has {}", mu.len(), slip.len()),
                    ));
                }
                if slip.len() < 2 {
                    return Err(InvalidField::new(
                        "slip",
                        format!("needs at least 2 points (got {})", slip.len()),
                    ));
                }
                for (i, (&s, &m)) in slip.iter().zip(mu).enumerate() {
                    validate::finite(&format!("slip[{i}]"), s)?;
                    validate::finite(&format!("mu[{i}]"), m)?;
                    if m < 0.0 {
                        return Err(InvalidField::new(
                            format!("mu[{i}]"),
                            format!("must be >= 0 (got {m})"),
                        ));
                    }
                    if i > 0 && s <= slip[i - 1] {
                        return Err(InvalidField::new(
                            format!("slip[{i}]"),
                            format!(
                                "must be strictly increasing (got {s} after {})",
                                slip[i - 1]
                            ),
                        ));
                    }
                }
                if slip[0] != 0.0 {
                    return Err(InvalidField::new(
                        "slip[0]",
                        format!("must be 0 (got {})", slip[0]),
                    ));
                }
                if mu[0] != 0.0 {
                    return Err(InvalidField::new(
                        "mu[0]",
                        format!("must be 0: no friction force at zero slip (got {})", mu[0]),
                    ));
                }
                if mu[1] <= 0.0 {
                    return Err(InvalidField::new(
                        "mu[1]",
                        format!("must be > 0 (got {})", mu[1]),
                    ));
                }
                Ok(())
            }
        }
    }

    /// mu(λ) for λ >= 0 (no symmetry handling).
    #[inline]
    fn mu_pos(&self, l: f64) -> f64 {
        match *self {
            Self::Burckhardt { c1, c2, c3 } => c1 * (1.0 - (-c2 * l).exp()) - c3 * l,
            Self::Pacejka { b, c, d, e } => {
                let bl = b * l;
                d * (c * (bl - e * (bl - bl.atan())).atan()).sin()
            }
            Self::Table { ref slip, ref mu } => {
                let n = slip.len();
                if l >= slip[n - 1] {
                    return mu[n - 1];
                }
                // First knot strictly greater than l; l >= 0 = slip[0] so k >= 1.
                let k = slip.partition_point(|&s| s <= l).max(1);
                let (s0, s1, m0, m1) = (slip[k - 1], slip[k], mu[k - 1], mu[k]);
                m0 + (m1 - m0) * (l - s0) / (s1 - s0)
            }
        }
    }

    /// dmu/dλ for λ >= 0.
    #[inline]
    fn dmu_pos(&self, l: f64) -> f64 {
        match *self {
            Self::Burckhardt { c1, c2, c3 } => c1 * c2 * (-c2 * l).exp() - c3,
            Self::Pacejka { b, c, d, e } => {
                let bl = b * l;
                let z = bl - e * (bl - bl.atan());
                let dz = b * (1.0 - e) + e * b / (1.0 + bl * bl);
                d * (c * z.atan()).cos() * c * dz / (1.0 + z * z)
            }
            Self::Table { ref slip, ref mu } => {
                let n = slip.len();
                if l >= slip[n - 1] {
                    return 0.0;
                }
                let k = slip.partition_point(|&s| s <= l).max(1);
                (mu[k] - mu[k - 1]) / (slip[k] - slip[k - 1])
            }
        }
    }

    /// mu(λ), odd-symmetric: mu(-λ) = -mu(λ). Allocation-free.
    #[inline]
    pub fn mu(&self, lambda: f64) -> f64 {
        if lambda >= 0.0 {
            self.mu_pos(lambda)
        } else {
            -self.mu_pos(-lambda)
        }
    }

    /// dmu/dλ, even: dmu/dλ(-λ) = dmu/dλ(λ). For tables, the slope of the
    /// segment to the right of λ (0 beyond the last knot). Allocation-free.
    #[inline]
    pub fn dmu_dlambda(&self, lambda: f64) -> f64 {
        self.dmu_pos(lambda.abs())
    }

    /// (λ_opt, mu_peak) in closed form where it exists, else `None`.
    pub fn peak_closed_form(&self) -> Option<(f64, f64)> {
        match *self {
            Self::Burckhardt { c1, c2, c3 } => {
                if c3 == 0.0 {
                    // Monotonic: 99 % of mu(1) (module docs).
                    let mu1 = c1 * (1.0 - (-c2).exp());
                    let target = PLATEAU_FRACTION * mu1;
                    let l = -(1.0 - target / c1).ln() / c2;
                    return Some((l, mu1));
                }
                let l = (c1 * c2 / c3).ln() / c2;
                (l > 0.0 && l <= 1.0).then(|| (l, self.mu_pos(l)))
            }
            Self::Pacejka { b, c, d, e } => {
                if e != 0.0 || c <= 1.0 {
                    return None;
                }
                let l = (std::f64::consts::FRAC_PI_2 / c).tan() / b;
                (l > 0.0 && l <= 1.0).then_some((l, d))
            }
            Self::Table { .. } => None,
        }
    }

    /// (λ_opt, mu_peak) by numerical maximisation over [0, 1] (module docs),
    /// regardless of whether a closed form exists. Used at construction when
    /// there is no closed form, and by tests to check the closed forms.
    pub fn peak_numeric(&self) -> (f64, f64) {
        let mut best_i = 0;
        let mut best = f64::NEG_INFINITY;
        for i in 0..=GRID {
            let l = i as f64 / GRID as f64;
            let m = self.mu_pos(l);
            if m > best {
                best = m;
                best_i = i;
            }
        }
        let (mut l_opt, mut mu_peak) = (best_i as f64 / GRID as f64, best);
        if let Self::Table { ref slip, ref mu } = *self {
            // Piecewise linear: the maximum on [0, 1] is at a knot or at 1.
            for (&s, &m) in slip.iter().zip(mu) {
                if s <= 1.0 && m > mu_peak {
                    mu_peak = m;
                    l_opt = s;
                }
            }
            // The first knot reaching the maximum (flat tops report their start).
            if let Some((&s, _)) = slip
                .iter()
                .zip(mu)
                .find(|&(&s, &m)| s <= 1.0 && m >= mu_peak)
            {
                l_opt = s;
            }
        } else if best_i > 0 && best_i < GRID {
            // Golden-section refinement on the bracket around the best grid point.
            let (mut a, mut b) = (
                (best_i - 1) as f64 / GRID as f64,
                (best_i + 1) as f64 / GRID as f64,
            );
            let g = 0.5 * (5f64.sqrt() - 1.0);
            let mut x1 = b - g * (b - a);
            let mut x2 = a + g * (b - a);
            let (mut f1, mut f2) = (self.mu_pos(x1), self.mu_pos(x2));
            for _ in 0..80 {
                if f1 > f2 {
                    b = x2;
                    x2 = x1;
                    f2 = f1;
                    x1 = b - g * (b - a);
                    f1 = self.mu_pos(x1);
                } else {
                    a = x1;
                    x1 = x2;
                    f1 = f2;
                    x2 = a + g * (b - a);
                    f2 = self.mu_pos(x2);
                }
                if b - a < 1e-13 {
                    break;
                }
            }
            let l = 0.5 * (a + b);
            let m = self.mu_pos(l);
            if m >= mu_peak {
                l_opt = l;
                mu_peak = m;
            }
        }
        // Monotonic on [0, 1] (maximum at λ = 1, up to rounding: ice's mu is
        // flat to machine precision long before λ = 1): smallest λ reaching
        // 99 % of mu(1), by a grid scan for the first crossing then bisection.
        let mu1 = self.mu_pos(1.0);
        if mu1 >= mu_peak * (1.0 - 1e-12) {
            mu_peak = mu_peak.max(mu1);
            let target = PLATEAU_FRACTION * mu_peak;
            let mut hi = 1.0;
            for i in 1..=GRID {
                let l = i as f64 / GRID as f64;
                if self.mu_pos(l) >= target {
                    hi = l;
                    break;
                }
            }
            let mut lo = hi - 1.0 / GRID as f64;
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if self.mu_pos(mid) >= target {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            l_opt = hi;
        }
        (l_opt, mu_peak)
    }
}

/// The longest road name, bytes: a road's name travels in the services'
/// messages (ground truth, road estimates) in a field of this many bytes
/// (`grip_msgs::NAME_LEN`); a longer one would be cut there, and two roads
/// alike in their first 16 bytes would be one road to the services.
pub const NAME_MAX_BYTES: usize = 16;

/// One road: a named friction curve with its optimum cached.
#[derive(Debug, Clone, PartialEq)]
pub struct Road {
    name: String,
    label: Option<String>,
    model: FrictionModel,
    lambda_opt: f64,
    mu_peak: f64,
}

impl Road {
    /// Validate `model` and compute λ_opt and mu_peak (closed form where it
    /// exists, numerically otherwise; see the module docs).
    pub fn new(name: impl Into<String>, model: FrictionModel) -> Result<Self, InvalidField> {
        let name = name.into();
        if name.trim().is_empty() {
            return Err(InvalidField::new("name", "must not be empty"));
        }
        if name.len() > NAME_MAX_BYTES {
            return Err(InvalidField::new(
                "name",
                format!(
                    "`{name}` is {} bytes long; at most {NAME_MAX_BYTES} (a road's name travels in a {NAME_MAX_BYTES}-byte field of the services' messages)",
                    name.len()
                ),
            ));
        }
        model.validate()?;
        let (lambda_opt, mu_peak) = model
            .peak_closed_form()
            .unwrap_or_else(|| model.peak_numeric());
        if !(mu_peak > 0.0 && lambda_opt > 0.0 && lambda_opt <= 1.0) {
            return Err(InvalidField::new(
                "model",
                format!(
                    "curve has no positive friction peak on (0, 1] (lambda_opt {lambda_opt}, mu_peak {mu_peak})"
                ),
            ));
        }
        Ok(Self {
            name,
            label: None,
            model,
            lambda_opt,
            mu_peak,
        })
    }

    /// A Burckhardt road (convenience for tests and examples).
    pub fn burckhardt(name: &str, c1: f64, c2: f64, c3: f64) -> Result<Self, InvalidField> {
        Self::new(name, FrictionModel::Burckhardt { c1, c2, c3 })
    }

    /// The same road with a display label for plots and tables.
    pub fn with_label(mut self, label: impl Into<String>) -> Self {
        self.label = Some(label.into());
        self
    }

    /// The road's name (catalogue key, e.g. `asphalt`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Display label: the configured label, or the name.
    pub fn label(&self) -> &str {
        self.label.as_deref().unwrap_or(&self.name)
    }

    /// The friction model.
    pub fn model(&self) -> &FrictionModel {
        &self.model
    }

    /// Friction coefficient at slip λ (odd in λ). Allocation-free.
    #[inline]
    pub fn mu(&self, lambda: f64) -> f64 {
        self.model.mu(lambda)
    }

    /// Slope dmu/dλ at slip λ (even in λ). Allocation-free.
    #[inline]
    pub fn dmu_dlambda(&self, lambda: f64) -> f64 {
        self.model.dmu_dlambda(lambda)
    }

    /// Optimal slip on [0, 1] (see the module docs for monotonic curves).
    pub fn lambda_opt(&self) -> f64 {
        self.lambda_opt
    }

    /// Peak friction coefficient on [0, 1].
    pub fn mu_peak(&self) -> f64 {
        self.mu_peak
    }
}

/// An ordered set of roads with unique names; lookup by name or index.
#[derive(Debug, Clone, PartialEq)]
pub struct RoadCatalogue {
    roads: Vec<Road>,
}

/// Burckhardt's published parameter sets (name, c1, c2, c3), the values
/// `config/roads.toml` ships: dry asphalt, wet asphalt, dry cobblestone,
/// wet cobblestone, snow, ice.
pub const BURCKHARDT: [(&str, f64, f64, f64); 6] = [
    ("asphalt", 1.2801, 23.99, 0.52),
    ("wet_asphalt", 0.857, 33.822, 0.347),
    ("stone", 1.3713, 6.4565, 0.6691),
    ("wet_stone", 0.4004, 33.708, 0.1204),
    ("snow", 0.1946, 94.129, 0.0646),
    ("ice", 0.05, 306.39, 0.0),
];

impl RoadCatalogue {
    /// A catalogue of [`BURCKHARDT`] roads in the order named (examples,
    /// tests); an unknown name is an error naming it.
    pub fn burckhardt(names: &[&str]) -> Result<Self, InvalidField> {
        let roads = names
            .iter()
            .map(|&n| {
                let (_, c1, c2, c3) = BURCKHARDT
                    .iter()
                    .find(|b| b.0 == n)
                    .ok_or_else(|| InvalidField::new("road", format!("no Burckhardt set `{n}`")))?;
                Road::burckhardt(n, *c1, *c2, *c3)
            })
            .collect::<Result<Vec<_>, _>>()?;
        Self::new(roads)
    }

    /// A catalogue from roads in order; fails when empty or when a name repeats
    /// (the error's field is `road[i].name`).
    pub fn new(roads: Vec<Road>) -> Result<Self, InvalidField> {
        if roads.is_empty() {
            return Err(InvalidField::new("road", "the road list is empty"));
        }
        for (i, r) in roads.iter().enumerate() {
            if let Some(j) = roads[..i].iter().position(|o| o.name == r.name) {
                return Err(InvalidField::new(
                    format!("road[{i}].name"),
                    format!("duplicate road name `{}` (also road[{j}])", r.name),
                ));
            }
        }
        Ok(Self { roads })
    }

    /// Roads in catalogue order.
    pub fn roads(&self) -> &[Road] {
        &self.roads
    }

    /// Iterate in catalogue order.
    pub fn iter(&self) -> std::slice::Iter<'_, Road> {
        self.roads.iter()
    }

    /// Number of roads (never 0).
    pub fn len(&self) -> usize {
        self.roads.len()
    }

    /// Always false (a catalogue is never empty); here for clippy's sake.
    pub fn is_empty(&self) -> bool {
        self.roads.is_empty()
    }

    /// Index of the road called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.roads.iter().position(|r| r.name == name)
    }

    /// The road called `name`.
    pub fn get(&self, name: &str) -> Option<&Road> {
        self.roads.iter().find(|r| r.name == name)
    }

    /// The road at `index`.
    pub fn by_index(&self, index: usize) -> Option<&Road> {
        self.roads.get(index)
    }

    /// Names in order, comma-separated (for error messages).
    pub fn names(&self) -> String {
        self.roads
            .iter()
            .map(|r| r.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl std::ops::Index<usize> for RoadCatalogue {
    type Output = Road;
    fn index(&self, i: usize) -> &Road {
        &self.roads[i]
    }
}

impl<'a> IntoIterator for &'a RoadCatalogue {
    type Item = &'a Road;
    type IntoIter = std::slice::Iter<'a, Road>;
    fn into_iter(self) -> Self::IntoIter {
        self.roads.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn asphalt() -> Road {
        Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap()
    }

    #[test]
    fn burckhardt_catalogue_by_name() {
        let c = RoadCatalogue::burckhardt(&["snow", "asphalt"]).unwrap();
        assert_eq!(c.names(), "snow, asphalt");
        assert!((c[1].lambda_opt() - 0.170).abs() < 1e-3);
        let e = RoadCatalogue::burckhardt(&["tarmac"]).unwrap_err();
        assert!(e.reason.contains("`tarmac`"), "{e:?}");
    }

    #[test]
    fn burckhardt_closed_forms_match_models_md() {
        // README.md's catalogue table: (c1, c2, c3, λ_opt, mu_peak) to the printed precision.
        let cases = [
            ("asphalt", 1.2801, 23.99, 0.52, 0.170, 1.17),
            ("stone", 1.3713, 6.4565, 0.6691, 0.400, 1.00),
            ("snow", 0.1946, 94.129, 0.0646, 0.060, 0.19),
        ];
        for (name, c1, c2, c3, l, m) in cases {
            let r = Road::burckhardt(name, c1, c2, c3).unwrap();
            assert!(
                (r.lambda_opt() - l).abs() < 0.0015,
                "{name}: lambda_opt {}",
                r.lambda_opt()
            );
            assert!(
                (r.mu_peak() - m).abs() < 0.006,
                "{name}: mu_peak {}",
                r.mu_peak()
            );
        }
    }

    #[test]
    fn closed_form_agrees_with_numeric_maximisation() {
        let models = [
            FrictionModel::Burckhardt {
                c1: 1.2801,
                c2: 23.99,
                c3: 0.52,
            },
            FrictionModel::Burckhardt {
                c1: 1.3713,
                c2: 6.4565,
                c3: 0.6691,
            },
            FrictionModel::Burckhardt {
                c1: 0.1946,
                c2: 94.129,
                c3: 0.0646,
            },
            FrictionModel::Burckhardt {
                c1: 0.857,
                c2: 33.822,
                c3: 0.347,
            },
            FrictionModel::Burckhardt {
                c1: 0.4004,
                c2: 33.708,
                c3: 0.1204,
            },
            FrictionModel::Burckhardt {
                c1: 0.05,
                c2: 306.39,
                c3: 0.0,
            },
            FrictionModel::Pacejka {
                b: 10.0,
                c: 1.9,
                d: 1.0,
                e: 0.0,
            },
            FrictionModel::Pacejka {
                b: 4.0,
                c: 1.3,
                d: 0.6,
                e: 0.0,
            },
        ];
        for m in models {
            let (lc, mc) = m.peak_closed_form().expect("closed form exists");
            let (ln, mn) = m.peak_numeric();
            assert!((lc - ln).abs() < 1e-6, "{m:?}: closed {lc} numeric {ln}");
            assert!((mc - mn).abs() < 1e-9, "{m:?}: closed {mc} numeric {mn}");
        }
    }

    #[test]
    fn ice_is_monotonic_and_reports_the_99_percent_point() {
        let ice = Road::burckhardt("ice", 0.05, 306.39, 0.0).unwrap();
        assert!((ice.mu_peak() - 0.05).abs() < 1e-12);
        assert!((ice.lambda_opt() - 100f64.ln() / 306.39).abs() < 1e-9);
        assert!((ice.mu(ice.lambda_opt()) - 0.99 * ice.mu_peak()).abs() < 1e-12);
        // The curve never turns down.
        for i in 1..1000 {
            let l = i as f64 / 1000.0;
            assert!(ice.mu(l) >= ice.mu(l - 0.001));
        }
    }

    #[test]
    fn pacejka_with_curvature_uses_numeric_peak() {
        let m = FrictionModel::Pacejka {
            b: 11.7,
            c: 1.69,
            d: 1.2,
            e: 0.377,
        };
        assert!(m.peak_closed_form().is_none());
        let r = Road::new("p", m.clone()).unwrap();
        // Stationary point: derivative ~ 0 and D reached (sin = 1 at the peak).
        assert!(r.dmu_dlambda(r.lambda_opt()).abs() < 1e-6);
        assert!((r.mu_peak() - 1.2).abs() < 1e-9);
    }

    #[test]
    fn pacejka_shape_limits() {
        // C > 2 is fine while the curve stays positive (E = 1 bounds the argument).
        assert!(
            Road::new(
                "w",
                FrictionModel::Pacejka {
                    b: 12.0,
                    c: 2.3,
                    d: 0.82,
                    e: 1.0
                }
            )
            .is_ok()
        );
        // C = 2.5 with E = 0 turns negative at large slip.
        let e = Road::new(
            "n",
            FrictionModel::Pacejka {
                b: 12.0,
                c: 2.5,
                d: 0.82,
                e: 0.0,
            },
        )
        .unwrap_err();
        assert_eq!(e.field, "c");
    }

    #[test]
    fn table_interpolates_and_clamps() {
        let m = FrictionModel::Table {
            slip: vec![0.0, 0.1, 0.2, 0.5],
            mu: vec![0.0, 0.5, 0.6, 0.4],
        };
        let r = Road::new("t", m).unwrap();
        assert!((r.mu(0.05) - 0.25).abs() < 1e-12);
        assert!((r.mu(0.15) - 0.55).abs() < 1e-12);
        assert!((r.mu(0.35) - 0.5).abs() < 1e-12);
        assert!((r.mu(0.9) - 0.4).abs() < 1e-12);
        assert!((r.mu(-0.15) + 0.55).abs() < 1e-12);
        assert!((r.dmu_dlambda(0.05) - 5.0).abs() < 1e-12);
        assert!((r.dmu_dlambda(-0.05) - 5.0).abs() < 1e-12);
        assert_eq!(r.dmu_dlambda(0.7), 0.0);
        assert!((r.lambda_opt() - 0.2).abs() < 1e-12);
        assert!((r.mu_peak() - 0.6).abs() < 1e-12);
    }

    #[test]
    fn table_rejections() {
        let bad = [
            (vec![0.0, 0.1], vec![0.0], "mu"),
            (vec![0.0, 0.1, 0.1], vec![0.0, 0.5, 0.6], "slip[2]"),
            (vec![0.01, 0.1], vec![0.0, 0.5], "slip[0]"),
            (vec![0.0, 0.1], vec![0.1, 0.5], "mu[0]"),
            (vec![0.0, f64::NAN], vec![0.0, 0.5], "slip[1]"),
        ];
        for (slip, mu, field) in bad {
            let e = Road::new("t", FrictionModel::Table { slip, mu }).unwrap_err();
            assert_eq!(e.field, field, "{e}");
        }
    }

    #[test]
    fn burckhardt_rejections() {
        assert_eq!(
            Road::burckhardt("x", f64::NAN, 1.0, 0.0).unwrap_err().field,
            "c1"
        );
        assert_eq!(
            Road::burckhardt("x", 0.1, 1.0, 0.5).unwrap_err().field,
            "c3"
        );
        assert_eq!(
            Road::burckhardt("", 1.0, 10.0, 0.1).unwrap_err().field,
            "name"
        );
    }

    #[test]
    fn catalogue_lookup_and_duplicates() {
        let c = RoadCatalogue::new(vec![
            asphalt(),
            Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap(),
        ])
        .unwrap();
        assert_eq!(c.index_of("snow"), Some(1));
        assert_eq!(c.get("asphalt").unwrap().name(), "asphalt");
        assert_eq!(c[1].name(), "snow");
        assert!(c.get("gravel").is_none());
        assert_eq!(RoadCatalogue::new(vec![]).unwrap_err().field, "road");
        // a name the services' 16-byte field holds, and one it does not
        let m = || FrictionModel::Burckhardt {
            c1: 1.2801,
            c2: 23.99,
            c3: 0.52,
        };
        assert!(Road::new("a".repeat(NAME_MAX_BYTES), m()).is_ok());
        let e = Road::new("wet_asphalt_night", m()).unwrap_err();
        assert_eq!(e.field, "name");
        assert!(
            e.reason
                .contains("`wet_asphalt_night` is 17 bytes long; at most 16"),
            "{e}"
        );
        // bytes, not characters: 9 two-byte characters are 18 bytes
        assert!(Road::new("é".repeat(9), m()).is_err());
        assert_eq!(
            RoadCatalogue::new(vec![asphalt(), asphalt()])
                .unwrap_err()
                .field,
            "road[1].name"
        );
    }

    #[test]
    fn derivative_matches_finite_difference() {
        let roads = [
            asphalt(),
            Road::new(
                "p",
                FrictionModel::Pacejka {
                    b: 11.7,
                    c: 1.69,
                    d: 1.2,
                    e: 0.377,
                },
            )
            .unwrap(),
        ];
        for r in &roads {
            for i in 1..100 {
                let l = i as f64 / 100.0;
                let h = 1e-6;
                let fd = (r.mu(l + h) - r.mu(l - h)) / (2.0 * h);
                assert!(
                    (fd - r.dmu_dlambda(l)).abs() < 1e-5 * (1.0 + fd.abs()),
                    "{} at {l}",
                    r.name()
                );
            }
        }
    }

    proptest! {
        #[test]
        fn odd_symmetry(l in 0.0f64..2.0, c1 in 0.05f64..1.5, c2 in 5.0f64..300.0, c3 in 0.0f64..0.7,
                        b in 1.0f64..30.0, c in 1.05f64..1.95, d in 0.1f64..1.5, e in -2.0f64..1.0) {
            prop_assume!(c1 * c2 > c3);
            let models = [
                FrictionModel::Burckhardt { c1, c2, c3 },
                FrictionModel::Pacejka { b, c, d, e },
                FrictionModel::Table { slip: vec![0.0, 0.1, 0.3, 1.0], mu: vec![0.0, d, 0.9 * d, 0.7 * d] },
            ];
            for m in &models {
                prop_assert_eq!(m.mu(-l), -m.mu(l));
                prop_assert_eq!(m.dmu_dlambda(-l), m.dmu_dlambda(l));
                prop_assert!(m.mu(l).is_finite());
            }
        }
    }
}
