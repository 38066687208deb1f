//! `mochi simulate` end to end: frames and the .pvd index, checkpoints that resume bit for bit
//! on the cpu backend and within rounding on the GPU backends, and clear errors for bad scenes.

mod common;

use common::cli::{BIN, fails, mochi, ok, snapshot};
use mochi::dem::Particles;
use mochi::engines::BackendKind;
use mochi::gpu::Need;
use mochi::io::read_checkpoint;
use std::path::Path;
use std::process::Command;

/// The paper's slab with its law (`linear`, frictionless), which every backend runs.
const SMALL: [&str; 11] = [
    "simulate",
    "--scene",
    "slab",
    "-n",
    "1500",
    "--backend",
    "cpu",
    "--quiet",
    "--csv",
    "--set",
    "contact=linear",
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
    let saved = read_checkpoint(&out.join("checkpoint.bin")).unwrap();
    let (particles, scene) = (saved.particles, saved.scene);
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
    let a = checkpoint(dir.path(), "straight");
    let b = checkpoint(dir.path(), "split");
    assert_eq!(a.step, 80);
    assert!(a == b, "a resumed run differs from an uninterrupted one");
    // The index keeps the frames before the resume and adds the later ones.
    let pvd = std::fs::read_to_string(dir.path().join("split/series.pvd")).unwrap();
    for step in [0, 10, 20, 30, 40, 80] {
        assert!(pvd.contains(&format!("frame_{step:08}.vtu")), "{pvd}");
    }
}

#[test]
fn one_process_writes_whole_checkpoints_where_pieces_are_asked() {
    // Pieces are one a process of a run over several: one process's checkpoint is one file.
    let dir = tempfile::tempdir().unwrap();
    let mut run = SMALL.to_vec();
    let pieces = [
        "--set",
        "checkpoint_pieces=true",
        "--checkpoint-every",
        "10",
    ];
    run.extend(
        pieces
            .iter()
            .chain(&["--steps", "20", "--frame-every", "0", "-o", "out"]),
    );
    ok(&run, dir.path());
    let out = dir.path().join("out");
    let bytes = std::fs::read(out.join("checkpoint.bin")).unwrap();
    assert!(bytes.starts_with(b"MOCHICKP"));
    let saved = read_checkpoint(&out.join("checkpoint.bin")).unwrap();
    assert_eq!(saved.particles.step, 20);
    assert!(
        saved.scene.contains("checkpoint_pieces = true"),
        "{}",
        saved.scene
    );
    let names: Vec<_> = (std::fs::read_dir(&out).unwrap())
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert!(
        !names.iter().any(|n| n.starts_with("checkpoint_")),
        "{names:?}"
    );
}

#[test]
fn resuming_a_frictional_cpu_run_continues_bit_for_bit() {
    resumes_bit_for_bit("mindlin");
}

#[test]
fn resuming_a_cpu_run_under_mindlin_deresiewicz_continues_bit_for_bit_with_its_load_history() {
    resumes_bit_for_bit("mindlin-deresiewicz");
}

/// A heap of 64 pressed-together spheres thrown about on the floor: Hertz–Mindlin with friction
/// (the tangential model `model`) and EPSD rolling resistance, so contacts carry springs (and
/// the Mindlin–Deresiewicz model's load histories) across the resume.
fn resumes_bit_for_bit(model: &str) {
    let dir = tempfile::tempdir().unwrap();
    let mut rows = String::from("x,y,z,r,vx,vy,vz\n");
    for k in 0..64 {
        let at = [k % 4, (k / 4) % 4, k / 16].map(|i| 0.0101 + 0.0199 * i as f32);
        let v = [
            ((k % 3) as f32 - 1.0) * 0.1,
            (k % 5) as f32 * 0.02 - 0.04,
            -0.05,
        ];
        rows += &format!(
            "{},{},{},0.01,{},{},{}\n",
            at[0], at[1], at[2], v[0], v[1], v[2]
        );
    }
    std::fs::write(dir.path().join("heap.csv"), rows).unwrap();
    let run = |out: &str, steps: &str| {
        let args = [
            "simulate",
            "--input",
            "heap.csv",
            "--steps",
            steps,
            "--frame-every",
            "0",
            "--set",
            "contact=hertz-mindlin",
            "--set",
            "young_modulus=1e5",
            "--set",
            &format!("tangential_model=\"{model}\""),
            "--set",
            "box_lo=[0,0,0]",
            "--set",
            "box_hi=[0.3,0.3,0.3]",
            "--backend",
            "cpu",
            "-q",
            "-o",
            out,
        ];
        ok(&args, dir.path());
    };
    run("straight", "120");
    run("split", "50");
    ok(&strs(&resume_run("split", "120", &[])), dir.path());
    let a = checkpoint(dir.path(), "straight");
    let b = checkpoint(dir.path(), "split");
    assert_eq!(a.step, 120);
    assert!(
        a.history.len() > 100,
        "{} contacts with history",
        a.history.len()
    );
    assert_eq!(a.history.has_loads(), model == "mindlin-deresiewicz");
    assert!(
        a.angular_velocities
            .iter()
            .all(|w| w.iter().any(|&x| x != 0.0))
    );
    let bits = |p: &Particles| -> Vec<u32> {
        let vectors = [&p.positions, &p.velocities, &p.angular_velocities];
        let springs = p
            .history
            .contacts()
            .flat_map(|(_, e)| e.tangential.into_iter().chain(e.rolling));
        let loads =
            (p.history.contact_loads()).flat_map(|l| l.reversal.into_iter().chain([l.normal]));
        vectors
            .into_iter()
            .flat_map(|v| v.iter().flatten().copied())
            .chain(springs)
            .chain(loads)
            .map(f32::to_bits)
            .collect()
    };
    assert!(
        a == b,
        "a resumed frictional run ({model}) differs from an uninterrupted one"
    );
    assert_eq!(bits(&a), bits(&b));
}

