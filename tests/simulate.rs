//! `mochi simulate` end to end: frames and the .pvd index, checkpoints that resume bit for bit
//! on the cpu backend and within rounding on the GPU backends, and clear errors for bad scenes.

mod common;

use mochi::backend::BackendKind;
use mochi::dem::Particles;
use mochi::gpu::Need;
use mochi::io::read_checkpoint;
use std::path::Path;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_mochi");

fn mochi(args: &[&str], dir: &Path) -> (Option<i32>, String, String) {
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

fn ok(args: &[&str], dir: &Path) -> String {
    let (code, stdout, stderr) = mochi(args, dir);
    assert_eq!(code, Some(0), "{args:?}\n{stdout}\n{stderr}");
    stdout
}

fn fails(args: &[&str], dir: &Path) -> String {
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

const SMALL: [&str; 9] = [
    "simulate",
    "--scene",
    "slab",
    "-n",
    "1500",
    "--backend",
    "cpu",
    "--quiet",
    "--csv",
];

#[test]
fn a_run_writes_frames_an_index_a_checkpoint_and_a_summary() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = SMALL.to_vec();
    args.extend(["--steps", "60", "--frame-every", "20", "-o", "out"]);
    let stdout = ok(&args, dir.path());
    assert!(stdout.contains("| build | DCD | update |"), "{stdout}");
    let out = dir.path().join("out");
    let pvd = std::fs::read_to_string(out.join("series.pvd")).unwrap();
    for step in [0, 20, 40, 60] {
        let name = format!("frame_{step:08}.vtu");
        assert!(pvd.contains(&name), "{name} missing from\n{pvd}");
        assert!(out.join(&name).is_file());
        assert!(out.join(format!("frame_{step:08}.csv")).is_file());
    }
    let (particles, scene) = read_checkpoint(&out.join("checkpoint.bin")).unwrap();
    assert_eq!(particles.step, 60);
    assert_eq!(particles.len(), 1500);
    assert!(
        scene.contains("dt = "),
        "the saved scene is resolved: {scene}"
    );
    // Under gravity the slab has moved down.
    assert!(particles.velocities.iter().all(|v| v[2] < 0.0));
}

#[test]
fn resuming_the_cpu_backend_continues_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let mut straight = SMALL.to_vec();
    straight.extend(["--steps", "80", "--frame-every", "0", "-o", "straight"]);
    ok(&straight, dir.path());
    let mut first = SMALL.to_vec();
    first.extend(["--steps", "30", "--frame-every", "10", "-o", "split"]);
    ok(&first, dir.path());
    ok(
        &[
            "simulate",
            "--resume",
            "split/checkpoint.bin",
            "--steps",
            "80",
            "-o",
            "split",
            "--backend",
            "cpu",
            "-q",
        ],
        dir.path(),
    );
    let a = read_checkpoint(&dir.path().join("straight/checkpoint.bin"))
        .unwrap()
        .0;
    let b = read_checkpoint(&dir.path().join("split/checkpoint.bin"))
        .unwrap()
        .0;
    assert_eq!(a.step, 80);
    assert!(a == b, "a resumed run differs from an uninterrupted one");
    // The index keeps the frames before the resume and adds the later ones.
    let pvd = std::fs::read_to_string(dir.path().join("split/series.pvd")).unwrap();
    for step in [0, 10, 20, 30, 40, 80] {
        assert!(pvd.contains(&format!("frame_{step:08}.vtu")), "{pvd}");
    }
}

#[test]
fn a_csv_frame_restarts_a_run_with_its_velocities() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = SMALL.to_vec();
    first.extend(["--steps", "40", "--frame-every", "40", "-o", "a"]);
    ok(&first, dir.path());
    let frame = dir.path().join("a/frame_00000040.csv");
    let (spheres, velocities) = mochi::io::read_particles(&frame).unwrap();
    let velocities = velocities.expect("frame CSVs carry velocities");
    assert_eq!(spheres.len(), 1500);
    // Same box as the slab (the file's own bounds would be the default).
    ok(
        &[
            "simulate",
            "--input",
            "a/frame_00000040.csv",
            "--set",
            "box_lo=[0,0,0]",
            "--set",
            "box_hi=[1,1,1]",
            "--steps",
            "1",
            "--frame-every",
            "0",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "b",
        ],
        dir.path(),
    );
    let (after, _) = read_checkpoint(&dir.path().join("b/checkpoint.bin")).unwrap();
    // One step of free fall from the frame's velocities: v = v0 - g dt.
    for (v, v0) in after.velocities.iter().zip(&velocities) {
        assert!(
            (v[2] - (v0[2] - 9.81 * 1e-4)).abs() < 1e-6,
            "{v:?} vs {v0:?}"
        );
    }
}

