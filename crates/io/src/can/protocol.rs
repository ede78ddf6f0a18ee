//! The inverter protocol of `config/inverter.dbc`: typed messages ↔ 8-byte
//! frames, the E2E protection (CRC-8 + alive counter) and the receivers that
//! check it.
//!
//! The tables here ([`MESSAGES`]) mirror the DBC exactly; the test
//! `tests/dbc_agreement.rs` parses the DBC with `can-dbc` and proves that
//! ids, DLCs, every signal's start bit, length, byte order, sign, factor,
//! offset and range, and the cycle time, timeout and data-id attributes agree,
//! and that frames encoded here decode to the same physical values with a
//! generic DBC-driven decoder.
//!
//! # E2E scheme (AUTOSAR E2E Profile 1/2 style)
//! - byte 0: CRC-8 SAE J1850 (polynomial 0x1D, initial value 0xFF, final
//!   XOR 0xFF, no reflection; check value of "123456789" = 0x4B), computed over
//!   the message's 16-bit *data id* (low byte, then high byte; never sent)
//!   followed by data bytes 1..=7. The data id makes a frame that lands on the
//!   wrong id (masquerading) fail its CRC.
//! - bits 8..=11: alive counter, +1 modulo 16 with every transmission
//!   (Profile 2's range; Profile 1 skips 15).
//! - A receiver rejects and counts: wrong DLC, bad CRC, a repeated counter,
//!   a counter that jumped by more than `max_delta` (default 1: any lost frame
//!   is reported; the receiver re-synchronises on the jumped frame so only that
//!   one frame is dropped), and ids not in the protocol. The first frame
//!   after start or after a timeout is accepted with any counter (resync).
//! - Timeout: no accepted frame for `timeout_ms` (DBC attribute
//!   `GripTimeoutMs`) is one timeout episode, counted once on entry.
//!
//! Everything here is allocation-free.

use grip_msgs::{CanFrame, E2eFaults};

/// One signal of a message, as in the DBC (`SG_ name : start|len@1± (factor,offset) [min|max] "unit"`).
/// All grip signals are Intel (little-endian, `@1`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignalSpec {
    /// Signal name in the DBC.
    pub name: &'static str,
    /// Start bit (Intel: least significant bit's position).
    pub start: u8,
    /// Length in bits.
    pub len: u8,
    /// Two's-complement signed (`-`) or unsigned (`+`).
    pub signed: bool,
    /// Physical = raw × factor + offset.
    pub factor: f64,
    /// See `factor`.
    pub offset: f64,
    /// Physical minimum as written in the DBC (`[0|0]`: no range given).
    /// grip sends nothing below it ([`to_raw`](Self::to_raw)); a received
    /// value below it is decoded as the frame carries it.
    pub min: f64,
    /// Physical maximum as written in the DBC (see `min`).
    pub max: f64,
    /// Unit string.
    pub unit: &'static str,
    /// Motorola (big-endian, DBC `@0`) byte order; `start` is then the most
    /// significant bit in the DBC's numbering (bit 7 of byte 0 is 7, bit 0
    /// of byte 1 is 8). grip's own DBC is all Intel.
    pub motorola: bool,
    /// For a flag: the one raw value that means set (for grip's validity
    /// flags: valid), e.g. `Some(0)` for a bus whose bit says *invalid*
    /// when it is 1 (`can.toml` `[dbc_valid]`, or the DBC's `VAL_` table
    /// naming a state `"Valid"`). `None`: any non-zero raw value is set,
    /// grip's own convention and the built-in protocol's
    /// ([`get_flag`](Self::get_flag), [`put_flag`](Self::put_flag)).
    pub set_raw: Option<i64>,
}

impl SignalSpec {
    const fn new(
        name: &'static str,
        start: u8,
        len: u8,
        signed: bool,
        factor: f64,
        min: f64,
        max: f64,
        unit: &'static str,
    ) -> Self {
        Self {
            name,
            start,
            len,
            signed,
            factor,
            offset: 0.0,
            min,
            max,
            unit,
            motorola: false,
            set_raw: None,
        }
    }
    const fn flag(name: &'static str, start: u8) -> Self {
        Self::new(name, start, 1, false, 1.0, 0.0, 1.0, "")
    }
    /// True when the DBC gives the signal a range `[min|max]`. By DBC
    /// convention `[0|0]` means "no range given": then the bit field alone
    /// limits the signal.
    pub fn has_range(&self) -> bool {
        !(self.min == 0.0 && self.max == 0.0)
    }
    /// Smallest raw value the bit field holds.
    pub fn field_raw_min(&self) -> i64 {
        if self.signed {
            -(1i64 << (self.len - 1))
        } else {
            0
        }
    }
    /// Largest raw value the bit field holds.
    pub fn field_raw_max(&self) -> i64 {
        if self.signed {
            (1i64 << (self.len - 1)) - 1
        } else {
            (1i64 << self.len) - 1
        }
    }
    /// The raw values inside the DBC's range `[min|max]`, if it gives one:
    /// the first and last whole raw value whose physical value lies in it
    /// (an end that is a whole raw value up to floating-point rounding
    /// counts as one). `None` without a range or for one that is not two
    /// finite numbers.
    pub fn range_raw(&self) -> Option<(i64, i64)> {
        if !(self.has_range() && self.min.is_finite() && self.max.is_finite()) {
            return None;
        }
        let a = (self.min - self.offset) / self.factor;
        let b = (self.max - self.offset) / self.factor;
        if !(a.is_finite() && b.is_finite()) {
            return None;
        }
        let (lo, hi) = (a.min(b), a.max(b));
        let snap = |x: f64, inward: fn(f64) -> f64| {
            let r = x.round();
            if (x - r).abs() <= 1e-9 * x.abs().max(1.0) {
                r as i64
            } else {
                inward(x) as i64
            }
        };
        Some((snap(lo, f64::ceil), snap(hi, f64::floor)))
    }
    /// Smallest raw value grip sends: the bit field's, raised to the DBC's
    /// range where it gives one (the field alone where the range and the
    /// field do not overlap, which the DBC loader refuses).
    pub fn raw_min(&self) -> i64 {
        self.raw_limits().0
    }
    /// Largest raw value grip sends: the bit field's, lowered to the DBC's
    /// range where it gives one (see [`raw_min`](Self::raw_min)).
    pub fn raw_max(&self) -> i64 {
        self.raw_limits().1
    }
    fn raw_limits(&self) -> (i64, i64) {
        let (f_lo, f_hi) = (self.field_raw_min(), self.field_raw_max());
        match self.range_raw() {
            Some((lo, hi)) if lo.max(f_lo) <= hi.min(f_hi) => (lo.max(f_lo), hi.min(f_hi)),
            _ => (f_lo, f_hi),
        }
    }
    /// The physical values grip sends, lowest first: [`raw_min`](Self::raw_min)
    /// and [`raw_max`](Self::raw_max) scaled (swapped for a negative factor).
    pub fn phys_limits(&self) -> (f64, f64) {
        let (a, b) = (self.to_phys(self.raw_min()), self.to_phys(self.raw_max()));
        (a.min(b), a.max(b))
    }
    /// Physical value → raw, rounded to nearest and saturated at the DBC's
    /// range (when it gives one, [`has_range`](Self::has_range)) and at the
    /// bit field: between [`raw_min`](Self::raw_min) and
    /// [`raw_max`](Self::raw_max). A non-finite input is sent as the
    /// physical value 0 (for a torque: no torque), i.e. the raw value of 0
    /// N m (`-offset / factor`, rounded), saturated like any other value.
    pub fn to_raw(&self, phys: f64) -> i64 {
        let phys = if phys.is_finite() { phys } else { 0.0 };
        let r = ((phys - self.offset) / self.factor).round();
        let (lo, hi) = self.raw_limits();
        if r.is_nan() {
            return 0i64.clamp(lo, hi);
        }
        // `as` saturates at i64's ends; the clamp then at the signal's
        (r as i64).clamp(lo, hi)
    }
    /// Raw → physical.
    pub fn to_phys(&self, raw: i64) -> f64 {
        raw as f64 * self.factor + self.offset
    }
    /// The field's shift and mask in a 64-bit word of the payload: for Intel
    /// the word is `u64::from_le_bytes`, for Motorola `u64::from_be_bytes`
    /// (in which a Motorola field is a contiguous run of bits).
    fn shift_mask(&self) -> (u32, u64) {
        let mask = if self.len >= 64 {
            u64::MAX
        } else {
            (1u64 << self.len) - 1
        };
        if self.motorola {
            // the MSB's position counted from the first byte's top bit
            let msb = u32::from(self.start / 8) * 8 + 7 - u32::from(self.start % 8);
            (64 - (msb + u32::from(self.len)), mask)
        } else {
            (u32::from(self.start), mask)
        }
    }
    fn word(&self, data: &[u8; 8]) -> u64 {
        if self.motorola {
            u64::from_be_bytes(*data)
        } else {
            u64::from_le_bytes(*data)
        }
    }
    fn store(&self, data: &mut [u8; 8], word: u64) {
        *data = if self.motorola {
            word.to_be_bytes()
        } else {
            word.to_le_bytes()
        };
    }
    /// Writes a raw value into `data` (the DBC's bit numbering and byte
    /// order).
    pub fn put_raw(&self, data: &mut [u8; 8], raw: i64) {
        let (shift, mask) = self.shift_mask();
        let bits = (raw as u64) & mask;
        let mut word = self.word(data);
        word &= !(mask << shift);
        word |= bits << shift;
        self.store(data, word);
    }
    /// Reads the raw value (sign-extended if signed).
    pub fn get_raw(&self, data: &[u8; 8]) -> i64 {
        let (shift, mask) = self.shift_mask();
        let v = (self.word(data) >> shift) & mask;
        if self.signed && self.len < 64 && (v >> (self.len - 1)) & 1 == 1 {
            (v | !mask) as i64
        } else {
            v as i64
        }
    }
    /// The payload bits the field occupies, as a mask over
    /// `u64::from_le_bytes` of the payload (bit `8 k + b` = bit `b` of byte
    /// `k`), whatever the byte order: for overlap checks.
    pub fn bits(&self) -> u64 {
        let mut d = [0u8; 8];
        self.put_raw(&mut d, -1);
        u64::from_le_bytes(d)
    }
    /// Reads a flag: true when the raw value is [`set_raw`](Self::set_raw),
    /// or, without one, when it is non-zero. Allocation-free.
    pub fn get_flag(&self, data: &[u8; 8]) -> bool {
        let raw = self.get_raw(data);
        match self.set_raw {
            None => raw != 0,
            Some(v) => raw == v,
        }
    }
    /// The raw value a flag is sent with when cleared (for a validity flag:
    /// invalid): 0, or, where 0 is the set value ([`set_raw`](Self::set_raw)
    /// `Some(0)`, an inverted bit), 1 (-1 in a signed 1-bit field, which
    /// holds only -1 and 0).
    pub fn clear_raw(&self) -> i64 {
        match self.set_raw {
            Some(0) if self.field_raw_max() >= 1 => 1,
            Some(0) => -1,
            _ => 0,
        }
    }
    /// Writes a flag: [`set_raw`](Self::set_raw) (without one, 1) when
    /// `on`, else [`clear_raw`](Self::clear_raw), so that
    /// [`get_flag`](Self::get_flag) reads back `on`.
    pub fn put_flag(&self, data: &mut [u8; 8], on: bool) {
        let raw = if on {
            self.set_raw.unwrap_or(1)
        } else {
            self.clear_raw()
        };
        self.put_raw(data, raw);
    }
    /// Writes a physical value (see [`to_raw`](Self::to_raw)).
    pub fn put(&self, data: &mut [u8; 8], phys: f64) {
        self.put_raw(data, self.to_raw(phys));
    }
    /// Reads a physical value.
    pub fn get(&self, data: &[u8; 8]) -> f64 {
        self.to_phys(self.get_raw(data))
    }
}

