//! Logged against replayed messages, field by field, in each record's own
//! JSON encoding (the log's), so a field added to a payload is compared
//! without a change here. No tolerance: a field is identical when its
//! encoded value is (floats are written in their shortest round-trip form,
//! so this is bit equality; NaN equals NaN).

use std::fmt::Write as _;

use grip_io::mcaplog::McapRecord;
use serde_json::{Map, Value};

use super::fields;

/// The first difference of a topic.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Divergence {
    /// Topic (and direction for the CAN log).
    pub topic: String,
    /// Index of the message in the topic (0-based).
    pub index: usize,
    /// Its `seq` field, if it has one.
    pub seq: Option<u64>,
    /// The field (dotted for nested ones), or `(message)` when one side has
    /// no message at that index.
    pub field: String,
    /// Logged value.
    pub old: String,
    /// Replayed value.
    pub new: String,
}

impl std::fmt::Display for Divergence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} message {}", self.topic, self.index)?;
        if let Some(s) = self.seq {
            write!(f, " (seq {s})")?;
        }
        write!(
            f,
            ": field {}: logged {}, replayed {}",
            self.field, self.old, self.new
        )
    }
}

/// One topic compared.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicDiff {
    /// Topic label.
    pub topic: String,
    /// Messages in the log.
    pub logged: usize,
    /// Messages the replay produced.
    pub replayed: usize,
    /// Indices where the two differ (a message present on one side only counts).
    pub differing: usize,
    /// Fields that differ at least once, with how often.
    pub fields: Vec<(String, usize)>,
    /// The first difference.
    pub first: Option<Divergence>,
}

impl TopicDiff {
    /// Nothing differs.
    pub fn identical(&self) -> bool {
        self.differing == 0
    }
}

fn flat(prefix: &str, m: &Map<String, Value>, out: &mut Vec<(String, Value)>) {
    for (k, v) in m {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match v {
            Value::Object(o) => flat(&key, o, out),
            _ => out.push((key, v.clone())),
        }
    }
}

fn show(v: Option<&Value>) -> String {
    match v {
        None => "(absent)".into(),
        Some(Value::Null) => "NaN/null".into(),
        Some(v) => v.to_string(),
    }
}

/// Compares `old` and `new` message by message.
pub fn compare<T: McapRecord>(topic: &str, old: &[T], new: &[T]) -> TopicDiff {
    compare_except(topic, old, new, &[])
}

/// [`compare`], leaving out the fields `ignore` (fields a log predates).
pub fn compare_except<T: McapRecord>(
    topic: &str,
    old: &[T],
    new: &[T],
    ignore: &[&str],
) -> TopicDiff {
    let mut d = TopicDiff {
        topic: topic.to_owned(),
        logged: old.len(),
        replayed: new.len(),
        differing: 0,
        fields: Vec::new(),
        first: None,
    };
    let n = old.len().max(new.len());
    for i in 0..n {
        let (a, b) = (old.get(i).map(fields), new.get(i).map(fields));
        let seq = |m: &Option<Map<String, Value>>| {
            m.as_ref()
                .and_then(|m| m.get("seq"))
                .and_then(Value::as_u64)
        };
        let (Some(a), Some(b)) = (&a, &b) else {
            d.differing += 1;
            if d.first.is_none() {
                d.first = Some(Divergence {
                    topic: topic.to_owned(),
                    index: i,
                    seq: seq(&a).or(seq(&b)),
                    field: "(message)".into(),
                    old: if a.is_some() { "present" } else { "absent" }.into(),
                    new: if b.is_some() { "present" } else { "absent" }.into(),
                });
            }
            continue;
        };
        let (mut fa, mut fb) = (Vec::new(), Vec::new());
        flat("", a, &mut fa);
        flat("", b, &mut fb);
        let mut keys: Vec<&String> = fa.iter().map(|(k, _)| k).collect();
        for (k, _) in &fb {
            if !keys.contains(&k) {
                keys.push(k);
            }
        }
        let mut differs = false;
        for k in keys {
            if ignore.contains(&k.as_str()) {
                continue;
            }
            let va = fa.iter().find(|(x, _)| x == k).map(|(_, v)| v);
            let vb = fb.iter().find(|(x, _)| x == k).map(|(_, v)| v);
            if va != vb {
                differs = true;
                match d.fields.iter_mut().find(|(f, _)| f == k) {
                    Some((_, n)) => *n += 1,
                    None => d.fields.push((k.clone(), 1)),
                }
                if d.first.is_none() {
                    d.first = Some(Divergence {
                        topic: topic.to_owned(),
                        index: i,
                        seq: a.get("seq").and_then(Value::as_u64),
                        field: k.clone(),
                        old: show(va),
                        new: show(vb),
                    });
                }
            }
        }
        d.differing += usize::from(differs);
    }
    d
}

/// The per-topic table.
pub fn render(diffs: &[TopicDiff]) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "  {:<22} {:>9} {:>9} {:>9}  verdict",
        "topic", "logged", "replayed", "differing"
    );
    for d in diffs {
        let verdict = if d.identical() {
            "identical".to_owned()
        } else {
            let f: Vec<String> = d
                .fields
                .iter()
                .take(6)
                .map(|(k, n)| format!("{k} {n}"))
                .collect();
            format!("DIFFERENT (fields: {})", f.join(", "))
        };
        let _ = writeln!(
            o,
            "  {:<22} {:>9} {:>9} {:>9}  {verdict}",
            d.topic, d.logged, d.replayed, d.differing
        );
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_msgs::CycleRecord;

    #[test]
    fn identical_and_first_divergence_named() {
        let mut a = vec![CycleRecord::zeroed(); 3];
        for (k, c) in a.iter_mut().enumerate() {
            c.seq = k as u64;
            c.torque_cmd = 100.0;
            c.internal = f64::NAN;
        }
        let d = compare("grip/tcs/cycle", &a, &a.clone());
        assert!(d.identical(), "{d:?}");
        let mut b = a.clone();
        b[1].torque_cmd = 101.0;
        b[2].faults.crc = 1;
        b.push(CycleRecord::zeroed());
        let d = compare("grip/tcs/cycle", &a, &b);
        assert_eq!(d.differing, 3);
        let f = d.first.unwrap();
        assert_eq!(
            (
                f.index,
                f.seq,
                f.field.as_str(),
                f.old.as_str(),
                f.new.as_str()
            ),
            (1, Some(1), "torque_cmd", "100.0", "101.0")
        );
        assert!(
            d.fields.iter().any(|(k, _)| k == "faults.crc"),
            "{:?}",
            d.fields
        );
    }
}