#[test]
fn a_csv_frame_restarts_a_run_with_its_velocities() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = SMALL.to_vec();
    first.extend(["--steps", "40", "--frame-every", "40", "-o", "a"]);
    ok(&first, dir.path());
    let frame = dir.path().join("a/frame_00000040.csv");
    let particles = mochi::io::read_particles(&frame).unwrap();
    let velocities = particles.velocities.clone();
    assert!(
        velocities.iter().any(|v| *v != [0.0; 3]),
        "frame CSVs carry velocities"
    );
    assert_eq!(particles.len(), 1500);
    // Same box as the slab (the file's own bounds would be the default).
    ok(
        &[
            "simulate",
            "--input",
            "a/frame_00000040.csv",
            "--set",
            "contact=linear",
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
    let after = read_checkpoint(&dir.path().join("b/checkpoint.bin"))
        .unwrap()
        .particles;
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
    let obj = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/box.obj");
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
    let saved = read_checkpoint(&dir.path().join("out/checkpoint.bin")).unwrap();
    let (particles, scene) = (saved.particles, saved.scene);
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
    let mut saved = read_checkpoint(&path).unwrap();
    // Through the floor, as a soft wall allows (the residual goes with the centre).
    let [x, y, _] = saved.particles.exact_position(0);
    saved
        .particles
        .set_exact_position(0, [x, y, -0.0001])
        .unwrap();
    mochi::io::write_checkpoint(&path, &saved.particles, &saved.scene, &saved.state).unwrap();
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
fn named_options_set_the_scene_and_set_overrides_them() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("s.toml"), "scene = \"poly12\"\nseed = 5\n").unwrap();
    let args = [
        "simulate",
        "s.toml",
        "--scene",
        "rotating",
        "-n",
        "200",
        "--mode",
        "nns",
        "--dt",
        "2e-5",
        "--csv",
        "--steps",
        "1",
        "--set",
        "spheres=100",
        "--set",
        "contact=linear",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "out",
    ];
    ok(&args, dir.path());
    let scene = std::fs::read_to_string(dir.path().join("out/scene.toml")).unwrap();
    for line in [
        "scene = \"rotating\"",
        "spheres = 100",
        "seed = 5",
        "mode = \"nns\"",
        // The time step as f32 resolved it, by its shortest decimal.
        "dt = 0.00002",
        "csv = true",
    ] {
        assert!(scene.lines().any(|l| l == line), "{line} in\n{scene}");
    }
}

#[test]
fn the_saved_scene_holds_short_numbers_and_resumes_as_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    // The default scene, whose box (fitted to 300 spheres) and time step (0.2 Rayleigh times)
    // are derived f32 values.
    let run = ["simulate", "-n", "300", "--backend", "cpu", "-q"];
    ok(
        &[&run[..], &["--steps", "6", "-o", "straight"]].concat(),
        dir.path(),
    );
    ok(
        &[&run[..], &["--steps", "3", "-o", "split"]].concat(),
        dir.path(),
    );
    let saved = std::fs::read_to_string(dir.path().join("split/scene.toml")).unwrap();
    for key in ["dt = ", "box_hi = ", "gravity_spin = "] {
        let line = saved.lines().find(|l| l.starts_with(key)).unwrap();
        // An f32 by its shortest decimal has at most 9 significant digits, one widened to f64
        // (0.800000011920929) 15 to 17.
        let digits = line.split([',', '[']).map(|number| {
            let mantissa = number.split('e').next().unwrap();
            let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
            digits.trim_matches('0').len()
        });
        assert!(digits.max().unwrap() <= 9, "{line}");
    }
    // Resumed from its saved scene, the run is the uninterrupted one: the same particles, the
    // same scene saved.
    ok(&strs(&resume_run("split", "6", &[])), dir.path());
    let read = |run: &str| std::fs::read(dir.path().join(run).join("checkpoint.bin")).unwrap();
    assert!(read("straight") == read("split"), "the checkpoints differ");
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
            "contact=linear",
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
fn a_damaged_checkpoint_is_refused_by_its_checksum() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = SMALL.to_vec();
    first.extend(["--steps", "10", "--frame-every", "0", "-o", "a"]);
    ok(&first, dir.path());
    let path = dir.path().join("a/checkpoint.bin");
    let mut bytes = std::fs::read(&path).unwrap();
    let middle = bytes.len() / 2; // inside the positions
    bytes[middle] ^= 0x01;
    std::fs::write(&path, &bytes).unwrap();
    let resume = resume_run("a", "20", &[]);
    let e = fails(&strs(&resume), dir.path());
    assert!(
        e.contains("checkpoint.bin") && e.contains("checksum mismatch"),
        "{e}"
    );
}

#[test]
fn a_resumed_state_is_checked_like_a_fresh_one() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = SMALL.to_vec();
    first.extend(["--steps", "10", "--frame-every", "0", "-o", "a"]);
    ok(&first, dir.path());
    let path = dir.path().join("a/checkpoint.bin");
    let saved = read_checkpoint(&path).unwrap();
    let (particles, scene) = (saved.particles, saved.scene);
    let resume = resume_run("a", "20", &[]);
    // A centre far outside the unit box, though the file is intact.
    let mut far = particles.clone();
    let [_, y, z] = far.exact_position(3);
    far.set_exact_position(3, [5.0, y, z]).unwrap();
    mochi::io::write_checkpoint(&path, &far, &scene, "").unwrap();
    let e = fails(&strs(&resume), dir.path());
    assert!(
        e.contains("sphere 3") && e.contains("outside the box"),
        "{e}"
    );
    // A radius no sphere file may hold.
    let mut flat = particles.clone();
    flat.radii[7] = 0.0;
    mochi::io::write_checkpoint(&path, &flat, &scene, "").unwrap();
    let e = fails(&strs(&resume), dir.path());
    assert!(e.contains("sphere 7"), "{e}");
    // Parameters a fresh run refuses.
    let soft = scene.replace("restitution = 0.5", "restitution = 0.0");
    assert_ne!(soft, scene);
    mochi::io::write_checkpoint(&path, &particles, &soft, "").unwrap();
    let e = fails(&strs(&resume), dir.path());
    assert!(e.contains("restitution"), "{e}");
}

#[test]
fn resume_refuses_overrides_that_change_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = SMALL.to_vec();
    first.extend(["--steps", "10", "--frame-every", "5", "-o", "a"]);
    ok(&first, dir.path());
    let scene_toml = std::fs::read(dir.path().join("a/scene.toml")).unwrap();
    let checkpoint = std::fs::read(dir.path().join("a/checkpoint.bin")).unwrap();
    for (set, key) in [
        ("dt=2e-4", "dt"),
        ("box_hi=[0.1, 0.1, 0.1]", "box_hi"),
        ("scene=\"poly120\"", "scene"),
        ("gravity=[0, 0, -1.62]", "gravity"),
        ("seed=9", "seed"),
    ] {
        let e = fails(&strs(&resume_run("a", "20", &["--set", set])), dir.path());
        assert!(
            e.contains(&format!("--set {key}:")) && e.contains("--resume"),
            "{set}: {e}"
        );
        assert_eq!(
            std::fs::read(dir.path().join("a/scene.toml")).unwrap(),
            scene_toml,
            "{set} rewrote scene.toml"
        );
        assert_eq!(
            std::fs::read(dir.path().join("a/checkpoint.bin")).unwrap(),
            checkpoint
        );
    }
    // What a resume may change: how far it runs and what it writes; a value equal to the
    // checkpoint's is no change.
    ok(
        &[
            "simulate",
            "--resume",
            "a/checkpoint.bin",
            "--steps",
            "20",
            "--frame-every",
            "10",
            "--set",
            "restitution=0.5",
            "-o",
            "a",
            "--backend",
            "cpu",
            "-q",
        ],
        dir.path(),
    );
    let scene = read_checkpoint(&dir.path().join("a/checkpoint.bin"))
        .unwrap()
        .scene;
    assert!(scene.contains("scene = \"slab\""), "{scene}");
    assert!(scene.contains("steps = 20"), "{scene}");
}

