//! A damaged log loses only its damaged parts: a bad attachment or a bad
//! chunk (its record length still readable) is skipped, named in the report,
//! and every intact chunk after it is read. The log here is laid out as the
//! recorder writes a drive: a large attachment first (as the ARTE model
//! is), run metadata, then messages over many small chunks.
//!
//! The logs are written with a fixed `grip.clock` stamp: with the real
//! clock, the length of that record (the digits of the machine's uptime)
//! would shift every byte after it, and with them the places a stride
//! through the file hits.

use std::ops::Range;
use std::time::Duration;

use grip_io::mcaplog::*;
use grip_msgs::*;
use proptest::prelude::*;

const MODEL: &str = "default.model";
const CYCLES: u64 = 160;

/// The `grip.clock` monotonic stamp of the logs here (13 digits: an uptime
/// of about 3 h).
const CLOCK_NS: u64 = 1_234_567_890_123;

/// Stamps of other lengths (1, 12 and 20 digits: uptimes of nothing, 10 min
/// and 585 years); each shifts the layout after the clock record.
const OTHER_CLOCKS_NS: [u64; 3] = [7, 600_000_000_000, u64::MAX];

/// A chunk of the written log, as the mcap crate's own summary reader
/// finds it.
struct Chunk {
    /// The whole chunk record.
    record: Range<usize>,
    /// Its compressed records.
    data: Range<usize>,
    /// Messages in it.
    messages: usize,
}

struct Log {
    bytes: Vec<u8>,
    cycles: Vec<CycleRecord>,
    truth: Vec<GroundTruth>,
    model: Vec<u8>,
    /// The attachment record of the model.
    attachment: Range<usize>,
    chunks: Vec<Chunk>,
}

impl Log {
    fn messages(&self) -> usize {
        self.chunks.iter().map(|c| c.messages).sum()
    }

    /// Messages in the chunks that hold no byte of `hit`.
    fn untouched(&self, hit: &Range<usize>) -> usize {
        self.chunks
            .iter()
            .filter(|c| !overlap(&c.record, hit))
            .map(|c| c.messages)
            .sum()
    }

    fn flipped(&self, pos: usize, mask: u8) -> Vec<u8> {
        let mut b = self.bytes.clone();
        b[pos] ^= mask;
        b
    }
}

fn overlap(a: &Range<usize>, b: &Range<usize>) -> bool {
    a.start < b.end && b.start < a.end
}

/// Incompressible bytes (xorshift), the size of a small model.
fn model_bytes(n: usize) -> Vec<u8> {
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect()
}

/// Writes the log with clock stamp [`CLOCK_NS`].
fn write_log() -> Log {
    write_log_with_clock(CLOCK_NS)
}

/// Writes the log (lz4 chunks of 2 KiB: about 8 cycles and their ground
/// truth each) with `monotonic_ns` in its `grip.clock` record and finds its
/// chunks with the mcap crate's summary reader.
fn write_log_with_clock(monotonic_ns: u64) -> Log {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drive.mcap");
    let mut w = McapWriter::create_with_clock(
        &path,
        McapWriterOptions {
            compression: Compression::Lz4,
            chunk_size: 2048,
            flush_interval: Duration::from_secs(3600),
        },
        monotonic_ns,
        1_780_000_000_000_000_000,
    )
    .unwrap();
    let model = model_bytes(128 * 1024);
    w.attach_bytes(MODEL, "application/octet-stream", &model)
        .unwrap();
    w.write_run_info(&RunInfo {
        version: "0.1.0".into(),
        git_revision: "abc123".into(),
        ..RunInfo::default()
    })
    .unwrap();
    let mut cycles = Vec::new();
    let mut truth = Vec::new();
    for i in 0..CYCLES {
        let mut c = CycleRecord::zeroed();
        c.seq = i;
        c.stamp_ns = 1_000_000_000 + i * 1_000_000;
        c.omega = 30.0 + (i as f64).sin();
        c.torque_cmd = 187.25 - i as f64 * 0.125;
        c.v = 8.3e-3 * i as f64;
        // zeroed() leaves these NaN ("none yet"), which no value equals
        c.torque_cap = 182.5;
        c.belief_prob = 0.75;
        w.write(topics::CYCLE, &c).unwrap();
        cycles.push(c);
        let mut g = GroundTruth::zeroed();
        g.seq = i;
        g.stamp_ns = c.stamp_ns + 1;
        g.road_name = name_to_bytes("asphalt");
        g.x = 0.01 * i as f64;
        w.write(topics::TRUTH, &g).unwrap();
        truth.push(g);
    }
    w.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();

    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    let chunks: Vec<Chunk> = summary
        .chunk_indexes
        .iter()
        .map(|ci| {
            let start = ci.chunk_start_offset as usize;
            let data = ci.compressed_data_offset().unwrap() as usize;
            Chunk {
                record: start..start + ci.chunk_length as usize,
                data: data..data + ci.compressed_size as usize,
                messages: summary.stream_chunk(&bytes, ci).unwrap().count(),
            }
        })
        .collect();
    let a = summary
        .attachment_indexes
        .iter()
        .find(|a| a.name == MODEL)
        .expect("the model's attachment index");
    let attachment = a.offset as usize..(a.offset + a.length) as usize;
    assert!(chunks.len() >= 20, "{} chunks", chunks.len());
    assert!(
        attachment.end < chunks[0].record.start,
        "the attachment comes before the data chunks"
    );
    let log = Log {
        bytes,
        cycles,
        truth,
        model,
        attachment,
        chunks,
    };
    assert_eq!(log.messages(), 2 * CYCLES as usize);
    log
}

