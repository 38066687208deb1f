//! Inputs larger than memory or than the documented limits: each is refused with one `error:`
//! line naming the limit or the memory it needed, never an allocation abort. The binary runs
//! under a cap on its address space (`RLIMIT_AS`), so an allocation sized by the input fails
//! inside the test instead of depending on the machine's memory.
#![cfg(target_os = "linux")]

use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::Command;
use tempfile::TempDir;

const BIN: &str = env!("CARGO_BIN_EXE_mochi");

/// Address space the binary may map: enough for its code, threads and small scenes.
const CAP_BYTES: u64 = 1 << 30;

/// Runs mochi with its address space capped at [`CAP_BYTES`]; returns the single `error:` line
/// it must have printed alone (after checking it did not abort, panic or succeed).
fn capped_error(args: &[&str], dir: &Path) -> String {
    let stderr = capped(args, dir);
    let lines: Vec<&str> = stderr.lines().collect();
    assert!(
        lines.len() == 1 && lines[0].starts_with("error:"),
        "expected one error line\n{args:?}\n{stderr}"
    );
    lines[0].to_owned()
}

/// Runs mochi with its address space capped at [`CAP_BYTES`]; returns what it printed on
/// standard error, which must end with its one `error:` line (after checking it did not abort,
/// panic or succeed).
fn capped(args: &[&str], dir: &Path) -> String {
    let mut command = Command::new(BIN);
    command
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_BACKTRACE")
        // Few threads and malloc arenas, so the cap is spent on data rather than reservations.
        .env("RAYON_NUM_THREADS", "2")
        .env("MALLOC_ARENA_MAX", "2");
    // SAFETY: setrlimit is async-signal-safe and touches only the child.
    unsafe {
        command.pre_exec(|| {
            let cap = libc::rlimit {
                rlim_cur: CAP_BYTES,
                rlim_max: CAP_BYTES,
            };
            match libc::setrlimit(libc::RLIMIT_AS, &cap) {
                0 => Ok(()),
                _ => Err(std::io::Error::last_os_error()),
            }
        });
    }
    let out = command.output().expect("the binary runs");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let describe = format!("{args:?}: exit {:?}\n{stderr}", out.status.code());
    match out.status.code() {
        None => panic!("killed by a signal (an allocation abort?)\n{describe}"),
        Some(0) => panic!("expected failure\n{describe}"),
        Some(101) => panic!("exit 101 looks like a panic\n{describe}"),
        Some(_) => {}
    }
    let errors = stderr.lines().filter(|l| l.starts_with("error:")).count();
    let last = stderr.lines().last().unwrap_or("");
    assert!(
        errors == 1 && last.starts_with("error:"),
        "expected one error line, last\n{describe}"
    );
    stderr
}

fn assert_contains(line: &str, want: &str) {
    assert!(line.contains(want), "{line:?} should contain {want:?}");
}

#[test]
fn sphere_counts_beyond_the_index_limit_are_refused_up_front() {
    let dir = TempDir::new().unwrap();
    let limit = "exceeds the limit of 4294967295";
    for args in [
        &[
            "generate",
            "--layout",
            "random",
            "-n",
            "10000000000",
            "-o",
            "g.csv",
        ][..],
        &["detect", "--backend", "cpu", "-n", "10000000000"],
        &[
            "bench",
            "--backends",
            "cpu",
            "--spheres",
            "10000000000",
            "-q",
        ],
        &[
            "simulate",
            "--backend",
            "cpu",
            "-n",
            "10000000000",
            "-o",
            "s",
        ],
    ] {
        assert_contains(&capped_error(args, dir.path()), limit);
    }
    assert!(!dir.path().join("g.csv").exists());
    assert!(!dir.path().join("s").exists());
}

#[test]
fn generated_scenes_larger_than_memory_are_refused() {
    let dir = TempDir::new().unwrap();
    let n = "4000000000";
    for args in [
        &["generate", "--layout", "random", "-n", n, "-o", "g.csv"][..],
        &["detect", "--backend", "cpu", "-n", n],
        &["bench", "--backends", "cpu", "--spheres", n, "-q"],
    ] {
        let line = capped_error(args, dir.path());
        assert_contains(&line, "4000000000 spheres");
        assert_contains(&line, "out of memory");
    }
    assert!(!dir.path().join("g.csv").exists());
}

