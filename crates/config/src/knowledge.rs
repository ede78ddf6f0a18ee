//! `[knowledge]` of the arte service's configuration (`config/arte-svc.toml`)
//! -> [`KnowledgeConfig`]: the per-road overrides of the one road-knowledge
//! rule (`grip_tcs::knowledge::RoadTable`). The arte service reads the whole
//! file; `grip sim` and tcs-loop read this section of the same file, so a
//! simulation and a drive given the same configuration directory build the
//! same table.

use std::path::Path;

use grip_physics::RoadCatalogue;
pub use grip_tcs::knowledge::{KnowledgeConfig, RoadTable};

use crate::{ConfigError, parse_toml, read_file};

/// The file name, in a configuration directory, that holds `[knowledge]`.
pub const KNOWLEDGE_FILE: &str = "arte-svc.toml";

/// Only `[knowledge]`; the arte service's other sections are its own.
#[derive(serde::Deserialize)]
struct Section {
    #[serde(default)]
    knowledge: KnowledgeConfig,
}

/// Parse `[knowledge]` from TOML `text` (the contents of `file`) and
/// validate it against `roads`; a missing section is the default (no
/// overrides).
pub fn parse_knowledge(
    file: &Path,
    text: &str,
    roads: &RoadCatalogue,
) -> Result<KnowledgeConfig, ConfigError> {
    let s: Section = parse_toml(file, text)?;
    s.knowledge
        .validate(roads)
        .map_err(|e| ConfigError::invalid(file, "knowledge", e))?;
    Ok(s.knowledge)
}

/// Read `[knowledge]` of `path` (see [`parse_knowledge`]).
pub fn load_knowledge(
    path: impl AsRef<Path>,
    roads: &RoadCatalogue,
) -> Result<KnowledgeConfig, ConfigError> {
    let path = path.as_ref();
    parse_knowledge(path, &read_file(path)?, roads)
}

/// The road table of `roads` with the `[knowledge]` of `path`.
pub fn load_road_table(
    path: impl AsRef<Path>,
    roads: &RoadCatalogue,
) -> Result<RoadTable, ConfigError> {
    let path = path.as_ref();
    let k = load_knowledge(path, roads)?;
    RoadTable::new(roads, &k).map_err(|e| ConfigError::invalid(path, "knowledge", e))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roads() -> RoadCatalogue {
        RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap()
    }

    #[test]
    fn reads_only_knowledge_and_names_bad_fields() {
        let f = Path::new("arte-svc.toml");
        let k = parse_knowledge(f, "model = \"m\"\n[stream]\nhop_s = 0.1\n", &roads()).unwrap();
        assert_eq!(k, KnowledgeConfig::default());
        let k = parse_knowledge(f, "[knowledge]\nalpha = { snow = 0.9 }\n", &roads()).unwrap();
        assert_eq!(k.alpha.get("snow"), Some(&0.9));
        let e = parse_knowledge(f, "[knowledge]\nalpha = { ice = 0.9 }\n", &roads()).unwrap_err();
        assert_eq!(e.field, "knowledge.alpha.ice", "{e}");
        assert_eq!(e.file, f);
        let e = parse_knowledge(f, "[knowledge]\nbeta = 1\n", &roads()).unwrap_err();
        assert!(e.to_string().contains("beta"), "{e}");
    }
}
