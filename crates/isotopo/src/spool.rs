//! Records written once to a scratch file and read back in any order: what a job holds for
//! each of 100,000 handles while it finds the order to report them in, with only their places
//! in memory.

use crate::error::{Error, Result};
use std::io::Write;

/// An unnamed scratch file of records (gone when dropped, even if the process is killed).
pub(crate) struct Spool {
    file: std::io::BufWriter<std::fs::File>,
    len: u64,
}

/// Where a record lies in its spool.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Place {
    offset: u64,
    len: u32,
}

fn scratch_error(e: std::io::Error) -> Error {
    Error::scratch("write", "the results", e, TMPDIR_ADVICE)
}

/// What to do when a scratch file fails.
pub(crate) const TMPDIR_ADVICE: &str = "set TMPDIR to a writable folder with room";

impl Spool {
    pub(crate) fn new() -> Result<Spool> {
        let file = tempfile::tempfile().map_err(scratch_error)?;
        Ok(Spool {
            file: std::io::BufWriter::with_capacity(1 << 20, file),
            len: 0,
        })
    }

    /// Appends a record; returns where it lies.
    pub(crate) fn push(&mut self, record: &[u8]) -> Result<Place> {
        let len = u32::try_from(record.len())
            .map_err(|_| Error::Internal("a record of more than 4 GiB".into()))?;
        self.file.write_all(record).map_err(scratch_error)?;
        let place = Place {
            offset: self.len,
            len,
        };
        self.len += record.len() as u64;
        Ok(place)
    }

    /// Done writing: the records can be read.
    pub(crate) fn finish(self) -> Result<SpoolReader> {
        let file = self
            .file
            .into_inner()
            .map_err(|e| scratch_error(e.into_error()))?;
        Ok(SpoolReader { file })
    }
}

/// The records of a finished [`Spool`].
pub(crate) struct SpoolReader {
    file: std::fs::File,
}

impl SpoolReader {
    /// The record at `place`.
    pub(crate) fn read(&self, place: Place) -> Result<Vec<u8>> {
        use std::os::unix::fs::FileExt;
        let mut bytes = vec![0u8; place.len as usize];
        self.file
            .read_exact_at(&mut bytes, place.offset)
            .map_err(|e| Error::scratch("read back", "the results", e, TMPDIR_ADVICE))?;
        Ok(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_come_back_in_any_order() {
        let mut s = Spool::new().unwrap();
        let places: Vec<Place> = (0..1000u32)
            .map(|i| s.push(format!("record {i}").as_bytes()).unwrap())
            .collect();
        let r = s.finish().unwrap();
        for i in (0..1000).rev().step_by(7) {
            assert_eq!(
                r.read(places[i]).unwrap(),
                format!("record {i}").into_bytes()
            );
        }
        assert!(r.read(places[0]).unwrap().starts_with(b"record 0"));
    }
}
