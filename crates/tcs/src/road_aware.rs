//! Road knowledge ahead of and under the wheel, for the "with ARTE"
//! variants of all three controllers: the preview queue, the road belief,
//! and the torque they allow. The same code runs in `grip sim` and in the
//! live tcs-loop.
//!
//! Every cycle [`RoadAware::step`]:
//!
//! 1. looks up the road under the wheel and the next one ahead in the
//!    [`PreviewQueue`] at the loop's odometer (acoustic decisions are
//!    queued by [`RoadAware::decision`] at the place the microphone heard
//!    them, `mic_lead_m` ahead of the wheel);
//! 2. fuses the acoustic estimate of the road under the wheel with the
//!    wheel's slip evidence ([`RoadBelief`]) while the decision stream is
//!    alive (a decision within `[arte] max_age_s`);
//! 3. hands the controller the [`RoadKnowledge`] of the most probable road
//!    (its probability as the confidence, age 0: the belief is this
//!    cycle's), which the controller's own fallback rule accepts or not;
//!    nothing while no decision came within `[arte] max_age_s` (a dead or
//!    not yet started stream: the no-ARTE behaviour);
//! 4. and a torque cap: what the believed road transmits,
//!    `cap_share · μ_peak · N · r` (the μ-λ curves are flat near their peaks,
//!    so a cap below the peak holds the slip where μ reaches about that
//!    share of μ_peak: nearly all the traction at much less slip); while the
//!    measured slip is beyond `recover_slip_factor · λ_opt` (the wheel
//!    spins) `recover_share · μ_peak · N · r` so that it regains grip; and,
//!    when the next road ahead carries less and the wheel reaches it within
//!    `horizon_s` (enough for the motor's lag), that road's cap already.
//!    On a road that carries more, the cap is released when the wheel
//!    arrives (the queue places a grippier road at `(1 + change_at) / 2` of
//!    the frame that named it, 0.6875 as shipped: later than a road that
//!    carries less, at `change_at`).
//!
//! Reverse travel (the car's signed distance, ∫ v dt, more than
//! `[preview] reverse_m` below its running maximum) clears the queue and
//! drops the decisions available within `reverse_hold_s` after it: the
//! odometer counts forward travel only, so the queue's places no longer
//! match the road (every change would be met early by the distance
//! reversed). Standing still keeps the queue.
//!
//! The cap is applied as `T* = min(T*_controller, cap)`: the controllers
//! stay as they are and react to slip themselves below the cap (MTTE's
//! observer, fed its own command, does not see a binding cap: crates/tcs
//! README, "Known limits"). The variants without ARTE never see this.

use grip_physics::{InvalidField, RoadCatalogue, VehicleParams};
use serde::Deserialize;

use crate::any::ControllerKind;
use crate::filters::LowPass;
use crate::fusion::RoadBelief;
use crate::knowledge::{RoadInfo, RoadTable};
use crate::params::{ArteUse, ControllersConfig, in_range, positive};
use crate::preview::{PreviewQueue, PreviewView};
use crate::types::{ControlOutput, Controller, Measurement, RoadKnowledge};

/// `[preview]` of `controllers.toml`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreviewParams {
    /// Torque cap on a believed road, share of its μ_peak · N · r, (0, 1.5].
    pub cap_share: f64,
    /// Cap while the wheel spins, share of μ_peak · N · r, (0, 1.5].
    pub recover_share: f64,
    /// The wheel spins when the measured slip exceeds this many λ_opt of
    /// the believed road, >= 1.
    pub recover_slip_factor: f64,
    /// Longest look-ahead, s: a lower-friction road further than this (in
    /// time at the current speed) is not acted on yet.
    pub horizon_s: f64,
    /// Time added to the motor lag's drop time as a margin for the
    /// measurement delay and odometer error, s (>= 0).
    pub lag_margin_s: f64,
    /// Where in a decision's frame the road change is taken to lie, as a
    /// share of the frame from its start, [0, 1]: 0 is the most cautious
    /// (the earliest point); a classifier that switches once most of its
    /// frame is on the new road puts the change before the middle.
    pub change_at: f64,
    /// Decisions in a row an acoustic road needs before it caps the torque
    /// (ahead or under the wheel), >= 1: one stray frame of a noisy
    /// classifier does not cost traction; the wheel's own evidence still acts.
    pub min_hits: u32,
    /// The slip the controller is told to aim at on a road: where μ reaches
    /// this share of μ_peak on the rising side of the curve, (0, 1]. The
    /// μ-λ curves are flat near their peaks (snow reaches 95 % of its peak
    /// at half its λ_opt), so a share just below 1 gives nearly all the
    /// traction at much less slip. 1: λ_opt itself.
    pub slip_share: f64,
    /// Plausibility of a binding cap, in the grippy direction: while the
    /// motor delivers the believed road's cap and the wheel slips less than
    /// this share of that road's target slip, or of the slip the road needs
    /// to carry its cap when that is lower (`cap_share` below `slip_share`),
    /// for `release_s` (on the believed road it would slip more), the road
    /// carries more than believed and its cap is released until the belief
    /// changes road or the wheel spins, [0, 1] (0: never).
    pub release_slip_share: f64,
    /// How long the wheel must contradict the cap before it is released, s.
    pub release_s: f64,
    /// How a previewed drop is shaped, [0, 1): the constant command that
    /// brings the motor (first-order lag `tau_m`) to the target by arrival
    /// never goes below this share of the target, so the drop begins early
    /// enough for that command (`tau_m ln((T - f T*) / ((1 - f) T*))` ahead,
    /// plus the margin). 0: the latest possible drop, a zero command and
    /// then the target (the least torque given up, but a 300 → 0 → 183 N m
    /// step that an inverter and a driveline feel); towards 1 one smooth
    /// step down, started earlier (more torque given up on the road before).
    /// Absent from a file: 0 (the drop before this field existed, so that
    /// older drive logs' attached configuration still loads and replays).
    #[serde(default)]
    pub approach_floor: f64,
    /// How far a previewed drop may dip under its target, as a share of
    /// the drop itself (0.001-100): the constant command never goes below
    /// `target − approach_dip · (T − target)` either (T: what the motor has
    /// or the driver asks, the higher), whichever of the two bounds is
    /// higher. A bound in proportion to the drop starts every drop it
    /// shapes the same `tau_m ln((1 + d) / d)` ahead, and moves the command
    /// at most `1 + 2 d` times the drop, so a small drop (200 N m onto
    /// snow's 183) is not shaped as deep as a large one. Absent from a
    /// file: no such bound (the drop before this field existed, so that
    /// older drive logs still replay).
    #[serde(default)]
    pub approach_dip: Option<f64>,
    /// How far above its target the motor may read while a previewed
    /// drop's command, once come down to the target, stays there
    /// (1.02-2, a factor of the target; the hold begins at the first
    /// reading within 2 % of the target): under way the drop's command does not rise
    /// again before it is the target, and from then on it stays the target
    /// while the motor reads at most this times it. The constant command is
    /// recomputed every cycle from the measured torque, whose noise it
    /// amplifies by `1 / (1 − e^(−t/τ_m))` near arrival; with the 2 % band
    /// alone a motor settling at 1.02 × the target flipped the command
    /// between the target and the floor (183 → 128 → 183 N m). A motor
    /// further above (the command at the target for another reason) is
    /// brought down by the floor's command again. Absent from a file: no
    /// hold (the drop before this field existed, so that older drive logs
    /// still replay).
    #[serde(default)]
    pub approach_hold: Option<f64>,
    /// When a spinning wheel's cut ends, [0, 2]: the cut to `recover_share`
    /// ends once the wheel's excess angular momentum over the road's peak
    /// slip, `J_w ω (λ − λ_opt) / (1 − λ_opt)`, is no more than this share
    /// of what the motor's return to the cap through its lag will still take
    /// from it, `(cap − T) τ_m`. 0: only when the slip is back under λ_opt
    /// (the motor, then far below the cap, lets the slip fall well under the
    /// target before it is back). Absent from a file: 0 (the rule before
    /// this field existed, so that older drive logs still replay).
    #[serde(default)]
    pub recover_landing: f64,
    /// The least speed difference between the wheel and the car, r·ω − V
    /// (m/s, [0, 10]), at which a slip beyond `recover_slip_factor · λ_opt`
    /// counts as a spin. At creep the slip is a small difference over a
    /// small speed, and the speed sensors' noise alone takes it past the
    /// threshold: with the shipped sensors (σ 0.05 rad/s at r 0.28 m and
    /// 0.02 m/s: σ 0.024 m/s of r·ω − V) a pull-away on snow cut the torque
    /// for single cycles 20 times below 1 m/s (183 → 73 → 183 N m). A wheel
    /// that really spins passes 0.15 m/s within a few milliseconds. 0: no
    /// such floor. Absent from a file: 0 (the rule before this field
    /// existed, so that older drive logs still replay).
    #[serde(default)]
    pub spin_dv_min: f64,
    /// Reverse travel, m: when the car's signed distance (∫ v dt, v the
    /// measured vehicle speed, else r·ω) falls more than this below its
    /// running maximum, the car has reversed, and the road knowledge placed
    /// on the odometer (which counts forward travel only) no longer matches
    /// the road: the preview queue is cleared (see `reverse_hold_s`), and
    /// the maximum starts again from there. [0.001, 10]. Absent from a file:
    /// 0.1, the shipped value (a queue left in place after a reverse meets
    /// every road change that many metres early, the end of a low-friction
    /// patch included, so older files get the detection too): within the
    /// queue's own placement error (a 0.1 s frame at 1 m/s), and 20 times
    /// the standstill drift of ∫ v dt over 60 s with the shipped speed
    /// sensor's noise (σ 0.02 m/s at 1 kHz: about 0.005 m).
    #[serde(default = "default_reverse_m")]
    pub reverse_m: f64,
    /// Standstill, m/s: a measured speed (V, else r·ω) of smaller magnitude
    /// than this is no travel, neither for the odometer
    /// ([`odometer_speed`]) nor for the reverse detection (`reverse_m`).
    /// Without it a standing car's speed noise moves the odometer: it
    /// integrates the noise's positive half (σ/√(2π) on average, 8 mm/s
    /// with the shipped σ of 0.02 m/s, about 29 m an hour), so after about
    /// six minutes at a standstill the front-mic car's 2.77 m of heard road
    /// ahead were all "passed", and the signed distance wanders (a 0.1 m
    /// drawdown, a false reverse, after about 7 h). [0, 1]. Absent from a
    /// file: 0 (the rule before this field existed, so that older drive logs
    /// still replay); shipped 0.1 (5 σ of the shipped V noise, 0.36 km/h).
    #[serde(default)]
    pub standstill_mps: f64,
    /// After the last cycle that detected reverse travel (`reverse_m`), the
    /// acoustic decisions available (their stamp) within this time are
    /// dropped, s, [0, 10]: their frames may have been heard while the car
    /// went backwards, and would be placed where the car is not. Absent
    /// from a file: 0.6, the shipped value: a 0.1 s frame plus arte's
    /// `max_lag_s` (0.5 s), beyond which arte drops audio unclassified, so
    /// no decision on audio heard while reversing is kept.
    #[serde(default = "default_reverse_hold_s")]
    pub reverse_hold_s: f64,
    /// `[preview.mfc]`: MFC-ARTE's own trade of slip for traction, in place
    /// of the two values above (see [`PreviewTrade`]). Absent: none.
    #[serde(default)]
    pub mfc: PreviewTrade,
    /// `[preview.src]`: SRC-ARTE's own trade.
    #[serde(default)]
    pub src: PreviewTrade,
    /// `[preview.mtte]`: MTTE-ARTE's own trade.
    #[serde(default)]
    pub mtte: PreviewTrade,
}

