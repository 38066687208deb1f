//! The `mochi` binary end to end: bad inputs fail cleanly (one `error:` line, no panic, no partial
//! or temporary file), outputs round-trip through the library readers and agree with the oracle,
//! generated scenes are reproducible, and the argument parser rejects contradictory arguments.

use mochi::io::{read_pairs, read_spheres};
use mochi::oracle::brute_force_pairs;
use npyz::WriterBuilder;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tempfile::TempDir;

const BIN: &str = env!("CARGO_BIN_EXE_mochi");

// ----------------------------------------------------------------------------------------------
// Helpers
// ----------------------------------------------------------------------------------------------

/// What a run of the binary left behind.
struct Run {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

impl Run {
    fn describe(&self) -> String {
        format!(
            "exit {:?}\n--- stdout ---\n{}\n--- stderr ---\n{}",
            self.code, self.stdout, self.stderr
        )
    }

    fn assert_success(&self) {
        assert_eq!(self.code, Some(0), "expected success\n{}", self.describe());
        assert!(!self.stderr.contains("panicked"), "{}", self.describe());
    }

    /// Failed with an ordinary error exit: not 0, not a panic (101), not a signal.
    fn assert_failure(&self) {
        match self.code {
            Some(0) => panic!("expected failure, got success\n{}", self.describe()),
            Some(101) => panic!("exit 101 looks like a panic\n{}", self.describe()),
            None => panic!("killed by a signal\n{}", self.describe()),
            Some(_) => {}
        }
        assert!(
            !self.stderr.contains("panicked"),
            "panic text in stderr\n{}",
            self.describe()
        );
    }

    /// Stderr is exactly one line, starting with `error:`; returns it.
    fn single_error_line(&self) -> &str {
        let lines: Vec<&str> = self.stderr.lines().collect();
        assert_eq!(
            lines.len(),
            1,
            "stderr must be a single line\n{}",
            self.describe()
        );
        assert!(
            lines[0].starts_with("error:"),
            "stderr must start with `error:`\n{}",
            self.describe()
        );
        lines[0]
    }
}

fn mochi<I, S>(args: I) -> Run
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let out: Output = Command::new(BIN)
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("the mochi binary runs");
    Run {
        code: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn p(path: &Path) -> &OsStr {
    path.as_os_str()
}

/// Names in `dir` that look like mochi's temporary files.
fn leftover_temp_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("read_dir")
        .map(|e| {
            e.expect("dir entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .filter(|name| name.starts_with(".mochi-"))
        .collect()
}

fn write_file(path: &Path, bytes: &[u8]) {
    std::fs::write(path, bytes).expect("write test input");
}

/// Writes a `.npy` array of `shape` holding `data` (row-major unless `order` says otherwise).
fn write_npy_ordered<T: npyz::AutoSerialize + Copy>(
    path: &Path,
    shape: &[u64],
    order: npyz::Order,
    data: &[T],
) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).expect("create .npy"));
    let mut npy = npyz::WriteOptions::<T>::new()
        .default_dtype()
        .shape(shape)
        .order(order)
        .writer(file)
        .begin_nd()
        .expect("begin .npy");
    npy.extend(data.iter().copied()).expect("write .npy data");
    npy.finish().expect("finish .npy");
}

fn write_npy<T: npyz::AutoSerialize + Copy>(path: &Path, shape: &[u64], data: &[T]) {
    write_npy_ordered(path, shape, npyz::Order::C, data);
}

/// A `.npy` header with an arbitrary shape string and no data (or `data`), written by hand.
fn write_raw_npy(path: &Path, descr: &str, shape: &str, data: &[u8]) {
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - total % 64) % 64));
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(data);
    write_file(path, &bytes);
}

/// What the error line must say about a rejected input.
struct Expect<'a> {
    /// The 1-based line, for CSV errors that have one (`path:LINE:` must appear).
    line: Option<u64>,
    /// Words that must appear in the message (case-insensitive).
    problem: &'a [&'a str],
}

/// Runs `mochi detect INPUT -o OUT` in `dir` and checks that it fails cleanly.
fn assert_rejected(dir: &Path, input: &Path, expect: Expect) -> String {
    let out = dir.join("pairs-out.csv");
    let run = mochi([OsStr::new("detect"), p(input), OsStr::new("-o"), p(&out)]);
    run.assert_failure();
    let line = run.single_error_line().to_owned();
    let shown = input.display().to_string();
    assert!(
        line.contains(&shown),
        "error must name the file {shown}\n{}",
        run.describe()
    );
    if let Some(n) = expect.line {
        let at = format!("{shown}:{n}:");
        assert!(
            line.contains(&at),
            "error must name line {n} as `{at}`\n{}",
            run.describe()
        );
    }
    let lower = line.to_lowercase();
    for word in expect.problem {
        assert!(
            lower.contains(&word.to_lowercase()),
            "error must mention {word:?}\n{}",
            run.describe()
        );
    }
    assert!(
        run.stdout.is_empty(),
        "no summary on failure\n{}",
        run.describe()
    );
    assert!(
        !out.exists(),
        "no output file may be written on failure: {}",
        out.display()
    );
    assert_eq!(
        leftover_temp_files(dir),
        Vec::<String>::new(),
        "temporary files left behind"
    );
    line
}

/// A CSV file in a fresh directory; returns (dir, path).
/// Writes `content` to a CSV file and checks that `detect` rejects it as `expect` says.
fn csv_rejected(content: &str, line: Option<u64>, problem: &[&str]) {
    let (dir, path) = csv_case(content);
    assert_rejected(dir.path(), &path, Expect { line, problem });
}

