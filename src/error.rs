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
    /// A setting is invalid: a scene file's or a command-line option's value, a parameter, or
    /// options that cannot go together.
    #[error("{what}: {reason}")]
    InvalidConfig {
        /// The setting (or settings), as the user wrote it where possible.
        what: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A simulation blew up: a sphere's position or velocity stopped being finite.
    #[error(
        "the simulation became unstable by step {step}: sphere {sphere} {what}; try a smaller \
         time step or a softer stiffness"
    )]
    Unstable {
        /// The step whose state was found non-finite (the state is checked between batches
        /// of steps, so the blow-up began at or before it).
        step: u64,
        /// The first such sphere, 0-based in input order.
        sphere: usize,
        /// What is not finite about it.
        what: String,
    },
    /// `auto` found no backend that runs here.
    #[error("no backend can run here: {}", list_reasons(reasons))]
    NoBackend {
        /// Each backend tried (name as on the command line) and why it could not run.
        reasons: Vec<(&'static str, String)>,
    },
    /// The GPU failed: out of memory, a lost device, a rejected command.
    #[error("GPU: {0}")]
    Gpu(String),
    /// The OptiX or CUDA layer of the optix backend failed.
    #[cfg(feature = "optix")]
    #[error(transparent)]
    Optix(OptixError),
    /// A checkpoint's scene or particles do not pass the checks of a resumed run.
    #[error("resuming {}: {error}", checkpoint.display())]
    Resuming {
        /// The checkpoint.
        checkpoint: PathBuf,
        /// What is wrong with its scene or particles.
        error: Box<Error>,
    },
    /// A library call was made in the wrong order or with mismatched arguments (a bug in the
    /// caller, never the user's input).
    #[error("{0}")]
    Usage(String),
}

impl Error {
    /// This error as the reason a backend was passed over: a [`Error::BackendUnavailable`]'s own
    /// reason (the backend is named beside it), else the whole message.
    pub fn into_reason(self) -> String {
        match self {
            Error::BackendUnavailable { reason, .. } => reason,
            e => e.to_string(),
        }
    }
}

/// "name: reason; name: reason".
fn list_reasons(reasons: &[(&'static str, String)]) -> String {
    let parts: Vec<String> = reasons
        .iter()
        .map(|(name, why)| format!("{name}: {why}"))
        .collect();
    parts.join("; ")
}

/// A failure of the OptiX/CUDA layer (`engines::optix`): an OptiX call's status, a CUDA driver
/// error, an NVRTC compilation with its log, or a launch whose buffers do not match its count.
#[cfg(feature = "optix")]
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum OptixError {
    /// The NVIDIA driver, its OptiX or NVRTC cannot be used here (becomes
    /// [`Error::BackendUnavailable`]).
    #[error("{0}")]
    Unavailable(String),
    /// An OptiX call returned an error status.
    #[error("OptiX {call}: {name} ({code}){}", log_suffix(log))]
    Call {
        /// What was being done (the call, in words).
        call: &'static str,
        /// `OptixResult` status code.
        code: i32,
        /// The status's name, as OptiX gives it.
        name: String,
        /// The compiler's or linker's log, where the call writes one (may be empty).
        log: String,
    },
    /// A CUDA driver call failed.
    #[error("CUDA {call}: {error}")]
    Cuda {
        /// What was being done.
        call: &'static str,
        /// The driver's status.
        #[source]
        error: cudarc::driver::DriverError,
    },
    /// NVRTC could not compile a unit of the device code.
    #[error("NVRTC could not compile {unit}: {log}")]
    Compile {
        /// The unit's name (`optix/detect.cu`, ...).
        unit: String,
        /// NVRTC's log (or its status where it wrote none).
        log: String,
    },
    /// A launch was given a buffer shorter than its count needs (a bug in the caller).
    #[error("{launch}: buffer {buffer} holds {len} elements, {needed} needed")]
    BufferTooShort {
        /// The kernel or device program.
        launch: &'static str,
        /// The parameter.
        buffer: &'static str,
        /// Its length in elements.
        len: usize,
        /// Elements the launch reads or writes.
        needed: usize,
    },
    /// An index buffer holds an entry beyond the rows it indexes (a bug in the caller).
    #[error("{buffer}: entry {index} is out of range for {len} rows")]
    IndexOutOfRange {
        /// The buffer.
        buffer: &'static str,
        /// The offending entry.
        index: u64,
        /// Rows it indexes.
        len: usize,
    },
}

#[cfg(feature = "optix")]
fn log_suffix(log: &str) -> String {
    let log = log.trim_end_matches('\0').trim();
    if log.is_empty() {
        String::new()
    } else {
        format!(": {log}")
    }
}

#[cfg(feature = "optix")]
impl From<OptixError> for Error {
    /// A missing driver, OptiX or NVRTC means the backend is unavailable; the rest are failures
    /// of the OptiX/CUDA layer.
    fn from(e: OptixError) -> Self {
        match e {
            OptixError::Unavailable(reason) => Error::BackendUnavailable {
                backend: "optix",
                reason,
            },
            e => Error::Optix(e),
        }
    }
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

/// Resizes `v` to `n` items, new ones `value`, growing it fallibly (see [`try_vec`]).
pub(crate) fn try_resize<T: Clone>(
    v: &mut Vec<T>,
    n: usize,
    value: T,
    what: impl FnOnce() -> String,
) -> Result<()> {
    if let Some(more) = n.checked_sub(v.len()) {
        v.try_reserve_exact(more).map_err(|_| Error::OutOfMemory {
            what: what(),
            bytes: (n as u64).saturating_mul(std::mem::size_of::<T>() as u64),
        })?;
    }
    v.resize(n, value);
    Ok(())
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
