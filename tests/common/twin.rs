//! The CUDA twins of the Rust laws compiled as host C++ (no fused multiply-adds, as NVRTC
//! compiles them for the GPU), for the tests that compare them bit for bit.

use std::path::{Path, PathBuf};
use std::process::Command;

/// `source` compiled into `binary` against `optix/` with the preprocessor `defines`, or `None`
/// without a C++ compiler (`c++`), where CI fails instead; `what` names the comparison skipped.
pub fn compile(source: &Path, binary: &Path, defines: &[&str], what: &str) -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let compiled = Command::new("c++")
        .args(["-std=c++17", "-O2", "-ffp-contract=off"])
        .args(defines.iter().map(|d| format!("-D{d}")))
        .arg("-I")
        .arg(root.join("optix"))
        .arg(source)
        .arg("-o")
        .arg(binary)
        .output();
    match compiled {
        Err(why) => {
            assert!(!super::ci(), "CI expects a C++ compiler (c++): {why}");
            eprintln!("note: no C++ compiler here ({why}); {what} is not compared");
            None
        }
        Ok(out) => {
            assert!(
                out.status.success(),
                "{} does not compile as C++:\n{}",
                source.display(),
                String::from_utf8_lossy(&out.stderr)
            );
            Some(binary.to_path_buf())
        }
    }
}
