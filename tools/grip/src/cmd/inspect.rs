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
    /// off.mcap`); or a directory of logs (one row per drive, then the
    /// drives with ARTE on and off of one scenario, controller, vehicle and
    /// seed paired: the ratios on/off).
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
    /// entries, E2E faults, command timeouts, the inverter's episodes
    /// (`tools/grip/README.md`,
    /// "grip inspect --json"). A bad log gives an object whose `status` says
    /// why (exit status 0 unless --strict).
    #[arg(long, conflicts_with_all = ["csv", "plot"])]
    json: bool,
    /// One log: write its vehicle-bus log (channel `grip/can/bus`) to this
    /// file in candump's log format, `(epoch.micros) IFACE ID#DATA`, which
    /// can-utils' `canplayer`, python-can and SavvyCAN read. The times are
    /// wall time from the log's `grip.clock` record (else seconds since
    /// boot, and the command says so). The bus log holds the frames that
    /// are not grip's own unless recorder.toml says `bus = "all"`; grip's
    /// own are in `grip/can/log` (`--csv`: can.csv).
    #[arg(long, conflicts_with = "json")]
    candump: Option<PathBuf>,
    /// Overwrite what `--csv`, `--plot` and `--candump` would replace (an
    /// existing file is refused without it, before the log is read).
    #[arg(long)]
    force: bool,
}

/// The files `--csv DIR` of one log writes (`export::write_csv`).
const CSV_FILES: [&str; 4] = ["cycles.csv", "estimates.csv", "truth.csv", "can.csv"];
/// The files `--plot DIR` writes (`plot::write_plots`).
const PLOT_FILES: [&str; 2] = ["drive.png", "timing.png"];

/// `flag DIR` (created) of files named `files`: refused, naming them, when
/// DIR is no directory, or when any of them is there already and not
/// `force`.
fn check_output_dir(
    flag: &str,
    dir: &std::path::Path,
    files: &[&str],
    force: bool,
) -> anyhow::Result<()> {
    if std::fs::symlink_metadata(dir).is_ok() && !dir.is_dir() {
        anyhow::bail!(
            "{flag} {}: is a file, not a directory; {flag} names a directory for {}",
            dir.display(),
            files.join(", ")
        );
    }
    let there: Vec<&str> = files
        .iter()
        .copied()
        .filter(|f| std::fs::symlink_metadata(dir.join(f)).is_ok())
        .collect();
    if !force && !there.is_empty() {
        anyhow::bail!(
            "{flag} {}: {} already there; pass --force to overwrite, or name another directory",
            dir.display(),
            there.join(", ")
        );
    }
    Ok(())
}

