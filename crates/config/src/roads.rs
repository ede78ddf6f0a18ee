//! `config/roads.toml`: the road catalogue as data.
//!
//! ```toml
//! [[road]]
//! name = "asphalt"              # catalogue key (unique)
//! label = "Asphalt (dry)"       # optional, for plots and tables
//! source = "Burckhardt (1993)"  # optional, free text: where the numbers come from
//! model = "burckhardt"          # burckhardt | pacejka | table
//! c1 = 1.2801
//! c2 = 23.99
//! c3 = 0.52
//!
//! [[road]]
//! name = "gravel"
//! model = "table"
//! csv = "roads/gravel.csv"      # relative to roads.toml; or inline: slip = [...], mu = [...]
//! ```
//!
//! CSV tables: a header row `slip,mu`, then one row per knot; lines starting
//! with `#` are comments. A bad CSV gives an error naming the CSV file, the
//! line and the reason.

use std::path::{Path, PathBuf};

use grip_physics::{FrictionModel, InvalidField, Road, RoadCatalogue};

use crate::error::{ConfigError, parse_toml, read_file};

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
enum ModelKind {
    Burckhardt,
    Pacejka,
    Table,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RoadSpec {
    name: String,
    label: Option<String>,
    #[allow(dead_code)] // documentation in the data file; not used by the code
    source: Option<String>,
    model: ModelKind,
    c1: Option<f64>,
    c2: Option<f64>,
    c3: Option<f64>,
    b: Option<f64>,
    c: Option<f64>,
    d: Option<f64>,
    e: Option<f64>,
    csv: Option<PathBuf>,
    slip: Option<Vec<f64>>,
    mu: Option<Vec<f64>>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RoadsFile {
    #[serde(default)]
    road: Vec<RoadSpec>,
}

/// A table read from CSV, with the file line of each data row.
struct CsvTable {
    file: PathBuf,
    slip: Vec<f64>,
    mu: Vec<f64>,
    lines: Vec<u64>,
}

/// Parses `text`, the contents of the table `file`.
fn read_csv_table(file: &Path, text: &str) -> Result<CsvTable, ConfigError> {
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .has_headers(true)
        .from_reader(text.as_bytes());
    let headers = rdr.headers().map_err(|e| {
        ConfigError::new(file, "header", format!("cannot read the header row: {e}"))
    })?;
    let cols: Vec<&str> = headers.iter().collect();
    if cols != ["slip", "mu"] {
        return Err(ConfigError::new(
            file,
            "header",
            format!("must be `slip,mu` (got `{}`)", cols.join(",")),
        ));
    }
    let mut t = CsvTable {
        file: file.to_owned(),
        slip: Vec::new(),
        mu: Vec::new(),
        lines: Vec::new(),
    };
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            let line = e
                .position()
                .map(|p| format!("line {}", p.line()))
                .unwrap_or_default();
            ConfigError::new(file, line, format!("malformed row: {e}"))
        })?;
        let line = rec.position().map(|p| p.line()).unwrap_or(0);
        if rec.len() != 2 {
            return Err(ConfigError::new(
                file,
                format!("line {line}"),
                format!("expected 2 columns (slip,mu), got {}", rec.len()),
            ));
        }
        let mut vals = [0.0; 2];
        for (k, col) in ["slip", "mu"].iter().enumerate() {
            let s = &rec[k];
            vals[k] = s.parse::<f64>().map_err(|_| {
                ConfigError::new(
                    file,
                    format!("line {line}, column {col}"),
                    format!("not a number: `{s}`"),
                )
            })?;
        }
        t.slip.push(vals[0]);
        t.mu.push(vals[1]);
        t.lines.push(line);
    }
    Ok(t)
}

/// Map a table validation error (`slip[i]`, `mu[i]`) back to the CSV line.
fn csv_error(t: &CsvTable, e: InvalidField) -> ConfigError {
    let parsed = e.field.split_once('[').and_then(|(col, rest)| {
        let i: usize = rest.trim_end_matches(']').parse().ok()?;
        Some((col.to_owned(), i))
    });
    match parsed {
        Some((col, i)) if i < t.lines.len() => ConfigError::new(
            &t.file,
            format!("line {}, column {col}", t.lines[i]),
            e.reason,
        ),
        _ => ConfigError::new(&t.file, e.field, e.reason),
    }
}