#[test]
fn a_mesh_file_is_filled_and_dropped() {
    let dir = tempfile::tempdir().unwrap();
    let obj = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/box.obj");
    let stdout = ok(
        &[
            "simulate",
            "--mesh",
            obj,
            "--set",
            "mesh_radius=0.02",
            "--set",
            "mesh_size=0.3",
            "--steps",
            "20",
            "--frame-every",
            "0",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "out",
        ],
        dir.path(),
    );
    assert!(stdout.contains("| cpu"), "{stdout}");
    let (particles, scene) = read_checkpoint(&dir.path().join("out/checkpoint.bin")).unwrap();
    // The box (1.75 × 2 × 0.75) fitted into 0.3 is scaled by 0.15 to 0.2625 × 0.3 × 0.1125;
    // the lattice of spacing 2.2 · 0.02 = 0.044 centred on it has ⌈extent / 0.044⌉ = 6 × 7 × 3
    // points, every one at least 0.012 inside a face.
    assert_eq!(particles.len(), 6 * 7 * 3);
    assert!(scene.contains("scene = \"mesh\""), "{scene}");
}

#[test]
fn a_checkpoint_with_a_sphere_pushed_into_a_wall_still_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = SMALL.to_vec();
    first.extend(["--steps", "10", "--frame-every", "0", "-o", "a"]);
    ok(&first, dir.path());
    let path = dir.path().join("a/checkpoint.bin");
    let (mut particles, scene) = read_checkpoint(&path).unwrap();
    particles.positions[0][2] = -0.0001; // through the floor, as a soft wall allows
    mochi::io::write_checkpoint(&path, &particles, &scene).unwrap();
    ok(
        &[
            "simulate",
            "--resume",
            "a/checkpoint.bin",
            "--steps",
            "20",
            "-o",
            "a",
            "--backend",
            "cpu",
            "-q",
        ],
        dir.path(),
    );
    // At t = 0 the same sphere is refused.
    std::fs::write(
        dir.path().join("out.csv"),
        "x,y,z,r\n0.5,0.5,-0.5,0.01\n0.5,0.5,0.5,0.01\n",
    )
    .unwrap();
    let e = fails(
        &[
            "simulate",
            "--input",
            "out.csv",
            "--set",
            "box_lo=[0,0,0]",
            "--set",
            "box_hi=[1,1,1]",
            "-q",
            "--backend",
            "cpu",
        ],
        dir.path(),
    );
    assert!(e.contains("outside the box"), "{e}");
}

#[test]
fn bad_scenes_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| std::fs::write(dir.path().join(name), text).unwrap();
    write("typo.toml", "scene = \"slab\"\nsphers = 10\n");
    assert!(fails(&["simulate", "typo.toml", "-q"], dir.path()).contains("sphers"));
    write("broken.toml", "scene = \"slab\nspheres = 10\n");
    assert!(fails(&["simulate", "broken.toml", "-q"], dir.path()).contains("broken.toml"));
    write("type.toml", "spheres = \"many\"\n");
    assert!(fails(&["simulate", "type.toml", "-q"], dir.path()).contains("spheres"));
    let e = fails(
        &[
            "simulate",
            "-n",
            "100",
            "--set",
            "stiffness=1e9",
            "--steps",
            "1",
            "-q",
            "--backend",
            "cpu",
        ],
        dir.path(),
    );
    assert!(e.contains("stable limit"), "{e}");
    assert!(fails(&["simulate", "--scene", "teapot", "-q"], dir.path()).contains("teapot"));
    assert!(fails(&["simulate", "missing.toml", "-q"], dir.path()).contains("missing.toml"));
    write("junk.bin", "not a checkpoint");
    assert!(fails(&["simulate", "--resume", "junk.bin", "-q"], dir.path()).contains("junk.bin"));
    let e = fails(
        &[
            "simulate",
            "--set",
            "restitution=0",
            "-n",
            "100",
            "-q",
            "--backend",
            "cpu",
        ],
        dir.path(),
    );
    assert!(e.contains("restitution"), "{e}");
}

#[test]
fn coincident_spheres_are_warned_about_and_pushed_apart() {
    let dir = tempfile::tempdir().unwrap();
    // Three spheres at one point (three pairs), one elsewhere.
    let csv = "x,y,z,r\n0.5,0.5,0.5,0.01\n0.5,0.5,0.5,0.01\n0.5,0.5,0.5,0.01\n0.2,0.2,0.2,0.01\n";
    std::fs::write(dir.path().join("same.csv"), csv).unwrap();
    let args = [
        "simulate",
        "--input",
        "same.csv",
        "--set",
        "box_lo=[0,0,0]",
        "--set",
        "box_hi=[1,1,1]",
        "--set",
        "gravity=[0,0,0]",
        "--steps",
        "20",
        "--frame-every",
        "0",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "out",
    ];
    let (code, stdout, stderr) = mochi(&args, dir.path());
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    let warnings: Vec<&str> = stderr.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(warnings.len(), 1, "{stderr}");
    assert!(
        warnings[0].contains("3 pairs of spheres share their centre"),
        "{stderr}"
    );
    let (end, _) = read_checkpoint(&dir.path().join("out/checkpoint.bin")).unwrap();
    for i in 0..3 {
        for j in i + 1..3 {
            let (a, b) = (end.positions[i], end.positions[j]);
            let d = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f32>().sqrt();
            assert!(d > 0.02, "spheres {i} and {j} {d} m apart: {end:?}");
        }
    }
}

