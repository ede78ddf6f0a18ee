//! Real-coefficient polynomials in s.
//!
//! Public constructors take coefficients **highest power first**, the way a
//! user types them (`[2.0, 1.0]` is 2 s + 1). Internally the coefficients are
//! stored lowest power first (`c[k]` multiplies s^k), which keeps the
//! arithmetic short.

use nalgebra::{Complex, DMatrix, Schur};

use super::AnalysisError;

/// A polynomial with real coefficients. Leading zero coefficients are
/// trimmed on construction, so `degree()` is exact; the zero polynomial has
/// no coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct Poly {
    /// Coefficients, lowest power first (`c[k]` multiplies s^k).
    c: Vec<f64>,
}

impl Poly {
    /// From coefficients highest power first (`[1, 3, 2]` = s^2 + 3 s + 2).
    /// Fails on NaN or infinite coefficients.
    pub fn new(desc: &[f64]) -> Result<Self, AnalysisError> {
        if let Some(i) = desc.iter().position(|x| !x.is_finite()) {
            return Err(AnalysisError::NonFinite {
                index: i,
                value: desc[i],
            });
        }
        let mut c: Vec<f64> = desc.iter().rev().copied().collect();
        trim(&mut c);
        Ok(Self { c })
    }

    /// From coefficients lowest power first (`c[k]` multiplies s^k).
    pub fn from_ascending(asc: Vec<f64>) -> Result<Self, AnalysisError> {
        if let Some(i) = asc.iter().position(|x| !x.is_finite()) {
            return Err(AnalysisError::NonFinite {
                index: i,
                value: asc[i],
            });
        }
        let mut c = asc;
        trim(&mut c);
        Ok(Self { c })
    }

    /// The constant polynomial `k`.
    pub fn constant(k: f64) -> Self {
        let mut c = vec![k];
        trim(&mut c);
        Self { c }
    }

    /// The polynomial `s`.
    pub fn s() -> Self {
        Self { c: vec![0.0, 1.0] }
    }

    /// The monic first-order factor `s - root` for a real root.
    pub fn linear(root: f64) -> Self {
        Self {
            c: vec![-root, 1.0],
        }
    }

    /// A polynomial from its (real or complex-conjugate-paired) roots and a
    /// leading coefficient. Complex roots must come with their conjugates;
    /// the imaginary parts left by rounding are dropped.
    pub fn from_roots(lead: f64, roots: &[Complex<f64>]) -> Self {
        let mut acc: Vec<Complex<f64>> = vec![Complex::new(lead, 0.0)];
        for r in roots {
            let mut next = vec![Complex::new(0.0, 0.0); acc.len() + 1];
            for (k, a) in acc.iter().enumerate() {
                next[k + 1] += a;
                next[k] -= a * r;
            }
            acc = next;
        }
        let mut c: Vec<f64> = acc.iter().map(|z| z.re).collect();
        trim(&mut c);
        Self { c }
    }

    /// Coefficients highest power first (empty for the zero polynomial).
    pub fn coeffs_desc(&self) -> Vec<f64> {
        self.c.iter().rev().copied().collect()
    }

    /// Coefficients lowest power first.
    pub fn coeffs_asc(&self) -> &[f64] {
        &self.c
    }

    /// Degree; `None` for the zero polynomial.
    pub fn degree(&self) -> Option<usize> {
        self.c.len().checked_sub(1)
    }

    /// True for the zero polynomial.
    pub fn is_zero(&self) -> bool {
        self.c.is_empty()
    }

    /// Leading coefficient (0 for the zero polynomial).
    pub fn leading(&self) -> f64 {
        self.c.last().copied().unwrap_or(0.0)
    }

    /// Coefficient of s^k (0 beyond the degree).
    pub fn coeff(&self, k: usize) -> f64 {
        self.c.get(k).copied().unwrap_or(0.0)
    }

    /// Value at a real point (Horner).
    pub fn eval(&self, s: f64) -> f64 {
        self.c.iter().rev().fold(0.0, |acc, &a| acc * s + a)
    }

