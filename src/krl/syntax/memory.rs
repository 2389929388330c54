//! Fresh memory for the big buffers of one parse (the copy of the source, the node pools, the
//! emitted bytes). A million-line program fills a few hundred megabytes that the kernel hands
//! out page by page, one fault per 4 KiB page; on a virtual machine each fault costs a
//! microsecond or two, a third of the parse. Asking the kernel to map a run of pages in one
//! call (`MADV_POPULATE_WRITE`, Linux ≥ 5.14) costs about a fifth less per page. The pages
//! are mapped just ahead of where the buffer is written, never beyond its capacity, so
//! nothing is mapped that would not be touched anyway. Elsewhere (other systems, older
//! kernels) this does nothing and the pages fault in as usual.

/// Bytes mapped per call while a pool grows: small enough that the lines the kernel zeroed
/// are still in cache when the parser writes them (measured: 256 KiB beat 4 MiB and 64 KiB).
const STEP: usize = 256 << 10;

/// How far a growing buffer's pages are mapped: the buffer's address when last seen (it
/// moves when it grows) and the address up to which its pages are mapped.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Ahead {
    base: usize,
    mapped_to: usize,
}

impl Ahead {
    /// Makes sure the pages that the next element pushed onto `v` lands on are mapped,
    /// mapping up to `STEP` bytes ahead (within the capacity) when they are not.
    #[inline]
    pub fn before_push<T>(&mut self, v: &Vec<T>) {
        self.before_extend(v, 1);
    }

    /// The same for the next `n` elements.
    #[inline]
    pub fn before_extend<T>(&mut self, v: &Vec<T>, n: usize) {
        let end = v.as_ptr() as usize + (v.len() + n) * std::mem::size_of::<T>();
        if end > self.mapped_to {
            self.advance(v, n);
        }
    }

    #[cold]
    fn advance<T>(&mut self, v: &Vec<T>, n: usize) {
        let base = v.as_ptr() as usize;
        let size = std::mem::size_of::<T>();
        let written = base + v.len() * size;
        if base != self.base {
            // A new buffer: what was mapped of the old one says nothing about it.
            self.base = base;
            self.mapped_to = written;
        }
        let from = self.mapped_to.max(written);
        let needed = written + n * size;
        let to = (from + STEP).max(needed).min(base + v.capacity() * size);
        populate(from, to);
        self.mapped_to = to.max(needed);
    }
}

/// Appends `bytes` to `out`, mapping its pages a step at a time just before they are written.
pub(crate) fn extend_mapped(out: &mut Vec<u8>, ahead: &mut Ahead, bytes: &[u8]) {
    for chunk in bytes.chunks(STEP) {
        ahead.before_extend(out, chunk.len());
        out.extend_from_slice(chunk);
    }
}

/// A copy of `bytes` in freshly mapped memory.
pub(crate) fn copy_of(bytes: &[u8]) -> Vec<u8> {
    let mut v = Vec::with_capacity(bytes.len());
    extend_mapped(&mut v, &mut Ahead::default(), bytes);
    v
}

/// Maps the whole pages inside `from..to` (addresses inside one allocation we own).
#[cfg(target_os = "linux")]
fn populate(from: usize, to: usize) {
    const PAGE: usize = 4096;
    let start = (from + PAGE - 1) & !(PAGE - 1);
    let end = to & !(PAGE - 1);
    // Small runs are not worth a system call.
    if end < start + 16 * PAGE {
        return;
    }
    // SAFETY: the range lies inside an allocation owned by the caller's Vec (its capacity),
    // and MADV_POPULATE_WRITE only maps pages as a write would: it never changes their
    // contents. A failure (older kernel: EINVAL) leaves the pages to fault in as usual.
    unsafe {
        libc::madvise(
            start as *mut libc::c_void,
            end - start,
            libc::MADV_POPULATE_WRITE,
        );
    }
}

#[cfg(not(target_os = "linux"))]
fn populate(_from: usize, _to: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapping_ahead_never_changes_what_is_pushed() {
        let mut v: Vec<u64> = Vec::with_capacity(10);
        let mut ahead = Ahead::default();
        for k in 0..3_000_000u64 {
            ahead.before_push(&v);
            v.push(k * 7);
        }
        assert!(v.iter().enumerate().all(|(i, &x)| x == i as u64 * 7));
        let src: Vec<u8> = (0..5_000_000u32).map(|i| (i % 251) as u8).collect();
        assert_eq!(copy_of(&src), src);
        assert_eq!(copy_of(b""), b"");
    }
}
