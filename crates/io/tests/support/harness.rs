//! A minimal libtest-compatible runner for this crate's `harness = false`
//! test binaries (they spawn themselves as child processes, so they need
//! their own `main`). It understands what cargo test and cargo nextest pass:
//! `--list [--format terse] [--ignored]` lists the tests as `name: test`;
//! a positional filter (substring, or whole name with `--exact`) selects
//! tests; other flags (`--nocapture`, `--test-threads=N`, ...) are accepted
//! and ignored. Exits non-zero when a selected test fails.

use std::panic::{UnwindSafe, catch_unwind};

/// Run the selected `tests` (name, function) and exit with the result.
pub fn run_tests(tests: &[(&str, fn())]) {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let has = |flag: &str| args.iter().any(|a| a == flag);
    let mut filter: Option<&str> = None;
    let mut skip_next = false;
    for a in &args {
        if skip_next {
            skip_next = false;
            continue;
        }
        if a == "--format" || a == "--logfile" || a == "--skip" || a == "--color" {
            skip_next = true;
        } else if !a.starts_with('-') && filter.is_none() {
            filter = Some(a);
        }
    }
    let exact = has("--exact");
    let selected: Vec<&(&str, fn())> = tests
        .iter()
        .filter(|(name, _)| match filter {
            None => true,
            Some(f) if exact => *name == f,
            Some(f) => name.contains(f),
        })
        .collect();
    if has("--list") {
        // none of these tests is #[ignore]d
        if !has("--ignored") {
            for (name, _) in &selected {
                println!("{name}: test");
            }
        }
        return;
    }
    let mut failed = 0;
    for (name, f) in &selected {
        if !run_one(name, *f) {
            failed += 1;
        }
    }
    println!(
        "\ntest result: {}. {} passed; {failed} failed",
        if failed == 0 { "ok" } else { "FAILED" },
        selected.len() - failed
    );
    if failed > 0 {
        std::process::exit(101);
    }
}

fn run_one(name: &str, f: impl FnOnce() + UnwindSafe) -> bool {
    println!("test {name} ...");
    let ok = catch_unwind(f).is_ok();
    println!("test {name} ... {}", if ok { "ok" } else { "FAILED" });
    ok
}