fn csv_case(content: &str) -> (TempDir, PathBuf) {
    let dir = TempDir::new().expect("tempdir");
    let path = dir.path().join("spheres.csv");
    write_file(&path, content.as_bytes());
    (dir, path)
}

fn generate(args: &[&str], out: &Path) -> Run {
    let mut all: Vec<&OsStr> = vec![OsStr::new("generate")];
    all.extend(args.iter().map(OsStr::new));
    all.push(OsStr::new("-o"));
    all.push(p(out));
    let run = mochi(all);
    run.assert_success();
    run
}

fn detect(input: &Path, out: &Path, extra: &[&str]) -> Run {
    let mut all: Vec<&OsStr> = vec![OsStr::new("detect"), p(input), OsStr::new("-o"), p(out)];
    all.extend(extra.iter().map(OsStr::new));
    let run = mochi(all);
    run.assert_success();
    run
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

const SMALL_RANDOM: [&str; 8] = [
    "--scene", "poly120", "-n", "2000", "--layout", "random", "--seed", "3",
];
/// A denser scene with a few dozen pairs.
const SLAB_RANDOM: [&str; 8] = [
    "--scene", "slab", "-n", "5000", "--layout", "random", "--seed", "3",
];

// ----------------------------------------------------------------------------------------------
// 1. Bad sphere inputs
// ----------------------------------------------------------------------------------------------

#[test]
fn simulate_help_names_every_scene() {
    let run = mochi(["simulate", "--help"]);
    assert_eq!(run.code, Some(0), "{}", run.describe());
    let help = run
        .stdout
        .split("--scene")
        .nth(1)
        .expect("the help of --scene");
    let help = help.split("\n  -").next().unwrap();
    for kind in mochi::dem::scene::SceneKind::ALL {
        assert!(
            help.contains(kind.name()),
            "--scene's help lacks {}:\n{help}",
            kind.name()
        );
    }
}

#[test]
fn csv_nan_coordinate_is_rejected_with_its_line() {
    csv_rejected(
        "x,y,z,r\n0,0,0,1\nNaN,0,0,1\n",
        Some(3),
        &["x is NaN", "not a finite number"],
    );
}

#[test]
fn csv_inf_coordinate_is_rejected_with_its_line() {
    csv_rejected(
        "x,y,z,r\n0,0,0,1\n1,2,3,1\n0,inf,0,1\n",
        Some(4),
        &["y is inf", "not a finite number"],
    );
    // -inf too, and an overflowing literal that parses to inf.
    csv_rejected("x,y,z,r\n0,0,-inf,1\n", Some(2), &["z is -inf"]);
    csv_rejected("x,y,z,r\n1e39,0,0,1\n", Some(2), &["not a finite number"]);
}

#[test]
fn csv_zero_radius_is_rejected_with_its_line() {
    csv_rejected(
        "x,y,z,r\n0,0,0,1\n5,5,5,0\n",
        Some(3),
        &["radius must be > 0"],
    );
}

#[test]
fn csv_negative_radius_is_rejected_with_its_line() {
    csv_rejected(
        "x,y,z,r\n0,0,0,-0.5\n",
        Some(2),
        &["radius must be > 0", "-0.5"],
    );
}

#[test]
fn csv_nan_and_too_large_radius_are_rejected() {
    csv_rejected("x,y,z,r\n0,0,0,nan\n", Some(2), &["radius is NaN"]);
    csv_rejected("x,y,z,r\n0,0,0,1\n0,0,0,1e19\n", Some(3), &["exceeds"]);
}

#[test]
fn csv_radius_below_the_smallest_is_rejected_with_its_line() {
    csv_rejected(
        "x,y,z,r\n0,0,0,1e-12\n0,0,0,9e-13\n",
        Some(3),
        &["below the smallest radius", "1e-12"],
    );
}

#[test]
fn coordinates_f32_cannot_place_at_the_radii_get_a_warning_naming_the_sphere() {
    // A true gap of 3 > 2, but both centres round to the same f32: reported touching, with a
    // warning that names the first sphere too coarse for its radius.
    let (dir, path) = csv_case("x,y,z,r\n0,0,0,1\n1e17,0,0,1\n1.00000000000000003e17,0,0,1\n");
    let out = dir.path().join("pairs.csv");
    let run = detect(&path, &out, &["--backend", "cpu"]);
    let warnings: Vec<&str> = run
        .stderr
        .lines()
        .filter(|l| l.starts_with("warning:"))
        .collect();
    assert_eq!(warnings.len(), 1, "{}", run.describe());
    for words in [
        &path.display().to_string(),
        "sphere 1 (0-based)",
        "x = 1e17",
        "1 more",
    ] {
        assert!(
            warnings[0].contains(words),
            "{words:?} missing\n{}",
            run.describe()
        );
    }
    assert_eq!(read_pairs(&out).unwrap(), vec![mochi::Pair::new(1, 2)]);
    // simulate reads its input the same way and warns the same way.
    let sim = dir.path().join("run");
    let run = mochi([
        OsStr::new("simulate"),
        OsStr::new("--input"),
        p(&path),
        OsStr::new("--steps"),
        OsStr::new("1"),
        OsStr::new("--backend"),
        OsStr::new("cpu"),
        OsStr::new("-o"),
        p(&sim),
    ]);
    run.assert_success();
    let warning = run
        .stderr
        .lines()
        .find(|l| l.starts_with("warning: sphere 1 (0-based)"));
    assert!(
        warning.is_some_and(|w| w.contains("x = 1e17")),
        "{}",
        run.describe()
    );
    // Fine coordinates get none.
    let (dir, path) = csv_case("x,y,z,r\n0,0,0,1\n1e3,0,0,1\n");
    let run = detect(&path, &dir.path().join("pairs.csv"), &["--backend", "cpu"]);
    assert!(!run.stderr.contains("warning"), "{}", run.describe());
}

#[test]
fn csv_three_columns_is_rejected_with_its_line() {
    csv_rejected(
        "x,y,z,r\n0,0,0,1\n1,2,3\n",
        Some(3),
        &["expected 4 columns", "found 3"],
    );
}

#[test]
fn csv_five_columns_is_rejected_with_its_line() {
    csv_rejected(
        "x,y,z,r\n1,2,3,4,5\n",
        Some(2),
        &["expected 4 columns", "found 5"],
    );
}

#[test]
fn csv_non_number_is_rejected_with_its_line_and_column() {
    csv_rejected(
        "x,y,z,r\n0,0,0,1\n0,0,0,1\n1,abc,3,4\n",
        Some(4),
        &["column y", "\"abc\"", "is not a number"],
    );
}

#[test]
fn csv_invalid_utf8_is_rejected_with_its_line() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("spheres.csv");
    write_file(&path, b"x,y,z,r\n0,0,0,1\n1,2,3,\xff\n");
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: Some(3),
            problem: &["utf"],
        },
    );
}

