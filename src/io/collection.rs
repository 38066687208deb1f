//! ParaView collections (`.pvd`): a list of `<DataSet>` entries, each a file at a time step. A
//! run's collections (`series.pvd`, `walls.pvd`) grow by a frame at a time: [`append_entries`]
//! writes the new entries over the collection's closing tags in one write, so each frame costs
//! its own entries, never the whole index, and the file is a whole collection before and after.

use super::{io_error, parse_error, write_atomically};
use crate::error::Result;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

/// Everything before the entries.
const HEAD: &str = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" \
                    byte_order=\"LittleEndian\">\n  <Collection>\n";

/// Everything after the entries: what [`append_entries`] writes over.
const TAIL: &str = "  </Collection>\n</VTKFile>\n";

/// The entry of `file` at `time`, part `part`, as one line.
pub fn entry_line(time: f64, part: usize, file: &str) -> String {
    format!("    <DataSet timestep=\"{time}\" group=\"\" part=\"{part}\" file=\"{file}\"/>\n")
}

/// Writes the collection `path` with `entries` (lines of [`entry_line`]), replacing any file
/// there (through [`write_atomically`]).
pub fn write_collection(path: &Path, entries: &str) -> Result<()> {
    write_atomically(path, |out| {
        out.write_all(HEAD.as_bytes())?;
        out.write_all(entries.as_bytes())?;
        out.write_all(TAIL.as_bytes())
    })
}

/// Adds `entries` (lines of [`entry_line`]) at the end of the collection `path`, which
/// [`write_collection`] wrote: they and the closing tags go in one write over the closing tags.
/// A file that does not end in those tags is refused, unchanged.
pub fn append_entries(path: &Path, entries: &str) -> Result<()> {
    let fail = io_error(path);
    let mut file = std::fs::File::options()
        .read(true)
        .write(true)
        .open(path)
        .map_err(io_error(path))?;
    let tail = TAIL.len() as u64;
    let len = file.metadata().map_err(io_error(path))?.len();
    let mut end = vec![0; TAIL.len()];
    let ends_in_tail = len >= tail
        && file
            .seek(SeekFrom::Start(len - tail))
            .and_then(|_| file.read_exact(&mut end))
            .is_ok()
        && end == TAIL.as_bytes();
    if !ends_in_tail {
        return Err(parse_error(
            path,
            None,
            "not a collection this program wrote: it does not end in </Collection></VTKFile>",
        ));
    }
    let text = format!("{entries}{TAIL}");
    file.seek(SeekFrom::Start(len - tail))
        .and_then(|_| file.write_all(text.as_bytes()))
        .map_err(fail)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn appended_entries_read_as_if_the_collection_had_been_written_whole() {
        let dir = tempfile::tempdir().unwrap();
        let (grown, whole) = (dir.path().join("a.pvd"), dir.path().join("b.pvd"));
        let first = entry_line(0.0, 0, "frame_0.vtu");
        let second = entry_line(0.5, 1, "wall_0.vtp") + &entry_line(0.5, 0, "frame_1.vtu");
        write_collection(&grown, &first).unwrap();
        append_entries(&grown, &second).unwrap();
        write_collection(&whole, &(first + &second)).unwrap();
        let text = std::fs::read_to_string(&grown).unwrap();
        assert_eq!(text, std::fs::read_to_string(&whole).unwrap());
        assert!(text.contains(r#"<DataSet timestep="0.5" group="" part="1" file="wall_0.vtp"/>"#));
        // A file cut short (or not a collection) is refused and left as it was.
        std::fs::write(&grown, &text[..text.len() - 3]).unwrap();
        let e = append_entries(&grown, &entry_line(1.0, 0, "x.vtu")).unwrap_err();
        assert!(e.to_string().contains("not a collection"), "{e}");
        assert_eq!(
            std::fs::read_to_string(&grown).unwrap(),
            text[..text.len() - 3]
        );
    }
}
