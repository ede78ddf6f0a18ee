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
}
