//! [`ArteError`]: what stops the arte service from starting.

use std::path::PathBuf;

use grip_arte::model::ModelError;
use grip_arte::stream::StreamError;

/// Errors of the arte service (start-up).
#[derive(Debug, thiserror::Error)]
pub enum ArteError {
    /// Bad configuration file (or road catalogue).
    #[error(transparent)]
    Config(#[from] grip_config::ConfigError),
    /// The model file cannot be read.
    #[error("model file {}: cannot read: {reason}", path.display())]
    ModelIo {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The model file is not a valid model.
    #[error("model file {}: {error}", path.display())]
    Model {
        /// The file.
        path: PathBuf,
        /// The model crate's error (said in the message, not returned as
        /// the source: a chain printed in full, as `grip replay` prints
        /// it, would say it twice).
        error: ModelError,
    },
    /// A model class has no road in the catalogue, or too many classes.
    #[error("model file {}: {reason}", path.display())]
    Classes {
        /// The model file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The model's confidence calibration was fitted for other `[stream]`
    /// settings (hop, smoothing) than the configuration file's: the
    /// confidence arte would publish is not calibrated for them.
    #[error("{}: {reason}", config_file.display())]
    CalibrationMismatch {
        /// The configuration file (`arte-svc.toml`).
        config_file: PathBuf,
        /// The model file.
        model_path: PathBuf,
        /// The differing field(s), both settings and the remedy.
        reason: String,
    },
    /// The streaming estimator refused model or settings (said in the
    /// message, not returned as the source).
    #[error("streaming estimator: {0}")]
    Stream(StreamError),
    /// iceoryx2.
    #[error(transparent)]
    Ipc(#[from] grip_io::ipc::IpcError),
    /// The helper thread could not be started.
    #[error(transparent)]
    Helper(#[from] grip_io::service::monitor::HelperError),
    /// Other start-up failure.
    #[error("{0}")]
    Other(String),
}

impl grip_io::service::ServiceError for ArteError {
    fn is_config(&self) -> bool {
        // listed, so that a variant added later is decided, not defaulted;
        // `Other` is the model's classes against the road table
        match self {
            Self::Config(_)
            | Self::ModelIo { .. }
            | Self::Model { .. }
            | Self::Classes { .. }
            | Self::CalibrationMismatch { .. }
            | Self::Stream(_)
            | Self::Other(_) => true,
            Self::Ipc(_) | Self::Helper(_) => false,
        }
    }
}

impl From<StreamError> for ArteError {
    fn from(e: StreamError) -> Self {
        Self::Stream(e)
    }
}