/// One message of the protocol.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MessageSpec {
    /// Which of grip's messages this is.
    pub kind: MsgKind,
    /// Message name in the DBC.
    pub name: &'static str,
    /// 11-bit identifier.
    pub id: u32,
    /// Data length code.
    pub dlc: u8,
    /// E2E data id (DBC attribute `GripE2eDataId`).
    pub data_id: u16,
    /// Transmission period, ms (`GenMsgCycleTime`).
    pub cycle_ms: u32,
    /// Receive timeout, ms (`GripTimeoutMs`).
    pub timeout_ms: u32,
    /// Transmitting node.
    pub sender: &'static str,
    /// Receiving node: the receiver the DBC names for every signal of the
    /// message. The one place that says which ids a grip service consumes
    /// ([`Role::receives`]: its [`ProtocolRx`] and its bus's receive filter).
    pub receiver: Role,
    /// All signals, CRC and Counter first (a slice through `Deref`).
    pub signals: SignalList,
}

/// Most signals a message has (MotorStatus: CRC, Counter and seven).
pub const MAX_SIGNALS: usize = 9;

/// A message's signals, held inline (no allocation, nothing leaked when a
/// protocol is read from a DBC); a `&[SignalSpec]` through `Deref`.
#[derive(Clone, Copy, PartialEq)]
pub struct SignalList {
    buf: [SignalSpec; MAX_SIGNALS],
    len: usize,
}

const UNUSED: SignalSpec = SignalSpec::flag("", 0);

impl SignalList {
    /// The list of `signals` (at most [`MAX_SIGNALS`]; a longer slice is a
    /// programming error, caught at compile time for the built-in tables).
    pub const fn new(signals: &[SignalSpec]) -> Self {
        assert!(signals.len() <= MAX_SIGNALS, "too many signals");
        let mut buf = [UNUSED; MAX_SIGNALS];
        let mut i = 0;
        while i < signals.len() {
            buf[i] = signals[i];
            i += 1;
        }
        Self {
            buf,
            len: signals.len(),
        }
    }
}

impl core::ops::Deref for SignalList {
    type Target = [SignalSpec];
    fn deref(&self) -> &[SignalSpec] {
        &self.buf[..self.len]
    }
}

impl core::fmt::Debug for SignalList {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl MessageSpec {
    /// The byte that carries the CRC (signal 0, a whole byte: the loader
    /// checks it).
    pub fn crc_byte(&self) -> usize {
        usize::from(self.signals[0].start / 8)
    }
    /// The alive counter in a payload (signal 1).
    pub fn counter(&self, data: &[u8; 8]) -> u8 {
        (self.signals[1].get_raw(data) & 0x0F) as u8
    }
}

const CRC_SIG: SignalSpec = SignalSpec::new("CRC", 0, 8, false, 1.0, 0.0, 255.0, "");
const COUNTER_SIG: SignalSpec = SignalSpec::new("Counter", 8, 4, false, 1.0, 0.0, 15.0, "");

/// `TorqueCommand` (TCS → INV).
pub const TORQUE_COMMAND: MessageSpec = MessageSpec {
    kind: MsgKind::TorqueCommand,
    name: "TorqueCommand",
    id: 0x100,
    dlc: 8,
    data_id: 0x1A01,
    cycle_ms: 1,
    timeout_ms: 20,
    sender: "TCS",
    receiver: Role::Inverter,
    signals: SignalList::new(&[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("Enable", 12),
        SignalSpec::new("TorqueRequest", 16, 16, true, 0.1, -3276.8, 3276.7, "Nm"),
    ]),
};

/// `MotorStatus` (INV → TCS).
pub const MOTOR_STATUS: MessageSpec = MessageSpec {
    kind: MsgKind::MotorStatus,
    name: "MotorStatus",
    id: 0x110,
    dlc: 8,
    data_id: 0x1A02,
    cycle_ms: 1,
    timeout_ms: 10,
    sender: "INV",
    receiver: Role::Tcs,
    signals: SignalList::new(&[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("Ready", 12),
        SignalSpec::flag("Fault", 13),
        SignalSpec::flag("Derating", 14),
        SignalSpec::flag("CmdTimeout", 15),
        SignalSpec::new("TorqueActual", 16, 16, true, 0.1, -3276.8, 3276.7, "Nm"),
        SignalSpec::new("MotorSpeed", 32, 16, true, 0.01, -327.68, 327.67, "rad/s"),
        SignalSpec::new("FaultCode", 48, 8, false, 1.0, 0.0, 255.0, ""),
    ]),
};

/// `WheelSpeeds` (ABS → TCS).
pub const WHEEL_SPEEDS: MessageSpec = MessageSpec {
    kind: MsgKind::WheelSpeeds,
    name: "WheelSpeeds",
    id: 0x120,
    dlc: 8,
    data_id: 0x1A03,
    cycle_ms: 1,
    timeout_ms: 10,
    sender: "ABS",
    receiver: Role::Tcs,
    signals: SignalList::new(&[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("DrivenValid", 12),
        SignalSpec::flag("RefValid", 13),
        SignalSpec::new("OmegaDriven", 16, 16, true, 0.01, -327.68, 327.67, "rad/s"),
        SignalSpec::new("OmegaRef", 32, 16, true, 0.01, -327.68, 327.67, "rad/s"),
    ]),
};

/// `VehicleSpeed` (VCU → TCS).
pub const VEHICLE_SPEED: MessageSpec = MessageSpec {
    kind: MsgKind::VehicleSpeed,
    name: "VehicleSpeed",
    id: 0x130,
    dlc: 8,
    data_id: 0x1A04,
    cycle_ms: 10,
    timeout_ms: 50,
    sender: "VCU",
    receiver: Role::Tcs,
    signals: SignalList::new(&[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("Valid", 12),
        SignalSpec::new("Speed", 16, 16, true, 0.01, -327.68, 327.67, "m/s"),
        SignalSpec::new("LongAccel", 32, 16, true, 0.001, -32.768, 32.767, "m/s2"),
    ]),
};

/// `DriverDemand` (VCU → TCS).
pub const DRIVER_DEMAND: MessageSpec = MessageSpec {
    kind: MsgKind::DriverDemand,
    name: "DriverDemand",
    id: 0x140,
    dlc: 8,
    data_id: 0x1A05,
    cycle_ms: 10,
    timeout_ms: 50,
    sender: "VCU",
    receiver: Role::Tcs,
    signals: SignalList::new(&[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("BrakePressed", 12),
        SignalSpec::flag("TcsEnable", 13),
        SignalSpec::new("TorqueDemand", 16, 16, true, 0.1, -3276.8, 3276.7, "Nm"),
        SignalSpec::new("PedalPosition", 32, 8, false, 0.5, 0.0, 127.5, "%"),
    ]),
};

/// Every message of the built-in protocol (the one `config/inverter.dbc`
/// describes), in [`MsgKind`] order.
pub const MESSAGES: [&MessageSpec; 5] = [
    &TORQUE_COMMAND,
    &MOTOR_STATUS,
    &WHEEL_SPEEDS,
    &VEHICLE_SPEED,
    &DRIVER_DEMAND,
];

/// Which of grip's five messages a [`MessageSpec`] is: what the code means
/// by it, whatever id and layout a DBC gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MsgKind {
    /// [`TorqueCommand`].
    TorqueCommand = 0,
    /// [`MotorStatus`].
    MotorStatus = 1,
    /// [`WheelSpeeds`].
    WheelSpeeds = 2,
    /// [`VehicleSpeed`].
    VehicleSpeed = 3,
    /// [`DriverDemand`].
    DriverDemand = 4,
}

impl MsgKind {
    /// All five, in the protocol's order.
    pub const ALL: [Self; 5] = [
        Self::TorqueCommand,
        Self::MotorStatus,
        Self::WheelSpeeds,
        Self::VehicleSpeed,
        Self::DriverDemand,
    ];
    /// The built-in specification (grip's names, signal order and units).
    pub fn builtin(self) -> &'static MessageSpec {
        MESSAGES[self as usize]
    }
}

