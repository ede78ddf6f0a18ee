//! The bench's output: a Markdown table for people, JSON and CSV for
//! programs.

use std::io::Write;
use std::path::Path;

use serde::Serialize;

use crate::verdict::{Budget, Line, Measurements, Overall};

/// The whole result of one run, as written to `bench.json`.
#[derive(Debug, Serialize)]
pub struct Report<'a> {
    /// Where and how the run was made (host, kernel, CPUs, mode, date).
    pub conditions: &'a [(String, String)],
    /// The limits used.
    pub budget: &'a Budget,
    /// Every measurement.
    pub measurements: &'a Measurements,
    /// The verdict lines.
    pub lines: &'a [Line],
    /// The verdict.
    pub overall: Overall,
}

/// The verdict table (Markdown) and the overall line.
pub fn table(lines: &[Line], overall: Overall) -> String {
    let mut s =
        String::from("| item | measured | limit | verdict | reason |\n|---|---|---|---|---|\n");
    for l in lines {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} |\n",
            l.item,
            l.measured,
            l.limit,
            l.verdict.as_str(),
            l.reason.replace('|', "/")
        ));
    }
    let n = |v| lines.iter().filter(|l| l.verdict == v).count();
    use crate::verdict::Verdict::*;
    s.push_str(&format!(
        "\nverdict: {} ({} PASS, {} FAIL, {} NOT MEASURED, {} INFO)\n",
        match overall {
            Overall::Pass => "PASS",
            Overall::Fail => "FAIL",
            Overall::Incomplete => "INCOMPLETE",
        },
        n(Pass),
        n(Fail),
        n(NotMeasured),
        n(Info)
    ));
    s
}

/// Writes the verdict lines as CSV (`item,measured,limit,verdict,reason,value,limit_value`).
pub fn write_csv(path: &Path, lines: &[Line]) -> anyhow::Result<()> {
    let mut w =
        csv::Writer::from_path(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    w.write_record([
        "item",
        "measured",
        "limit",
        "verdict",
        "reason",
        "value",
        "limit_value",
    ])?;
    let num = |v: Option<f64>| v.map(|x| format!("{x}")).unwrap_or_default();
    for l in lines {
        w.write_record([
            l.item.as_str(),
            l.measured.as_str(),
            l.limit.as_str(),
            l.verdict.as_str(),
            l.reason.as_str(),
            &num(l.value),
            &num(l.limit_value),
        ])?;
    }
    w.flush()?;
    Ok(())
}

/// Writes the report as pretty JSON.
pub fn write_json(path: &Path, r: &Report<'_>) -> anyhow::Result<()> {
    let mut f =
        std::fs::File::create(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    serde_json::to_writer_pretty(&mut f, r)?;
    writeln!(f)?;
    Ok(())
}
