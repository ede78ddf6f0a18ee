//! Which parts of an MCAP file can be read, and which are damaged.
//!
//! [`scan`] walks the top-level records once, when a log is opened, and
//! checks each one on its own: a chunk is decompressed and its content CRC
//! checked before any record inside it is parsed (the mcap reader (0.26)
//! reserves buffers from the lengths inside a chunk and aborts the process,
//! without an error, on absurd ones, so no unchecked chunk reaches it), an
//! attachment by its CRC, every other record by its fields, which must fill
//! its length exactly. A damaged record whose end can still be found (from
//! its length field, or, when that leads nowhere or the record only checks
//! with them, from the lengths of its own fields) is left out ([`Skipped`])
//! and reading goes on with the next record. When neither says for sure
//! where it ends and no record that checks follows where it seems to, the
//! walk resynchronises: it reads on at the first record after it that
//! checks ([`resync`]; a scan only after such damage, never on the way
//! through an intact file). Reading stops only where no next record can be
//! found: a crash-truncated tail, or a length damaged beyond repair.

use std::cmp::Ordering;
use std::collections::HashMap;
use std::fmt;

use mcap::records::{Record, op};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

/// Largest uncompressed chunk accepted (the recorder writes 512 KiB chunks).
const MAX_CHUNK: u64 = 1 << 30;

/// Uncompressed bytes all chunks together may claim per byte of the file
/// (and at least [`MAX_CHUNK`]): a crafted file of many small chunks that
/// each claim a large size would otherwise make every one of them reserve
/// that size.
const MAX_RATIO: u64 = 1024;

const MAGIC_LEN: usize = 8;

/// Opcode (1 byte) and length (8 bytes) before every record's body.
pub(super) const HEAD: usize = 9;

fn u64_at(d: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(
        d.get(at..at.checked_add(8)?)?.try_into().ok()?,
    ))
}

fn u32_at(d: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(
        d.get(at..at.checked_add(4)?)?.try_into().ok()?,
    ))
}

/// What a skipped part of a log was.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SkippedKind {
    /// A chunk: the messages in it are lost.
    Chunk,
    /// An attachment (configuration file, DBC, model), by name when its
    /// record or the summary's attachment index still gives it.
    Attachment {
        /// Name.
        name: Option<String>,
    },
    /// A metadata record, by name when known.
    Metadata {
        /// Name.
        name: Option<String>,
    },
    /// The magic bytes at the start or the end of the file (one byte
    /// differs; nothing is lost).
    Magic,
    /// Any other record, by opcode: a schema, channel, message, index,
    /// statistics... An unknown opcode is most likely a damaged one.
    Record {
        /// Opcode.
        opcode: u8,
    },
}

/// A damaged part of a log that the reader left out, reading on after it:
/// the log has a hole there.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Skipped {
    /// What it was.
    pub kind: SkippedKind,
    /// Its first byte in the file.
    pub start: u64,
    /// One past its last byte.
    pub end: u64,
    /// A chunk's log times (its first and last message, ns), as its header
    /// gives them.
    pub log_time_ns: Option<(u64, u64)>,
    /// Why it was left out.
    pub reason: String,
}

fn record_name(opcode: u8) -> Option<&'static str> {
    Some(match opcode {
        op::HEADER => "header",
        op::FOOTER => "footer",
        op::SCHEMA => "schema",
        op::CHANNEL => "channel",
        op::MESSAGE => "message",
        op::CHUNK => "chunk",
        op::MESSAGE_INDEX => "message index",
        op::CHUNK_INDEX => "chunk index",
        op::ATTACHMENT => "attachment",
        op::ATTACHMENT_INDEX => "attachment index",
        op::STATISTICS => "statistics",
        op::METADATA => "metadata",
        op::METADATA_INDEX => "metadata index",
        op::SUMMARY_OFFSET => "summary offset",
        op::DATA_END => "data end",
        _ => return None,
    })
}

