//! What a run with mesh walls and flows writes, and what `mochi render` may write beside it:
//! nothing of a run or of an input is lost, the walls' and flows' files belong to the run, a
//! resumed run's logs and counts go on as the uninterrupted run's, a resumed run meets the
//! walls it had, and a saved scene names its files from any folder.

mod common;

use common::cli::{fails, mochi, ok, snapshot};
use std::path::Path;

/// A floor of two triangles under the unit box.
const FLOOR: &str = "v -0.5 -0.5 0\nv 1.5 -0.5 0\nv 1.5 1.5 0\nv -0.5 1.5 0\nf 1 2 3\nf 1 3 4\n";

/// A scene in `dir/sub/scene.toml`: eight spheres falling in the unit box onto `floor.obj`
/// (beside the scene, named relative to it) and a plate moving up through the box, with an
/// inflow adding spheres (`rate` a second) under the plate.
fn scene(dir: &Path, rate: u32) {
    let sub = dir.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    std::fs::write(sub.join("floor.obj"), FLOOR).unwrap();
    let mut csv = String::from("x,y,z,r\n");
    for k in 0..8 {
        csv += &format!("{},{},{},0.02\n", 0.2 + 0.08 * k as f64, 0.5, 0.3);
    }
    std::fs::write(sub.join("start.csv"), csv).unwrap();
    let text = format!(
        "scene = \"input\"\ninput = \"start.csv\"\ncontact = \"linear\"\nbox_lo = [0, 0, 0]\n\
         box_hi = [1, 1, 1]\ndt = 1e-4\nflow_every = 1\n\n[[wall]]\nmesh = \"floor.obj\"\n\n\
         [[wall]]\nmesh = \"floor.obj\"\nscale = 0.2\ntranslate = [0.4, 0.4, 0.9]\n\
         velocity = [0, 0, -0.5]\n\n[[inflow]]\nlo = [0.2, 0.2, 0.5]\nhi = [0.8, 0.8, 0.6]\n\
         rate = {rate}\nsphere_radius = 0.01\n"
    );
    std::fs::write(sub.join("scene.toml"), text).unwrap();
}

/// Runs the scene of [`scene`] from `dir` into `out` for `steps` steps, frames every 10.
fn run(dir: &Path, out: &str, steps: &str, extra: &[&str]) -> String {
    let mut args = vec![
        "simulate",
        "sub/scene.toml",
        "--steps",
        steps,
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
    ok(&args, dir)
}

#[test]
fn render_refuses_to_write_over_a_file_of_the_run_or_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, 1000);
    run(d, "rr", "20", &[]);
    let before = snapshot(&d.join("rr"));
    let floor = std::fs::read(d.join("sub/floor.obj")).unwrap();
    let refused: [&[&str]; 10] = [
        &["render", "rr", "--gif", "rr/checkpoint.bin"],
        &["render", "rr/frame_00000010.vtu", "-o", "rr/scene.toml"],
        &["render", "rr", "--gif", "rr/scene.toml"],
        &["render", "rr", "--gif", "rr/frame_00000010.csv"],
        &["render", "rr/frame_00000010.vtu", "-o", "rr/series.pvd"],
        &[
            "render",
            "rr/frame_00000010.vtu",
            "-o",
            "rr/frame_00000020.vtu",
        ],
        &["render", "rr/frame_00000010.vtu", "-o", "rr/walls.csv"],
        &["render", "rr", "--gif", "rr/wall_00000010_1.vtp"],
        &["render", "rr", "--gif", "sub/floor.obj"],
        &["render", "rr/frame_00000010.vtu", "-o", "sub/start.csv"],
    ];
    for args in refused {
        let e = fails(args, d);
        assert_eq!(e.lines().count(), 1, "{args:?}: {e}");
        assert_eq!(snapshot(&d.join("rr")), before, "{args:?}");
    }
    assert_eq!(std::fs::read(d.join("sub/floor.obj")).unwrap(), floor);
    // A frame's own picture is what render writes.
    let out = ok(&["render", "rr/frame_00000010.vtu"], d);
    assert!(out.contains("wall triangles"), "{out}");
    assert!(d.join("rr/frame_00000010.png").is_file());
    // A folder as -o takes the frame's picture; a series' index stands for its folder; a
    // folder as --gif is refused before anything is drawn.
    std::fs::create_dir(d.join("pictures")).unwrap();
    ok(
        &[
            "render",
            "rr/frame_00000020.vtu",
            "-o",
            "pictures",
            "--size",
            "64x48",
        ],
        d,
    );
    assert!(d.join("pictures/frame_00000020.png").is_file());
    let out = ok(
        &["render", "rr/series.pvd", "-o", "all", "--size", "64x48"],
        d,
    );
    assert!(out.contains("3 frames"), "{out}");
    let e = fails(&["render", "rr", "-o", "drawn", "--gif", "pictures"], d);
    assert!(e.contains("--gif pictures is a folder"), "{e}");
    assert!(!d.join("drawn").exists());
}

