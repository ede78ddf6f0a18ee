//! Vehicle parameters (MODELS.md §1, paper Table IV).

/// Parameters of the vehicle and its driven wheel. Defaults are the paper's
/// Table IV plus MODELS.md §1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleParams {
    /// Vehicle mass M, kg.
    pub mass: f64,
    /// Driven wheels sharing the vehicle, n (the wheel carries M/n).
    pub n_driven: f64,
    /// Wheel + shaft inertia J_w, kg m^2.
    pub j_w: f64,
    /// Tyre radius r, m.
    pub r: f64,
    /// Wheel mass m, kg.
    pub m_wheel: f64,
    /// Motor torque lag tau_m, s (first order).
    pub tau_m: f64,
    /// Rolling resistance coefficient C_rr.
    pub c_rr: f64,
    /// Air density rho, kg/m^3.
    pub rho: f64,
    /// Drag area C_d A, m^2.
    pub c_d_a: f64,
    /// Speed floor in the slip denominator, m/s.
    pub v_eps: f64,
    /// Motor torque limit, N m (|T| is clamped to this).
    pub torque_max: f64,
}

impl Default for VehicleParams {
    fn default() -> Self {
        Self {
            mass: 1400.0,
            n_driven: 4.0,
            j_w: 0.6,
            r: 0.28,
            m_wheel: 10.0,
            tau_m: 0.05,
            c_rr: 0.015,
            rho: 1.2,
            c_d_a: 0.7,
            v_eps: 0.1,
            torque_max: 1000.0,
        }
    }
}

impl VehicleParams {
    /// Mass carried by one driven wheel, M/n, kg.
    pub fn mass_share(&self) -> f64 {
        self.mass / self.n_driven
    }
    /// Normal force on the driven wheel, N = M g / n.
    pub fn normal_force(&self) -> f64 {
        self.mass * crate::G / self.n_driven
    }
    /// Inertia of the vehicle share reflected to the wheel, J_w + (M/n) r^2 (paper eq. 2).
    pub fn j_model(&self) -> f64 {
        self.j_w + self.mass_share() * self.r * self.r
    }
}
