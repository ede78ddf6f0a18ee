//! An independent check of the headline figures of `grip inspect --json`:
//! Python recomputes them from the raw log with the official `mcap` reader,
//! written from the definitions as the READMEs give them (not from grip's
//! code), and each is compared with grip's:
//!
//! - the ground-truth metrics over the scenario window
//!   (`tools/grip/README.md`, "grip inspect"; `crates/tcs/README.md`,
//!   "Metrics"): slip deviation (1/T)∫|λ|dt, max |T|, torque effort, mean
//!   acceleration, distance ∫V dt, energy ∫Tω dt, kinetic energy gain,
//!   duration, the command's total variation per second, where the command
//!   figures start, the largest |λ| and when, the window's length;
//! - what the loop measured (`crates/drive/README.md`, "Measured by the
//!   loop"; `tools/grip/README.md`, "measured by the loop"): mean |λ_m|,
//!   the cycles it covers and leaves out, the command's total variation;
//! - ARTE's accuracy (judged and correct estimates) during the scenario and
//!   over the whole log;
//! - deadline misses, safe-state cycles and safe-state entries, during the
//!   scenario and over the whole log.
//!
//! Two points the READMEs left open were settled by reading
//! `crates/drive/src/summary.rs` (and are said so where the Python does
//! them; `tools/grip/README.md` states them since): the ground-truth block's command figure takes, at each truth
//! sample, the command of the latest cycle record stamped at or before it
//! (the measured section takes the cycles' own commands, each for its
//! cycle's time; on a live drive the two differ); and an estimate without
//! a class (audio not classified) is not judged at all.
//!
//! Logs: two `grip generate` drives of the `paper` scenario with ARTE on
//! (MTTE on the front-mic car, SRC on the paper's car), the stored live
//! drive `tests/data/reference-drive.mcap` (a real clock: jittered truth
//! stamps, cycles offset from them), and an MFC drive rewritten by Python
//! with deadline misses, safe-state episodes across the window's start,
//! inside it and at its last cycle, an unclassified and a wrong estimate,
//! so that the counts, 0 on a generated drive, are compared where they are
//! not.
//!
//! Tolerance: counts exactly; every other figure within a relative 1e-9
//! (and 1e-12 absolute). Both sides sum the same IEEE doubles over at most
//! 2400 samples, whose rounding bound is n ε ≈ 2400 × 1.1e-16 ≈ 3e-13 of
//! the sum's magnitude; the only other difference is how a time is formed
//! from the ns stamps (a difference of stamps against a sum of steps: the
//! mean acceleration differs by 6e-14). A definition that differs by one
//! 1 ms sample in a 1.5-2.4 s window moves a figure by about 1e-4 of
//! itself, 1e5 times the tolerance.
//!
//! Python: `tools/.venv-mcap/bin/python3` when `tools/setup` made it (the
//! interpreter `tools/test` puts first on `PATH`), else `python3`; without
//! `mcap`, `zstandard` and `lz4` the test FAILS saying how to install them,
//! it never passes silently.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// Recomputes the figures of one log (argument: its path) and prints them as
/// one line `RESULT {json}`, keyed as `grip inspect --json` keys them (a dot
/// between nested keys).
const RECOMPUTE: &str = r##"
import sys, json, math, bisect
try:
    import tomllib
    from mcap.reader import make_reader
    import zstandard, lz4  # noqa: F401  (the reader needs them for compressed chunks)
except ImportError as e:
    print(f"python package missing ({e}): run tools/setup (it makes tools/.venv-mcap) or pip install mcap zstandard lz4")
    sys.exit(3)

NO_INDEX = 4294967295  # "none" in an index field (crates/io/README.md)
DEMAND_MIN_NM = 10.0   # the command's figures start at the first cycle with the demand above it
MIN_SPEED_MPS = 1.0    # measured slip only where max(|r w|, |V|) is at least this
MAX_HOLD = 5           # a sample holds until the next one, at most five periods


def fail(msg):
    print(f"recompute: {msg}")
    sys.exit(1)


def finite(*xs):
    return all(x is not None and math.isfinite(x) for x in xs)


path = sys.argv[1]
topics = {"grip/plant/truth": [], "grip/tcs/cycle": [], "grip/arte/road": []}
with open(path, "rb") as f:
    for _, ch, m in make_reader(f).iter_messages(topics=list(topics), log_time_order=False):
        topics[ch.topic].append(json.loads(m.data))
