//! `[synth.aliases]` of `audio-acq.toml`: catalogue roads the synthesiser
//! has no sound for, played as another road's sound. The one home of the
//! rule; audio-acq's start-up, `grip sim --arte acoustic` and the drive
//! summary all resolve a table through [`SynthAliases::resolve`]:
//!
//! - a value that is not a string is refused;
//! - a SOUND that is not one of [`ROADS`] is refused (also for a ROAD the
//!   synthesiser has: audio-acq has always refused it);
//! - an alias of a ROAD the synthesiser has a sound for is ignored (the road
//!   plays its own sound), with a note the caller can print;
//! - every other ROAD = SOUND plays ROAD as SOUND. A road neither
//!   synthesisable nor aliased gives no tyre-road sound (vehicle and
//!   microphone only).
//!
//! Errors name the file, the field `synth.aliases.ROAD` and the reason.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde::de::{self, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};

use super::{ROADS, road_index};

/// One value of `[synth.aliases]` as written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AliasValue {
    /// A string: the name of the sound to play.
    Sound(String),
    /// Anything else, described (e.g. ``integer `3` ``).
    NotAString(String),
}

/// `[synth.aliases]` as written: ROAD = SOUND, not yet checked
/// ([`SynthAliases::resolve`] applies the rule). Deserialises from any
/// table (values that are not strings are kept, to be refused by name).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SynthAliases(pub BTreeMap<String, AliasValue>);

/// The part of an `audio-acq.toml` the alias rule reads: `[synth.aliases]`
/// (absent: none); every other key is ignored. Deserialise the whole file
/// into it (e.g. `toml::from_str::<AudioAcqAliases>(text)`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
pub struct AudioAcqAliases {
    /// `[synth]`.
    #[serde(default)]
    synth: SynthPart,
}

#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
struct SynthPart {
    #[serde(default)]
    aliases: SynthAliases,
}

impl AudioAcqAliases {
    /// The file's `[synth.aliases]`, as written.
    pub fn aliases(&self) -> &SynthAliases {
        &self.synth.aliases
    }
}

/// The effective aliases: what [`SynthAliases::resolve`] leaves.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ResolvedAliases {
    /// ROAD → SOUND (one of [`ROADS`]), for roads the synthesiser has no
    /// sound for.
    pub sounds: BTreeMap<String, String>,
    /// Entries ignored, one line each, naming the file and field: an alias
    /// of a road the synthesiser has a sound for.
    pub notes: Vec<String>,
}

/// An alias refused: which file, which field (`synth.aliases.ROAD`) and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: field `{field}`: {reason}", file.display())]
pub struct AliasError {
    /// The file the table came from.
    pub file: PathBuf,
    /// `synth.aliases.ROAD`.
    pub field: String,
    /// What is wrong, with the value.
    pub reason: String,
}

impl SynthAliases {
    /// Whether the table has no entry.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The rule (module docs) applied to the table of `file`.
    pub fn resolve(&self, file: &Path) -> Result<ResolvedAliases, AliasError> {
        let mut out = ResolvedAliases::default();
        for (road, value) in &self.0 {
            let field = format!("synth.aliases.{road}");
            let refuse = |reason: String| AliasError {
                file: file.to_owned(),
                field: field.clone(),
                reason,
            };
            let to = match value {
                AliasValue::Sound(s) => s,
                AliasValue::NotAString(what) => {
                    return Err(refuse(format!(
                        "{what} is not a synthesiser road's name (a string)"
                    )));
                }
            };
            if road_index(to).is_none() {
                return Err(refuse(format!(
                    "`{to}` is not a road the synthesiser knows ({})",
                    ROADS.join(", ")
                )));
            }
            if road_index(road).is_some() {
                out.notes.push(format!(
                    "{}: field `{field}` = \"{to}\" is ignored: the synthesiser has a sound of its own for `{road}` and plays it",
                    file.display()
                ));
                continue;
            }
            out.sounds.insert(road.clone(), to.clone());
        }
        Ok(out)
    }
}

impl From<&BTreeMap<String, String>> for SynthAliases {
    /// A table whose values are all strings (audio-acq's parsed
    /// `[synth] aliases`).
    fn from(m: &BTreeMap<String, String>) -> Self {
        Self(
            m.iter()
                .map(|(k, v)| (k.clone(), AliasValue::Sound(v.clone())))
                .collect(),
        )
    }
}

impl<'de> Deserialize<'de> for AliasValue {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ValueVisitor)
    }
}

impl<'de> Deserialize<'de> for SynthAliases {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        BTreeMap::<String, AliasValue>::deserialize(d).map(Self)
    }
}

struct ValueVisitor;

fn other<E>(what: impl fmt::Display) -> Result<AliasValue, E> {
    Ok(AliasValue::NotAString(what.to_string()))
}