#[test]
fn csv_empty_file_is_rejected() {
    csv_rejected("", None, &["empty file", "x,y,z,r"]);
}

#[test]
fn csv_wrong_header_is_rejected_on_line_1() {
    csv_rejected(
        "a,b,c,d\n0,0,0,1\n",
        Some(1),
        &["the header must be x,y,z,r", "a,b,c,d"],
    );
    // A header with 3 columns, and data where the header should be.
    csv_rejected("x,y,z\n0,0,0\n", Some(1), &["the header must be x,y,z,r"]);
    csv_rejected(
        "0,0,0,1\n1,1,1,1\n",
        Some(1),
        &["the header must be x,y,z,r"],
    );
}

#[test]
fn csv_header_only_is_zero_spheres_not_an_error() {
    let (dir, path) = csv_case("x,y,z,r\n");
    let out = dir.path().join("pairs.csv");
    let run = detect(&path, &out, &["--backend", "cpu"]);
    assert!(
        run.stdout.contains("spheres 0 | pairs 0 |"),
        "{}",
        run.describe()
    );
    assert_eq!(read(&out), b"i,j\n");
    assert_eq!(read_pairs(&out).unwrap(), vec![]);
    assert!(read_spheres(&path).unwrap().is_empty());
    assert_eq!(leftover_temp_files(dir.path()), Vec::<String>::new());
}

#[test]
fn csv_header_is_case_and_space_insensitive() {
    let (dir, path) = csv_case(" X , Y ,z, R \n 0 , 0 , 0 , 1 \n1.5,0,0,0.5\n");
    let out = dir.path().join("pairs.csv");
    let run = detect(&path, &out, &["--backend", "cpu"]);
    assert!(
        run.stdout.contains("spheres 2 | pairs 1 |"),
        "{}",
        run.describe()
    );
    assert_eq!(read(&out), b"i,j\n0,1\n");
}

#[test]
fn nonexistent_input_is_rejected() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("does-not-exist.csv");
    let os_message = std::fs::File::open(&path).unwrap_err().to_string();
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &[&os_message],
        },
    );
    let path = dir.path().join("does-not-exist.npy");
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &[&os_message],
        },
    );
}

#[test]
fn unknown_extension_is_rejected() {
    let dir = TempDir::new().unwrap();
    // Valid CSV content, but the extension decides the format.
    let path = dir.path().join("spheres.txt");
    write_file(&path, b"x,y,z,r\n0,0,0,1\n");
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["unknown sphere file type", "\"txt\"", ".csv", ".npy"],
        },
    );
    let path = dir.path().join("no-extension");
    write_file(&path, b"x,y,z,r\n0,0,0,1\n");
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["unknown sphere file type"],
        },
    );
}

#[test]
fn directory_as_input_is_rejected() {
    let dir = TempDir::new().unwrap();
    // A directory without an extension: rejected for its type.
    let plain = dir.path().join("a-directory");
    std::fs::create_dir(&plain).unwrap();
    assert_rejected(
        dir.path(),
        &plain,
        Expect {
            line: None,
            problem: &["unknown sphere file type"],
        },
    );
    // Directories named like sphere files: rejected when read.
    for name in ["dir.csv", "dir.npy"] {
        let d = dir.path().join(name);
        std::fs::create_dir(&d).unwrap();
        let os_message = std::fs::read(&d).unwrap_err().to_string();
        assert_rejected(
            dir.path(),
            &d,
            Expect {
                line: None,
                problem: &[&os_message],
            },
        );
    }
}

#[test]
fn npy_with_three_columns_is_rejected() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("spheres.npy");
    write_npy::<f32>(&path, &[2, 3], &[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["shape N×4", "[2, 3]"],
        },
    );
    // One-dimensional arrays too.
    write_npy::<f32>(&path, &[4], &[0.0, 0.0, 0.0, 1.0]);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["shape N×4", "[4]"],
        },
    );
}

#[test]
fn npy_with_int32_dtype_is_rejected() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("spheres.npy");
    write_npy::<i32>(&path, &[2, 4], &[0, 0, 0, 1, 5, 5, 5, 1]);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["expected float32", "i4"],
        },
    );
}

#[test]
fn truncated_npy_is_rejected() {
    let dir = TempDir::new().unwrap();
    let full = dir.path().join("full.npy");
    generate(&SMALL_RANDOM, &full);
    let bytes = read(&full);
    assert!(bytes.len() > 1000);
    let path = dir.path().join("half.npy");
    write_file(&path, &bytes[..bytes.len() / 2]);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["truncated"],
        },
    );
    // Cut inside the header, and a file that is not .npy at all.
    write_file(&path, &bytes[..20]);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["not a .npy file"],
        },
    );
    write_file(&path, b"x,y,z,r\n0,0,0,1\n");
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["not a .npy file"],
        },
    );
}

