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
    /// Physical minimum as written in the DBC.
    pub min: f64,
    /// Physical maximum as written in the DBC.
    pub max: f64,
    /// Unit string.
    pub unit: &'static str,
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
        }
    }
    const fn flag(name: &'static str, start: u8) -> Self {
        Self::new(name, start, 1, false, 1.0, 0.0, 1.0, "")
    }
    /// Smallest raw value the bit field holds.
    pub fn raw_min(&self) -> i64 {
        if self.signed {
            -(1i64 << (self.len - 1))
        } else {
            0
        }
    }
    /// Largest raw value the bit field holds.
    pub fn raw_max(&self) -> i64 {
        if self.signed {
            (1i64 << (self.len - 1)) - 1
        } else {
            (1i64 << self.len) - 1
        }
    }
    /// Physical value → raw, rounded to nearest and saturated to the bit
    /// field; non-finite input gives raw 0 (for a torque: no torque).
    pub fn to_raw(&self, phys: f64) -> i64 {
        let r = ((phys - self.offset) / self.factor).round();
        if !r.is_finite() {
            return 0;
        }
        (r as i64).clamp(self.raw_min(), self.raw_max())
    }
    /// Raw → physical.
    pub fn to_phys(&self, raw: i64) -> f64 {
        raw as f64 * self.factor + self.offset
    }
    /// Writes a raw value into `data` (Intel bit numbering).
    pub fn put_raw(&self, data: &mut [u8; 8], raw: i64) {
        let mask = if self.len >= 64 {
            u64::MAX
        } else {
            (1u64 << self.len) - 1
        };
        let bits = (raw as u64) & mask;
        let mut word = u64::from_le_bytes(*data);
        word &= !(mask << self.start);
        word |= bits << self.start;
        *data = word.to_le_bytes();
    }
    /// Reads the raw value (sign-extended if signed).
    pub fn get_raw(&self, data: &[u8; 8]) -> i64 {
        let word = u64::from_le_bytes(*data);
        let v = (word >> self.start) & ((1u64 << self.len) - 1);
        if self.signed && (v >> (self.len - 1)) & 1 == 1 {
            (v | !((1u64 << self.len) - 1)) as i64
        } else {
            v as i64
        }
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
    /// All signals, CRC and Counter first.
    pub signals: &'static [SignalSpec],
}

const CRC_SIG: SignalSpec = SignalSpec::new("CRC", 0, 8, false, 1.0, 0.0, 255.0, "");
const COUNTER_SIG: SignalSpec = SignalSpec::new("Counter", 8, 4, false, 1.0, 0.0, 15.0, "");

/// `TorqueCommand` (TCS → INV).
pub const TORQUE_COMMAND: MessageSpec = MessageSpec {
    name: "TorqueCommand",
    id: 0x100,
    dlc: 8,
    data_id: 0x1A01,
    cycle_ms: 1,
    timeout_ms: 20,
    sender: "TCS",
    receiver: Role::Inverter,
    signals: &[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("Enable", 12),
        SignalSpec::new("TorqueRequest", 16, 16, true, 0.1, -3276.8, 3276.7, "Nm"),
    ],
};

/// `MotorStatus` (INV → TCS).
pub const MOTOR_STATUS: MessageSpec = MessageSpec {
    name: "MotorStatus",
    id: 0x110,
    dlc: 8,
    data_id: 0x1A02,
    cycle_ms: 1,
    timeout_ms: 10,
    sender: "INV",
    receiver: Role::Tcs,
    signals: &[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("Ready", 12),
        SignalSpec::flag("Fault", 13),
        SignalSpec::flag("Derating", 14),
        SignalSpec::flag("CmdTimeout", 15),
        SignalSpec::new("TorqueActual", 16, 16, true, 0.1, -3276.8, 3276.7, "Nm"),
        SignalSpec::new("MotorSpeed", 32, 16, true, 0.01, -327.68, 327.67, "rad/s"),
        SignalSpec::new("FaultCode", 48, 8, false, 1.0, 0.0, 255.0, ""),
    ],
};

/// `WheelSpeeds` (ABS → TCS).
pub const WHEEL_SPEEDS: MessageSpec = MessageSpec {
    name: "WheelSpeeds",
    id: 0x120,
    dlc: 8,
    data_id: 0x1A03,
    cycle_ms: 1,
    timeout_ms: 10,
    sender: "ABS",
    receiver: Role::Tcs,
    signals: &[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("DrivenValid", 12),
        SignalSpec::flag("RefValid", 13),
        SignalSpec::new("OmegaDriven", 16, 16, true, 0.01, -327.68, 327.67, "rad/s"),
        SignalSpec::new("OmegaRef", 32, 16, true, 0.01, -327.68, 327.67, "rad/s"),
    ],
};

