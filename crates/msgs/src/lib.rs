//! grip-msgs: the fixed-size payloads every grip process exchanges over
//! iceoryx2, and the names of every service and topic.
//!
//! Every payload is `#[repr(C)]`, `Copy`, holds no pointer and no heap data,
//! and derives iceoryx2's [`ZeroCopySend`] with a *versioned* type name
//! (`grip::<Type>::v<N>`). iceoryx2 refuses to connect a publisher and a
//! subscriber whose type names or layouts differ, so changing a layout means
//! bumping the version in the type name (and in [`TYPE_NAME`](AudioBlock::TYPE_NAME)).
//!
//! Layouts have no implicit padding: every gap is an explicit `_reserved`
//! field that senders keep at zero. The static assertions at the end of this
//! file pin size and alignment of each type; a layout change fails to compile.
//!
//! Times are `CLOCK_MONOTONIC` nanoseconds (`stamp_ns`), physical values are
//! SI (rad/s, m/s, N m, m). This crate depends only on iceoryx2's traits; the
//! JSON mapping for MCAP lives in `grip-io`.
#![warn(missing_docs)]

use iceoryx2::prelude::ZeroCopySend;

pub mod topics;

/// Largest number of samples one [`AudioBlock`] can carry. Block sizes up to
/// this are configurable; `n_samples` says how many are valid.
pub const AUDIO_MAX_SAMPLES: usize = 4096;
/// Number of road classes a [`RoadEstimate`] can carry probabilities for.
pub const MAX_ROAD_CLASSES: usize = 8;
/// Length of a fixed road/class name field (ASCII/UTF-8, zero padded).
pub const NAME_LEN: usize = 16;
/// `class_index` / `road_index` value meaning "no class" (not yet estimated,
/// or unknown road).
pub const NO_CLASS: u32 = u32::MAX;

/// Writes `name` into a zero-padded fixed field, truncating at a UTF-8
/// character boundary if it is longer than [`NAME_LEN`] bytes.
pub fn name_to_bytes(name: &str) -> [u8; NAME_LEN] {
    let mut out = [0u8; NAME_LEN];
    let mut end = name.len().min(NAME_LEN);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    out[..end].copy_from_slice(&name.as_bytes()[..end]);
    out
}

/// Reads a zero-padded fixed name field: the bytes up to the first zero.
/// Returns `None` if those bytes are not UTF-8.
pub fn name_from_bytes(bytes: &[u8; NAME_LEN]) -> Option<&str> {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(NAME_LEN);
    core::str::from_utf8(&bytes[..end]).ok()
}

/// One block of mono PCM from `audio-acq` (microphone near the tyre).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("grip::AudioBlock::v1")]
#[repr(C)]
pub struct AudioBlock {
    /// Block sequence number, +1 per block (gaps = lost blocks).
    pub seq: u64,
    /// CLOCK_MONOTONIC time of the first sample, ns.
    pub stamp_ns: u64,
    /// Sample rate, Hz.
    pub sample_rate: u32,
    /// Valid samples in `samples` (≤ [`AUDIO_MAX_SAMPLES`]).
    pub n_samples: u32,
    /// Capture channel this block came from (0-based).
    pub channel: u16,
    /// Explicit padding, zero.
    pub _reserved: u16,
    /// Capture overruns (xruns) counted since the start of the service.
    pub xruns: u32,
    /// Signed 16-bit PCM; only the first `n_samples` are meaningful.
    pub samples: [i16; AUDIO_MAX_SAMPLES],
}

impl AudioBlock {
    /// Versioned type name (same string iceoryx2 and the MCAP schema use).
    pub const TYPE_NAME: &'static str = "grip::AudioBlock::v1";

    /// An all-zero block (no samples).
    pub const fn zeroed() -> Self {
        Self {
            seq: 0,
            stamp_ns: 0,
            sample_rate: 0,
            n_samples: 0,
            channel: 0,
            _reserved: 0,
            xruns: 0,
            samples: [0; AUDIO_MAX_SAMPLES],
        }
    }

    /// The valid samples (clamped to the array if `n_samples` is corrupt).
    pub fn samples(&self) -> &[i16] {
        let n = (self.n_samples as usize).min(AUDIO_MAX_SAMPLES);
        &self.samples[..n]
    }
}

impl Default for AudioBlock {
    fn default() -> Self {
        Self::zeroed()
    }
}

