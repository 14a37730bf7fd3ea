//! Column-wise record layout for the raw bytes of a block, chosen so zstd compresses it well.
//!
//! A stage writes each field of its records as one column, in a fixed order, and reads them back
//! in the same order. Each column is a tag byte, the value count as a LEB128 varint
//! (`shuffle::varint`, at most 10 bytes), then:
//!
//! | tag | writer | payload |
//! |-----|--------|---------|
//! | 1 | [`ColumnWriter::put_u32_sorted_delta`] | LEB128 varints of successive differences (mod 2^32) |
//! | 2 | [`ColumnWriter::put_u32`] | byte planes: every value's byte 0, then every byte 1, ... (little-endian) |
//! | 3 | [`ColumnWriter::put_f32`] | byte planes of the IEEE-754 bits (exact, NaN payloads kept) |
//! | 4 | [`ColumnWriter::put_bytes`] | the bytes |
//! | 5 | [`ColumnWriter::put_f32_delta`] | byte planes of the zigzagged differences (mod 2^32) of successive IEEE-754 bit patterns, the first from 0 (exact) |
//!
//! Byte planes put the slowly varying high bytes (exponents, high id bits) next to each other,
//! where zstd finds long runs; bit differences of neighbouring samples' nearby floats (positions,
//! normals, distances) also clear most of the middle bytes. Reading never panics and never allocates more than the input
//! length allows; errors carry no key (the caller adds it).

use super::varint::{self, VarintError};

/// Why a column could not be read. The column index counts from 0 in reading order.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ColumnError {
    /// The input ends inside column `column`.
    #[error("column {column}: truncated, needs {needed} more bytes, {available} left")]
    Truncated {
        /// Index of the column being read.
        column: usize,
        /// Bytes the column still needs (at least).
        needed: u64,
        /// Bytes left in the input.
        available: usize,
    },
    /// The column has a different type than the reader asked for.
    #[error("column {column}: holds tag {found}, expected {expected} (tag {expected_tag})")]
    WrongType {
        /// Index of the column being read.
        column: usize,
        /// The tag byte found.
        found: u8,
        /// The column type asked for.
        expected: &'static str,
        /// Its tag.
        expected_tag: u8,
    },
    /// A varint is longer than its type allows.
    #[error("column {column}: malformed varint")]
    BadVarint {
        /// Index of the column being read.
        column: usize,
    },
    /// Bytes remain after the last column the caller read.
    #[error("{count} unread bytes after column {columns_read}")]
    TrailingBytes {
        /// Number of unread bytes.
        count: usize,
        /// Number of columns read.
        columns_read: usize,
    },
}

const TAG_U32_SORTED_DELTA: u8 = 1;
const TAG_U32: u8 = 2;
const TAG_F32: u8 = 3;
const TAG_BYTES: u8 = 4;
const TAG_F32_DELTA: u8 = 5;

/// Zigzag: small differences of either sign become small unsigned numbers.
fn zigzag(delta: u32) -> u32 {
    let d = delta as i32;
    ((d << 1) ^ (d >> 31)) as u32
}

fn unzigzag(z: u32) -> u32 {
    (z >> 1) ^ (z & 1).wrapping_neg()
}

/// Builds the raw bytes of a block one column at a time. Output is a pure function of the calls.
#[derive(Debug, Clone, Default)]
pub struct ColumnWriter {
    bytes: Vec<u8>,
}

impl ColumnWriter {
    /// An empty writer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a column of `u32`s as varint deltas: about one byte per value when the column is
    /// non-decreasing with small steps (sorted pixel indices). Any column round-trips exactly;
    /// an unsorted one just compresses worse (differences wrap modulo 2^32).
    pub fn put_u32_sorted_delta(&mut self, values: &[u32]) {
        self.header(TAG_U32_SORTED_DELTA, values.len());
        let mut previous = 0u32;
        for &value in values {
            varint::write(&mut self.bytes, u64::from(value.wrapping_sub(previous)));
            previous = value;
        }
    }

    /// Appends a column of `u32`s, split into byte planes.
    pub fn put_u32(&mut self, values: &[u32]) {
        self.header(TAG_U32, values.len());
        self.put_planes(values.iter().map(|v| v.to_le_bytes()), values.len());
    }

    /// Appends a column of `f32`s (their exact bits), split into byte planes.
    pub fn put_f32(&mut self, values: &[f32]) {
        self.header(TAG_F32, values.len());
        self.put_planes(
            values.iter().map(|v| v.to_bits().to_le_bytes()),
            values.len(),
        );
    }

