//! A warning said once per process: a file several parts of one process
//! load (e.g. `grip drive` reads the vehicle file, and echoes the same
//! warning from the tcs-loop and plant-sim it supervises) warns once.

use std::collections::HashSet;
use std::sync::{Mutex, OnceLock};

fn said() -> &'static Mutex<HashSet<String>> {
    static SAID: OnceLock<Mutex<HashSet<String>>> = OnceLock::new();
    SAID.get_or_init(|| Mutex::new(HashSet::new()))
}

/// Whether this process has not said `line` before (and it now counts as
/// said). A poisoned lock says "first time": a warning said twice is
/// better than none.
pub fn first_time(line: &str) -> bool {
    match said().lock() {
        Ok(mut s) => s.insert(line.to_owned()),
        Err(_) => true,
    }
}

/// `line` on stderr unless this process has already said it.
pub fn warn_once(line: &str) {
    if first_time(line) {
        eprintln!("{line}");
    }
}

/// `line` on stderr unless this process has already said a line of the
/// same `key`: for a warning whose file is named by a path that varies
/// within one command (`grip generate` loads each log's scenario from a
/// copy of its own, after checking the user's file) while what it says
/// does not.
pub fn warn_once_as(key: &str, line: &str) {
    if first_time_as(key, line) {
        eprintln!("{line}");
    }
}

/// Whether this process has said neither a line of `key` nor `line` (and
/// both now count as said).
fn first_time_as(key: &str, line: &str) -> bool {
    // keys kept apart from lines
    let key = first_time(&format!("\u{0}{key}"));
    first_time(line) && key
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_is_said_once() {
        let l = "warning: x.toml: a line no other test says";
        assert!(first_time(l));
        assert!(!first_time(l));
        assert!(first_time("warning: x.toml: another line"));
    }

    #[test]
    fn a_key_is_said_once_whatever_the_line() {
        let key = "a key no other test uses";
        assert!(first_time_as(key, "warning: /tmp/a/x.toml: k"));
        assert!(!first_time_as(key, "warning: /tmp/b/x.toml: k"));
        assert!(!first_time("warning: /tmp/a/x.toml: k"));
        assert!(!first_time_as(
            "another key no other test uses",
            "warning: /tmp/a/x.toml: k"
        ));
        assert!(first_time(key), "keys apart from lines");
    }
}
