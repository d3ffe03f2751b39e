//! A cancel-safe, size-capped line reader over a tokio byte stream.

use tokio::io::{AsyncBufRead, AsyncBufReadExt};

/// Capacity a reader keeps between lines: a longer line's buffer is given back once it is done,
/// so a connection holds the message limit only while it is reading such a line.
pub const KEPT_CAPACITY: usize = 64 * 1024;

/// What [`LineReader::next_line`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Line {
    /// A complete line (with its newline) is in [`LineReader::line`].
    Complete,
    /// A line longer than the limit was skipped up to its newline.
    TooLong,
    /// The stream ended in the middle of a line; the partial line is in [`LineReader::line`].
    Partial,
    /// The stream ended cleanly.
    Eof,
}

/// Reads lines, never buffering more than the limit; its state lives in the struct, so a
/// `next_line` future dropped mid-line (in a `select!`) loses nothing.
#[derive(Debug)]
pub struct LineReader<R> {
    input: R,
    buf: Vec<u8>,
    limit: usize,
    skipping: bool,
    ready: bool,
}

impl<R: AsyncBufRead + Unpin> LineReader<R> {
    /// A reader taking lines of at most `limit` bytes (newline included).
    pub fn new(input: R, limit: usize) -> Self {
        Self {
            input,
            buf: Vec::new(),
            limit,
            skipping: false,
            ready: false,
        }
    }

    /// Changes the longest line taken from the next line on (e.g. after a short hello).
    pub fn set_limit(&mut self, limit: usize) {
        self.limit = limit;
    }

    /// The underlying reader (what it has buffered stays in it; a partial line is dropped).
    pub fn into_inner(self) -> R {
        self.input
    }

    /// The last line read (with its newline, if it had one).
    pub fn line(&self) -> &[u8] {
        &self.buf
    }

    /// Empties the line buffer, giving back capacity beyond [`KEPT_CAPACITY`].
    fn reset(&mut self) {
        self.buf.clear();
        self.buf.shrink_to(KEPT_CAPACITY);
    }

    /// Reads the next line.
    pub async fn next_line(&mut self) -> std::io::Result<Line> {
        if self.ready {
            self.reset();
            self.ready = false;
        }
        loop {
            let chunk = self.input.fill_buf().await?;
            if chunk.is_empty() {
                self.ready = true;
                return Ok(if self.skipping {
                    self.skipping = false;
                    Line::TooLong
                } else if self.buf.is_empty() {
                    Line::Eof
                } else {
                    Line::Partial
                });
            }
            let newline = chunk.iter().position(|b| *b == b'\n');
            let take = newline.map_or(chunk.len(), |i| i + 1);
            if !self.skipping {
                if self.buf.len() + take > self.limit {
                    self.skipping = true;
                    self.reset();
                } else {
                    self.buf.extend_from_slice(&chunk[..take]);
                }
            }
            self.input.consume(take);
            if newline.is_some() {
                self.ready = true;
                if self.skipping {
                    self.skipping = false;
                    return Ok(Line::TooLong);
                }
                return Ok(Line::Complete);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn lines_long_lines_and_a_cut_off_end() {
        let data: &[u8] = b"ab\nxxxxxxxxxxxx\ncd\nef";
        let mut r = LineReader::new(tokio::io::BufReader::with_capacity(4, data), 5);
        assert_eq!(r.next_line().await.unwrap(), Line::Complete);
        assert_eq!(r.line(), b"ab\n");
        // 13 bytes with the newline > 5: skipped.
        assert_eq!(r.next_line().await.unwrap(), Line::TooLong);
        assert_eq!(r.next_line().await.unwrap(), Line::Complete);
        assert_eq!(r.line(), b"cd\n");
        assert_eq!(r.next_line().await.unwrap(), Line::Partial);
        assert_eq!(r.line(), b"ef");
        assert_eq!(r.next_line().await.unwrap(), Line::Eof);
    }

    #[tokio::test]
    async fn a_long_line_gives_its_buffer_back() {
        let mut data = vec![b'x'; 600_000];
        data.push(b'\n');
        data.extend_from_slice(&[b'y'; 2_000_000]);
        data.extend_from_slice(b"\nok\n");
        let mut r = LineReader::new(tokio::io::BufReader::new(data.as_slice()), 1 << 20);
        assert_eq!(r.next_line().await.unwrap(), Line::Complete);
        assert_eq!(r.line().len(), 600_001);
        // Too long: skipped, and the half-read part's buffer given back.
        assert_eq!(r.next_line().await.unwrap(), Line::TooLong);
        assert!(r.buf.capacity() <= KEPT_CAPACITY, "{}", r.buf.capacity());
        assert_eq!(r.next_line().await.unwrap(), Line::Complete);
        assert_eq!(r.line(), b"ok\n");
        assert!(r.buf.capacity() <= KEPT_CAPACITY, "{}", r.buf.capacity());
    }
}
