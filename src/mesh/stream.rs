//! A mesh file read front to back: either all of it in memory (an upload or a file as it is), or
//! a gzip stream decoded only as far as the reader asks, and never past the decoded-size limit.
//! Loaders look at the first bytes (a header, a triangle count), check what they announce
//! against the limits, and only then ask for the rest: a decompression bomb or a header that
//! claims millions of triangles is refused after its first few kilobytes have been inflated.

use std::borrow::Cow;
use std::io::Read;

use super::{MeshError, malformed};

/// Bytes decoded from a gzip stream per read at least (and at most, per step, [`MAX_STEP`]).
const MIN_STEP: usize = 64 << 10;
const MAX_STEP: usize = 1 << 20;

pub(super) struct Stream<'a> {
    /// Bytes at hand; `buf[pos..]` are not consumed yet. Borrowed when the whole file is in
    /// memory, owned (a window of the decoded stream) otherwise.
    buf: Cow<'a, [u8]>,
    pos: usize,
    /// The decoder of the rest of the file; `None` once its end is reached (or from the start
    /// when the file is in memory).
    src: Option<flate2::read::MultiGzDecoder<&'a [u8]>>,
    /// Whether the file is compressed (decoded as read) rather than all in memory.
    compressed: bool,
    /// Bytes decoded so far, and the most that may be.
    decoded: u64,
    limit: u64,
    /// Tests only: blocks of this size for [`line_blocks`] instead of the reader's own.
    test_block: Option<usize>,
}

/// The first two bytes of every gzip member.
pub(super) const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