/// One controller's own `cap_share`, `slip_share` and `recover_share`
/// (`[preview.mfc]`, `[preview.src]`, `[preview.mtte]`): the values that
/// decide how much traction (and command smoothness) its ARTE variant gives
/// up for less slip. A value left out is `[preview]`'s. [`PreviewParams::for_controller`] applies it.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreviewTrade {
    /// In place of [`PreviewParams::cap_share`], (0, 1.5].
    pub cap_share: Option<f64>,
    /// In place of [`PreviewParams::slip_share`], (0, 1].
    pub slip_share: Option<f64>,
    /// In place of [`PreviewParams::recover_share`], (0, 1.5].
    pub recover_share: Option<f64>,
}

impl PreviewTrade {
    /// The value set for `key` (`cap_share`, `slip_share` or
    /// `recover_share`, as in the file); `None` when not set or not one of
    /// them.
    pub fn get(&self, key: &str) -> Option<f64> {
        match key {
            "cap_share" => self.cap_share,
            "slip_share" => self.slip_share,
            "recover_share" => self.recover_share,
            _ => None,
        }
    }

    fn validate(&self) -> Result<(), InvalidField> {
        if let Some(v) = self.cap_share {
            in_range("cap_share", v, 1e-3, 1.5)?;
        }
        if let Some(v) = self.slip_share {
            in_range("slip_share", v, 1e-3, 1.0)?;
        }
        if let Some(v) = self.recover_share {
            in_range("recover_share", v, 1e-3, 1.5)?;
        }
        Ok(())
    }
}

fn default_reverse_m() -> f64 {
    0.1
}

fn default_reverse_hold_s() -> f64 {
    0.6
}

impl Default for PreviewParams {
    fn default() -> Self {
        Self {
            cap_share: 1.0,
            recover_share: 0.4,
            recover_slip_factor: 1.5,
            horizon_s: 1.0,
            lag_margin_s: 0.02,
            change_at: 0.375,
            min_hits: 2,
            slip_share: 0.95,
            release_slip_share: 0.7,
            release_s: 0.02,
            approach_floor: 0.7,
            approach_dip: Some(0.5),
            approach_hold: Some(1.1),
            recover_landing: 0.5,
            spin_dv_min: 0.15,
            reverse_m: default_reverse_m(),
            standstill_mps: 0.1,
            reverse_hold_s: default_reverse_hold_s(),
            mfc: PreviewTrade::default(),
            src: PreviewTrade {
                cap_share: Some(0.9),
                ..PreviewTrade::default()
            },
            mtte: PreviewTrade::default(),
        }
    }
}

impl PreviewParams {
    /// Ranges (NaN fails).
    pub fn validate(&self) -> Result<(), InvalidField> {
        in_range("cap_share", self.cap_share, 1e-3, 1.5)?;
        in_range("recover_share", self.recover_share, 1e-3, 1.5)?;
        in_range("recover_slip_factor", self.recover_slip_factor, 1.0, 100.0)?;
        in_range("horizon_s", self.horizon_s, 0.0, 10.0)?;
        in_range("lag_margin_s", self.lag_margin_s, 0.0, 1.0)?;
        in_range("change_at", self.change_at, 0.0, 1.0)?;
        in_range("slip_share", self.slip_share, 1e-3, 1.0)?;
        in_range("release_slip_share", self.release_slip_share, 0.0, 1.0)?;
        in_range("release_s", self.release_s, 0.0, 10.0)?;
        in_range("approach_floor", self.approach_floor, 0.0, 0.99)?;
        if let Some(d) = self.approach_dip {
            in_range("approach_dip", d, 1e-3, 100.0)?;
        }
        if let Some(h) = self.approach_hold {
            // under the band the hold would never begin
            in_range("approach_hold", h, APPROACH_BAND, 2.0)?;
        }
        in_range("recover_landing", self.recover_landing, 0.0, 2.0)?;
        in_range("spin_dv_min", self.spin_dv_min, 0.0, 10.0)?;
        // 0 or less would take the standstill's speed noise for reverse
        // travel (and clear the queue every cycle); NaN would never detect.
        in_range("reverse_m", self.reverse_m, 1e-3, 10.0)?;
        in_range("reverse_hold_s", self.reverse_hold_s, 0.0, 10.0)?;
        in_range("standstill_mps", self.standstill_mps, 0.0, 1.0)?;
        if self.min_hits == 0 {
            return Err(InvalidField::new("min_hits", "must be >= 1 (got 0)"));
        }
        self.mfc.validate().map_err(|e| e.prefixed("mfc"))?;
        self.src.validate().map_err(|e| e.prefixed("src"))?;
        self.mtte.validate().map_err(|e| e.prefixed("mtte"))?;
        Ok(())
    }

    /// `kind`'s own trade, `[preview.<kind>]` (empty where none is set).
    pub fn trade(&self, kind: ControllerKind) -> PreviewTrade {
        match kind {
            ControllerKind::Mfc => self.mfc,
            ControllerKind::Src => self.src,
            ControllerKind::Mtte => self.mtte,
        }
    }

    /// What `kind`'s ARTE variant runs with: these values with its own
    /// `[preview.<kind>]` trade applied (and no per-controller trades left
    /// in the result).
    pub fn for_controller(&self, kind: ControllerKind) -> PreviewParams {
        let t = self.trade(kind);
        PreviewParams {
            cap_share: t.cap_share.unwrap_or(self.cap_share),
            slip_share: t.slip_share.unwrap_or(self.slip_share),
            recover_share: t.recover_share.unwrap_or(self.recover_share),
            mfc: PreviewTrade::default(),
            src: PreviewTrade::default(),
            mtte: PreviewTrade::default(),
            ..*self
        }
    }
}

/// The wheel's word on binding caps, in the grippy direction
/// (`release_slip_share`, `release_s`): one verdict per road. A wheel that
/// has overruled road r's cap has overruled it whichever way the cap comes,
/// as the believed road's or as the road the microphone says is under the
/// wheel; the verdict holds while either still names r (the belief with a
/// usable estimate, or the heard road with a live decision stream) and the
/// wheel does not spin. Each way has its own clock of contradiction, since
/// each is a different cap binding.
#[derive(Debug, Clone, PartialEq, Default)]
struct Verdicts {
    /// Per road of the catalogue: the wheel has overruled its cap.
    overruled: Vec<bool>,
    /// How long the wheel has contradicted the believed road's cap, s.
    believed_s: f64,
    /// How long the wheel has contradicted the heard road's cap, s.
    heard_s: f64,
}

impl Verdicts {
    fn new(roads: usize) -> Self {
        Self {
            overruled: vec![false; roads],
            ..Self::default()
        }
    }

    fn reset(&mut self) {
        self.overruled.fill(false);
        self.believed_s = 0.0;
        self.heard_s = 0.0;
    }

    /// Road `r`'s cap is overruled (false for a road not in the catalogue).
    fn overruled(&self, r: Option<usize>) -> bool {
        r.and_then(|r| self.overruled.get(r).copied())
            .unwrap_or(false)
    }

    /// One cycle's hold: only a road still named by `believed` or `heard`
    /// keeps its verdict, and none while the wheel spins.
    fn hold(&mut self, believed: Option<usize>, heard: Option<usize>, spinning: bool) {
        for (r, o) in self.overruled.iter_mut().enumerate() {
            *o &= !spinning && (believed == Some(r) || heard == Some(r));
        }
    }

    /// One cycle of one way's clock (`clock`): the cap of `candidate`,
    /// when there is one and it is not overruled, is overruled once the
    /// wheel has contradicted it (`contradicts`) for `release_s`.
    fn judge(
        &mut self,
        heard: bool,
        candidate: Option<usize>,
        contradicts: bool,
        dt: f64,
        p: &PreviewParams,
    ) {
        let open = candidate.filter(|&r| !self.overruled(Some(r)));
        let clock = if heard {
            &mut self.heard_s
        } else {
            &mut self.believed_s
        };
        match open {
            Some(r) if contradicts => {
                *clock += dt;
                if *clock >= p.release_s
                    && p.release_slip_share > 0.0
                    && let Some(o) = self.overruled.get_mut(r)
                {
                    *o = true;
                }
            }
            _ => *clock = 0.0,
        }
    }
}

/// What [`RoadAware::step`] gives for one cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Guidance {
    /// The knowledge for the controller (the believed road).
    pub knowledge: Option<RoadKnowledge>,
    /// Catalogue index of the believed road and its probability.
    pub belief: (usize, f64),
    /// Torque the road allows, N m (`f64::INFINITY`: no cap).
    pub torque_cap: f64,
    /// The acoustic queue at the wheel: road under it and the next ahead
    /// with its distance, m.
    pub view: PreviewView,
}

/// See the module docs.
#[derive(Debug, Clone)]
pub struct RoadAware {
    table: RoadTable,
    /// Per road: the slip where μ = slip_share · μ_peak (rising side).
    lambda_target: Vec<f64>,
    /// Per road: the slip the release check compares with, the lower of
    /// the target and the slip where μ = cap_share · μ_peak (what the road
    /// needs to carry its cap; below the target when cap_share < slip_share).
    lambda_release: Vec<f64>,
    belief: RoadBelief,
    queue: PreviewQueue,
    p: PreviewParams,
    arte: ArteUse,
    nr: f64,
    r: f64,
    tau_m: f64,
    lead: f64,
    last_decision: f64,
    dt: f64,
    /// The wheel's word on binding caps, one verdict per road: the
    /// believed road's cap and that of the road the microphone says is
    /// under the wheel (when that carries less than the believed road).
    verdicts: Verdicts,
    /// Last cycle's cap, N m.
    last_cap: f64,
    /// Last cycle's cap came from the heard road under the wheel: that road.
    here_binding: Option<usize>,
    /// The wheel's spin and its cut, as of last cycle (see `spin`).
    spin: Spin,
    /// Wheel inertia, kg m².
    j_w: f64,
    /// The measured slip, low-passed over `release_s / 2` (the release check).
    slip_lp: LowPass,
    /// The car's signed distance, ∫ v dt, m (reverse detection).
    travel: f64,
    /// Its running maximum since the last detected reverse, m.
    travel_peak: f64,
    /// Time of the last cycle that detected reverse travel, s (−∞: none).
    reversed_at: f64,
}

/// How long a landing (`Spin::Landing`) may keep the slip above the
/// entry threshold without a new cut, in motor time constants: by 3 τ_m
/// the motor has made 95 % of its return, which was to take the rest of
/// the wheel's excess momentum. A wheel that broke away at near 100 % slip
/// (a hill start rolling back on wet stone) otherwise stayed "landing" at
/// 0.98 slip for seconds, since its slip could not rise by the band again.
const LANDING_TAUS: f64 = 3.0;

/// A previewed drop's motor within this factor of its target counts as
/// there ([`RoadAware::approach`]); `approach_hold` is at least this.
const APPROACH_BAND: f64 = 1.02;

/// A spinning wheel and its cut (`RoadAware::spins`).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Spin {
    /// No spin: the slip under the entry threshold, or back under λ_opt.
    Gripping,
    /// Spinning: the torque is cut to `recover_share`.
    Cut,
    /// The cut ended early at slip `from` (`recover_landing`), at time `t0`,
    /// and the wheel is coming back; a new cut needs the slip to rise again
    /// by the entry band above `from`, or, once the motor has had
    /// [`LANDING_TAUS`] time constants to return, to be still above the
    /// entry threshold (a landing that does not land: a wheel still
    /// spinning at the torque the motor returned to).
    Landing { from: f64, t0: f64 },
}

