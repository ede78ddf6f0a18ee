//! Independent readers agree with `grip replay`: the reference drive is
//! replayed to a new log (`--out`), and Python's official `mcap` reader finds
//! the same `grip/tcs/cycle` records (every field, as JSON) and the same
//! transmitted CAN frames in both files; Python's `jsonschema` (Draft
//! 2020-12) validates every message of both files against its channel's
//! JSON Schema. Needs `python3` with `mcap`, `zstandard`, `lz4` and
//! `jsonschema` (`pip install mcap zstandard lz4 jsonschema`); without them
//! the test FAILS with that instruction, it never passes silently.

use std::path::Path;
use std::process::Command;

const SCRIPT: &str = r#"
import sys, json
try:
    from mcap.reader import make_reader
    from mcap.decoder import DecoderFactory
    import jsonschema, zstandard, lz4
except ImportError as e:
    print(f"python package missing ({e}): pip install mcap zstandard lz4 jsonschema")
    sys.exit(3)

def read(path):
    cycles, tx, checked = [], [], 0
    validators = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            d = json.loads(message.data)
            v = validators.get(schema.id)
            if v is None:
                s = json.loads(schema.data)
                jsonschema.Draft202012Validator.check_schema(s)
                v = validators[schema.id] = jsonschema.Draft202012Validator(s)
            errors = list(v.iter_errors(d))
            if errors:
                print(f"{path}: {channel.topic} message {message.sequence}: {errors[0].message}")
                sys.exit(1)
            checked += 1
            if channel.topic == "grip/tcs/cycle":
                cycles.append(d)
            elif channel.topic == "grip/can/log" and d["direction"] == 1:
                tx.append(d)
    return cycles, tx, checked

a = read(sys.argv[1])
b = read(sys.argv[2])
if a[0] != b[0]:
    i = next(i for i, (x, y) in enumerate(zip(a[0], b[0])) if x != y) if len(a[0]) == len(b[0]) else min(len(a[0]), len(b[0]))
    print(f"cycle records differ at {i} ({len(a[0])} vs {len(b[0])})")
    sys.exit(1)
if a[1] != b[1]:
    print(f"transmitted frames differ ({len(a[1])} vs {len(b[1])})")
    sys.exit(1)
print(f"same: {len(a[0])} cycle records, {len(a[1])} transmitted frames; schema-valid: {a[2]} + {b[2]} messages")
"#;

#[test]
fn python_finds_the_same_outputs_and_every_message_matches_its_schema() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = tempfile::tempdir().unwrap();
    let reference = root.join("tests/data/reference-drive.mcap");
    let replayed = dir.path().join("replayed.mcap");
    let out = Command::new(env!("CARGO_BIN_EXE_grip"))
        .arg("--config-dir")
        .arg(root.join("config"))
        .arg("replay")
        .arg(&reference)
        .arg("--out")
        .arg(&replayed)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let py = Command::new("python3")
        .arg("-c")
        .arg(SCRIPT)
        .arg(&reference)
        .arg(&replayed)
        .output()
        .expect("python3 is needed (pip install mcap zstandard lz4 jsonschema)");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&py.stdout),
        String::from_utf8_lossy(&py.stderr)
    );
    assert!(py.status.success(), "{text}");
    println!("{text}");
    let line = text.lines().find(|l| l.starts_with("same: ")).unwrap_or("");
    let n: usize = line
        .split_whitespace()
        .nth(1)
        .and_then(|x| x.parse().ok())
        .unwrap_or(0);
    assert!(n > 1000, "{text}");
}