    /// Value at a complex point (Horner).
    pub fn eval_c(&self, s: Complex<f64>) -> Complex<f64> {
        self.c
            .iter()
            .rev()
            .fold(Complex::new(0.0, 0.0), |acc, &a| acc * s + a)
    }

    /// Value at s = jω.
    pub fn eval_jw(&self, omega: f64) -> Complex<f64> {
        self.eval_c(Complex::new(0.0, omega))
    }

    /// p(-s).
    pub fn mirror(&self) -> Self {
        let c = self
            .c
            .iter()
            .enumerate()
            .map(|(k, &a)| if k % 2 == 1 { -a } else { a })
            .collect();
        Self { c }
    }

    /// Product.
    pub fn mul(&self, other: &Self) -> Self {
        if self.is_zero() || other.is_zero() {
            return Self { c: Vec::new() };
        }
        let mut c = vec![0.0; self.c.len() + other.c.len() - 1];
        for (i, a) in self.c.iter().enumerate() {
            for (j, b) in other.c.iter().enumerate() {
                c[i + j] += a * b;
            }
        }
        trim(&mut c);
        Self { c }
    }

    /// Sum. Coefficients that cancel to rounding noise (below `1e-13` of the
    /// larger of the two terms) are set to exactly zero, so a leading term
    /// that cancels does not leave a spurious huge root behind.
    pub fn add(&self, other: &Self) -> Self {
        let n = self.c.len().max(other.c.len());
        let mut c = vec![0.0; n];
        for k in 0..n {
            let a = self.coeff(k);
            let b = other.coeff(k);
            let s = a + b;
            c[k] = if s.abs() <= 1e-13 * a.abs().max(b.abs()) {
                0.0
            } else {
                s
            };
        }
        trim(&mut c);
        Self { c }
    }

    /// Difference, with the same cancellation rule as [`Poly::add`].
    pub fn sub(&self, other: &Self) -> Self {
        self.add(&other.scale(-1.0))
    }

    /// Multiply by a constant.
    pub fn scale(&self, k: f64) -> Self {
        let mut c: Vec<f64> = self.c.iter().map(|a| a * k).collect();
        trim(&mut c);
        Self { c }
    }

    /// Number of roots at s = 0 (trailing zero coefficients).
    fn zero_roots(&self) -> usize {
        self.c.iter().take_while(|&&a| a == 0.0).count()
    }

    /// All roots, with multiplicity (degree many; none for constants).
    ///
    /// Exact zero roots are split off first (trailing zero coefficients).
    /// The rest are the eigenvalues (nalgebra's real Schur form) of the
    /// companion matrix of the polynomial rescaled by s = σ z
    /// (σ = |a0/an|^(1/n), which balances the coefficients); if that
    /// iteration does not converge, the variable is shifted by a fraction of
    /// σ and the eigenvalues are shifted back. Each root is then polished by
    /// a few Newton steps on the original polynomial (a step is kept only if
    /// it reduces |p|).
    pub fn roots(&self) -> Result<Vec<Complex<f64>>, AnalysisError> {
        if self.is_zero() {
            return Err(AnalysisError::ZeroPolynomial);
        }
        let nz = self.zero_roots();
        let mut out = vec![Complex::new(0.0, 0.0); nz];
        let c = &self.c[nz..];
        let n = c.len() - 1;
        if n == 0 {
            return Ok(out);
        }
        let an = c[n];
        let a0 = c[0];
        let sigma = (a0 / an).abs().powf(1.0 / n as f64);
        let sigma = if sigma.is_finite() && sigma > 0.0 {
            sigma
        } else {
            1.0
        };
        // nalgebra's Francis iteration can stall on spectra symmetric about
        // the imaginary axis (even polynomials such as d(-s) d(s)); a real
        // shift of the variable, s = z + δ, breaks the symmetry.
        let eig = [0.0, 0.3137, -0.2718, 0.5813]
            .iter()
            .find_map(|&f| {
                let delta = f * sigma;
                let shifted = taylor_shift(c, delta);
                companion_eigenvalues(&shifted)
                    .map(|e| e.into_iter().map(|z| z + delta).collect::<Vec<_>>())
            })
            .ok_or(AnalysisError::RootsFailed { degree: n })?;
        let tail = Poly { c: c.to_vec() };
        let dtail = tail.derivative();
        for z in eig.iter() {
            let mut r = *z;
            let mut pr = tail.eval_c(r).norm();
            for _ in 0..8 {
                let d = dtail.eval_c(r);
                if d.norm() == 0.0 || pr == 0.0 {
                    break;
                }
                let cand = r - tail.eval_c(r) / d;
                let pc = tail.eval_c(cand).norm();
                if pc.is_finite() && pc < pr {
                    r = cand;
                    pr = pc;
                } else {
                    break;
                }
            }
            out.push(r);
        }
        // Roots of a real polynomial: force exact conjugate symmetry and
        // realness where the imaginary part is rounding noise.
        for r in out.iter_mut() {
            if r.im.abs() <= 1e-12 * r.norm().max(1e-300) {
                r.im = 0.0;
            }
        }
        Ok(out)
    }

