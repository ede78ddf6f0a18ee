//! An independent check of `grip sim`'s `summary.csv`, the figures of the
//! project's results tables: Python recomputes them from the per-run traces
//! that `grip sim --out DIR --all-traces` writes
//! (`trace_<variant>_seed<s>.csv`), written from the definitions as the
//! READMEs give them (`crates/sim/README.md`, "The loop" (Metrics),
//! "Outputs of grip sim --out DIR", "A smooth command"; `crates/tcs/README.md`,
//! "Metrics"), not from grip's code, and each is compared with grip's.
//!
//! Recomputed from the traces, per (variant, seed): `slip_deviation`
//! (1/T)Σ|λ|dt, `max_torque` max|T|, `torque_effort` (1/T)Σ|T|dt,
//! `mean_accel` (V_last − V_first)/(time between their starts), `distance`
//! Σ V dt, `energy` Σ Tω dt, `kinetic_energy_gain` ½(M/n)ΔV² + ½J_wΔω²
//! (M, n and J_w from the vehicle file), `duration` Σ dt, `samples`,
//! `rejected`, `non_finite_cycles`, `cmd_tv_per_s` Σ|ΔT*|/T_cmd, `cmd_hf_rms`
//! and `cmd_hf_share` (the command through a 4th-order Butterworth high-pass
//! at 20 Hz: two biquads, bilinear transform with the cut-off pre-warped,
//! started at rest on the first command; its mean-square over the
//! command's variance), `arte_usage` (the share of cycles with `used_arte`),
//! and `arte_frames` (one decision per 0.1 s frame of the confusion source
//! in an ARTE run, none otherwise).
//!
//! Not in the traces, so checked otherwise:
//! - `final_speed_kmh` is V at T, one plant step past the trace's last row
//!   (V at T − dt): compared with the linear extrapolation 2 V(T − dt) −
//!   V(T − 2dt) within a tenth of the last cycle's speed change (measured:
//!   at most 0.5 % of it on these runs; V(T − dt) itself, or km/h read as
//!   m/s, is 100 % of it or more off).
//! - `arte_accuracy` judges the estimator's decisions, which the trace does
//!   not hold (its `est_road` is the fused belief). With the microphone at
//!   the wheel it is compared with the in-loop probe's `arte_inloop.csv`
//!   (correct / decisions, "(= summary.csv's arte_accuracy)" in "ARTE in
//!   the loop"), and `arte_frames` with its decisions; with a lead the
//!   probe also counts the pre-roll's decisions (33 against 24 on the
//!   front-mic car), so there only accuracy × frames must be a whole number
//!   in 0..=frames.
//!
//! The printed table (`table.txt`): every "mean ± std" of the first table
//! and every "ARTE vs base" change is compared with Python's means and
//! sample standard deviations (n − 1) of its own figures (V end and ARTE
//! acc. from `summary.csv`), within half a unit of the printed last digit.
//!
//! Two points the READMEs left open were settled by reading the Rust
//! (`crates/sim/README.md`, "Outputs", states them since):
//! `arte_usage` is used cycles over cycles (`crates/sim/src/sim.rs`,
//! `ArteStats::usage`; the READMEs name the column only), and the table's
//! "± std" is the sample standard deviation (`crates/sim/src/report.rs`,
//! `Stat::of`). "At rest on the first command" (the high-pass's start) is
//! read as the state of a constant input equal to it (output 0), as
//! `crates/tcs/src/metrics.rs`'s module doc says; a filter started from a
//! zero state would see a 300 N m step at t = 0.
//!
//! Tolerance: counts exactly; every other figure within a relative 1e-10
//! (and 1e-12 absolute). The traces are written in shortest round-trip
//! form, so Python reads the very doubles grip summed: every figure but
//! the two of the high-pass agrees bit for bit; those, a recursive filter
//! of another form, within 6e-14 (measured). Sums of 2400 terms in another
//! order could differ by up to n ε ≈ 3e-13 of their magnitude. Any alternative
//! reading of a definition moves a figure by far more: one cycle more or
//! less in a time or a sum is 1/2400 ≈ 4e-4.
//!
//! Runs: the six variants on the reference scenario (seeds 1-2) on the
//! paper's car and the front-mic car, and on one random road sequence
//! (seed 1000) on each; debug build, about 3 s of `grip sim` each.

