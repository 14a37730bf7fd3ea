//! The block codec: header, zstd payload, checksum.

use zstd::zstd_safe::zstd_sys::ZSTD_ErrorCode::ZSTD_error_dstSize_tooSmall;

/// The first 8 bytes of every block.
pub const BLOCK_MAGIC: [u8; 8] = *b"HORTBLK\0";
/// The format version this build writes, and the only one it reads.
pub const BLOCK_VERSION: u16 = 1;
/// Header length in bytes; the zstd payload starts here.
pub const BLOCK_HEADER_LEN: usize = 36;
/// The largest raw (uncompressed) length a block may declare: 4 GiB. Larger declared lengths are
/// rejected before any allocation.
pub const MAX_RAW_LEN: u64 = 4 << 30;
/// The zstd level of every payload (single-threaded, no dictionary).
///
/// Level 1, chosen by measurement (`core/examples/shuffle_levels.rs`; the table is in
/// docs/ARCHITECTURE.md, section 8): on a staged k = 8 job of a 500k-triangle scene it compresses
/// and decompresses all blocks in half the CPU time of level 3 (94 ms against 190 ms) for 7% more
/// bytes (24.2 MB against 22.7 MB), which is cheaper wherever storage moves more than about
/// 32 MB/s (Lambda to S3: about 100 MB/s). Negative levels save little more CPU and compress
/// pixel blocks much worse. Any level decodes with the same reader: the level is not part of
/// the format.
pub const ZSTD_LEVEL: i32 = 1;

/// Offset of the raw-bytes CRC in the header.
const RAW_CRC_AT: usize = 28;
/// Offset of the block CRC in the header; it covers every header byte before it.
const BLOCK_CRC_AT: usize = 32;

/// What the records of a block are. The numeric values are part of the format: never reuse one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u16)]
pub enum RecordKind {
    /// CastMap output: candidate nearest hit per pixel sample against one split.
    CastCandidate = 1,
    /// CastReduce output: the nearest hit per pixel sample.
    Hit = 2,
    /// Expand output: a hit routed to a split for shadow testing.
    ShadowQuery = 3,
    /// TraceMap output: per hit and light, occluded or not by one split.
    ShadowResult = 4,
    /// TraceReduce output: shaded colour per pixel sample.
    PixelColor = 5,
    /// A scene split: its triangles, shading data and prebuilt BVH.
    SplitObject = 6,
    /// TraceReduce output of an adaptive job's first round: the pixels of a span that get a
    /// second round, with their first-pass radiance sums.
    RefineList = 7,
    /// The vertex positions and normals one range of a scene's OBJ file defines.
    VertexPage = 8,
    /// One frame of a scene range's triangles, with positions, shading and scene-wide ids.
    PartRecords = 9,
    /// A decoded diffuse texture (see [`crate::texture`]).
    Texture = 10,
}

impl RecordKind {
    /// Every kind, in numeric order.
    pub const ALL: [RecordKind; 10] = [
        RecordKind::CastCandidate,
        RecordKind::Hit,
        RecordKind::ShadowQuery,
        RecordKind::ShadowResult,
        RecordKind::PixelColor,
        RecordKind::SplitObject,
        RecordKind::RefineList,
        RecordKind::VertexPage,
        RecordKind::PartRecords,
        RecordKind::Texture,
    ];

    /// The kind's number in the header.
    pub const fn code(self) -> u16 {
        self as u16
    }

    /// The kind with this number, if any.
    pub fn from_code(code: u16) -> Option<Self> {
        Self::ALL.into_iter().find(|kind| kind.code() == code)
    }
}

impl std::fmt::Display for RecordKind {
    /// The variant name and number, e.g. `Hit (2)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{self:?} ({})", self.code())
    }
}

/// A decoded block: its kind, its record count as written, and the raw record bytes, verified
/// against the header's length and checksum.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Block {
    /// The record kind from the header (always the expected kind).
    pub kind: RecordKind,
    /// The record count the producer declared; the codec does not interpret the raw bytes.
    pub record_count: u64,
    /// The uncompressed record bytes.
    pub raw: Vec<u8>,
}

/// A block that cannot be decoded: which object, and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("shuffle block {key}: {problem}")]
pub struct BlockError {
    /// The object key the bytes came from.
    pub key: String,
    /// What is wrong.
    pub problem: BlockProblem,
}

