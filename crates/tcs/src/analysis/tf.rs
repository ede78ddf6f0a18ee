//! SISO rational transfer functions `num(s) / den(s)`.

use nalgebra::Complex;

use super::AnalysisError;
use super::poly::Poly;

/// Relative tolerance below which a root counts as lying on the imaginary
/// axis: `|Re r| <= AXIS_TOL * |r|` (exact zeros always do). Companion-matrix
/// roots are accurate to about 1e-15 |r| when simple and to about 1e-8 |r|
/// when double, so 1e-6 separates "on the axis up to rounding" from a
/// genuine (if slow) pole.
pub const AXIS_TOL: f64 = 1e-6;

/// Relative distance below which a numerator and a denominator root are
/// taken as a common factor by [`Tf::minreal`].
pub const CANCEL_TOL: f64 = 1e-6;

/// Where a root lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Half {
    /// Open left half plane.
    Left,
    /// On the imaginary axis (within [`AXIS_TOL`]).
    Axis,
    /// Open right half plane.
    Right,
}

/// Classify a root by half plane.
pub fn half_of(r: Complex<f64>) -> Half {
    if r.re.abs() <= AXIS_TOL * r.norm() {
        Half::Axis
    } else if r.re > 0.0 {
        Half::Right
    } else {
        Half::Left
    }
}

/// A SISO transfer function with real coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct Tf {
    /// Numerator.
    pub num: Poly,
    /// Denominator (never the zero polynomial).
    pub den: Poly,
}

impl Tf {
    /// `num / den`; fails when the denominator is the zero polynomial.
    pub fn new(num: Poly, den: Poly) -> Result<Self, AnalysisError> {
        if den.is_zero() {
            return Err(AnalysisError::ZeroDenominator);
        }
        Ok(Self { num, den })
    }

    /// From coefficient slices, highest power first.
    pub fn from_coeffs(num: &[f64], den: &[f64]) -> Result<Self, AnalysisError> {
        Self::new(Poly::new(num)?, Poly::new(den)?)
    }

    /// A constant gain.
    pub fn gain(k: f64) -> Self {
        Self {
            num: Poly::constant(k),
            den: Poly::constant(1.0),
        }
    }

    /// Value at a complex point (may be infinite at a pole).
    pub fn eval_c(&self, s: Complex<f64>) -> Complex<f64> {
        self.num.eval_c(s) / self.den.eval_c(s)
    }

    /// Frequency response P(jω).
    pub fn freq_response(&self, omega: f64) -> Complex<f64> {
        self.eval_c(Complex::new(0.0, omega))
    }

    /// Poles (roots of the denominator as given; call [`Tf::minreal`] first
    /// if the representation may hold common factors).
    pub fn poles(&self) -> Result<Vec<Complex<f64>>, AnalysisError> {
        self.den.roots()
    }

    /// Finite zeros (roots of the numerator; none for a zero numerator).
    pub fn zeros(&self) -> Result<Vec<Complex<f64>>, AnalysisError> {
        if self.num.is_zero() {
            return Ok(Vec::new());
        }
        self.num.roots()
    }

    /// Number of poles in the open right half plane, η(P).
    pub fn rhp_poles(&self) -> Result<usize, AnalysisError> {
        Ok(self
            .poles()?
            .into_iter()
            .filter(|&p| half_of(p) == Half::Right)
            .count())
    }

    /// Number of poles on the imaginary axis, η₀(P) (with multiplicity).
    pub fn imag_axis_poles(&self) -> Result<usize, AnalysisError> {
        Ok(self
            .poles()?
            .into_iter()
            .filter(|&p| half_of(p) == Half::Axis)
            .count())
    }

    /// Relative degree deg(den) - deg(num) (negative when improper).
    pub fn relative_degree(&self) -> i64 {
        let dn = self.num.degree().map_or(0, |d| d as i64);
        let dd = self.den.degree().map_or(0, |d| d as i64);
        dd - dn
    }

    /// Product (series connection).
    pub fn mul(&self, other: &Self) -> Self {
        Self {
            num: self.num.mul(&other.num),
            den: self.den.mul(&other.den),
        }
    }

    /// Multiply by a constant.
    pub fn scale(&self, k: f64) -> Self {
        Self {
            num: self.num.scale(k),
            den: self.den.clone(),
        }
    }

