//! One module per subcommand.

pub mod analyze;
pub mod roads;
pub mod sim;
pub mod train;
pub mod classify;
pub mod dataset;
pub mod features;

/// What every subcommand gets from the global options.
pub struct Ctx {
    /// The configuration directory (`--config-dir`, default `config`).
    pub config_dir: std::path::PathBuf,
}
