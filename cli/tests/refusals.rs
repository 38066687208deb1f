//! Inputs no run can use are refused up front with one error line that names the key and the
//! real reason, before anything is written: values single precision cannot hold, rates no
//! region can take, walls fast enough to pass through spheres, regions outside the box, meshes
//! that are not what they claim, and options that would be silently ignored.

mod common;

use common::cli::{fails, mochi, ok};
use std::path::Path;

/// Runs `mochi simulate SCENE` (a TOML text written to `dir/scene.toml`) on the cpu backend
/// for a few steps into `dir/out`, which must fail; its error line. Nothing may be written.
fn refused(dir: &Path, scene: &str, extra: &[&str]) -> String {
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    let mut args = vec![
        "simulate",
        "scene.toml",
        "--steps",
        "10",
        "--backend",
        "cpu",
        "-q",
        "-o",
        "out",
    ];
    args.extend(extra);
    let e = fails(&args, dir);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(!dir.join("out").exists(), "{e}");
    e
}

/// Eight spheres falling in the unit box under the linear law, and `more`.
fn scene(more: &str) -> String {
    format!("scene = \"freefall\"\nspheres = 8\ncontact = \"linear\"\n{more}")
}

/// An inflow over the middle of the box with `keys`.
fn inflow(keys: &str) -> String {
    scene(&format!(
        "[[inflow]]\nlo = [0.4, 0.4, 0.5]\nhi = [0.6, 0.6, 0.6]\nsphere_radius = 0.01\n{keys}"
    ))
}

#[test]
fn values_that_used_to_panic_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let e = refused(
        d,
        &scene(
            "[[inflow]]\nlo = [0.4, 0.4, 0.5]\nhi = [0.6, 0.6, 0.6]\nrate = 10\nsphere_radii = [0.003, 1e39]\n",
        ),
        &[],
    );
    assert!(
        e.contains("inflow 0: radii") && e.contains("single-precision"),
        "{e}"
    );
    let e = refused(
        d,
        &scene(
            "[[inflow]]\nlo = [-1e39, 0.4, 0.5]\nhi = [0.6, 0.6, 0.6]\nrate = 10\nsphere_radius = 0.01\n",
        ),
        &[],
    );
    assert!(e.contains("inflow 0") && e.contains("-1e39"), "{e}");
    let e = refused(d, "scene = \"mesh\"\nmesh_copies = 4294967295\n", &[]);
    assert!(e.contains("4294967295"), "{e}");
    let e = fails(&["bench", "--warmup", "18446744073709551615", "-q"], d);
    assert!(e.contains("--warmup") && e.contains("at most"), "{e}");
}

#[test]
fn inflows_are_bounded_by_their_region_and_the_box() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for rate in ["rate = 1e12", "rate = 1e300", "mass_rate = 1e30"] {
        let e = refused(d, &inflow(rate), &[]);
        assert!(e.contains("more than its region holds"), "{rate}: {e}");
    }
    let outside = scene(
        "[[inflow]]\nlo = [5.1, 0.1, 0.5]\nhi = [5.3, 0.3, 0.6]\nrate = 100\nsphere_radius = 0.01\n",
    );
    let e = refused(d, &outside, &[]);
    assert!(e.contains("not inside the box"), "{e}");
    let e = refused(d, &inflow("rate = 100\nstart = -1e300\n"), &[]);
    assert!(e.contains("start must be a finite time >= 0"), "{e}");
    // A rate a region cannot take at every flow event is capped there, with one warning.
    let capped = format!("flow_every = 50\n{}", inflow("rate = 2e5\n"));
    std::fs::write(d.join("scene.toml"), capped).unwrap();
    let args = [
        "simulate",
        "scene.toml",
        "--steps",
        "100",
        "--backend",
        "cpu",
        "-o",
        "capped",
    ];
    let (code, stdout, stderr) = mochi(&args, d);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        stderr.matches("owes more spheres per flow event").count(),
        1,
        "{stderr}"
    );
    let flows = stdout.lines().find(|l| l.starts_with("flows:")).unwrap();
    assert!(flows.contains(" refused"), "{flows}");
}

#[test]
fn walls_that_would_pass_through_spheres_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("plate.obj"),
        "v 0 0 0.9\nv 1 0 0.9\nv 1 1 0.9\nv 0 1 0.9\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let plate = |keys: &str| scene(&format!("[[wall]]\nmesh = \"plate.obj\"\n{keys}"));
    for speed in [
        "velocity = [0, 0, -500]",
        "velocity = [0, 0, -100]",
        "omega = 1e5",
    ] {
        let e = refused(d, &plate(speed), &[]);
        assert!(
            e.contains("wall 0") && e.contains("pass through"),
            "{speed}: {e}"
        );
    }
    for bad in ["omega = 1e39", "velocity = [1e39, 0, 0]", "friction = 1e39"] {
        let e = refused(d, &plate(bad), &[]);
        assert!(e.contains("wall 0"), "{bad}: {e}");
    }
    // The same plate, slow: it runs.
    std::fs::write(d.join("scene.toml"), plate("velocity = [0, 0, -0.5]")).unwrap();
    ok(
        &[
            "simulate",
            "scene.toml",
            "--steps",
            "10",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "slow",
        ],
        d,
    );
    for omega in ["1e5", "1e38"] {
        let e = refused(
            d,
            "scene = \"drum\"\nspheres = 200\n",
            &["--set", &format!("drum_omega={omega}")],
        );
        assert!(
            e.contains("drum") && e.contains("pass through"),
            "{omega}: {e}"
        );
    }
}