use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

/// The recomputation: argument 1 the `--out` directory, argument 2 the
/// vehicle file; prints `RESULT {json}`.
const RECOMPUTE: &str = r##"
import csv, glob, json, math, os, re, sys
try:
    import tomllib
except ImportError as e:
    print(f"python 3.11 or later needed (tomllib: {e})")
    sys.exit(3)

out_dir, vehicle_file = sys.argv[1], sys.argv[2]
with open(vehicle_file, "rb") as f:
    veh = tomllib.load(f)["vehicle"]
M_n = veh["mass"] / veh["n_driven"]  # one driven wheel's share of the car
J_w = veh["j_w"]
lead0 = veh.get("mic_lead_m", 0.0) == 0  # the microphone at the driven wheel
FRAME_S = 0.1  # the confusion source's frame: one decision per 0.1 s
FC = 20.0  # the command's high-pass cut-off, Hz


def num(s):
    return float(s) if s != "" else math.nan


def butterworth_hp(dt):
    # 4th order = two biquads s^2 / (s^2 + (w/Q) s + w^2), Q = 1 / (2 cos th),
    # th = pi/8 and 3 pi/8 (the Butterworth poles); bilinear transform with the
    # cut-off pre-warped: K = tan(w dt / 2) = tan(pi fc dt)
    K = math.tan(math.pi * FC * dt)
    out = []
    for th in (math.pi / 8, 3 * math.pi / 8):
        Q = 1 / (2 * math.cos(th))
        g = 1 / (1 + K / Q + K * K)
        out.append((g, -2 * g, g, 2 * (K * K - 1) * g, (1 - K / Q + K * K) * g))
    return out