#[test]
fn absurd_parameters_are_refused_up_front_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec![
            "simulate",
            "-n",
            "100",
            "--set",
            "contact=linear",
            "--steps",
            "20",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "out",
        ];
        args.extend(extra);
        fails(&args, dir.path())
    };
    let e = run(&["--dt", "1e-30"]);
    assert!(e.contains("derived stiffness") && e.contains("f32"), "{e}");
    let e = run(&["--set", "gravity=[0, 0, 1e30]"]);
    assert!(e.contains("gravity") && e.contains("single step"), "{e}");
    // Refused before anything is written.
    assert!(!dir.path().join("out").exists());
}

#[test]
fn conflicting_options_are_errors_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("good.csv"), "x,y,z,r\n0.5,0.5,0.5,0.01\n").unwrap();
    let mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/box.obj");
    let cases: [(&[&str], [&str; 2]); 8] = [
        (
            &["--input", "good.csv", "--scene", "slab"],
            ["--input", "--scene"],
        ),
        (
            &["--input", "good.csv", "-n", "100"],
            ["--input", "--spheres"],
        ),
        (
            &["--input", "good.csv", "--seed", "3"],
            ["--input", "--seed"],
        ),
        (&["--mesh", mesh, "--scene", "slab"], ["--mesh", "--scene"]),
        (&["--mesh", mesh, "-n", "100"], ["--mesh", "--spheres"]),
        (&["--set", "input=\"good.csv\""], ["--set input", "--scene"]),
        (
            &["--set", "mesh_copies=2"],
            ["--set mesh_copies", "--scene"],
        ),
        (&["--set", "scene=\"mesh\"", "-n", "100"], ["-n", "--mesh"]),
    ];
    for (extra, [a, b]) in cases {
        let mut args = vec![
            "simulate",
            "--steps",
            "1",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "out",
        ];
        args.extend(extra);
        let (code, _, stderr) = mochi(&args, dir.path());
        assert!(matches!(code, Some(1 | 2)), "{extra:?}: {code:?} {stderr}");
        assert!(stderr.starts_with("error: "), "{extra:?}: {stderr}");
        assert!(
            stderr.contains(a) && stderr.contains(b),
            "{extra:?}: {stderr}"
        );
        assert!(!dir.path().join("out").exists(), "{extra:?} wrote output");
    }
    // mesh_copies of the mesh scene must be at least 1.
    let e = fails(
        &[
            "simulate",
            "--mesh",
            mesh,
            "--set",
            "mesh_copies=0",
            "-q",
            "-o",
            "out",
        ],
        dir.path(),
    );
    assert!(e.contains("mesh_copies: must be from 1"), "{e}");
}

#[test]
fn step_counts_beyond_the_scene_range_get_a_range_error() {
    let dir = tempfile::tempdir().unwrap();
    let (code, _, stderr) = mochi(
        &[
            "simulate",
            "--steps",
            "18446744073709551615",
            "-q",
            "-o",
            "out",
        ],
        dir.path(),
    );
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("0..=9223372036854775807"), "{stderr}");
    assert!(!stderr.contains("TOML"), "{stderr}");
    let e = fails(
        &[
            "simulate",
            "--set",
            "steps=18446744073709551615",
            "-q",
            "-o",
            "out",
        ],
        dir.path(),
    );
    assert!(
        e.contains("outside the range") && !e.contains("TOML"),
        "{e}"
    );
    assert!(!dir.path().join("out").exists());
}

#[test]
fn a_run_of_zero_steps_claims_no_clock_and_no_contacts() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = SMALL.to_vec();
    args.extend(["--steps", "0", "-o", "out"]);
    let stdout = ok(&args, dir.path());
    // No step taken: nothing counted, nothing timed.
    assert!(stdout.contains("| 0 | 0.00 | 0.0 | — |"), "{stdout}");
    assert!(!stdout.contains("per step"), "{stdout}");
    assert!(!stdout.contains("GPU timestamps"), "{stdout}");
}

// ----------------------------------------------------------------------------------------------
// The output folder: nothing of an earlier run or of an input is lost
// ----------------------------------------------------------------------------------------------

/// A short run of 300 spheres of the paper's slab (`linear`) into `out` with frames every 10
/// steps (as CSV too).
fn short_run(out: &str, extra: &[&str]) -> Vec<String> {
    let mut args = vec![
        "simulate",
        "--scene",
        "slab",
        "--set",
        "contact=linear",
        "-n",
        "300",
        "--steps",
        "20",
        "--frame-every",
        "10",
        "--csv",
        "--backend",
        "cpu",
        "-q",
        "-o",
        out,
    ];
    args.extend(extra);
    args.into_iter().map(String::from).collect()
}

/// Resumes the checkpoint of the run in `out` up to `steps`, into `out`, on the cpu backend,
/// quietly, with `extra` options.
fn resume_run(out: &str, steps: &str, extra: &[&str]) -> Vec<String> {
    let checkpoint = format!("{out}/checkpoint.bin");
    let mut args = vec!["simulate", "--resume", &checkpoint, "--steps", steps];
    args.extend(extra);
    args.extend(["--backend", "cpu", "-q", "-o", out]);
    args.into_iter().map(String::from).collect()
}

fn strs(args: &[String]) -> Vec<&str> {
    args.iter().map(String::as_str).collect()
}

#[test]
fn a_resume_without_out_continues_in_the_checkpoints_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&strs(&short_run("run", &[])), d);
    let checkpoint = "run/checkpoint.bin";
    let args = [
        "simulate",
        "--resume",
        checkpoint,
        "--steps",
        "30",
        "--backend",
        "cpu",
        "-q",
    ];
    let stdout = ok(&args, d);
    assert!(d.join("run/frame_00000030.vtu").is_file(), "{stdout}");
    assert!(!d.join("mochi-out").exists(), "{stdout}");
    let particles = mochi::io::read_checkpoint(&d.join(checkpoint))
        .unwrap()
        .particles;
    assert_eq!(particles.step, 30);
}