#[test]
fn refusals_name_the_key_and_the_real_reason() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (set, key) in [
        ("young_modulus=inf", "young_modulus"),
        ("density=0", "density"),
        ("density=-500", "density"),
        ("density=nan", "density"),
        ("rolling_friction=1e20", "rolling_friction"),
    ] {
        let e = refused(d, "scene = \"pour\"\nspheres = 100\n", &["--set", set]);
        assert!(e.contains(&format!("scene key {key}")), "{set}: {e}");
        assert!(!e.contains("time step"), "{set}: {e}");
    }
    // A sphere whose mass single precision cannot hold.
    std::fs::write(d.join("big.csv"), "x,y,z,r\n0,0,0,1e12\n3e12,0,0,1\n").unwrap();
    let e = fails(
        &[
            "simulate",
            "--input",
            "big.csv",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "b",
        ],
        d,
    );
    assert!(e.contains("largest radius this density allows"), "{e}");
    // Mesh coordinates whose squares single precision cannot hold.
    std::fs::write(
        d.join("huge.obj"),
        "v 0 0 0\nv 1e38 0 0\nv 0 1e38 0\nf 1 2 3\n",
    )
    .unwrap();
    let e = refused(d, &scene("[[wall]]\nmesh = \"huge.obj\"\n"), &[]);
    assert!(e.contains("beyond") && !e.contains("zero area"), "{e}");
    // Hoppers of few spheres or a wide orifice have room for their spheres.
    for set in ["spheres=200", "hopper_orifice=10"] {
        let args = [
            "simulate",
            "--scene",
            "hopper",
            "--set",
            set,
            "--steps",
            "1",
            "--backend",
            "cpu",
            "-q",
            "-o",
            set,
        ];
        ok(&args, d);
    }
}

#[test]
fn options_that_would_be_ignored_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (flag, value) in [
        ("--structure", "mlgrid"),
        ("--grid-build", "sorted"),
        ("--rebuild", "5"),
    ] {
        let e = refused(d, &scene(""), &[flag, value]);
        assert!(e.contains(&format!("{flag} is an option of the")), "{e}");
    }
    let e = fails(
        &[
            "detect",
            "--backend",
            "cpu",
            "--structure",
            "mlgrid",
            "-n",
            "100",
        ],
        d,
    );
    assert!(
        e.contains("--structure is an option of the wgpu-compute backend"),
        "{e}"
    );
    let e = refused(d, &scene(""), &["--renderer", "cpu"]);
    assert!(e.contains("--renderer is a picture option"), "{e}");
    let e = refused(d, &scene("flow_every = 10\n"), &[]);
    assert!(e.contains("scene key flow_every"), "{e}");
    let e = refused(
        d,
        "scene = \"pour\"\nspheres = 100\nrolling_friction = 0\nrolling_model = \"constant-torque\"\n",
        &[],
    );
    assert!(e.contains("scene key rolling_model"), "{e}");
    let (_, help, _) = mochi(&["simulate", "--help"], d);
    assert!(
        help.contains("`pour`: 4,000 spheres") && !help.contains("50,000"),
        "{help}"
    );
}

#[test]
fn meshes_that_are_not_what_they_claim_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A binary STL that declares one triangle and holds two.
    let mut stl = vec![0u8; 80];
    stl.extend(1u32.to_le_bytes());
    for t in 0..2u32 {
        stl.extend([0u8; 12]);
        for v in [
            [0.0f32, 0.0, t as f32],
            [1.0, 0.0, t as f32],
            [0.0, 1.0, t as f32],
        ] {
            v.iter().for_each(|x| stl.extend(x.to_le_bytes()));
        }
        stl.extend([0u8; 2]);
    }
    std::fs::write(d.join("two.stl"), &stl).unwrap();
    let e = refused(d, &scene("[[wall]]\nmesh = \"two.stl\"\n"), &[]);
    assert!(
        e.contains("declares 1 triangles") && e.contains("184 bytes"),
        "{e}"
    );
    // Meshes that enclose no volume are not filled: only zero-area triangles, an open plate.
    std::fs::write(d.join("zero.obj"), "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n").unwrap();
    std::fs::write(
        d.join("plate.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    for mesh in ["zero.obj", "plate.obj"] {
        let e = refused(
            d,
            "scene = \"mesh\"\n",
            &["--set", &format!("mesh=\"{mesh}\"")],
        );
        assert!(e.contains("closed surface"), "{mesh}: {e}");
        let bench = [
            "bench",
            "--experiments",
            "clustered",
            "--backends",
            "cpu",
            "--scale",
            "small",
            "--mesh",
            mesh,
            "-q",
            "--out",
            "bench-out",
        ];
        let e = fails(&bench, d);
        assert!(e.contains("closed surface"), "{mesh}: {e}");
    }
}