impl<'a> Stream<'a> {
    /// A file as uploaded: gzip (by its magic bytes) decoded as it is read up to `limit`
    /// decoded bytes, anything else as it is.
    pub(super) fn of(bytes: &'a [u8], limit: u64) -> Stream<'a> {
        if bytes.starts_with(&GZIP_MAGIC) {
            Stream::gzip(bytes, limit)
        } else {
            Stream::whole(bytes)
        }
    }

    /// A file all in memory.
    pub(super) fn whole(bytes: &'a [u8]) -> Stream<'a> {
        Stream {
            buf: Cow::Borrowed(bytes),
            pos: 0,
            src: None,
            compressed: false,
            decoded: bytes.len() as u64,
            limit: u64::MAX,
            test_block: None,
        }
    }

    /// A gzip file (one or more members), decoded as it is read, at most `limit` bytes.
    pub(super) fn gzip(bytes: &'a [u8], limit: u64) -> Stream<'a> {
        Stream {
            buf: Cow::Owned(Vec::new()),
            pos: 0,
            src: Some(flate2::read::MultiGzDecoder::new(bytes)),
            compressed: true,
            decoded: 0,
            limit,
            test_block: None,
        }
    }

    /// Whether the file is decoded as it is read (so reading more costs memory and time).
    pub(super) fn is_compressed(&self) -> bool {
        self.compressed
    }

    /// The unconsumed bytes at hand.
    #[inline]
    pub(super) fn available(&self) -> &[u8] {
        &self.buf[self.pos..]
    }

    /// Whether the end of the file is at hand: [`Stream::available`] is all that is left.
    pub(super) fn at_end(&self) -> bool {
        self.src.is_none()
    }

    /// At least `n` unconsumed bytes at hand, unless the file ends sooner. Errors when decoding
    /// fails or would pass the limit.
    #[inline]
    pub(super) fn fill_to(&mut self, n: usize) -> Result<(), MeshError> {
        if self.buf.len() - self.pos >= n || self.src.is_none() {
            return Ok(());
        }
        self.fill_slow(n)
    }

    /// [`Stream::fill_to`], then what is at hand.
    pub(super) fn peek(&mut self, n: usize) -> Result<&[u8], MeshError> {
        self.fill_to(n)?;
        Ok(self.available())
    }

    /// Everything left, read to the end (within the limit).
    pub(super) fn rest(&mut self) -> Result<&[u8], MeshError> {
        self.peek(usize::MAX)
    }

    #[inline]
    pub(super) fn consume(&mut self, n: usize) {
        self.pos += n;
        debug_assert!(self.pos <= self.buf.len());
    }

    /// Takes the next `n` unconsumed bytes of a compressed file out of the window, which keeps
    /// what follows them (in `spare`'s allocation), so that they can be read while more is
    /// decoded. They are `taken[start..start + n]`.
    fn take_front(&mut self, n: usize, mut spare: Vec<u8>) -> (Vec<u8>, usize) {
        let buf = self.buf.to_mut();
        spare.clear();
        spare.extend_from_slice(&buf[self.pos + n..]);
        let taken = std::mem::replace(buf, spare);
        let start = std::mem::take(&mut self.pos);
        (taken, start)
    }

    /// The most bytes that can still come: exact at the end, else what the limit still allows.
    pub(super) fn remaining_bound(&self) -> u64 {
        let at_hand = (self.buf.len() - self.pos) as u64;
        if self.src.is_none() {
            at_hand
        } else {
            at_hand + self.limit.saturating_sub(self.decoded)
        }
    }

    /// Blocks of about `block` bytes for the line readers (so small files take several).
    #[cfg(test)]
    pub(super) fn with_blocks(mut self, block: usize) -> Self {
        self.test_block = Some(block);
        self
    }

    /// Bytes decoded so far (all of them for a file in memory).
    #[cfg(test)]
    pub(super) fn decoded(&self) -> u64 {
        self.decoded
    }

    /// The decoded-size limit (what a compressed file may expand to).
    pub(super) fn limit(&self) -> u64 {
        self.limit
    }

    #[cold]
    fn fill_slow(&mut self, n: usize) -> Result<(), MeshError> {
        let buf = self.buf.to_mut();
        // Drop what was consumed, so the window holds only what is still needed.
        if self.pos > 0 {
            buf.drain(..self.pos);
            self.pos = 0;
        }
        while buf.len() < n {
            let Some(src) = &mut self.src else { break };
            // Never decode more than one byte past the limit: that byte is how going over it
            // is seen.
            let room = self.limit.saturating_add(1).saturating_sub(self.decoded);
            let step = (n - buf.len())
                .clamp(MIN_STEP, MAX_STEP)
                .min(usize::try_from(room).unwrap_or(usize::MAX));
            let old = buf.len();
            buf.resize(old + step, 0);
            let got = loop {
                match src.read(&mut buf[old..]) {
                    Ok(k) => break k,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(e) => {
                        buf.truncate(old);
                        return Err(malformed("gzip", format!("cannot decompress: {e}")));
                    }
                }
            };
            buf.truncate(old + got);
            if got == 0 {
                self.src = None;
                break;
            }
            self.decoded += got as u64;
            if self.decoded > self.limit {
                self.src = None;
                return Err(MeshError::TooLarge(self.limit));
            }
        }
        Ok(())
    }
}

/// Bytes [`line_blocks`] decodes before the first block of a compressed file is read.
const FIRST_BLOCK: usize = 1 << 20;

/// Feeds `f` the unconsumed rest of the file in blocks of whole lines: all of it at once when it
/// is in memory, else blocks of about `block` bytes cut after a line that `line_end` accepts (it
/// gives the end of the last complete line of a block). A line longer than `max_line` in a
/// compressed file is refused. `f` gets each block and whether it is the last; while it reads a
/// block of a compressed file, the next one is decoded.
pub(super) fn line_blocks(
    s: &mut Stream,
    format: &'static str,
    block: usize,
    max_line: usize,
    line_end: fn(&[u8]) -> Option<usize>,
    mut f: impl FnMut(&[u8], bool) -> Result<(), MeshError> + Send,
) -> Result<(), MeshError> {
    let block = s
        .test_block
        .unwrap_or(if s.compressed { block } else { usize::MAX });
    // The first block is small: it is read while the next is decoded, but nothing is read
    // while it is.
    let mut want = block.min(FIRST_BLOCK);
    // The allocation of the block read last, for the window to reuse.
    let mut spare = Vec::new();
    loop {
        s.fill_to(want)?;
        let at_end = s.at_end();
        let avail = s.available();
        if avail.is_empty() {
            // Called once more with nothing, so a reader can finish its state.
            return f(&[], true);
        }
        let end = if at_end && avail.len() <= block {
            avail.len()
        } else {
            let first = line_end(&avail[..avail.len().min(block)]);
            match first.or_else(|| line_end(avail)) {
                Some(e) => e,
                None if at_end => avail.len(),
                None if avail.len() > max_line => {
                    return Err(malformed(
                        format,
                        format!("a line is longer than {max_line} bytes"),
                    ));
                }
                None => {
                    want = avail.len().saturating_mul(2).min(max_line + 1);
                    continue;
                }
            }
        };
        let last = at_end && end == avail.len();
        if last || !s.compressed {
            f(&avail[..end], last)?;
            if last {
                return Ok(());
            }
            s.consume(end);
        } else {
            // The next block is decoded while this one is read: the two take about as long for
            // OBJ text, and inflating is serial. One worker of the pool decodes, the others
            // read (and the decoder helps them once it is done): a thread of its own would
            // compete with them for the cores. Decoding stays within the limit, one block
            // ahead at most; an error of this block wins over one of decoding the next, as
            // when they came one after the other.
            let (taken, start) = s.take_front(end, std::mem::take(&mut spare));
            let (ahead, read) =
                rayon::join(|| s.fill_to(block), || f(&taken[start..start + end], false));
            read?;
            ahead?;
            spare = taken;
        }
        want = block;
    }
}

/// The end of the last line of `b` (just past its `\n`).
pub(super) fn after_last_newline(b: &[u8]) -> Option<usize> {
    b.iter().rposition(|&c| c == b'\n').map(|i| i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testkit::gz;

    #[test]
    fn gzip_stream_stops_at_the_limit() {
        let data = vec![7u8; 3 << 20];
        let z = gz(&data);
        let mut s = Stream::gzip(&z, 1 << 20);
        assert_eq!(s.peek(10).unwrap()[0], 7);
        assert!(s.available().len() <= MAX_STEP);
        assert_eq!(s.rest().unwrap_err(), MeshError::TooLarge(1 << 20));
        // At the limit exactly is fine.
        let mut s = Stream::gzip(&z, 3 << 20);
        assert_eq!(s.rest().unwrap().len(), 3 << 20);
        assert!(s.at_end());
    }

    #[test]
    fn blocks_are_whole_lines() {
        let text: Vec<u8> = (0..200_000)
            .flat_map(|i| format!("line {i}\n").into_bytes())
            .collect();
        let z = gz(&text);
        let mut s = Stream::gzip(&z, u64::MAX);
        let mut seen = Vec::new();
        let mut blocks = 0;
        line_blocks(&mut s, "test", 100_000, 1000, after_last_newline, |b, _| {
            assert!(b.is_empty() || b.ends_with(b"\n"));
            seen.extend_from_slice(b);
            blocks += 1;
            Ok(())
        })
        .unwrap();
        assert_eq!(seen, text);
        assert!(blocks > 5);
        // A compressed file with an endless line is refused once the line is too long.
        let z = gz(&vec![b' '; 1 << 20]);
        let mut s = Stream::gzip(&z, u64::MAX);
        let e = line_blocks(&mut s, "test", 1000, 10_000, after_last_newline, |_, _| {
            Ok(())
        });
        assert!(e.unwrap_err().to_string().contains("longer than 10000"));
    }
}