/// One road-type decision of `arte` for one audio frame.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("grip::RoadEstimate::v2")]
#[repr(C)]
pub struct RoadEstimate {
    /// Decision sequence number.
    pub seq: u64,
    /// CLOCK_MONOTONIC time the decision was published, ns.
    pub stamp_ns: u64,
    /// Start of the audio frame the decision is about, ns.
    pub frame_t0_ns: u64,
    /// End of that frame, ns.
    pub frame_t1_ns: u64,
    /// Index of the winning class in the classifier's class list, or [`NO_CLASS`].
    pub class_index: u32,
    /// Number of valid entries in `probabilities`.
    pub n_classes: u32,
    /// Name of the winning class, zero padded (see [`name_to_bytes`]).
    pub class_name: [u8; NAME_LEN],
    /// Class probabilities (first `n_classes` valid), sum ≈ 1.
    pub probabilities: [f32; MAX_ROAD_CLASSES],
    /// Confidence of the decision in [0, 1].
    pub confidence: f64,
    /// Optimal slip of the estimated road's μ-λ curve.
    pub lambda_opt: f64,
    /// Peak friction coefficient of that curve.
    pub mu_peak: f64,
    /// MTTE relaxation factor α the road implies.
    pub alpha: f64,
    /// tcs-loop's odometer (`CycleRecord::odometer`, m) at the start of the
    /// audio frame: where the microphone began hearing it, less the
    /// microphone's lead. NaN when no fresh cycle record was at hand.
    pub x_from: f64,
    /// The odometer at the end of the audio frame, m (NaN as `x_from`).
    pub x_to: f64,
}

impl RoadEstimate {
    /// Versioned type name.
    pub const TYPE_NAME: &'static str = "grip::RoadEstimate::v2";

    /// All-zero estimate with `class_index = NO_CLASS`.
    pub const fn zeroed() -> Self {
        Self {
            seq: 0,
            stamp_ns: 0,
            frame_t0_ns: 0,
            frame_t1_ns: 0,
            class_index: NO_CLASS,
            n_classes: 0,
            class_name: [0; NAME_LEN],
            probabilities: [0.0; MAX_ROAD_CLASSES],
            confidence: 0.0,
            lambda_opt: 0.0,
            mu_peak: 0.0,
            alpha: 0.0,
            x_from: f64::NAN,
            x_to: f64::NAN,
        }
    }

    /// The winning class's name, if the field is valid UTF-8.
    pub fn class_name(&self) -> Option<&str> {
        name_from_bytes(&self.class_name)
    }
}

impl Default for RoadEstimate {
    fn default() -> Self {
        Self::zeroed()
    }
}

/// Fault counters of the E2E-protected CAN receive path (one set per
/// receiver or summed over all receivers). Counts since start, wrapping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ZeroCopySend)]
#[type_name("grip::E2eFaults::v1")]
#[repr(C)]
pub struct E2eFaults {
    /// Frames whose CRC did not match.
    pub crc: u32,
    /// Frames whose alive counter repeated the previous one.
    pub counter_repeated: u32,
    /// Frames whose alive counter jumped (frames lost in between).
    pub counter_skipped: u32,
    /// Frames with the wrong length (DLC).
    pub length: u32,
    /// Frames with an identifier the protocol does not know.
    pub unknown_id: u32,
    /// Timeout episodes: a message stayed away longer than its timeout.
    pub timeout: u32,
}

impl E2eFaults {
    /// Versioned type name.
    pub const TYPE_NAME: &'static str = "grip::E2eFaults::v1";

    /// Sum of all fault counts.
    pub fn total(&self) -> u64 {
        u64::from(self.crc)
            + u64::from(self.counter_repeated)
            + u64::from(self.counter_skipped)
            + u64::from(self.length)
            + u64::from(self.unknown_id)
            + u64::from(self.timeout)
    }

    /// Field-wise wrapping sum.
    pub fn add(&mut self, o: &E2eFaults) {
        self.crc = self.crc.wrapping_add(o.crc);
        self.counter_repeated = self.counter_repeated.wrapping_add(o.counter_repeated);
        self.counter_skipped = self.counter_skipped.wrapping_add(o.counter_skipped);
        self.length = self.length.wrapping_add(o.length);
        self.unknown_id = self.unknown_id.wrapping_add(o.unknown_id);
        self.timeout = self.timeout.wrapping_add(o.timeout);
    }
}