/// The GPU backends whose `simulate` runs here: wgpu-compute and wgpu-rq wherever an adapter
/// exists (a panic under CI without one), optix where it runs or is expected.
fn gpu_backends() -> Vec<&'static str> {
    let mut out: Vec<&str> = [("wgpu-compute", Need::Compute), ("wgpu-rq", Need::RayQuery)]
        .into_iter()
        .filter(|(name, need)| common::adapter_for(*need, &format!("simulate --backend {name}")))
        .map(|(name, _)| name)
        .collect();
    if common::expected(BackendKind::Optix) || BackendKind::Optix.probe().is_ok() {
        out.push("optix");
    }
    out
}

/// `SMALL` on `backend`.
fn small_on(backend: &str) -> Vec<&str> {
    let mut args = SMALL.to_vec();
    args[6] = backend;
    args
}

fn checkpoint(dir: &Path, run: &str) -> Particles {
    read_checkpoint(&dir.join(run).join("checkpoint.bin"))
        .unwrap()
        .0
}

/// The largest difference of one coordinate between the same sphere in `a` and in `b` [m].
fn largest_gap(a: &Particles, b: &Particles) -> f32 {
    assert_eq!(a.len(), b.len());
    a.positions
        .iter()
        .zip(&b.positions)
        .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).abs()).fold(0.0, f32::max))
        .fold(0.0, f32::max)
}

#[test]
fn gpu_backends_run_simulate_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let run = ["--steps", "40", "--frame-every", "20", "-o"];
    let mut cpu = SMALL.to_vec();
    cpu.extend(run);
    cpu.push("cpu");
    ok(&cpu, dir.path());
    let expected = checkpoint(dir.path(), "cpu");
    for backend in gpu_backends() {
        let mut args = small_on(backend);
        args.extend(run);
        args.push(backend);
        let stdout = ok(&args, dir.path());
        assert!(stdout.contains(&format!("| {backend}")), "{stdout}");
        let out = dir.path().join(backend);
        let pvd = std::fs::read_to_string(out.join("series.pvd")).unwrap();
        for step in [0, 20, 40] {
            let name = format!("frame_{step:08}.vtu");
            assert!(
                pvd.contains(&name) && out.join(&name).is_file(),
                "{backend}: {name}"
            );
            assert!(out.join(format!("frame_{step:08}.csv")).is_file());
        }
        // In input order, where the cpu run put the same spheres (the slab falls without
        // contacts, so only the rounding of fused multiply-adds differs).
        let got = checkpoint(dir.path(), backend);
        assert_eq!(got.step, 40, "{backend}");
        assert!(
            got.radii == expected.radii,
            "{backend}: radii not in input order"
        );
        let gap = largest_gap(&got, &expected);
        assert!(gap < 1e-6, "{backend}: {gap} m from the cpu run");
        assert!(
            got.velocities.iter().all(|v| v[2] < 0.0),
            "{backend}: falling"
        );
    }
}

#[test]
fn gpu_runs_resume_from_a_checkpoint() {
    // Gravity turning at 50 rad/s has turned 0.75 rad by the resume at step 150: a resume that
    // lost the phase (or the step counter, or wrote the GPU's sorted order back) would pull
    // the spheres millimetres away from the uninterrupted run.
    let dir = tempfile::tempdir().unwrap();
    for backend in gpu_backends() {
        let (straight, split) = (format!("{backend}-straight"), format!("{backend}-split"));
        let spin = ["--set", "gravity_spin=50", "--frame-every", "0", "--steps"];
        let mut args = small_on(backend);
        args.extend(spin);
        args.extend(["300", "-o", &straight]);
        ok(&args, dir.path());
        let mut args = small_on(backend);
        args.extend(spin);
        args.extend(["150", "-o", &split]);
        ok(&args, dir.path());
        let resume = format!("{split}/checkpoint.bin");
        ok(
            &[
                "simulate",
                "--resume",
                &resume,
                "--steps",
                "300",
                "-o",
                &split,
                "--backend",
                backend,
                "-q",
            ],
            dir.path(),
        );
        let (a, b) = (
            checkpoint(dir.path(), &straight),
            checkpoint(dir.path(), &split),
        );
        assert_eq!((a.step, b.step), (300, 300), "{backend}");
        assert!(a.radii == b.radii, "{backend}: radii not in input order");
        let gap = largest_gap(&a, &b);
        assert!(
            gap < 1e-6,
            "{backend}: the resumed run is {gap} m from the uninterrupted one"
        );
    }
}