with open(path, "rb") as f:
    att = {a.name: a.data for a in make_reader(f).iter_attachments()}
with open(path, "rb") as f:
    meta = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
truth, cycles, ests = topics["grip/plant/truth"], topics["grip/tcs/cycle"], topics["grip/arte/road"]
run = meta.get("grip.run", {})
if len(truth) < 2 or not cycles:
    fail("the log has no ground truth or no cycle records")


def toml_att(name):
    if name not in att:
        fail(f"attachment {name} missing")
    return tomllib.loads(att[name].decode())


# the configuration the drive ran with, as attached to the log: the vehicle
# is drive/vehicle.toml when grip.run names a --vehicle, else vehicle.toml
veh = toml_att("drive/vehicle.toml" if run.get("vehicle") else "vehicle.toml")["vehicle"]
r_m, v_eps, j_w = veh["r"], veh["v_eps"], veh["j_w"]
m_share = veh["mass"] / veh["n_driven"]
plant_ns = round(1e9 / toml_att("plant-sim.toml").get("rate_hz", 1000.0))
loop_ns = round(1e9 / toml_att("controllers.toml").get("loop", {}).get("rate_hz", 1000.0))
scen_name = run.get("scenario")
scen = toml_att(f"scenarios/{scen_name}.toml")
duration = float(run["scenario_duration_s"]) if "scenario_duration_s" in run else scen["duration"]
demand = scen.get("demand", {})
if demand.get("kind") != "constant" or not demand.get("torque", 0) > 0:
    fail(f"scenario {scen_name}: a driver who waits (demand {demand}) shifts the window; not recomputed here")

# the scenario window: from the last truth sample before the held state first
# changes (a pre-roll, x rising to 0 at unchanged speeds, does not count) for
# the scenario's duration
f0 = truth[0]
first = next((i for i, s in enumerate(truth)
              if s["v"] != f0["v"] or s["omega"] != f0["omega"] or (s["x"] != f0["x"] and s["x"] > 0)), None)
if first is None:
    fail("the scenario never started")
t_start = truth[first - 1]["stamp_ns"]
t_end = t_start + round(duration * 1e9)
tst = [s["stamp_ns"] for s in truth]
cst = [c["stamp_ns"] for c in cycles]


def in_window(t):
    return t_start <= t < t_end


def held_s(stamps, i, period_ns):
    # a sample stands for the time to the next one, at most five periods,
    # and not past the window's end (a complete log's duration is the window's)
    nxt = stamps[i + 1] if i + 1 < len(stamps) else stamps[i] + period_ns
    return (min(nxt, stamps[i] + MAX_HOLD * period_ns, t_end) - stamps[i]) * 1e-9


# ground-truth metrics (crates/tcs/README.md, "Metrics"): every integral the
# sum of x dt over the window's samples
win = [i for i in range(len(truth)) if in_window(tst[i])]
T = s_lam = s_abs_t = dist = energy = 0.0
max_t = 0.0
max_slip, max_slip_at = -1.0, None
used = []
for i in win:
    s = truth[i]
    dt = held_s(tst, i, plant_ns)
    if not finite(s["lambda"], s["torque"], s["omega"], s["v"]) or dt <= 0:
        continue  # a rejected sample
    used.append(i)
    T += dt
    s_lam += abs(s["lambda"]) * dt
    s_abs_t += abs(s["torque"]) * dt
    max_t = max(max_t, abs(s["torque"]))
    dist += s["v"] * dt
    energy += s["torque"] * s["omega"] * dt
    if abs(s["lambda"]) > max_slip:
        max_slip, max_slip_at = abs(s["lambda"]), (tst[i] - t_start) * 1e-9
a, b = truth[used[0]], truth[used[-1]]
out = {
    "metrics.slip_deviation": s_lam / T,
    "metrics.max_torque_nm": max_t,
    "metrics.torque_effort_nm": s_abs_t / T,
    "metrics.mean_accel_ms2": (b["v"] - a["v"]) / ((b["stamp_ns"] - a["stamp_ns"]) * 1e-9),
    "metrics.distance_m": dist,
    "metrics.energy_j": energy,
    "metrics.kinetic_energy_gain_j": 0.5 * m_share * (b["v"] ** 2 - a["v"] ** 2)
    + 0.5 * j_w * (b["omega"] ** 2 - a["omega"] ** 2),
    "metrics.duration_s": T,
    "max_slip": max_slip,
    "max_slip_s": max_slip_at,
}