#[test]
fn a_folder_holding_a_run_is_refused_unless_overwrite_which_removes_only_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&strs(&short_run("prev", &[])), d);
    std::fs::write(d.join("prev/notes.txt"), "mine").unwrap();
    let before = snapshot(&d.join("prev"));

    // A run that fails its checks (a bad picture size) changes nothing, not even with
    // --overwrite (without it, the folder is refused first).
    for (extra, problem) in [(None, "holds an earlier run"), (Some("--overwrite"), "0x0")] {
        let mut bad = short_run("prev", &["--render-every", "5", "--size", "0x0"]);
        bad.extend(extra.map(String::from));
        let e = fails(&strs(&bad), d);
        assert!(e.contains(problem), "{e}");
        assert_eq!(snapshot(&d.join("prev")), before, "{extra:?}");
    }

    // A valid run into the folder is refused: it holds a run.
    let again = short_run("prev", &["--seed", "2"]);
    let e = fails(&strs(&again), d);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(
        e.contains("prev holds an earlier run") && e.contains("--overwrite"),
        "{e}"
    );
    assert_eq!(snapshot(&d.join("prev")), before);

    // --overwrite: the old run's files go (frame 10 and the CSVs are not written again), the
    // other files stay.
    let mut overwrite = again.clone();
    overwrite.retain(|a| a != "--csv");
    let every = overwrite.iter().position(|a| a == "--frame-every").unwrap();
    overwrite[every + 1] = "20".into();
    overwrite.push("--overwrite".into());
    ok(&strs(&overwrite), d);
    let names: Vec<String> = snapshot(&d.join("prev")).into_iter().map(|f| f.0).collect();
    assert_eq!(
        names,
        [
            "checkpoint.bin",
            "frame_00000000.vtu",
            "frame_00000020.vtu",
            "notes.txt",
            "scene.toml",
            "series.pvd"
        ]
    );
    assert_eq!(std::fs::read(d.join("prev/notes.txt")).unwrap(), b"mine");
    let (code, _, e) = mochi(
        &["simulate", "--overwrite", "--resume", "prev/checkpoint.bin"],
        d,
    );
    assert_eq!(code, Some(2), "a resumed run keeps its files: {e}");
}

#[test]
fn an_input_among_the_files_a_run_writes_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&strs(&short_run("ow", &[])), d);
    let before = snapshot(&d.join("ow"));
    let problems = [
        (None, "ow/ holds an earlier run"),
        (
            Some("--overwrite"),
            "ow/frame_00000010.csv lies in the output folder",
        ),
    ];
    for (extra, problem) in problems {
        let mut args: Vec<&str> = vec![
            "simulate",
            "--input",
            "ow/frame_00000010.csv",
            "--set",
            "box_lo=[0,0,0]",
            "--set",
            "box_hi=[1,1,1]",
            "--steps",
            "10",
            "--csv",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "./ow/",
        ];
        args.extend(extra);
        let e = fails(&args, d);
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(e.contains(problem), "{e}");
        assert_eq!(snapshot(&d.join("ow")), before, "{extra:?}");
    }
    // A GIF may not take the place of an input either.
    std::fs::copy(d.join("ow/frame_00000010.csv"), d.join("start.csv")).unwrap();
    let e = fails(
        &[
            "simulate",
            "--input",
            "start.csv",
            "--set",
            "box_lo=[0,0,0]",
            "--set",
            "box_hi=[1,1,1]",
            "--steps",
            "10",
            "--render-every",
            "10",
            "--size",
            "16x12",
            "--renderer",
            "cpu",
            "--gif",
            "start.csv",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "new",
        ],
        d,
    );
    assert!(e.contains("--gif start.csv is the input file"), "{e}");
    assert!(!d.join("new").exists());
    std::fs::copy(d.join("ow/checkpoint.bin"), d.join("saved.bin")).unwrap();
    let saved = std::fs::read(d.join("saved.bin")).unwrap();
    let e = fails(
        &[
            "simulate",
            "--resume",
            "saved.bin",
            "--steps",
            "30",
            "--render-every",
            "10",
            "--size",
            "16x12",
            "--renderer",
            "cpu",
            "--gif",
            "saved.bin",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "ow",
        ],
        d,
    );
    assert!(e.contains("--gif saved.bin is the input file"), "{e}");
    assert_eq!(std::fs::read(d.join("saved.bin")).unwrap(), saved);
    assert_eq!(snapshot(&d.join("ow")), before);
}

#[test]
fn a_resume_with_a_broken_index_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&strs(&short_run("run", &[])), d);
    std::fs::write(d.join("run/series.pvd"), "<VTKFile>not an index").unwrap();
    let before = snapshot(&d.join("run"));
    let e = fails(&strs(&resume_run("run", "40", &["--set", "csv=true"])), d);
    assert!(e.contains("series.pvd"), "{e}");
    assert_eq!(snapshot(&d.join("run")), before);
}

#[test]
fn a_folder_another_run_holds_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let other = mochi::io::RunFolder::lock(&d.join("busy")).unwrap();
    let e = fails(&strs(&short_run("busy", &[])), d);
    assert!(
        e.contains("busy: another mochi run is writing into this folder"),
        "{e}"
    );
    assert!(snapshot(&d.join("busy")).is_empty());
    drop(other);
    // Other tests of this process spawn children all the time; a child forked before the drop
    // holds the lock's descriptor until its exec closes it, so the folder frees within moments.
    let run = short_run("busy", &[]);
    let args = strs(&run);
    let freed = (0..100).any(|_| {
        let (code, _, stderr) = mochi(&args, d);
        if code != Some(0) && stderr.contains("another mochi run is writing") {
            std::thread::sleep(std::time::Duration::from_millis(50));
            return false;
        }
        assert_eq!(code, Some(0), "{stderr}");
        true
    });
    assert!(freed, "the folder stayed locked after its holder let go");
    // The run's lock ended with it.
    mochi::io::RunFolder::lock(&d.join("busy")).unwrap();
}

