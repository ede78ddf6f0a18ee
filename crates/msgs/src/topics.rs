//! Every iceoryx2 service name, process name and topic in one place.
//!
//! Service names are iceoryx2 `ServiceName`s (slash-separated). Each topic
//! says which payload type it carries, who publishes it and who reads it.

/// Process (node) names, also the systemd unit stems.
pub mod node {
    /// Microphone capture (ALSA) → [`super::AUDIO`].
    pub const AUDIO_ACQ: &str = "audio-acq";
    /// Acoustic road-type estimator: [`super::AUDIO`] → [`super::ROAD`].
    pub const ARTE: &str = "arte";
    /// 1 kHz traction-control loop: CAN + [`super::ROAD`] → CAN + [`super::CYCLE`].
    pub const TCS_LOOP: &str = "tcs-loop";
    /// Writes every topic to MCAP (not real-time).
    pub const RECORDER: &str = "recorder";
    /// Inverter + vehicle + road simulator on the CAN bus; publishes [`super::TRUTH`].
    pub const PLANT_SIM: &str = "plant-sim";
    /// The `grip` command line (drive, inspect).
    pub const CLI: &str = "grip-cli";
}

/// `AudioBlock` from audio-acq; read by arte (latest blocks, in order) and recorder.
pub const AUDIO: &str = "grip/audio/block";
/// `RoadEstimate` from arte; read by tcs-loop (every one, in order) and recorder.
pub const ROAD: &str = "grip/arte/road";
/// `CycleRecord` from tcs-loop, one per control cycle; read by the recorder and arte.
pub const CYCLE: &str = "grip/tcs/cycle";
/// `CanFrame` copies of every frame tcs-loop sent or received (any transport),
/// flagged with direction; read by recorder.
pub const CAN_LOG: &str = "grip/can/log";
/// `GroundTruth` from plant-sim; read by audio synthesis and recorder.
pub const TRUTH: &str = "grip/plant/truth";

/// MCAP channel (not an iceoryx2 topic: the recorder reads the bus itself,
/// `recorder.toml`'s `bus`) of [`crate::BusFrame`]s: the vehicle bus as a
/// CAN logger records it. Not in [`ALL`]; `grip replay` and the drive
/// summary ignore it.
pub const BUS: &str = "grip/can/bus";

/// Prefix of the simulated CAN bus services: bus `vcan0` is the
/// publish-subscribe service `grip/canbus/vcan0` carrying `CanFrame`s, plus an
/// event service of the same name with suffix [`SIM_BUS_EVENT_SUFFIX`].
pub const SIM_BUS_PREFIX: &str = "grip/canbus/";
/// Suffix of the simulated bus's wake-up event service.
pub const SIM_BUS_EVENT_SUFFIX: &str = "/wake";

/// Every data topic with its payload type name, for tools that list or
/// record everything (the recorder subscribes to exactly these).
pub const ALL: [(&str, &str); 5] = [
    (AUDIO, crate::AudioBlock::TYPE_NAME),
    (ROAD, crate::RoadEstimate::TYPE_NAME),
    (CYCLE, crate::CycleRecord::TYPE_NAME),
    (CAN_LOG, crate::CanFrame::TYPE_NAME),
    (TRUTH, crate::GroundTruth::TYPE_NAME),
];
