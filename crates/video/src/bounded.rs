//! A reader with a budget of operations, around the bytes handed to the MP4 demuxer.
//!
//! `re_mp4` (0.5) loops over child boxes by seeking to `start + size`; a child box whose size
//! field is 0 makes it seek back to where it was, forever (found by fuzzing: an `avc1` sample
//! entry with a zero-sized child). A parse reads and seeks a few times per box and table entry,
//! so it needs far fewer operations than the file has bytes; past a budget proportional to
//! the length every operation fails, and the demuxer returns an error instead of hanging.

use std::io::{Cursor, Read, Seek, SeekFrom};

/// Reads and seeks allowed per byte of the file (plus a constant for tiny files).
const OPS_PER_BYTE: u64 = 4;
const OPS_BASE: u64 = 10_000;

/// `Cursor` over `bytes` that fails every read and seek after its budget is spent.
pub(crate) struct Bounded<'a> {
    inner: Cursor<&'a [u8]>,
    left: u64,
}

impl<'a> Bounded<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Bounded {
            inner: Cursor::new(bytes),
            left: OPS_BASE + OPS_PER_BYTE * bytes.len() as u64,
        }
    }

    /// True when the budget ran out (the error then came from it).
    pub(crate) fn exhausted(&self) -> bool {
        self.left == 0
    }

    fn spend(&mut self) -> std::io::Result<()> {
        if self.left == 0 {
            return Err(std::io::Error::other("read budget exhausted"));
        }
        self.left -= 1;
        Ok(())
    }
}

impl Read for Bounded<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.spend()?;
        self.inner.read(buf)
    }
}

impl Seek for Bounded<'_> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.spend()?;
        self.inner.seek(pos)
    }
}
