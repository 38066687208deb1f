//! All-or-nothing file writes: a temporary file beside the target, renamed over it when complete.
//!
//! The temporary file is named `.mochi-<pid>-<random>` after the writing process, so that a later
//! run can tell the leftovers of a killed writer ([`remove_stale_temp_files`]) from the file of a
//! live one.

use super::io_error;
use crate::error::Result;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The name prefix of every temporary file this module creates.
const TEMP_PREFIX: &str = ".mochi-";

/// Symbolic links followed at most from the target to the file (as Linux's `MAXSYMLINKS`).
const MAX_LINKS: usize = 40;

/// Writes `path` with `fill`; on any error the target is untouched and no temporary file remains.
/// See [`AtomicFile`] for symbolic links, devices and pipes, and for permissions.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    fill(&mut file).map_err(io_error(path))?;
    file.commit()
}

/// A file being written: what is written goes to a temporary file beside the target, which
/// [`AtomicFile::commit`] renames over the target. Dropped without a commit (an error, a panic),
/// the temporary file is removed and the target is as it was.
///
/// A target that is a symbolic link is resolved, and the file it names is replaced (the link
/// stays). A target that exists and is neither a regular file nor a folder (a device such as
/// `/dev/null`, a FIFO, a socket) is written to directly: it cannot be replaced, and what is
/// written reaches its reader as it is written. A new file gets the usual permissions (0666 less
/// the umask on Unix); a replaced file keeps its own.
pub struct AtomicFile {
    /// The path as the caller named it (for errors).
    path: PathBuf,
    /// The file the link chain from `path` ends at.
    target: PathBuf,
    out: BufWriter<Sink>,
}

enum Sink {
    Temporary(tempfile::NamedTempFile),
    Direct(File),
}

impl Sink {
    fn file(&mut self) -> &mut File {
        match self {
            Sink::Temporary(t) => t.as_file_mut(),
            Sink::Direct(f) => f,
        }
    }
}

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.file().write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file().flush()
    }
}

impl AtomicFile {
    /// Starts writing `path`: creates the temporary file beside the file `path` resolves to (or
    /// opens a device or FIFO for writing). Fails, naming `path`, where its folder is missing or
    /// not writable.
    pub fn create(path: &Path) -> Result<Self> {
        // `metadata` follows links the way the kernel does (including /proc's links to pipes).
        let direct = std::fs::metadata(path)
            .ok()
            .filter(|m| !m.is_file() && !m.is_dir());
        let (target, sink) = if direct.is_some() {
            let file = File::options()
                .write(true)
                .open(path)
                .map_err(io_error(path))?;
            (path.to_owned(), Sink::Direct(file))
        } else {
            let target = resolve_links(path)?;
            let dir = match target.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            let prefix = format!("{TEMP_PREFIX}{}-", std::process::id());
            let mut builder = tempfile::Builder::new();
            builder.prefix(&prefix);
            #[cfg(unix)]
            builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
            let tmp = builder
                .tempfile_in(dir)
                .map_err(|e| io_error(path)(plain(e)))?;
            (target, Sink::Temporary(tmp))
        };
        Ok(Self {
            path: path.to_owned(),
            target,
            out: BufWriter::with_capacity(1 << 20, sink),
        })
    }

    /// Finishes the file: flushes it and renames it over the target (a device or FIFO is only
    /// flushed).
    pub fn commit(self) -> Result<()> {
        let path = self.path;
        let sink = self
            .out
            .into_inner()
            .map_err(|e| io_error(&path)(e.into_error()))?;
        let Sink::Temporary(tmp) = sink else {
            return Ok(());
        };
        if let Ok(existing) = std::fs::metadata(&self.target) {
            tmp.as_file()
                .set_permissions(existing.permissions())
                .map_err(io_error(&path))?;
        }
        tmp.persist(&self.target)
            .map_err(|e| io_error(&path)(plain(e.error)))?;
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.out.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// tempfile names its own path in its errors; the caller reports the target alone.
fn plain(e: std::io::Error) -> std::io::Error {
    let message = e.to_string();
    match message.rfind(" at path ") {
        Some(end) => std::io::Error::new(e.kind(), &message[..end]),
        None => e,
    }
}

/// The path at the end of the chain of symbolic links that starts at `path` (`path` itself when
/// it is no link); the last link may dangle.
fn resolve_links(path: &Path) -> Result<PathBuf> {
    let mut at = path.to_owned();
    for _ in 0..MAX_LINKS {
        match std::fs::symlink_metadata(&at) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = std::fs::read_link(&at).map_err(io_error(path))?;
                // A relative target is relative to the link's folder; an absolute one replaces.
                at = match at.parent() {
                    Some(dir) => dir.join(target),
                    None => target,
                };
            }
            _ => return Ok(at),
        }
    }
    Err(io_error(path)(std::io::Error::other(
        "too many levels of symbolic links",
    )))
}