    /// Remove common numerator/denominator roots (within [`CANCEL_TOL`],
    /// relative). Returns the reduced transfer function and the number of
    /// cancelled factors. When nothing cancels the coefficients are kept
    /// bit for bit.
    pub fn minreal(&self) -> Result<(Self, usize), AnalysisError> {
        if self.num.is_zero() {
            return Ok((
                Self {
                    num: Poly::constant(0.0),
                    den: Poly::constant(1.0),
                },
                0,
            ));
        }
        let zs = self.zeros()?;
        let mut ps = self.poles()?;
        let mut kept_z = Vec::with_capacity(zs.len());
        let mut cancelled = 0;
        for z in zs {
            let hit = ps
                .iter()
                .enumerate()
                .filter(|(_, p)| (z - **p).norm() <= CANCEL_TOL * z.norm().max(p.norm()))
                .min_by(|a, b| (z - a.1).norm().total_cmp(&(z - b.1).norm()))
                .map(|(i, _)| i);
            match hit {
                Some(i) => {
                    ps.swap_remove(i);
                    cancelled += 1;
                }
                None => kept_z.push(z),
            }
        }
        if cancelled == 0 {
            return Ok((self.clone(), 0));
        }
        let num = Poly::from_roots(self.num.leading(), &kept_z);
        let den = Poly::from_roots(self.den.leading(), &ps);
        Ok((Self { num, den }, cancelled))
    }

    /// `num / den` written out, e.g. `(100) / (2 s + 1)`.
    pub fn to_pretty(&self) -> String {
        format!("({}) / ({})", self.num.to_pretty(), self.den.to_pretty())
    }
}

/// Format a list of roots compactly: `-1, -0.5 ± 2j`. Conjugate pairs are
/// merged.
pub fn fmt_roots(roots: &[Complex<f64>]) -> String {
    use super::poly::fmt_num;
    let mut rs: Vec<Complex<f64>> = roots.to_vec();
    rs.sort_by(|a, b| a.re.total_cmp(&b.re).then(b.im.total_cmp(&a.im)));
    let mut parts = Vec::new();
    let mut skip = vec![false; rs.len()];
    for i in 0..rs.len() {
        if skip[i] {
            continue;
        }
        let r = rs[i];
        if r.im == 0.0 {
            parts.push(sign_num(r.re));
        } else {
            // find the conjugate
            if let Some(j) = (i + 1..rs.len())
                .find(|&j| !skip[j] && (rs[j] - r.conj()).norm() <= 1e-9 * r.norm().max(1e-300))
            {
                skip[j] = true;
                parts.push(format!("{} ± {}j", sign_num(r.re), fmt_num(r.im.abs())));
            } else {
                let sgn = if r.im < 0.0 { "-" } else { "+" };
                parts.push(format!("{} {sgn} {}j", sign_num(r.re), fmt_num(r.im.abs())));
            }
        }
    }
    if parts.is_empty() {
        "none".into()
    } else {
        parts.join(", ")
    }
}

fn sign_num(x: f64) -> String {
    super::poly::fmt_num(if x == 0.0 { 0.0 } else { x })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn response_poles_counts() {
        // 100 / (2 s - 1): one RHP pole at 0.5
        let p = Tf::from_coeffs(&[100.0], &[2.0, -1.0]).unwrap();
        let v = p.freq_response(0.0);
        assert!((v.re + 100.0).abs() < 1e-12 && v.im == 0.0);
        assert_eq!(p.rhp_poles().unwrap(), 1);
        assert_eq!(p.imag_axis_poles().unwrap(), 0);
        // 1 / (s (s^2 + 4)): three axis poles
        let q = Tf::from_coeffs(&[1.0], &[1.0, 0.0, 4.0, 0.0]).unwrap();
        assert_eq!(q.imag_axis_poles().unwrap(), 3);
        assert_eq!(q.rhp_poles().unwrap(), 0);
        assert!(Tf::from_coeffs(&[1.0], &[0.0]).is_err());
    }

    #[test]
    fn minreal_cancels_common_factor() {
        // (s - 1)(s + 3) / ((s - 1)(s + 2)(s + 5))
        let num = Poly::linear(1.0).mul(&Poly::linear(-3.0));
        let den = Poly::linear(1.0)
            .mul(&Poly::linear(-2.0))
            .mul(&Poly::linear(-5.0));
        let p = Tf::new(num, den).unwrap();
        assert_eq!(p.rhp_poles().unwrap(), 1);
        let (m, k) = p.minreal().unwrap();
        assert_eq!(k, 1);
        assert_eq!(m.rhp_poles().unwrap(), 0);
        assert_eq!(m.den.degree(), Some(2));
        let w = 0.7;
        assert!((m.freq_response(w) - p.freq_response(w)).norm() < 1e-12);
    }

    #[test]
    fn roots_formatting() {
        let r = [
            Complex::new(-1.0, 2.0),
            Complex::new(-1.0, -2.0),
            Complex::new(0.5, 0.0),
        ];
        assert_eq!(fmt_roots(&r), "-1 ± 2j, 0.5");
    }
}