    /// Derivative.
    pub fn derivative(&self) -> Self {
        if self.c.len() <= 1 {
            return Self { c: Vec::new() };
        }
        let c = self
            .c
            .iter()
            .enumerate()
            .skip(1)
            .map(|(k, &a)| a * k as f64)
            .collect();
        Self { c }
    }

    /// Human-readable form, e.g. `2 s^2 + 0.5 s - 1`.
    pub fn to_pretty(&self) -> String {
        if self.is_zero() {
            return "0".to_string();
        }
        let mut out = String::new();
        for k in (0..self.c.len()).rev() {
            let a = self.c[k];
            if a == 0.0 {
                continue;
            }
            let mag = a.abs();
            if out.is_empty() {
                if a < 0.0 {
                    out.push('-');
                }
            } else {
                out.push_str(if a < 0.0 { " - " } else { " + " });
            }
            let coef = fmt_num(mag);
            match k {
                0 => out.push_str(&coef),
                _ => {
                    if mag != 1.0 {
                        out.push_str(&coef);
                        out.push(' ');
                    }
                    out.push('s');
                    if k > 1 {
                        out.push_str(&format!("^{k}"));
                    }
                }
            }
        }
        out
    }
}

/// Format a number compactly with 6 significant digits.
pub fn fmt_num(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    let a = x.abs();
    if (1e-3..1e6).contains(&a) {
        let s = format!("{:.*}", (5 - a.log10().floor() as i32).max(0) as usize, x);
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{x:.5e}")
    }
}

/// Coefficients (lowest power first) of p(z + δ).
fn taylor_shift(c: &[f64], delta: f64) -> Vec<f64> {
    let mut a = c.to_vec();
    if delta == 0.0 {
        return a;
    }
    let n = a.len();
    for i in 0..n {
        for k in (i..n - 1).rev() {
            a[k] += delta * a[k + 1];
        }
    }
    a
}

/// Eigenvalues of the companion matrix of the polynomial with coefficients
/// `c` (lowest power first, degree >= 1, c[0] may be anything), computed on
/// the variable rescaled by σ = |c0/cn|^(1/n); `None` if the Schur
/// iteration does not converge.
fn companion_eigenvalues(c: &[f64]) -> Option<Vec<Complex<f64>>> {
    let n = c.len() - 1;
    let an = c[n];
    let sigma = (c[0] / an).abs().powf(1.0 / n as f64);
    let sigma = if sigma.is_finite() && sigma > 0.0 {
        sigma
    } else {
        1.0
    };
    let mut m = DMatrix::<f64>::zeros(n, n);
    for i in 1..n {
        m[(i, i - 1)] = 1.0;
    }
    for i in 0..n {
        m[(i, n - 1)] = -c[i] / an * sigma.powi(i as i32 - n as i32);
    }
    let schur = Schur::try_new(m, f64::EPSILON, 2_000)?;
    Some(
        schur
            .complex_eigenvalues()
            .iter()
            .map(|z| z * sigma)
            .collect(),
    )
}