/// What happened in one cycle of `tcs-loop`.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("grip::CycleRecord::v2")]
#[repr(C)]
pub struct CycleRecord {
    /// Cycle number.
    pub seq: u64,
    /// CLOCK_MONOTONIC time of the cycle's deadline (its nominal start), ns.
    pub stamp_ns: u64,
    /// Wake-up time minus deadline, ns (≥ 0 with an absolute timer).
    pub wakeup_latency_ns: i64,
    /// Time from wake-up to command sent, ns.
    pub compute_ns: u64,
    /// Deadline misses counted since start.
    pub deadline_misses: u64,
    /// Measured driven-wheel speed ω, rad/s.
    pub omega: f64,
    /// Measured vehicle speed V, m/s (meaningful when `v_valid` = 1).
    pub v: f64,
    /// Measured torque T at one driven wheel (the motor's after the gear,
    /// per driven wheel, as every torque here), N m.
    pub torque: f64,
    /// Driver demand T_d, N m (one driven wheel).
    pub demand: f64,
    /// Torque command T* sent to the inverter, N m (one driven wheel).
    pub torque_cmd: f64,
    /// Controller internal variable (MFC: the model's wheel speed ω_M,
    /// rad/s; SRC: λ*; MTTE: T_max, N m).
    pub internal: f64,
    /// Controller's friction estimate μ̂ (SRC, MTTE; NaN for MFC). Not the
    /// road's μ while road knowledge's cap binds MTTE's command.
    pub mu_hat: f64,
    /// Odometer: integral of the measured vehicle speed since start, m.
    pub odometer: f64,
    /// Torque cap of the road knowledge (ARTE on), N m; NaN: no cap.
    pub torque_cap: f64,
    /// Probability of the believed road (ARTE on), NaN without.
    pub belief_prob: f64,
    /// The newest road estimate's class index (the model's class list: the
    /// road heard at the microphone), set when `used_arte` is 1;
    /// `NO_CLASS` otherwise.
    pub road_class: u32,
    /// Catalogue index of the believed road (ARTE on), `NO_CLASS` without.
    pub belief_road: u32,
    /// 1 if the road belief was usable this cycle (a decision within
    /// `[arte] max_age_s`, the belief's probability at or above
    /// `min_confidence`); road knowledge's torque cap acts without it.
    pub used_arte: u8,
    /// 1 if the loop was in its safe state (sensor timeout, fault).
    pub safe_state: u8,
    /// 1 if `v` holds a valid measurement.
    pub v_valid: u8,
    /// How many road estimates this cycle took from `grip/arte/road`, the
    /// newest of them named by `road_taken` (every estimate is taken, in
    /// order: a burst after arte caught up is queued whole). 0 with a
    /// non-zero `road_taken`: a log from before this count (the byte was
    /// padding), whose loop took the newest estimate only.
    pub roads_taken: u8,
    /// CAN receive faults counted since start (all messages summed).
    pub faults: E2eFaults,
    /// The newest road estimate this cycle took from `grip/arte/road`
    /// (the one it holds): 1 + the low 32 bits of its `seq`; 0 if it took
    /// none. With `roads_taken`, what a replay needs to hand the loop the
    /// same estimates in the same cycle (an estimate's own stamp cannot
    /// tell: it races the poll).
    pub road_taken: u32,
}

impl CycleRecord {
    /// Versioned type name.
    pub const TYPE_NAME: &'static str = "grip::CycleRecord::v2";

    /// All-zero record (`road_class = NO_CLASS`).
    pub const fn zeroed() -> Self {
        Self {
            seq: 0,
            stamp_ns: 0,
            wakeup_latency_ns: 0,
            compute_ns: 0,
            deadline_misses: 0,
            omega: 0.0,
            v: 0.0,
            torque: 0.0,
            demand: 0.0,
            torque_cmd: 0.0,
            internal: 0.0,
            mu_hat: 0.0,
            odometer: 0.0,
            torque_cap: f64::NAN,
            belief_prob: f64::NAN,
            road_class: NO_CLASS,
            belief_road: NO_CLASS,
            used_arte: 0,
            safe_state: 0,
            v_valid: 0,
            roads_taken: 0,
            faults: E2eFaults {
                crc: 0,
                counter_repeated: 0,
                counter_skipped: 0,
                length: 0,
                unknown_id: 0,
                timeout: 0,
            },
            road_taken: 0,
        }
    }
}

