//! `grip inspect LOG`: the summary `grip drive` prints, for any drive log,
//! with the loop-timing histogram, the road timeline, `--csv DIR` and
//! `--plot DIR`. A truncated log gives a partial summary that says what was
//! lost; a file that is not MCAP gives a clear error. `grip inspect A B`:
//! the two drives' slip, traction, torque and energy side by side (B / A)
//! and what each one's torque did before the wheel reached a road that
//! carries less.

use std::path::PathBuf;

use super::Ctx;
use crate::drive::{export, plot};
use grip_drive::{self as drive, DriveLog, summary};

#[derive(clap::Args)]
pub struct Args {
    /// The MCAP log (from `grip drive` or the recorder service); with a
    /// second log, the two side by side (e.g. `grip inspect on.mcap
    /// off.mcap`); or a directory of logs (one row per drive).
    #[arg(required = true, num_args = 1..=2)]
    logs: Vec<PathBuf>,
    /// One log: write cycles.csv, estimates.csv, truth.csv and can.csv into
    /// this directory. A directory of logs: write the per-drive table to
    /// this CSV file.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Write drive.png and timing.png here (one log only).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// A directory of logs: exit with status 1 if any log is bad
    /// (unreadable, truncated, or damaged).
    #[arg(long)]
    strict: bool,
    /// One JSON object per log on stdout, one per line (JSON Lines):
    /// run metadata, metrics, ARTE accuracy per road and per speed band,
    /// confusion counts, detection delays, deadline misses, safe-state
    /// entries, E2E faults, command timeouts (`tools/grip/README.md`,
    /// "grip inspect --json"). A bad log gives an object whose `status` says
    /// why (exit status 0 unless --strict).
    #[arg(long, conflicts_with_all = ["csv", "plot"])]
    json: bool,
}

/// The summary of the log at `path`, with the vehicle the drive ran with
/// and the configuration directory's road catalogue (for the preview
/// report; without it, a warning and no preview report).
fn summary_of(
    ctx: &Ctx,
    path: &std::path::Path,
) -> anyhow::Result<(DriveLog, f64, summary::Summary)> {
    let log = DriveLog::load(path)?;
    let (vehicle, from, warnings) = drive::vehicle_for(&log, &ctx.config_dir);
    for w in warnings {
        eprintln!("{w}");
    }
    let roads = match grip_config::ConfigDir::new(&ctx.config_dir).roads() {
        Ok(r) => Some(r),
        Err(e) => {
            eprintln!("warning: {e}; no preview report");
            None
        }
    };
    let s = summary::summarize(&log, &vehicle, &from, roads.as_ref());
    Ok((log, vehicle.r, s))
}

pub fn run(ctx: &Ctx, args: Args) -> anyhow::Result<()> {
    if args.json {
        let mut paths = Vec::new();
        for p in &args.logs {
            if p.is_dir() {
                paths.extend(crate::drive::many::logs_in(p)?);
            } else {
                paths.push(p.clone());
            }
        }
        let mut bad = 0usize;
        for p in &paths {
            let v = crate::drive::json::log_json(p, &ctx.config_dir);
            bad += usize::from(v["status"] != "ok");
            println!("{v}");
        }
        if args.strict && bad > 0 {
            anyhow::bail!("{bad} of {} logs are bad (--strict)", paths.len());
        }
        return Ok(());
    }
    if let [dir] = args.logs.as_slice()
        && dir.is_dir()
    {
        return crate::drive::many::inspect_dir(ctx, dir, args.csv.as_deref(), args.strict);
    }
    if let [a, b] = args.logs.as_slice() {
        if args.csv.is_some() || args.plot.is_some() {
            anyhow::bail!(
                "--csv and --plot take one log (got two: {} and {})",
                a.display(),
                b.display()
            );
        }
        let (_, _, sa) = summary_of(ctx, a)?;
        let (_, _, sb) = summary_of(ctx, b)?;
        println!("{}", summary::compare(&sa, &sb));
        return Ok(());
    }
    let (log, r, s) = summary_of(ctx, &args.logs[0])?;
    println!("{}", s.render());
    println!(
        "loop wake-up latency histogram:\n{}",
        summary::latency_histogram(&s.timing.wakeup_ns)
    );
    println!(
        "road timeline (ground truth vs the latest ARTE estimate, every 0.1 s; t from the scenario start, negative while plant-sim held the vehicle):"
    );
    println!("{}", road_timeline(&log));
    if let Some(dir) = &args.csv {
        for p in export::write_csv(&log, dir)? {
            println!("wrote {}", p.display());
        }
    }
    if let Some(dir) = &args.plot {
        let title = format!(
            "grip drive: {}, ARTE {}, scenario {}",
            log.run
                .get("controller")
                .map_or("?", String::as_str)
                .to_uppercase(),
            log.run.get("arte").map_or("?", String::as_str),
            log.run.get("scenario").map_or("?", String::as_str)
        );
        for p in plot::write_plots(&log, dir, r, &title)? {
            println!("wrote {}", p.display());
        }
    }
    Ok(())
}

/// One line per 0.1 s: true road and the latest ARTE class published by then.
pub fn road_timeline(log: &DriveLog) -> String {
    let Some(first) = log.truth.first() else {
        return "  (no ground truth in the log)".into();
    };
    let last = log.truth.last().map_or(first.stamp_ns, |g| g.stamp_ns);
    let origin = summary::scenario_start(&log.truth)
        .and_then(|i| log.truth.get(i))
        .map_or(first.stamp_ns, |g| g.stamp_ns);
    let mut out = String::new();
    let step = 100_000_000u64;
    let mut t = first.stamp_ns;
    let mut k_est = 0usize;
    let mut latest: Option<String> = None;
    while t <= last {
        while k_est < log.roads.len() && log.roads[k_est].stamp_ns <= t {
            let e = &log.roads[k_est];
            latest = (e.class_index != grip_msgs::NO_CLASS)
                .then(|| e.class_name().unwrap_or("?").to_owned());
            k_est += 1;
        }
        let truth = summary::truth_at(&log.truth, t)
            .and_then(|g| g.road_name().map(str::to_owned))
            .unwrap_or_else(|| "?".into());
        let est = latest.clone().unwrap_or_else(|| "-".into());
        let mark = if est == truth { "" } else { "  <- differs" };
        out.push_str(&format!(
            "  {:>7.1} s  truth {:<10} ARTE {:<10}{mark}\n",
            (t as i128 - origin as i128) as f64 * 1e-9,
            truth,
            est
        ));
        t += step;
    }
    out
}
