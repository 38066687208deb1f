//! The one error type of the library.

use std::path::PathBuf;

/// Everything that can go wrong in mochi, as a value (never a panic).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A sphere (or a set of spheres) breaks the rules of [`crate::SphereSet`].
    #[error("sphere {index}: {reason}")]
    InvalidSphere {
        /// Index of the offending sphere (0-based, in input order).
        index: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// A file could not be parsed; `line` is 1-based where the format has lines.
    #[error("{}{}: {msg}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Parse {
        /// The file being read.
        path: PathBuf,
        /// 1-based line (CSV) or `None` (binary formats).
        line: Option<u64>,
        /// What is wrong.
        msg: String,
    },
    /// A file could not be read or written.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file involved.
        path: PathBuf,
        /// The underlying error (shown in this error's message, so not chained as a source).
        error: std::io::Error,
    },
    /// A backend cannot run on this machine.
    #[error("backend {backend} is unavailable: {reason}")]
    BackendUnavailable {
        /// Backend name, as on the command line.
        backend: &'static str,
        /// Why it cannot run.
        reason: String,
    },
    /// The input is larger than a backend or a scene allows.
    #[error("{what}: {got} exceeds the limit of {limit}")]
    TooLarge {
        /// What was counted.
        what: String,
        /// The requested amount.
        got: u64,
        /// The largest amount allowed.
        limit: u64,
    },
    /// Memory for something whose size comes from the input could not be had.
    #[error("{what}: out of memory ({bytes} bytes needed)")]
    OutOfMemory {
        /// What the memory was for, with its count.
        what: String,
        /// Bytes asked for.
        bytes: u64,
    },
    /// The GPU failed: out of memory, a lost device, a rejected command.
    #[error("GPU: {0}")]
    Gpu(String),
    /// A call was made in the wrong order or with mismatched arguments.
    #[error("{0}")]
    Usage(String),
    /// A benchmark plot could not be drawn.
    #[error("plot {name}: {msg}")]
    Plot {
        /// The plot.
        name: String,
        /// What went wrong.
        msg: String,
    },
}

/// Shorthand for results in this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// An empty vector with room for `n` items, or [`Error::OutOfMemory`] naming `what` (a count
/// taken from the input must never abort the process).
pub(crate) fn try_vec<T>(n: usize, what: impl FnOnce() -> String) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| Error::OutOfMemory {
        what: what(),
        bytes: (n as u64).saturating_mul(std::mem::size_of::<T>() as u64),
    })?;
    Ok(v)
}

/// Pushes `item`, growing `v` fallibly (see [`try_vec`]).
pub(crate) fn try_push<T>(v: &mut Vec<T>, item: T, what: impl FnOnce() -> String) -> Result<()> {
    if v.len() == v.capacity() {
        let more = v.capacity().max(16);
        v.try_reserve(more).map_err(|_| Error::OutOfMemory {
            what: what(),
            bytes: ((v.len() + more) as u64).saturating_mul(std::mem::size_of::<T>() as u64),
        })?;
    }
    v.push(item);
    Ok(())
}