def run_figures(path, arte):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    t = [float(r["t"]) for r in rows]
    dt = t[1] - t[0]
    # one row per cycle, t = k dt (dt = 1 / rate_hz is not in the trace: this
    # is what makes t[1] - t[0] the dt of every sample)
    bad = [k for k in range(len(t)) if abs(t[k] - k * dt) > 1e-9 * max(1.0, t[k])]
    assert not bad, f"{path}: t is not k dt at rows {bad[:5]}"
    v = [float(r["v"]) for r in rows]
    w = [float(r["omega"]) for r in rows]
    lam = [float(r["lambda"]) for r in rows]
    T = [float(r["torque"]) for r in rows]
    cmd = [num(r["torque_cmd"]) for r in rows]
    used = [int(r["used_arte"]) for r in rows]
    # a sample is used when its values (lambda, T, omega, V) are finite; dt > 0
    # throughout; non-finite plant state: V, omega or T
    ok = [k for k in range(len(rows)) if all(math.isfinite(x) for x in (lam[k], T[k], w[k], v[k]))]
    o = {"cycles": len(rows), "samples": len(ok), "rejected": len(rows) - len(ok)}
    o["non_finite_cycles"] = sum(1 for k in range(len(rows))
                                 if not all(math.isfinite(x) for x in (v[k], w[k], T[k])))
    T_run = 0.0
    for k in ok:
        T_run += dt  # T_run = sum of dt (tcs README, Metrics)
    o["duration"] = T_run
    o["slip_deviation"] = sum(abs(lam[k]) * dt for k in ok) / T_run
    o["max_torque"] = max(abs(T[k]) for k in ok)
    o["torque_effort"] = sum(abs(T[k]) * dt for k in ok) / T_run
    first, last = ok[0], ok[-1]
    span = 0.0
    for k in range(first, last):
        span += dt  # the time between the first and the last sample's starts
    o["mean_accel"] = (v[last] - v[first]) / span
    o["distance"] = sum(v[k] * dt for k in ok)
    o["energy"] = sum(T[k] * w[k] * dt for k in ok)
    o["kinetic_energy_gain"] = (0.5 * M_n * (v[last] ** 2 - v[first] ** 2)
                                + 0.5 * J_w * (w[last] ** 2 - w[first] ** 2))
    # the command's figures: the samples that carry a finite command
    c = [cmd[k] for k in range(len(rows)) if math.isfinite(cmd[k])]
    T_cmd = 0.0
    for _ in c:
        T_cmd += dt
    o["cmd_tv_per_s"] = sum(abs(c[i] - c[i - 1]) for i in range(1, len(c))) / T_cmd
    # y = the command through the high-pass, started at rest on the first
    # command (its state that of a constant input c[0]: first section's inputs
    # c[0], outputs 0; the second's all 0)
    secs = butterworth_hp(dt)
    st = [[c[0], c[0], 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]  # x1 x2 y1 y2
    e = 0.0
    for x in c:
        for s, (b0, b1, b2, a1, a2) in zip(st, secs):
            y = b0 * x + b1 * s[0] + b2 * s[1] - a1 * s[2] - a2 * s[3]
            s[:] = [x, s[0], y, s[2]]
            x = y
        e += x * x * dt
    o["cmd_hf_rms"] = math.sqrt(e / T_cmd)
    mean = sum(x * dt for x in c) / T_cmd
    var = sum((x - mean) ** 2 * dt for x in c) / T_cmd
    o["cmd_hf_share"] = (e / T_cmd) / var if var > 0 else 0.0
    # the cycles in which the controller used the road knowledge, of all
    # (crates/sim/src/sim.rs, ArteStats::usage: the READMEs name the column only)
    o["arte_usage"] = sum(used) / len(rows)
    # V at T is one plant step past the trace's last row: only extrapolated
    o["final_speed_extrapolated_kmh"] = 3.6 * (2 * v[last] - v[last - 1])
    o["last_step_kmh"] = 3.6 * abs(v[last] - v[last - 1])
    # the confusion source decides once per 0.1 s frame, in ARTE runs only
    o["arte_frames"] = int(T_run / FRAME_S + 1e-9) if arte else 0
    return o


runs = {}
for p in sorted(glob.glob(os.path.join(out_dir, "trace_*_seed*.csv"))):
    m = re.fullmatch(r"trace_(.+)_seed(\d+)\.csv", os.path.basename(p))
    variant, seed = m.group(1), m.group(2)
    runs[f"{variant}/{seed}"] = run_figures(p, variant.endswith("-arte"))

# cross-check (not from the traces): the in-loop probe's decisions
inloop = {}
p = os.path.join(out_dir, "arte_inloop.csv")
if os.path.exists(p):
    for r in csv.DictReader(open(p, newline="")):
        inloop[f"{r['variant']}/{r['seed']}"] = (int(r["decisions"]), int(r["correct"]))
for key, o in runs.items():
    if key in inloop:
        d, c = inloop[key]
        o["inloop_decisions"] = d
        o["inloop_accuracy"] = c / d

# the printed table: mean and sample std over the seeds (report.rs, Stat::of:
# n - 1), of Python's figures; V end and ARTE accuracy (not in the traces)
# from summary.csv
summary = {f"{r['variant']}/{r['seed']}": r
           for r in csv.DictReader(open(os.path.join(out_dir, "summary.csv"), newline=""))}
TABLE = ["slip_deviation", "max_torque", "torque_effort", "mean_accel", "distance", "energy",
         "kinetic_energy_gain", "final_speed_kmh", "arte_accuracy", "cmd_tv_per_s", "cmd_hf_rms",
         "cmd_hf_share", "arte_usage"]
table = {}
for variant in sorted({k.split("/")[0] for k in runs}):
    keys = [k for k in runs if k.split("/")[0] == variant]
    row = {}
    for col in TABLE:
        if col in ("final_speed_kmh", "arte_accuracy"):
            xs = [num(summary[k][col]) for k in keys]
        else:
            xs = [runs[k][col] for k in keys]
        xs = [x for x in xs if math.isfinite(x)]
        if col == "arte_usage":
            xs = [100 * x for x in xs] if variant.endswith("-arte") else []
        if not xs:
            row[col] = None
            continue
        n = len(xs)
        mean = sum(xs) / n
        std = math.sqrt(sum((x - mean) ** 2 for x in xs) / (n - 1)) if n > 1 else 0.0
        row[col] = [mean, std]
    table[variant.upper()] = row
# ARTE vs base: the change of the means, %
REL = ["slip_deviation", "max_torque", "torque_effort", "mean_accel", "distance", "energy",
       "kinetic_energy_gain", "cmd_tv_per_s"]
relative = {}
for variant, row in table.items():
    base = variant[:-len("-ARTE")] if variant.endswith("-ARTE") else None
    if base in table:
        relative[f"{variant} / {base}"] = {
            col: 100 * (row[col][0] - table[base][col][0]) / abs(table[base][col][0]) for col in REL}


def clean(x):
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: clean(v) for k, v in x.items()}
    if isinstance(x, list):
        return [clean(v) for v in x]
    return x