/// A bus protocol: grip's five messages with the ids, layouts, scalings and
/// timing of one DBC. [`Protocol::builtin`] is `config/inverter.dbc`'s;
/// [`Protocol::from_dbc`](crate::can::protocol::Protocol::from_dbc) reads
/// another (a car's own bus). Each message's signals are in the built-in
/// order (CRC, Counter, then the payload), whatever the DBC's order, so
/// the typed messages address them by position.
#[derive(Debug, Clone, PartialEq)]
pub struct Protocol {
    messages: [MessageSpec; 5],
    bus: BusTiming,
    wheel_radii: Option<WheelRadii>,
}

static BUILTIN: Protocol = Protocol {
    messages: [
        TORQUE_COMMAND,
        MOTOR_STATUS,
        WHEEL_SPEEDS,
        VEHICLE_SPEED,
        DRIVER_DEMAND,
    ],
    bus: BusTiming::ASSUMED,
    wheel_radii: None,
};

/// The wheels' rolling radii, m, from the vehicle file (`r` and `r_ref`,
/// which defaults to `r`): what converts a wheel's circumferential speed
/// on the bus (`OmegaDriven` or `OmegaRef` in km/h or m/s) to the angular
/// speed grip computes in, ω = v ÷ r, folded into the signal's factor when
/// the DBC is read ([`Protocol::from_dbc_with`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelRadii {
    /// The driven wheel's, for `WheelSpeeds.OmegaDriven` (`r`).
    pub driven_m: f64,
    /// The non-driven reference wheel's, for `WheelSpeeds.OmegaRef`
    /// (`r_ref`, else `r`).
    pub reference_m: f64,
}

impl WheelRadii {
    /// The one rule for a vehicle's radii on the bus: the driven wheel's
    /// is `r`, the reference wheel's is `r_ref`, else `r`
    /// ([`VehicleParams::ref_radius`](grip_physics::VehicleParams::ref_radius)),
    /// as tcs-loop computes V = r_ref · OmegaRef and plant-sim sends
    /// OmegaRef = V ÷ r_ref. Used by tcs-loop, plant-sim, the recorder and
    /// a drive log's reader alike.
    pub fn of(vehicle: &grip_physics::VehicleParams) -> Self {
        Self {
            driven_m: vehicle.r,
            reference_m: vehicle.ref_radius(),
        }
    }
}

/// The bus a protocol runs on: the bit rate its bus load is judged at
/// (the interface's where the services read one, else the DBC's
/// `BA_ "Baudrate"`, else [`DEFAULT_BITRATE`]; [`super::bitrate`]) and
/// whether the DBC declares a CAN FD bus (`BA_ "BusType" "CAN FD"`; grip's
/// messages are classic frames on it, at the nominal rate).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BusTiming {
    /// Bit rate, bit/s (the nominal, arbitration rate on a CAN FD bus):
    /// the one [`Protocol::bus_load`] divides by.
    pub bitrate: u32,
    /// The DBC's bit rate (`Baudrate`, or its `BA_DEF_DEF_` default), if
    /// it gives one; `None`: [`DEFAULT_BITRATE`] assumed unless the
    /// interface reports its own.
    pub dbc_bitrate: Option<u32>,
    /// `Some(name)`: `bitrate` is the one interface `name` reports (read
    /// from the kernel at start-up, [`Protocol::with_bitrate`]), which wins
    /// over the DBC's.
    pub interface: Option<String>,
    /// The DBC's `BusType` is `"CAN FD"`.
    pub can_fd_bus: bool,
}

/// The bit rate assumed when a DBC gives none: grip's bus, 1 Mbit/s.
pub const DEFAULT_BITRATE: u32 = 1_000_000;

/// The largest share of the bus grip's five messages may take, worst case
/// ([`Protocol::bus_load`]); a DBC whose periods and bit rate give more is
/// refused. The rest is the car's other traffic's and the error recovery's
/// (an error frame and the retransmission of a whole frame); a classic CAN
/// bus loaded beyond about half is where lower-priority messages' worst-case
/// delays grow quickly (`crates/io/README.md`, "Bus load").
pub const MAX_BUS_LOAD: f64 = 0.5;

impl BusTiming {
    /// No bit rate in the DBC: [`DEFAULT_BITRATE`], classic CAN.
    pub const ASSUMED: Self = Self {
        bitrate: DEFAULT_BITRATE,
        dbc_bitrate: None,
        interface: None,
        can_fd_bus: false,
    };
}

/// Bits on the wire of one classic CAN data frame of `dlc` data bytes, at
/// worst: every bit from the start of frame to the end of the CRC stuffed
/// as often as it can be (one stuff bit per four after the first), plus
/// CRC delimiter, ACK, end of frame and the 3-bit interframe space (Davis,
/// Burns, Bril and Lukkien, "Controller Area Network (CAN) schedulability
/// analysis: refuted, revisited and revised", Real-Time Systems 35(3),
/// 2007, eq. 1). An 8-byte frame with an 11-bit id: 135 bits; with a
/// 29-bit id: 160.
pub const fn classic_frame_bits_worst(dlc: u8, extended: bool) -> u32 {
    let g = if extended { 54 } else { 34 };
    let n = 8 * (if dlc > 8 { 8 } else { dlc as u32 });
    g + n + 13 + (g + n - 1) / 4
}

static ACTIVE: std::sync::OnceLock<Protocol> = std::sync::OnceLock::new();

/// The protocol this process speaks: the one [`install`]ed at start-up,
/// else the built-in one. Allocation-free (one atomic load).
pub fn active() -> &'static Protocol {
    ACTIVE.get().unwrap_or(&BUILTIN)
}

/// The protocol [`install`]ed in this process, if any.
pub fn installed() -> Option<&'static Protocol> {
    ACTIVE.get()
}

/// Why [`install`] refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("a different CAN protocol is already installed in this process")]
pub struct AlreadyInstalled;

/// Makes `p` the process's protocol ([`active`]): a service calls it once at
/// start-up, before it opens its bus or builds a receiver (what was built
/// before keeps the protocol it was built with). Installing the same
/// protocol again is a no-op; a different one is refused.
pub fn install(p: Protocol) -> Result<&'static Protocol, AlreadyInstalled> {
    let got = ACTIVE.get_or_init(|| p.clone());
    if *got == p {
        Ok(got)
    } else {
        Err(AlreadyInstalled)
    }
}

