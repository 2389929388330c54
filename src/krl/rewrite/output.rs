//! The new bytes of an output file, in pieces: rewritten stretches and stretches of the source
//! left as they were, shared with the loaded file rather than copied (a program of a million
//! motions is written without a second copy of it in memory). Written piece by piece.

use crate::krl;

/// A file's new bytes in pieces: rewritten stretches, and stretches of the source left as
/// they were (shared with the loaded file, not copied: a program of a million motions is
/// written without a second copy of it in memory).
#[derive(Clone, Debug, Default)]
pub struct Output {
    chunks: Vec<Chunk>,
}

#[derive(Clone, Debug)]
pub(crate) enum Chunk {
    Owned(Vec<u8>),
    Shared(std::sync::Arc<Vec<u8>>, std::ops::Range<usize>),
}

impl Output {
    /// The pieces in order.
    pub fn pieces(&self) -> Vec<&[u8]> {
        self.chunks
            .iter()
            .map(|c| match c {
                Chunk::Owned(b) => &b[..],
                Chunk::Shared(src, r) => &src[r.clone()],
            })
            .filter(|p| !p.is_empty())
            .collect()
    }

    /// The bytes in one buffer.
    #[cfg(any(test, feature = "internals"))]
    pub fn to_vec(&self) -> Vec<u8> {
        self.pieces().concat()
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn len(&self) -> usize {
        self.pieces().iter().map(|p| p.len()).sum()
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub(crate) fn from_chunks(chunks: Vec<Chunk>) -> Output {
        Output { chunks }
    }

    /// The file as it was.
    pub fn source(file: &krl::SourceFile) -> Output {
        let src = file.shared_source();
        let len = src.len();
        Output {
            chunks: vec![Chunk::Shared(src, 0..len)],
        }
    }
}

impl From<Vec<u8>> for Output {
    fn from(bytes: Vec<u8>) -> Output {
        Output {
            chunks: vec![Chunk::Owned(bytes)],
        }
    }
}

impl PartialEq<&[u8]> for Output {
    fn eq(&self, other: &&[u8]) -> bool {
        self == *other
    }
}

impl PartialEq<[u8]> for Output {
    fn eq(&self, other: &[u8]) -> bool {
        let mut at = 0;
        for p in self.pieces() {
            if other.get(at..at + p.len()) != Some(p) {
                return false;
            }
            at += p.len();
        }
        at == other.len()
    }
}