#[test]
fn npy_with_nan_is_rejected_with_its_row() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("spheres.npy");
    #[rustfmt::skip]
    let data = [
        0.0f32, 0.0, 0.0, 1.0,
        1.0, 2.0, f32::NAN, 1.0,
        3.0, 3.0, 3.0, 1.0,
    ];
    write_npy(&path, &[3, 4], &data);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["row 1 (0-based)", "z is NaN", "not a finite number"],
        },
    );
    // A zero radius in a float64 file.
    #[rustfmt::skip]
    let data = [
        0.0f64, 0.0, 0.0, 1.0,
        1.0, 2.0, 3.0, 0.0,
    ];
    write_npy(&path, &[2, 4], &data);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["row 1 (0-based)", "radius must be > 0"],
        },
    );
}

/// A header whose shape overflows when multiplied out must be an error, not a crash.
#[test]
fn npy_with_absurd_shape_is_rejected() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("spheres.npy");
    write_raw_npy(&path, "<f4", "(4611686018427387904, 4)", &[]);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &[],
        },
    );
    write_raw_npy(&path, "<f4", "(4611686018427387905, 4)", &[0u8; 64]);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &[],
        },
    );
}

#[test]
fn npy_with_large_shape_but_no_data_is_rejected() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("spheres.npy");
    write_raw_npy(&path, "<f4", "(1099511627776, 4)", &[0u8; 32]);
    assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &["truncated"],
        },
    );
}

/// CSV errors must name the physical line, also with Windows line ends.
#[test]
fn csv_line_numbers_are_right_with_crlf() {
    csv_rejected(
        "x,y,z,r\r\n0,0,0,1\r\n0,0,0,nan\r\n",
        Some(3),
        &["radius is NaN"],
    );
}

/// CSV errors must name the physical line, also right after a blank line.
#[test]
fn csv_line_numbers_are_right_after_blank_lines() {
    csv_rejected(
        "x,y,z,r\n0,0,0,1\n\n0,0,0,nan\n",
        Some(4),
        &["radius is NaN"],
    );
}

#[test]
fn csv_quoted_fields_are_rejected_on_their_physical_line() {
    // Sphere files hold plain numbers: a quote is an error on the line where it stands.
    csv_rejected(
        "x,y,z,r\n0,0,0,1\n\"1\",2,3,1\n",
        Some(3),
        &["not a number"],
    );
}

/// An I/O error is reported once, not once per level of the error chain.
#[test]
fn io_error_message_is_not_repeated() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("does-not-exist.csv");
    let os_message = std::fs::File::open(&path).unwrap_err().to_string();
    let line = assert_rejected(
        dir.path(),
        &path,
        Expect {
            line: None,
            problem: &[&os_message],
        },
    );
    assert_eq!(line.matches(&os_message).count(), 1, "{line}");
}

// ----------------------------------------------------------------------------------------------
// 2. Unwritable output
// ----------------------------------------------------------------------------------------------

#[test]
fn output_to_missing_directory_fails_cleanly() {
    let dir = TempDir::new().unwrap();
    let input = dir.path().join("spheres.csv");
    write_file(&input, b"x,y,z,r\n0,0,0,1\n1,0,0,1\n");
    let missing = dir.path().join("missing-dir");
    let out = missing.join("pairs.csv");
    let os_message = std::fs::File::create(&out).unwrap_err().to_string();

    let run = mochi([
        OsStr::new("detect"),
        p(&input),
        OsStr::new("-o"),
        p(&out),
        OsStr::new("--backend"),
        OsStr::new("cpu"),
    ]);
    run.assert_failure();
    let line = run.single_error_line();
    assert!(line.contains(&out.display().to_string()), "{line}");
    assert!(line.contains(&os_message), "{line}");
    assert!(!missing.exists());

    // The same through `generate`, and with an absolute path outside any temp dir.
    let run = mochi(["generate", "-n", "10", "-o", "/nonexistent-dir/spheres.csv"]);
    run.assert_failure();
    let line = run.single_error_line();
    assert!(line.contains("/nonexistent-dir/spheres.csv"), "{line}");
    assert!(!Path::new("/nonexistent-dir").exists());

    // With `auto`, stderr also says which backend was picked; the error is the last line.
    let run = mochi([
        OsStr::new("detect"),
        p(&input),
        OsStr::new("-o"),
        OsStr::new("/nonexistent-dir/pairs.csv"),
    ]);
    run.assert_failure();
    let last = run.stderr.lines().last().unwrap_or_default();
    assert!(last.starts_with("error:"), "{}", run.describe());
    assert!(last.contains("/nonexistent-dir/pairs.csv"), "{last}");
}

#[test]
fn output_onto_a_directory_fails_and_keeps_it() {
    let dir = TempDir::new().unwrap();
    let input = dir.path().join("spheres.csv");
    write_file(&input, b"x,y,z,r\n0,0,0,1\n1,0,0,1\n");
    let out = dir.path().join("taken.csv");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("keep"), b"keep").unwrap();
    let run = mochi([
        OsStr::new("detect"),
        p(&input),
        OsStr::new("-o"),
        p(&out),
        OsStr::new("--backend"),
        OsStr::new("cpu"),
    ]);
    run.assert_failure();
    let line = run.single_error_line();
    assert!(line.contains(&out.display().to_string()), "{line}");
    assert!(out.is_dir());
    assert_eq!(read(&out.join("keep")), b"keep");
    assert_eq!(leftover_temp_files(dir.path()), Vec::<String>::new());
}