#[test]
fn npy_header_longer_than_the_file_is_refused_before_allocation() {
    let dir = TempDir::new().unwrap();
    let dict = b"{'descr': '<f4', 'fortran_order': False, 'shape': (1, 4), }\n";
    // Version 2: a 4-byte header length, here almost 4 GiB in a file of a few dozen bytes.
    let mut bytes = b"\x93NUMPY\x02\x00".to_vec();
    bytes.extend(0xFFFF_FFF0u32.to_le_bytes());
    bytes.extend(dict);
    std::fs::write(dir.path().join("big.npy"), bytes).unwrap();
    let line = capped_error(&["detect", "--backend", "cpu", "big.npy"], dir.path());
    assert_contains(
        &line,
        "big.npy: not a .npy file: its header declares 4294967280 bytes",
    );
}

#[test]
fn csv_line_longer_than_the_limit_is_refused_without_reading_it() {
    let dir = TempDir::new().unwrap();
    // A header, then one line of 1.5 GB (a sparse file: the line reads as NUL bytes).
    let path = dir.path().join("long.csv");
    std::fs::write(&path, "x,y,z,r\n").unwrap();
    let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    file.set_len(1_500_000_000).unwrap();
    let line = capped_error(&["detect", "--backend", "cpu", "long.csv"], dir.path());
    assert_contains(
        &line,
        "long.csv:2: line longer than the limit of 4096 bytes",
    );
}

#[test]
fn pairs_that_do_not_fit_in_memory_stop_with_their_count() {
    let dir = TempDir::new().unwrap();
    // 20,000 coincident spheres: every one of the 199,990,000 pairs collides (1.6 GB of pairs).
    let n = 20_000u64;
    let mut csv = String::from("x,y,z,r\n");
    csv.extend((0..n).map(|_| "0,0,0,1\n"));
    std::fs::write(dir.path().join("same.csv"), csv).unwrap();
    let args = ["detect", "--backend", "cpu", "same.csv", "-o", "pairs.csv"];
    let line = capped_error(&args, dir.path());
    assert_contains(
        &line,
        &format!("{} colliding pairs: out of memory", n * (n - 1) / 2),
    );
    assert!(!dir.path().join("pairs.csv").exists());
}

#[test]
fn npy_data_larger_than_memory_is_refused() {
    let dir = TempDir::new().unwrap();
    // 37.5 million rows of float32: 600 MB of data (a sparse file), twice that to hold.
    let mut dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (37500000, 4), }".to_owned();
    while !(10 + dict.len() + 1).is_multiple_of(64) {
        dict.push(' ');
    }
    dict.push('\n');
    let mut header = b"\x93NUMPY\x01\x00".to_vec();
    header.extend((dict.len() as u16).to_le_bytes());
    header.extend(dict.as_bytes());
    let path = dir.path().join("rows.npy");
    std::fs::write(&path, &header).unwrap();
    let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    file.set_len(header.len() as u64 + 600_000_000).unwrap();
    let line = capped_error(&["detect", "--backend", "cpu", "rows.npy"], dir.path());
    assert_contains(&line, "37500000 rows of rows.npy: out of memory");
}

#[test]
fn equipment_and_steps_larger_than_memory_are_refused() {
    let dir = TempDir::new().unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec![
            "simulate",
            "--backend",
            "cpu",
            "--steps",
            "1",
            "-q",
            "-o",
            "s",
        ];
        args.extend(extra);
        // A step that runs out of memory has said which scene it runs.
        let stderr = capped(&args, dir.path());
        stderr.lines().last().unwrap_or("").to_owned()
    };
    for scene in [
        &["--scene", "hopper", "-n", "3000000000"][..],
        &["--scene", "drum", "-n", "200000000"],
        &["--scene", "hopper", "-n", "20000000"],
        // The start fits; the step's grid, sums and contact history do not.
        &["-n", "2560000"],
    ] {
        assert_contains(&run(scene), "out of memory");
    }
    assert!(!dir.path().join("s").join("checkpoint.bin").exists());
}