fn build_road(file: &Path, base: &Path, i: usize, spec: RoadSpec) -> Result<Road, ConfigError> {
    let at = |field: &str| format!("road[{i}].{field}");
    let present = |name: &str| -> bool {
        match name {
            "c1" => spec.c1.is_some(),
            "c2" => spec.c2.is_some(),
            "c3" => spec.c3.is_some(),
            "b" => spec.b.is_some(),
            "c" => spec.c.is_some(),
            "d" => spec.d.is_some(),
            "e" => spec.e.is_some(),
            "csv" => spec.csv.is_some(),
            "slip" => spec.slip.is_some(),
            "mu" => spec.mu.is_some(),
            _ => false,
        }
    };
    let (own, kind): (&[&str], &str) = match spec.model {
        ModelKind::Burckhardt => (&["c1", "c2", "c3"], "burckhardt"),
        ModelKind::Pacejka => (&["b", "c", "d", "e"], "pacejka"),
        ModelKind::Table => (&["csv", "slip", "mu"], "table"),
    };
    for f in ["c1", "c2", "c3", "b", "c", "d", "e", "csv", "slip", "mu"] {
        if present(f) && !own.contains(&f) {
            return Err(ConfigError::new(
                file,
                at(f),
                format!(
                    "does not belong to model `{kind}` (its fields: {})",
                    own.join(", ")
                ),
            ));
        }
    }
    let need = |v: Option<f64>, f: &str| {
        v.ok_or_else(|| ConfigError::new(file, at(f), format!("missing (model `{kind}` needs it)")))
    };
    let model_err = |e: InvalidField| ConfigError::invalid(file, &format!("road[{i}]"), e);
    let road = match spec.model {
        ModelKind::Burckhardt => {
            let m = FrictionModel::Burckhardt {
                c1: need(spec.c1, "c1")?,
                c2: need(spec.c2, "c2")?,
                c3: need(spec.c3, "c3")?,
            };
            Road::new(spec.name, m).map_err(model_err)?
        }
        ModelKind::Pacejka => {
            let m = FrictionModel::Pacejka {
                b: need(spec.b, "b")?,
                c: need(spec.c, "c")?,
                d: need(spec.d, "d")?,
                e: spec.e.unwrap_or(0.0),
            };
            Road::new(spec.name, m).map_err(model_err)?
        }
        ModelKind::Table => match (spec.csv, spec.slip, spec.mu) {
            (Some(csv), None, None) => {
                let path = base.join(&csv);
                // a table that cannot be read is a mistake of this file's
                // `csv` field: name both files
                let text = std::fs::read_to_string(&path).map_err(|e| {
                    ConfigError::new(
                        file,
                        at("csv"),
                        format!("cannot read the table {}: {e}", path.display()),
                    )
                })?;
                let t = read_csv_table(&path, &text)?;
                let m = FrictionModel::Table {
                    slip: t.slip.clone(),
                    mu: t.mu.clone(),
                };
                Road::new(spec.name, m).map_err(|e| {
                    if e.field == "name" {
                        model_err(e)
                    } else {
                        csv_error(&t, e)
                    }
                })?
            }
            (None, Some(slip), Some(mu)) => {
                Road::new(spec.name, FrictionModel::Table { slip, mu }).map_err(model_err)?
            }
            _ => {
                return Err(ConfigError::new(
                    file,
                    at("csv"),
                    "a table needs either `csv = \"file.csv\"` or both `slip = [...]` and `mu = [...]`",
                ));
            }
        },
    };
    Ok(match spec.label {
        Some(l) => road.with_label(l),
        None => road,
    })
}