impl Protocol {
    /// The built-in protocol (`config/inverter.dbc`).
    pub fn builtin() -> &'static Self {
        &BUILTIN
    }
    /// Built from five specifications in [`MsgKind`] order (the DBC loader's
    /// constructor; checked there).
    pub(crate) fn from_specs(
        messages: [MessageSpec; 5],
        bus: BusTiming,
        wheel_radii: Option<WheelRadii>,
    ) -> Self {
        Self {
            messages,
            bus,
            wheel_radii,
        }
    }
    /// The radii a wheel speed in km/h or m/s on the bus was converted with
    /// (folded into its factor); `None` when the wheel speeds are angular
    /// (the built-in protocol's rad/s, or rpm), whatever radii were given.
    pub fn wheel_radii(&self) -> Option<WheelRadii> {
        self.wheel_radii
    }
    /// The bus as the DBC declares it (the built-in protocol's: 1 Mbit/s,
    /// classic CAN).
    pub fn bus(&self) -> &BusTiming {
        &self.bus
    }
    /// The share of the bus's bit rate grip's five messages take at their
    /// periods (`GenMsgCycleTime`), each frame at its worst-case length
    /// ([`classic_frame_bits_worst`]): 0.432 for the built-in protocol at 1
    /// Mbit/s (three 8-byte frames every 1 ms, two every 10 ms).
    pub fn bus_load(&self) -> f64 {
        let bits_per_s: f64 = self
            .messages
            .iter()
            .map(|m| {
                f64::from(classic_frame_bits_worst(m.dlc, false)) * 1e3 / f64::from(m.cycle_ms)
            })
            .sum();
        bits_per_s / f64::from(self.bus.bitrate)
    }
    /// This protocol on a bus that runs at `choice`'s bit rate (the
    /// interface's, read at start-up; [`super::bitrate::choose_bitrate`]):
    /// [`Self::bus_load`] and [`Self::bus_load_refusal`] judge that rate.
    pub fn with_bitrate(mut self, choice: &super::bitrate::BitrateChoice) -> Self {
        self.bus.bitrate = choice.bitrate;
        self.bus.interface = match &choice.source {
            super::bitrate::BitrateSource::Interface(name) => Some(name.clone()),
            _ => None,
        };
        self
    }
    /// One line for a log: the bit rate, where it comes from, and grip's
    /// worst-case share of it, e.g. `1000 kbit/s (assumed: no Baudrate in
    /// the DBC), grip's messages 43.2 % of it at worst`, or `1000 kbit/s
    /// (1000000 bit/s read from can0; the DBC's Baudrate agrees), ...`.
    pub fn describe_bus(&self) -> String {
        let from = match (&self.bus.interface, self.bus.dbc_bitrate) {
            (Some(i), dbc) => format!(
                "{} bit/s read from {i}; {}",
                self.bus.bitrate,
                match dbc {
                    None => "the DBC gives no Baudrate".to_owned(),
                    Some(d) if d == self.bus.bitrate => "the DBC's Baudrate agrees".to_owned(),
                    Some(d) => format!("the DBC's Baudrate says {d} bit/s"),
                }
            ),
            (None, Some(_)) => "the DBC's Baudrate".to_owned(),
            (None, None) => "assumed: no Baudrate in the DBC".to_owned(),
        };
        format!(
            "{} kbit/s ({from}){}, grip's messages {:.1} % of it at worst (limit {:.0} %)",
            f64::from(self.bus.bitrate) / 1e3,
            if self.bus.can_fd_bus {
                ", a CAN FD bus carrying grip's messages as classic frames"
            } else {
                ""
            },
            100.0 * self.bus_load(),
            100.0 * MAX_BUS_LOAD
        )
    }
    /// Why grip refuses this bus, if it does: its five messages would take
    /// more than [`MAX_BUS_LOAD`] of the bit rate at worst
    /// ([`Self::bus_load`]). `(what, reason)`: what is to blame (`interface`
    /// when the rate is the interface's, whose name the reason gives with
    /// its bit rate; `attribute Baudrate` when it is the DBC's; `bus load`
    /// when it is assumed) and the load, the rate and the periods.
    pub fn bus_load_refusal(&self) -> Option<(String, String)> {
        let load = self.bus_load();
        if load <= MAX_BUS_LOAD {
            return None;
        }
        let periods: Vec<String> = self
            .messages
            .iter()
            .map(|m| format!("{} every {} ms", m.name, m.cycle_ms))
            .collect();
        let (what, rate, remedy) = match (&self.bus.interface, self.bus.dbc_bitrate) {
            (Some(i), _) => (
                "interface",
                format!(
                    "{i}'s {} bit/s (the interface's bit rate, read from the kernel)",
                    self.bus.bitrate
                ),
                format!(
                    "run {i} at 1 Mbit/s (ip link set {i} down; ip link set {i} type can bitrate 1000000; ip link set {i} up)"
                ),
            ),
            (None, Some(d)) => (
                "attribute Baudrate",
                format!("the DBC's {} kbit/s", f64::from(d) / 1e3),
                "run the bus at 1 Mbit/s".to_owned(),
            ),
            (None, None) => (
                "bus load",
                format!(
                    "{} kbit/s (no Baudrate in the DBC: grip's bus assumed)",
                    f64::from(DEFAULT_BITRATE) / 1e3
                ),
                "run the bus at 1 Mbit/s".to_owned(),
            ),
        };
        Some((
            what.to_owned(),
            format!(
                "grip's five messages would take {:.1} % of {rate} at worst ({} bits per 8-byte frame with worst-case bit stuffing; {}); grip allows at most {:.0} %: {remedy} or give the messages longer periods (GenMsgCycleTime)",
                100.0 * load,
                classic_frame_bits_worst(8, false),
                periods.join(", "),
                100.0 * MAX_BUS_LOAD
            ),
        ))
    }
    /// One line for a log: how the wheel speeds and the validity flags are
    /// read, e.g. `wheel speeds converted from km/h or m/s with r = 0.3 m,
    /// r_ref = 0.3 m; valid: WheelSpeeds.DrivenValid = 0,
    /// WheelSpeeds.RefValid = 0, VehicleSpeed.Valid non-zero`.
    pub fn describe_speeds(&self) -> String {
        let wheels = match self.wheel_radii {
            None => "wheel speeds angular".to_owned(),
            Some(r) => format!(
                "wheel speeds converted from km/h or m/s with r = {} m, r_ref = {} m",
                r.driven_m, r.reference_m
            ),
        };
        let flags: Vec<String> = super::dbc::VALID_FLAGS
            .into_iter()
            .map(|(k, i, _)| {
                let m = self.spec(k);
                let s = &m.signals[i];
                match s.set_raw {
                    None => format!("{}.{} non-zero", m.name, s.name),
                    Some(v) => format!("{}.{} = {v}", m.name, s.name),
                }
            })
            .collect();
        format!("{wheels}; valid: {}", flags.join(", "))
    }
    /// The specification of `kind`.
    pub fn spec(&self, kind: MsgKind) -> &MessageSpec {
        &self.messages[kind as usize]
    }
    /// All five, in [`MsgKind`] order.
    pub fn messages(&self) -> &[MessageSpec; 5] {
        &self.messages
    }
    /// The message with this id, if any. Allocation-free.
    pub fn spec_for_id(&self, id: u32) -> Option<&MessageSpec> {
        self.messages.iter().find(|m| m.id == id)
    }
    /// The messages `role` receives, in [`MsgKind`] order.
    pub fn receives(&self, role: Role) -> impl Iterator<Item = &MessageSpec> + Clone {
        self.messages.iter().filter(move |m| m.receiver == role)
    }
    /// True if `id` (11-bit) is a message `role` receives. Allocation-free.
    pub fn receives_id(&self, role: Role, id: u32) -> bool {
        self.spec_for_id(id).is_some_and(|m| m.receiver == role)
    }
    /// One line for a log: each message's name and id.
    pub fn describe(&self) -> String {
        let mut s = String::new();
        for m in &self.messages {
            if !s.is_empty() {
                s.push_str(", ");
            }
            s.push_str(&format!("{} 0x{:03X}", m.name, m.id));
        }
        s
    }
}

/// The speed a wheel-speed or vehicle-speed signal must carry forward, m/s
/// (150 km/h): [`Protocol::envelope_warnings`].
pub const ENVELOPE_SPEED_MPS: f64 = 150.0 / 3.6;
/// The speed at which a speed signal's step is judged, m/s (10 km/h, the
/// launch speed of the shipped scenarios): one step over 1 % of it moves
/// the measured slip in steps over 0.01.
pub const ENVELOPE_STEP_AT_MPS: f64 = 10.0 / 3.6;

impl Protocol {
    /// What the signals grip controls with cannot carry for `vehicle`, one
    /// warning each, naming the DBC (`dbc`, as `can.toml` gives it), the
    /// message and signal, what it carries and what grip needs: the wheel
    /// speeds (`WheelSpeeds.OmegaDriven` at `r`, `OmegaRef` at `r_ref`)
    /// and `VehicleSpeed.Speed` up to [`ENVELOPE_SPEED_MPS`] and in steps of
    /// at most 1 % of [`ENVELOPE_STEP_AT_MPS`]; the torques read
    /// (`MotorStatus.TorqueActual`, `DriverDemand.TorqueDemand`) up to the
    /// vehicle's `torque_max` and in steps of at most 1 % of it (the
    /// command, `TorqueCommand.TorqueRequest`, under `torque_max` is refused
    /// by tcs-loop's start-up). A bus whose signal saturates or is
    /// coarse is read as it is (a trial's 8-bit OmegaDriven, ±1.27 rad/s,
    /// gave 10 times the slip with the loop "in control"), so these are
    /// said at start; none for the built-in protocol and the shipped DBC
    /// with the shipped vehicles.
    pub fn envelope_warnings(
        &self,
        dbc: &str,
        vehicle: &grip_physics::VehicleParams,
    ) -> Vec<String> {
        let mut w = Vec::new();
        for c in self.control_signals(vehicle) {
            let (m, sg) = (c.message, c.signal);
            let (_, hi) = sg.phys_limits();
            match c.need {
                Need::Speed { r, what } => {
                    let step = sg.factor.abs() * r;
                    if c.is_short() {
                        w.push(format!(
                            "{dbc}: {}.{} carries at most {} ({:.1} km/h of {what}): a faster one saturates there and grip reads it as that speed; grip needs up to {:.0} km/h",
                            m.name,
                            sg.name,
                            fmt_phys(hi, sg.unit),
                            hi * r * 3.6,
                            ENVELOPE_SPEED_MPS * 3.6
                        ));
                    }
                    if step > 0.01 * ENVELOPE_STEP_AT_MPS {
                        w.push(format!(
                            "{dbc}: {}.{} moves in steps of {} ({:.3} m/s of {what}, {:.1} % of 10 km/h): the slip grip measures from it moves in steps of {:.3} at 10 km/h, over the 0.01 its slip tests and road belief are tuned for",
                            m.name,
                            sg.name,
                            fmt_phys(sg.factor.abs(), sg.unit),
                            step,
                            100.0 * step / ENVELOPE_STEP_AT_MPS,
                            step / ENVELOPE_STEP_AT_MPS
                        ));
                    }
                }
                Need::Torque { t_max } => {
                    if c.is_short() {
                        w.push(format!(
                            "{dbc}: {}.{} carries at most {}, under the vehicle's torque_max = {t_max} N m: a torque above it saturates there",
                            m.name,
                            sg.name,
                            fmt_phys(hi, sg.unit)
                        ));
                    }
                    if sg.factor.abs() > 0.01 * t_max {
                        w.push(format!(
                            "{dbc}: {}.{} moves in steps of {}, over 1 % of the vehicle's torque_max = {t_max} N m",
                            m.name,
                            sg.name,
                            fmt_phys(sg.factor.abs(), sg.unit)
                        ));
                    }
                }
            }
        }
        w
    }

    /// The signals grip controls with and what each must carry for
    /// `vehicle` ([`Protocol::envelope_warnings`] judges them; the drive
    /// summary counts the frames a short one sat at its limit in): the
    /// wheel speeds (`WheelSpeeds.OmegaDriven` at `r`, `OmegaRef` at
    /// `r_ref`) and `VehicleSpeed.Speed` up to [`ENVELOPE_SPEED_MPS`], the
    /// torques read (`MotorStatus.TorqueActual`, `DriverDemand.TorqueDemand`)
    /// up to `torque_max`. (`TorqueCommand.TorqueRequest` under
    /// `torque_max` is refused by tcs-loop's start-up: it would cut grip's
    /// own commands.)
    pub fn control_signals(&self, vehicle: &grip_physics::VehicleParams) -> [ControlSignal<'_>; 5] {
        let speed = |kind: MsgKind, i: usize, r: f64, what: &'static str| {
            let m = self.spec(kind);
            ControlSignal {
                message: m,
                signal: sig(m, i),
                need: Need::Speed { r, what },
            }
        };
        let torque = |kind: MsgKind, i: usize| {
            let m = self.spec(kind);
            ControlSignal {
                message: m,
                signal: sig(m, i),
                need: Need::Torque {
                    t_max: vehicle.torque_max,
                },
            }
        };
        [
            speed(
                MsgKind::WheelSpeeds,
                4,
                vehicle.r,
                "the driven wheel's rim at r",
            ),
            speed(
                MsgKind::WheelSpeeds,
                5,
                vehicle.ref_radius(),
                "the reference wheel's rim at r_ref",
            ),
            speed(MsgKind::VehicleSpeed, 3, 1.0, "the car"),
            torque(MsgKind::MotorStatus, 6),
            torque(MsgKind::DriverDemand, 4),
        ]
    }
}