#[test]
fn generate_to_unknown_extension_fails_without_writing() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("spheres.txt");
    let run = mochi([
        OsStr::new("generate"),
        OsStr::new("-n"),
        OsStr::new("10"),
        OsStr::new("-o"),
        p(&out),
    ]);
    run.assert_failure();
    let line = run.single_error_line();
    assert!(line.contains("unknown sphere file type"), "{line}");
    assert!(!out.exists());
    assert_eq!(leftover_temp_files(dir.path()), Vec::<String>::new());
}

/// Files mochi writes get the same permissions as any other new file (the umask decides).
#[cfg(unix)]
#[test]
fn outputs_get_ordinary_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = TempDir::new().unwrap();
    let reference = dir.path().join("reference");
    std::fs::File::create(&reference).unwrap();
    let mode = |path: &Path| std::fs::metadata(path).unwrap().permissions().mode() & 0o777;
    let want = mode(&reference);

    let spheres = dir.path().join("spheres.csv");
    generate(&["-n", "10"], &spheres);
    assert_eq!(
        mode(&spheres),
        want,
        "sphere file mode {:o}",
        mode(&spheres)
    );
    let pairs = dir.path().join("pairs.csv");
    detect(&spheres, &pairs, &["--backend", "cpu"]);
    assert_eq!(mode(&pairs), want, "pair file mode {:o}", mode(&pairs));

    // Overwriting keeps the mode of the file that was there.
    let existing = dir.path().join("existing.csv");
    std::fs::write(&existing, b"old").unwrap();
    std::fs::set_permissions(&existing, std::fs::Permissions::from_mode(0o644)).unwrap();
    detect(&spheres, &existing, &["--backend", "cpu"]);
    assert_eq!(
        mode(&existing),
        0o644,
        "overwritten file mode {:o}",
        mode(&existing)
    );
}

// ----------------------------------------------------------------------------------------------
// 3. Round trips
// ----------------------------------------------------------------------------------------------

fn round_trip(scene: &[&str], n: usize) {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let (a_csv, a_npy) = (d.join("a.csv"), d.join("a.npy"));
    let run = generate(scene, &a_csv);
    assert!(
        run.stdout.contains(&format!("wrote {n} spheres")),
        "{}",
        run.describe()
    );
    generate(scene, &a_npy);

    let from_csv = read_spheres(&a_csv).expect("generated CSV reads back");
    let from_npy = read_spheres(&a_npy).expect("generated .npy reads back");
    assert_eq!(from_csv.len(), n);
    assert_eq!(from_csv, from_npy, "CSV and .npy hold different spheres");

    let want = brute_force_pairs(&from_csv);
    assert!(!want.is_empty(), "the scene should have some pairs");

    let (p_csv, q_csv) = (d.join("p.csv"), d.join("q.csv"));
    let runs = [
        detect(&a_csv, &p_csv, &["--backend", "cpu"]),
        detect(&a_npy, &q_csv, &["--backend", "cpu"]),
    ];
    assert_eq!(read(&p_csv), read(&q_csv), "pair files differ");
    let got = read_pairs(&p_csv).expect("the pair file parses");
    assert_eq!(got, want, "pair file differs from the oracle");
    let summary = format!("spheres {n} | pairs {} |", want.len());
    for run in &runs {
        assert!(run.stdout.contains(&summary), "{}", run.describe());
        assert!(run.stdout.contains("backend cpu"), "{}", run.describe());
        assert!(run.stdout.contains("mode mochi"), "{}", run.describe());
    }
    // Without --backend (auto, whatever it picks here): the same file and count.
    let auto = d.join("auto.csv");
    let run = detect(&a_csv, &auto, &[]);
    assert!(run.stdout.contains(&summary), "{}", run.describe());
    assert_eq!(read(&auto), read(&p_csv), "auto backend: pair files differ");
    assert_eq!(leftover_temp_files(d), Vec::<String>::new());
}

#[test]
fn round_trip_csv_and_npy_poly120() {
    round_trip(&SMALL_RANDOM, 2000);
}

#[test]
fn round_trip_csv_and_npy_slab() {
    round_trip(&SLAB_RANDOM, 5000);
}

#[test]
fn npy_in_fortran_order_and_float64_read_like_c_order_float32() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let a = d.join("a.npy");
    generate(&SMALL_RANDOM, &a);
    let spheres = read_spheres(&a).unwrap();
    let rows: Vec<[f32; 4]> = spheres.xyzr().collect();
    let n = rows.len() as u64;

    let fortran = d.join("fortran.npy");
    let columns: Vec<f32> = (0..4)
        .flat_map(|k| rows.iter().map(move |r| r[k]))
        .collect();
    write_npy_ordered(&fortran, &[n, 4], npyz::Order::Fortran, &columns);
    assert_eq!(read_spheres(&fortran).unwrap(), spheres);

    let wide = d.join("f64.npy");
    let values: Vec<f64> = rows.iter().flatten().map(|&x| x as f64).collect();
    write_npy(&wide, &[n, 4], &values);
    assert_eq!(read_spheres(&wide).unwrap(), spheres);

    let (p1, p2) = (d.join("p1.csv"), d.join("p2.csv"));
    detect(&a, &p1, &["--backend", "cpu"]);
    detect(&fortran, &p2, &["--backend", "cpu"]);
    assert_eq!(read(&p1), read(&p2));
}

// ----------------------------------------------------------------------------------------------
// 4. Reproducibility
// ----------------------------------------------------------------------------------------------