# the command's total variation per second, sum |T*_k - T*_(k-1)| / T_cmd, from
# the first cycle in the window with the driver's demand above 10 N m
cwin = [k for k in range(len(cycles)) if in_window(cst[k])]
k0 = next(k for k in cwin if finite(cycles[k]["demand"]) and cycles[k]["demand"] > DEMAND_MIN_NM)


def total_variation(samples):
    tv = t = 0.0
    prev = None
    for cmd, dt in samples:
        if not finite(cmd):
            continue
        if prev is not None:
            tv += abs(cmd - prev)
        prev = cmd
        t += dt
    return tv / t


# measured section: the cycles' own commands, each for its cycle's time
out["measured.cmd_tv_per_s"] = total_variation(
    (cycles[k]["torque_cmd"], held_s(cst, k, loop_ns)) for k in cwin if k >= k0)
out["measured.cmd_from_s"] = out["cmd_from_s"] = (cst[k0] - t_start) * 1e-9


# ground-truth block: at each truth sample the command in force, that of the
# latest cycle record stamped at or before it (from cycle k0 on), for the
# sample's time (the pairing is not in the READMEs: settled from summary.rs)
def cmd_at(i):
    j = bisect.bisect_right(cst, tst[i]) - 1
    return cycles[j]["torque_cmd"] if j >= k0 else None


out["metrics.cmd_tv_per_s"] = total_variation((cmd_at(i), held_s(tst, i, plant_ns)) for i in used)

# measured slip l_m = (r w - V) / max(|r w|, |V|, v_eps) on the window's cycles
# with a valid finite V, a finite w, out of the safe state, max(|r w|, |V|) >= 1
# m/s; mean |l_m| weighted by each cycle's time
slip_t = slip_x = 0.0
slip_n = safe_n = 0
for k in cwin:
    c = cycles[k]
    w, v = c["omega"], c["v"]
    if not (c["v_valid"] and finite(v, w)):
        continue
    if c["safe_state"]:
        safe_n += 1
        continue
    rw = r_m * w
    if max(abs(rw), abs(v)) < MIN_SPEED_MPS:
        continue
    dt = held_s(cst, k, loop_ns)
    slip_t += dt
    slip_x += abs((rw - v) / max(abs(rw), abs(v), v_eps)) * dt
    slip_n += 1
out["measured.cycles"] = len(cwin)
out["measured.slip_cycles"] = slip_n
out["measured.safe_state_cycles"] = safe_n
out["measured.mean_abs_slip"] = slip_x / slip_t


# loop counts: deadline_misses is tcs-loop's running count since its start, so
# a cycle's own misses (those just before it) are its increase over the record
# before it; a safe-state entry is a cycle in the safe state after an active one
def misses(k):
    return cycles[k]["deadline_misses"] - (cycles[k - 1]["deadline_misses"] if k else 0)


def entry(k):
    return k > 0 and cycles[k]["safe_state"] == 1 and cycles[k - 1]["safe_state"] == 0


out["deadline_misses"] = sum(misses(k) for k in range(len(cycles)))
out["deadline_misses_in_scenario"] = sum(misses(k) for k in cwin)
out["safe_cycles"] = sum(c["safe_state"] == 1 for c in cycles)
out["safe_cycles_in_scenario"] = sum(cycles[k]["safe_state"] == 1 for k in cwin)
out["safe_state_entries"] = sum(entry(k) for k in range(len(cycles)))
out["safe_state_entries_in_scenario"] = sum(entry(k) for k in cwin)

# ARTE: each estimate judged against the road at the microphone at its frame's
# midpoint (the truth sample in force there); during the scenario: midpoint in
# the window; whole log: every midpoint with ground truth (none after it ends).
# An estimate without a class is not judged (settled from summary.rs)
judged = correct = judged_all = correct_all = 0
w_end = min(t_end, tst[used[-1]] + plant_ns)
for e in ests:
    mid = (e["frame_t0_ns"] + e["frame_t1_ns"]) // 2
    i = bisect.bisect_right(tst, mid) - 1
    if e["class_index"] == NO_INDEX or i < 0 or mid >= tst[-1] + plant_ns:
        continue
    ok = e["class_name"] == truth[i]["mic_road_name"]
    judged_all += 1
    correct_all += ok
    if t_start <= mid < w_end:
        judged += 1
        correct += ok
