//! The `mochi` command-line tool; everything it does is in `mochi_cli::commands`.
#![deny(unsafe_code)]

fn main() -> std::process::ExitCode {
    restore_sigpipe();
    mochi_cli::commands::main()
}

/// Lets a closed pipe end the process quietly, as it does other Unix tools (`mochi backends |
/// head -1`): Rust ignores SIGPIPE by default, so printing into a closed pipe would panic.
#[cfg(unix)]
#[allow(unsafe_code)] // stable Rust has no safe way to set a signal's action
fn restore_sigpipe() {
    // SAFETY: called first thing in main, before any thread exists; SIG_DFL is a valid handler.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn restore_sigpipe() {}