#[test]
fn generate_names_the_scene_and_layout_as_the_command_line_does() {
    let dir = TempDir::new().unwrap();
    let args = [
        "--scene", "poly1.2", "-n", "50", "--layout", "random", "--seed", "3",
    ];
    let run = generate(&args, &dir.path().join("s.csv"));
    assert!(
        run.stdout
            .contains("scene poly1.2 (random layout, seed 3): wrote 50 spheres"),
        "{}",
        run.stdout
    );
}

#[test]
fn same_seed_same_file_other_seed_other_file() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    for ext in ["csv", "npy"] {
        for layout in ["lattice", "random"] {
            let args = |seed: &'static str| {
                [
                    "--scene", "poly120", "-n", "3000", "--layout", layout, "--seed", seed,
                ]
            };
            let (a, b, c) = (
                d.join(format!("a-{layout}.{ext}")),
                d.join(format!("b-{layout}.{ext}")),
                d.join(format!("c-{layout}.{ext}")),
            );
            generate(&args("11"), &a);
            generate(&args("11"), &b);
            generate(&args("12"), &c);
            let (a, b, c) = (read(&a), read(&b), read(&c));
            assert!(!a.is_empty());
            assert_eq!(a, b, "{layout} .{ext}: same seed, different files");
            assert_ne!(a, c, "{layout} .{ext}: different seeds, same file");
        }
    }
    // The default seed is fixed too.
    let (e, f) = (d.join("e.csv"), d.join("f.csv"));
    generate(&["-n", "500"], &e);
    generate(&["-n", "500"], &f);
    assert_eq!(read(&e), read(&f));
}

// ----------------------------------------------------------------------------------------------
// 5. Proxy modes agree
// ----------------------------------------------------------------------------------------------

#[test]
fn nns_mode_gives_the_same_pairs_as_mochi_mode() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let input = d.join("slab.npy");
    generate(&SLAB_RANDOM, &input);
    let (m, n, explicit) = (
        d.join("mochi.csv"),
        d.join("nns.csv"),
        d.join("explicit.csv"),
    );
    let run_default = detect(&input, &m, &["--backend", "cpu"]);
    let run_nns = detect(&input, &n, &["--backend", "cpu", "--mode", "nns"]);
    detect(&input, &explicit, &["--backend", "cpu", "--mode", "mochi"]);
    assert!(
        run_default.stdout.contains("mode mochi"),
        "{}",
        run_default.describe()
    );
    assert!(
        run_nns.stdout.contains("mode nns"),
        "{}",
        run_nns.describe()
    );
    assert_eq!(read(&m), read(&n), "nns and mochi modes disagree");
    assert_eq!(read(&m), read(&explicit));
    let pairs = read_pairs(&n).unwrap();
    assert!(!pairs.is_empty());
    assert_eq!(pairs, brute_force_pairs(&read_spheres(&input).unwrap()));
}

// ----------------------------------------------------------------------------------------------
// 6. Backends
// ----------------------------------------------------------------------------------------------

#[test]
fn backends_lists_cpu_as_available() {
    let run = mochi(["backends"]);
    run.assert_success();
    let cpu: Vec<&str> = run
        .stdout
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("cpu"))
        .collect();
    assert_eq!(cpu.len(), 1, "one cpu line\n{}", run.describe());
    let words: Vec<&str> = cpu[0].split_whitespace().collect();
    assert_eq!(words.get(1), Some(&"available"), "{}", run.describe());
    // Every line is `NAME available...` or `NAME unavailable: why`.
    for line in run.stdout.lines() {
        let status = line.split_whitespace().nth(1).unwrap_or_default();
        assert!(
            status == "available" || status == "unavailable:",
            "{line:?}\n{}",
            run.describe()
        );
    }
}

// ----------------------------------------------------------------------------------------------
// 7. Argument parsing
// ----------------------------------------------------------------------------------------------

#[test]
fn detect_rejects_an_input_file_together_with_scene_options() {
    let dir = TempDir::new().unwrap();
    let input = dir.path().join("spheres.csv");
    write_file(&input, b"x,y,z,r\n0,0,0,1\n");
    let out = dir.path().join("pairs.csv");
    for extra in [
        &["--scene", "poly120"][..],
        &["-n", "5"],
        &["--seed", "4"],
        &["--layout", "random"],
    ] {
        let mut args = vec![OsStr::new("detect"), p(&input), OsStr::new("-o"), p(&out)];
        args.extend(extra.iter().map(OsStr::new));
        let run = mochi(args);
        run.assert_failure();
        assert!(
            run.stderr.starts_with("error:") && run.stderr.contains("cannot be used with"),
            "{extra:?}\n{}",
            run.describe()
        );
        assert!(run.stdout.is_empty(), "{extra:?}\n{}", run.describe());
        assert!(!out.exists(), "{extra:?}");
    }
}

#[test]
fn bad_option_values_are_rejected_by_the_parser() {
    for args in [
        &["detect", "--mode", "fast"][..],
        &["detect", "--backend", "gpu9000"],
        &["detect", "--scene", "nope"],
        &["detect", "-n", "-3"],
        &["generate", "-n", "10"], // -o is required
        &["frobnicate"],
    ] {
        let run = mochi(args);
        run.assert_failure();
        assert!(
            run.stderr.starts_with("error:"),
            "{args:?}\n{}",
            run.describe()
        );
    }
}

// ----------------------------------------------------------------------------------------------
// 8. A failed run keeps an existing output
// ----------------------------------------------------------------------------------------------