out["scenario_s"] = (w_end - t_start) * 1e-9
out["arte_judged"] = judged
out["arte_correct"] = correct
out["arte_accuracy"] = correct / judged if judged else None
out["arte_judged_whole_log"] = judged_all
out["arte_correct_whole_log"] = correct_all
print("RESULT " + json.dumps(out))
"##;

/// Copies a log (argument 1) to a new one (argument 2) with, in tcs-loop's
/// cycle records, deadline misses and safe-state episodes placed around the
/// scenario window, and in arte's estimates one left without a class and one
/// naming another class; prints `INJECTED {json}` with where.
const INJECT: &str = r##"
import sys, json
try:
    from mcap.reader import make_reader
    from mcap.writer import Writer, CompressionType
    import zstandard, lz4  # noqa: F401
except ImportError as e:
    print(f"python package missing ({e}): run tools/setup (it makes tools/.venv-mcap) or pip install mcap zstandard lz4")
    sys.exit(3)

NO_INDEX = 4294967295
MS = 1_000_000
src, dst = sys.argv[1], sys.argv[2]
with open(src, "rb") as f:
    r = make_reader(f)
    header = r.get_header()
    records = list(r.iter_messages(log_time_order=False))
    attachments = list(r.iter_attachments())
    metadata = list(r.iter_metadata())

# the scenario window, as the README defines it
truth = [json.loads(m.data) for _, ch, m in records if ch.topic == "grip/plant/truth"]
f0 = truth[0]
i = next(i for i, s in enumerate(truth)
         if s["v"] != f0["v"] or s["omega"] != f0["omega"] or (s["x"] != f0["x"] and s["x"] > 0))
ts = truth[i - 1]["stamp_ns"]
run = dict(next(m for m in metadata if m.name == "grip.run").metadata)
te = ts + round(float(run["scenario_duration_s"]) * 1e9)
# deadline misses a cycle adds to the running count: 0.2 s before the window,
# at its first cycle, inside, at its last cycle, at the first cycle after it
misses_at = {ts - 200 * MS: 2, ts: 1, ts + 1000 * MS: 3, te - MS: 1, te: 5}
# safe-state episodes [from, to): entered before the window's start and
# lasting into it, inside it, entered at its last cycle
safe = [(ts - 3 * MS, ts + 2 * MS), (ts + 500 * MS, ts + 520 * MS), (te - MS, te + 5 * MS)]
stamps = {json.loads(m.data)["stamp_ns"] for _, ch, m in records if ch.topic == "grip/tcs/cycle"}
for t in list(misses_at) + [t for ab in safe for t in ab]:
    assert t in stamps, f"no cycle record at {t}"
classes = {}
for _, ch, m in records:
    if ch.topic == "grip/arte/road":
        e = json.loads(m.data)
        if e["class_index"] != NO_INDEX:
            classes[e["class_index"]] = e["class_name"]

out = open(dst, "wb")
w = Writer(out, compression=CompressionType.ZSTD)
w.start(profile=header.profile, library=header.library)
schemas, channels = {}, {}
added = 0
unclassified = wrong = None
for schema, ch, m in records:
    if schema.id not in schemas:
        schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
    if ch.id not in channels:
        channels[ch.id] = w.register_channel(ch.topic, ch.message_encoding, schemas[schema.id], ch.metadata)
    data = m.data
    if ch.topic == "grip/tcs/cycle":
        c = json.loads(data)
        t = c["stamp_ns"]
        added += misses_at.get(t, 0)
        c["deadline_misses"] += added
        if any(a <= t < b for a, b in safe):
            c.update(safe_state=1, torque_cmd=0.0, internal=None, mu_hat=None, torque_cap=None,
                     belief_prob=None, belief_road=NO_INDEX, road_class=NO_INDEX, used_arte=0)
        data = json.dumps(c).encode()
    elif ch.topic == "grip/arte/road":
        e = json.loads(data)
        mid = (e["frame_t0_ns"] + e["frame_t1_ns"]) // 2
        if unclassified is None and ts + 1000 * MS <= mid < te:
            unclassified = e["seq"]
            e.update(class_index=NO_INDEX, class_name="", confidence=0.0, lambda_opt=None,
                     mu_peak=None, alpha=None, probabilities=[0.0] * len(e["probabilities"]))
        elif wrong is None and ts + 1500 * MS <= mid < te:
            wrong = e["seq"]
            other = next(k for k in sorted(classes) if classes[k] != e["class_name"])
            e.update(class_index=other, class_name=classes[other])
        data = json.dumps(e).encode()
    w.add_message(channels[ch.id], log_time=m.log_time, data=data, publish_time=m.publish_time,
                  sequence=m.sequence)
