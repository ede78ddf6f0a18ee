//! [`Trace`]: every cycle of a run, column by column, preallocated.

use std::io::{self, Write};

/// One run's time series, one entry per controller cycle (structure of
/// arrays, preallocated to the run length so that recording never allocates).
///
/// Row k holds the values at the start of cycle k (`t = k dt`): the plant's
/// true state, the command the controller computed from the sensors at that
/// instant, and the road knowledge it was given.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// Time, s.
    pub t: Vec<f64>,
    /// Vehicle speed V, m/s (true).
    pub v: Vec<f64>,
    /// Wheel speed ω, rad/s (true).
    pub omega: Vec<f64>,
    /// Wheel circumferential speed r ω, m/s (true).
    pub r_omega: Vec<f64>,
    /// Slip λ (true).
    pub lambda: Vec<f64>,
    /// Motor torque T acting on the wheel, N m (true, after the lag).
    pub torque: Vec<f64>,
    /// Torque command T*, N m.
    pub torque_cmd: Vec<f64>,
    /// Driver demand T_d, N m.
    pub demand: Vec<f64>,
    /// Friction coefficient mu(λ) of the true road.
    pub mu: Vec<f64>,
    /// Controller's friction estimate μ̂ (NaN for MFC).
    pub mu_hat: Vec<f64>,
    /// Controller internal signal: MFC ω_M (rad/s), SRC λ*, MTTE T_max (N m).
    pub internal: Vec<f64>,
    /// True road, catalogue index.
    pub true_road: Vec<u32>,
    /// λ_opt of the true road.
    pub lambda_opt_true: Vec<f64>,
    /// Estimated road given to the controller, catalogue index (None: no
    /// estimate yet, or a variant without ARTE).
    pub est_road: Vec<Option<u32>>,
    /// Confidence of that estimate (NaN when none).
    pub confidence: Vec<f64>,
    /// The controller used the road knowledge this cycle.
    pub used_arte: Vec<bool>,
}

impl Trace {
    /// An empty trace with room for `n` cycles.
    pub fn with_capacity(n: usize) -> Self {
        Self {
            t: Vec::with_capacity(n),
            v: Vec::with_capacity(n),
            omega: Vec::with_capacity(n),
            r_omega: Vec::with_capacity(n),
            lambda: Vec::with_capacity(n),
            torque: Vec::with_capacity(n),
            torque_cmd: Vec::with_capacity(n),
            demand: Vec::with_capacity(n),
            mu: Vec::with_capacity(n),
            mu_hat: Vec::with_capacity(n),
            internal: Vec::with_capacity(n),
            true_road: Vec::with_capacity(n),
            lambda_opt_true: Vec::with_capacity(n),
            est_road: Vec::with_capacity(n),
            confidence: Vec::with_capacity(n),
            used_arte: Vec::with_capacity(n),
        }
    }

    /// Bytes a trace with room for `cycles` cycles holds (its columns).
    pub fn bytes_for(cycles: usize) -> u64 {
        let row = 13 * std::mem::size_of::<f64>()
            + std::mem::size_of::<u32>()
            + std::mem::size_of::<Option<u32>>()
            + std::mem::size_of::<bool>();
        cycles as u64 * row as u64
    }

    /// Number of cycles recorded.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when nothing is recorded.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The CSV header written by [`Trace::write_csv`].
    pub const CSV_HEADER: &'static str = "t,v,omega,r_omega,lambda,torque,torque_cmd,demand,mu,mu_hat,internal,true_road,lambda_opt_true,est_road,confidence,used_arte";

    /// Write the trace as CSV: the header, then one row per cycle. Road
    /// columns hold road names (`names[index]`); a missing estimate or a NaN
    /// is an empty field. Floats are written in Rust's shortest round-trip
    /// form, so a reader gets the exact values back.
    pub fn write_csv<W: Write>(&self, w: &mut W, names: &[&str]) -> io::Result<()> {
        let name = |i: u32| names.get(i as usize).copied().unwrap_or("?");
        writeln!(w, "{}", Self::CSV_HEADER)?;
        for k in 0..self.len() {
            write!(
                w,
                "{},{},{},{},{},{},{},{},{},",
                self.t[k],
                self.v[k],
                self.omega[k],
                self.r_omega[k],
                self.lambda[k],
                self.torque[k],
                self.torque_cmd[k],
                self.demand[k],
                self.mu[k],
            )?;
            write_opt(w, self.mu_hat[k])?;
            write!(
                w,
                ",{},{},{},",
                self.internal[k],
                name(self.true_road[k]),
                self.lambda_opt_true[k]
            )?;
            if let Some(e) = self.est_road[k] {
                write!(w, "{}", name(e))?;
            }
            w.write_all(b",")?;
            write_opt(w, self.confidence[k])?;
            writeln!(w, ",{}", u8::from(self.used_arte[k]))?;
        }
        Ok(())
    }
}

fn write_opt<W: Write>(w: &mut W, x: f64) -> io::Result<()> {
    if x.is_nan() { Ok(()) } else { write!(w, "{x}") }
}