#[cfg(unix)]
#[test]
fn temporary_files_of_killed_writers_are_removed_when_a_run_starts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("out")).unwrap();
    // A child that has exited and been reaped: its pid names no process.
    let mut child = Command::new("true").spawn().unwrap();
    let gone = child.id();
    child.wait().unwrap();
    let stale = format!(".mochi-{gone}-a1b2c3");
    let live = format!(".mochi-{}-d4e5f6", std::process::id());
    for name in [&stale, &live] {
        std::fs::write(d.join("out").join(name), "partial").unwrap();
        std::fs::write(d.join(name), "partial").unwrap();
    }
    ok(&strs(&short_run("out", &[])), d);
    assert!(!d.join("out").join(&stale).exists());
    assert!(
        d.join("out").join(&live).exists(),
        "a live writer's file was removed"
    );
    // `generate` cleans its output's folder too.
    ok(&["generate", "-n", "10", "-o", "spheres.csv"], d);
    assert!(!d.join(&stale).exists());
    assert!(d.join(&live).exists());
}

#[test]
fn gif_problems_are_found_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let e = fails(
        &strs(&short_run(
            "out",
            &[
                "--render-every",
                "10",
                "--size",
                "16x12",
                "--renderer",
                "cpu",
                "--gif",
                "missing/run.gif",
            ],
        )),
        d,
    );
    assert!(
        e.contains("--gif missing/run.gif: the folder missing does not exist"),
        "{e}"
    );
    assert!(!d.join("out").exists());
    let e = fails(&strs(&short_run("out", &["--gif", "run.gif"])), d);
    assert!(
        e.contains("--gif is a picture option") && e.contains("--render-every"),
        "{e}"
    );
    assert!(!d.join("out").exists());
    // In the output folder, which the run creates, a GIF is fine.
    ok(
        &strs(&short_run(
            "out",
            &[
                "--render-every",
                "10",
                "--size",
                "16x12",
                "--renderer",
                "cpu",
                "--gif",
                "./out/run.gif",
            ],
        )),
        d,
    );
    assert!(
        std::fs::read(d.join("out/run.gif"))
            .unwrap()
            .starts_with(b"GIF89a")
    );
}

/// A run killed while it writes leaves no GIF (only its temporary file), and the next run into
/// the folder removes that file.
#[cfg(unix)]
#[test]
fn a_killed_run_leaves_no_gif_and_its_temporary_file_is_removed_by_the_next() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let temp_files = || -> Vec<String> {
        std::fs::read_dir(d.join("out"))
            .map(|listing| {
                listing
                    .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                    .filter(|n| n.starts_with(".mochi-"))
                    .collect()
            })
            .unwrap_or_default()
    };
    let mut args = short_run(
        "out",
        &[
            "--render-every",
            "10",
            "--size",
            "16x12",
            "--renderer",
            "cpu",
            "--gif",
            "out/run.gif",
        ],
    );
    let steps = args.iter().position(|a| a == "--steps").unwrap();
    args[steps + 1] = "100000000".into();
    let mut child = Command::new(BIN)
        .args(&args)
        .current_dir(d)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Wait until pictures are being drawn into the GIF (a guard against a hang, not a timing).
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while !d.join("out/frame_00000020.png").exists() {
        assert!(std::time::Instant::now() < deadline, "no pictures drawn");
        assert!(child.try_wait().unwrap().is_none(), "the run ended early");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!d.join("out/run.gif").exists(), "a killed run left a GIF");
    let left = temp_files();
    assert!(
        left.iter()
            .any(|n| n.starts_with(&format!(".mochi-{}-", child.id()))),
        "{left:?}"
    );
    let mut again = short_run("out", &["--overwrite"]);
    again.retain(|a| a != "--csv");
    ok(&strs(&again), d);
    assert_eq!(temp_files(), Vec::<String>::new());
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
    let end = read_checkpoint(&dir.path().join("out/checkpoint.bin"))
        .unwrap()
        .particles;
    for i in 0..3 {
        for j in i + 1..3 {
            let (a, b) = (end.positions[i], end.positions[j]);
            let d = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f32>().sqrt();
            assert!(d > 0.02, "spheres {i} and {j} {d} m apart: {end:?}");
        }
    }
}