for a in attachments:
    w.add_attachment(create_time=a.create_time, log_time=a.log_time, name=a.name,
                     media_type=a.media_type, data=a.data)
for md in metadata:
    w.add_metadata(md.name, dict(md.metadata))
w.finish()
out.close()
assert unclassified is not None and wrong is not None
print("INJECTED " + json.dumps({"unclassified_seq": unclassified, "wrong_seq": wrong}))
"##;

/// Counts, compared exactly.
const COUNTS: &[&str] = &[
    "measured.cycles",
    "measured.slip_cycles",
    "measured.safe_state_cycles",
    "arte_judged",
    "arte_correct",
    "arte_judged_whole_log",
    "arte_correct_whole_log",
    "deadline_misses",
    "deadline_misses_in_scenario",
    "safe_cycles",
    "safe_cycles_in_scenario",
    "safe_state_entries",
    "safe_state_entries_in_scenario",
];

/// Figures, compared within [`REL_TOL`] (the module's "Tolerance").
const FIGURES: &[&str] = &[
    "metrics.slip_deviation",
    "metrics.max_torque_nm",
    "metrics.torque_effort_nm",
    "metrics.mean_accel_ms2",
    "metrics.distance_m",
    "metrics.energy_j",
    "metrics.kinetic_energy_gain_j",
    "metrics.duration_s",
    "metrics.cmd_tv_per_s",
    "cmd_from_s",
    "max_slip",
    "max_slip_s",
    "scenario_s",
    "measured.mean_abs_slip",
    "measured.cmd_tv_per_s",
    "measured.cmd_from_s",
    "arte_accuracy",
];

const REL_TOL: f64 = 1e-9;
const ABS_TOL: f64 = 1e-12;

/// Runs `script` with `args`; its stdout. Fails (never skips) without the
/// Python packages.
fn run_python(script: &str, args: &[&Path]) -> String {
    let py = common::python();
    let out = Command::new(&py)
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run {}: {e}; run tools/setup (it makes tools/.venv-mcap with mcap, zstandard, lz4)",
                py.display()
            )
        });
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.code() != Some(3),
        "{}: {text}\n(the Python packages are missing: run tools/setup)",
        py.display()
    );
    assert!(out.status.success(), "{} failed: {text}", py.display());
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The JSON after `tag` on the line of `text` that starts with it.
fn tagged(text: &str, tag: &str) -> Value {
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix(tag))
        .unwrap_or_else(|| panic!("no line {tag} in: {text}"));
    serde_json::from_str(line).unwrap()
}

/// `grip generate --count 1 ARGS` into `dir`: the log.
fn generate(dir: &Path, args: &[&str]) -> PathBuf {
    let out = dir.join("gen");
    common::run_ok(
        common::grip()
            .arg("generate")
            .arg("--out")
            .arg(&out)
            .args(["--count", "1", "--scenario", "paper"])
            .args(args),
    );
    let logs: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    assert_eq!(logs.len(), 1, "{logs:?}");
    logs.into_iter().next().unwrap()
}

fn field<'a>(v: &'a Value, key: &str) -> &'a Value {
    key.split('.').fold(v, |v, k| &v[k])
}

