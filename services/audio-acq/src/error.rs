//! [`AcqError`]: start-up and fatal run-time errors of audio-acq.

use crate::wav;

/// Errors of audio-acq (start-up and fatal run-time errors).
#[derive(Debug, thiserror::Error)]
pub enum AcqError {
    /// Bad configuration file.
    #[error(transparent)]
    Config(#[from] grip_config::ConfigError),
    /// iceoryx2 port problem.
    #[error(transparent)]
    Ipc(#[from] grip_io::ipc::IpcError),
    /// WAV file problem.
    #[error(transparent)]
    Wav(#[from] wav::WavError),
    /// The ALSA device does not open.
    #[error(
        "cannot open ALSA capture device {device:?}: {reason}. Capture PCMs alsa-lib knows: {available}"
    )]
    AlsaDevice {
        /// Device name.
        device: String,
        /// alsa-lib's reason.
        reason: String,
        /// What exists (like `arecord -L`).
        available: String,
    },
    /// The ALSA device refuses the configuration.
    #[error("ALSA capture device {device:?}: {reason}")]
    AlsaParams {
        /// Device name.
        device: String,
        /// What was refused.
        reason: String,
    },
    /// A capture error that could not be recovered.
    #[error("ALSA capture failed while {what}: {reason}")]
    AlsaIo {
        /// During what.
        what: &'static str,
        /// alsa-lib's reason.
        reason: String,
    },
    /// The helper thread could not be started.
    #[error(transparent)]
    Helper(#[from] grip_io::service::monitor::HelperError),
    /// The synthesiser refused its configuration.
    #[error("synth source: {0}")]
    Synth(String),
}

impl grip_io::service::ServiceError for AcqError {
    /// The configuration's: the file, the WAV file it names, the
    /// synthesiser's settings; not the ALSA device (one that does not open,
    /// refuses its parameters or fails to capture: a USB microphone still
    /// enumerating fails the same calls, and a restart may find it).
    fn is_config(&self) -> bool {
        matches!(self, Self::Config(_) | Self::Wav(_) | Self::Synth(_))
    }
}
