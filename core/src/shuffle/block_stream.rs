//! A block's raw bytes as a stream: decompressed piece by piece into one small reused buffer
//! and checked as [`decode_block`] checks them, for readers that convert the raw bytes straight
//! into their own arrays (split objects) instead of holding them all.

use super::block::{BLOCK_HEADER_LEN, BlockError, BlockProblem, RecordKind, decode_block};
use zstd::zstd_safe::{DCtx, InBuffer, OutBuffer};

/// Raw bytes per buffer zstd fills (it stays in the L2 cache while its bytes are converted).
const CHUNK: usize = 256 << 10;

/// The most [`RawStream::take`] hands out at once.
pub const MAX_TAKE: usize = 128 << 10;

/// Reads the raw bytes of the block `bytes` from `key` (of kind `kind`) with `read`, and
/// returns what `read` returns if the block is sound.
///
/// First checks the header (magic, version, `kind`, raw length), the block CRC and that the
/// payload is one whole zstd frame, as [`decode_block`] does; then `read` takes raw bytes from
/// the stream as zstd produces them (memory: one 384 KiB buffer and zstd's context and window,
/// whatever the raw length); then the rest of the frame is decompressed.
///
/// Guarantees: `Ok` only if the frame decompresses to exactly the declared raw length and the
/// raw CRC matches every raw byte, that is exactly when [`decode_block`] gives `Ok`; every
/// error is the one [`decode_block`] gives for these bytes, and it wins over whatever `read`
/// made of damaged bytes. `read` must not trust the raw bytes beyond what it checks itself: its
/// result is returned only once the checksum has vouched for them.
pub fn read_block<R>(
    key: &str,
    bytes: &[u8],
    kind: RecordKind,
    read: impl FnOnce(&mut RawStream<'_>) -> R,
) -> Result<R, BlockError> {
    let error = |problem| BlockError {
        key: key.to_owned(),
        problem,
    };
    let (raw_len, raw_crc) = super::block::verify_stored(bytes, kind).map_err(error)?;
    let mut stream = RawStream {
        raw_len,
        decoder: Decoder {
            payload: bytes.get(BLOCK_HEADER_LEN..).unwrap_or_default(),
            read: 0,
            dctx: DCtx::create(),
            raw_len,
            produced: 0,
            hasher: crc32fast::Hasher::new(),
            ended: false,
            failed: false,
        },
        buf: vec![0u8; MAX_TAKE + CHUNK],
        start: MAX_TAKE,
        end: MAX_TAKE,
        exhausted: false,
    };
    let result = read(&mut stream);
    let RawStream {
        mut decoder,
        mut buf,
        ..
    } = stream;
    decoder.drain(&mut buf);
    if decoder.sound(raw_crc) {
        return Ok(result);
    }
    // The one-shot decoder names the exact problem (the same zstd underneath).
    Err(match decode_block(key, bytes, kind) {
        Err(e) => e,
        Ok(_) => error(BlockProblem::CorruptPayload {
            detail: "streaming and one-shot decompression disagree".into(),
        }),
    })
}

/// The raw bytes of one block, in order (see [`read_block`]).
pub struct RawStream<'a> {
    raw_len: u64,
    decoder: Decoder<'a>,
    /// `buf[start..end]` are decompressed bytes not yet taken; zstd fills the buffer from
    /// `MAX_TAKE` on, the bytes left from the previous fill moved just before.
    buf: Vec<u8>,
    start: usize,
    end: usize,
    /// No more bytes will come (the frame ended or failed).
    exhausted: bool,
}

impl RawStream<'_> {
    /// The raw length the (CRC-checked) header declares.
    pub fn raw_len(&self) -> u64 {
        self.raw_len
    }

    /// The next `len` raw bytes (at most [`MAX_TAKE`]), or `None` if the frame ends or fails
    /// before them (then [`read_block`] gives the error).
    pub fn take(&mut self, len: usize) -> Option<&[u8]> {
        if len > MAX_TAKE {
            return None;
        }
        if self.end - self.start < len && !self.exhausted {
            self.refill();
        }
        if self.end - self.start < len {
            return None;
        }
        let at = self.start;
        self.start += len;
        self.buf.get(at..at + len)
    }

    /// Moves the bytes left (fewer than `MAX_TAKE`) before `MAX_TAKE` and decompresses the
    /// next ones after them.
    fn refill(&mut self) {
        let left = self.end - self.start;
        self.buf.copy_within(self.start..self.end, MAX_TAKE - left);
        let filled = self
            .decoder
            .fill(self.buf.get_mut(MAX_TAKE..).unwrap_or_default());
        self.start = MAX_TAKE - left;
        self.end = MAX_TAKE + filled;
        self.exhausted = filled < CHUNK;
    }
}

/// zstd over one frame, counting and checksumming what it produces.
struct Decoder<'a> {
    payload: &'a [u8],
    read: usize,
    dctx: DCtx<'static>,
    raw_len: u64,
    produced: u64,
    hasher: crc32fast::Hasher,
    /// The frame ended; or zstd failed, or the frame holds more than the declared length.
    ended: bool,
    failed: bool,
}

impl Decoder<'_> {
    /// Fills `out` with the next raw bytes until it is full or the frame ends or fails; the
    /// number of bytes written.
    fn fill(&mut self, out: &mut [u8]) -> usize {
        let mut at = 0;
        while at < out.len() && !self.ended && !self.failed {
            at += self.step(out.get_mut(at..).unwrap_or_default());
        }
        at
    }

    /// Decompresses (and checksums) the rest of the frame into `scratch`.
    fn drain(&mut self, scratch: &mut [u8]) {
        while !self.ended && !self.failed {
            self.fill(scratch);
        }
    }

    /// After the frame: whether it held exactly the declared length, with raw CRC `raw_crc`.
    fn sound(self, raw_crc: u32) -> bool {
        self.ended
            && !self.failed
            && self.produced == self.raw_len
            && self.hasher.finalize() == raw_crc
    }

    /// One zstd call into `out`, at most one byte past the declared raw length; checksums what
    /// it wrote and returns its length.
    fn step(&mut self, out: &mut [u8]) -> usize {
        let allowed = (self.raw_len + 1).saturating_sub(self.produced);
        let len = (out.len() as u64).min(allowed) as usize;
        let Some(free) = out.get_mut(..len).filter(|f| !f.is_empty()) else {
            self.failed = true;
            return 0;
        };
        let mut output = OutBuffer::around(free);
        let mut input = InBuffer::around(self.payload.get(self.read..).unwrap_or_default());
        let result = self.dctx.decompress_stream(&mut output, &mut input);
        let (wrote, consumed) = (output.pos(), input.pos());
        self.read += consumed;
        match result {
            Ok(0) => self.ended = true,
            Ok(_) if wrote == 0 && consumed == 0 => self.failed = true,
            Ok(_) => {}
            Err(_) => self.failed = true,
        }
        self.produced += wrote as u64;
        if self.produced > self.raw_len {
            self.failed = true;
        } else if let Some(new) = out.get(..wrote) {
            self.hasher.update(new);
        }
        wrote
    }
}

#[cfg(test)]
mod tests;