impl Default for CycleRecord {
    fn default() -> Self {
        Self::zeroed()
    }
}

/// Direction of a logged [`CanFrame`] relative to the process that logged it.
pub mod can_dir {
    /// Received by the logging process.
    pub const RX: u8 = 0;
    /// Sent by the logging process.
    pub const TX: u8 = 1;
}

/// [`CanFrame::flags`] bits.
pub mod can_flags {
    /// 29-bit extended identifier.
    pub const EXTENDED: u8 = 1 << 0;
    /// Remote transmission request.
    pub const RTR: u8 = 1 << 1;
    /// Error frame.
    pub const ERROR: u8 = 1 << 2;
    /// Frame was rejected by the E2E check (set by receivers that log).
    pub const E2E_REJECTED: u8 = 1 << 3;
}

/// One classic CAN frame (≤ 8 data bytes) as carried on the simulated bus
/// and logged by the recorder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ZeroCopySend)]
#[type_name("grip::CanFrame::v1")]
#[repr(C)]
pub struct CanFrame {
    /// CLOCK_MONOTONIC time of sending or reception, ns.
    pub stamp_ns: u64,
    /// Identifier (11 bit, or 29 bit with `can_flags::EXTENDED`).
    pub id: u32,
    /// Data length code 0..=8.
    pub dlc: u8,
    /// [`can_dir`] value.
    pub direction: u8,
    /// Bus number (0 = inverter bus).
    pub bus: u8,
    /// [`can_flags`] bits.
    pub flags: u8,
    /// Payload; bytes at and beyond `dlc` are zero.
    pub data: [u8; 8],
}

impl CanFrame {
    /// Versioned type name.
    pub const TYPE_NAME: &'static str = "grip::CanFrame::v1";

    /// A standard-id data frame with the given payload (`data.len()` ≤ 8;
    /// longer input is truncated to 8 bytes).
    pub fn new(id: u32, data: &[u8]) -> Self {
        let n = data.len().min(8);
        let mut d = [0u8; 8];
        d[..n].copy_from_slice(&data[..n]);
        Self {
            stamp_ns: 0,
            id,
            dlc: n as u8,
            direction: can_dir::RX,
            bus: 0,
            flags: 0,
            data: d,
        }
    }

    /// The valid payload bytes (clamped if `dlc` is corrupt).
    pub fn payload(&self) -> &[u8] {
        &self.data[..usize::from(self.dlc).min(8)]
    }
}

/// One frame of the vehicle's CAN bus as the recorder reads it off the bus
/// (MCAP channel [`topics::BUS`]), every participant's traffic, grip's
/// own and the car's: a CAN logger's record. Not an iceoryx2 payload (the
/// recorder reads the bus itself); its own schema, so that a reader of the
/// CAN log ([`CanFrame`], tcs-loop's copies) never mixes the two.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(C)]
pub struct BusFrame {
    /// Receive time, CLOCK_MONOTONIC ns: the kernel's on SocketCAN
    /// (`SO_TIMESTAMPNS`, moved onto CLOCK_MONOTONIC), else the sender's
    /// at publish (the simulated bus, which has no delay).
    pub stamp_ns: u64,
    /// Identifier (11 bit, or 29 bit with `can_flags::EXTENDED`; for an
    /// error frame the error class bits, `can_flags::ERROR`).
    pub id: u32,
    /// Data length code 0..=8.
    pub dlc: u8,
    /// Bus number (`can.toml`'s `bus_id`).
    pub bus: u8,
    /// [`can_flags`] bits: `EXTENDED`, `RTR`, `ERROR`.
    pub flags: u8,
    /// Explicit padding, zero.
    pub _reserved: u8,
    /// Payload; bytes at and beyond `dlc` are zero.
    pub data: [u8; 8],
}

impl BusFrame {
    /// Versioned type name (the MCAP schema name).
    pub const TYPE_NAME: &'static str = "grip::BusFrame::v1";

    /// The bus record of a frame a transport received (its stamp, id,
    /// flags, DLC and payload; the direction is dropped: the recorder
    /// never sends).
    pub fn from_can(f: &CanFrame) -> Self {
        Self {
            stamp_ns: f.stamp_ns,
            id: f.id,
            dlc: f.dlc.min(8),
            bus: f.bus,
            flags: f.flags & (can_flags::EXTENDED | can_flags::RTR | can_flags::ERROR),
            _reserved: 0,
            data: f.data,
        }
    }