/// The summary of the log at `path`, with the vehicle the drive ran with
/// and its road catalogue (for the preview report: the log's attached
/// `roads.toml`, else the configuration directory's with a warning).
fn summary_of(
    ctx: &Ctx,
    path: &std::path::Path,
) -> anyhow::Result<(DriveLog, f64, summary::Summary)> {
    let log = crate::drive::load_log(path, Default::default())?;
    let (vehicle, from, warnings) = drive::vehicle_for(&log, &ctx.config_dir);
    for w in warnings {
        eprintln!("{w}");
    }
    // the log's own road catalogue (its warnings go into the summary)
    let roads = log.road_catalogue(&ctx.config_dir);
    let s = summary::summarize_with_roads(&log, &vehicle, &from, &roads);
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
        if args.plot.is_some() || args.candump.is_some() {
            anyhow::bail!(
                "{} is a directory of logs: --plot and --candump take one log (a directory gives its per-drive table; --csv writes it)",
                dir.display()
            );
        }
        if let Some(f) = &args.csv {
            super::train::check_output_file("--csv", f, args.force)?;
        }
        return crate::drive::many::inspect_dir(ctx, dir, args.csv.as_deref(), args.strict);
    }
    if args.strict && args.logs.iter().all(|p| p.exists()) {
        anyhow::bail!(
            "--strict takes a directory of logs (or --json), where it fails the command on any bad log; it does nothing for one log or two"
        );
    }
    if let [a, b] = args.logs.as_slice() {
        // A B compares two logs; a directory here would be read as one
        if let Some(d) = [a, b].into_iter().find(|p| p.is_dir()) {
            anyhow::bail!(
                "{} is a directory: `grip inspect A B` compares two logs; a directory of logs is inspected alone (`grip inspect DIR`), or with --json together with other logs and directories",
                d.display()
            );
        }
        if args.csv.is_some() || args.plot.is_some() || args.candump.is_some() {
            anyhow::bail!(
                "--csv, --plot and --candump take one log (got two: {} and {})",
                a.display(),
                b.display()
            );
        }

        let (_, _, sa) = summary_of(ctx, a)?;
        let (_, _, sb) = summary_of(ctx, b)?;
        println!("{}", summary::compare(&sa, &sb));
        return Ok(());
    }
    // the outputs, before the log is read
    if let Some(f) = &args.candump {
        super::train::check_output_file("--candump", f, args.force)?;
    }
    if let Some(d) = &args.csv {
        check_output_dir("--csv", d, &CSV_FILES, args.force)?;
    }
    if let Some(d) = &args.plot {
        check_output_dir("--plot", d, &PLOT_FILES, args.force)?;
    }
    let (log, r, s) = summary_of(ctx, &args.logs[0])?;
    print!("{}", report(&log, &s));
    if let Some(file) = &args.candump {
        write_candump(&log, file)?;
    }
    if let Some(dir) = &args.csv {
        for p in export::write_csv(&log, dir)? {
            println!("wrote {}", p.display());
        }
    }
    if let Some(dir) = &args.plot {
        for p in plot::write_plots(&log, dir, r, s.vehicle_params.v_eps)? {
            println!("wrote {}", p.display());
        }
    }
    Ok(())
}

/// `--candump FILE`: the bus log in candump's log format; says how many
/// frames and how their times were placed. A log without a bus log is an
/// error (an empty file would look like a silent bus).
fn write_candump(log: &DriveLog, file: &std::path::Path) -> anyhow::Result<()> {
    use anyhow::Context as _;
    if !drive::bus::has_bus(log) {
        anyhow::bail!(
            "{}: no bus log in this drive (channel {} absent: a recorder before the bus log, or bus = \"off\"); {} not written",
            log.path.display(),
            grip_msgs::topics::BUS,
            file.display()
        );
    }
    let f = std::fs::File::create(file).with_context(|| format!("creating {}", file.display()))?;
    let mut w = std::io::BufWriter::new(f);
    let clock = drive::bus::write_candump(log, &mut w)
        .and_then(|c| std::io::Write::flush(&mut w).map(|()| c))
        .with_context(|| format!("writing {}", file.display()))?;
    let how = match clock {
        drive::bus::WallClock::FromLog => "wall time from the log's grip.clock record",
        drive::bus::WallClock::Monotonic => {
            "the log has no grip.clock record: times are seconds since boot (CLOCK_MONOTONIC), not dates"
        }
    };
    println!(
        "wrote {} ({} frames, candump log format; {how})",
        file.display(),
        log.bus.len()
    );
    if let Some(note) = empty_bus_note(log) {
        println!("{note}");
    }
    Ok(())
}

/// Why a bus log without frames can be right: by default the recorder
/// keeps only frames that are not grip's own, and on a bus with nothing
/// else on it (a simulated drive's) that is none; grip's own frames are
/// in the loop's CAN log. None when the bus log has frames.
fn empty_bus_note(log: &DriveLog) -> Option<String> {
    if !log.bus.is_empty() {
        return None;
    }
    Some(format!(
        "note: the bus log holds no frame: the recorder keeps only frames that are not grip's own unless recorder.toml says bus = \"all\" (default \"foreign\"), and nothing else was on this bus; grip's own {} frames are in channel {}, with the loop's stamps (`grip inspect LOG --csv DIR` writes them to can.csv)",
        log.can.len(),
        grip_msgs::topics::CAN_LOG
    ))
}