/// `VehicleSpeed` (VCU → TCS).
pub const VEHICLE_SPEED: MessageSpec = MessageSpec {
    name: "VehicleSpeed",
    id: 0x130,
    dlc: 8,
    data_id: 0x1A04,
    cycle_ms: 10,
    timeout_ms: 50,
    sender: "VCU",
    receiver: Role::Tcs,
    signals: &[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("Valid", 12),
        SignalSpec::new("Speed", 16, 16, true, 0.01, -327.68, 327.67, "m/s"),
        SignalSpec::new("LongAccel", 32, 16, true, 0.001, -32.768, 32.767, "m/s2"),
    ],
};

/// `DriverDemand` (VCU → TCS).
pub const DRIVER_DEMAND: MessageSpec = MessageSpec {
    name: "DriverDemand",
    id: 0x140,
    dlc: 8,
    data_id: 0x1A05,
    cycle_ms: 10,
    timeout_ms: 50,
    sender: "VCU",
    receiver: Role::Tcs,
    signals: &[
        CRC_SIG,
        COUNTER_SIG,
        SignalSpec::flag("BrakePressed", 12),
        SignalSpec::flag("TcsEnable", 13),
        SignalSpec::new("TorqueDemand", 16, 16, true, 0.1, -3276.8, 3276.7, "Nm"),
        SignalSpec::new("PedalPosition", 32, 8, false, 0.5, 0.0, 127.5, "%"),
    ],
};

/// Every message of the protocol.
pub const MESSAGES: [&MessageSpec; 5] = [
    &TORQUE_COMMAND,
    &MOTOR_STATUS,
    &WHEEL_SPEEDS,
    &VEHICLE_SPEED,
    &DRIVER_DEMAND,
];

/// The message with this id, if any.
pub fn spec_for_id(id: u32) -> Option<&'static MessageSpec> {
    MESSAGES.iter().copied().find(|m| m.id == id)
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
    /// The messages this role receives, in [`MESSAGES`] order.
    pub fn receives(self) -> impl Iterator<Item = &'static MessageSpec> + Clone {
        MESSAGES.iter().copied().filter(move |m| m.receiver == self)
    }
    /// True if `id` (11-bit) is a message this role receives.
    /// Allocation-free.
    pub fn receives_id(self, id: u32) -> bool {
        spec_for_id(id).is_some_and(|m| m.receiver == self)
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
    let c = crc8_update(0xFF, &data_id.to_le_bytes());
    crc8_update(c, &data[1..]) ^ 0xFF
}

// ------------------------------------------------------- typed messages ----