#[test]
fn the_walls_and_flows_files_belong_to_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, 1000);
    run(d, "out", "20", &[]);
    let names: Vec<String> = snapshot(&d.join("out")).into_iter().map(|f| f.0).collect();
    for name in [
        "walls.pvd",
        "walls.csv",
        "flow.csv",
        "wall_0.vtp",
        "wall_00000020_1.vtp",
    ] {
        assert!(names.contains(&name.to_owned()), "{name}: {names:?}");
    }
    // The floor never moves: one file for every frame. The plate: one a frame.
    assert!(
        !names
            .iter()
            .any(|n| n.starts_with("wall_000") && n.ends_with("_0.vtp"))
    );
    let index = std::fs::read_to_string(d.join("out/walls.pvd")).unwrap();
    assert_eq!(index.matches(r#"file="wall_0.vtp""#).count(), 3, "{index}");
    assert!(
        index.contains(r#"part="1" file="wall_00000010_1.vtp""#),
        "{index}"
    );

    // A scene file named as a log in the output folder is not overwritten by it.
    let text = std::fs::read_to_string(d.join("sub/scene.toml")).unwrap();
    let abs = text.replace("\"start.csv\"", &format!("{:?}", d.join("sub/start.csv")));
    let abs = abs.replace("\"floor.obj\"", &format!("{:?}", d.join("sub/floor.obj")));
    std::fs::create_dir(d.join("mine")).unwrap();
    std::fs::write(d.join("mine/walls.csv"), &abs).unwrap();
    let args = [
        "simulate",
        "mine/walls.csv",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "mine",
    ];
    for extra in [None, Some("--overwrite")] {
        let mut args = args.to_vec();
        args.extend(extra);
        let e = fails(&args, d);
        assert!(e.contains("walls.csv"), "{e}");
        assert_eq!(
            std::fs::read_to_string(d.join("mine/walls.csv")).unwrap(),
            abs
        );
    }

    // --overwrite leaves nothing of the walls and flows of the run before.
    let pour = [
        "simulate",
        "--scene",
        "freefall",
        "-n",
        "8",
        "--steps",
        "10",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "out",
        "--overwrite",
    ];
    ok(&pour, d);
    let names: Vec<String> = snapshot(&d.join("out")).into_iter().map(|f| f.0).collect();
    assert!(
        !names
            .iter()
            .any(|n| n.starts_with("wall") || n == "flow.csv"),
        "{names:?}"
    );
}

#[test]
fn a_resumed_run_logs_and_counts_its_flows_as_the_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, 3000);
    let whole = run(d, "straight", "60", &[]);
    // Stopped at step 25, between two frames, and resumed.
    run(d, "split", "25", &[]);
    let resumed = ok(
        &[
            "simulate",
            "--resume",
            "split/checkpoint.bin",
            "--steps",
            "60",
            "-q",
        ],
        d,
    );
    let read = |path: &str| std::fs::read_to_string(d.join(path)).unwrap();
    for log in ["flow.csv", "walls.csv", "walls.pvd", "series.pvd"] {
        assert_eq!(
            read(&format!("straight/{log}")),
            read(&format!("split/{log}")),
            "{log}"
        );
    }
    let flows = |out: &str| {
        let line = out
            .lines()
            .find(|l| l.starts_with("flows:"))
            .unwrap()
            .to_owned();
        line.split(';').next().unwrap().to_owned()
    };
    assert_eq!(flows(&resumed), flows(&whole));
    // The inflow inserted spheres in every frame's interval.
    let inserted: Vec<u64> = read("straight/flow.csv")
        .lines()
        .skip(2)
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    assert!(inserted.iter().all(|&k| k > 0), "{inserted:?}");
}

#[test]
fn a_resumed_run_refuses_a_wall_mesh_that_changed_since_it_started() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, 1000);
    run(d, "out", "20", &[]);
    let resume = [
        "simulate",
        "--resume",
        "out/checkpoint.bin",
        "--steps",
        "30",
        "-q",
    ];
    let moved = FLOOR.replace("v 1.5 1.5 0", "v 1.5 1.5 0.1");
    std::fs::write(d.join("sub/floor.obj"), moved).unwrap();
    let before = snapshot(&d.join("out"));
    let e = fails(&resume, d);
    assert!(
        e.contains("floor.obj") && e.contains("changed since the run started"),
        "{e}"
    );
    assert_eq!(snapshot(&d.join("out")), before);
    std::fs::write(d.join("sub/floor.obj"), FLOOR).unwrap();
    ok(&resume, d);
}

#[test]
fn a_saved_scene_names_its_files_from_any_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, 1000);
    run(d, "out", "20", &[]);
    let saved = std::fs::read_to_string(d.join("out/scene.toml")).unwrap();
    let floor = d.join("sub/floor.obj");
    assert!(saved.contains(&format!("mesh = {:?}", floor)), "{saved}");
    // Rendered and resumed from another folder, the run meets its walls.
    let elsewhere = d.join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let out = ok(&["render", "../out/frame_00000020.vtu"], &elsewhere);
    assert!(out.contains("with 4 wall triangles"), "{out}");
    let (code, _, e) = mochi(
        &[
            "simulate",
            "--resume",
            "../out/checkpoint.bin",
            "--steps",
            "30",
            "-q",
        ],
        &elsewhere,
    );
    assert_eq!(code, Some(0), "{e}");
}
