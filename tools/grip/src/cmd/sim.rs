//! `grip sim`: the six controller variants (MFC, SRC, MTTE, each with and
//! without ARTE) over many seeds on a scenario, reported in the form of the
//! paper's Table V plus traction and energy; optional CSV and PNG output.
//! The simulation itself is `grip-sim`; this file loads the configuration,
//! runs the batch with a progress bar, prints and writes.

mod plot;

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use grip_config::{ConfigDir, ConfigError, parse_toml, read_file};
use grip_sim::report::{self, format_paper_comparison, format_relative, format_table, summarize};
use grip_sim::{
    ArteConfig, ConfusionArte, Job, PerfectArte, RoadEstimator, RunResult, SimSetup, Variant,
    run_batch,
};
use grip_tcs::ControllersConfig;

use super::Ctx;

/// Which road-estimate source the ARTE variants get.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ArteSource {
    /// The true road through the confusion matrix of `arte.toml` (paper Table II).
    Confusion,
    /// The true road, confidence 1 (upper bound of what ARTE can give).
    Perfect,
}

#[derive(clap::Args)]
pub struct Args {
    /// Scenario: a path to a TOML file, or a name under <config-dir>/scenarios.
    #[arg(long, default_value = "paper")]
    scenario: String,
    /// Number of seeds per variant.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    seeds: u64,
    /// First seed (seeds are seed0, seed0 + 1, ...).
    #[arg(long, default_value_t = 1)]
    seed0: u64,
    /// Comma-separated variants: mfc, src, mtte, mfc-arte, src-arte, mtte-arte, or all.
    #[arg(long, default_value = "all")]
    variants: String,
    /// Road-estimate source of the ARTE variants.
    #[arg(long, value_enum, default_value_t = ArteSource::Confusion)]
    arte: ArteSource,
    /// ARTE configuration (default: <config-dir>/arte.toml).
    #[arg(long)]
    arte_config: Option<PathBuf>,
    /// Write summary.csv, traces and plots here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the time series of every seed (default: the first seed only).
    #[arg(long)]
    all_traces: bool,
    /// Worker threads (default: the number of CPUs).
    #[arg(long)]
    threads: Option<usize>,
    /// Plant integration sub-step bound, s (default: the physics crate's 1e-4).
    #[arg(long)]
    max_substep: Option<f64>,
}

/// Everything `grip sim` loads from the configuration directory.
pub struct Loaded {
    /// The validated simulation setup.
    pub setup: SimSetup,
    /// The ARTE configuration (confusion matrix, knowledge rule).
    pub arte: ArteConfig,
    /// The scenario file.
    pub scenario_path: PathBuf,
}

/// Load vehicle, roads, scenario, controllers and ARTE configuration.
pub fn load(
    config_dir: &Path,
    scenario: &str,
    arte_config: Option<&Path>,
) -> anyhow::Result<Loaded> {
    let dir = ConfigDir::new(config_dir);
    let (vehicle, sensors) = dir.vehicle()?;
    let roads = dir.roads()?;
    let scenario_path = dir.scenario_path(scenario);
    let scenario = dir.scenario_with(scenario, &roads)?;
    // grip_config::controllers is not exported yet (see requests.md); this is
    // what its parse_controllers does.
    let cpath = dir.file("controllers.toml");
    let controllers: ControllersConfig = parse_toml(&cpath, &read_file(&cpath)?)?;
    controllers
        .validate()
        .map_err(|e| ConfigError::invalid(&cpath, "", e))?;
    let apath = arte_config.map_or_else(|| dir.file("arte.toml"), Path::to_owned);
    let arte: ArteConfig = parse_toml(&apath, &read_file(&apath)?)?;
    arte.validate(&roads)
        .map_err(|e| ConfigError::new(&apath, e.field(), reason_of(&e)))?;
    let setup = SimSetup::new(
        vehicle,
        sensors,
        roads,
        scenario,
        controllers,
        &arte.knowledge,
    )
    .map_err(|e| anyhow::anyhow!("{}: {e}", scenario_path.display()))?;
    Ok(Loaded {
        setup,
        arte,
        scenario_path,
    })
}

fn reason_of(e: &grip_sim::SimError) -> String {
    match e {
        grip_sim::SimError::Invalid { reason, .. } => reason.clone(),
    }
}