/// grip's `--json` and Python's figures of `log` (Python's keyed flat,
/// `measured.cycles` for grip's `measured` → `cycles`), compared field by field;
/// prints both columns; panics naming every field that differs. Returns
/// Python's figures.
fn check(label: &str, log: &Path) -> Value {
    let grip: Value = serde_json::from_str(
        common::run_ok(common::grip().arg("inspect").arg("--json").arg(log))
            .lines()
            .next()
            .unwrap(),
    )
    .unwrap();
    assert_eq!(grip["status"], "ok", "{label}: {grip}");
    assert_eq!(grip["scenario_window"], "complete", "{label}: {grip}");
    let py = tagged(&run_python(RECOMPUTE, &[log]), "RESULT ");

    let mut table = format!(
        "{label} ({}):\n  {:<34} {:>24} {:>24}  difference (relative; counts absolute)\n",
        log.display(),
        "field",
        "grip inspect --json",
        "python"
    );
    let mut bad = Vec::new();
    for (key, exact) in COUNTS
        .iter()
        .map(|k| (*k, true))
        .chain(FIGURES.iter().map(|k| (*k, false)))
    {
        let (g, p) = (field(&grip, key), &py[key]);
        let (ok, diff) = match (g.as_f64(), p.as_f64()) {
            (Some(a), Some(b)) if exact => (g.as_u64().is_some() && g == p, (a - b).abs()),
            (Some(a), Some(b)) => {
                let d = (a - b).abs();
                let rel = d / a.abs().max(b.abs()).max(f64::MIN_POSITIVE);
                (d <= REL_TOL * a.abs().max(b.abs()) + ABS_TOL, rel)
            }
            _ => (false, f64::NAN),
        };
        let mark = if ok { "" } else { "  <-- DIFFERS" };
        table.push_str(&format!(
            "  {key:<34} {:>24} {:>24}  {diff:.1e}{mark}\n",
            g.to_string(),
            p.to_string()
        ));
        if !ok {
            bad.push(format!("{key}: grip {g}, python {p}"));
        }
    }
    println!("{table}");
    assert!(
        bad.is_empty(),
        "{label}: grip inspect --json and the Python recomputation differ (tolerance: counts exact, \
         figures {REL_TOL:e} relative):\n  {}\n{table}",
        bad.join("\n  ")
    );
    // not compared on empty data
    assert!(py["measured.slip_cycles"].as_u64() > Some(1000), "{table}");
    assert!(py["arte_judged"].as_u64() > Some(50), "{table}");
    py
}

#[test]
fn mtte_with_arte_on_the_front_mic_car() {
    let dir = tempfile::tempdir().unwrap();
    let vehicle = common::config_dir().join("vehicles/front-mic.toml");
    let log = generate(
        dir.path(),
        &[
            "--controllers",
            "mtte",
            "--arte",
            "on",
            "--seed0",
            "1",
            "--vehicle",
            vehicle.to_str().unwrap(),
        ],
    );
    check("paper, MTTE, ARTE on, front-mic car, seed 1", &log);
}

#[test]
fn src_with_arte_on_the_papers_car() {
    let dir = tempfile::tempdir().unwrap();
    let log = generate(
        dir.path(),
        &["--controllers", "src", "--arte", "on", "--seed0", "2"],
    );
    check("paper, SRC, ARTE on, the paper's car, seed 2", &log);
}

/// A live drive: plant-sim's stamps jitter (steps of 0.34-1.8 ms) and the
/// cycle records lie between them, so the window's clipping at its end and
/// the ground-truth block's pairing of commands with truth samples matter.
#[test]
fn the_stored_live_reference_drive() {
    let log = common::reference_drive();
    check("tests/data/reference-drive.mcap (e2e, MTTE, ARTE on)", &log);
}

/// Counts that are 0 in a generated drive, made not to be: deadline misses
/// before, at the first cycle of, inside, at the last cycle of and after
/// the window (5 of 12 in it); safe-state episodes entered before the
/// window (2 cycles in it, no entry), inside it (20 cycles) and at its last
/// cycle (1 cycle, an entry): 2 entries and 23 cycles in it; an estimate
/// without a class and one naming another class.
#[test]
fn a_rewritten_mfc_drive_with_deadline_misses_safe_states_and_bad_estimates() {
    let dir = tempfile::tempdir().unwrap();
    let log = generate(
        dir.path(),
        &["--controllers", "mfc", "--arte", "on", "--seed0", "3"],
    );
    let rewritten = dir.path().join("rewritten.mcap");
    let what = tagged(&run_python(INJECT, &[&log, &rewritten]), "INJECTED ");
    println!("rewritten: {what}");
    let source = tagged(&run_python(RECOMPUTE, &[&log]), "RESULT ");
    let py = check(
        "paper, MFC, ARTE on, the paper's car, seed 3, rewritten",
        &rewritten,
    );
    // the rewrite is where it was meant to be (the Python's own figures)
    let n = |v: &Value, k: &str| v[k].as_u64().unwrap();
    assert_eq!(n(&py, "deadline_misses"), 12);
    assert_eq!(n(&py, "deadline_misses_in_scenario"), 5);
    assert_eq!(n(&py, "safe_state_entries_in_scenario"), 2);
    assert_eq!(
        n(&py, "safe_state_entries"),
        n(&source, "safe_state_entries") + 3
    );
    assert_eq!(n(&py, "safe_cycles_in_scenario"), 23);
    assert_eq!(n(&py, "measured.safe_state_cycles"), 23);
    assert_eq!(n(&py, "arte_judged"), n(&source, "arte_judged") - 1);
}