impl fmt::Display for Skipped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.kind {
            SkippedKind::Chunk => write!(f, "chunk")?,
            SkippedKind::Attachment { name: Some(n) } => write!(f, "attachment {n:?}")?,
            SkippedKind::Attachment { name: None } => write!(f, "attachment (name unreadable)")?,
            SkippedKind::Metadata { name: Some(n) } => write!(f, "metadata {n:?}")?,
            SkippedKind::Metadata { name: None } => write!(f, "metadata (name unreadable)")?,
            SkippedKind::Magic => write!(f, "magic bytes")?,
            SkippedKind::Record { opcode } => match record_name(*opcode) {
                Some(n) => write!(f, "{n} record")?,
                None => write!(f, "record of unknown type {opcode:#04x}")?,
            },
        }
        write!(f, " at bytes {}-{}", self.start, self.end)?;
        if let Some((t0, t1)) = self.log_time_ns {
            write!(
                f,
                " (log time {:.3}-{:.3} s)",
                t0 as f64 * 1e-9,
                t1 as f64 * 1e-9
            )?;
        }
        write!(f, ": {}", self.reason)
    }
}

/// A record that reads: its opcode and where its body lies in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Rec {
    pub op: u8,
    pub body: (usize, usize),
}

/// What [`scan`] found.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(super) struct Scan {
    /// The records that read, in file order.
    pub records: Vec<Rec>,
    /// The damaged parts left out, in file order.
    pub skipped: Vec<Skipped>,
    /// Where reading stopped before the end of the file, and why.
    pub stop: Option<(usize, String)>,
    /// A footer was read (the writer finished the file).
    pub finished: bool,
}

/// The fields of a record's body, in order, as far as its length goes.
#[derive(Clone, Copy)]
enum Field {
    Fixed(usize),
    /// A u32 length, then that many bytes (string, map, array, schema data).
    Bytes32,
    /// A u64 length, then that many bytes (chunk records, attachment data).
    Bytes64,
}

/// The layout of each record type of the MCAP spec; none for a message
/// (its data runs to the end of the record) or an unknown opcode.
fn layout(opcode: u8) -> Option<&'static [Field]> {
    use Field::*;
    Some(match opcode {
        op::HEADER => &[Bytes32, Bytes32],
        op::FOOTER => &[Fixed(20)],
        op::SCHEMA => &[Fixed(2), Bytes32, Bytes32, Bytes32],
        op::CHANNEL => &[Fixed(4), Bytes32, Bytes32, Bytes32],
        op::CHUNK => &[Fixed(28), Bytes32, Bytes64],
        op::MESSAGE_INDEX => &[Fixed(2), Bytes32],
        op::CHUNK_INDEX => &[Fixed(32), Bytes32, Fixed(8), Bytes32, Fixed(16)],
        op::ATTACHMENT => &[Fixed(16), Bytes32, Bytes32, Bytes64, Fixed(4)],
        op::ATTACHMENT_INDEX => &[Fixed(40), Bytes32, Bytes32],
        op::STATISTICS => &[Fixed(42), Bytes32],
        op::METADATA => &[Bytes32, Bytes32],
        op::METADATA_INDEX => &[Fixed(16), Bytes32],
        op::SUMMARY_OFFSET => &[Fixed(17)],
        op::DATA_END => &[Fixed(4)],
        _ => return None,
    })
}

/// The length of a body of type `opcode` that starts `b`, from the lengths
/// of its own fields; `None` if it has no fixed layout or runs past `b`.
fn fields_len(opcode: u8, b: &[u8]) -> Option<usize> {
    let mut at = 0usize;
    for f in layout(opcode)? {
        at = match *f {
            Field::Fixed(n) => at.checked_add(n)?,
            Field::Bytes32 => {
                let n = usize::try_from(u32_at(b, at)?).ok()?;
                at.checked_add(4)?.checked_add(n)?
            }
            Field::Bytes64 => {
                let n = usize::try_from(u64_at(b, at)?).ok()?;
                at.checked_add(8)?.checked_add(n)?
            }
        };
        if at > b.len() {
            return None;
        }
    }
    Some(at)
}

/// `b` is the magic, or differs from it in one byte.
fn near_magic(b: &[u8]) -> bool {
    b.len() == MAGIC_LEN && b.iter().zip(mcap::MAGIC).filter(|(x, y)| x != y).count() <= 1
}

/// Where the record at `at` ends by its length field, if a known record
/// type starts there and its length stays within the file.
fn next_record(d: &[u8], at: usize) -> Option<usize> {
    let opcode = *d.get(at)?;
    record_name(opcode)?;
    let len = usize::try_from(u64_at(d, at + 1)?).ok()?;
    at.checked_add(HEAD)?
        .checked_add(len)
        .filter(|e| *e <= d.len())
}