/// A typed protocol message.
pub trait ProtocolMessage: Sized + Copy {
    /// The message's specification.
    const SPEC: &'static MessageSpec;
    /// Writes the payload signals (everything except CRC and counter).
    fn write_signals(&self, data: &mut [u8; 8]);
    /// Reads the payload signals.
    fn read_signals(data: &[u8; 8]) -> Self;
    /// Calls `f(name, physical value)` for each payload signal, in DBC
    /// order (booleans as 0/1). Used by tests and by `grip inspect`.
    fn for_each_signal(&self, f: &mut dyn FnMut(&'static str, f64));
}

fn sig(spec: &'static MessageSpec, i: usize) -> &'static SignalSpec {
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
    const SPEC: &'static MessageSpec = &TORQUE_COMMAND;
    fn write_signals(&self, d: &mut [u8; 8]) {
        sig(Self::SPEC, 2).put_raw(d, i64::from(self.enable));
        sig(Self::SPEC, 3).put(d, self.torque_request);
    }
    fn read_signals(d: &[u8; 8]) -> Self {
        Self {
            enable: sig(Self::SPEC, 2).get_raw(d) != 0,
            torque_request: sig(Self::SPEC, 3).get(d),
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
    const SPEC: &'static MessageSpec = &MOTOR_STATUS;
    fn write_signals(&self, d: &mut [u8; 8]) {
        let s = Self::SPEC;
        sig(s, 2).put_raw(d, i64::from(self.ready));
        sig(s, 3).put_raw(d, i64::from(self.fault));
        sig(s, 4).put_raw(d, i64::from(self.derating));
        sig(s, 5).put_raw(d, i64::from(self.cmd_timeout));
        sig(s, 6).put(d, self.torque_actual);
        sig(s, 7).put(d, self.motor_speed);
        sig(s, 8).put_raw(d, i64::from(self.fault_code));
    }
    fn read_signals(d: &[u8; 8]) -> Self {
        let s = Self::SPEC;
        Self {
            ready: sig(s, 2).get_raw(d) != 0,
            fault: sig(s, 3).get_raw(d) != 0,
            derating: sig(s, 4).get_raw(d) != 0,
            cmd_timeout: sig(s, 5).get_raw(d) != 0,
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
    /// Non-driven reference wheel, rad/s (V = r · omega_ref).
    pub omega_ref: f64,
}
impl ProtocolMessage for WheelSpeeds {
    const SPEC: &'static MessageSpec = &WHEEL_SPEEDS;
    fn write_signals(&self, d: &mut [u8; 8]) {
        let s = Self::SPEC;
        sig(s, 2).put_raw(d, i64::from(self.driven_valid));
        sig(s, 3).put_raw(d, i64::from(self.ref_valid));
        sig(s, 4).put(d, self.omega_driven);
        sig(s, 5).put(d, self.omega_ref);
    }
    fn read_signals(d: &[u8; 8]) -> Self {
        let s = Self::SPEC;
        Self {
            driven_valid: sig(s, 2).get_raw(d) != 0,
            ref_valid: sig(s, 3).get_raw(d) != 0,
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
    const SPEC: &'static MessageSpec = &VEHICLE_SPEED;
    fn write_signals(&self, d: &mut [u8; 8]) {
        let s = Self::SPEC;
        sig(s, 2).put_raw(d, i64::from(self.valid));
        sig(s, 3).put(d, self.speed);
        sig(s, 4).put(d, self.long_accel);
    }
    fn read_signals(d: &[u8; 8]) -> Self {
        let s = Self::SPEC;
        Self {
            valid: sig(s, 2).get_raw(d) != 0,
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
    const SPEC: &'static MessageSpec = &DRIVER_DEMAND;
    fn write_signals(&self, d: &mut [u8; 8]) {
        let s = Self::SPEC;
        sig(s, 2).put_raw(d, i64::from(self.brake_pressed));
        sig(s, 3).put_raw(d, i64::from(self.tcs_enable));
        sig(s, 4).put(d, self.torque_demand);
        sig(s, 5).put(d, self.pedal_position);
    }
    fn read_signals(d: &[u8; 8]) -> Self {
        let s = Self::SPEC;
        Self {
            brake_pressed: sig(s, 2).get_raw(d) != 0,
            tcs_enable: sig(s, 3).get_raw(d) != 0,
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
    /// Decodes the payload of a frame whose id is in the protocol, without
    /// any E2E check. `None` for an unknown id.
    pub fn decode_unchecked(frame: &CanFrame) -> Option<Self> {
        let d = &frame.data;
        Some(match frame.id {
            0x100 => Self::TorqueCommand(TorqueCommand::read_signals(d)),
            0x110 => Self::MotorStatus(MotorStatus::read_signals(d)),
            0x120 => Self::WheelSpeeds(WheelSpeeds::read_signals(d)),
            0x130 => Self::VehicleSpeed(VehicleSpeed::read_signals(d)),
            0x140 => Self::DriverDemand(DriverDemand::read_signals(d)),
            _ => return None,
        })
    }
}

/// Encodes `msg` with the given alive counter (mod 16) into a frame with a
/// valid CRC. `stamp_ns` is written into the frame.
pub fn encode<M: ProtocolMessage>(msg: &M, counter: u8, stamp_ns: u64) -> CanFrame {
    let spec = M::SPEC;
    let mut data = [0u8; 8];
    msg.write_signals(&mut data);
    spec.signals[1].put_raw(&mut data, i64::from(counter & 0x0F));
    data[0] = e2e_crc(spec.data_id, &data);
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

/// The alive counter of a frame.
pub fn counter_of(frame: &CanFrame) -> u8 {
    (frame.data[1]) & 0x0F
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
        let expected = e2e_crc(spec.data_id, &frame.data);
        if frame.data[0] != expected {
            self.faults.crc = self.faults.crc.wrapping_add(1);
            return Err(E2eError::Crc {
                id: frame.id,
                got: frame.data[0],
                expected,
            });
        }
        // a timeout makes the next frame a resync
        self.poll(now_ns);
        let c = counter_of(frame);
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
            Ok(InverterMsg::decode_unchecked(frame))
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