/// Parse the road catalogue from `text` (the contents of `file`); CSV paths
/// are resolved relative to `file`'s directory.
pub fn parse_roads(file: &Path, text: &str) -> Result<RoadCatalogue, ConfigError> {
    let f: RoadsFile = parse_toml(file, text)?;
    if f.road.is_empty() {
        return Err(ConfigError::new(
            file,
            "road",
            "the road list is empty: give at least one [[road]]",
        ));
    }
    let base = file.parent().unwrap_or(Path::new("."));
    let roads = f
        .road
        .into_iter()
        .enumerate()
        .map(|(i, spec)| {
            // the entry's index is what the field gives; its name is what
            // the reader looks for in the file (road[5] is the sixth
            // [[road]], counted from 0): said beside it
            let name = spec.name.clone();
            build_road(file, base, i, spec).map_err(|mut e| {
                let own_field = e.file == file && !e.field.ends_with(".name");
                if own_field && !name.trim().is_empty() {
                    e.reason = format!("road `{name}`: {}", e.reason);
                }
                e
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    RoadCatalogue::new(roads).map_err(|e| ConfigError::invalid(file, "", e))
}

/// Load `config/roads.toml` (or any file of that shape); a road whose
/// peak friction no tyre on a road reaches is said on stderr, once
/// ([`implausible_peaks`]).
pub fn load_roads(path: impl AsRef<Path>) -> Result<RoadCatalogue, ConfigError> {
    let path = path.as_ref();
    let roads = parse_roads(path, &read_file(path)?)?;
    // said once per road and peak whatever the path (grip generate reads
    // each log's copy of the user's file after the file itself)
    for (i, r) in implausible(&roads) {
        crate::warn::warn_once_as(
            &format!("roads.mu_peak {} {}", r.name(), r.mu_peak()),
            &implausible_line(path, i, r),
        );
    }
    Ok(roads)
}

/// The highest peak friction coefficient a tyre on a road plausibly
/// reaches (dry asphalt about 1.2, racing slicks up to about 1.8).
pub const MU_PEAK_PLAUSIBLE: f64 = 2.0;

/// One warning per road of `roads` (from `file`) whose μ_peak is above
/// [`MU_PEAK_PLAUSIBLE`]: most likely a coefficient in the wrong unit or
/// a typo (Burckhardt `c1 = 50` for 0.50 gives μ_peak 50), which lifts
/// the road's torque cap as far. Kept a warning, not an error: a study
/// may mean it.
pub fn implausible_peaks(file: &Path, roads: &RoadCatalogue) -> Vec<String> {
    implausible(roads)
        .map(|(i, r)| implausible_line(file, i, r))
        .collect()
}

/// The roads of `roads` (with their index) above [`MU_PEAK_PLAUSIBLE`].
fn implausible(roads: &RoadCatalogue) -> impl Iterator<Item = (usize, &grip_physics::Road)> {
    roads
        .iter()
        .enumerate()
        .filter(|(_, r)| r.mu_peak() > MU_PEAK_PLAUSIBLE)
}

/// The warning for road `i` (`r`) of `file`.
fn implausible_line(file: &Path, i: usize, r: &grip_physics::Road) -> String {
    format!(
        "warning: {}: road[{i}] ({}): mu_peak {} is above any tyre on a road (dry asphalt about 1.2, racing slicks up to about 1.8): a coefficient in the wrong unit or a typo? Every road-aware cap and target of this road follows it",
        file.display(),
        r.name(),
        if r.mu_peak() < 1e4 {
            format!("{:.3}", r.mu_peak())
        } else {
            format!("{:.3e}", r.mu_peak())
        }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A peak no tyre reaches (snow's c1 typed 50) is named; the shipped
    /// catalogue has none.
    #[test]
    fn an_implausible_peak_is_named() {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/roads.toml");
        let roads = load_roads(&shipped).unwrap();
        assert!(implausible_peaks(&shipped, &roads).is_empty());
        let text = std::fs::read_to_string(&shipped).unwrap();
        assert!(text.contains("c1 = 0.1946"), "snow's c1");
        let typo = text.replacen("c1 = 0.1946", "c1 = 50", 1);
        let roads = parse_roads(&shipped, &typo).unwrap();
        let w = implausible_peaks(&shipped, &roads);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("(snow): mu_peak 49.99") && w[0].contains("roads.toml"),
            "{w:?}"
        );
    }

    const GOOD: &str = r#"
[[road]]
name = "asphalt"
label = "Asphalt (dry)"
model = "burckhardt"
c1 = 1.2801
c2 = 23.99
c3 = 0.52

[[road]]
name = "pac"
model = "pacejka"
b = 10.0
c = 1.9
d = 1.0

[[road]]
name = "inline"
model = "table"
slip = [0.0, 0.1, 0.3]
mu = [0.0, 0.5, 0.4]
"#;

    fn parse(text: &str) -> Result<RoadCatalogue, ConfigError> {
        parse_roads(Path::new("config/roads.toml"), text)
    }

    #[test]
    fn good_catalogue() {
        let c = parse(GOOD).unwrap();
        assert_eq!(c.len(), 3);
        assert_eq!(c[0].label(), "Asphalt (dry)");
        assert_eq!(c[1].label(), "pac");
        assert!((c[2].lambda_opt() - 0.1).abs() < 1e-12);
    }

    #[test]
    fn empty_road_list() {
        let e = parse("").unwrap_err();
        assert_eq!(
            e.to_string(),
            "config/roads.toml: field `road`: the road list is empty: give at least one [[road]]"
        );
    }

    #[test]
    fn unknown_field_and_wrong_model_field() {
        let e = parse("[[road]]\nname = \"a\"\nmodel = \"burckhardt\"\nc1 = 1.0\nc2 = 20.0\nc3 = 0.5\nc4 = 1.0\n").unwrap_err();
        assert_eq!(e.field, "road[0].c4", "{e}");
        assert!(e.reason.starts_with("line 7: unknown field `c4`"), "{e}");
        let e = parse("[[road]]\nname = \"a\"\nmodel = \"burckhardt\"\nc1 = 1.0\nc2 = 20.0\nc3 = 0.5\nb = 1.0\n").unwrap_err();
        assert_eq!(e.field, "road[0].b", "{e}");
        let e = parse("[[road]]\nname = \"a\"\nmodel = \"burckhardt\"\nc1 = 1.0\nc2 = 20.0\n")
            .unwrap_err();
        assert_eq!(e.field, "road[0].c3", "{e}");
        assert!(e.reason.contains("missing"), "{e}");
        let e = parse("[[road]]\nname = \"a\"\nmodel = \"magic\"\n").unwrap_err();
        assert_eq!(e.field, "road[0].model", "{e}");
    }

    #[test]
    fn nan_and_duplicates() {
        let e = parse(
            "[[road]]\nname = \"a\"\nmodel = \"burckhardt\"\nc1 = nan\nc2 = 20.0\nc3 = 0.5\n",
        )
        .unwrap_err();
        assert_eq!(e.field, "road[0].c1", "{e}");
        // the entry is named beside its index (which counts from 0)
        let e = parse(
            "[[road]]\nname = \"a\"\nmodel = \"pacejka\"\nb = 10.0\nc = 1.9\nd = 1.0\n\
             [[road]]\nname = \"snow\"\nmodel = \"burckhardt\"\nc1 = 0.2\nc2 = -94.1\nc3 = 0.06\n",
        )
        .unwrap_err();
        assert_eq!(e.field, "road[1].c2", "{e}");
        assert!(e.reason.starts_with("road `snow`: must be > 0"), "{e}");
        let two = "[[road]]\nname = \"a\"\nmodel = \"pacejka\"\nb = 10.0\nc = 1.9\nd = 1.0\n";
        let e = parse(&format!("{two}{two}")).unwrap_err();
        assert_eq!(e.field, "road[1].name", "{e}");
        // a name longer than the services' messages carry
        let long = two.replace("\"a\"", "\"gravel_after_rain\"");
        let e = parse(&long).unwrap_err();
        assert_eq!(e.field, "road[0].name", "{e}");
        assert!(e.to_string().contains("17 bytes long; at most 16"), "{e}");
    }

    #[test]
    fn csv_tables() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("roads")).unwrap();
        let roads = dir.path().join("roads.toml");
        std::fs::write(
            &roads,
            "[[road]]\nname = \"t\"\nmodel = \"table\"\ncsv = \"roads/t.csv\"\n",
        )
        .unwrap();
        let csv = dir.path().join("roads/t.csv");

        std::fs::write(&csv, "# measured\nslip,mu\n0.0,0.0\n0.1, 0.6\n0.5,0.5\n").unwrap();
        let c = load_roads(&roads).unwrap();
        assert!((c[0].mu(0.05) - 0.3).abs() < 1e-12);

        std::fs::write(&csv, "slip,mu\n0.0,0.0\n0.1,abc\n").unwrap();
        let e = load_roads(&roads).unwrap_err();
        assert_eq!(e.file, csv);
        assert_eq!(e.field, "line 3, column mu", "{e}");
        assert!(e.reason.contains("not a number"), "{e}");

        std::fs::write(&csv, "slip,mu\n0.0,0.0\n0.2,0.5\n0.1,0.6\n").unwrap();
        let e = load_roads(&roads).unwrap_err();
        assert_eq!(e.field, "line 4, column slip", "{e}");
        assert!(e.reason.contains("strictly increasing"), "{e}");

        std::fs::write(&csv, "slip,mu\n0.0,0.0\n0.2,0.5,7\n").unwrap();
        let e = load_roads(&roads).unwrap_err();
        assert_eq!(e.file, csv);
        assert!(e.field.starts_with("line 3"), "{e}");

        std::fs::write(&csv, "s,m\n0.0,0.0\n").unwrap();
        assert_eq!(load_roads(&roads).unwrap_err().field, "header");

        // a missing table is a mistake of roads.toml's `csv` field: the
        // error names roads.toml and the field, and the table's path (the
        // config fuzz target found it naming only the table)
        std::fs::remove_file(&csv).unwrap();
        let e = load_roads(&roads).unwrap_err();
        assert_eq!(e.file, roads);
        assert_eq!(e.field, "road[0].csv", "{e}");
        assert!(
            e.reason.starts_with("road `t`: cannot read the table"),
            "{e}"
        );
        assert!(e.reason.contains(&csv.display().to_string()), "{e}");
    }
}