#[test]
fn failed_detect_keeps_the_existing_output() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let out = d.join("pairs.csv");
    let old = b"i,j\n0,1\n";
    write_file(&out, old);
    let bad_inputs: [(&str, &[u8]); 4] = [
        ("nan.csv", b"x,y,z,r\n0,0,0,1\nnan,0,0,1\n"),
        ("header.csv", b"a,b,c,d\n"),
        ("empty.csv", b""),
        ("bad.npy", b"not an npy file"),
    ];
    for (name, content) in bad_inputs {
        let input = d.join(name);
        write_file(&input, content);
        let run = mochi([OsStr::new("detect"), p(&input), OsStr::new("-o"), p(&out)]);
        run.assert_failure();
        run.single_error_line();
        assert_eq!(read(&out), old, "{name}: the old output was changed");
        assert_eq!(leftover_temp_files(d), Vec::<String>::new(), "{name}");
    }
    // And a successful run does replace it.
    let input = d.join("good.csv");
    write_file(&input, b"x,y,z,r\n0,0,0,1\n5,5,5,1\n");
    detect(&input, &out, &["--backend", "cpu"]);
    assert_eq!(read(&out), b"i,j\n");
    assert_eq!(leftover_temp_files(d), Vec::<String>::new());
}

/// `write_atomically` keeps the file intact if the closure fails mid-write (library level).
#[test]
fn write_atomically_leaves_nothing_on_failure() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("out.csv");
    write_file(&out, b"old");
    let err = mochi::io::write_atomically(&out, |w| {
        w.write_all(b"partial")?;
        Err(std::io::Error::other("disk on fire"))
    })
    .unwrap_err();
    assert!(err.to_string().contains("disk on fire"), "{err}");
    assert_eq!(read(&out), b"old");
    assert_eq!(leftover_temp_files(dir.path()), Vec::<String>::new());
}

// ----------------------------------------------------------------------------------------------
// Odd but valid files, and messages that name the real problem
// ----------------------------------------------------------------------------------------------

/// Spreadsheet programs open a UTF-8 CSV with a byte-order mark: it is not part of the header.
#[test]
fn csv_with_a_utf8_byte_order_mark_is_read() {
    let (dir, path) = csv_case("\u{feff}x,y,z,r\n0,0,0,1\n1.5,0,0,1\n9,9,9,1\n");
    let out = dir.path().join("pairs.csv");
    detect(&path, &out, &["--backend", "cpu"]);
    assert_eq!(read(&out), b"i,j\n0,1\n");
}

/// A `.vtu` frame with a NaN radius: the error names the file and the point.
#[test]
fn render_of_a_frame_with_a_nan_radius_names_the_file() {
    let dir = TempDir::new().unwrap();
    let vtu = dir.path().join("frame_00000003.vtu");
    let positions = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0]];
    let velocities = [[0.0f32; 3]; 2];
    mochi::io::write_vtu(
        &vtu,
        &mochi::io::Frame {
            time: 0.0,
            step: 3,
            positions: &positions,
            position_residuals: &[],
            radii: &[0.1, f32::NAN],
            velocities: &velocities,
            angular_velocities: &velocities,
            materials: &[],
            contacts: None,
            clumps: None,
            ids: None,
        },
    )
    .unwrap();
    let png = dir.path().join("out.png");
    let run = mochi([
        OsStr::new("render"),
        p(&vtu),
        OsStr::new("-o"),
        p(&png),
        OsStr::new("--renderer"),
        OsStr::new("cpu"),
    ]);
    run.assert_failure();
    let line = run.single_error_line();
    assert!(
        line.contains("frame_00000003.vtu") && line.contains("point 1"),
        "{line}"
    );
    assert!(!png.exists());
}

/// `--fov 0` is reported as a field of view out of range (not as a camera at infinity).
#[test]
fn render_with_a_zero_field_of_view_says_so() {
    let (dir, path) = csv_case("x,y,z,r\n0,0,0,1\n");
    let png = dir.path().join("out.png");
    let run = mochi([
        OsStr::new("render"),
        p(&path),
        OsStr::new("-o"),
        p(&png),
        OsStr::new("--renderer"),
        OsStr::new("cpu"),
        OsStr::new("--fov"),
        OsStr::new("0"),
    ]);
    run.assert_failure();
    let line = run.single_error_line();
    assert!(line.contains("field of view"), "{line}");
}

// ----------------------------------------------------------------------------------------------
// Output targets that are links, devices or pipes; outputs that name an input
// ----------------------------------------------------------------------------------------------

const TWO_TOUCHING: &[u8] = b"x,y,z,r\n0,0,0,1\n1,0,0,1\n";

/// A link is written through: the file it names gets the output, the link stays a link; a
/// dangling link gets its file created.
#[cfg(unix)]
#[test]
fn output_through_a_symlink_replaces_the_file_it_names() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let input = d.join("spheres.csv");
    write_file(&input, TWO_TOUCHING);
    std::fs::create_dir(d.join("real")).unwrap();
    write_file(&d.join("real/pairs.csv"), b"old");
    let link = d.join("link.csv");
    std::os::unix::fs::symlink("real/pairs.csv", &link).unwrap();
    detect(&input, &link, &["--backend", "cpu"]);
    assert!(link.symlink_metadata().unwrap().file_type().is_symlink());
    assert_eq!(read(&d.join("real/pairs.csv")), b"i,j\n0,1\n");

    let dangling = d.join("dangling.csv");
    std::os::unix::fs::symlink(d.join("real/new.csv"), &dangling).unwrap();
    detect(&input, &dangling, &["--backend", "cpu"]);
    assert!(
        dangling
            .symlink_metadata()
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(read(&d.join("real/new.csv")), b"i,j\n0,1\n");
    assert_eq!(leftover_temp_files(d), Vec::<String>::new());
    assert_eq!(leftover_temp_files(&d.join("real")), Vec::<String>::new());
}