impl<'de> Visitor<'de> for ValueVisitor {
    type Value = AliasValue;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a synthesiser road's name (a string)")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<AliasValue, E> {
        Ok(AliasValue::Sound(v.to_owned()))
    }

    fn visit_bool<E: de::Error>(self, v: bool) -> Result<AliasValue, E> {
        other(format_args!("boolean `{v}`"))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<AliasValue, E> {
        other(format_args!("integer `{v}`"))
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<AliasValue, E> {
        other(format_args!("integer `{v}`"))
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<AliasValue, E> {
        other(format_args!("float `{v}`"))
    }

    fn visit_unit<E: de::Error>(self) -> Result<AliasValue, E> {
        other("nothing")
    }

    fn visit_none<E: de::Error>(self) -> Result<AliasValue, E> {
        other("nothing")
    }

    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<AliasValue, D::Error> {
        d.deserialize_any(self)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<AliasValue, A::Error> {
        while seq.next_element::<IgnoredAny>()?.is_some() {}
        other("an array")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<AliasValue, A::Error> {
        while map.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
        other("a table")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(entries: &[(&str, AliasValue)]) -> SynthAliases {
        SynthAliases(
            entries
                .iter()
                .map(|(k, v)| ((*k).to_owned(), v.clone()))
                .collect(),
        )
    }

    fn sound(s: &str) -> AliasValue {
        AliasValue::Sound(s.to_owned())
    }

    const FILE: &str = "config/audio-acq.toml";

    #[test]
    fn roads_without_a_sound_play_their_alias() {
        let r = table(&[
            ("asphalt_mf", sound("asphalt")),
            ("wet_gravel", sound("gravel")),
        ])
        .resolve(Path::new(FILE))
        .unwrap();
        assert_eq!(
            r.sounds,
            BTreeMap::from([
                ("asphalt_mf".to_owned(), "asphalt".to_owned()),
                ("wet_gravel".to_owned(), "gravel".to_owned()),
            ])
        );
        assert!(r.notes.is_empty());
        assert_eq!(
            SynthAliases::default().resolve(Path::new(FILE)),
            Ok(ResolvedAliases::default())
        );
    }

    /// An alias of a road the synthesiser has is left out, with a note
    /// naming the file, the field and why.
    #[test]
    fn an_alias_of_a_synthesiser_road_is_ignored_with_a_note() {
        let r = table(&[("snow", sound("gravel")), ("asphalt_mf", sound("asphalt"))])
            .resolve(Path::new(FILE))
            .unwrap();
        assert_eq!(
            r.sounds,
            BTreeMap::from([("asphalt_mf".to_owned(), "asphalt".to_owned())])
        );
        assert_eq!(r.notes.len(), 1);
        let n = &r.notes[0];
        assert!(
            n.starts_with(
                "config/audio-acq.toml: field `synth.aliases.snow` = \"gravel\" is ignored"
            ),
            "{n}"
        );
        assert!(n.contains("sound of its own for `snow`"), "{n}");
    }

    #[test]
    fn an_unknown_sound_is_refused_naming_the_field() {
        for road in ["ice", "snow"] {
            let e = table(&[(road, sound("tarmac"))])
                .resolve(Path::new(FILE))
                .unwrap_err();
            assert_eq!(e.file, Path::new(FILE));
            assert_eq!(e.field, format!("synth.aliases.{road}"));
            assert!(
                e.reason
                    .starts_with("`tarmac` is not a road the synthesiser knows (asphalt, gravel"),
                "{e}"
            );
            assert!(
                e.to_string().starts_with(&format!(
                    "config/audio-acq.toml: field `synth.aliases.{road}`: `tarmac`"
                )),
                "{e}"
            );
        }
    }

    #[test]
    fn a_value_that_is_not_a_string_is_refused_naming_the_field() {
        let e = table(&[("wet_gravel", AliasValue::NotAString("integer `3`".into()))])
            .resolve(Path::new(FILE))
            .unwrap_err();
        assert_eq!(e.field, "synth.aliases.wet_gravel");
        assert_eq!(
            e.reason,
            "integer `3` is not a synthesiser road's name (a string)"
        );
    }

    /// Deserialised from a document: strings kept, anything else described
    /// (not a deserialisation error), so that the refusal names the key.
    #[test]
    fn values_deserialise_as_written() {
        let json = r#"{"synth": {"seed": 1, "aliases": {"a": "gravel", "b": 3, "c": true, "d": [1], "e": {"x": 1}, "f": 1.5}}, "audio": {}}"#;
        let doc: AudioAcqAliases = serde_json::from_str(json).unwrap();
        assert_eq!(
            doc.aliases(),
            &table(&[
                ("a", sound("gravel")),
                ("b", AliasValue::NotAString("integer `3`".into())),
                ("c", AliasValue::NotAString("boolean `true`".into())),
                ("d", AliasValue::NotAString("an array".into())),
                ("e", AliasValue::NotAString("a table".into())),
                ("f", AliasValue::NotAString("float `1.5`".into())),
            ])
        );
        let none: AudioAcqAliases = serde_json::from_str(r#"{"synth": {"seed": 1}}"#).unwrap();
        assert!(none.aliases().is_empty());
        let none: AudioAcqAliases = serde_json::from_str("{}").unwrap();
        assert!(none.aliases().is_empty());
        assert!(serde_json::from_str::<AudioAcqAliases>(r#"{"synth": {"aliases": 3}}"#).is_err());
        let strings = BTreeMap::from([("x".to_owned(), "snow".to_owned())]);
        assert_eq!(SynthAliases::from(&strings), table(&[("x", sound("snow"))]));
    }
}
