//! One 64-bit FNV-1a (offset basis `0xcbf29ce484222325`, prime `0x100000001b3`): a fast,
//! stable, non-cryptographic digest for ids, fingerprints, seeded draws and golden checks that
//! must be the same on every machine and in every version. Not for anything an adversary may
//! choose to collide.
//!
//! Its own crate, with no dependencies, so that every crate of the workspace (the emulator's
//! S3 server and state machine interpreter included, which do not depend on `hort-core`) uses
//! this one.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

/// FNV-1a 64's offset basis: the digest of no bytes.
pub const OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a 64's prime.
pub const PRIME: u64 = 0x0000_0100_0000_01b3;

/// The 64-bit FNV-1a digest of `bytes`.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    Fnv1a64::new().bytes(bytes).finish()
}

/// FNV-1a 64 fed in pieces: the digest of the pieces one after another is the digest of their
/// concatenation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fnv1a64(u64);

impl Fnv1a64 {
    /// The digest of nothing yet.
    pub const fn new() -> Self {
        Fnv1a64(OFFSET_BASIS)
    }

    /// Feeds `bytes`.
    pub fn bytes(mut self, bytes: &[u8]) -> Self {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(PRIME);
        }
        self
    }

    /// Feeds `bytes` in place.
    pub fn write(&mut self, bytes: &[u8]) {
        *self = self.bytes(bytes);
    }

    /// The digest of everything fed.
    pub const fn finish(self) -> u64 {
        self.0
    }
}

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published test vectors of FNV-1a 64.
    #[test]
    fn known_vectors() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn pieces_digest_as_their_concatenation() {
        let mut h = Fnv1a64::new();
        h.write(b"foo");
        h.write(b"");
        h.write(b"bar");
        assert_eq!(h.finish(), fnv1a64(b"foobar"));
    }
}