    /// Appends a column of `f32`s (their exact bits) as the zigzagged differences of successive
    /// bit patterns, split into byte planes: smaller than [`ColumnWriter::put_f32`] after zstd
    /// when neighbouring values are close (measured in docs/ARCHITECTURE.md, section 8).
    /// [`ColumnReader::read_f32`] reads either.
    pub fn put_f32_delta(&mut self, values: &[f32]) {
        self.header(TAG_F32_DELTA, values.len());
        let mut previous = 0u32;
        let deltas = values.iter().map(|v| {
            let bits = v.to_bits();
            let delta = zigzag(bits.wrapping_sub(previous));
            previous = bits;
            delta.to_le_bytes()
        });
        let deltas: Vec<[u8; 4]> = deltas.collect();
        self.put_planes(deltas.iter().copied(), values.len());
    }

    /// Appends a column of bytes as they are (flags, small enums, nested encodings).
    pub fn put_bytes(&mut self, values: &[u8]) {
        self.header(TAG_BYTES, values.len());
        self.bytes.extend_from_slice(values);
    }

    /// Bytes written so far.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// True before the first column.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// The bytes written so far.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// The finished raw bytes.
    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }

    fn header(&mut self, tag: u8, count: usize) {
        self.bytes.push(tag);
        varint::write(&mut self.bytes, count as u64);
    }

    fn put_planes(&mut self, words: impl Iterator<Item = [u8; 4]> + Clone, count: usize) {
        self.bytes.reserve(count * 4);
        for plane in 0..4 {
            self.bytes.extend(words.clone().map(|word| word[plane]));
        }
    }
}

/// Reads columns written by [`ColumnWriter`], in the order they were written.
#[derive(Debug, Clone)]
pub struct ColumnReader<'a> {
    rest: &'a [u8],
    column: usize,
}

impl<'a> ColumnReader<'a> {
    /// A reader positioned at the first column of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self {
            rest: bytes,
            column: 0,
        }
    }

    /// Reads a [`ColumnWriter::put_u32_sorted_delta`] column.
    pub fn read_u32_sorted_delta(&mut self) -> Result<Vec<u32>, ColumnError> {
        let count = self.header(TAG_U32_SORTED_DELTA, "u32 sorted delta", 1)?;
        let mut values = Vec::with_capacity(count);
        let mut previous = 0u32;
        for _ in 0..count {
            let delta = self.varint()?;
            let delta = u32::try_from(delta).map_err(|_| self.bad_varint())?;
            previous = previous.wrapping_add(delta);
            values.push(previous);
        }
        self.column += 1;
        Ok(values)
    }

    /// Reads a [`ColumnWriter::put_u32`] column.
    pub fn read_u32(&mut self) -> Result<Vec<u32>, ColumnError> {
        Ok(self.read_u32_planes()?.u32s().collect())
    }

    /// Reads a [`ColumnWriter::put_f32`] or [`ColumnWriter::put_f32_delta`] column, bit for
    /// bit. Any other tag is a [`ColumnError::WrongType`] naming tag 3.
    pub fn read_f32(&mut self) -> Result<Vec<f32>, ColumnError> {
        if self.rest.first() != Some(&TAG_F32_DELTA) {
            return Ok(self.read_f32_planes()?.f32s().collect());
        }
        let count = self.header(TAG_F32_DELTA, "f32 delta", 4)?;
        let mut previous = 0u32;
        let values = self
            .planes(count)?
            .u32s()
            .map(|z| {
                previous = previous.wrapping_add(unzigzag(z));
                f32::from_bits(previous)
            })
            .collect();
        Ok(values)
    }

    /// Reads a [`ColumnWriter::put_u32`] column in place: its byte planes, borrowed from the
    /// input, for callers that convert the values straight into their own types.
    pub fn read_u32_planes(&mut self) -> Result<Planes<'a>, ColumnError> {
        let count = self.header(TAG_U32, "u32", 4)?;
        self.planes(count)
    }

    /// Reads a [`ColumnWriter::put_f32`] column in place, like [`ColumnReader::read_u32_planes`].
    pub fn read_f32_planes(&mut self) -> Result<Planes<'a>, ColumnError> {
        let count = self.header(TAG_F32, "f32", 4)?;
        self.planes(count)
    }

    /// Reads a [`ColumnWriter::put_bytes`] column, borrowing from the input.
    pub fn read_bytes(&mut self) -> Result<&'a [u8], ColumnError> {
        let count = self.header(TAG_BYTES, "bytes", 1)?;
        let values = self.take(count)?;
        self.column += 1;
        Ok(values)
    }

    /// Bytes not yet read.
    pub fn remaining(&self) -> usize {
        self.rest.len()
    }

    /// Succeeds only if every byte has been read: call after the last column.
    pub fn finish(self) -> Result<(), ColumnError> {
        match self.rest.len() {
            0 => Ok(()),
            count => Err(ColumnError::TrailingBytes {
                count,
                columns_read: self.column,
            }),
        }
    }

    /// Reads tag and count; checks the count fits in the input at `min_width` bytes per value.
    fn header(
        &mut self,
        tag: u8,
        name: &'static str,
        min_width: u64,
    ) -> Result<usize, ColumnError> {
        let [found] = *self.take(1)? else {
            return Err(self.truncated(1));
        };
        if found != tag {
            return Err(ColumnError::WrongType {
                column: self.column,
                found,
                expected: name,
                expected_tag: tag,
            });
        }
        let count = self.varint()?;
        let needed = count.saturating_mul(min_width);
        if needed > self.rest.len() as u64 {
            return Err(self.truncated(needed));
        }
        // `count <= rest.len()`, so it fits in usize.
        usize::try_from(count).map_err(|_| self.truncated(needed))
    }

    fn planes(&mut self, count: usize) -> Result<Planes<'a>, ColumnError> {
        let bytes = self.take(count.saturating_mul(4))?;
        let (b0, rest) = bytes.split_at(count);
        let (b1, rest) = rest.split_at(count);
        let (b2, b3) = rest.split_at(count);
        self.column += 1;
        Ok(Planes {
            planes: [b0, b1, b2, b3],
        })
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], ColumnError> {
        if n > self.rest.len() {
            return Err(self.truncated(n as u64));
        }
        let (head, tail) = self.rest.split_at(n);
        self.rest = tail;
        Ok(head)
    }

    fn varint(&mut self) -> Result<u64, ColumnError> {
        varint::read_u64(&mut self.rest).map_err(|e| match e {
            // The input ran out: one more byte was needed.
            VarintError::Truncated => self.truncated(1),
            VarintError::Malformed => self.bad_varint(),
        })
    }

    fn truncated(&self, needed: u64) -> ColumnError {
        ColumnError::Truncated {
            column: self.column,
            needed,
            available: self.rest.len(),
        }
    }

    fn bad_varint(&self) -> ColumnError {
        ColumnError::BadVarint {
            column: self.column,
        }
    }
}