fn trim(c: &mut Vec<f64>) {
    while c.last() == Some(&0.0) {
        c.pop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sorted_re(mut r: Vec<Complex<f64>>) -> Vec<Complex<f64>> {
        r.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
        r
    }

    #[test]
    fn construct_trim_eval() {
        let p = Poly::new(&[0.0, 0.0, 1.0, 3.0, 2.0]).unwrap();
        assert_eq!(p.degree(), Some(2));
        assert_eq!(p.coeffs_desc(), vec![1.0, 3.0, 2.0]);
        assert_eq!(p.eval(2.0), 12.0);
        let v = p.eval_jw(1.0); // -1 + 3j + 2
        assert!((v - Complex::new(1.0, 3.0)).norm() < 1e-15);
        assert!(Poly::new(&[1.0, f64::NAN]).is_err());
        assert!(Poly::new(&[0.0, 0.0]).unwrap().is_zero());
    }

    #[test]
    fn mirror_mul_add() {
        let p = Poly::new(&[2.0, 1.0]).unwrap(); // 2s+1
        assert_eq!(p.mirror().coeffs_desc(), vec![-2.0, 1.0]);
        let q = p.mul(&p.mirror()); // 1 - 4 s^2
        assert_eq!(q.coeffs_desc(), vec![-4.0, 0.0, 1.0]);
        let z = q.add(&Poly::new(&[4.0, 0.0, 0.0]).unwrap());
        assert_eq!(z.coeffs_desc(), vec![1.0]);
    }

    #[test]
    fn roots_real_complex_zero() {
        // (s+1)(s+2) s^2 (s^2 + 2 s + 5): roots -1, -2, 0, 0, -1 ± 2j
        let p = Poly::new(&[1.0, 3.0, 2.0])
            .unwrap()
            .mul(&Poly::new(&[1.0, 0.0, 0.0]).unwrap())
            .mul(&Poly::new(&[1.0, 2.0, 5.0]).unwrap());
        let mut r = p.roots().unwrap();
        let want = [
            Complex::new(-2.0, 0.0),
            Complex::new(-1.0, -2.0),
            Complex::new(-1.0, 0.0),
            Complex::new(-1.0, 2.0),
            Complex::new(0.0, 0.0),
            Complex::new(0.0, 0.0),
        ];
        assert_eq!(r.len(), 6);
        for w in want {
            let i = r.iter().position(|z| (z - w).norm() < 1e-9);
            assert!(i.is_some(), "{w} not among {r:?}");
            r.swap_remove(i.unwrap());
        }
    }

    #[test]
    fn roots_wide_scale() {
        // roots 1e-4 and 1e4
        let p = Poly::linear(1e-4).mul(&Poly::linear(1e4));
        let r = sorted_re(p.roots().unwrap());
        assert!((r[0].re - 1e-4).abs() < 1e-12);
        assert!((r[1].re - 1e4).abs() < 1e-6);
    }

    #[test]
    fn from_roots_roundtrip() {
        let roots = [
            Complex::new(-1.0, 2.0),
            Complex::new(-1.0, -2.0),
            Complex::new(3.0, 0.0),
        ];
        let p = Poly::from_roots(2.0, &roots);
        // 2 (s^2 + 2 s + 5)(s - 3) = 2 s^3 - 2 s^2 - 2 s - 30
        let d = p.coeffs_desc();
        for (a, b) in d.iter().zip([2.0, -2.0, -2.0, -30.0]) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn pretty() {
        assert_eq!(
            Poly::new(&[2.0, 0.0, -1.0, 0.5]).unwrap().to_pretty(),
            "2 s^3 - s + 0.5"
        );
        assert_eq!(Poly::new(&[-1.0, 0.0]).unwrap().to_pretty(), "-s");
        assert_eq!(Poly::constant(0.0).to_pretty(), "0");
    }
}