pub fn run(ctx: &Ctx, args: Args) -> anyhow::Result<()> {
    let variants = Variant::parse_list(&args.variants)?;
    let mut loaded = load(&ctx.config_dir, &args.scenario, args.arte_config.as_deref())?;
    if let Some(h) = args.max_substep {
        loaded.setup.set_max_substep(h).context("--max-substep")?;
    }
    let setup = &loaded.setup;
    let seeds: Vec<u64> = (0..args.seeds)
        .map(|i| {
            args.seed0
                .checked_add(i)
                .context("--seed0 + --seeds overflows u64")
        })
        .collect::<anyhow::Result<_>>()?;
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);
    let jobs = Job::grid(&variants, &seeds, args.all_traces);

    // One estimator prototype, checked now; each worker clones it.
    let confusion = ConfusionArte::new(&loaded.arte.confusion, setup.roads())
        .map_err(|e| anyhow::anyhow!("{}", e))?;
    let frame_s = loaded.arte.confusion.frame_s;
    let source = args.arte;
    let make = move || -> Box<dyn RoadEstimator> {
        match source {
            ArteSource::Confusion => Box::new(confusion.clone()),
            ArteSource::Perfect => Box::new(PerfectArte::new(frame_s)),
        }
    };

    let sc = setup.scenario();
    eprintln!(
        "scenario `{}` ({}): {:.2} s, {} cycles at {} Hz, plant sub-step <= {:.0e} s; {} variants x {} seeds on {} threads; ARTE source: {:?}",
        sc.name,
        loaded.scenario_path.display(),
        setup.sim_time(),
        setup.cycles(),
        setup.controllers().loop_.rate_hz,
        setup.max_substep(),
        variants.len(),
        seeds.len(),
        threads,
        source
    );
    let bar = indicatif::ProgressBar::new(jobs.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} runs {elapsed_precise}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let started = Instant::now();
    let results = run_batch(setup, &jobs, threads, &make, &|_r| bar.inc(1))
        .map_err(|e| anyhow::anyhow!("simulation setup: {e}"))?;
    let wall = started.elapsed().as_secs_f64();
    bar.finish_and_clear();

    let summaries = summarize(&results);
    let mut out = String::new();
    out.push_str(&format!(
        "\nScenario `{}`: {}\n{} seeds ({}..={}), mean ± std over seeds; ARTE source: {:?}.\n\
         slip dev. = (1/T) ∫|λ| dt; max torque = max |T|; effort = (1/T) ∫|T| dt (the paper's \"normalised area\", N m);\n\
         mean accel = ΔV / T; ∫Tω dt = motor energy at the wheel; ΔKE = kinetic energy gained (one wheel's share, M/n).\n\n",
        sc.name,
        sc.description,
        seeds.len(),
        seeds[0],
        seeds[seeds.len() - 1],
        source
    ));
    out.push_str(&format_table(&summaries));
    out.push('\n');
    out.push_str(&format_relative(&summaries));
    out.push_str("\nOurs (means) beside the paper's Table V (its scenario is not published; ours is documented above):\n");
    out.push_str(&format_paper_comparison(&summaries));
    let unhealthy: usize = summaries.iter().map(|s| s.unhealthy_runs).sum();
    if unhealthy > 0 {
        out.push_str(&format!(
            "\nWARNING: {unhealthy} runs had a non-finite plant state or rejected metric samples (see summary.csv).\n"
        ));
    }
    let simulated = setup.sim_time() * results.len() as f64;
    out.push_str(&format!(
        "\n{} runs, {:.1} simulated s in {:.2} s wall ({:.0}x real time on {} threads).\n",
        results.len(),
        simulated,
        wall,
        simulated / wall.max(1e-9),
        threads
    ));
    print!("{out}");

    if let Some(dir) = &args.out {
        write_outputs(dir, setup, &results, &out)?;
        eprintln!("wrote {}", dir.display());
    }
    Ok(())
}

fn create(path: &Path) -> anyhow::Result<BufWriter<File>> {
    Ok(BufWriter::new(File::create(path).with_context(|| {
        format!("cannot create {}", path.display())
    })?))
}

fn write_outputs(
    dir: &Path,
    setup: &SimSetup,
    results: &[RunResult],
    table: &str,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let p = dir.join("summary.csv");
    let mut w = create(&p)?;
    report::write_summary_csv(&mut w, results)
        .with_context(|| format!("writing {}", p.display()))?;
    w.flush()
        .with_context(|| format!("writing {}", p.display()))?;
    let p = dir.join("table.txt");
    std::fs::write(&p, table).with_context(|| format!("writing {}", p.display()))?;
    let names: Vec<&str> = setup.roads().iter().map(|r| r.name()).collect();
    for r in results {
        if let Some(tr) = &r.trace {
            let p = dir.join(format!("trace_{}_seed{}.csv", r.variant.name(), r.seed));
            let mut w = create(&p)?;
            tr.write_csv(&mut w, &names)
                .and_then(|()| w.flush())
                .with_context(|| format!("writing {}", p.display()))?;
        }
    }
    // Figures for the first seed that has traces.
    let Some(first) = results.iter().find(|r| r.trace.is_some()).map(|r| r.seed) else {
        return Ok(());
    };
    for (arte, file, title) in [
        (false, "fig10_without_arte.png", "without ARTE"),
        (true, "fig11_with_arte.png", "with ARTE"),
    ] {
        let runs: Vec<&RunResult> = results
            .iter()
            .filter(|r| r.seed == first && r.variant.arte == arte && r.trace.is_some())
            .collect();
        if runs.is_empty() {
            continue;
        }
        let p = dir.join(file);
        plot::figure(
            &p,
            setup,
            &runs,
            &format!(
                "{title}, scenario `{}`, seed {first}",
                setup.scenario().name
            ),
        )
        .map_err(|e| anyhow::anyhow!("drawing {}: {e}", p.display()))?;
    }
    Ok(())
}
