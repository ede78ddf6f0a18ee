//! Property: mutated configuration text never panics a loader; it either
//! loads or gives a `ConfigError` naming the file.

use std::path::{Path, PathBuf};

use grip_config::{parse_roads, parse_scenario, parse_vehicle};
use proptest::prelude::*;

fn read(rel: &str) -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../config")
        .join(rel);
    std::fs::read_to_string(p).unwrap()
}

/// Replace `len` bytes at `at` (clamped to char boundaries) with `with`.
fn mutate(text: &str, at: usize, len: usize, with: &str) -> String {
    let mut a = at.min(text.len());
    while !text.is_char_boundary(a) {
        a -= 1;
    }
    let mut b = (a + len).min(text.len());
    while !text.is_char_boundary(b) {
        b += 1;
    }
    format!("{}{}{}", &text[..a], with, &text[b..])
}

const PIECES: &[&str] = &[
    "",
    "=",
    "nan",
    "-5.0",
    "\"x\"",
    "[",
    "]]",
    "\n",
    "[[road]]\n",
    "1e999",
    "inf",
    "#",
    "0",
    "true",
    "[demand]\n",
    "{",
    ".",
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    #[test]
    fn no_panic_on_mutated_text(at in 0usize..4000, len in 0usize..12, piece in 0usize..PIECES.len()) {
        let vehicle = mutate(&read("vehicle.toml"), at, len, PIECES[piece]);
        if let Err(e) = parse_vehicle(Path::new("vehicle.toml"), &vehicle) {
            prop_assert_eq!(e.file, PathBuf::from("vehicle.toml"));
        }
        let roads_text = mutate(&read("roads.toml"), at, len, PIECES[piece]);
        // CSV paths resolve against the real config directory.
        let roads_file = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/roads.toml");
        let _ = parse_roads(&roads_file, &roads_text);
        let roads = grip_config::load_roads(&roads_file).unwrap();
        let scen = mutate(&read("scenarios/paper.toml"), at, len, PIECES[piece]);
        if let Err(e) = parse_scenario(Path::new("paper.toml"), &scen, &roads) {
            prop_assert_eq!(e.file, PathBuf::from("paper.toml"));
            prop_assert!(!e.reason.is_empty());
        }
    }
}
