//! One module per subcommand.

pub mod analyze;
pub mod calibrate;
pub mod classify;
pub mod dataset;
pub mod dataset_merge;
pub mod drive;
pub mod features;
pub mod generate;
pub mod inspect;
pub mod replay;
pub mod roads;
pub mod sim;
pub mod snr;
pub mod train;

/// What every subcommand gets from the global options.
pub struct Ctx {
    /// The configuration directory (`--config-dir`, default `config`).
    pub config_dir: std::path::PathBuf,
    /// Whether `--config-dir` was given on the command line (`grip replay`
    /// then uses it instead of the log's configuration).
    pub config_dir_given: bool,
}

/// The value parser of a count of workers (`--threads`, `--jobs`): a
/// whole number of at least 1, refused by clap otherwise (0 used to run 1).
pub fn at_least_one() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(1..)
}