    /// The valid payload bytes (clamped if `dlc` is corrupt; none for a
    /// remote frame, whose DLC is the length it asks for).
    pub fn payload(&self) -> &[u8] {
        if self.flags & can_flags::RTR != 0 {
            return &[];
        }
        &self.data[..usize::from(self.dlc).min(8)]
    }

    /// True for a 29-bit identifier.
    pub fn is_extended(&self) -> bool {
        self.flags & can_flags::EXTENDED != 0
    }
}

/// What the plant simulator knows to be true (never seen by the controller).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("grip::GroundTruth::v2")]
#[repr(C)]
pub struct GroundTruth {
    /// Plant step sequence number.
    pub seq: u64,
    /// CLOCK_MONOTONIC time, ns.
    pub stamp_ns: u64,
    /// Index of the true road under the driven wheel in the road
    /// catalogue, or [`NO_CLASS`].
    pub road_index: u32,
    /// Index of the true road at the microphone (`vehicle.mic_lead_m` ahead
    /// of the driven wheel, at `x + mic_lead_m`), or [`NO_CLASS`]: the road
    /// the synthetic audio is rendered for.
    pub mic_road_index: u32,
    /// Name of the true road under the driven wheel, zero padded.
    pub road_name: [u8; NAME_LEN],
    /// Name of the true road at the microphone, zero padded.
    pub mic_road_name: [u8; NAME_LEN],
    /// True vehicle speed V, m/s.
    pub v: f64,
    /// True wheel speed ω, rad/s.
    pub omega: f64,
    /// True slip λ.
    pub lambda: f64,
    /// True torque T at one driven wheel (after the motor's lag), N m.
    pub torque: f64,
    /// Distance travelled x, m.
    pub x: f64,
}

impl GroundTruth {
    /// Versioned type name.
    pub const TYPE_NAME: &'static str = "grip::GroundTruth::v2";

    /// All-zero truth (`road_index = mic_road_index = NO_CLASS`).
    pub const fn zeroed() -> Self {
        Self {
            seq: 0,
            stamp_ns: 0,
            road_index: NO_CLASS,
            mic_road_index: NO_CLASS,
            road_name: [0; NAME_LEN],
            mic_road_name: [0; NAME_LEN],
            v: 0.0,
            omega: 0.0,
            lambda: 0.0,
            torque: 0.0,
            x: 0.0,
        }
    }

    /// The true road's name (under the driven wheel), if valid UTF-8.
    pub fn road_name(&self) -> Option<&str> {
        name_from_bytes(&self.road_name)
    }

    /// The true road's name at the microphone, if valid UTF-8.
    pub fn mic_road_name(&self) -> Option<&str> {
        name_from_bytes(&self.mic_road_name)
    }
}

impl Default for GroundTruth {
    fn default() -> Self {
        Self::zeroed()
    }
}

// ---- layout pins: sizes equal the sum of the fields (no implicit padding) ----
const _: () = {
    use core::mem::{align_of, size_of};
    assert!(size_of::<AudioBlock>() == 8 + 8 + 4 + 4 + 2 + 2 + 4 + 2 * AUDIO_MAX_SAMPLES);
    assert!(align_of::<AudioBlock>() == 8);
    assert!(size_of::<RoadEstimate>() == 8 * 4 + 4 + 4 + NAME_LEN + 4 * MAX_ROAD_CLASSES + 8 * 6);
    assert!(align_of::<RoadEstimate>() == 8);
    assert!(size_of::<E2eFaults>() == 6 * 4);
    assert!(align_of::<E2eFaults>() == 4);
    assert!(size_of::<CycleRecord>() == 8 * 5 + 8 * 10 + 4 + 4 + 4 + size_of::<E2eFaults>() + 4);
    assert!(align_of::<CycleRecord>() == 8);
    assert!(size_of::<CanFrame>() == 24);
    assert!(align_of::<CanFrame>() == 8);
    assert!(size_of::<GroundTruth>() == 8 + 8 + 4 + 4 + 2 * NAME_LEN + 8 * 5);
    assert!(align_of::<GroundTruth>() == 8);
};

#[cfg(test)]
mod tests;