/// What is wrong with a block. Every variant means the bytes are corrupt, truncated, or from an
/// incompatible producer; none is transient.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BlockProblem {
    /// Fewer bytes than the header.
    #[error("truncated: {len} bytes, shorter than the {BLOCK_HEADER_LEN}-byte header")]
    TooShort {
        /// The length found.
        len: usize,
    },
    /// The magic bytes are wrong.
    #[error("not a HORT block: starts with \"{}\", expected \"HORTBLK\\0\"", .found.escape_ascii())]
    BadMagic {
        /// The first 8 bytes found.
        found: [u8; 8],
    },
    /// A format version this build does not read.
    #[error("unsupported format version {found}; this build reads version {supported}")]
    UnsupportedVersion {
        /// The version in the header.
        found: u16,
        /// The version this build reads.
        supported: u16,
    },
    /// A record kind number this build does not know.
    #[error("unknown record kind {found}, expected {expected}")]
    UnknownKind {
        /// The number in the header.
        found: u16,
        /// The kind the caller expected.
        expected: RecordKind,
    },
    /// A known record kind, but not the one the caller expected.
    #[error("unexpected record kind {found}, expected {expected}")]
    UnexpectedKind {
        /// The kind in the header.
        found: RecordKind,
        /// The kind the caller expected.
        expected: RecordKind,
    },
    /// The header declares an absurd raw length.
    #[error("declared raw length {len} bytes exceeds the {max}-byte limit")]
    RawTooLarge {
        /// The declared length.
        len: u64,
        /// [`MAX_RAW_LEN`].
        max: u64,
    },
    /// The payload is not exactly one valid zstd frame.
    #[error("zstd payload corrupt or truncated: {detail}")]
    CorruptPayload {
        /// What zstd or the frame check reported.
        detail: String,
    },
    /// The payload decompresses to a different length than the header declares.
    #[error("raw length mismatch: header declares {declared} bytes, payload holds {found}{}",
        if .found > .declared { " or more" } else { "" })]
    RawLengthMismatch {
        /// The header's raw length.
        declared: u64,
        /// The decompressed length (decoding stops one byte past `declared`).
        found: u64,
    },
    /// The CRC-32 of the stored header and payload differs from the block checksum: the object
    /// was damaged after it was written.
    #[error(
        "block checksum mismatch (stored bytes damaged): header stores CRC-32 {stored:#010x}, \
         bytes give {computed:#010x}"
    )]
    BlockChecksumMismatch {
        /// The checksum in the header.
        stored: u32,
        /// The checksum of the bytes found.
        computed: u32,
    },
    /// The CRC-32 of the decompressed bytes differs from the raw checksum: the payload does not
    /// hold what the producer wrote.
    #[error(
        "raw checksum mismatch (decompressed bytes differ from those written): header stores \
         CRC-32 {stored:#010x}, decompressed bytes give {computed:#010x}"
    )]
    RawChecksumMismatch {
        /// The checksum in the header.
        stored: u32,
        /// The checksum of the bytes found.
        computed: u32,
    },
}

/// Encodes `raw` as a block of `kind` declaring `record_count` records.
///
/// Layout, all integers little-endian:
///
/// | bytes  | field |
/// |--------|-------|
/// | 0..8   | magic `b"HORTBLK\0"` |
/// | 8..10  | format version, u16 = 1 |
/// | 10..12 | record kind, u16 ([`RecordKind::code`]) |
/// | 12..20 | record count, u64 |
/// | 20..28 | raw length in bytes, u64 |
/// | 28..32 | raw CRC: CRC-32 of the raw (uncompressed) bytes |
/// | 32..36 | block CRC: CRC-32 of header bytes 0..32 followed by the zstd payload |
/// | 36..   | one zstd frame of the raw bytes, level [`ZSTD_LEVEL`], single-threaded, no dictionary |
///
/// Both checksums are CRC-32 (IEEE 802.3 polynomial, as in zlib and PNG). The block CRC covers
/// every stored byte, so any damage of up to 32 consecutive bits (in particular every single bit
/// flip, even one zstd would decode harmlessly) is caught before decompressing; the raw CRC checks
/// the decoded records end to end, independent of the codec. Output is deterministic: the same arguments give the same bytes on every machine
/// running the same zstd version (pinned through Cargo.lock).
///
/// # Panics
/// If `raw` is longer than [`MAX_RAW_LEN`] (a planning bug: blocks are bounded by span size), or
/// if zstd cannot allocate its context.
pub fn encode_block(kind: RecordKind, record_count: u64, raw: &[u8]) -> Vec<u8> {
    let raw_len = raw.len() as u64;
    assert!(
        raw_len <= MAX_RAW_LEN,
        "block of {raw_len} raw bytes exceeds {MAX_RAW_LEN}"
    );
    let payload = zstd::bulk::compress(raw, ZSTD_LEVEL)
        .unwrap_or_else(|e| panic!("zstd compression failed: {e}"));
    let mut block = Vec::with_capacity(BLOCK_HEADER_LEN + payload.len());
    block.extend_from_slice(&BLOCK_MAGIC);
    block.extend_from_slice(&BLOCK_VERSION.to_le_bytes());
    block.extend_from_slice(&kind.code().to_le_bytes());
    block.extend_from_slice(&record_count.to_le_bytes());
    block.extend_from_slice(&raw_len.to_le_bytes());
    block.extend_from_slice(&crc32fast::hash(raw).to_le_bytes());
    let block_crc = checksum(&block, &payload);
    block.extend_from_slice(&block_crc.to_le_bytes());
    block.extend_from_slice(&payload);
    block
}