print("RESULT " + json.dumps(clean({"runs": runs, "table": table, "relative": relative,
                                    "lead0": lead0})))
"##;

/// Figures compared within [`REL_TOL`] (the module's "Tolerance").
const FIGURES: &[&str] = &[
    "slip_deviation",
    "max_torque",
    "torque_effort",
    "mean_accel",
    "distance",
    "energy",
    "kinetic_energy_gain",
    "duration",
    "cmd_tv_per_s",
    "cmd_hf_rms",
    "cmd_hf_share",
    "arte_usage",
];

/// Counts, compared exactly.
const COUNTS: &[&str] = &["samples", "rejected", "non_finite_cycles", "arte_frames"];

/// The columns of the printed table, in its order.
const TABLE: &[&str] = &[
    "slip_deviation",
    "max_torque",
    "torque_effort",
    "mean_accel",
    "distance",
    "energy",
    "kinetic_energy_gain",
    "final_speed_kmh",
    "arte_accuracy",
    "cmd_tv_per_s",
    "cmd_hf_rms",
    "cmd_hf_share",
    "arte_usage",
];

/// The columns of the "ARTE vs base" table, in its order.
const RELATIVE: &[&str] = &[
    "slip_deviation",
    "max_torque",
    "torque_effort",
    "mean_accel",
    "distance",
    "energy",
    "kinetic_energy_gain",
    "cmd_tv_per_s",
];

const REL_TOL: f64 = 1e-10;
const ABS_TOL: f64 = 1e-12;
/// `final_speed_kmh` against the extrapolation: this share of the last
/// cycle's speed change.
const FINAL_SPEED_SHARE: f64 = 0.1;

/// [`RECOMPUTE`] on `out` and `vehicle`: its result. Fails (never skips)
/// without a usable Python.
fn recompute(out: &Path, vehicle: &Path) -> Value {
    let py = common::python();
    let o = Command::new(&py)
        .arg("-c")
        .arg(RECOMPUTE)
        .arg(out)
        .arg(vehicle)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run {}: {e} (python 3.11 or later needed)",
                py.display()
            )
        });
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "{} failed: {text}", py.display());
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix("RESULT "))
        .unwrap_or_else(|| panic!("no RESULT line in: {text}"));
    serde_json::from_str(line).unwrap()
}

