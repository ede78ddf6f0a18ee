//! `grip inspect --csv DIR`: the log's cycle records, road estimates,
//! ground truth and CAN frames as CSV files (one row per message, times in
//! seconds from the first message of the log, plus the raw ns stamp).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::Context;
use grip_io::can::protocol::spec_for_id;
use grip_msgs::can_dir;

use grip_drive::DriveLog;

fn f(x: f64) -> String {
    if x.is_finite() {
        format!("{x}")
    } else {
        String::new()
    }
}

fn open(dir: &Path, name: &str) -> anyhow::Result<(BufWriter<File>, PathBuf)> {
    let p = dir.join(name);
    let w = File::create(&p).with_context(|| format!("creating {}", p.display()))?;
    Ok((BufWriter::new(w), p))
}

/// First stamp in the log (the time origin of the CSVs).
pub fn t0_ns(log: &DriveLog) -> u64 {
    [
        log.cycles.first().map(|c| c.stamp_ns),
        log.truth.first().map(|c| c.stamp_ns),
        log.roads.first().map(|c| c.stamp_ns),
        log.can.first().map(|c| c.stamp_ns),
    ]
    .into_iter()
    .flatten()
    .min()
    .unwrap_or(0)
}

/// Writes `cycles.csv`, `estimates.csv`, `truth.csv`, `can.csv` into `dir`
/// (created); returns the paths.
pub fn write_csv(log: &DriveLog, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let t0 = t0_ns(log);
    let t = |ns: u64| format!("{:.6}", (ns as i128 - t0 as i128) as f64 * 1e-9);
    let mut out = Vec::new();

    let (mut w, p) = open(dir, "cycles.csv")?;
    writeln!(
        w,
        "t_s,stamp_ns,seq,wakeup_latency_ns,compute_ns,deadline_misses,omega,v,v_valid,torque,demand,torque_cmd,internal,mu_hat,road_class,used_arte,safe_state,faults_crc,faults_counter_repeated,faults_counter_skipped,faults_length,faults_unknown_id,faults_timeout,odometer,torque_cap,belief_road,belief_prob"
    )?;
    for c in &log.cycles {
        let idx = |i: u32| {
            if i == grip_msgs::NO_CLASS {
                String::new()
            } else {
                i.to_string()
            }
        };
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            t(c.stamp_ns),
            c.stamp_ns,
            c.seq,
            c.wakeup_latency_ns,
            c.compute_ns,
            c.deadline_misses,
            f(c.omega),
            f(c.v),
            c.v_valid,
            f(c.torque),
            f(c.demand),
            f(c.torque_cmd),
            f(c.internal),
            f(c.mu_hat),
            if c.road_class == grip_msgs::NO_CLASS {
                String::new()
            } else {
                c.road_class.to_string()
            },
            c.used_arte,
            c.safe_state,
            c.faults.crc,
            c.faults.counter_repeated,
            c.faults.counter_skipped,
            c.faults.length,
            c.faults.unknown_id,
            c.faults.timeout,
            f(c.odometer),
            f(c.torque_cap),
            idx(c.belief_road),
            f(c.belief_prob)
        )?;
    }
    w.flush()?;
    out.push(p);

    let (mut w, p) = open(dir, "estimates.csv")?;
    writeln!(
        w,
        "t_s,stamp_ns,seq,frame_t0_s,frame_t1_s,class_index,class_name,confidence,lambda_opt,mu_peak,alpha,probabilities,x_from,x_to"
    )?;
    for e in &log.roads {
        let n = (e.n_classes as usize).min(e.probabilities.len());
        let probs: Vec<String> = e.probabilities[..n]
            .iter()
            .map(|p| format!("{p}"))
            .collect();
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            t(e.stamp_ns),
            e.stamp_ns,
            e.seq,
            t(e.frame_t0_ns),
            t(e.frame_t1_ns),
            if e.class_index == grip_msgs::NO_CLASS {
                String::new()
            } else {
                e.class_index.to_string()
            },
            e.class_name().unwrap_or(""),
            f(e.confidence),
            f(e.lambda_opt),
            f(e.mu_peak),
            f(e.alpha),
            probs.join(" "),
            f(e.x_from),
            f(e.x_to)
        )?;
    }
    w.flush()?;
    out.push(p);

    let (mut w, p) = open(dir, "truth.csv")?;
    writeln!(
        w,
        "t_s,stamp_ns,seq,road_index,road_name,v,omega,lambda,torque,x,mic_road_index,mic_road_name"
    )?;
    for g in &log.truth {
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{}",
            t(g.stamp_ns),
            g.stamp_ns,
            g.seq,
            g.road_index,
            g.road_name().unwrap_or(""),
            f(g.v),
            f(g.omega),
            f(g.lambda),
            f(g.torque),
            f(g.x),
            g.mic_road_index,
            g.mic_road_name().unwrap_or("")
        )?;
    }
    w.flush()?;
    out.push(p);

    let (mut w, p) = open(dir, "can.csv")?;
    writeln!(w, "t_s,stamp_ns,id,name,direction,dlc,flags,data")?;
    for c in &log.can {
        let data: Vec<String> = c.payload().iter().map(|b| format!("{b:02X}")).collect();
        writeln!(
            w,
            "{},{},0x{:03X},{},{},{},{},{}",
            t(c.stamp_ns),
            c.stamp_ns,
            c.id,
            spec_for_id(c.id).map_or("", |m| m.name),
            if c.direction == can_dir::TX {
                "tx"
            } else {
                "rx"
            },
            c.dlc,
            c.flags,
            data.join(" ")
        )?;
    }
    w.flush()?;
    out.push(p);
    Ok(out)
}
