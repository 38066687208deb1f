//! The `mochi` binary run as a user runs it: its exit code and what it printed.

use std::path::Path;
use std::process::Command;

/// The binary cargo built for these tests.
pub const BIN: &str = env!("CARGO_BIN_EXE_mochi");

/// Runs `mochi args` in the folder `dir`: exit code, standard output, standard error.
pub fn mochi(args: &[&str], dir: &Path) -> (Option<i32>, String, String) {
    let out = Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the binary runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs `mochi args` in `dir`, which must succeed; its standard output.
pub fn ok(args: &[&str], dir: &Path) -> String {
    let (code, stdout, stderr) = mochi(args, dir);
    assert_eq!(code, Some(0), "{args:?}\n{stdout}\n{stderr}");
    stdout
}

/// Runs `mochi args` in `dir`, which must fail with one error line and no panic; its standard
/// error.
pub fn fails(args: &[&str], dir: &Path) -> String {
    let (code, stdout, stderr) = mochi(args, dir);
    assert_eq!(
        code,
        Some(1),
        "{args:?} should fail cleanly\n{stdout}\n{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    stderr
}

/// The files of `dir` (but the run lock), with their bytes, in name order.
pub fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_name() != mochi::io::LOCK_FILE)
        .map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            (name, std::fs::read(e.path()).unwrap())
        })
        .collect();
    files.sort();
    files
}