/// A column of 4-byte values as written: byte 0 of every value, then byte 1, ... (see the
/// module docs), borrowed from the reader's input. Every plane has [`Planes::len`] bytes.
#[derive(Debug, Clone, Copy)]
pub struct Planes<'a> {
    planes: [&'a [u8]; 4],
}

impl<'a> Planes<'a> {
    /// Number of values.
    pub fn len(&self) -> usize {
        self.planes[0].len()
    }

    /// True for an empty column.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The values as `u32`s.
    pub fn u32s(&self) -> impl ExactSizeIterator<Item = u32> + 'a {
        self.groups::<1>().map(|[w]| w)
    }

    /// The values as `f32`s, bit for bit.
    pub fn f32s(&self) -> impl ExactSizeIterator<Item = f32> + 'a {
        self.groups::<1>().map(|[w]| f32::from_bits(w))
    }

    /// The values in consecutive groups of `K` (values `K * i .. K * i + K` as item `i`), as
    /// `u32` bits. A trailing partial group is skipped: callers check [`Planes::len`] first.
    pub fn groups<const K: usize>(&self) -> impl ExactSizeIterator<Item = [u32; K]> + 'a {
        let [b0, b1, b2, b3] = self.planes.map(|p| p.as_chunks::<K>().0);
        b0.iter()
            .zip(b1)
            .zip(b2)
            .zip(b3)
            .map(|(((b0, b1), b2), b3)| words(b0, b1, b2, b3))
    }
}

/// The little-endian words whose bytes 0, 1, 2, 3 are `b0[k]`, `b1[k]`, `b2[k]`, `b3[k]`.
#[inline(always)]
fn words<const K: usize>(b0: &[u8; K], b1: &[u8; K], b2: &[u8; K], b3: &[u8; K]) -> [u32; K] {
    std::array::from_fn(|k| u32::from_le_bytes([b0[k], b1[k], b2[k], b3[k]]))
}

#[cfg(test)]
mod tests;