/// What a signal grip controls with must carry ([`ControlSignal`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Need {
    /// A speed up to [`ENVELOPE_SPEED_MPS`] at radius `r` (m; 1 for the
    /// car's own speed), `what` saying whose.
    Speed {
        /// Radius the signal's unit is turned into m/s with.
        r: f64,
        /// Whose speed, for the warning.
        what: &'static str,
    },
    /// A torque up to the vehicle's `torque_max`, N m.
    Torque {
        /// The vehicle's `torque_max`, N m.
        t_max: f64,
    },
}

/// One signal grip controls with ([`Protocol::control_signals`]).
#[derive(Debug, Clone, Copy)]
pub struct ControlSignal<'a> {
    /// Its message.
    pub message: &'a MessageSpec,
    /// The signal.
    pub signal: &'a SignalSpec,
    /// What it must carry.
    pub need: Need,
}

impl ControlSignal<'_> {
    /// The largest physical value it must carry (rad/s or m/s for a speed,
    /// in the signal's own terms: [`ENVELOPE_SPEED_MPS`] / r; N m for a
    /// torque).
    pub fn needed(&self) -> f64 {
        match self.need {
            Need::Speed { r, .. } => ENVELOPE_SPEED_MPS / r,
            Need::Torque { t_max } => t_max,
        }
    }

    /// Whether its largest value is under what it must carry: a larger
    /// one saturates there.
    pub fn is_short(&self) -> bool {
        self.signal.phys_limits().1 < self.needed() * (1.0 - 1e-9)
    }

    /// Whether the frame's payload `data` holds the signal at its largest
    /// value (within a thousandth of a step).
    pub fn at_limit(&self, data: &[u8; 8]) -> bool {
        let (_, hi) = self.signal.phys_limits();
        self.signal.get(data) >= hi - 1e-3 * self.signal.factor.abs()
    }
}

/// A physical value with its unit, as a warning gives it.
fn fmt_phys(x: f64, unit: &str) -> String {
    let v = format!("{}", (x * 1e6).round() / 1e6);
    if unit.is_empty() {
        v
    } else {
        format!("{v} {unit}")
    }
}

/// The message with this id in the [`active`] protocol, if any.
pub fn spec_for_id(id: u32) -> Option<&'static MessageSpec> {
    active().spec_for_id(id)
}

/// The part a grip service plays on the bus: a DBC node that receives
/// protocol messages. Which messages it receives is read from the messages'
/// [`MessageSpec::receiver`], never listed again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Role {
    /// `TCS`, the traction-control ECU (tcs-loop): receives MotorStatus,
    /// WheelSpeeds, VehicleSpeed and DriverDemand.
    Tcs,
    /// `INV`, the motor inverter (played by plant-sim): receives
    /// TorqueCommand.
    Inverter,
}

impl Role {
    /// The node's name in the DBC (`BU_`).
    pub const fn node(self) -> &'static str {
        match self {
            Self::Tcs => "TCS",
            Self::Inverter => "INV",
        }
    }
    /// The messages this role receives in the [`active`] protocol, in
    /// [`MsgKind`] order.
    pub fn receives(self) -> impl Iterator<Item = &'static MessageSpec> + Clone {
        active().receives(self)
    }
    /// True if `id` (11-bit) is a message this role receives in the
    /// [`active`] protocol. Allocation-free.
    pub fn receives_id(self, id: u32) -> bool {
        active().receives_id(self, id)
    }
}

// ---------------------------------------------------------------- CRC-8 ----

