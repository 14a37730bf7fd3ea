//! Shuffle blocks: the one binary format of every shuffle partition and intermediate blob.
//!
//! A block is a fixed 36-byte header followed by one zstd frame of the raw record bytes (see
//! [`encode_block`] for the exact layout). Record layouts inside the raw bytes belong to the
//! stages; [`columns`] helps lay them out column-wise so they compress well.

mod block;
mod block_stream;
pub mod columns;
pub(crate) mod varint;

pub use block::{
    BLOCK_HEADER_LEN, BLOCK_MAGIC, BLOCK_VERSION, Block, BlockError, BlockProblem, MAX_RAW_LEN,
    RecordKind, ZSTD_LEVEL, decode_block, encode_block, relabel_block,
};
pub use block_stream::{MAX_TAKE, RawStream, read_block};