/// Decodes a block read from `key`, demanding `expected_kind`.
///
/// Guarantees: never panics; allocates the declared raw length (at most [`MAX_RAW_LEN`]) only
/// after the block CRC has verified the header, so damaged bytes never cause a large allocation; returns `Ok` only if magic, version and kind are
/// right, the block CRC matches the stored bytes, the payload is exactly one complete zstd frame,
/// it decompresses to exactly the declared length, and the raw CRC matches the result. Every error's message names `key` and the problem.
pub fn decode_block(
    key: &str,
    bytes: &[u8],
    expected_kind: RecordKind,
) -> Result<Block, BlockError> {
    decode(bytes, expected_kind).map_err(|problem| BlockError {
        key: key.to_owned(),
        problem,
    })
}

/// Relabels the block `bytes` read from `key`, which must be of kind `from`, as kind `to`: the
/// same records, the same payload bytes, only the header's kind and block CRC rewritten.
///
/// Guarantees: for every `raw` and `count`, `relabel_block(k, &encode_block(from, count, raw),
/// from, to)` is `Ok(encode_block(to, count, raw))` byte for byte, since the level is fixed and
/// the payload is copied; a reader of the result sees exactly what a reader of the input sees.
/// Costs one CRC pass over the bytes and one copy: the payload is not decompressed. It checks
/// the header (magic, version, kind `from`, raw length) and the block CRC, which covers every
/// stored byte, so storage damage is caught here, and fails with the same errors as
/// [`decode_block`]; the raw CRC and the payload travel unchanged, to be checked when the
/// result is decoded.
pub fn relabel_block(
    key: &str,
    bytes: &[u8],
    from: RecordKind,
    to: RecordKind,
) -> Result<Vec<u8>, BlockError> {
    relabel(bytes, from, to).map_err(|problem| BlockError {
        key: key.to_owned(),
        problem,
    })
}

fn relabel(bytes: &[u8], from: RecordKind, to: RecordKind) -> Result<Vec<u8>, BlockProblem> {
    let (head, payload) = bytes
        .split_first_chunk::<BLOCK_HEADER_LEN>()
        .ok_or(BlockProblem::TooShort { len: bytes.len() })?;
    parse_header(head, from)?;
    let stored = u32_at(head, BLOCK_CRC_AT);
    let computed = checksum(&head[..BLOCK_CRC_AT], payload);
    if stored != computed {
        return Err(BlockProblem::BlockChecksumMismatch { stored, computed });
    }
    let mut out = bytes.to_vec();
    out[10..12].copy_from_slice(&to.code().to_le_bytes());
    let block_crc = checksum(&out[..BLOCK_CRC_AT], payload);
    out[BLOCK_CRC_AT..BLOCK_HEADER_LEN].copy_from_slice(&block_crc.to_le_bytes());
    Ok(out)
}

fn decode(bytes: &[u8], expected: RecordKind) -> Result<Block, BlockProblem> {
    let (head, payload) = bytes
        .split_first_chunk::<BLOCK_HEADER_LEN>()
        .ok_or(BlockProblem::TooShort { len: bytes.len() })?;
    let (kind, record_count, raw_len) = parse_header(head, expected)?;
    let stored = u32_at(head, BLOCK_CRC_AT);
    let computed = checksum(&head[..BLOCK_CRC_AT], payload);
    if stored != computed {
        return Err(BlockProblem::BlockChecksumMismatch { stored, computed });
    }
    check_one_frame(payload)?;
    let raw = inflate(payload, raw_len)?;
    let stored = u32_at(head, RAW_CRC_AT);
    let computed = crc32fast::hash(&raw);
    if stored != computed {
        return Err(BlockProblem::RawChecksumMismatch { stored, computed });
    }
    Ok(Block {
        kind,
        record_count,
        raw,
    })
}

