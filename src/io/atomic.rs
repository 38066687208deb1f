//! All-or-nothing file writes: a temporary file beside the target, renamed over it when complete.

use super::io_error;
use crate::error::Result;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `path` with `fill`; on any error the target is untouched and no temporary file remains.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".mochi-")
        .tempfile_in(dir)
        .map_err(io_error(path))?;
    {
        let mut out = BufWriter::with_capacity(1 << 20, tmp.as_file_mut());
        fill(&mut out).map_err(io_error(path))?;
        out.flush().map_err(io_error(path))?;
    }
    tmp.persist(path).map_err(|e| io_error(path)(e.error))?;
    Ok(())
}
