//! Linear analysis (paper §III, and the ν-gaps of paper §IV): polynomials and
//! SISO transfer functions, the paper's transfer functions for the configured
//! vehicle (with the corrections documented in `crates/tcs/README.md`,
//! section "Analysis"), the K_MFC bound (4), SRC's gains derived for the
//! vehicle, the Vinnicombe ν-gap and the
//! ν-gaps of the three controller structures with and without ARTE, and the
//! slip noise of the vehicle's sensors against the road belief's.
//!
//! Nothing here runs in a control loop; allocation is allowed.

pub mod gaps;
pub mod nugap;
pub mod poly;
pub mod sensors;
pub mod tf;
pub mod vehicle_tf;

pub use nugap::{NuGap, nu_gap};
pub use poly::Poly;
pub use tf::Tf;

/// Errors of the linear analysis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// A polynomial coefficient is NaN or infinite.
    #[error("coefficient {index} is {value}, not a finite number")]
    NonFinite {
        /// Position in the slice as given.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The zero polynomial where a nonzero one is needed (roots of 0).
    #[error("the polynomial is identically zero")]
    ZeroPolynomial,
    /// A transfer function with a zero denominator.
    #[error("the denominator is identically zero")]
    ZeroDenominator,
    /// The companion-matrix eigenvalue iteration did not converge.
    #[error("root finding did not converge for a polynomial of degree {degree}")]
    RootsFailed {
        /// Degree of the polynomial.
        degree: usize,
    },
    /// The vehicle parameters are invalid.
    #[error("vehicle parameters: {0}")]
    Vehicle(grip_physics::InvalidField),
    /// A road the analysis needs is not in the catalogue.
    #[error("road `{name}` is not in the catalogue (have: {available})")]
    MissingRoad {
        /// The missing road.
        name: String,
        /// The catalogue's road names.
        available: String,
    },
    /// A physical parameter out of its valid range.
    #[error("parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Why it is rejected.
        reason: &'static str,
    },
}