/// How plausible it is that a record starts at `at`: 2 if it and the one
/// after it are known records within the file (or the file ends there),
/// 1 if only the first is, 0 if not even that.
fn plausibility(d: &[u8], mut at: usize) -> u8 {
    for score in 0..2 {
        if at == d.len() || d.len() - at == MAGIC_LEN {
            return 2;
        }
        match next_record(d, at) {
            Some(next) => at = next,
            None => return score,
        }
    }
    2
}

/// Whether the record `opcode` with body `body` checks ([`check`]), without
/// spending `budget`.
fn checks(opcode: u8, body: &[u8], budget: u64) -> bool {
    let mut b = budget;
    check(opcode, body, &mut b).is_ok()
}

/// Whether a record that checks starts at `at`, or the file, or its end
/// magic, starts there.
fn checks_at(d: &[u8], at: usize, budget: u64) -> bool {
    if at == d.len() || (d.len() - at == MAGIC_LEN && near_magic(&d[at..])) {
        return true;
    }
    next_record(d, at).is_some_and(|end| checks(d[at], &d[at + HEAD..end], budget))
}

/// The first place in `from..to` where a record starts that checks, whose
/// fields fill its length, after which another record (or the file's end)
/// follows, and of a type never found inside a chunk: not a schema, channel
/// or message (an uncompressed chunk holds those as they are), nor a header.
/// Where a damaged record's length cannot be trusted, reading resumes there.
/// Few bytes get past the type and length tests, so a scan costs little
/// more than reading the bytes once.
fn resync(d: &[u8], from: usize, to: usize, budget: u64) -> Option<usize> {
    (from..to.min(d.len())).find(|&p| {
        let opcode = d[p];
        if matches!(opcode, op::HEADER | op::SCHEMA | op::CHANNEL | op::MESSAGE) {
            return false;
        }
        let Some(end) = next_record(d, p) else {
            return false;
        };
        let body = &d[p + HEAD..end];
        fields_len(opcode, body) == Some(body.len())
            && plausibility(d, p) == 2
            && checks(opcode, body, budget)
    })
}

/// What a chunk's header says.
struct ChunkHeader {
    start_ns: u64,
    end_ns: u64,
    uncompressed: u64,
    compressed: u64,
    no_compression: bool,
}

fn chunk_header(body: &[u8]) -> Option<ChunkHeader> {
    let clen = usize::try_from(u32_at(body, 28)?).ok()?;
    let comp = body.get(32..32usize.checked_add(clen)?)?;
    Some(ChunkHeader {
        start_ns: u64_at(body, 0)?,
        end_ns: u64_at(body, 8)?,
        uncompressed: u64_at(body, 16)?,
        compressed: u64_at(body, 32 + clen)?,
        no_compression: comp.is_empty(),
    })
}

/// Calls `f` with the opcode and bytes of every record inside the chunk
/// whose record body is `body`, after its content CRC has been checked
/// (when the chunk has one) and with no record or buffer longer than the
/// chunk's uncompressed size (or its body); the first error ends it. A
/// chunk may only hold schemas, channels and messages.
pub(super) fn for_each_in_chunk(
    body: &[u8],
    mut f: impl FnMut(u8, &[u8]) -> Result<(), String>,
) -> Result<(), String> {
    let h = chunk_header(body).ok_or("unreadable chunk header")?;
    if h.uncompressed > MAX_CHUNK {
        return Err(format!(
            "chunk claims {} bytes uncompressed",
            h.uncompressed
        ));
    }
    if h.no_compression && h.uncompressed != h.compressed {
        return Err(format!(
            "uncompressed chunk of {} bytes claims {}",
            h.compressed, h.uncompressed
        ));
    }
    let limit = usize::try_from(h.uncompressed)
        .unwrap_or(usize::MAX)
        .max(body.len());
    let mut r = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(limit),
    );
    // the chunk record as the reader expects it: opcode, length, body
    let mut head = [0u8; HEAD];
    head[0] = op::CHUNK;
    head[1..].copy_from_slice(&(body.len() as u64).to_le_bytes());
    let total = HEAD + body.len();
    let mut fed = 0usize;
    while let Some(ev) = r.next_event() {
        match ev {
            Ok(LinearReadEvent::ReadRequest(n)) => {
                let n = n.min(total - fed);
                if n == 0 {
                    r.notify_read(0); // the end: the reader ends or fails
                    continue;
                }
                let buf = r.insert(n);
                let from_head = HEAD.saturating_sub(fed).min(n);
                if from_head > 0 {
                    buf[..from_head].copy_from_slice(&head[fed..fed + from_head]);
                }
                if from_head < n {
                    let at = fed + from_head - HEAD;
                    buf[from_head..].copy_from_slice(&body[at..at + n - from_head]);
                }
                r.notify_read(n);
                fed += n;
            }
            Ok(LinearReadEvent::Record { opcode, data }) => {
                if !matches!(opcode, op::SCHEMA | op::CHANNEL | op::MESSAGE) {
                    return Err(format!("chunk holds a record of type {opcode:#04x}"));
                }
                f(opcode, data)?;
            }
            Err(mcap::McapError::Io(e)) => {
                return Err(format!("its compressed data does not decompress ({e})"));
            }
            Err(e) => return Err(e.to_string()),
        }
    }
    Ok(())
}