/// The report of one log, as `grip inspect LOG` prints it and `grip drive`
/// after its drive (the same code): the summary, the wake-up latency
/// histogram, the road timeline and the vehicle bus section (when the log
/// has a bus log).
pub fn report(log: &DriveLog, s: &summary::Summary) -> String {
    format!(
        "{}\nloop wake-up latency histogram:\n{}\n{}\n{}",
        s.render(),
        summary::latency_histogram(&s.timing.wakeup_ns),
        road_timeline(log),
        drive::bus::render(log).unwrap_or_default()
    )
}

/// The road timeline: a header, then one line per 0.1 s (on the grid of
/// the scenario start when the log shows it, else of the first message):
/// the road under the driven wheel, the road at the microphone, and the
/// latest ARTE class published by then, marked when it is not the road at
/// the microphone (what ARTE hears; ahead of the wheel on a front-mic car).
pub fn road_timeline(log: &DriveLog) -> String {
    let tb = export::TimeBase::of(log);
    let (Some(first), Some(last)) = (log.truth.first(), log.truth.last()) else {
        return "road timeline: none (no ground truth in the log)\n".into();
    };
    let mut out = format!(
        "road timeline (every 0.1 s; {}):\n  wheel: the road under the driven wheel; microphone: the road at the microphone, which ARTE hears and is judged against; ARTE: the latest estimate published by then (\"late\": right for the audio frame it heard, but the microphone has reached another road since)\n",
        if tb.scenario_ns.is_some() {
            "t from the scenario start, negative while plant-sim held the vehicle and during the pre-roll if any"
        } else {
            "t from the first message of the log: the ground truth does not show the scenario start"
        }
    );
    out.push_str(&format!(
        "  {:>7}    {:<12} {:<12} ARTE\n",
        "t", "wheel", "microphone"
    ));
    const STEP: i128 = 100_000_000;
    let origin = i128::from(tb.origin_ns());
    let name = |n: Option<&str>| n.unwrap_or("?").to_owned();
    // the first grid time at or after the first sample
    let mut k = (i128::from(first.stamp_ns) - origin).div_euclid(STEP);
    if origin + k * STEP < i128::from(first.stamp_ns) {
        k += 1;
    }
    let mut next_est = 0usize;
    let mut latest: Option<&grip_msgs::RoadEstimate> = None;
    // a row per 0.1 s cannot outnumber the samples of a log the plant
    // wrote (it samples far more often; twice, to spare any rate): more
    // means a stamp far from the others (a damaged log printed 10 million
    // rows, or ran out of memory)
    let mut rows_left = 2 * log.truth.len() + 10;
    while origin + k * STEP <= i128::from(last.stamp_ns) {
        if rows_left == 0 {
            out.push_str(&format!(
                "  ... the timeline stops here: the ground truth's {} samples span {:.1} s ({} to {} ns), more than two rows per sample: a stamp lies far from the others\n",
                log.truth.len(),
                (i128::from(last.stamp_ns) - i128::from(first.stamp_ns)) as f64 * 1e-9,
                first.stamp_ns,
                last.stamp_ns
            ));
            break;
        }
        rows_left -= 1;
        let t = u64::try_from(origin + k * STEP).unwrap_or(0);
        while let Some(e) = log.roads.get(next_est)
            && e.stamp_ns <= t
        {
            latest = Some(e);
            next_est += 1;
        }
        let g = summary::truth_at(&log.truth, t);
        let wheel = name(g.and_then(|g| g.road_name()));
        let mic = name(g.and_then(|g| g.mic_road_name()));
        let est = latest
            .filter(|e| e.class_index != grip_msgs::NO_CLASS)
            .map(|e| name(e.class_name()));
        let mark = match (&est, latest) {
            (Some(est), Some(e)) if *est != mic => {
                // what the microphone heard during the estimate's frame
                let mid = summary::frame_mid_ns(e);
                let heard = summary::truth_at(&log.truth, mid).map(|g| name(g.mic_road_name()));
                if heard.as_deref() == Some(est.as_str()) {
                    "  <- differs (late)"
                } else {
                    "  <- differs"
                }
            }
            _ => "",
        };
        let line = format!(
            "  {:>7.1} s  {:<12} {:<12} {:<12}{mark}",
            (k * STEP) as f64 * 1e-9,
            wheel,
            mic,
            est.as_deref().unwrap_or("-"),
        );
        out.push_str(line.trim_end());
        out.push('\n');
        k += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use crate::drive::export::test_log;

    /// An empty bus log says where grip's own frames are; one with frames
    /// says nothing more.
    #[test]
    fn an_empty_bus_log_points_to_grips_own_frames() {
        let mut log = super::DriveLog {
            can: vec![grip_msgs::CanFrame::new(0x123, &[1]); 7],
            ..super::DriveLog::default()
        };
        let note = super::empty_bus_note(&log).unwrap();
        assert!(
            note.contains("grip's own 7 frames are in channel grip/can/log")
                && note.contains("bus = \"all\""),
            "{note}"
        );
        log.bus.push(grip_msgs::BusFrame::default());
        assert_eq!(super::empty_bus_note(&log), None);
    }

    /// A ground-truth stamp far from the others (a damaged log): the
    /// timeline stops after twice as many rows as samples, and says why (it
    /// printed a row per 0.1 s up to the stamp: 10 million rows).
    #[test]
    fn a_far_stamp_stops_the_timeline() {
        let mut log = test_log::drive();
        let n = log.truth.len();
        log.truth.last_mut().unwrap().stamp_ns += 1_000_000_000_000_000;
        let t = super::road_timeline(&log);
        assert!(
            t.lines().count() < 2 * n + 20,
            "{} lines",
            t.lines().count()
        );
        assert!(
            t.trim_end()
                .ends_with("more than two rows per sample: a stamp lies far from the others"),
            "{}",
            &t[t.len().saturating_sub(300)..]
        );
        // an undamaged log: no such line
        assert!(!super::road_timeline(&test_log::drive()).contains("stops here"));
    }

    /// The row of time `t` ("0.3 s") of a road timeline.
    fn row<'a>(timeline: &'a str, t: &str) -> &'a str {
        timeline
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{t} s ")))
            .unwrap_or_else(|| panic!("no row at {t} s in\n{timeline}"))
    }

    /// ARTE is judged against the road at the microphone: on a front-mic
    /// car the microphone reaches snow 2 m before the driven wheel, and a
    /// right estimate of snow while the wheel is still on asphalt is not
    /// marked; a wrong one (asphalt while the microphone hears snow, the
    /// wheel still on asphalt) is.
    #[test]
    fn the_timeline_judges_arte_by_the_road_at_the_microphone() {
        let log = test_log::drive();
        let tl = super::road_timeline(&log);
        // 0.0 s: wheel on asphalt, microphone on snow, ARTE says snow
        let r = row(&tl, "0.0");
        assert!(r.contains("snow"), "{r}");
        assert!(!r.contains("differs"), "a right estimate marked: {r}\n{tl}");
        // 0.3 s: the wrong estimate (published at 0.23 s), wheel on asphalt
        let r = row(&tl, "0.3");
        assert!(r.contains("asphalt"), "{r}");
        assert!(
            r.contains("<- differs") && !r.contains("late"),
            "a wrong estimate not marked: {r}\n{tl}"
        );
        // both roads are shown: the wheel on asphalt, the microphone on snow
        let cols: Vec<&str> = r.split_whitespace().collect();
        assert_eq!(
            &cols[..5],
            ["0.3", "s", "asphalt", "snow", "asphalt"],
            "{r}"
        );
        // -0.5 s: the microphone has just reached snow; the latest estimate
        // heard asphalt, rightly: late, not wrong
        let r = row(&tl, "-0.5");
        assert!(r.contains("<- differs (late)"), "{r}\n{tl}");
        // the rows are on the grid of the scenario start, which the header
        // names
        assert!(tl.contains("t from the scenario start"), "{tl}");
        assert!(
            tl.lines().any(|l| l.trim_start().starts_with("-1.2 s ")),
            "{tl}"
        );
    }

    #[test]
    fn the_timeline_without_ground_truth_says_so() {
        let tl = super::road_timeline(&test_log::drive_without_truth());
        assert!(tl.contains("no ground truth"), "{tl}");
    }
}