#[test]
fn large_coincident_groups_in_a_file_run_in_the_box_fitted_to_them() {
    // 200 and 2000 rows at one point, the box fitted to the file: the group spreads into a
    // cluster about the point and the box holds it (fitted to the centres it spreads to, with
    // the margin of two diameters), under Hertz–Mindlin (the default) and the linear law.
    // Left a fraction of a radius apart, their overlaps would fling them through the walls of
    // a box of 8 radii, and the step would diverge under Hertz–Mindlin.
    let dir = tempfile::tempdir().unwrap();
    let r = 0.01f32;
    for n in [200, 2000] {
        let csv = format!("x,y,z,r\n{}", "0.5,0.5,0.5,0.01\n".repeat(n));
        std::fs::write(dir.path().join("same.csv"), csv).unwrap();
        for law in ["hertz-mindlin", "linear"] {
            let out = format!("out-{n}-{law}");
            let contact = format!("contact={law}");
            let args = [
                "simulate",
                "--input",
                "same.csv",
                "--set",
                &contact,
                "--steps",
                "100",
                "--frame-every",
                "0",
                "--backend",
                "cpu",
                "-q",
                "-o",
                &out,
            ];
            let (code, stdout, stderr) = mochi(&args, dir.path());
            assert_eq!(code, Some(0), "{n} spheres, {law}: {stdout}\n{stderr}");
            let pairs = format!("{} pairs of spheres share their centre", n * (n - 1) / 2);
            assert!(stderr.contains(&pairs), "{stderr}");
            let checkpoint = dir.path().join(&out).join("checkpoint.bin");
            let saved = read_checkpoint(&checkpoint).unwrap();
            let (end, scene) = (saved.particles, saved.scene);
            let scene: toml::Table = toml::from_str(&scene).unwrap();
            let corner = |key: &str| -> Vec<f32> {
                let values = scene["domain"][key].as_array().unwrap();
                values
                    .iter()
                    .map(|x| x.as_float().unwrap() as f32)
                    .collect()
            };
            let (lo, hi) = (corner("box_lo"), corner("box_hi"));
            for (i, (c, v)) in end.positions.iter().zip(&end.velocities).enumerate() {
                let inside = (0..3).all(|a| c[a] - r >= lo[a] && c[a] + r <= hi[a]);
                assert!(
                    inside,
                    "{n}, {law}: sphere {i} at {c:?}, box {lo:?} .. {hi:?}"
                );
                let speed = v.iter().map(|x| x * x).sum::<f32>().sqrt();
                assert!(speed < 0.1, "{n}, {law}: sphere {i} moves at {speed} m/s");
            }
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
        .particles
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
        let gap = common::largest_gap(&got, &expected);
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
        let gap = common::largest_gap(&a, &b);
        assert!(
            gap < 1e-6,
            "{backend}: the resumed run is {gap} m from the uninterrupted one"
        );
    }
}

/// A turning drum (an OBJ cylinder about y, radius 0.1 m) with a few spheres inside, as files
/// in `dir`: `drum.obj`, `input.csv` and `scene.toml`.
fn drum_scene(dir: &Path) {
    let sides = 32;
    let mut obj = String::new();
    for k in 0..sides {
        let a = std::f64::consts::TAU * k as f64 / sides as f64;
        for y in [-0.05, 0.05] {
            obj += &format!("v {} {y} {}\n", 0.1 * a.cos(), 0.1 * a.sin());
        }
    }
    for k in 0..sides {
        let (a, b) = (2 * k + 1, 2 * ((k + 1) % sides) + 1);
        obj += &format!("f {a} {b} {}\nf {a} {} {}\n", b + 1, b + 1, a + 1);
    }
    std::fs::write(dir.join("drum.obj"), obj).unwrap();
    let mut csv = String::from("x,y,z,r\n");
    // Three layers on the bottom arc, the first already touching the drum.
    for (layer, radius) in [0.094f64, 0.081, 0.068].into_iter().enumerate() {
        for i in -3..=3 {
            let a = (-90.0 + 8.5 * i as f64 + 4.0 * layer as f64).to_radians();
            csv += &format!("{},0,{},0.006\n", radius * a.cos(), radius * a.sin());
        }
    }
    std::fs::write(dir.join("input.csv"), csv).unwrap();
    let scene = "scene = \"input\"\ninput = \"input.csv\"\nbox_lo = [-0.12, -0.05, -0.12]\n\
                 box_hi = [0.12, 0.05, 0.12]\n\n[[wall]]\nmesh = \"drum.obj\"\nomega = 3.0\n\
                 axis = [0, 1, 0]\n";
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
}

#[test]
fn a_turning_mesh_wall_is_written_with_its_loads_and_resumes_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    drum_scene(dir.path());
    let run = |out: &str, steps: &str| {
        let args = [
            "simulate",
            "scene.toml",
            "--steps",
            steps,
            "--frame-every",
            "50",
            "-q",
            "-o",
            out,
        ];
        ok(&args, dir.path());
    };
    run("straight", "200");
    run("split", "100");
    let resume = [
        "simulate",
        "--resume",
        "split/checkpoint.bin",
        "--steps",
        "200",
        "-q",
    ];
    ok(&resume, dir.path());
    let a = checkpoint(dir.path(), "straight");
    assert!(
        a == checkpoint(dir.path(), "split"),
        "a resumed run differs"
    );
    let read = |path: &str| std::fs::read_to_string(dir.path().join(path)).unwrap();
    let loads = read("straight/walls.csv");
    assert_eq!(loads, read("split/walls.csv"));
    // A row per frame (steps 0, 50, .., 200) for the one wall, the drum carrying weight.
    assert_eq!(loads.lines().count(), 1 + 5, "{loads}");
    assert!(
        loads.starts_with("time,wall,fx,fy,fz,tx,ty,tz\n"),
        "{loads}"
    );
    let last_fz: f64 = loads
        .lines()
        .last()
        .unwrap()
        .split(',')
        .nth(4)
        .unwrap()
        .parse()
        .unwrap();
    assert!(last_fz < 0.0, "{loads}");
    let index = read("split/walls.pvd");
    for step in [0, 100, 200] {
        let file = format!("wall_{step:08}_0.vtp");
        assert!(index.contains(&file), "{index}");
        assert!(dir.path().join("split").join(file).exists());
    }
    // The turned wall moved: its surface differs between frames.
    let surface = |path: &str| std::fs::read(dir.path().join(path)).unwrap();
    assert_ne!(
        surface("straight/wall_00000050_0.vtp"),
        surface("straight/wall_00000200_0.vtp")
    );
}

#[test]
fn the_wgpu_backends_load_a_turning_mesh_wall_as_the_cpu_does_and_run_it_without_box_walls() {
    let dir = tempfile::tempdir().unwrap();
    drum_scene(dir.path());
    let loads = |backend: &str| {
        let out = format!("on-{backend}");
        let args = [
            "simulate",
            "scene.toml",
            "--steps",
            "100",
            "--frame-every",
            "50",
            "--backend",
            backend,
            "-q",
            "-o",
            &out,
        ];
        ok(&args, dir.path());
        let csv = std::fs::read_to_string(dir.path().join(&out).join("walls.csv")).unwrap();
        let rows: Vec<Vec<f64>> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        rows
    };
    let cpu = loads("cpu");
    // Frames at steps 0, 50 and 100; the drum took the first layer's impact by step 50.
    assert_eq!(cpu.len(), 3);
    let largest = cpu
        .iter()
        .flat_map(|r| r[2..].iter())
        .fold(0.0f64, |m, x| m.max(x.abs()));
    // More than the 21 spheres weigh (21 × 4.5e-4 kg × 9.81 m/s² = 0.093 N): the drum carries
    // them, and took the first layer's impact.
    assert!(largest > 0.093, "{cpu:?}");
    for backend in gpu_backends() {
        let gpu = loads(backend);
        assert_eq!(gpu.len(), cpu.len(), "{backend}");
        // The same force and torque as the cpu step's to rounding grown over the impact
        // (measured on lavapipe: within 2e-3 of the largest).
        for (g, c) in gpu.iter().zip(&cpu) {
            assert_eq!(g[..2], c[..2], "{backend}: time and wall");
            for (x, y) in g[2..].iter().zip(&c[2..]) {
                assert!(
                    (x - y).abs() <= 1e-2 * largest,
                    "{backend}: {g:?} against the cpu's {c:?}"
                );
            }
        }
    }
    // Without the box walls spheres leave below the box: every backend runs it (its flows
    // remove them).
    for backend in gpu_backends() {
        let out = format!("no-box-{backend}");
        let args = [
            "simulate",
            "scene.toml",
            "-q",
            "-o",
            &out,
            "--set",
            "box_walls=false",
            "--steps",
            "10",
            "--backend",
            backend,
        ];
        let out = ok(&args, dir.path());
        assert!(out.contains("flows:"), "{backend}: {out}");
    }
    let e = fails(
        &["simulate", "scene.toml", "--set", "box_walls=maybe"],
        dir.path(),
    );
    assert!(e.contains("box_walls"), "{e}");
}

/// A scene of two materials (glass, steel: a pair given, the box walls steel) with an inflow of
/// steel spheres, started from `heap.csv`.
const TWO_MATERIALS: &str = r#"
scene = "input"
input = "heap.csv"
contact = "hertz-mindlin"
young_modulus = 1e5
box_lo = [0, 0, 0]
box_hi = [0.3, 0.3, 0.3]
frame_every = 40
csv = true
box_material = "steel"

