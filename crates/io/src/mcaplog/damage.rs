//! Where a damaged MCAP file stops being safe to read.
//!
//! Corrupt lengths inside a chunk make the mcap reader (0.26) reserve
//! absurd buffers and abort the process (no error, no unwinding), so
//! [`super::McapLog::open`] keeps only what precedes the first damaged
//! record or chunk ([`first_damage`]) and reports the rest as lost.

/// Largest uncompressed chunk accepted (the recorder writes 512 KiB chunks).
const MAX_CHUNK: u64 = 1 << 30;

fn u64_at(d: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(d.get(at..at + 8)?.try_into().ok()?))
}

fn u32_at(d: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(d.get(at..at + 4)?.try_into().ok()?))
}

/// Walks the top-level MCAP records and returns where a safe read must
/// stop, with the reason: the first record whose length runs past the end
/// of the file (a crash-truncated tail), the first Chunk whose header is
/// implausible (uncompressed size over 1 GiB, or an uncompressed chunk whose
/// sizes disagree), or the first Chunk whose CRC does not match its
/// decompressed content (checked with the mcap crate's reader, which
/// validates a chunk before it parses a record of it). `None`: the file
/// reads as a whole.
pub fn first_damage(d: &[u8]) -> Option<(usize, String)> {
    const MAGIC_LEN: usize = 8;
    let mut at = MAGIC_LEN;
    let mut chunks = Vec::new();
    // largest uncompressed chunk accepted: the reader's record length limit
    let mut largest = 0u64;
    let mut stop = None;
    while at + 9 <= d.len() {
        let op = d[at];
        let Some(len) = u64_at(d, at + 1) else { break };
        let body = at + 9;
        let end = usize::try_from(len).ok().and_then(|l| body.checked_add(l));
        let Some(end) = end.filter(|e| *e <= d.len()) else {
            stop = Some((
                at,
                format!("record at byte {at} runs past the end of the file"),
            ));
            break;
        };
        if op == 0x06 {
            let hdr = (|| {
                let usize_ = u64_at(d, body + 16)?;
                let clen = u32_at(d, body + 28)? as usize;
                let comp = d.get(body + 32..body + 32 + clen)?;
                let rec_len = u64_at(d, body + 32 + clen)?;
                Some((usize_, comp.is_empty(), rec_len))
            })();
            match hdr {
                None => {
                    stop = Some((at, "unreadable chunk header".to_owned()));
                    break;
                }
                Some((u, _, _)) if u > MAX_CHUNK => {
                    stop = Some((at, format!("chunk claims {u} bytes uncompressed")));
                    break;
                }
                Some((u, true, r)) if u != r => {
                    stop = Some((at, format!("uncompressed chunk of {r} bytes claims {u}")));
                    break;
                }
                Some((u, _, _)) => {
                    largest = largest.max(u);
                    chunks.push(at);
                }
            }
        }
        at = end;
    }
    // CRC of every chunk before the stop point
    let limit = stop.as_ref().map_or(d.len(), |s| s.0);
    let data = &d[..limit];
    let mut r = mcap::sans_io::LinearReader::new_with_options(
        mcap::sans_io::LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_prevalidate_chunk_crcs(true)
            // a record is at most the file (outside chunks) or a chunk's
            // decompressed content (inside one)
            .with_record_length_limit(
                data.len()
                    .max(usize::try_from(largest).unwrap_or(usize::MAX)),
            ),
    );
    let mut fed = 0usize;
    while let Some(ev) = r.next_event() {
        match ev {
            Ok(mcap::sans_io::LinearReadEvent::ReadRequest(n)) => {
                let n = n.min(data.len() - fed);
                if n == 0 {
                    break;
                }
                r.insert(n).copy_from_slice(&data[fed..fed + n]);
                r.notify_read(n);
                fed += n;
            }
            Ok(mcap::sans_io::LinearReadEvent::Record { .. }) => {}
            Err(e) => {
                let bad = chunks.iter().rev().find(|&&c| c < fed).copied();
                return match bad {
                    Some(c) => Some((c, format!("chunk at byte {c} is corrupt: {e}"))),
                    None => Some((MAGIC_LEN.min(d.len()), format!("{e}"))),
                };
            }
        }
    }
    stop
}