const fn crc8_table() -> [u8; 256] {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u8;
        let mut b = 0;
        while b < 8 {
            c = if c & 0x80 != 0 {
                (c << 1) ^ 0x1D
            } else {
                c << 1
            };
            b += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
}
static CRC8_TABLE: [u8; 256] = crc8_table();

/// Feeds bytes into a running CRC-8 SAE J1850 register (no final XOR).
fn crc8_update(mut crc: u8, bytes: &[u8]) -> u8 {
    for &b in bytes {
        crc = CRC8_TABLE[usize::from(crc ^ b)];
    }
    crc
}

/// CRC-8 SAE J1850 of `bytes` (init 0xFF, final XOR 0xFF).
pub fn crc8_j1850(bytes: &[u8]) -> u8 {
    crc8_update(0xFF, bytes) ^ 0xFF
}

/// The E2E CRC of a frame payload: over data id (lo, hi) and bytes 1..=7.
pub fn e2e_crc(data_id: u16, data: &[u8; 8]) -> u8 {
    e2e_crc_at(data_id, data, 0)
}

/// [`e2e_crc`] for a CRC in byte `crc_byte` (0..=7): over the data id,
/// then every other byte in order. Byte 0 gives [`e2e_crc`].
pub fn e2e_crc_at(data_id: u16, data: &[u8; 8], crc_byte: usize) -> u8 {
    let c = crc8_update(0xFF, &data_id.to_le_bytes());
    let c = crc8_update(c, &data[..crc_byte]);
    crc8_update(c, &data[crc_byte + 1..]) ^ 0xFF
}

// ------------------------------------------------------- typed messages ----

/// A typed protocol message.
pub trait ProtocolMessage: Sized + Copy {
    /// Which message this is.
    const KIND: MsgKind;
    /// The message's specification in the [`active`] protocol.
    fn spec() -> &'static MessageSpec {
        active().spec(Self::KIND)
    }
    /// Writes the payload signals (everything except CRC and counter) as
    /// `spec` (this message in some protocol) lays them out.
    fn write_signals_in(&self, spec: &MessageSpec, data: &mut [u8; 8]);
    /// Reads the payload signals as `spec` lays them out.
    fn read_signals_in(spec: &MessageSpec, data: &[u8; 8]) -> Self;
    /// Writes the payload signals in the [`active`] protocol's layout.
    fn write_signals(&self, data: &mut [u8; 8]) {
        self.write_signals_in(Self::spec(), data);
    }
    /// Reads the payload signals in the [`active`] protocol's layout.
    fn read_signals(data: &[u8; 8]) -> Self {
        Self::read_signals_in(Self::spec(), data)
    }
    /// Calls `f(name, physical value)` for each payload signal, in DBC
    /// order (booleans as 0/1). Used by tests and by `grip inspect`.
    fn for_each_signal(&self, f: &mut dyn FnMut(&'static str, f64));
}

fn sig(spec: &MessageSpec, i: usize) -> &SignalSpec {
    &spec.signals[i]
}

fn b(x: bool) -> f64 {
    if x { 1.0 } else { 0.0 }
}

/// Torque request of the traction controller to the inverter.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TorqueCommand {
    /// Requested torque T*, N m.
    pub torque_request: f64,
    /// Torque enabled.
    pub enable: bool,
}
impl ProtocolMessage for TorqueCommand {
    const KIND: MsgKind = MsgKind::TorqueCommand;
    fn write_signals_in(&self, s: &MessageSpec, d: &mut [u8; 8]) {
        sig(s, 2).put_flag(d, self.enable);
        sig(s, 3).put(d, self.torque_request);
    }
    fn read_signals_in(s: &MessageSpec, d: &[u8; 8]) -> Self {
        Self {
            enable: sig(s, 2).get_flag(d),
            torque_request: sig(s, 3).get(d),
        }
    }
    fn for_each_signal(&self, f: &mut dyn FnMut(&'static str, f64)) {
        f("Enable", b(self.enable));
        f("TorqueRequest", self.torque_request);
    }
}

/// Inverter status.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotorStatus {
    /// Inverter ready.
    pub ready: bool,
    /// Inverter fault active.
    pub fault: bool,
    /// Torque derated (e.g. temperature).
    pub derating: bool,
    /// Torque zeroed because commands stopped.
    pub cmd_timeout: bool,
    /// Delivered torque T, N m.
    pub torque_actual: f64,
    /// Motor speed (= driven wheel ω with direct drive), rad/s.
    pub motor_speed: f64,
    /// Inverter fault code (0 = none).
    pub fault_code: u8,
}
impl ProtocolMessage for MotorStatus {
    const KIND: MsgKind = MsgKind::MotorStatus;
    fn write_signals_in(&self, s: &MessageSpec, d: &mut [u8; 8]) {
        sig(s, 2).put_flag(d, self.ready);
        sig(s, 3).put_flag(d, self.fault);
        sig(s, 4).put_flag(d, self.derating);
        sig(s, 5).put_flag(d, self.cmd_timeout);
        sig(s, 6).put(d, self.torque_actual);
        sig(s, 7).put(d, self.motor_speed);
        sig(s, 8).put_raw(d, i64::from(self.fault_code));
    }
    fn read_signals_in(s: &MessageSpec, d: &[u8; 8]) -> Self {
        Self {
            ready: sig(s, 2).get_flag(d),
            fault: sig(s, 3).get_flag(d),
            derating: sig(s, 4).get_flag(d),
            cmd_timeout: sig(s, 5).get_flag(d),
            torque_actual: sig(s, 6).get(d),
            motor_speed: sig(s, 7).get(d),
            fault_code: sig(s, 8).get_raw(d) as u8,
        }
    }
    fn for_each_signal(&self, f: &mut dyn FnMut(&'static str, f64)) {
        f("Ready", b(self.ready));
        f("Fault", b(self.fault));
        f("Derating", b(self.derating));
        f("CmdTimeout", b(self.cmd_timeout));
        f("TorqueActual", self.torque_actual);
        f("MotorSpeed", self.motor_speed);
        f("FaultCode", f64::from(self.fault_code));
    }
}

/// Driven and reference wheel speeds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WheelSpeeds {
    /// `omega_driven` is valid.
    pub driven_valid: bool,
    /// `omega_ref` is valid.
    pub ref_valid: bool,
    /// Driven wheel ω, rad/s.
    pub omega_driven: f64,
    /// Non-driven reference wheel, rad/s (V = r_ref · omega_ref, r_ref the
    /// reference wheel's rolling radius).
    pub omega_ref: f64,
}
impl ProtocolMessage for WheelSpeeds {
    const KIND: MsgKind = MsgKind::WheelSpeeds;
    fn write_signals_in(&self, s: &MessageSpec, d: &mut [u8; 8]) {
        sig(s, 2).put_flag(d, self.driven_valid);
        sig(s, 3).put_flag(d, self.ref_valid);
        sig(s, 4).put(d, self.omega_driven);
        sig(s, 5).put(d, self.omega_ref);
    }
    fn read_signals_in(s: &MessageSpec, d: &[u8; 8]) -> Self {
        Self {
            driven_valid: sig(s, 2).get_flag(d),
            ref_valid: sig(s, 3).get_flag(d),
            omega_driven: sig(s, 4).get(d),
            omega_ref: sig(s, 5).get(d),
        }
    }
    fn for_each_signal(&self, f: &mut dyn FnMut(&'static str, f64)) {
        f("DrivenValid", b(self.driven_valid));
        f("RefValid", b(self.ref_valid));
        f("OmegaDriven", self.omega_driven);
        f("OmegaRef", self.omega_ref);
    }
}

/// Vehicle speed reference.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VehicleSpeed {
    /// Speed is valid.
    pub valid: bool,
    /// Vehicle speed V, m/s.
    pub speed: f64,
    /// Longitudinal acceleration, m/s².
    pub long_accel: f64,
}
impl ProtocolMessage for VehicleSpeed {
    const KIND: MsgKind = MsgKind::VehicleSpeed;
    fn write_signals_in(&self, s: &MessageSpec, d: &mut [u8; 8]) {
        sig(s, 2).put_flag(d, self.valid);
        sig(s, 3).put(d, self.speed);
        sig(s, 4).put(d, self.long_accel);
    }
    fn read_signals_in(s: &MessageSpec, d: &[u8; 8]) -> Self {
        Self {
            valid: sig(s, 2).get_flag(d),
            speed: sig(s, 3).get(d),
            long_accel: sig(s, 4).get(d),
        }
    }
    fn for_each_signal(&self, f: &mut dyn FnMut(&'static str, f64)) {
        f("Valid", b(self.valid));
        f("Speed", self.speed);
        f("LongAccel", self.long_accel);
    }
}

/// Driver demand.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DriverDemand {
    /// Brake pedal pressed.
    pub brake_pressed: bool,
    /// Traction control switched on by the driver.
    pub tcs_enable: bool,
    /// Demanded wheel torque T_d, N m.
    pub torque_demand: f64,
    /// Accelerator pedal position, %.
    pub pedal_position: f64,
}
impl ProtocolMessage for DriverDemand {
    const KIND: MsgKind = MsgKind::DriverDemand;
    fn write_signals_in(&self, s: &MessageSpec, d: &mut [u8; 8]) {
        sig(s, 2).put_flag(d, self.brake_pressed);
        sig(s, 3).put_flag(d, self.tcs_enable);
        sig(s, 4).put(d, self.torque_demand);
        sig(s, 5).put(d, self.pedal_position);
    }
    fn read_signals_in(s: &MessageSpec, d: &[u8; 8]) -> Self {
        Self {
            brake_pressed: sig(s, 2).get_flag(d),
            tcs_enable: sig(s, 3).get_flag(d),
            torque_demand: sig(s, 4).get(d),
            pedal_position: sig(s, 5).get(d),
        }
    }
    fn for_each_signal(&self, f: &mut dyn FnMut(&'static str, f64)) {
        f("BrakePressed", b(self.brake_pressed));
        f("TcsEnable", b(self.tcs_enable));
        f("TorqueDemand", self.torque_demand);
        f("PedalPosition", self.pedal_position);
    }
}

/// Any decoded protocol message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InverterMsg {
    /// See [`TorqueCommand`].
    TorqueCommand(TorqueCommand),
    /// See [`MotorStatus`].
    MotorStatus(MotorStatus),
    /// See [`WheelSpeeds`].
    WheelSpeeds(WheelSpeeds),
    /// See [`VehicleSpeed`].
    VehicleSpeed(VehicleSpeed),
    /// See [`DriverDemand`].
    DriverDemand(DriverDemand),
}

impl InverterMsg {
    /// Decodes the payload of a frame whose id is in the [`active`]
    /// protocol, without any E2E check. `None` for an unknown id.
    pub fn decode_unchecked(frame: &CanFrame) -> Option<Self> {
        Self::decode_in(active(), frame)
    }
    /// [`decode_unchecked`](Self::decode_unchecked) in protocol `p` (e.g. a
    /// drive log's own DBC). Allocation-free.
    pub fn decode_in(p: &Protocol, frame: &CanFrame) -> Option<Self> {
        Some(Self::decode_as(p.spec_for_id(frame.id)?, &frame.data))
    }
    /// Decodes `d` as the message `spec` describes. Allocation-free.
    pub fn decode_as(spec: &MessageSpec, d: &[u8; 8]) -> Self {
        match spec.kind {
            MsgKind::TorqueCommand => Self::TorqueCommand(TorqueCommand::read_signals_in(spec, d)),
            MsgKind::MotorStatus => Self::MotorStatus(MotorStatus::read_signals_in(spec, d)),
            MsgKind::WheelSpeeds => Self::WheelSpeeds(WheelSpeeds::read_signals_in(spec, d)),
            MsgKind::VehicleSpeed => Self::VehicleSpeed(VehicleSpeed::read_signals_in(spec, d)),
            MsgKind::DriverDemand => Self::DriverDemand(DriverDemand::read_signals_in(spec, d)),
        }
    }
}

/// Encodes `msg` with the given alive counter (mod 16) into a frame with a
/// valid CRC. `stamp_ns` is written into the frame; its `bus` is 0, for the
/// sender to set to the bus it sends on (tcs-loop: `can.toml`'s `bus_id`).
pub fn encode<M: ProtocolMessage>(msg: &M, counter: u8, stamp_ns: u64) -> CanFrame {
    encode_in(M::spec(), msg, counter, stamp_ns)
}

/// [`encode`] as `spec` (this message in some protocol) lays it out.
pub fn encode_in<M: ProtocolMessage>(
    spec: &MessageSpec,
    msg: &M,
    counter: u8,
    stamp_ns: u64,
) -> CanFrame {
    let mut data = [0u8; 8];
    msg.write_signals_in(spec, &mut data);
    spec.signals[1].put_raw(&mut data, i64::from(counter & 0x0F));
    let crc = spec.crc_byte();
    data[crc] = e2e_crc_at(spec.data_id, &data, crc);
    CanFrame {
        stamp_ns,
        id: spec.id,
        dlc: spec.dlc,
        direction: grip_msgs::can_dir::TX,
        bus: 0,
        flags: 0,
        data,
    }
}

/// The alive counter of a frame of the [`active`] protocol (bits 8..=11
/// for an id it does not know).
pub fn counter_of(frame: &CanFrame) -> u8 {
    match spec_for_id(frame.id) {
        Some(s) => s.counter(&frame.data),
        None => frame.data[1] & 0x0F,
    }
}

/// Sender side: keeps the alive counter of one message.
#[derive(Debug, Clone, Default)]
pub struct E2eSender<M: ProtocolMessage> {
    counter: u8,
    _m: core::marker::PhantomData<M>,
}

impl<M: ProtocolMessage> E2eSender<M> {
    /// Counter starts at 0.
    pub fn new() -> Self {
        Self {
            counter: 0,
            _m: core::marker::PhantomData,
        }
    }
    /// Encodes the next frame and advances the counter.
    pub fn encode(&mut self, msg: &M, stamp_ns: u64) -> CanFrame {
        let f = encode(msg, self.counter, stamp_ns);
        self.counter = (self.counter + 1) & 0x0F;
        f
    }
    /// The counter the next frame will carry.
    pub fn next_counter(&self) -> u8 {
        self.counter
    }
}

/// Why a received frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum E2eError {
    /// The DLC differs from the message's.
    #[error("frame 0x{id:03X}: DLC {got}, expected {expected}")]
    Length {
        /// Frame id.
        id: u32,
        /// Received DLC.
        got: u8,
        /// DLC of the message.
        expected: u8,
    },
    /// CRC mismatch.
    #[error("frame 0x{id:03X}: CRC 0x{got:02X}, expected 0x{expected:02X}")]
    Crc {
        /// Frame id.
        id: u32,
        /// Received CRC.
        got: u8,
        /// CRC computed over the payload.
        expected: u8,
    },
    /// Counter equal to the last accepted one.
    #[error("frame 0x{id:03X}: alive counter {counter} repeated")]
    CounterRepeated {
        /// Frame id.
        id: u32,
        /// The repeated counter.
        counter: u8,
    },
    /// Counter jumped: frames were lost.
    #[error("frame 0x{id:03X}: alive counter jumped by {delta} (max {max_delta})")]
    CounterSkipped {
        /// Frame id.
        id: u32,
        /// Counter difference mod 16.
        delta: u8,
        /// Largest accepted difference.
        max_delta: u8,
    },
    /// Id not in the protocol.
    #[error("unknown CAN id 0x{id:X}")]
    UnknownId {
        /// Frame id.
        id: u32,
    },
    /// The frame's id belongs to another receiver (programming error; not counted).
    #[error("frame 0x{got:03X} given to the receiver of 0x{expected:03X}")]
    WrongReceiver {
        /// Frame id.
        got: u32,
        /// This receiver's id.
        expected: u32,
    },
}

/// Link state of one received message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkState {
    /// No frame accepted yet.
    NeverReceived,
    /// Last accepted frame is younger than the timeout.
    Ok,
    /// Last accepted frame is older than the timeout.
    TimedOut,
}

/// Receiver of one message: checks DLC, CRC and alive counter, tracks the
/// timeout and counts every fault.
#[derive(Debug, Clone)]
pub struct E2eReceiver {
    spec: &'static MessageSpec,
    timeout_ns: u64,
    max_delta: u8,
    last_counter: Option<u8>,
    last_ok_ns: Option<u64>,
    timed_out: bool,
    accepted: u64,
    faults: E2eFaults,
}