[[material]]
name = "glass"
density = 2500
restitution = 0.9
friction = 0.3

[[material]]
name = "steel"
density = 7800
young_modulus = 3e5
restitution = 0.5

[[material_pair]]
materials = ["glass", "steel"]
friction = 0.2

[[inflow]]
lo = [0.05, 0.05, 0.2]
hi = [0.25, 0.25, 0.28]
rate = 200
sphere_radius = 0.008
material = "steel"
"#;

/// `heap.csv` of [`TWO_MATERIALS`]: 64 spheres thrown onto the floor, every third glass (0),
/// the others steel (1), by the file's `material` column; their materials.
fn two_material_heap(dir: &Path) -> Vec<u8> {
    let mut rows = String::from("x,y,z,r,vx,vy,vz,material\n");
    let mut materials = Vec::new();
    for k in 0..64 {
        let at = [k % 4, (k / 4) % 4, k / 16].map(|i| 0.0101 + 0.0199 * i as f32);
        let material = u8::from(k % 3 != 0);
        rows += &format!(
            "{},{},{},0.01,{},-0.05,-0.1,{material}\n",
            at[0],
            at[1],
            at[2],
            ((k % 3) as f32 - 1.0) * 0.1
        );
        materials.push(material);
    }
    std::fs::write(dir.join("heap.csv"), rows).unwrap();
    std::fs::write(dir.join("scene.toml"), TWO_MATERIALS).unwrap();
    materials
}

#[test]
fn a_two_material_run_from_a_csv_writes_each_spheres_material_and_resumes_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let file_materials = two_material_heap(dir.path());
    let run = |out: &str, steps: &str| {
        let args = [
            "simulate",
            "scene.toml",
            "--steps",
            steps,
            "--backend",
            "cpu",
            "-q",
            "-o",
            out,
        ];
        let (code, stdout, stderr) = mochi(&args, dir.path());
        assert_eq!(code, Some(0), "{stdout}\n{stderr}");
        stderr
    };
    let said = run("straight", "120");
    assert!(
        said.contains("| 2 materials: glass, steel (1 pair given) |")
            && said.contains("| friction up to 0.5 (walls up to 0.5)"),
        "{said}"
    );
    let end = checkpoint(dir.path(), "straight");
    assert_eq!(end.step, 120);
    let n = end.len();
    assert!(n > 64, "the inflow inserted no sphere ({n})");
    // The file's spheres keep their materials, the inflow's are steel.
    let mut expected = file_materials.clone();
    expected.resize(n, 1);
    assert_eq!(end.materials, expected);
    // Every frame carries them: the `.vtu`'s `material` array and the CSV's column.
    let out = dir.path().join("straight");
    for step in [0, 40, 80, 120] {
        for ext in ["vtu", "csv"] {
            let path = out.join(format!("frame_{step:08}.{ext}"));
            let frame = mochi::io::read_frame(&path).unwrap();
            assert_eq!(frame.materials, expected[..frame.radii.len()], "{path:?}");
        }
    }
    let csv = std::fs::read_to_string(out.join("frame_00000000.csv")).unwrap();
    assert!(
        csv.starts_with("x,y,z,r,vx,vy,vz,wx,wy,wz,material\n"),
        "{csv}"
    );
    // A run resumed from its checkpoint goes on as the uninterrupted one, materials and all.
    run("split", "50");
    let (code, stdout, stderr) = mochi(&strs(&resume_run("split", "120", &[])), dir.path());
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    let resumed = checkpoint(dir.path(), "split");
    assert!(resumed == end, "a resumed two-material run differs");
    assert_eq!(resumed.materials, end.materials);
    // A frame CSV restarts a run with its materials.
    let restart = [
        "simulate",
        "scene.toml",
        "--input",
        "straight/frame_00000120.csv",
        "--steps",
        "1",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "again",
    ];
    ok(&restart, dir.path());
    assert_eq!(checkpoint(dir.path(), "again").materials[..n], expected);
}

#[test]
fn gpu_runs_of_two_materials_resume_with_their_materials() {
    // The two-material heap with its steel inflow on each GPU backend: resumed at step 50, a run
    // ends at step 120 with the uninterrupted run's spheres, each of its own material (a GPU step
    // keeps it in its angular velocity rows: a resume that lost it would make glass steel, three
    // times as heavy, and put the heap far from the straight run's) and near its place.
    let dir = tempfile::tempdir().unwrap();
    let file_materials = two_material_heap(dir.path());
    for backend in gpu_backends() {
        let (straight, split) = (format!("{backend}-straight"), format!("{backend}-split"));
        let run = |out: &str, steps: &str| {
            let args = [
                "simulate",
                "scene.toml",
                "--steps",
                steps,
                "--frame-every",
                "0",
                "--backend",
                backend,
                "-q",
                "-o",
                out,
            ];
            ok(&args, dir.path());
        };
        run(&straight, "120");
        run(&split, "50");
        let resume = format!("{split}/checkpoint.bin");
        let args = [
            "simulate",
            "--resume",
            &resume,
            "--steps",
            "120",
            "--backend",
            backend,
            "-q",
            "-o",
            &split,
        ];
        ok(&args, dir.path());
        let (a, b) = (
            checkpoint(dir.path(), &straight),
            checkpoint(dir.path(), &split),
        );
        assert_eq!((a.step, b.step), (120, 120), "{backend}");
        assert!(a.len() > 64, "{backend}: the inflow inserted no sphere");
        assert_eq!(
            a.materials[..64],
            file_materials,
            "{backend}: the file's materials"
        );
        assert!(
            a.materials[64..].iter().all(|&m| m == 1),
            "{backend}: the inflow's spheres are steel"
        );
        assert_eq!(
            b.materials, a.materials,
            "{backend}: the resumed run's materials"
        );
        let gap = common::largest_gap(&a, &b);
        assert!(
            gap < 1e-4,
            "{backend}: the resumed run is {gap} m from the uninterrupted one"
        );
    }
}