/// Where the top-level records of `b` (an intact file) start.
fn record_starts(b: &[u8]) -> Vec<usize> {
    let mut starts = Vec::new();
    let mut at = 8;
    while at + 9 <= b.len() {
        starts.push(at);
        at += 9 + u64::from_le_bytes(b[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    starts
}

fn read(bytes: Vec<u8>) -> (McapLog, Vec<LogEntry>, ReadReport) {
    let log = McapLog::from_bytes(bytes, "damaged.mcap");
    let (m, rep) = log.messages().expect("an MCAP file");
    (log, m, rep)
}

/// Every message read is the one written (no message is invented or
/// altered by the damage).
fn assert_intact(log: &Log, m: &[LogEntry], what: &str) {
    for e in m {
        match &e.msg {
            LogMessage::Cycle(c) => {
                assert_eq!(*c, log.cycles[c.seq as usize], "{what}");
                assert_eq!(e.topic, topics::CYCLE, "{what}");
            }
            LogMessage::Truth(g) => {
                assert_eq!(*g, log.truth[g.seq as usize], "{what}");
                assert_eq!(e.topic, topics::TRUTH, "{what}");
            }
            other => panic!("{what}: unexpected {other:?}"),
        }
    }
}

#[test]
fn the_intact_log_reads_whole() {
    let log = write_log();
    let (l, m, rep) = read(log.bytes.clone());
    assert_eq!(m.len(), log.messages());
    assert_intact(&log, &m, "intact");
    assert_eq!(rep.truncated, None);
    assert!(rep.skipped.is_empty(), "{:?}", rep.skipped);
    assert_eq!(first_damage(&log.bytes), None);
    assert_eq!(l.attachments().unwrap()[0].data, log.model);
}

/// (a) A flipped byte inside the model attachment: every message is still
/// read, the model is left out, and the report names it and says why.
#[test]
fn a_bad_attachment_is_skipped_and_named() {
    let log = write_log();
    let pos = log.attachment.start + log.attachment.len() / 2;
    let (l, m, rep) = read(log.flipped(pos, 0x5A));
    assert_eq!(m.len(), log.messages(), "{rep:?}");
    assert_intact(&log, &m, "attachment flip");
    let t = rep
        .truncated
        .as_deref()
        .expect("the log is reported damaged");
    assert!(
        t.contains(MODEL) && t.contains("CRC"),
        "the report names the attachment and why: {t}"
    );
    assert!(l.attachments().unwrap().is_empty());
    // the run metadata after the attachment is read too
    assert!(l.metadata().unwrap().iter().any(|(n, _)| n == "grip.run"));
    assert_eq!(rep.skipped.len(), 1, "{:?}", rep.skipped);
    let s = &rep.skipped[0];
    assert_eq!(
        s.kind,
        SkippedKind::Attachment {
            name: Some(MODEL.into())
        }
    );
    assert_eq!(
        (s.start, s.end),
        (log.attachment.start as u64, log.attachment.end as u64)
    );
    assert_eq!(rep.skipped_attachments(), 1);
    assert_eq!(rep.skipped_chunks(), 0);
}

/// (b) A flipped byte inside the compressed data of a chunk in the middle:
/// the messages of every other chunk are read, in order, and the report
/// names the one chunk skipped and its bytes.
#[test]
fn a_bad_chunk_is_skipped_and_the_rest_read() {
    let log = write_log();
    let k = log.chunks.len() / 2;
    let bad = &log.chunks[k];
    let pos = bad.data.start + bad.data.len() / 2;
    let (l, m, rep) = read(log.flipped(pos, 0x5A));
    assert_eq!(m.len(), log.messages() - bad.messages, "{rep:?}");
    assert_intact(&log, &m, "chunk flip");
    // in file order, with one hole
    let seqs: Vec<u64> = m
        .iter()
        .filter_map(|e| match &e.msg {
            LogMessage::Cycle(c) => Some(c.seq),
            _ => None,
        })
        .collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    assert_eq!(seqs.last(), Some(&(CYCLES - 1)), "the last cycle is read");
    let t = rep
        .truncated
        .as_deref()
        .expect("the log is reported damaged");
    assert!(
        t.contains("1 chunk") && t.contains(&bad.record.start.to_string()),
        "{t}"
    );
    assert_eq!(l.attachments().unwrap()[0].data, log.model);
    assert_eq!(rep.skipped_chunks(), 1, "{:?}", rep.skipped);
    assert_eq!(rep.skipped.len(), 1, "{:?}", rep.skipped);
    let s = &rep.skipped[0];
    assert_eq!(s.kind, SkippedKind::Chunk);
    assert_eq!(
        (s.start, s.end),
        (bad.record.start as u64, bad.record.end as u64)
    );
    assert_eq!(rep.stopped, None, "nothing is cut off");
}

/// What every damaged read must satisfy: no panic, only written messages,
/// at least those of the chunks the flip did not touch, the model unless
/// the flip was in it, and a log that lost anything is reported.
fn check_flip(log: &Log, pos: usize, mask: u8) {
    let what = format!("byte {pos} ^ {mask:#04x}");
    check_damage(log, log.flipped(pos, mask), pos..pos + 1, &what);
}

/// [`check_flip`]'s checks, for `bytes`: the log with the bytes `hit`
/// changed.
fn check_damage(log: &Log, bytes: Vec<u8>, hit: Range<usize>, what: &str) {
    let l = McapLog::from_bytes(bytes, "damaged.mcap");
    let (m, rep) = l.messages().unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_intact(log, &m, what);
    assert!(
        m.len() >= log.untouched(&hit),
        "{what}: {} messages read, {} in untouched chunks; {rep:?}",
        m.len(),
        log.untouched(&hit)
    );
    let att = l.attachments().unwrap();
    let model_read = att.iter().any(|a| a.name == MODEL && a.data == log.model);
    if !overlap(&log.attachment, &hit) {
        assert!(model_read, "{what}: the model is lost; {rep:?}");
    }
    if m.len() < log.messages() || !model_read {
        assert!(rep.truncated.is_some(), "{what}: a loss not reported");
    }
    if !model_read {
        let t = rep.truncated.as_deref().unwrap_or("");
        assert!(t.contains(MODEL), "{what}: lost model not named: {t}");
    }
}

/// (c) Single-byte flips at many places: every byte of the file's head, of
/// the attachment's head and tail, of the first chunk's head, of a middle
/// chunk's head and of what lies between it and the next chunk's data
/// (message indexes), of the footer; the two low bytes of the length of
/// every record up to the summary (a flip in a higher one makes a length
/// past the end of the file, as in the heads above); every 64th byte of
/// the summary; and a stride through the rest.
#[test]
fn single_byte_flips_lose_at_most_the_chunk_they_hit() {
    let log = write_log();
    let n = log.bytes.len();
    let (first, k) = (&log.chunks[0], log.chunks.len() / 2);
    let (mid, next) = (&log.chunks[k], &log.chunks[k + 1]);
    let summary = log.chunks.last().unwrap().record.end;
    let mut positions: Vec<usize> = (0..64).collect();
    positions.extend(log.attachment.start..log.attachment.start + 48);
    positions.extend(log.attachment.end - 16..log.attachment.end + 48);
    positions.extend(first.record.start..first.data.start + 4);
    positions.extend(mid.record.start..mid.data.start + 4);
    positions.extend(mid.data.end..next.data.start + 4);
    positions.extend((summary..n).step_by(64));
    positions.extend(n - 48..n);
    positions.extend((0..n).step_by(n / 150));
    positions.extend(
        record_starts(&log.bytes)
            .into_iter()
            .filter(|r| *r < summary)
            .flat_map(|r| r + 1..r + 3),
    );
    positions.sort_unstable();
    positions.dedup();
    for pos in positions {
        check_flip(&log, pos, 0x5A);
    }
    // a type byte flipped into every other value: the model's record (into
    // a message's 0x05 it still parses), a chunk's (into a message, a
    // footer, data end, an attachment...), a message index's (a message)
    for mask in 1..=255 {
        check_flip(&log, log.attachment.start, mask);
    }
    for mask in [0x01, 0x02, 0x03, 0x04, 0x05, 0x09, 0x0A, 0x0F] {
        check_flip(&log, mid.record.start, mask);
    }
    check_flip(&log, mid.record.end, 0x02);
}

/// (c)'s stride with the clock record of other lengths (a machine's uptime
/// sets it), which shifts the file under the stride: the places it hits
/// are others each time.
#[test]
fn single_byte_flips_whatever_the_clock_record_length() {
    for clock in OTHER_CLOCKS_NS {
        let log = write_log_with_clock(clock);
        let n = log.bytes.len();
        for pos in (0..n).step_by(n / 150) {
            check_flip(&log, pos, 0x5A);
        }
    }
}

/// A flipped byte in a record's length that makes it end exactly where a
/// later record starts (which reads, and so does the one after it: the
/// length field cannot be told from the record's fields by what follows):
/// the records in between are read all the same. Every record and every
/// later record one flipped byte away, up to the summary. (What follows the clock record
/// shifts as a whole with its length, so which flips these are does not
/// depend on it.)
#[test]
fn a_length_flipped_onto_a_later_record_loses_nothing_between() {
    let log = write_log();
    let b = &log.bytes;
    let starts = record_starts(b);
    let mut tried = 0;
    let summary = log.chunks.last().unwrap().record.end;
    for (i, &r) in starts.iter().enumerate().filter(|(_, r)| **r < summary) {
        let len = u64::from_le_bytes(b[r + 1..r + 9].try_into().unwrap());
        // (starts[i + 1] is where the record ends)
        for &q in starts.iter().skip(i + 2) {
            let diff = (q - r - 9) as u64 ^ len;
            let k = diff.trailing_zeros() / 8;
            if diff >> (8 * k) <= 0xFF {
                check_flip(&log, r + 1 + k as usize, (diff >> (8 * k)) as u8);
                tried += 1;
            }
        }
    }
    assert!(tried > 100, "{tried} lengths redirected");
}

/// Several bytes overwritten over the head of a record (its length and the
/// fields after it, so that neither tells where it ends): reading goes on
/// at the next record that checks, and only what was hit is lost. Every
/// record from the model's to the chunk after the middle one, 24 bytes from
/// its length on: zeros, 0xFF, or each byte flipped.
#[test]
fn a_burst_over_a_record_head_loses_at_most_what_it_hit() {
    /// Name, and what byte `i` of the burst makes of byte `x`.
    type Burst = (&'static str, fn(usize, u8) -> u8);
    const BURSTS: [Burst; 3] = [
        ("zeros", |_, _| 0x00),
        ("0xFF", |_, _| 0xFF),
        ("every byte flipped", |i, x| x ^ (2 * i as u8 + 1)),
    ];
    let log = write_log();
    let k = log.chunks.len() / 2;
    let mut tried = 0;
    for r in record_starts(&log.bytes) {
        if r < log.attachment.start || r > log.chunks[k + 1].record.start {
            continue;
        }
        for (name, burst) in BURSTS {
            let hit = r + 1..r + 25;
            let mut b = log.bytes.clone();
            for (i, x) in b[hit.clone()].iter_mut().enumerate() {
                *x = burst(i, *x);
            }
            let what = format!("bytes {}-{}: {name}", hit.start, hit.end - 1);
            check_damage(&log, b, hit, &what);
            tried += 1;
        }
    }
    assert!(tried >= 3 * 40, "{tried} bursts");
}

/// A log cut off inside a chunk after a damaged chunk: the damaged one is
/// skipped, the tail is lost, and the report says both.
#[test]
fn a_bad_chunk_before_a_cut_off_tail() {
    let log = write_log();
    let (bad, cut) = (&log.chunks[3], &log.chunks[log.chunks.len() - 4]);
    let mut b = log.flipped(bad.data.start + 5, 0x5A);
    b.truncate(cut.data.start + 10);
    let (_, m, rep) = read(b);
    let kept: usize = log.chunks[..log.chunks.len() - 4]
        .iter()
        .map(|c| c.messages)
        .sum();
    assert_eq!(m.len(), kept - bad.messages, "{rep:?}");
    assert_intact(&log, &m, "bad chunk and cut");
    assert_eq!(rep.skipped_chunks(), 1, "{rep:?}");
    let stopped = rep.stopped.as_deref().expect("the cut is reported");
    assert!(stopped.contains(&cut.record.start.to_string()), "{stopped}");
    let t = rep.truncated.as_deref().unwrap();
    assert!(t.contains("1 chunk") && t.contains(stopped), "{t}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Any byte, any flip.
    #[test]
    fn any_single_byte_flip_loses_at_most_its_chunk(at in 0.0f64..1.0, mask in 1u8..=255) {
        let log = LOG.with(|l| l.clone());
        let pos = ((log.bytes.len() as f64 * at) as usize).min(log.bytes.len() - 1);
        check_flip(&log, pos, mask);
    }
}

thread_local! {
    static LOG: std::rc::Rc<Log> = std::rc::Rc::new(write_log());
}

/// A crafted attachment record too short for its CRC (which the mcap
/// crate's record parser would slice out of bounds on): skipped, named, no
/// panic.
#[test]
fn an_attachment_without_room_for_its_crc_is_skipped() {
    let rec = |op: u8, body: &[u8]| {
        let mut v = vec![op];
        v.extend((body.len() as u64).to_le_bytes());
        v.extend(body);
        v
    };
    let mut att = vec![0u8; 16]; // log and create time
    att.extend(1u32.to_le_bytes());
    att.extend(b"m");
    att.extend(0u32.to_le_bytes()); // media type ""
    att.extend(0u64.to_le_bytes()); // no data, and no CRC after it
    let mut f = mcap::MAGIC.to_vec();
    f.extend(rec(0x01, &[0; 8])); // header: profile "", library ""
    f.extend(rec(0x09, &att));
    f.extend(rec(0x0F, &[0; 4])); // data end
    let l = McapLog::from_bytes(f, "crafted.mcap");
    assert!(l.attachments().unwrap().is_empty());
    let (m, rep) = l.messages().unwrap();
    assert!(m.is_empty());
    assert_eq!(rep.skipped_attachments(), 1, "{rep:?}");
    let t = rep.truncated.unwrap();
    assert!(t.contains("attachment \"m\""), "{t}");
}

/// A flipped byte in an index's offset that makes it point at another
/// record (in the summary, which has no per-record check) loses nothing:
/// the index is not trusted over a record that reads.
#[test]
fn an_index_pointing_at_another_record_loses_nothing() {
    let log = write_log();
    let b = &log.bytes;
    let starts = record_starts(b);
    let summary = mcap::Summary::read(b).unwrap().unwrap();
    let footer = mcap::read::footer(b).unwrap();
    let offsets: Vec<u64> = summary
        .metadata_indexes
        .iter()
        .map(|m| m.offset)
        .chain(summary.attachment_indexes.iter().map(|a| a.offset))
        .chain(summary.chunk_indexes.iter().map(|c| c.chunk_start_offset))
        .collect();
    let mut tried = 0;
    for off in offsets {
        // where the summary holds this offset (the first 8-byte match)
        let field = (footer.summary_start as usize..b.len() - 8)
            .find(|&i| b[i..i + 8] == off.to_le_bytes())
            .expect("the offset in the summary");
        for &other in &starts {
            let (o, t) = (off as usize, other);
            if o != t && o >> 8 == t >> 8 {
                check_flip(&log, field, (o ^ t) as u8);
                tried += 1;
            }
        }
    }
    assert!(tried > 20, "{tried} offsets redirected");
}