/// A FIFO is written to, not replaced: its reader gets the pairs and it stays a FIFO.
#[cfg(unix)]
#[test]
fn output_to_a_fifo_reaches_its_reader() {
    use std::os::unix::fs::FileTypeExt;
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let input = d.join("spheres.csv");
    write_file(&input, TWO_TOUCHING);
    let fifo = d.join("pairs.fifo");
    let name = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: a NUL-terminated path that outlives the call.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    detect(&input, &fifo, &["--backend", "cpu"]);
    let kind = fifo.symlink_metadata().unwrap().file_type();
    assert!(kind.is_fifo(), "the FIFO was replaced by {kind:?}");
    assert_eq!(reader.join().unwrap(), b"i,j\n0,1\n");
    assert_eq!(leftover_temp_files(d), Vec::<String>::new());
}

/// A character device is written to, not replaced. Run on a device node of our own (a copy of
/// /dev/null, where this user may create one), else on /dev/null itself where this user cannot
/// replace it (not root): never where a failure could replace the system's /dev/null.
#[cfg(unix)]
#[test]
fn output_to_a_device_is_written_through() {
    use std::os::unix::fs::FileTypeExt;
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let input = d.join("spheres.csv");
    write_file(&input, TWO_TOUCHING);
    let own = d.join("null");
    let name = std::ffi::CString::new(own.to_str().unwrap()).unwrap();
    // SAFETY: a NUL-terminated path that outlives the call; /dev/null's numbers (1, 3).
    let made = unsafe { libc::mknod(name.as_ptr(), libc::S_IFCHR | 0o666, libc::makedev(1, 3)) };
    // SAFETY: no arguments.
    let root = unsafe { libc::geteuid() } == 0;
    let device = if made == 0 {
        own
    } else if !root {
        PathBuf::from("/dev/null")
    } else {
        eprintln!("no device node of our own can be made and /dev/null is not safe as root");
        return;
    };
    detect(&input, &device, &["--backend", "cpu"]);
    let kind = device.symlink_metadata().unwrap().file_type();
    assert!(
        kind.is_char_device(),
        "{} is now {kind:?}",
        device.display()
    );
    assert_eq!(leftover_temp_files(d), Vec::<String>::new());
}

/// An output that is the input (by another spelling or through a link) is refused before
/// anything is written, and the input is kept.
#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let input = d.join("same.csv");
    write_file(&input, TWO_TOUCHING);
    let rdir = d.join("rdir");
    std::fs::create_dir(&rdir).unwrap();
    let frame = rdir.join("frame_00000000.csv");
    write_file(&frame, TWO_TOUCHING);
    let respelled = d.join("rdir/../same.csv");
    let cases: Vec<Vec<&OsStr>> = vec![
        vec![OsStr::new("detect"), p(&input), OsStr::new("-o"), p(&input)],
        vec![
            OsStr::new("detect"),
            p(&input),
            OsStr::new("-o"),
            p(&respelled),
        ],
        vec![
            OsStr::new("render"),
            p(&input),
            OsStr::new("-o"),
            p(&respelled),
        ],
        vec![
            OsStr::new("render"),
            p(&input),
            OsStr::new("--gif"),
            p(&input),
        ],
        vec![
            OsStr::new("render"),
            p(&rdir),
            OsStr::new("--gif"),
            p(&frame),
        ],
    ];
    for mut args in cases {
        args.extend(["--renderer", "cpu", "--size", "16x12"].map(OsStr::new));
        if args[0] == "detect" {
            args.truncate(4);
            args.extend(["--backend", "cpu"].map(OsStr::new));
        }
        let run = mochi(&args);
        run.assert_failure();
        let line = run.single_error_line();
        assert!(line.contains("is the input file"), "{args:?}: {line}");
        assert_eq!(read(&input), TWO_TOUCHING, "{args:?}");
        assert_eq!(read(&frame), TWO_TOUCHING, "{args:?}");
        assert_eq!(leftover_temp_files(d), Vec::<String>::new());
        assert_eq!(leftover_temp_files(&rdir), Vec::<String>::new());
    }
    #[cfg(unix)]
    {
        let link = d.join("link.csv");
        std::os::unix::fs::symlink("same.csv", &link).unwrap();
        let run = mochi([OsStr::new("detect"), p(&input), OsStr::new("-o"), p(&link)]);
        run.assert_failure();
        assert!(run.single_error_line().contains("is the input file"));
        assert_eq!(read(&input), TWO_TOUCHING);
    }
}

/// An output in a folder that does not exist is refused before any work: the error names the
/// folder, and nothing is written anywhere.
#[test]
fn an_output_in_a_missing_folder_is_refused_before_the_work() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let input = d.join("in.csv");
    write_file(&input, TWO_TOUCHING);
    let missing = d.join("missing");
    let out = missing.join("out.csv");
    let png = missing.join("out.png");
    let cases: Vec<Vec<&OsStr>> = vec![
        vec![OsStr::new("detect"), p(&input), OsStr::new("-o"), p(&out)],
        vec![
            OsStr::new("generate"),
            OsStr::new("--scene"),
            OsStr::new("slab"),
            OsStr::new("-n"),
            OsStr::new("100"),
            OsStr::new("-o"),
            p(&out),
        ],
        vec![
            OsStr::new("render"),
            p(&input),
            OsStr::new("-o"),
            p(&png),
            OsStr::new("--renderer"),
            OsStr::new("cpu"),
        ],
    ];
    for args in cases {
        let run = mochi(args);
        run.assert_failure();
        let line = run.single_error_line();
        assert!(
            line.contains("-o") && line.contains("does not exist") && line.contains("missing"),
            "{line}"
        );
        assert!(!missing.exists());
    }
}