/// Checks the record `opcode` with body `body`; `budget`: the uncompressed
/// bytes chunks may still claim.
fn check(opcode: u8, body: &[u8], budget: &mut u64) -> Result<(), String> {
    let parses = |o: u8, b: &[u8]| {
        mcap::parse_record(o, b)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    match opcode {
        op::CHUNK => {
            // (the mcap reader reads a chunk that ends before its length
            // says, taking what follows for the rest of it)
            if fields_len(opcode, body) != Some(body.len()) {
                return Err("its fields do not fill its length".into());
            }
            // (a claim over MAX_CHUNK is refused before anything is reserved)
            let claim = chunk_header(body)
                .map(|h| h.uncompressed)
                .filter(|u| *u <= MAX_CHUNK)
                .unwrap_or(0);
            if claim > *budget {
                return Err(format!(
                    "chunk claims {claim} bytes uncompressed, more than a file this size holds"
                ));
            }
            *budget -= claim;
            for_each_in_chunk(body, parses)
        }
        op::MESSAGE => parses(opcode, body),
        _ if record_name(opcode).is_some() => {
            if fields_len(opcode, body) != Some(body.len()) {
                return Err("its fields do not fill its length".into());
            }
            parses(opcode, body)
        }
        _ => Err(format!(
            "unknown record type {opcode:#04x} (a damaged opcode?)"
        )),
    }
}

/// The string (u32 length, UTF-8) at `at` of `b`, if it lies within `b`.
fn string_at(b: &[u8], at: usize) -> Option<String> {
    let n = usize::try_from(u32_at(b, at)?).ok()?;
    let s = b.get(at + 4..(at + 4).checked_add(n)?)?;
    Some(String::from_utf8_lossy(s).into_owned())
}

/// The part of the file `start..end` (a record with opcode `opcode`, body
/// from `body`), skipped for `reason`.
fn skipped(d: &[u8], opcode: u8, start: usize, body: usize, end: usize, reason: String) -> Skipped {
    let b = &d[body.min(end)..end];
    let (kind, log_time_ns) = match opcode {
        op::CHUNK => (
            SkippedKind::Chunk,
            chunk_header(b).map(|h| (h.start_ns, h.end_ns)),
        ),
        op::ATTACHMENT => (
            SkippedKind::Attachment {
                name: string_at(b, 16),
            },
            None,
        ),
        op::METADATA => (
            SkippedKind::Metadata {
                name: string_at(b, 0),
            },
            None,
        ),
        _ => (SkippedKind::Record { opcode }, None),
    };
    Skipped {
        kind,
        start: start as u64,
        end: end as u64,
        log_time_ns,
        reason,
    }
}

/// Walks the top-level records of `d` and sorts them into those that read
/// and the damaged ones; `None` if `d` is not MCAP (its magic bytes differ
/// in more than one byte, or one differs and no header record follows).
///
/// A record's end is where its length field says, unless nothing readable
/// starts there while something does where the lengths of its own fields
/// end, or as much starts at both and the record checks only with the
/// latter, and a record that checks follows it (a damaged length field,
/// e.g. one pointing at a later record). A record that does not check
/// ([`check`]) is skipped; if the two ends differ (or there is only one)
/// and no record that checks starts at the end taken, the skip ends at the
/// first record before it that does ([`resync`]). A record that runs past
/// the end of the file, both ways, ends at the first record after it that
/// checks, or, with none, stops the walk (a crash-truncated tail). Every
/// step moves on by at least one byte, so the walk ends.
pub(super) fn scan(d: &[u8]) -> Option<Scan> {
    let mut s = Scan::default();
    if !d.starts_with(mcap::MAGIC) {
        let head_follows = d.get(MAGIC_LEN) == Some(&op::HEADER) && plausibility(d, MAGIC_LEN) > 0;
        if !(d.len() >= MAGIC_LEN && near_magic(&d[..MAGIC_LEN]) && head_follows) {
            return None;
        }
        s.skipped.push(Skipped {
            kind: SkippedKind::Magic,
            start: 0,
            end: MAGIC_LEN as u64,
            log_time_ns: None,
            reason: "one byte differs (nothing lost)".into(),
        });
    }
    let mut budget = MAX_CHUNK.max((d.len() as u64).saturating_mul(MAX_RATIO));
    let mut at = MAGIC_LEN;
    while at < d.len() {
        let rest = d.len() - at;
        if s.finished {
            // after the footer: the end magic
            if rest == MAGIC_LEN && near_magic(&d[at..]) {
                if d[at..] != *mcap::MAGIC {
                    s.skipped.push(Skipped {
                        kind: SkippedKind::Magic,
                        start: at as u64,
                        end: d.len() as u64,
                        log_time_ns: None,
                        reason: "one byte differs (nothing lost)".into(),
                    });
                }
            } else {
                s.stop = Some((
                    at,
                    format!("{rest} bytes after the footer where the end magic belongs"),
                ));
            }
            break;
        }
        if rest < HEAD {
            if d[at..] != *mcap::MAGIC {
                s.stop = Some((at, format!("the file ends inside a record at byte {at}")));
            }
            break;
        }
        let opcode = d[at];
        let body = at + HEAD;
        let by_length = u64_at(d, at + 1)
            .and_then(|l| usize::try_from(l).ok())
            .and_then(|l| body.checked_add(l))
            .filter(|e| *e <= d.len());
        let by_fields = fields_len(opcode, &d[body..]).map(|l| body + l);
        let end = match (by_length, by_fields) {
            (Some(l), Some(f)) if l != f => match plausibility(d, f).cmp(&plausibility(d, l)) {
                Ordering::Greater => f,
                Ordering::Less => l,
                // e.g. a length damaged so that it points at a later record
                Ordering::Equal
                    if !checks(opcode, &d[body..l], budget)
                        && checks(opcode, &d[body..f], budget)
                        && checks_at(d, f, budget) =>
                {
                    f
                }
                Ordering::Equal => l,
            },
            (Some(l), _) => l,
            (None, Some(f)) if plausibility(d, f) > 0 => f,
            (None, _) => {
                let Some(next) = resync(d, at + 1, d.len(), budget) else {
                    s.stop = Some((
                        at,
                        format!(
                            "record at byte {at} runs past the end of the file (cut off, or its length is damaged)"
                        ),
                    ));
                    break;
                };
                let why = format!(
                    "its length runs past the end of the file; read on at byte {next}, the next record that checks"
                );
                s.skipped.push(skipped(d, opcode, at, body, next, why));
                at = next;
                continue;
            }
        };
        match check(opcode, &d[body..end], &mut budget) {
            Ok(()) => {
                s.records.push(Rec {
                    op: opcode,
                    body: (body, end),
                });
                s.finished |= opcode == op::FOOTER;
                at = end;
            }
            Err(mut why) => {
                // the end is in doubt: the length and the fields disagree
                // (or the fields give none), and nothing that checks
                // starts there
                let sure = by_length.is_some() && by_length == by_fields;
                let next = if sure || checks_at(d, end, budget) {
                    end
                } else {
                    match resync(d, at + 1, end, budget) {
                        Some(next) => {
                            why.push_str(&format!(
                                "; its length is damaged too: read on at byte {next}, the next record that checks"
                            ));
                            next
                        }
                        None => end,
                    }
                };
                s.skipped.push(skipped(d, opcode, at, body, next, why));
                at = next;
            }
        }
    }
    apply_indexes(d, &mut s);
    Some(s)
}

/// What the summary's indexes say about the records they point at (by
/// offset; a crash-truncated file has none). A skipped attachment or
/// metadata record is named by its index (its own name may be what was
/// damaged); a skipped record whose type byte was damaged is called what
/// the index says is there; and a record that reads, but as another type
/// than its index says (a damaged type byte that still parses, e.g. as a
/// message), is skipped, if it also has the length the index gives (so
/// that a damaged offset in an index, pointing at another record, does not
/// throw that record away).
fn apply_indexes(d: &[u8], s: &mut Scan) {
    let mut indexed: HashMap<usize, (u8, u64, SkippedKind)> = HashMap::new();
    for r in &s.records {
        if !matches!(
            r.op,
            op::ATTACHMENT_INDEX | op::METADATA_INDEX | op::CHUNK_INDEX
        ) {
            continue;
        }
        let (offset, opcode, length, kind) = match mcap::parse_record(r.op, &d[r.body.0..r.body.1])
        {
            Ok(Record::AttachmentIndex(a)) => (
                a.offset,
                op::ATTACHMENT,
                a.length,
                SkippedKind::Attachment { name: Some(a.name) },
            ),
            Ok(Record::MetadataIndex(m)) => (
                m.offset,
                op::METADATA,
                m.length,
                SkippedKind::Metadata { name: Some(m.name) },
            ),
            Ok(Record::ChunkIndex(c)) => (
                c.chunk_start_offset,
                op::CHUNK,
                c.chunk_length,
                SkippedKind::Chunk,
            ),
            _ => continue,
        };
        if let Ok(offset) = usize::try_from(offset) {
            indexed.insert(offset, (opcode, length, kind));
        }
    }
    if indexed.is_empty() {
        return;
    }
    let mut misread = Vec::new();
    s.records.retain(|r| {
        let start = r.body.0 - HEAD;
        match indexed.get(&start) {
            Some((opcode, length, kind))
                if *opcode != r.op && (r.body.1 - start) as u64 == *length =>
            {
                let mut k = skipped(
                    d,
                    *opcode,
                    start,
                    r.body.0,
                    r.body.1,
                    format!(
                        "it reads as {} record, but the summary's index has {} there (a damaged type byte)",
                        match record_name(r.op).unwrap_or("?") {
                            n @ ("attachment" | "attachment index") => format!("an {n}"),
                            n => format!("a {n}"),
                        },
                        match *opcode {
                            op::ATTACHMENT => "an attachment",
                            op::METADATA => "a metadata record",
                            _ => "a chunk",
                        }
                    ),
                );
                k.kind = kind.clone();
                misread.push(k);
                false
            }
            _ => true,
        }
    });
    for k in &mut s.skipped {
        if k.kind == SkippedKind::Magic {
            continue;
        }
        let start = usize::try_from(k.start).unwrap_or(usize::MAX);
        if let Some((_, _, kind)) = indexed.get(&start) {
            k.kind = kind.clone();
            if k.kind == SkippedKind::Chunk && k.log_time_ns.is_none() {
                let end = usize::try_from(k.end).unwrap_or(usize::MAX).min(d.len());
                k.log_time_ns = d
                    .get(start + HEAD..end)
                    .and_then(chunk_header)
                    .map(|h| (h.start_ns, h.end_ns));
            }
        }
    }
    if !misread.is_empty() {
        s.skipped.append(&mut misread);
        s.skipped.sort_by_key(|k| k.start);
    }
}

/// The first damaged place of `d` and what it is: the first part a read
/// skips, or where it stops (a cut-off tail), whichever comes first.
/// `None`: the file reads whole.
pub fn first_damage(d: &[u8]) -> Option<(usize, String)> {
    let Some(s) = scan(d) else {
        return Some((0, "not an MCAP file".into()));
    };
    let skip = s.skipped.first().map(|k| {
        (
            usize::try_from(k.start).unwrap_or(usize::MAX),
            k.to_string(),
        )
    });
    match (skip, s.stop) {
        (Some(k), Some(t)) => Some(if t.0 < k.0 { t } else { k }),
        (k, t) => k.or(t),
    }
}
