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
    /// The model file cannot be read (missing, a directory, no permission).
    #[error("{}model file {}: cannot read: {reason}", from.prefix(), path.display())]
    ModelIo {
        /// The file.
        path: PathBuf,
        /// What named it (`arte-svc.toml`'s `model`, or `--model`).
        from: ModelSource,
        /// Why.
        reason: String,
    },
    /// The model file is not a valid model.
    #[error("{}model file {}: {error}", from.prefix(), path.display())]
    Model {
        /// The file.
        path: PathBuf,
        /// What named it (`arte-svc.toml`'s `model`, or `--model`).
        from: ModelSource,
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

/// What named the model file arte loads: a model error begins with it, so
/// that it says which setting to change, in the style of
/// [`grip_config::ConfigError`] (``FILE: field `model`: ...``).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ModelSource {
    /// The path was given to [`crate::load_model`] as it is (a library
    /// caller that names the file in its own words): the error names the
    /// file only.
    #[default]
    Direct,
    /// A field of a configuration file: `arte-svc.toml`'s `model`.
    Config {
        /// The configuration file.
        file: PathBuf,
        /// The field's dotted key path (`model`).
        field: &'static str,
    },
    /// A command-line option (`--model`).
    Option(&'static str),
}

impl ModelSource {
    /// What a model error begins with: ``FILE: field `model`: ``,
    /// ``option `--model`: `` or nothing.
    pub fn prefix(&self) -> String {
        match self {
            Self::Direct => String::new(),
            Self::Config { file, field } => format!("{}: field `{field}`: ", file.display()),
            Self::Option(name) => format!("option `{name}`: "),
        }
    }
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