impl RoadAware {
    /// For the ARTE variant of `kind` on `roads` (with their knowledge
    /// `table`), `vehicle` (its `mic_lead_m`, N and r), with `controllers`'
    /// `[arte]`, `[fusion]` and `[preview]` (with `kind`'s own trade,
    /// [`PreviewParams::for_controller`]), at sample time `dt`. Errors name
    /// the field.
    pub fn new(
        kind: ControllerKind,
        roads: &RoadCatalogue,
        table: RoadTable,
        vehicle: &VehicleParams,
        controllers: &ControllersConfig,
        dt: f64,
    ) -> Result<Self, InvalidField> {
        controllers
            .preview
            .validate()
            .map_err(|e| e.prefixed("preview"))?;
        let preview = controllers.preview.for_controller(kind);
        let (arte, fusion) = (controllers.arte, controllers.fusion);
        positive("dt", dt)?;
        let belief =
            RoadBelief::new(roads, vehicle, fusion, dt).map_err(|e| e.prefixed("fusion"))?;
        let at_share = |share: f64| -> Vec<f64> {
            roads
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    let info = table.info(i);
                    slip_at_share(|l| r.mu(l), info.lambda_opt, info.mu_peak, share)
                })
                .collect()
        };
        let lambda_target = at_share(preview.slip_share);
        let lambda_release = at_share(preview.cap_share.min(1.0))
            .into_iter()
            .zip(&lambda_target)
            .map(|(c, &t)| c.min(t))
            .collect();
        Ok(Self {
            table,
            lambda_target,
            lambda_release,
            belief,
            queue: PreviewQueue::new(),
            p: preview,
            arte,
            nr: vehicle.normal_force() * vehicle.r,
            r: vehicle.r,
            tau_m: vehicle.tau_m,
            lead: vehicle.mic_lead_m,
            last_decision: f64::NEG_INFINITY,
            dt,
            verdicts: Verdicts::new(roads.len()),
            last_cap: f64::INFINITY,
            here_binding: None,
            spin: Spin::Gripping,
            j_w: vehicle.j_w,
            slip_lp: LowPass::new(0.5 * preview.release_s, dt),
            travel: 0.0,
            travel_peak: 0.0,
            reversed_at: f64::NEG_INFINITY,
        })
    }

    /// Start of a drive.
    pub fn reset(&mut self) {
        self.belief.reset();
        self.queue.clear();
        self.last_decision = f64::NEG_INFINITY;
        self.verdicts.reset();
        self.last_cap = f64::INFINITY;
        self.here_binding = None;
        self.spin = Spin::Gripping;
        self.slip_lp.reset();
        self.travel = 0.0;
        self.travel_peak = 0.0;
        self.reversed_at = f64::NEG_INFINITY;
    }

    /// The microphone's lead, m.
    pub fn lead(&self) -> f64 {
        self.lead
    }

    /// An acoustic decision for catalogue road `road` with `confidence`,
    /// available at `stamp` (s), heard while the loop's odometer went from
    /// `x_from` to `x_to` (m; the lead is added here). Allocation-free.
    ///
    /// A decision available within `reverse_hold_s` of the last cycle that
    /// detected reverse travel (or before it) is not queued: its frame may
    /// have been heard while the car went backwards. It still shows the
    /// decision stream alive (`[arte] max_age_s`).
    pub fn decision(&mut self, road: usize, confidence: f64, stamp: f64, x_from: f64, x_to: f64) {
        if stamp <= self.reversed_at + self.p.reverse_hold_s {
            self.last_decision = stamp;
            return;
        }
        let x_from = x_from + self.p.change_at * (x_to - x_from);
        let table = &self.table;
        self.queue.push(
            road,
            confidence,
            stamp,
            x_from + self.lead,
            x_to + self.lead,
            |i| table.info(i).mu_peak,
        );
        self.last_decision = stamp;
    }

    /// The command that brings the motor torque (first-order lag `tau_m`)
    /// from `torque` down to `target` by the time the wheel arrives in
    /// `t_arrive` s: full freedom (no cap) until the drop no longer fits
    /// (with the constant command at the floor F, the higher of
    /// `approach_floor · target` and `target − approach_dip · (T − target)`:
    /// `tau_m ln((T − F) / (target − F))` plus the margin, T the higher of
    /// the motor's torque and the demand); then the constant command that
    /// reaches `target` at arrival, and `target` itself from arrival on.
    /// The drop's command does not rise again until it is the target
    /// (`prev_cap`, the last cycle's cap, between the floor and the
    /// target), and once it has come down to `target` it stays there while
    /// the motor reads at most `approach_hold` times it: the measured
    /// torque's noise must move neither (absent: neither rule).
    fn approach(&self, torque: f64, demand: f64, target: f64, t_arrive: f64, prev_cap: f64) -> f64 {
        if self.tau_m <= 0.0 {
            return if t_arrive <= self.p.lag_margin_s {
                target
            } else {
                f64::INFINITY
            };
        }
        // The most the motor may carry by then: what it has or what the
        // driver asks for.
        let high = torque.max(demand);
        let target_pos = target.max(1e-9);
        let share_floor = self.p.approach_floor * target_pos;
        let floor = self.p.approach_dip.map_or(share_floor, |d| {
            (target_pos - d * (high - target_pos)).max(share_floor)
        });
        let t_drop = if high > target {
            self.tau_m * ((high - floor) / (target_pos - floor)).ln()
        } else {
            0.0
        } + self.p.lag_margin_s;
        if t_arrive > t_drop {
            return f64::INFINITY;
        }
        // Within 2 % of the target the motor is there: the measured torque's
        // noise must not turn into a zero command (near arrival the constant
        // command amplifies it by 1 / (1 - e^(-t/τ_m))). Once there, it
        // stays there (`approach_hold`, whose docs say why).
        if torque <= APPROACH_BAND * target
            || torque.is_nan()
            || self
                .p
                .approach_hold
                .is_some_and(|h| prev_cap == target && torque <= h * target)
        {
            return target;
        }
        let t = (t_arrive - self.p.lag_margin_s).max(0.0);
        let a = (-t / self.tau_m).exp();
        if a >= 1.0 {
            return floor;
        }
        let c = ((target - torque * a) / (1.0 - a)).clamp(floor.min(target), target);
        // Under way (the last cycle's cap between the floor and the target)
        // the command does not rise again before the motor is there
        // (`approach_hold`); the motor then comes a few milliseconds early.
        if self.p.approach_hold.is_some() && prev_cap >= floor.min(target) && prev_cap < target {
            c.min(prev_cap)
        } else {
            c
        }
    }

    /// One cycle of a "with ARTE" controller at time `m.t` and odometer `x`
    /// (m): [`step`](Self::step), the controller stepped with the believed
    /// road's knowledge, its command limited to the torque cap. The one
    /// place where the
    /// cap meets the command, for `grip sim` and tcs-loop alike.
    /// Allocation-free.
    pub fn control<C: Controller + ?Sized>(
        &mut self,
        controller: &mut C,
        m: &Measurement,
        x: f64,
    ) -> (Guidance, ControlOutput) {
        let g = self.step(m, x);
        let mut out = controller.step(m, g.knowledge.as_ref());
        if g.torque_cap < out.torque_cmd {
            out.torque_cmd = g.torque_cap.max(0.0);
        }
        (g, out)
    }

    /// Whether the wheel spins this cycle, at slip `lambda` on the believed
    /// road `info`: from `recover_slip_factor · λ_opt` on, until the slip is
    /// back under λ_opt or (`recover_landing`) the motor's return to the cap
    /// through its lag will take the rest of the wheel's excess speed. After
    /// such an early end the wheel is landing: a new spin needs the slip to
    /// rise again by the entry band above where the cut ended. No new cut
    /// while the wheel turns less than `spin_dv_min` faster than the car
    /// (forward, λ·|rω| = rω − V).
    fn spins(&mut self, m: &Measurement, lambda: f64, road: usize, info: &RoadInfo) -> bool {
        let lo = info.lambda_opt;
        let band = (self.p.recover_slip_factor - 1.0) * lo;
        self.spin = if !lambda.is_finite() || lambda <= lo {
            Spin::Gripping
        } else {
            match self.spin {
                Spin::Cut => {
                    let excess = self.j_w * m.omega.abs() * (lambda - lo) / (1.0 - lo).max(0.1);
                    // what the tyre carries at this slip, when less than the
                    // cap: beyond λ_opt the curve falls, so on the way back
                    // the tyre carries at least this; against the cap alone
                    // a wheel at 98 % slip on wet stone (μ 0.28, peak 0.38)
                    // "landed" at once and spun up again every 0.24 s
                    let carried = self.belief.mu_of(road, lambda.min(1.0)) * self.nr;
                    let cap = self.torque(self.p.cap_share, info.mu_peak);
                    let back = self.p.recover_landing * (cap.min(carried) - m.torque) * self.tau_m;
                    if back > 0.0 && excess <= back {
                        Spin::Landing {
                            from: lambda,
                            t0: m.t,
                        }
                    } else {
                        Spin::Cut
                    }
                }
                Spin::Landing { from, t0 }
                    if lambda <= from.max(lo + band) + band
                        && (m.t - t0 < LANDING_TAUS * self.tau_m || lambda <= lo + band) =>
                {
                    Spin::Landing { from, t0 }
                }
                // under the speed-difference floor no new cut (creep noise)
                _ if lambda * (self.r * m.omega).abs() < self.p.spin_dv_min => self.spin,
                Spin::Gripping if lambda <= lo + band => Spin::Gripping,
                Spin::Landing { .. } | Spin::Gripping => Spin::Cut,
            }
        };
        self.spin == Spin::Cut
    }

    /// The torque at the wheel of `share` of a road's `mu_peak`: share · μ_peak · N · r.
    fn torque(&self, share: f64, mu_peak: f64) -> f64 {
        share * mu_peak * self.nr
    }

    /// Whether this cycle detects reverse travel (`reverse_m`): the signed
    /// distance ∫ v dt (v the measured vehicle speed, else r·ω, as the
    /// odometer's speed but with its sign; a speed that is no number adds
    /// nothing) more than `reverse_m` below its running maximum. The
    /// maximum then starts again from here, so a reverse of d metres is
    /// detected about every `reverse_m` of it, the last within `reverse_m`
    /// of its end.
    fn reversing(&mut self, m: &Measurement) -> bool {
        let v = m.v.unwrap_or(self.r * m.omega);
        if v.is_finite() && v.abs() >= self.p.standstill_mps {
            self.travel += v * self.dt;
        }
        self.travel_peak = self.travel_peak.max(self.travel);
        if self.travel_peak - self.travel > self.p.reverse_m {
            self.travel_peak = self.travel;
            true
        } else {
            false
        }
    }

    /// One cycle at time `m.t` and odometer `x` (m). Allocation-free.
    ///
    /// Reverse travel (`reverse_m`) clears the preview queue: the odometer
    /// counts forward travel only, so after a reverse every queued road
    /// would be met that many metres early. The road knowledge is then
    /// none (the controller's no-acoustic behaviour, with the wheel's slip
    /// evidence), and it rebuilds from the decisions after
    /// `reverse_hold_s` ([`decision`](Self::decision)).
    pub fn step(&mut self, m: &Measurement, x: f64) -> Guidance {
        if self.reversing(m) {
            self.queue.clear();
            self.reversed_at = m.t;
        }
        let view = self.queue.view(x);
        let alive = m.t - self.last_decision <= self.arte.max_age_s;
        self.belief
            .set_acoustic(view.here.filter(|_| alive).map(|e| (e.road, e.confidence)));
        self.belief.step(m);
        let (road, prob) = self.belief.best();
        let info = self.table.info(road);
        let mut knowledge = info.knowledge(prob, 0.0);
        if let Some(&l) = self.lambda_target.get(road) {
            knowledge.lambda_opt = l;
        }
        // Without a live decision stream the controller falls back to its
        // no-ARTE behaviour (`[arte] max_age_s`): no knowledge, no cap.
        let usable = alive && self.arte.usable(Some(&knowledge)).is_some();
        let (_, lambda) = self.belief.measured();
        // The wheel spins from recover_slip_factor · λ_opt on (hysteresis: a
        // noisy slip at the threshold must not flip the cap every cycle), and
        // its cut ends in time for the motor's lag (`spins`).
        let spinning = self.spins(m, lambda, road, &info);
        // The wheel's word on a binding cap, in the grippy direction: the
        // motor delivers the cap and the wheel slips well below what the
        // believed road would need for it.
        let slip_lp = if lambda.is_finite() {
            self.slip_lp.step(lambda)
        } else {
            f64::NAN
        };
        // Only where the road under the wheel has surely begun (a change
        // heard ahead is placed up to a frame early, the cautious end, and
        // the wheel may still be on the grippier road before it).
        let surely_on = view.here.is_none_or(|h| x >= h.x_sure);
        // The wheel contradicts road `r`'s binding cap this cycle: the motor
        // delivers the cap and the wheel slips well below what `r` would
        // need for it.
        let contradicts = |r: usize| {
            surely_on
                && m.torque >= 0.95 * self.last_cap
                && slip_lp
                    < self.p.release_slip_share
                        * self.lambda_release.get(r).copied().unwrap_or(f64::NAN)
        };
        let (dt, p) = (self.dt, &self.p);
        // The believed road's cap: released until neither the belief (with
        // a usable estimate) nor the heard road (with a live stream) names
        // that road any more, or the wheel spins.
        let believed = usable.then_some(road);
        let here_road = view.here.map(|h| h.road).filter(|_| alive);
        self.verdicts.hold(believed, here_road, spinning);
        let said = believed.is_some_and(contradicts);
        self.verdicts.judge(false, believed, said, dt, p);
        // The same word on the cap of the road the microphone says is under
        // the wheel, when that cap is the one binding (it carries less than
        // the believed road: the cautious direction, which the belief alone
        // does not lift): a wheel that carries that road's cap at well
        // under the slip the road would need for it is on a grippier road
        // (wet stone heard as snow: at snow's 183 N m it slips 0.019, snow
        // would need 0.03). One verdict per road: gravel heard as snow,
        // released on the wheel's word as the believed road, is not capped
        // again at snow's torque when the belief's confidence falls under
        // the gate and the heard road's cap would take over.
        let binding = self.here_binding.filter(|&r| Some(r) == here_road);
        let said = binding.is_some_and(contradicts);
        self.verdicts.judge(true, binding, said, dt, p);

        let mut here_cap = f64::INFINITY;
        let mut cap = f64::INFINITY;
        // What the microphone says of the road under the wheel caps too when
        // it carries less than the believed road: the belief may override
        // acoustics only in the cautious direction (in the grippy one only
        // the release test above lifts it).
        if alive
            && let Some(here) = view.here
            && here.peak_confidence >= self.arte.min_confidence
            && here.hits >= self.p.min_hits
        {
            let h = self.table.info(here.road);
            if (h.mu_peak < info.mu_peak || !usable) && !self.verdicts.overruled(Some(here.road)) {
                here_cap = self.torque(self.p.cap_share, h.mu_peak);
                cap = here_cap;
            }
        }
        if usable && !self.verdicts.overruled(Some(road)) {
            let share = if spinning {
                self.p.recover_share
            } else {
                self.p.cap_share
            };
            cap = cap.min(self.torque(share, info.mu_peak));
        }
        if alive {
            // Every confirmed lower-friction road ahead within the horizon
            // (not only the next entry: a stray decision between two snow
            // decisions must not hide the snow).
            let v = m.v.unwrap_or(self.r * m.omega).max(0.1);
            let here_mu = if usable { info.mu_peak } else { f64::INFINITY };
            let skip = usize::from(view.here.is_some());
            for e in self.queue.entries().iter().skip(skip) {
                let t_arrive = (e.x_start - x).max(0.0) / v;
                if t_arrive > self.p.horizon_s {
                    break;
                }
                let e_info = self.table.info(e.road);
                if e_info.mu_peak < here_mu
                    && e.peak_confidence >= self.arte.min_confidence
                    && e.hits >= self.p.min_hits
                {
                    let target = self.torque(self.p.cap_share, e_info.mu_peak);
                    cap =
                        cap.min(self.approach(m.torque, m.demand, target, t_arrive, self.last_cap));
                }
            }
        }
        self.here_binding = (here_cap.is_finite() && here_cap <= cap)
            .then_some(here_road)
            .flatten();
        self.last_cap = cap;
        Guidance {
            knowledge: alive.then_some(knowledge),
            belief: (road, prob),
            torque_cap: cap,
            view,
        }
    }
}