/// Checks magic, version, kind and raw length; returns (kind, record count, raw length).
fn parse_header(
    head: &[u8; BLOCK_HEADER_LEN],
    expected: RecordKind,
) -> Result<(RecordKind, u64, u64), BlockProblem> {
    let (magic, rest) = head
        .split_first_chunk::<8>()
        .ok_or(BlockProblem::TooShort { len: 0 })?;
    if *magic != BLOCK_MAGIC {
        return Err(BlockProblem::BadMagic { found: *magic });
    }
    let version = u16::from_le_bytes([rest[0], rest[1]]);
    if version != BLOCK_VERSION {
        return Err(BlockProblem::UnsupportedVersion {
            found: version,
            supported: BLOCK_VERSION,
        });
    }
    let code = u16::from_le_bytes([rest[2], rest[3]]);
    let kind = RecordKind::from_code(code).ok_or(BlockProblem::UnknownKind {
        found: code,
        expected,
    })?;
    if kind != expected {
        return Err(BlockProblem::UnexpectedKind {
            found: kind,
            expected,
        });
    }
    let record_count = u64_at(head, 12);
    let raw_len = u64_at(head, 20);
    if raw_len > MAX_RAW_LEN {
        return Err(BlockProblem::RawTooLarge {
            len: raw_len,
            max: MAX_RAW_LEN,
        });
    }
    Ok((kind, record_count, raw_len))
}

fn u32_at(head: &[u8; BLOCK_HEADER_LEN], at: usize) -> u32 {
    let mut word = [0u8; 4];
    word.copy_from_slice(&head[at..at + 4]);
    u32::from_le_bytes(word)
}

fn u64_at(head: &[u8; BLOCK_HEADER_LEN], at: usize) -> u64 {
    let mut word = [0u8; 8];
    word.copy_from_slice(&head[at..at + 8]);
    u64::from_le_bytes(word)
}

/// The checks [`decode_block`] makes before decompressing (header, block CRC, one whole zstd
/// frame), for [`super::block_stream`]: the declared raw length and the raw CRC.
pub(super) fn verify_stored(
    bytes: &[u8],
    expected: RecordKind,
) -> Result<(u64, u32), BlockProblem> {
    let (head, payload) = bytes
        .split_first_chunk::<BLOCK_HEADER_LEN>()
        .ok_or(BlockProblem::TooShort { len: bytes.len() })?;
    let (_, _, raw_len) = parse_header(head, expected)?;
    let stored = u32_at(head, BLOCK_CRC_AT);
    let computed = checksum(&head[..BLOCK_CRC_AT], payload);
    if stored != computed {
        return Err(BlockProblem::BlockChecksumMismatch { stored, computed });
    }
    check_one_frame(payload)?;
    Ok((raw_len, u32_at(head, RAW_CRC_AT)))
}

/// Checks that the payload is exactly one whole zstd frame.
fn check_one_frame(payload: &[u8]) -> Result<(), BlockProblem> {
    let corrupt = |detail: String| BlockProblem::CorruptPayload { detail };
    let frame_len = zstd::zstd_safe::find_frame_compressed_size(payload)
        .map_err(|code| corrupt(zstd::zstd_safe::get_error_name(code).to_owned()))?;
    if frame_len != payload.len() {
        return Err(corrupt(format!(
            "{} bytes follow the {frame_len}-byte frame",
            payload.len().saturating_sub(frame_len)
        )));
    }
    Ok(())
}

/// Decompresses a payload that is exactly one zstd frame (checked) to exactly `raw_len` bytes.
fn inflate(payload: &[u8], raw_len: u64) -> Result<Vec<u8>, BlockProblem> {
    let corrupt = |detail: String| BlockProblem::CorruptPayload { detail };
    // The block CRC has vouched for the declared length (and it is <= MAX_RAW_LEN): allocate it
    // once, plus one byte to tell a longer payload from a corrupt one. zstd decompresses the
    // whole frame straight into it (no window buffer, no copy) and never writes past it.
    // (Only a 32-bit target can fail to hold it.)
    let capacity = usize::try_from(raw_len + 1)
        .ok()
        .filter(|&c| c <= isize::MAX as usize)
        .ok_or(BlockProblem::RawTooLarge {
            len: raw_len,
            max: isize::MAX as u64 - 1,
        })?;
    let mut raw = Vec::with_capacity(capacity);
    let found = match zstd::zstd_safe::decompress(&mut raw, payload) {
        Ok(found) => found as u64,
        Err(code) if zstd::zstd_safe::is_error_kind(code, ZSTD_error_dstSize_tooSmall) => {
            raw_len + 1
        }
        Err(code) => return Err(corrupt(zstd::zstd_safe::get_error_name(code).to_owned())),
    };
    if found != raw_len {
        return Err(BlockProblem::RawLengthMismatch {
            declared: raw_len,
            found,
        });
    }
    Ok(raw)
}

fn checksum(header: &[u8], payload: &[u8]) -> u32 {
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(header);
    hasher.update(payload);
    hasher.finalize()
}

#[cfg(test)]
mod tests;