/// Removes the temporary files of [`AtomicFile`]s in `dir` whose writing process has ended (a
/// killed run's leftovers); returns the paths removed. A file whose writer may be alive, or whose
/// name does not carry a process id, is left alone; so is everything else. Where processes cannot
/// be queried (not Unix), nothing is removed. A folder that cannot be read is skipped.
pub fn remove_stale_temp_files(dir: &Path) -> Vec<PathBuf> {
    let Ok(listing) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut removed = Vec::new();
    for entry in listing.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(writer_pid) else {
            continue;
        };
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        if is_file && !process_alive(pid) && std::fs::remove_file(entry.path()).is_ok() {
            removed.push(entry.path());
        }
    }
    removed
}

/// The process id in a temporary file's name `.mochi-<pid>-<random>`.
/// Whether `name` is the name of a temporary file of this module's.
pub(super) fn is_temp_file_name(name: &str) -> bool {
    writer_pid(name).is_some()
}

fn writer_pid(name: &str) -> Option<u32> {
    let (pid, random) = name.strip_prefix(TEMP_PREFIX)?.split_once('-')?;
    let all_digits = !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit());
    (all_digits && !random.is_empty())
        .then(|| pid.parse().ok())
        .flatten()
}

/// Whether process `pid` may be running (anything but a definite "no such process" counts).
#[cfg(unix)]
fn process_alive(pid: u32) -> bool {
    // Only a positive pid names one process (0 and negative ones name process groups).
    let Some(pid) = i32::try_from(pid)
        .ok()
        .and_then(rustix::process::Pid::from_raw)
    else {
        return true;
    };
    // Signal 0 sends nothing; it only checks that the process exists.
    rustix::process::test_kill_process(pid) != Err(rustix::io::Errno::SRCH)
}

#[cfg(not(unix))]
fn process_alive(_pid: u32) -> bool {
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_names_with_a_process_id_are_temporary_files_of_a_writer() {
        assert_eq!(writer_pid(".mochi-123-abcDEF"), Some(123));
        assert_eq!(writer_pid(".mochi-123-"), None);
        assert_eq!(writer_pid(".mochi-abcDEF"), None);
        assert_eq!(writer_pid(".mochi--x"), None);
        assert_eq!(writer_pid(".mochi.lock"), None);
        assert_eq!(writer_pid("mochi-1-x"), None);
    }

    #[cfg(unix)]
    #[test]
    fn temporary_files_of_ended_writers_are_removed_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        // A child that has exited and been reaped: its pid names no process (until reused).
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let gone = child.id();
        child.wait().unwrap();
        let stale = dir.path().join(format!(".mochi-{gone}-aaaaaa"));
        let live = dir
            .path()
            .join(format!(".mochi-{}-bbbbbb", std::process::id()));
        let legacy = dir.path().join(".mochi-cccccc");
        let foreign = dir.path().join("frame_00000000.vtu");
        for path in [&stale, &live, &legacy, &foreign] {
            std::fs::write(path, b"x").unwrap();
        }
        let writing = AtomicFile::create(&dir.path().join("out.csv")).unwrap();
        assert_eq!(remove_stale_temp_files(dir.path()), vec![stale.clone()]);
        assert!(!stale.exists());
        assert!(live.exists() && legacy.exists() && foreign.exists());
        drop(writing);
        assert!(!dir.path().join("out.csv").exists());
    }
}