impl E2eReceiver {
    /// Receiver with the DBC's timeout and `max_delta` = 1.
    pub fn new(spec: &'static MessageSpec) -> Self {
        Self {
            spec,
            timeout_ns: u64::from(spec.timeout_ms) * 1_000_000,
            max_delta: 1,
            last_counter: None,
            last_ok_ns: None,
            timed_out: false,
            accepted: 0,
            faults: E2eFaults::default(),
        }
    }
    /// Overrides the timeout.
    pub fn with_timeout_ns(mut self, timeout_ns: u64) -> Self {
        self.timeout_ns = timeout_ns;
        self
    }
    /// Accepts counter jumps up to `max_delta` (1..=14; clamped). A jump > 1
    /// within the limit is still counted as `counter_skipped` but accepted.
    pub fn with_max_delta(mut self, max_delta: u8) -> Self {
        self.max_delta = max_delta.clamp(1, 14);
        self
    }
    /// The message this receiver checks.
    pub fn spec(&self) -> &'static MessageSpec {
        self.spec
    }
    /// Faults counted so far.
    pub fn faults(&self) -> &E2eFaults {
        &self.faults
    }
    /// Frames accepted so far.
    pub fn accepted(&self) -> u64 {
        self.accepted
    }

    /// Checks one frame received at `now_ns`; on success the frame's payload
    /// may be decoded. Every rejection is counted.
    pub fn check(&mut self, frame: &CanFrame, now_ns: u64) -> Result<(), E2eError> {
        let spec = self.spec;
        if frame.id != spec.id {
            return Err(E2eError::WrongReceiver {
                got: frame.id,
                expected: spec.id,
            });
        }
        if frame.dlc != spec.dlc {
            self.faults.length = self.faults.length.wrapping_add(1);
            return Err(E2eError::Length {
                id: frame.id,
                got: frame.dlc,
                expected: spec.dlc,
            });
        }
        let crc = spec.crc_byte();
        let expected = e2e_crc_at(spec.data_id, &frame.data, crc);
        if frame.data[crc] != expected {
            self.faults.crc = self.faults.crc.wrapping_add(1);
            return Err(E2eError::Crc {
                id: frame.id,
                got: frame.data[crc],
                expected,
            });
        }
        // a timeout makes the next frame a resync
        self.poll(now_ns);
        let c = spec.counter(&frame.data);
        if let (Some(last), false) = (self.last_counter, self.timed_out) {
            let delta = c.wrapping_sub(last) & 0x0F;
            if delta == 0 {
                self.faults.counter_repeated = self.faults.counter_repeated.wrapping_add(1);
                return Err(E2eError::CounterRepeated {
                    id: frame.id,
                    counter: c,
                });
            }
            if delta > 1 {
                self.faults.counter_skipped = self.faults.counter_skipped.wrapping_add(1);
                if delta > self.max_delta {
                    self.last_counter = Some(c); // resync: only this frame is lost
                    return Err(E2eError::CounterSkipped {
                        id: frame.id,
                        delta,
                        max_delta: self.max_delta,
                    });
                }
            }
        }
        self.last_counter = Some(c);
        self.last_ok_ns = Some(now_ns);
        self.timed_out = false;
        self.accepted += 1;
        Ok(())
    }

    /// Updates and returns the link state at `now_ns`; entering `TimedOut`
    /// counts one timeout episode.
    pub fn poll(&mut self, now_ns: u64) -> LinkState {
        match self.last_ok_ns {
            None => LinkState::NeverReceived,
            Some(t) => {
                if now_ns.saturating_sub(t) > self.timeout_ns {
                    if !self.timed_out {
                        self.timed_out = true;
                        self.faults.timeout = self.faults.timeout.wrapping_add(1);
                    }
                    LinkState::TimedOut
                } else {
                    LinkState::Ok
                }
            }
        }
    }

    /// Time of the last accepted frame.
    pub fn last_ok_ns(&self) -> Option<u64> {
        self.last_ok_ns
    }
}

/// Receive side of one node: one [`E2eReceiver`] per message it listens to,
/// dispatch by id, unknown ids counted.
#[derive(Debug, Clone)]
pub struct ProtocolRx {
    rx: heapless::Vec<E2eReceiver, 5>,
    unknown_id: u32,
}