#[test]
fn a_checkpoint_whose_sphere_has_a_material_the_scene_lacks_is_refused_on_resume() {
    // The checkpoint reads (its bytes are whole), but sphere 3's material 5 names no
    // [[material]] table of its scene: the resume says so and writes nothing.
    let dir = tempfile::tempdir().unwrap();
    two_material_heap(dir.path());
    let args = [
        "simulate",
        "scene.toml",
        "--steps",
        "5",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "run",
    ];
    ok(&args, dir.path());
    let path = dir.path().join("run/checkpoint.bin");
    let mut saved = read_checkpoint(&path).unwrap();
    saved.particles.materials[3] = 5;
    mochi::io::write_checkpoint(&path, &saved.particles, &saved.scene, &saved.state).unwrap();
    let before = snapshot(&dir.path().join("run"));
    let e = fails(&strs(&resume_run("run", "10", &[])), dir.path());
    assert!(
        e.contains("checkpoint.bin")
            && e.contains("sphere 3: material 5, but the scene has 2 materials"),
        "{e}"
    );
    assert_eq!(
        snapshot(&dir.path().join("run")),
        before,
        "the refused resume wrote nothing"
    );
}

#[test]
fn a_sphere_of_a_material_the_scene_lacks_is_refused_naming_the_file_and_sphere() {
    let dir = tempfile::tempdir().unwrap();
    two_material_heap(dir.path());
    let mut rows = std::fs::read_to_string(dir.path().join("heap.csv")).unwrap();
    rows += "0.25,0.25,0.25,0.01,0,0,0,2\n";
    std::fs::write(dir.path().join("three.csv"), rows).unwrap();
    let args = [
        "simulate",
        "scene.toml",
        "--input",
        "three.csv",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "out",
    ];
    let e = fails(&args, dir.path());
    assert!(
        e.contains("three.csv: sphere 64: material 2, but the scene has 2 materials"),
        "{e}"
    );
    assert!(!dir.path().join("out").exists());
    // Without [[material]] tables, every sphere must be of the one material.
    let args = [
        "simulate",
        "--input",
        "heap.csv",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "out",
    ];
    let e = fails(&args, dir.path());
    assert!(
        e.contains("heap.csv: sphere 1: material 1, but the scene has 1 material ("),
        "{e}"
    );
}

#[test]
fn print_scene_writes_the_scene_in_its_tables_and_that_scene_runs_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let given = [
        "--scene",
        "hopper",
        "-n",
        "200",
        "--set",
        "hopper_orifice=0.05",
        "--set",
        "friction=0.3",
    ];
    let mut args = vec!["simulate"];
    args.extend(given);
    args.push("--print-scene");
    let printed = ok(&args, dir.path());
    for expected in [
        "[source]\nscene = \"hopper\"\nspheres = 200\n",
        "orifice = 0.05\n",
        "[material]\ncontact = \"hertz-mindlin\"\n",
        "friction = 0.3\n",
        "dt = ",
    ] {
        assert!(printed.contains(expected), "{expected:?} in\n{printed}");
    }
    assert!(
        !dir.path().join("mochi-out").exists(),
        "--print-scene writes nothing"
    );
    std::fs::write(dir.path().join("printed.toml"), &printed).unwrap();
    let run = |first: &[&str], out: &str| {
        let mut args = vec!["simulate"];
        args.extend(first);
        args.extend([
            "--steps",
            "20",
            "--frame-every",
            "20",
            "--backend",
            "cpu",
            "-q",
            "-o",
            out,
        ]);
        ok(&args, dir.path());
        std::fs::read(dir.path().join(out).join("frame_00000020.vtu")).unwrap()
    };
    assert!(
        run(&given, "flags") == run(&["printed.toml"], "file"),
        "the printed scene runs as the flags do"
    );
}

#[test]
fn a_run_of_clumps_names_them_and_its_frames_carry_each_spheres_clump() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "simulate",
        "--scene",
        "gravel",
        "-n",
        "30",
        "--steps",
        "40",
        "--frame-every",
        "40",
        "-o",
        "out",
    ];
    let (code, _, stderr) = mochi(&args, dir.path());
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains("in 30 clumps ("), "{stderr}");
    let frame = std::fs::read(dir.path().join("out/frame_00000040.vtu")).unwrap();
    assert!(String::from_utf8_lossy(&frame).contains("Name=\"clump\""));
    // Beside each frame, its clumps: one point each, with its pose, in their own collection.
    let clumps = std::fs::read(dir.path().join("out/clumps_00000040.vtu")).unwrap();
    let text = String::from_utf8_lossy(&clumps);
    assert!(text.contains("NumberOfPoints=\"30\""), "{text}");
    for array in [
        "orientation",
        "velocity",
        "angular_velocity",
        "mass",
        "spheres",
        "kind",
    ] {
        assert!(text.contains(&format!("Name=\"{array}\"")), "{array}");
    }
    let index = std::fs::read_to_string(dir.path().join("out/clumps.pvd")).unwrap();
    assert!(index.contains("file=\"clumps_00000040.vtu\""), "{index}");
    let saved = read_checkpoint(&dir.path().join("out/checkpoint.bin")).unwrap();
    assert_eq!(saved.particles.clumps.clumps.len(), 30);
}

#[test]
fn one_of_several_mpi_processes_without_the_mpi_feature_is_refused_before_it_writes() {
    // As `mpirun -np 2 mochi simulate` starts it, in a build without the mpi feature (the
    // test build): each process would run the whole scene.
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(BIN)
        .args([
            "simulate", "--scene", "pour", "-n", "50", "--steps", "10", "-o", "run",
        ])
        .env("OMPI_COMM_WORLD_SIZE", "2")
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("built without the mpi feature"), "{stderr}");
    assert!(!dir.path().join("run").exists());
}

/// Every scene file of the guide's simulate chapter (its ```toml blocks) is one the tool takes as
/// written, with stand-ins for the files it names (a sphere file, meshes).
#[test]
fn the_guides_scene_files_load_as_written() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let guide = std::fs::read_to_string(root.join("docs/guide/simulate.md")).unwrap();
    let blocks: Vec<&str> = guide
        .split("```toml\n")
        .skip(1)
        .map(|rest| rest.split("```").next().expect("a closed block"))
        .collect();
    assert!(
        blocks.len() >= 5,
        "the chapter's scene files: {}",
        blocks.len()
    );
    let dir = tempfile::tempdir().unwrap();
    let mesh = root.join("tests/data/box_ascii.stl");
    for name in ["hopper.stl", "drum.stl"] {
        std::fs::copy(&mesh, dir.path().join(name)).unwrap();
    }
    std::fs::write(
        dir.path().join("spheres.csv"),
        "x,y,z,r,material\n0.3,0.3,0.1,0.004,0\n0.5,0.5,0.1,0.005,1\n",
    )
    .unwrap();
    for (k, block) in blocks.iter().enumerate() {
        let file = format!("scene_{k}.toml");
        std::fs::write(dir.path().join(&file), block).unwrap();
        let printed = ok(&["simulate", &file, "--print-scene"], dir.path());
        assert!(printed.contains("[source]"), "{block}\nprinted\n{printed}");
    }
}