/// `grip sim ARGS --vehicle VEHICLE --all-traces --out DIR/out` with the six
/// variants: the output directory.
fn sim(dir: &Path, vehicle: &Path, args: &[&str]) -> PathBuf {
    let out = dir.join("out");
    common::run_ok(
        common::grip()
            .arg("sim")
            .args(args)
            .args(["--variants", "mfc,mfc-arte,src,src-arte,mtte,mtte-arte"])
            .arg("--vehicle")
            .arg(vehicle)
            .arg("--all-traces")
            .arg("--out")
            .arg(&out),
    );
    out
}

/// A CSV as rows of (header, field).
fn read_csv(path: &Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), head.len(), "{}: {l}", path.display());
            head.iter()
                .zip(f)
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

/// A summary.csv field: empty is NaN.
fn number(s: &str) -> f64 {
    if s.is_empty() {
        f64::NAN
    } else {
        s.parse()
            .unwrap_or_else(|e| panic!("summary.csv: {s:?}: {e}"))
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= REL_TOL * a.abs().max(b.abs()) + ABS_TOL
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(f64::MIN_POSITIVE)
}

/// One cell of a printed table: "x ± s", "x %" (then `std` is `None`).
#[derive(Debug, Clone)]
struct Cell {
    text: String,
    value: f64,
    decimals: usize,
    std: Option<(f64, usize)>,
}

fn decimals(s: &str) -> usize {
    s.split_once('.').map_or(0, |(_, d)| d.len())
}

/// The rows of the table of `text` whose heading line starts with `head`
/// (the row's name: its first `cells` words), each a cell per column,
/// `None` for "-".
fn printed_table(text: &str, head: &str, cells: usize) -> BTreeMap<String, Vec<Option<Cell>>> {
    let lines = text.lines().skip_while(|l| !l.starts_with(head)).skip(2);
    let mut rows = BTreeMap::new();
    for l in lines.take_while(|l| !l.trim().is_empty()) {
        let t: Vec<&str> = l.split_whitespace().collect();
        let name = t[..cells].join(" ");
        let mut row = Vec::new();
        let mut i = cells;
        let parse = |s: &str| -> f64 {
            s.parse()
                .unwrap_or_else(|e| panic!("table.txt: {s:?} in {l:?}: {e}"))
        };
        while i < t.len() {
            if t[i] == "-" {
                row.push(None);
                i += 1;
            } else if t.get(i + 1) == Some(&"±") {
                let s = t[i + 2];
                row.push(Some(Cell {
                    text: t[i..i + 3].join(" "),
                    value: parse(t[i]),
                    decimals: decimals(t[i]),
                    std: Some((parse(s), decimals(s))),
                }));
                i += 3;
            } else {
                assert_eq!(t.get(i + 1), Some(&"%"), "table.txt, {head}: {l}");
                row.push(Some(Cell {
                    text: t[i..i + 2].join(" "),
                    value: parse(t[i]),
                    decimals: decimals(t[i]),
                    std: None,
                }));
                i += 2;
            }
        }
        rows.insert(name, row);
    }
    assert!(!rows.is_empty(), "no table {head:?} in:\n{text}");
    rows
}

/// A printed figure of `decimals` decimals is the rounding of `x`.
fn printed_is(p: f64, decimals: usize, x: f64) -> bool {
    (p - x).abs() <= 0.5 * 10f64.powi(-(decimals as i32)) * (1.0 + 1e-6) + 1e-9 * x.abs()
}

/// grip's `summary.csv` and `table.txt` in `out` against Python's
/// recomputation from the traces; prints every value compared, panics naming
/// each that differs.
fn check(label: &str, out: &Path, vehicle: &Path) {
    let py = recompute(out, vehicle);
    let runs = py["runs"].as_object().unwrap();
    let summary = read_csv(&out.join("summary.csv"));
    let lead0 = py["lead0"].as_bool().unwrap();
    let mut report = format!(
        "{label} ({}):\n  {:<16} {:<22} {:>24} {:>24}  difference: relative (figures), absolute (counts, \
         table.txt), share of the last step (final speed)\n",
        out.display(),
        "run",
        "column",
        "summary.csv",
        "python"
    );
    let mut bad = Vec::new();
    let mut row_out = |run: &str, col: &str, g: String, p: String, diff: f64, ok: bool| {
        let mark = if ok { "" } else { "  <-- DIFFERS" };
        report.push_str(&format!(
            "  {run:<16} {col:<22} {g:>24} {p:>24}  {diff:.1e}{mark}\n"
        ));
        if !ok {
            bad.push(format!("{run} {col}: grip {g}, python {p}"));
        }
    };

    // one trace per summary row, and no other
    let keys: BTreeSet<String> = summary
        .iter()
        .map(|r| format!("{}/{}", r["variant"], r["seed"]))
        .collect();
    let traced: BTreeSet<String> = runs.keys().cloned().collect();
    assert_eq!(keys, traced, "{label}: summary.csv rows and trace files");
    assert!(!keys.is_empty());

    for r in &summary {
        let run = format!("{}/{}", r["variant"], r["seed"]);
        let p = &runs[&run];
        let arte = r["variant"].ends_with("-arte");
        for &col in COUNTS {
            let (g, q) = (&r[col], p[col].as_u64().unwrap());
            let ok = g.parse::<u64>().ok() == Some(q);
            row_out(&run, col, g.clone(), q.to_string(), 0.0, ok);
        }
        for &col in FIGURES {
            let (g, q) = (number(&r[col]), p[col].as_f64().unwrap());
            row_out(
                &run,
                col,
                g.to_string(),
                q.to_string(),
                rel(g, q),
                close(g, q),
            );
        }
        // V at T: the extrapolation of the last two rows
        let g = number(&r["final_speed_kmh"]);
        let q = p["final_speed_extrapolated_kmh"].as_f64().unwrap();
        let step = p["last_step_kmh"].as_f64().unwrap();
        row_out(
            &run,
            "final_speed_kmh (≈)",
            g.to_string(),
            q.to_string(),
            (g - q).abs() / step,
            (g - q).abs() <= FINAL_SPEED_SHARE * step,
        );
        // ARTE accuracy: not in the traces
        let acc = number(&r["arte_accuracy"]);
        let frames = p["arte_frames"].as_u64().unwrap() as f64;
        if !arte {
            row_out(
                &run,
                "arte_accuracy",
                r["arte_accuracy"].clone(),
                "(none)".into(),
                0.0,
                acc.is_nan(),
            );
        } else if lead0 {
            let q = p["inloop_accuracy"].as_f64().unwrap();
            row_out(
                &run,
                "arte_accuracy (inloop)",
                acc.to_string(),
                q.to_string(),
                rel(acc, q),
                close(acc, q),
            );
            let d = p["inloop_decisions"].as_u64().unwrap();
            row_out(
                &run,
                "arte_frames (inloop)",
                r["arte_frames"].clone(),
                d.to_string(),
                0.0,
                r["arte_frames"] == d.to_string(),
            );
        } else {
            let n = acc * frames;
            row_out(
                &run,
                "arte_accuracy x frames",
                n.to_string(),
                "a whole number".into(),
                (n - n.round()).abs(),
                (0.0..=frames).contains(&n) && (n - n.round()).abs() < 1e-9,
            );
        }
    }

    // the printed table: means and standard deviations
    let text = std::fs::read_to_string(out.join("table.txt")).unwrap();
    let table = printed_table(&text, "variant ", 1);
    let py_table = py["table"].as_object().unwrap();
    assert_eq!(
        table.keys().collect::<Vec<_>>(),
        py_table.keys().collect::<Vec<_>>(),
        "{label}: table.txt's variants"
    );
    for (variant, row) in &table {
        assert_eq!(
            row.len(),
            TABLE.len(),
            "{label}: table.txt, {variant}: {row:?}"
        );
        for (&col, cell) in TABLE.iter().zip(row) {
            let q = &py_table[variant][col];
            match cell {
                None => row_out(variant, col, "-".into(), q.to_string(), 0.0, q.is_null()),
                Some(c) => {
                    let (qm, qs) = (
                        q[0].as_f64().unwrap_or(f64::NAN),
                        q[1].as_f64().unwrap_or(f64::NAN),
                    );
                    let ok = printed_is(c.value, c.decimals, qm)
                        && c.std.is_none_or(|(s, d)| printed_is(s, d, qs));
                    row_out(
                        variant,
                        col,
                        c.text.clone(),
                        format!("{qm} ± {qs}"),
                        (c.value - qm).abs(),
                        ok,
                    );
                }
            }
        }
    }
    let relative = printed_table(&text, "ARTE vs base", 3);
    let py_rel = py["relative"].as_object().unwrap();
    assert_eq!(
        relative.keys().collect::<Vec<_>>(),
        py_rel.keys().collect::<Vec<_>>(),
        "{label}: table.txt's ARTE vs base rows"
    );
    for (pair, row) in &relative {
        assert_eq!(row.len(), RELATIVE.len(), "{label}: {pair}: {row:?}");
        for (&col, cell) in RELATIVE.iter().zip(row) {
            let q = py_rel[pair][col].as_f64().unwrap();
            let ok = cell
                .as_ref()
                .is_some_and(|c| printed_is(c.value, c.decimals, q));
            let text = cell.as_ref().map_or("-".into(), |c| c.text.clone());
            let diff = cell.as_ref().map_or(f64::NAN, |c| (c.value - q).abs());
            row_out(pair, col, text, format!("{q} %"), diff, ok);
        }
    }

    println!("{report}");
    assert!(
        bad.is_empty(),
        "{label}: grip sim's summary.csv / table.txt and the Python recomputation from the traces \
         differ (tolerance: counts exact, figures {REL_TOL:e} relative, final speed {FINAL_SPEED_SHARE} of \
         the last step, table half its last digit):\n  {}\n{report}",
        bad.join("\n  ")
    );
    // not compared on empty data
    let any = |f: &dyn Fn(&Value) -> bool| runs.values().any(f);
    assert!(any(&|p| p["samples"].as_u64() >= Some(2400)), "{label}");
    assert!(any(&|p| p["arte_usage"].as_f64() > Some(0.5)), "{label}");
    assert!(any(&|p| p["cmd_hf_share"].as_f64() > Some(0.01)), "{label}");
}

/// `grip sim` of the six variants on `vehicle` (under the configuration
/// directory) with `args`, checked.
fn case(vehicle: &str, args: &[&str], label: &str) {
    let dir = tempfile::tempdir().unwrap();
    let vehicle = common::config_dir().join(vehicle);
    let out = sim(dir.path(), &vehicle, args);
    check(label, &out, &vehicle);
}

const PAPER: [&str; 4] = ["--scenario", "paper", "--seeds", "2"];
const RANDOM: [&str; 6] = ["--scenario", "random", "--seed0", "1000", "--seeds", "1"];

#[test]
fn paper_on_the_papers_car() {
    case("vehicle.toml", &PAPER, "paper, seeds 1-2, vehicle.toml");
}

#[test]
fn paper_on_the_front_mic_car() {
    case(
        "vehicles/front-mic.toml",
        &PAPER,
        "paper, seeds 1-2, front-mic.toml",
    );
}

#[test]
fn random_roads_on_the_papers_car() {
    case("vehicle.toml", &RANDOM, "random, seed 1000, vehicle.toml");
}

#[test]
fn random_roads_on_the_front_mic_car() {
    case(
        "vehicles/front-mic.toml",
        &RANDOM,
        "random, seed 1000, front-mic.toml",
    );
}