/// The speed the loop's odometer integrates (the place [`RoadAware`] works
/// in), m/s: the measured vehicle speed `v`, else the wheel's `r · omega`;
/// never negative, 0 when not finite or below `standstill` (`[preview]
/// standstill_mps`: a standing car's speed noise is no travel). `grip sim`
/// and tcs-loop alike. (In reverse the odometer stands; [`RoadAware`]
/// detects the reverse itself, `[preview] reverse_m`, and clears what it
/// had placed on it.)
pub fn odometer_speed(v: Option<f64>, omega: f64, r: f64, standstill: f64) -> f64 {
    let s = v.unwrap_or(r * omega);
    if s.is_finite() && s >= standstill {
        s.max(0.0)
    } else {
        0.0
    }
}

/// The slip in (0, λ_opt] where `mu` reaches `share · mu_peak` (bisection;
/// λ_opt when the share is 1 or the curve is odd): the least slip that
/// carries that friction, on the curve's stable branch. The controllers'
/// target and release slips and `grip_sim::ideal` use it.
pub fn slip_at_share(mu: impl Fn(f64) -> f64, lambda_opt: f64, mu_peak: f64, share: f64) -> f64 {
    if !(lambda_opt > 0.0 && mu_peak > 0.0 && share < 1.0) {
        return lambda_opt;
    }
    let goal = share * mu_peak;
    let (mut lo, mut hi) = (0.0, lambda_opt);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if mu(mid) < goal {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knowledge::KnowledgeConfig;

    fn roads() -> RoadCatalogue {
        RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap()
    }

    fn aware(lead: f64) -> RoadAware {
        aware_with(lead, PreviewParams::default())
    }

    fn aware_with(lead: f64, preview: PreviewParams) -> RoadAware {
        // MTTE: its ARTE variant has no trade of its own by default, so
        // `preview` is what it runs with.
        aware_for(ControllerKind::Mtte, lead, preview)
    }

    /// The road awareness of `kind`'s ARTE variant under `preview`, the
    /// microphone `lead` m ahead of the driven wheel.
    fn aware_for(kind: ControllerKind, lead: f64, preview: PreviewParams) -> RoadAware {
        let roads = roads();
        let v = VehicleParams {
            mic_lead_m: lead,
            ..Default::default()
        };
        let controllers = ControllersConfig {
            preview,
            ..ControllersConfig::default()
        };
        RoadAware::new(
            kind,
            &roads,
            RoadTable::new(&roads, &KnowledgeConfig::default()).unwrap(),
            &v,
            &controllers,
            1e-3,
        )
        .unwrap()
    }

    /// 5 m/s at 1 % slip with the torque `road` transmits there.
    fn cruise(t: f64, road: usize) -> Measurement {
        let lambda: f64 = 0.01;
        let mu = roads()[road].mu(lambda);
        Measurement {
            t,
            omega: 5.0 / (1.0 - lambda) / 0.28,
            v: Some(5.0),
            torque: mu * VehicleParams::default().normal_force() * 0.28,
            demand: 300.0,
        }
    }

    /// 5 m/s at slip `lambda` with the motor at `torque`, 300 N m asked.
    fn slipping(t: f64, lambda: f64, torque: f64) -> Measurement {
        Measurement {
            t,
            omega: 5.0 / (1.0 - lambda) / 0.28,
            v: Some(5.0),
            torque,
            demand: 300.0,
        }
    }

    fn run(a: &mut RoadAware, t0: f64, x0: f64, road: usize, cycles: usize) -> Guidance {
        let mut g = None;
        for k in 0..cycles {
            let t = t0 + k as f64 * 1e-3;
            g = Some(a.step(&cruise(t, road), x0 + 5.0 * (t - t0)));
        }
        g.unwrap()
    }

    #[test]
    fn snow_ahead_caps_the_torque_before_the_wheel_arrives() {
        let mut a = aware(2.77);
        a.decision(0, 0.95, 0.0, -2.77, 0.5); // asphalt from the start
        a.decision(0, 0.95, 0.0, -2.77, 0.5); // heard twice: confirmed
        a.decision(1, 0.95, 0.1, 0.5, 1.0); // snow from 0.5 + 2.77 m
        a.decision(1, 0.95, 0.125, 0.6, 1.1); // heard twice: confirmed
        let snow_cap = 0.19 * 3433.5 * 0.28;
        // 0.1 s of cruising on asphalt up to x = 2.0 (1.27 m = 0.25 s ahead
        // at 5 m/s): not yet.
        let g = run(&mut a, 0.1, 1.5, 0, 100);
        assert_eq!(g.belief.0, 0, "{g:?}");
        assert_eq!(g.view.next.unwrap().0.road, 1);
        assert!(g.torque_cap > 500.0, "{g:?}");
        // At x = 2.4 (0.87 m = 0.17 s ahead) the motor (τ_m 50 ms) can still
        // wait: 259 N m falls to snow's 183 N m in 17 ms with a zero command.
        let g = run(&mut a, 0.2, 2.0, 0, 81);
        assert!(g.torque_cap > 1000.0, "asphalt's own cap only: {g:?}");
        // 0.02 m before the snow (4 ms): the command is at or below snow's cap.
        a.decision(1, 0.95, 0.28, 1.0, 1.5); // the stream goes on
        let g = run(&mut a, 0.281, 2.405, 0, 170);
        assert!(g.torque_cap <= snow_cap + 1e-9, "{g:?}");
        // On the snow the belief follows the acoustic estimate.
        a.decision(1, 0.95, 0.3, 0.8, 1.3);
        let g = run(&mut a, 0.3, 3.3, 1, 150);
        assert_eq!(g.belief.0, 1, "{g:?}");
        assert!((g.torque_cap - snow_cap).abs() < 5.0, "{g:?}");
    }

    /// The previewed drop from 300 N m to snow's cap against a first-order
    /// motor (τ_m = 50 ms, 1 ms steps), arriving in 0.5 s: the commands, the
    /// motor torque at arrival and the first capped cycle.
    fn drop_to(a: &RoadAware, target: f64) -> (Vec<f64>, f64, usize) {
        drop_from(a, 300.0, target)
    }

    /// [`drop_to`] from a demand of `demand` N m.
    fn drop_from(a: &RoadAware, demand: f64, target: f64) -> (Vec<f64>, f64, usize) {
        drop_noisy(a, demand, target, 0.0)
    }

    /// [`drop_from`] with the motor read `noise` N m high on even cycles and
    /// as much low on odd ones.
    fn drop_noisy(a: &RoadAware, demand: f64, target: f64, noise: f64) -> (Vec<f64>, f64, usize) {
        let (dt, tau) = (1e-3, a.tau_m);
        let mut torque = demand;
        let mut cmds = Vec::new();
        let mut first = usize::MAX;
        let mut prev = f64::INFINITY;
        for k in 0..500 {
            let t_arrive = 0.5 - k as f64 * dt;
            let read = torque + if k % 2 == 0 { noise } else { -noise };
            let cmd = a.approach(read, demand, target, t_arrive, prev);
            prev = cmd;
            let cmd = cmd.min(demand);
            if cmd < demand && first == usize::MAX {
                first = k;
            }
            cmds.push(cmd);
            torque += (cmd - torque) * (1.0 - (-dt / tau).exp());
        }
        (cmds, torque, first)
    }

    /// Total variation of the commands `c` of a drop from `from` N m.
    fn tv(c: &[f64], from: f64) -> f64 {
        c.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f64>() + from - c[0]
    }

    #[test]
    fn an_approach_floor_starts_the_drop_earlier_and_still_arrives_at_the_cap() {
        let target = 183.0;
        // The latest drop: a zero command, then the target.
        let mut fast = aware(2.77);
        fast.p.approach_floor = 0.0;
        fast.p.approach_dip = None;
        let (cmds, at, first_fast) = drop_to(&fast, target);
        assert!(cmds.contains(&0.0), "a zero command");
        assert!((at - target).abs() < 3.0, "arrives at {at}");
        assert!(
            tv(&cmds, 300.0) > 2.0 * target,
            "down to 0 and up: {}",
            tv(&cmds, 300.0)
        );
        // With approach_floor 0.5 the drop starts earlier, never below half
        // the target, and the motor still arrives at the cap.
        let mut smooth = aware(2.77);
        smooth.p.approach_floor = 0.5;
        smooth.p.approach_dip = None;
        let (cmds, at, first) = drop_to(&smooth, target);
        assert!(first < first_fast, "earlier: {first} vs {first_fast}");
        let lowest = cmds.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(lowest > 0.49 * target, "never below half the cap: {lowest}");
        assert!((at - target).abs() < 3.0, "arrives at {at}");
        assert!(
            tv(&cmds, 300.0) < (300.0 - target) + 1.1 * target,
            "down to half the cap and up: {}",
            tv(&cmds, 300.0)
        );
    }

    #[test]
    fn a_drop_that_reached_its_target_stays_there_under_a_noisy_torque_reading() {
        // The shipped shape (floor 0.7, dip 0.5), the motor read with
        // +-1.5 N m of noise (the shipped sigma is 1 N m): once the command
        // has come down to the target it stays there, and under way it does
        // not rise again, so the command goes 300 -> the floor -> the target
        // and no further. Without the hold (`approach_hold` absent, the rule
        // before it) the noise moves it.
        let target = 183.0;
        let a = aware(2.77);
        assert_eq!(a.p.approach_hold, Some(1.1), "the shipped hold");
        let (cmds, at, _) = drop_noisy(&a, 300.0, target, 1.5);
        let floor = 0.7 * target;
        assert!(
            cmds.iter().any(|&c| (c - floor).abs() < 1e-6),
            "the floor's command was used"
        );
        let reached = cmds
            .iter()
            .position(|&c| c == target)
            .expect("reaches the target");
        assert!(
            cmds[reached..].iter().all(|&c| c == target),
            "stays at the target: {:?}",
            &cmds[reached..]
        );
        let one_dip = (300.0 - floor) + (target - floor);
        let tv_hold = tv(&cmds, 300.0);
        assert!(tv_hold <= one_dip + 1e-6, "one dip only: tv {tv_hold}");
        assert!((at - target).abs() < 0.03 * target, "arrives at {at}");
        let mut old = aware(2.77);
        old.p.approach_hold = None;
        let (cmds, at, _) = drop_noisy(&old, 300.0, target, 1.5);
        let tv_old = tv(&cmds, 300.0);
        assert!(tv_old > one_dip + 50.0, "the noise moves it: tv {tv_old}");
        assert!((at - target).abs() < 0.03 * target, "arrives at {at}");
        // A motor far above the target is brought down again, whatever the
        // last cycle's cap was.
        let c = a.approach(1.2 * target, 300.0, target, 0.05, target);
        assert!(c < target, "{c}");
    }

    #[test]
    fn a_previewed_drop_through_step_moves_the_command_once_under_a_noisy_reading() {
        // The whole cycle (`step`, its last cap fed back to the drop): snow
        // heard ahead of a wheel on asphalt, a first-order motor read with
        // +-1.5 N m of noise. With the hold the command goes 300 -> the
        // floor -> snow's cap once; without it the noise moves it more.
        let snow_cap = 0.19 * 3433.5 * 0.28;
        let drive = |a: &mut RoadAware| {
            a.decision(0, 0.95, 0.0, -2.77, 0.5);
            a.decision(0, 0.95, 0.0, -2.77, 0.5);
            a.decision(1, 0.95, 0.1, 0.5, 1.0); // snow heard from 0.5 + 2.77 m
            a.decision(1, 0.95, 0.125, 0.6, 1.1);
            let tau = a.tau_m;
            let (mut motor, mut cmds) = (300.0, Vec::new());
            for k in 0..400 {
                let t = 0.1 + k as f64 * 1e-3;
                let x = 1.5 + 5.0 * (t - 0.1);
                // snow placed at change_at (0.375) of its first frame
                if x >= 0.5 + 0.375 * 0.5 + 2.77 {
                    break;
                }
                if k == 180 {
                    a.decision(1, 0.95, t, 1.0, 1.5); // the stream goes on
                }
                let noise = if k % 2 == 0 { 1.5 } else { -1.5 };
                let m = Measurement {
                    torque: motor + noise,
                    ..cruise(t, 0)
                };
                let g = a.step(&m, x);
                assert_eq!(g.belief.0, 0, "on asphalt: {g:?}");
                let cmd = g.torque_cap.min(300.0);
                cmds.push(cmd);
                motor += (cmd - motor) * (1.0 - (-1e-3 / tau).exp());
            }
            (cmds, motor)
        };
        let rises = |c: &[f64]| c.windows(2).filter(|w| w[1] > w[0] + 1e-9).count();
        let floor = 0.7 * snow_cap;
        let one_dip = (300.0 - floor) + (snow_cap - floor);
        let (cmds, at) = drive(&mut aware(2.77));
        let tv_hold = tv(&cmds, 300.0);
        let mut old = aware(2.77);
        old.p.approach_hold = None;
        let (cmds_old, at_old) = drive(&mut old);
        let tv_old = tv(&cmds_old, 300.0);
        assert!(tv_hold <= one_dip + 1e-6, "one dip: tv {tv_hold}");
        assert!(rises(&cmds) <= 1, "one rise at most: {cmds:?}");
        // The price: the hold begins at the first reading within 2 % of the
        // cap, here a low one (-1.5 N m), and the motor arrives a little
        // higher than the old rule's floor commands would have brought it
        // (185.6 against 183.5 N m with this noise).
        assert!((at - snow_cap).abs() < 0.03 * snow_cap, "arrives at {at}");
        assert!(
            (at_old - snow_cap).abs() < 0.03 * snow_cap,
            "arrives at {at_old}"
        );
        assert!(tv_old > tv_hold + 20.0, "the noise moves it: tv {tv_old}");
        assert!(rises(&cmds_old) > 1, "{cmds_old:?}");
    }

    #[test]
    fn an_approach_dip_shapes_a_small_drop_shallow_and_leaves_a_large_one_alone() {
        let target = 183.0;
        let mut floor_only = aware(2.77);
        floor_only.p.approach_floor = 0.7;
        floor_only.p.approach_dip = None;
        let mut dip = aware(2.77);
        dip.p.approach_floor = 0.7;
        dip.p.approach_dip = Some(0.5);
        // 200 N m onto snow's cap (a 17 N m drop): the floor alone dips to
        // 0.7 of the cap, 72 N m down and 55 back up; the dip bound keeps
        // the command within half the drop of the cap, started earlier.
        let (deep, at_deep, first_deep) = drop_from(&floor_only, 200.0, target);
        let (shallow, at, first) = drop_from(&dip, 200.0, target);
        let lowest = shallow.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(lowest >= target - 0.5 * 17.0 - 1e-6, "lowest {lowest}");
        assert!(
            deep.iter().copied().fold(f64::INFINITY, f64::min) < 0.71 * target,
            "the floor alone goes deep"
        );
        assert!(first < first_deep, "earlier: {first} vs {first_deep}");
        assert!((at - target).abs() < 0.03 * target, "arrives at {at}");
        assert!(
            (at_deep - target).abs() < 0.03 * target,
            "arrives at {at_deep}"
        );
        assert!(
            tv(&shallow, 200.0) <= 2.0 * 17.0 + 1e-6,
            "tv {}",
            tv(&shallow, 200.0)
        );
        assert!(tv(&deep, 200.0) > 100.0, "tv {}", tv(&deep, 200.0));
        // 300 N m onto the same cap: the floor (128 N m) is above the dip
        // bound (124.5 N m), so the drop is the floor's, command for command.
        assert_eq!(
            drop_from(&dip, 300.0, target),
            drop_from(&floor_only, 300.0, target)
        );
    }

    #[test]
    fn a_wheel_that_slips_too_little_at_the_cap_releases_it() {
        // Believed snow (heard so), the motor at snow's cap, the wheel at
        // 1 % slip: on snow it would need about 4 %; the road carries more.
        let mut a = aware(0.0);
        a.decision(1, 0.95, 0.0, -0.5, 0.0);
        a.decision(1, 0.95, 0.0, -0.5, 0.0);
        let snow_cap = 0.19 * 3433.5 * 0.28;
        let at_cap = |t: f64| Measurement {
            torque: snow_cap,
            ..cruise(t, 0)
        };
        let g = a.step(&at_cap(0.001), 0.0);
        assert_eq!(g.belief.0, 1, "{g:?}");
        assert!((g.torque_cap - snow_cap).abs() < 1.0, "{g:?}");
        let mut released_at = None;
        for k in 2..200 {
            let t = k as f64 * 1e-3;
            let g = a.step(&at_cap(t), 5.0 * t);
            if released_at.is_none() && g.torque_cap.is_infinite() {
                released_at = Some(t);
            }
        }
        let t = released_at.expect("released");
        assert!(
            (0.02..0.06).contains(&t),
            "after release_s of contradiction: {t}"
        );
        // A wheel that slips as snow would keeps the cap.
        let mut a = aware(0.0);
        a.decision(1, 0.95, 0.0, -0.5, 0.0);
        a.decision(1, 0.95, 0.0, -0.5, 0.0);
        for k in 1..200 {
            let t = k as f64 * 1e-3;
            let g = a.step(&slipping(t, 0.037, snow_cap), 5.0 * t);
            assert!(g.torque_cap <= snow_cap + 1.0, "{t}: {g:?}");
        }
    }

    /// Gravel heard as snow, believed snow: the wheel carries snow's cap
    /// at 1 % slip and lifts it. The motor then delivers the demand and
    /// the belief leaves snow; the road heard under the wheel is still
    /// snow, and its cap, which now binds, was overruled by the same
    /// wheel: it must not come back for another `release_s` (it did, in
    /// `grip sim` on paper.toml, 300 → 183 → 300 N m on gravel).
    #[test]
    fn a_cap_the_wheel_overruled_stays_lifted_when_the_belief_moves_on() {
        let mut a = aware(0.0);
        let snow_cap = 0.19 * 3433.5 * 0.28;
        let asphalt = roads()[0].clone();
        // asphalt's slip for the full 300 N m
        let mu_300 = 300.0 / (3433.5 * 0.28);
        let lam_300 = (1..1000)
            .map(|k| k as f64 * 1e-4)
            .find(|&l| asphalt.mu(l) >= mu_300)
            .unwrap();
        let mut released_at = None;
        let mut recapped = Vec::new();
        let mut left_snow = false;
        for k in 1..600 {
            let t = k as f64 * 1e-3;
            let x = 5.0 * t;
            if k % 25 == 1 {
                // snow heard under the wheel, every hop (a live stream)
                a.decision(1, 0.95, t, x - 0.1, x);
            }
            let m = if released_at.is_none() {
                Measurement {
                    torque: snow_cap,
                    ..cruise(t, 0)
                }
            } else {
                slipping(t, lam_300, 300.0)
            };
            let g = a.step(&m, x);
            if released_at.is_none() && g.torque_cap.is_infinite() {
                released_at = Some(t);
            } else if released_at.is_some() {
                left_snow |= g.belief.0 != 1;
                if g.torque_cap < 300.0 {
                    recapped.push((t, g.torque_cap, g.belief));
                }
            }
        }
        assert!(released_at.is_some(), "the wheel's word lifted snow's cap");
        assert!(
            left_snow,
            "the belief never left snow: the case is not made"
        );
        assert!(recapped.is_empty(), "capped again: {recapped:?}");
    }

    /// Asphalt, snow and wet stone, and a maker of MTTE-ARTE's road
    /// awareness on them (the default vehicle and controllers, 1 kHz).
    fn with_wet_stone() -> (RoadCatalogue, impl Fn() -> RoadAware) {
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow", "wet_stone"]).unwrap();
        let r = roads.clone();
        let mk = move || {
            RoadAware::new(
                ControllerKind::Mtte,
                &r,
                RoadTable::new(&r, &KnowledgeConfig::default()).unwrap(),
                &VehicleParams::default(),
                &ControllersConfig::default(),
                1e-3,
            )
            .unwrap()
        };
        (roads, mk)
    }

    /// Wet stone heard as snow (a confusion the acoustic model makes): the
    /// belief, from the wheel's slip, is wet stone, so the cap that binds
    /// is the heard road's, snow's. At snow's cap the wheel slips 1.9 %,
    /// where snow would need about twice that: the wheel's word lifts the
    /// heard road's cap as it lifts a believed road's. A wheel that slips
    /// as snow would keeps it.
    #[test]
    fn a_wheel_that_slips_too_little_at_the_heard_roads_cap_releases_it() {
        let (roads, mk) = with_wet_stone();
        let snow_cap = roads[1].mu_peak() * 3433.5 * 0.28;
        // (released at, cycles at snow's cap under a wet-stone belief) for a
        // wheel at snow's cap and slip
        // `lambda`, after 0.3 s at 4.4 % slip and 300 N m on wet stone
        // (the belief's evidence)
        let run = |lambda: f64| {
            let mut a = mk();
            let mut released = None;
            let mut capped = 0;
            for k in 1..800 {
                let t = k as f64 * 1e-3;
                if k == 300 {
                    // snow heard under the wheel, twice: confirmed
                    a.decision(1, 0.93, t, 5.0 * t - 0.5, 5.0 * t - 0.4);
                }
                if k >= 300 && k % 25 == 0 {
                    // and on, every hop (a live stream)
                    a.decision(1, 0.93, t, 5.0 * t - 0.4, 5.0 * t - 0.3);
                }
                let m = if k < 300 {
                    slipping(t, 0.044, 300.0)
                } else {
                    slipping(t, lambda, snow_cap)
                };
                let g = a.step(&m, 5.0 * t);
                if k > 300 && g.belief.0 == 2 && (g.torque_cap - snow_cap).abs() < 1.0 {
                    capped += 1;
                }
                if k > 300 && released.is_none() && g.torque_cap > 1.5 * snow_cap {
                    released = Some(t);
                }
            }
            (released, capped)
        };
        let (released, capped) = run(0.019);
        assert!(
            capped > 0,
            "the heard road's cap never bound under a wet-stone belief"
        );
        let t = released.expect("the heard road's cap is released");
        assert!(
            (0.32..0.40).contains(&t),
            "after release_s of contradiction: {t}"
        );
        // at snow's cap a wheel on snow sits near its λ_opt, 0.06
        let (released, _) = run(0.055);
        assert_eq!(
            released, None,
            "a wheel slipping as snow would kept the cap"
        );
    }

    /// The other half of one verdict per road: wet stone believed (from
    /// the slip), snow heard under the wheel, the wheel carrying snow's cap
    /// at 1.9 % lifts the heard road's cap. The wheel then slips too little
    /// to say anything (0.5 % at 300 N m), the slip evidence fades and the
    /// belief follows the microphone to snow: the believed road's cap is
    /// snow's, which the same wheel has overruled, so it must not bind for
    /// another `release_s`.
    #[test]
    fn a_heard_roads_cap_the_wheel_overruled_stays_lifted_when_believed() {
        let (roads, mk) = with_wet_stone();
        let mut a = mk();
        let snow_cap = roads[1].mu_peak() * 3433.5 * 0.28;
        let mut released_at = None;
        let mut believed_snow = 0;
        let mut capped = Vec::new();
        for k in 1..1500 {
            let t = k as f64 * 1e-3;
            if k >= 300 && k % 25 == 0 {
                // snow heard under the wheel, every hop
                a.decision(1, 0.93, t, 5.0 * t - 0.1, 5.0 * t);
            }
            let m = if k < 300 {
                slipping(t, 0.044, 300.0)
            } else if released_at.is_none() {
                slipping(t, 0.019, snow_cap)
            } else {
                slipping(t, 0.005, 300.0)
            };
            let g = a.step(&m, 5.0 * t);
            if k > 300 && released_at.is_none() && g.torque_cap > 1.5 * snow_cap {
                assert_eq!(g.belief.0, 2, "the heard road's cap lifted: {g:?}");
                released_at = Some(t);
            } else if released_at.is_some() && g.belief.0 == 1 {
                believed_snow += 1;
                if g.torque_cap < 300.0 {
                    capped.push((t, g.torque_cap));
                }
            }
        }
        assert!(released_at.is_some(), "the heard road's cap was lifted");
        assert!(
            believed_snow > 100,
            "the belief never followed the microphone to snow ({believed_snow} cycles): the case is not made"
        );
        assert!(capped.is_empty(), "snow's cap came back: {capped:?}");
    }

    /// Believed snow; the wheel spins at 30 % slip under 300 N m, then, the
    /// motor at 80 N m, comes back 0.5 % every 2 ms. The slip at which the
    /// cap is back at snow's cap (None: never above λ_opt).
    fn spin_and_land(landing: f64) -> (Option<f64>, RoadAware, f64) {
        let p = PreviewParams {
            recover_landing: landing,
            ..PreviewParams::default()
        };
        let mut a = aware_with(0.0, p);
        a.decision(1, 0.95, 0.0, -0.5, 0.0);
        a.decision(1, 0.95, 0.0, -0.5, 0.0);
        let snow_cap = 0.19 * 3433.5 * 0.28;
        let mut t = 0.0;
        for _ in 0..20 {
            t += 1e-3;
            let g = a.step(&slipping(t, 0.3, 300.0), 5.0 * t);
            assert_eq!(g.belief.0, 1, "{g:?}");
        }
        let g = a.step(&slipping(t + 1e-3, 0.3, 300.0), 5.0 * t);
        let cut = p.recover_share * snow_cap;
        assert!((g.torque_cap - cut).abs() < 1.0, "the spin is cut: {g:?}");
        let lo = roads()[1].lambda_opt();
        let mut lambda = 0.3;
        while lambda > lo {
            for _ in 0..2 {
                t += 1e-3;
                let g = a.step(&slipping(t, lambda, 80.0), 5.0 * t);
                if g.torque_cap > cut + 1.0 {
                    assert!((g.torque_cap - snow_cap).abs() < 1.0, "{g:?}");
                    return (Some(lambda), a, t);
                }
            }
            lambda -= 0.005;
        }
        (None, a, t)
    }

    #[test]
    fn a_spinning_wheels_cut_ends_when_the_motors_return_will_take_the_rest() {
        // recover_landing 0: the cut holds until the slip is under λ_opt.
        assert_eq!(spin_and_land(0.0).0, None);
        // 0.5: it ends where the wheel's excess angular momentum over the
        // peak, J_w ω (λ − λ_opt) / (1 − λ_opt), is half of what the motor's
        // return from 80 N m through its lag takes against what the tyre
        // carries, (min(cap, μ(λ) N r) − 80) τ_m (beyond λ_opt snow carries
        // a little less than its peak: 0.182 at 20 % slip against 0.190).
        let (landed, mut a, t0) = spin_and_land(0.5);
        let landed = landed.expect("the cut ends above λ_opt");
        let lo = roads()[1].lambda_opt();
        let v = VehicleParams::default();
        let excess = |l: f64| v.j_w * 5.0 / (1.0 - l) / 0.28 * (l - lo) / (1.0 - lo);
        let nr = 3433.5 * 0.28;
        let back = |l: f64| {
            let carried = (roads()[1].mu(l) * nr).min(roads()[1].mu_peak() * nr);
            0.5 * (carried - 80.0) * v.tau_m
        };
        assert!(
            excess(landed) <= back(landed) && excess(landed + 0.005) > back(landed + 0.005),
            "{landed}"
        );
        assert!(landed > 2.0 * lo, "well before the slip is back: {landed}");
        // Landing: the slip wobbling where the cut ended starts no new cut;
        // rising again by the entry band (0.5 λ_opt) above it does.
        let snow_cap = 0.19 * 3433.5 * 0.28;
        for k in 1..=20 {
            let t = t0 + k as f64 * 1e-3;
            let g = a.step(&slipping(t, landed + 0.01, 120.0), 5.0 * t);
            assert!((g.torque_cap - snow_cap).abs() < 1.0, "{g:?}");
        }
        let t = t0 + 0.021;
        let g = a.step(&slipping(t, landed + 0.6 * lo, 120.0), 5.0 * t);
        assert!(g.torque_cap < 0.5 * snow_cap, "a new spin is cut: {g:?}");
    }

    #[test]
    fn a_cap_below_the_target_share_is_judged_by_the_slip_it_needs() {
        // cap_share 0.75 under slip_share 0.95: at its binding cap snow
        // needs the slip where μ = 0.75 μ_peak (about 1.4 %), below 0.7 of
        // the 2.9 % target; a wheel slipping so is on snow and keeps the
        // cap, one at 0.5 % is on something grippier and releases it.
        let slip_run = |lambda: f64| {
            let p = PreviewParams {
                cap_share: 0.75,
                ..PreviewParams::default()
            };
            let mut a = aware_with(0.0, p);
            a.decision(1, 0.95, 0.0, -0.5, 0.0);
            a.decision(1, 0.95, 0.0, -0.5, 0.0);
            let cap = 0.75 * roads()[1].mu_peak() * 3433.5 * 0.28;
            let mut released = false;
            for k in 1..200 {
                let t = k as f64 * 1e-3;
                let g = a.step(&slipping(t, lambda, cap), 5.0 * t);
                released |= g.torque_cap.is_infinite();
            }
            released
        };
        let r = roads();
        let at_cap = slip_at_share(|l| r[1].mu(l), r[1].lambda_opt(), r[1].mu_peak(), 0.75);
        assert!((0.012..0.016).contains(&at_cap), "{at_cap}");
        assert!(!slip_run(at_cap), "released at the slip snow needs");
        assert!(slip_run(0.005), "kept on a road that carries more");
    }

    /// A road aware of `kind` under `preview`, the wheel at lead 0 on snow
    /// (heard twice) for 0.15 s: the cap it gives.
    fn snow_cap_of(kind: ControllerKind, preview: PreviewParams) -> f64 {
        let mut a = aware_for(kind, 0.0, preview);
        a.decision(1, 0.95, 0.0, -0.5, 0.0);
        a.decision(1, 0.95, 0.025, -0.4, 0.1);
        run(&mut a, 0.03, 0.0, 1, 150).torque_cap
    }

    #[test]
    fn each_controller_runs_with_its_own_trade() {
        let snow_peak = 0.19 * 3433.5 * 0.28;
        let p = PreviewParams {
            cap_share: 1.0,
            mfc: PreviewTrade {
                cap_share: Some(0.8),
                slip_share: Some(0.9),
                recover_share: None,
            },
            src: PreviewTrade {
                cap_share: None,
                slip_share: Some(0.85),
                recover_share: Some(0.6),
            },
            mtte: PreviewTrade::default(),
            ..PreviewParams::default()
        };
        let mfc = p.for_controller(ControllerKind::Mfc);
        assert_eq!((mfc.cap_share, mfc.slip_share), (0.8, 0.9));
        assert_eq!(mfc.mfc, PreviewTrade::default(), "applied, not left");
        let src = p.for_controller(ControllerKind::Src);
        assert_eq!((src.cap_share, src.slip_share), (1.0, 0.85));
        assert_eq!(
            (src.recover_share, mfc.recover_share),
            (0.6, p.recover_share)
        );
        let mtte = p.for_controller(ControllerKind::Mtte);
        assert_eq!((mtte.cap_share, mtte.slip_share), (1.0, 0.95));
        assert_eq!(mtte.recover_share, p.recover_share);
        // In the loop: MFC's cap on snow is its own 0.8 of the peak, MTTE's
        // the shared 1.0.
        let cap = snow_cap_of(ControllerKind::Mfc, p);
        assert!((cap - 0.8 * snow_peak).abs() < 1.0, "{cap}");
        let cap = snow_cap_of(ControllerKind::Mtte, p);
        assert!((cap - snow_peak).abs() < 1.0, "{cap}");
        // As shipped (the defaults): SRC-ARTE 0.9, the others 1.0.
        let d = PreviewParams::default();
        let cap = snow_cap_of(ControllerKind::Src, d);
        assert!((cap - 0.9 * snow_peak).abs() < 1.0, "{cap}");
        let cap = snow_cap_of(ControllerKind::Mfc, d);
        assert!((cap - snow_peak).abs() < 1.0, "{cap}");
    }

    #[test]
    fn a_bad_per_controller_trade_is_named() {
        let mut p = PreviewParams::default();
        p.src.cap_share = Some(0.0);
        let e = p.validate().unwrap_err().prefixed("preview");
        assert_eq!(e.field, "preview.src.cap_share", "{e:?}");
        let mut p = PreviewParams::default();
        p.mtte.slip_share = Some(1.2);
        assert_eq!(p.validate().unwrap_err().field, "mtte.slip_share");
        let text = "cap_share = 1.0\nrecover_share = 0.4\nrecover_slip_factor = 1.5\n\
                    horizon_s = 1.0\nlag_margin_s = 0.02\nchange_at = 0.0\nmin_hits = 2\n\
                    slip_share = 0.95\nrelease_slip_share = 0.7\nrelease_s = 0.02\n";
        let p: PreviewParams = toml::from_str(text).unwrap();
        assert_eq!(p.src, PreviewTrade::default(), "absent: none");
        let p: PreviewParams = toml::from_str(&format!("{text}[mfc]\ncap_share = 0.9\n")).unwrap();
        assert_eq!(p.mfc.cap_share, Some(0.9));
        let e = toml::from_str::<PreviewParams>(&format!("{text}[src]\ncap = 0.9\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown field `cap`"), "{e}");
    }

    #[test]
    fn slip_target_at_a_share_of_the_peak() {
        // The flat-peak table of the docs: snow 95 % at λ 0.029, asphalt at 0.100.
        let r = roads();
        for (i, want) in [(0, 0.100), (1, 0.029)] {
            let l = slip_at_share(|l| r[i].mu(l), r[i].lambda_opt(), r[i].mu_peak(), 0.95);
            assert!((l - want).abs() < 0.002, "{i}: {l}");
            assert!((r[i].mu(l) - 0.95 * r[i].mu_peak()).abs() < 1e-9);
        }
        assert_eq!(slip_at_share(|l| l, 0.2, 0.2, 1.0), 0.2);
    }

    /// The car at speed `v` (m/s, its wheel turning with it), `torque` at
    /// the motor and `demand` asked, at time `t`.
    fn moving(t: f64, v: f64, torque: f64, demand: f64) -> Measurement {
        Measurement {
            t,
            omega: v / 0.28,
            v: Some(v),
            torque,
            demand,
        }
    }

    /// Snow queued 0.5 m + lead ahead (heard twice), asphalt before it;
    /// the wheel at x = 0.
    fn snow_ahead() -> RoadAware {
        let mut a = aware(2.77);
        a.decision(0, 0.95, 0.0, -2.77, -2.77);
        a.decision(0, 0.95, 0.0, -2.77, -2.77);
        a.decision(1, 0.95, 0.0, 0.5, 0.5);
        a.decision(1, 0.95, 0.0, 0.5, 0.5);
        a
    }

    #[test]
    fn reversing_clears_the_queue_and_drops_what_was_heard_meanwhile() {
        let snow_cap = 0.19 * 3433.5 * 0.28;
        let mut a = snow_ahead();
        let g = a.step(&moving(0.001, 0.0, 0.0, 0.0), 0.0);
        assert_eq!(g.view.here.unwrap().road, 0);
        let (next, d) = g.view.next.unwrap();
        assert_eq!(next.road, 1);
        assert!((d - 3.27).abs() < 1e-9, "{d}");
        // 1 m back at 1 m/s (the odometer, forward travel only, stands at
        // 0), the microphone's decisions going on every 0.1 s.
        let mut t = 0.001;
        for k in 1..=1000 {
            t = 0.001 + k as f64 * 1e-3;
            let g = a.step(&moving(t, -1.0, -100.0, -100.0), 0.0);
            if k % 100 == 0 {
                a.decision(1, 0.95, t, 0.0, 0.0);
            }
            if k > 100 {
                assert!(g.torque_cap.is_infinite(), "{k}: {g:?}");
            }
        }
        // The queue is empty: the snow 3.27 m ahead of x = 0 is now 4.27 m
        // ahead of the wheel, and no place on the odometer says so.
        assert!(a.queue.is_empty(), "{:?}", a.queue.entries());
        let end = t;
        assert!(
            (end - 0.1..=end).contains(&a.reversed_at),
            "last detected {} (reverse ended {end})",
            a.reversed_at
        );
        // Standing: a decision within reverse_hold_s (0.6 s) of the last
        // detection is dropped, and still keeps the stream alive; a later
        // one is queued, ahead of the wheel by the lead.
        let hold = PreviewParams::default().reverse_hold_s;
        assert_eq!(hold, 0.6);
        let mut queued_at = None;
        for k in 1..=800 {
            t = end + k as f64 * 1e-3;
            let g = a.step(&moving(t, 0.0, 0.0, 300.0), 0.0);
            if k % 100 == 0 {
                a.decision(1, 0.95, t, 0.0, 0.0);
                if queued_at.is_none() && !a.queue.is_empty() {
                    queued_at = Some(t);
                }
            }
            assert!(g.knowledge.is_some(), "{k}: the stream is alive");
        }
        let queued_at = queued_at.expect("a decision after the hold is queued");
        assert!(
            queued_at > a.reversed_at + hold && queued_at <= a.reversed_at + hold + 0.1,
            "first queued at {queued_at}, last reverse at {}",
            a.reversed_at
        );
        let e = a.queue.entries();
        assert_eq!(e.len(), 1, "{e:?}");
        assert!(e[0].road == 1 && e[0].hits >= 2, "{e:?}");
        assert!((e[0].x_start - 2.77).abs() < 1e-9, "{e:?}");
        // The snow, heard now, caps as the wheel comes to it.
        let g = a.step(&moving(t + 0.001, 1.0, 250.0, 300.0), 2.7);
        assert!(g.torque_cap <= snow_cap + 1e-9, "{g:?}");
    }

    #[test]
    fn standing_still_with_speed_noise_keeps_the_queue() {
        // Stopped on snow (heard twice under the wheel), asphalt heard
        // ahead; 60 s of standstill with the shipped sensors' noise (V:
        // σ 0.02 m/s, ω: σ 0.05 rad/s, Gaussian, a fixed sequence), the
        // decisions going on: the queue stays, and the car pulls away capped
        // at snow's cap (until `spin_dv_min` the standstill's noise cut it to
        // 0.4 of that, which passed for "capped" against a rounded peak).
        let snow_cap = roads()[1].mu_peak() * 3433.5 * 0.28;
        let mut a = aware(2.77);
        a.decision(1, 0.95, 0.0, -2.77, -2.77);
        a.decision(1, 0.95, 0.0, -2.77, -2.77);
        a.decision(0, 0.95, 0.0, 0.0, 0.0);
        a.decision(0, 0.95, 0.0, 0.0, 0.0);
        let before = a.queue.entries().to_vec();
        assert_eq!(before.len(), 2);
        let mut seed: u64 = 4242;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut gauss = || {
            let (u1, u2) = (uniform(), uniform());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        let (mut drift, mut lowest) = (0.0, 0.0f64);
        let mut g = None;
        for k in 1..=60_000u32 {
            let t = f64::from(k) * 1e-3;
            let v = 0.02 * gauss();
            let omega = 0.05 * gauss();
            drift += v * 1e-3;
            lowest = lowest.min(drift);
            let m = Measurement {
                t,
                omega,
                v: Some(v),
                torque: 0.0,
                demand: if k > 59_000 { 300.0 } else { 0.0 },
            };
            g = Some(a.step(&m, 0.0));
            if k % 100 == 0 {
                a.decision(0, 0.95, t, 0.0, 0.0);
            }
        }
        let g = g.unwrap();
        assert!(lowest > -0.05, "the noise's own drift: {lowest} m");
        assert_eq!(a.reversed_at, f64::NEG_INFINITY, "no reverse detected");
        let after = a.queue.entries();
        assert_eq!(after.len(), 2, "{after:?}");
        assert_eq!((after[0].road, after[0].x_start), (1, 0.0));
        assert_eq!((after[1].road, after[1].x_start), (0, 2.77));
        assert_eq!(g.view.here.unwrap().road, 1);
        assert!(
            (g.torque_cap - snow_cap).abs() < 1e-9,
            "pulls away at snow's cap: {g:?}"
        );
    }

    /// One hour standing with the shipped V sensor's noise (σ 0.02 m/s,
    /// Gaussian, 1 kHz): with the shipped `standstill_mps` the odometer
    /// stays within a centimetre; without it (0, the rule before) it
    /// integrates the noise's positive half, ~29 m. Moving speeds pass
    /// unchanged; reverse, NaN and infinity add nothing.
    #[test]
    fn a_standing_cars_speed_noise_does_not_move_the_odometer() {
        let shipped = PreviewParams::default().standstill_mps;
        assert_eq!(shipped, 0.1);
        let mut seed: u64 = 77;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (mut with, mut without) = (0.0, 0.0);
        for _ in 0..3_600_000u32 {
            let (u1, u2) = (uniform(), uniform());
            let v = 0.02 * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            with += odometer_speed(Some(v), 0.0, 0.28, shipped) * 1e-3;
            without += odometer_speed(Some(v), 0.0, 0.28, 0.0) * 1e-3;
        }
        assert!(with < 0.01, "with the standstill: {with} m in an hour");
        assert!(
            (25.0..33.0).contains(&without),
            "without it: {without} m in an hour (σ/√(2π) · 3600 s = 28.7 m)"
        );
        for v in [0.1, 0.5, 2.78, 30.0] {
            assert_eq!(odometer_speed(Some(v), 0.0, 0.28, shipped), v);
        }
        // no V: the wheel's r·ω, under the same rule
        assert!((odometer_speed(None, 10.0, 0.28, shipped) - 2.8).abs() < 1e-12);
        assert_eq!(odometer_speed(None, 0.3, 0.28, shipped), 0.0);
        for v in [-0.05, -3.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(odometer_speed(Some(v), 0.0, 0.28, shipped), 0.0, "{v}");
        }
    }

    /// A speed sensor that reads -0.05 m/s at rest (an offset, not noise):
    /// the signed distance would fall 0.1 m in 2 s and clear the queue as
    /// a reverse; under `standstill_mps` it is no travel. A real reverse
    /// (0.5 m/s) is still detected.
    #[test]
    fn a_standstill_offset_is_no_reverse_but_a_reverse_is() {
        let standing = |standstill_mps: f64| {
            let mut a = aware_with(
                2.77,
                PreviewParams {
                    standstill_mps,
                    ..PreviewParams::default()
                },
            );
            a.decision(0, 0.95, 0.0, 0.0, 0.0);
            a.decision(0, 0.95, 0.0, 0.0, 0.0);
            for k in 1..=5000u32 {
                a.step(&moving(f64::from(k) * 1e-3, -0.05, 0.0, 0.0), 0.0);
            }
            a
        };
        let a = standing(0.0);
        assert!(
            a.reversed_at > 0.0,
            "without the standstill: a false reverse"
        );
        assert!(a.queue.is_empty());
        let a = standing(0.1);
        assert_eq!(a.reversed_at, f64::NEG_INFINITY, "no reverse at rest");
        assert_eq!(a.queue.entries().len(), 1);
        let mut a = standing(0.1);
        for k in 5001..=5400u32 {
            a.step(&moving(f64::from(k) * 1e-3, -0.5, 0.0, 0.0), 0.0);
        }
        assert!(
            a.reversed_at > 5.0,
            "a 0.2 m reverse at 0.5 m/s: {}",
            a.reversed_at
        );
        assert!(a.queue.is_empty());
    }

    /// Cycles of a creeping pull-away on snow (heard so under the wheel,
    /// the motor at snow's cap) in which the spin cut acts: the car from
    /// 0.2 to 1.0 m/s, the wheel 3 % faster, both speeds with the shipped
    /// sensors' noise (σ 0.05 rad/s, 0.02 m/s), and from `spin_at` (cycle)
    /// a wheel that really spins, `spin_dv` m/s faster than the car.
    fn creep_cuts(spin_dv_min: f64, spin_at: u32, spin_dv: f64) -> (u32, Option<u32>) {
        let p = PreviewParams {
            spin_dv_min,
            ..PreviewParams::default()
        };
        let mut a = aware_with(0.0, p);
        let snow_cap = roads()[1].mu_peak() * 3433.5 * 0.28;
        let mut seed: u64 = 7;
        let mut gauss = move || {
            // sum of 12 uniforms less 6: unit variance
            let mut s = -6.0;
            for _ in 0..12 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += (seed >> 11) as f64 / (1u64 << 53) as f64;
            }
            s
        };
        let (mut cuts, mut first_cut_after_spin) = (0, None);
        let mut x = 0.0;
        for k in 0..2000u32 {
            let t = f64::from(k) * 1e-3;
            if k % 25 == 0 {
                a.decision(1, 0.95, t, x, x);
            }
            let v = 0.2 + 0.8 * t / 2.0;
            let rw = if k >= spin_at { v + spin_dv } else { 1.03 * v };
            let m = Measurement {
                t,
                omega: rw / 0.28 + 0.05 * gauss(),
                v: Some(v + 0.02 * gauss()),
                torque: snow_cap,
                demand: 300.0,
            };
            x += v * 1e-3;
            let g = a.step(&m, x);
            if k >= 50 && g.torque_cap < 0.5 * snow_cap {
                cuts += 1;
                if k >= spin_at && first_cut_after_spin.is_none() {
                    first_cut_after_spin = Some(k - spin_at);
                }
            }
        }
        (cuts, first_cut_after_spin)
    }

    #[test]
    fn creep_noise_is_no_spin_but_a_spin_at_creep_is_cut() {
        // Without the floor the sensors' noise cuts the torque again and
        // again (the pull-away of crates/tcs/README.md, "The spin cut at
        // creep"); with the shipped 0.15 m/s not once.
        let (noisy, _) = creep_cuts(0.0, u32::MAX, 0.0);
        assert!(noisy >= 10, "{noisy} cut cycles without the floor");
        let (cuts, _) = creep_cuts(PreviewParams::default().spin_dv_min, u32::MAX, 0.0);
        assert_eq!(cuts, 0);
        // A wheel that spins 0.5 m/s faster than the car at 0.6 m/s (slip
        // 0.45) is cut within 2 ms.
        let (_, after) = creep_cuts(PreviewParams::default().spin_dv_min, 1000, 0.5);
        assert!(after.is_some_and(|k| k <= 2), "{after:?}");
    }

    #[test]
    fn rolling_back_under_a_forward_demand_keeps_asphalt_s_cap() {
        // A hill start that rolled back: the car at 3 m/s backwards on
        // asphalt (heard so under the wheel), the motor at 400 N m, the
        // wheel turning with the car (its speed sensor's noise, ±0.03 m/s).
        // reverse_m at its largest (10 m) so that the queue stays for the
        // second's 3 m: the belief and the spin cut alone. Neither goes
        // below asphalt's cap: the slip is the plant's, about noise over
        // 3 m/s (over v_eps, as before, 30 % of noise: snow's cap, the cut).
        let asphalt_cap = roads()[0].mu_peak() * 3433.5 * 0.28;
        let p = PreviewParams {
            reverse_m: 10.0,
            ..PreviewParams::default()
        };
        let mut a = aware_with(0.0, p);
        let mut seed: u64 = 99;
        for k in 0..1000u32 {
            let t = f64::from(k) * 1e-3;
            if k % 25 == 0 {
                a.decision(0, 0.95, t, 0.0, 0.0);
            }
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
            let m = Measurement {
                t,
                omega: (-3.0 + 0.03 * u) / 0.28,
                v: Some(-3.0),
                torque: 400.0,
                demand: 400.0,
            };
            let g = a.step(&m, 0.0);
            if k >= 1 {
                assert_eq!(g.belief.0, 0, "{k}: {g:?}");
                assert!(g.torque_cap >= asphalt_cap - 1e-9, "{k}: {g:?}");
            }
        }
        assert!(a.queue.len() == 1, "no reverse detected within 10 m");
    }

    #[test]
    fn reverse_limits_are_checked() {
        for (field, v) in [
            ("reverse_m", 0.0),
            ("reverse_m", f64::NAN),
            ("reverse_m", 11.0),
            ("reverse_hold_s", -0.1),
            ("reverse_hold_s", f64::NAN),
        ] {
            let mut p = PreviewParams::default();
            match field {
                "reverse_m" => p.reverse_m = v,
                _ => p.reverse_hold_s = v,
            }
            assert_eq!(p.validate().unwrap_err().field, field, "{v}");
        }
        // Absent from a file: the shipped values.
        let text = "cap_share = 1.0\nrecover_share = 0.4\nrecover_slip_factor = 1.5\n\
                    horizon_s = 1.0\nlag_margin_s = 0.02\nchange_at = 0.0\nmin_hits = 2\n\
                    slip_share = 0.95\nrelease_slip_share = 0.7\nrelease_s = 0.02\n";
        let p: PreviewParams = toml::from_str(text).unwrap();
        assert_eq!((p.reverse_m, p.reverse_hold_s), (0.1, 0.6));
        let p: PreviewParams =
            toml::from_str(&format!("{text}reverse_m = 0.2\nreverse_hold_s = 0\n")).unwrap();
        assert_eq!((p.reverse_m, p.reverse_hold_s), (0.2, 0.0));
        // The spin cut's speed-difference floor: absent, none (older drive
        // logs replay as recorded); checked like the others.
        assert_eq!(p.spin_dv_min, 0.0);
        let p: PreviewParams = toml::from_str(&format!("{text}spin_dv_min = 0.15\n")).unwrap();
        assert_eq!(p.spin_dv_min, 0.15);
        for v in [-0.01, 10.5, f64::NAN] {
            let p = PreviewParams {
                spin_dv_min: v,
                ..PreviewParams::default()
            };
            assert_eq!(p.validate().unwrap_err().field, "spin_dv_min", "{v}");
        }
        // The standstill: absent, none (older logs replay as recorded).
        assert_eq!(p.standstill_mps, 0.0);
        let p: PreviewParams = toml::from_str(&format!("{text}standstill_mps = 0.1\n")).unwrap();
        assert_eq!(p.standstill_mps, 0.1);
        for v in [-0.01, 1.5, f64::NAN] {
            let p = PreviewParams {
                standstill_mps: v,
                ..PreviewParams::default()
            };
            assert_eq!(p.validate().unwrap_err().field, "standstill_mps", "{v}");
        }
    }

    #[test]
    fn a_dead_decision_stream_gives_no_acoustic_knowledge() {
        let mut a = aware(0.0);
        a.decision(1, 0.95, 0.0, 0.0, 0.5);
        a.decision(1, 0.95, 0.0, 0.0, 0.5);
        let g = run(&mut a, 0.01, 0.6, 1, 40);
        assert_eq!(g.belief.0, 1);
        assert!(g.torque_cap < 200.0, "{g:?}");
        // No decision for 5 s: the acoustic prior is gone; on a road that
        // neither curve rules out at 1 % slip the belief stays uncertain.
        let g = run(&mut a, 5.0, 25.0, 1, 1);
        assert!(g.belief.1 < 0.999, "{g:?}");
    }

    #[test]
    fn one_verdict_per_road_holds_while_either_way_names_it() {
        let p = PreviewParams::default();
        let dt = 0.001;
        let mut v = Verdicts::new(3);
        // The believed road 1's cap, contradicted for release_s: overruled.
        let cycles = (p.release_s / dt).ceil() as usize + 1;
        for _ in 0..cycles {
            v.hold(Some(1), None, false);
            v.judge(false, Some(1), true, dt, &p);
        }
        assert!(v.overruled(Some(1)));
        // The belief moves on while the heard road is 1: the verdict holds,
        // and the heard road's cap of 1 is not judged again.
        v.hold(Some(2), Some(1), false);
        v.judge(true, Some(1), true, dt, &p);
        assert!(v.overruled(Some(1)) && v.heard_s == 0.0);
        assert!(!v.overruled(Some(2)) && !v.overruled(Some(0)));
        // Neither way names 1 any more: gone, and coming back to it needs
        // the wheel's word again.
        v.hold(Some(2), Some(0), false);
        v.hold(Some(1), Some(1), false);
        assert!(!v.overruled(Some(1)));
        // A spinning wheel ends every verdict, named or not.
        for _ in 0..cycles {
            v.judge(true, Some(1), true, dt, &p);
        }
        assert!(v.overruled(Some(1)));
        v.hold(Some(1), Some(1), true);
        assert!(!v.overruled(Some(1)));
        // A contradiction broken before release_s starts the clock again:
        // two runs of nearly release_s each, one cycle apart, do not overrule.
        for _ in 0..2 {
            for _ in 0..cycles - 2 {
                v.judge(false, Some(0), true, dt, &p);
            }
            assert!(!v.overruled(Some(0)));
            v.judge(false, Some(0), false, dt, &p);
        }
        assert!(!v.overruled(Some(0)) && v.believed_s == 0.0);
        // A spinning wheel ends a verdict whether or not a way names it.
        for _ in 0..cycles {
            v.judge(false, Some(2), true, dt, &p);
        }
        assert!(v.overruled(Some(2)));
        v.hold(None, None, true);
        assert!(!v.overruled(Some(2)));
        // A road outside the catalogue is never overruled, and no panic.
        for _ in 0..cycles {
            v.judge(false, Some(7), true, dt, &p);
        }
        assert!(!v.overruled(Some(7)) && !v.overruled(None));
        v.reset();
        assert!(!v.overruled.iter().any(|&o| o));
    }
}