impl ProtocolRx {
    /// Listens to `specs` (at most the 5 protocol messages).
    pub fn new(specs: &[&'static MessageSpec]) -> Self {
        let mut rx = heapless::Vec::new();
        for s in specs.iter().take(5) {
            let _ = rx.push(E2eReceiver::new(s));
        }
        Self { rx, unknown_id: 0 }
    }
    /// Listens to what `role` receives ([`Role::receives`]).
    pub fn for_role(role: Role) -> Self {
        let mut rx = heapless::Vec::new();
        for s in role.receives() {
            let _ = rx.push(E2eReceiver::new(s));
        }
        Self { rx, unknown_id: 0 }
    }
    /// What `tcs-loop` listens to ([`Role::Tcs`]): MotorStatus, WheelSpeeds,
    /// VehicleSpeed, DriverDemand.
    pub fn for_tcs() -> Self {
        Self::for_role(Role::Tcs)
    }
    /// What the inverter (plant-sim) listens to ([`Role::Inverter`]):
    /// TorqueCommand.
    pub fn for_inverter() -> Self {
        Self::for_role(Role::Inverter)
    }
    /// Mutable access to the receiver of `id` (e.g. to change its timeout).
    pub fn receiver_mut(&mut self, id: u32) -> Option<&mut E2eReceiver> {
        self.rx.iter_mut().find(|r| r.spec.id == id)
    }
    /// Receiver of `id`.
    pub fn receiver(&self, id: u32) -> Option<&E2eReceiver> {
        self.rx.iter().find(|r| r.spec.id == id)
    }

    /// Checks and decodes one frame. `Ok(None)`: a protocol message this
    /// node does not listen to (ignored, not a fault).
    pub fn receive(
        &mut self,
        frame: &CanFrame,
        now_ns: u64,
    ) -> Result<Option<InverterMsg>, E2eError> {
        if let Some(r) = self.rx.iter_mut().find(|r| r.spec.id == frame.id) {
            r.check(frame, now_ns)?;
            Ok(Some(InverterMsg::decode_as(r.spec, &frame.data)))
        } else if spec_for_id(frame.id).is_some() {
            Ok(None)
        } else {
            self.unknown_id = self.unknown_id.wrapping_add(1);
            Err(E2eError::UnknownId { id: frame.id })
        }
    }

    /// Polls every receiver's timeout; returns true if any listened message
    /// is timed out or was never received.
    pub fn poll_timeouts(&mut self, now_ns: u64) -> bool {
        let mut bad = false;
        for r in self.rx.iter_mut() {
            bad |= r.poll(now_ns) != LinkState::Ok;
        }
        bad
    }

    /// All faults summed over the receivers, plus unknown ids.
    pub fn faults(&self) -> E2eFaults {
        let mut f = E2eFaults {
            unknown_id: self.unknown_id,
            ..E2eFaults::default()
        };
        for r in &self.rx {
            f.add(&r.faults);
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wheel_radii_of_a_vehicle() {
        // no r_ref: the reference wheel rolls on the driven tyre's radius
        let v = grip_physics::VehicleParams {
            r: 0.31,
            r_ref: None,
            ..Default::default()
        };
        assert_eq!(
            WheelRadii::of(&v),
            WheelRadii {
                driven_m: 0.31,
                reference_m: 0.31,
            }
        );
        // r_ref given: the reference wheel's own
        let v = grip_physics::VehicleParams {
            r_ref: Some(0.29),
            ..v
        };
        assert_eq!(
            WheelRadii::of(&v),
            WheelRadii {
                driven_m: 0.31,
                reference_m: 0.29,
            }
        );
    }

    #[test]
    fn crc8_j1850_check_value() {
        // CRC-8/SAE-J1850 catalogue check value (reveng.sourceforge.io/crc-catalogue)
        assert_eq!(crc8_j1850(b"123456789"), 0x4B);
        assert_eq!(crc8_j1850(&[]), 0x00);
        // AUTOSAR SWS CRC Library, SAE-J1850 examples
        assert_eq!(crc8_j1850(&[0x00, 0x00, 0x00, 0x00]), 0x59);
        assert_eq!(crc8_j1850(&[0xF2, 0x01, 0x83]), 0x37);
        assert_eq!(crc8_j1850(&[0xFF, 0xFF, 0xFF, 0xFF]), 0x74);
    }

    #[test]
    fn signed_fields_sign_extend_and_saturate() {
        let s = &TORQUE_COMMAND.signals[3];
        let mut d = [0u8; 8];
        s.put(&mut d, -12.3);
        assert_eq!(s.get_raw(&d), -123);
        assert!((s.get(&d) + 12.3).abs() < 1e-9);
        s.put(&mut d, 1e9);
        assert_eq!(s.get_raw(&d), 32767);
        s.put(&mut d, f64::NAN);
        assert_eq!(s.get_raw(&d), 0);
        // neighbours untouched
        assert_eq!(d[0], 0);
        assert_eq!(d[4..], [0, 0, 0, 0]);
    }

    /// A non-finite value is sent as the physical value 0 (no torque) also
    /// where a DBC gives the signal an offset (raw 0 is -3000 N m there).
    #[test]
    fn non_finite_is_zero_also_with_an_offset() {
        let s = SignalSpec {
            offset: -3000.0,
            ..TORQUE_COMMAND.signals[3]
        };
        let mut d = [0u8; 8];
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            s.put(&mut d, x);
            assert_eq!(s.get(&d), 0.0, "{x}");
        }
    }

    /// The review's repro (2026-12-05): `TrqReq : 23|16@0- (0.5,0)
    /// [-250|250] "Nm"`. 300 N m went out as raw 600 (the bit field's
    /// limit only); it is sent as 250 N m, the range's end, and so is
    /// -300 N m as -250.
    #[test]
    fn a_dbc_range_saturates_what_is_sent() {
        let s = SignalSpec {
            start: 23,
            factor: 0.5,
            min: -250.0,
            max: 250.0,
            motorola: true,
            ..TORQUE_COMMAND.signals[3]
        };
        assert!(s.has_range());
        assert_eq!((s.field_raw_min(), s.field_raw_max()), (-32768, 32767));
        assert_eq!((s.raw_min(), s.raw_max()), (-500, 500));
        assert_eq!(s.phys_limits(), (-250.0, 250.0));
        let mut d = [0u8; 8];
        for (sent, raw) in [
            (300.0, 500),
            (250.0, 500),
            (1e300, 500),
            (-300.0, -500),
            (-1e300, -500),
            (100.2, 200),
        ] {
            s.put(&mut d, sent);
            assert_eq!(s.get_raw(&d), raw, "{sent}");
        }
        // a received value beyond the range is decoded as the frame
        // carries it (not clamped, not refused)
        s.put_raw(&mut d, 600);
        assert_eq!(s.get(&d), 300.0);
    }

    /// `[0|0]` is a DBC's "no range": the bit field alone limits.
    #[test]
    fn a_range_of_zero_to_zero_is_none() {
        let s = SignalSpec {
            min: 0.0,
            max: 0.0,
            ..TORQUE_COMMAND.signals[3]
        };
        assert!(!s.has_range());
        assert_eq!(s.range_raw(), None);
        assert_eq!(s.to_raw(1e9), 32767);
        assert_eq!(s.to_raw(-1e9), -32768);
        assert_eq!(s.to_raw(12.34), 123);
    }

    /// An end that is not a whole step: the last step inside the range is
    /// sent, never one beyond it; with a negative factor the ends swap.
    #[test]
    fn a_range_end_between_steps_is_not_overshot() {
        let s = SignalSpec {
            factor: 0.3,
            min: -100.0,
            max: 250.0,
            ..TORQUE_COMMAND.signals[3]
        };
        assert_eq!((s.raw_min(), s.raw_max()), (-333, 833));
        assert!(s.to_phys(s.to_raw(1e4)) <= 250.0);
        assert!(s.to_phys(s.to_raw(-1e4)) >= -100.0);
        let n = SignalSpec {
            factor: -0.5,
            min: -10.0,
            max: 20.0,
            ..TORQUE_COMMAND.signals[3]
        };
        assert_eq!((n.raw_min(), n.raw_max()), (-40, 20));
        assert_eq!(n.phys_limits(), (-10.0, 20.0));
        assert_eq!(n.to_phys(n.to_raw(1e4)), 20.0);
        assert_eq!(n.to_phys(n.to_raw(-1e4)), -10.0);
    }

    /// A non-finite value is the physical value 0, saturated like any other:
    /// at the range's nearer end where the range leaves 0 out.
    #[test]
    fn non_finite_is_physical_zero_within_the_range() {
        let s = SignalSpec {
            min: 10.0,
            max: 100.0,
            ..TORQUE_COMMAND.signals[3]
        };
        assert_eq!(s.to_phys(s.to_raw(f64::NAN)), 10.0);
        let s = SignalSpec {
            offset: -3000.0,
            min: -3000.0,
            max: 3000.0,
            ..TORQUE_COMMAND.signals[3]
        };
        assert_eq!(s.to_raw(f64::NAN), 30000);
        assert_eq!(s.to_phys(s.to_raw(f64::INFINITY)), 0.0);
    }

    /// The built-in protocol's ranges are its bit fields' (what it sent
    /// before ranges were applied, it sends now) and its bus load is
    /// 43.2 % of 1 Mbit/s.
    #[test]
    fn the_built_in_protocol_is_unchanged_by_ranges_and_loads_the_bus_43_percent() {
        for m in MESSAGES {
            for s in m.signals.iter().skip(2) {
                assert!(s.has_range(), "{}.{}", m.name, s.name);
                assert_eq!(
                    (s.raw_min(), s.raw_max()),
                    (s.field_raw_min(), s.field_raw_max()),
                    "{}.{}",
                    m.name,
                    s.name
                );
            }
        }
        assert_eq!(classic_frame_bits_worst(8, false), 135);
        assert_eq!(classic_frame_bits_worst(8, true), 160);
        assert_eq!(classic_frame_bits_worst(0, false), 55);
        let p = Protocol::builtin();
        assert_eq!(*p.bus(), BusTiming::ASSUMED);
        // 3 × 135 bits every 1 ms + 2 × 135 every 10 ms
        assert!((p.bus_load() - 0.432).abs() < 1e-12, "{}", p.bus_load());
        assert!(p.bus_load() <= MAX_BUS_LOAD);
        assert!(p.describe_bus().contains("43.2 %"), "{}", p.describe_bus());
    }

    /// The bus load at the interface's bit rate: 43.2 % of can0's 1 Mbit/s
    /// is accepted and said to be read from can0; 500 kbit/s is refused
    /// naming the interface, its rate and the load, even where the DBC says
    /// 1 Mbit/s; without the interface's rate, today's DBC-or-assumed rule.
    #[test]
    fn the_bus_load_is_judged_at_the_interfaces_bit_rate() {
        use crate::can::bitrate::{InterfaceBitrate, choose_bitrate};
        let at = |read: InterfaceBitrate, dbc: Option<u32>| {
            let mut p = Protocol::builtin().clone();
            p.bus.dbc_bitrate = dbc;
            if let Some(d) = dbc {
                p.bus.bitrate = d;
            }
            p.with_bitrate(&choose_bitrate("can0", &read, dbc))
        };
        let p = at(InterfaceBitrate::Reported(1_000_000), Some(1_000_000));
        assert_eq!(p.bus_load_refusal(), None);
        assert!(
            p.describe_bus().starts_with(
                "1000 kbit/s (1000000 bit/s read from can0; the DBC's Baudrate agrees), grip's messages 43.2 %"
            ),
            "{}",
            p.describe_bus()
        );
        // a DBC that says 500 kbit/s on a 1 Mbit/s interface: accepted
        let p = at(InterfaceBitrate::Reported(1_000_000), Some(500_000));
        assert_eq!(p.bus_load_refusal(), None);
        assert!(
            p.describe_bus()
                .contains("the DBC's Baudrate says 500000 bit/s"),
            "{}",
            p.describe_bus()
        );
        for dbc in [None, Some(1_000_000)] {
            let p = at(InterfaceBitrate::Reported(500_000), dbc);
            let (what, reason) = p.bus_load_refusal().expect("86.4 % refused");
            assert_eq!(what, "interface");
            assert!(
                reason.starts_with(
                    "grip's five messages would take 86.4 % of can0's 500000 bit/s (the interface's bit rate, read from the kernel)"
                ) && reason.contains("ip link set can0 type can bitrate 1000000"),
                "{reason}"
            );
        }
        // vcan: the DBC's rate as before, refused naming the DBC's attribute
        let p = at(InterfaceBitrate::NotReported, Some(500_000));
        let (what, reason) = p.bus_load_refusal().expect("86.4 % refused");
        assert_eq!(what, "attribute Baudrate");
        assert!(
            reason.contains("86.4 % of the DBC's 500 kbit/s"),
            "{reason}"
        );
        let p = at(InterfaceBitrate::NotReported, None);
        assert_eq!(p.bus_load_refusal(), None);
        assert_eq!(*p.bus(), BusTiming::ASSUMED);
    }

    /// A flag's sense: without `set_raw` any non-zero value is set (the
    /// built-in protocol's); with one only that value, and a cleared flag
    /// is sent as a value that reads back cleared, also in a signed 1-bit
    /// field (which holds -1 and 0) whose set value is 0.
    #[test]
    fn a_flag_reads_and_writes_in_its_sense() {
        let plain = WHEEL_SPEEDS.signals[2];
        let inverted = SignalSpec {
            set_raw: Some(0),
            ..plain
        };
        let signed = SignalSpec {
            signed: true,
            ..inverted
        };
        let status = SignalSpec {
            len: 2,
            set_raw: Some(2),
            ..plain
        };
        for (s, set, clear) in [
            (plain, 1, 0),
            (inverted, 0, 1),
            (signed, 0, -1),
            (status, 2, 0),
        ] {
            let mut d = [0u8; 8];
            for on in [true, false, true] {
                s.put_flag(&mut d, on);
                assert_eq!(s.get_raw(&d), if on { set } else { clear }, "{s:?}");
                assert_eq!(s.get_flag(&d), on, "{s:?}");
            }
        }
        let mut d = [0u8; 8];
        status.put_raw(&mut d, 3);
        assert!(!status.get_flag(&d));
        plain.put_raw(&mut d, 1);
        assert!(plain.get_flag(&d) && !inverted.get_flag(&d));
    }

    #[test]
    fn known_frame_bytes() {
        let f = encode(
            &TorqueCommand {
                torque_request: 100.0,
                enable: true,
            },
            3,
            0,
        );
        // 1000 raw = 0x03E8 little-endian at byte 2; counter 3 | enable<<4
        assert_eq!(&f.data[1..], &[0x13, 0xE8, 0x03, 0, 0, 0, 0]);
        assert_eq!(
            f.data[0],
            crc8_j1850(&[0x01, 0x1A, 0x13, 0xE8, 0x03, 0, 0, 0, 0])
        );
    }

    #[test]
    fn timeout_is_counted_once_per_episode_and_resyncs() {
        let mut rx = E2eReceiver::new(&WHEEL_SPEEDS);
        let mut tx = E2eSender::<WheelSpeeds>::new();
        let m = WheelSpeeds::default();
        assert_eq!(rx.poll(0), LinkState::NeverReceived);
        assert!(rx.check(&tx.encode(&m, 0), 0).is_ok());
        assert_eq!(rx.poll(10_000_000), LinkState::Ok);
        assert_eq!(rx.poll(10_000_001), LinkState::TimedOut);
        assert_eq!(rx.poll(20_000_000), LinkState::TimedOut);
        assert_eq!(rx.faults().timeout, 1);
        // after a timeout any counter is accepted (resync)
        for _ in 0..5 {
            tx.encode(&m, 0);
        }
        assert!(rx.check(&tx.encode(&m, 0), 21_000_000).is_ok());
        assert_eq!(rx.poll(21_000_001), LinkState::Ok);
        assert_eq!(rx.faults().counter_skipped, 0);
    }
}
