//! All-or-nothing file writes: a temporary file beside the target, renamed over it when complete.

use super::io_error;
use crate::error::Result;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `path` with `fill`; on any error the target is untouched and no temporary file remains.
/// A new file gets the usual permissions (0666 less the umask on Unix); a replaced file keeps its
/// own.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".mochi-");
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    // tempfile names its own path in its errors; report the target alone.
    let plain = |e: std::io::Error| {
        let message = e.to_string();
        match message.rfind(" at path ") {
            Some(end) => std::io::Error::new(e.kind(), &message[..end]),
            None => e,
        }
    };
    let mut tmp = builder
        .tempfile_in(dir)
        .map_err(|e| io_error(path)(plain(e)))?;
    {
        let mut out = BufWriter::with_capacity(1 << 20, tmp.as_file_mut());
        fill(&mut out).map_err(io_error(path))?;
        out.flush().map_err(io_error(path))?;
    }
    if let Ok(existing) = std::fs::metadata(path) {
        tmp.as_file()
            .set_permissions(existing.permissions())
            .map_err(io_error(path))?;
    }
    tmp.persist(path)
        .map_err(|e| io_error(path)(plain(e.error)))?;
    Ok(())
}
