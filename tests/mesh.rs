//! Meshes: loading every format (and refusing broken files without panicking), the winding
//! number, and filling with spheres (count, placement, no overlaps, holes, errors).

use mochi::mesh::{
    FillSpec, MAX_LATTICE_POINTS, Mesh, WindingTree, fill, load, load_bytes, torus, winding_number,
};
use mochi::{Error, SphereSet};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

const MAJOR: f64 = 1.0;
const MINOR: f64 = 0.4;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn ring() -> Mesh {
    torus(MAJOR, MINOR, 96, 48)
}

/// Squared distance from p to the centre circle of the analytic torus.
fn tube_distance2(p: [f64; 3]) -> f64 {
    let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
    (rho - MAJOR).powi(2) + p[2] * p[2]
}

fn spec(spacing: f64, radii: Vec<(f32, f64)>, jitter: bool, seed: u64) -> FillSpec {
    FillSpec {
        spacing,
        radii,
        jitter,
        seed,
    }
}

/// Signed volume by the divergence theorem: positive for outward-facing triangles.
fn signed_volume(m: &Mesh) -> f64 {
    m.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| m.vertices[i as usize]);
            (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]))
                / 6.0
        })
        .sum()
}

// ---------------------------------------------------------------------------------------------
// The torus and the winding number

#[test]
fn torus_is_watertight_and_faces_outward() {
    let m = ring();
    assert_eq!(m.vertices.len(), 96 * 48);
    assert_eq!(m.triangles.len(), 2 * 96 * 48);
    // Every directed edge once, and its reverse once: closed and consistently oriented.
    let mut edges = std::collections::HashSet::new();
    for t in &m.triangles {
        for k in 0..3 {
            assert!(edges.insert((t[k], t[(k + 1) % 3])), "edge used twice");
        }
    }
    assert!(edges.iter().all(|&(a, b)| edges.contains(&(b, a))));
    let exact = 2.0 * PI * PI * MAJOR * MINOR * MINOR;
    let v = signed_volume(&m);
    assert!((v - exact).abs() < 0.01 * exact, "volume {v} vs {exact}");
}

#[test]
fn winding_number_is_one_inside_and_zero_outside_the_torus() {
    let m = ring();
    let mut rng = Pcg64::seed_from_u64(7);
    for _ in 0..200 {
        // Inside: within 0.8·MINOR of the centre circle.
        let (u, v): (f64, f64) = (
            rng.random_range(0.0..2.0 * PI),
            rng.random_range(0.0..2.0 * PI),
        );
        let s = rng.random_range(0.0..0.8 * MINOR);
        let rho = MAJOR + s * v.cos();
        let p = [rho * u.cos(), rho * u.sin(), s * v.sin()];
        let w = winding_number(&m, p);
        assert!((w - 1.0).abs() < 1e-9, "inside {p:?}: {w}");
    }
    for p in [
        [0.0; 3],
        [0.0, 0.0, 0.5],
        [3.0, 0.0, 0.0],
        [0.5, 0.5, 0.45],
        [-1.0, 0.0, 0.5],
    ] {
        let w = winding_number(&m, p);
        assert!(w.abs() < 1e-9, "outside {p:?}: {w}");
    }
}

#[test]
fn tree_agrees_with_the_exact_winding_number() {
    let m = ring();
    let tree = WindingTree::new(&m);
    let mut rng = Pcg64::seed_from_u64(3);
    let mut worst: f64 = 0.0;
    for _ in 0..300 {
        let p = [
            rng.random_range(-1.6..1.6),
            rng.random_range(-1.6..1.6),
            rng.random_range(-0.6..0.6),
        ];
        let (fast, exact) = (tree.winding_number(p), winding_number(&m, p));
        worst = worst.max((fast - exact).abs());
        assert_eq!(tree.contains(p), exact >= 0.5, "{p:?}: {fast} vs {exact}");
    }
    assert!(worst < 0.05, "largest error {worst}");
}

// ---------------------------------------------------------------------------------------------
// Filling

#[test]
fn torus_fill_matches_its_volume_and_stays_inside() {
    let m = ring();
    let s = 0.05;
    let (centers, radii) = fill(&m, &spec(s, vec![(0.02, 1.0)], false, 1)).unwrap();
    let expected = 2.0 * PI * PI * MAJOR * MINOR * MINOR / (s * s * s);
    let n = centers.len() as f64;
    assert!(
        (n - expected).abs() < 0.02 * expected,
        "{n} spheres, volume/spacing³ = {expected:.0}"
    );
    assert!(radii.iter().all(|&x| x == 0.02));
    // The mesh's chords can cut the exact torus by their sagitta, far below 1e-3.
    let limit = (MINOR + 1e-3) * (MINOR + 1e-3);
    for c in &centers {
        let p = c.map(f64::from);
        assert!(tube_distance2(p) <= limit, "{p:?} outside the torus");
    }
    // Jitter moves the same lattice points, each within its own cell.
    let (jittered, _) = fill(&m, &spec(s, vec![(0.02, 1.0)], true, 1)).unwrap();
    assert_eq!(jittered.len(), centers.len());
    let room = (0.5 * s - 0.02) as f32 + 1e-6;
    for (a, b) in jittered.iter().zip(&centers) {
        assert!(
            (0..3).all(|k| (a[k] - b[k]).abs() <= room),
            "{a:?} left its cell {b:?}"
        );
    }
    assert_ne!(jittered, centers);
    // Turned inside out (every triangle reversed), it fills the same points.
    let mut inverted = m.clone();
    for t in &mut inverted.triangles {
        t.swap(1, 2);
    }
    assert!((winding_number(&inverted, [MAJOR, 0.0, 0.0]) + 1.0).abs() < 1e-9);
    let (same, _) = fill(&inverted, &spec(s, vec![(0.02, 1.0)], false, 1)).unwrap();
    assert_eq!(same, centers);
}

#[test]
fn jittered_mixed_fill_has_no_overlaps_and_follows_the_weights() {
    let m = ring();
    let mix = vec![(0.048, 1.0), (0.024, 3.0)];
    let (centers, radii) = fill(&m, &spec(0.1, mix.clone(), true, 42)).unwrap();
    // Neither jitter nor the radius mix changes which lattice points are inside.
    let (points, _) = fill(&m, &spec(0.1, vec![(0.048, 1.0)], false, 7)).unwrap();
    assert_eq!(centers.len(), points.len());
    let small = radii.iter().filter(|&&x| x == 0.024).count() as f64 / radii.len() as f64;
    assert!((small - 0.75).abs() < 0.03, "small fraction {small}");
    let set = SphereSet::new(centers.clone(), radii.clone()).unwrap();
    assert_eq!(mochi::oracle::brute_force_pairs(&set), vec![]);
    // Seeded: the same seed gives the same spheres, another seed others.
    let again = fill(&m, &spec(0.1, mix.clone(), true, 42)).unwrap();
    assert_eq!(again, (centers.clone(), radii));
    let other = fill(&m, &spec(0.1, mix, true, 43)).unwrap();
    assert_ne!(other.0, centers);
}

#[test]
fn a_torus_with_a_hole_fills_essentially_the_same_points() {
    let whole = ring();
    let mut holed = whole.clone();
    // Cut out a 3 × 3 patch of quads on the outer equator (18 triangles): a hole about
    // 0.27 × 0.16, three to five lattice spacings across.
    let nt = 48;
    let cut: Vec<usize> = (0..3)
        .flat_map(|i| (0..3).map(move |j| i * nt + (nt - 1 + j) % nt))
        .flat_map(|q| [2 * q, 2 * q + 1])
        .collect();
    holed.triangles = holed
        .triangles
        .iter()
        .enumerate()
        .filter(|(t, _)| !cut.contains(t))
        .map(|(_, t)| *t)
        .collect();
    assert_eq!(holed.triangles.len(), whole.triangles.len() - 18);
    let s = spec(0.05, vec![(0.02, 1.0)], false, 1);
    let (a, _) = fill(&whole, &s).unwrap();
    let (b, _) = fill(&holed, &s).unwrap();
    let key = |c: &[f32; 3]| c.map(f32::to_bits);
    let a_set: std::collections::HashSet<_> = a.iter().map(key).collect();
    let b_set: std::collections::HashSet<_> = b.iter().map(key).collect();
    let differ = a_set.symmetric_difference(&b_set).count();
    assert!(
        differ as f64 <= 0.001 * a.len() as f64,
        "{differ} of {} points differ",
        a.len()
    );
    // The winding number in the middle of the tube behind the hole is still close to 1.
    let w = winding_number(&holed, [MAJOR, 0.0, 0.0]);
    assert!(w > 0.9, "{w}");
}

#[test]
fn fill_refuses_bad_specs_with_errors() {
    let m = ring();
    let bad = [
        spec(0.0, vec![(0.01, 1.0)], true, 0),
        spec(-0.1, vec![(0.01, 1.0)], true, 0),
        spec(f64::NAN, vec![(0.01, 1.0)], true, 0),
        spec(f64::INFINITY, vec![(0.01, 1.0)], true, 0),
        spec(0.1, vec![(0.051, 1.0)], true, 0),
        spec(0.1, vec![], true, 0),
        spec(0.1, vec![(0.01, 0.0)], true, 0),
        spec(0.1, vec![(0.01, -1.0)], true, 0),
        spec(0.1, vec![(0.01, f64::NAN)], true, 0),
        spec(0.1, vec![(0.01, 1e308), (0.02, 1e308)], true, 0),
        spec(0.1, vec![(0.0, 1.0)], true, 0),
        spec(0.1, vec![(f32::NAN, 1.0)], true, 0),
    ];
    for s in &bad {
        match fill(&m, s) {
            Err(Error::InvalidConfig { what, reason }) => {
                assert_eq!(what, "mesh fill");
                assert!(!reason.is_empty());
            }
            other => panic!("{s:?}: {other:?}"),
        }
    }
    // 2·r = spacing just fits.
    assert!(fill(&m, &spec(0.1, vec![(0.05, 1.0)], true, 0)).is_ok());
    // Too many lattice points: the count and the limit are reported.
    match fill(&m, &spec(1e-4, vec![(1e-5, 1.0)], true, 0)) {
        Err(e @ Error::TooLarge { got, limit, .. }) => {
            assert_eq!(limit, MAX_LATTICE_POINTS);
            assert!(got > limit);
            assert!(e.to_string().contains("raise the spacing"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    // Invalid meshes are refused too.
    let mut broken = m.clone();
    broken.triangles.push([0, 1, 999_999]);
    assert!(matches!(
        fill(&broken, &spec(0.1, vec![(0.01, 1.0)], true, 0)),
        Err(Error::InvalidConfig { .. })
    ));
    broken = m.clone();
    broken.vertices[5][1] = f64::NAN;
    assert!(matches!(
        fill(&broken, &spec(0.1, vec![(0.01, 1.0)], true, 0)),
        Err(Error::InvalidConfig { .. })
    ));
    assert!(matches!(
        fill(&Mesh::default(), &spec(0.1, vec![(0.01, 1.0)], true, 0)),
        Err(Error::InvalidConfig { .. })
    ));
}

#[test]
fn fitted_keeps_the_aspect_ratio_and_centres_the_mesh() {
    let m = ring().fitted([0.0, 0.0, 0.0], [1.0, 2.0, 1.0]);
    let (lo, hi) = m.bounds().unwrap();
    // 2.8 × 2.8 × 0.8 scaled by 1/2.8: x fills the box, y is centred, z keeps its ratio.
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
    assert!(close(lo[0], 0.0) && close(hi[0], 1.0), "{lo:?} {hi:?}");
    assert!(close(lo[1], 0.5) && close(hi[1], 1.5), "{lo:?} {hi:?}");
    assert!(close(hi[2] - lo[2], 0.8 / 2.8) && close(lo[2] + hi[2], 1.0));
    assert_eq!(Mesh::default().bounds(), None);
    assert_eq!(Mesh::default().fitted([0.0; 3], [1.0; 3]), Mesh::default());
}

// ---------------------------------------------------------------------------------------------
// Loading

/// Triangles as corner coordinates, each rotated to start at its smallest corner (orientation
/// kept), sorted: equal for equal meshes whatever the vertex numbering.
fn canonical(m: &Mesh) -> Vec<[[u64; 3]; 3]> {
    let mut out: Vec<[[u64; 3]; 3]> = m
        .triangles
        .iter()
        .map(|t| {
            let c = t.map(|i| m.vertices[i as usize].map(f64::to_bits));
            let k = (0..3).min_by_key(|&k| c[k]).unwrap();
            [c[k], c[(k + 1) % 3], c[(k + 2) % 3]]
        })
        .collect();
    out.sort();
    out
}

#[test]
fn every_format_loads_to_the_same_box() {
    let files = [
        "box.obj",
        "box_ascii.ply",
        "box_binary_le.ply",
        "box_binary_be.ply",
        "box_ascii.stl",
        "box_binary.stl",
    ];
    let reference = load(&data(files[0])).unwrap();
    assert_eq!(reference.triangles.len(), 12);
    assert_eq!(reference.vertices.len(), 8);
    let volume = signed_volume(&reference);
    assert!((volume - 1.75 * 2.0 * 0.75).abs() < 1e-12, "{volume}");
    for f in &files[1..] {
        let m = load(&data(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert_eq!(canonical(&m), canonical(&reference), "{f}");
    }
    // The extension is case-insensitive.
    let dir = tempfile::tempdir().unwrap();
    let upper = dir.path().join("BOX.Obj");
    std::fs::copy(data("box.obj"), &upper).unwrap();
    assert_eq!(load(&upper).unwrap(), reference);
    // And the box fills like a box: 1.75 × 2 × 0.75 at spacing 0.25 is 7 × 8 × 3.
    let (c, _) = fill(&reference, &spec(0.25, vec![(0.1, 1.0)], true, 0)).unwrap();
    assert_eq!(c.len(), 7 * 8 * 3);
}

/// Expects a parse error for `path` and returns its line and message.
fn parse_error(path: &Path) -> (Option<u64>, String) {
    match load(path) {
        Err(Error::Parse { path: p, line, msg }) => {
            assert_eq!(p, path);
            (line, msg)
        }
        other => panic!("{}: expected a parse error, got {other:?}", path.display()),
    }
}

#[test]
fn broken_fixtures_are_parse_errors() {
    let (line, msg) = parse_error(&data("truncated.stl"));
    assert_eq!(line, None);
    assert!(
        msg.contains("declares 12 triangles") && msg.contains("351"),
        "{msg}"
    );
    let (line, msg) = parse_error(&data("bad_index.obj"));
    assert_eq!(line, Some(5), "{msg}");
    assert!(
        msg.contains("vertex 9") && msg.contains("3 vertices"),
        "{msg}"
    );
    let (line, msg) = parse_error(&data("missing_property.ply"));
    assert_eq!(line, Some(4), "{msg}");
    assert!(msg.contains("`z`"), "{msg}");
    let (_, msg) = parse_error(&data("empty.obj"));
    assert!(msg.contains("empty"), "{msg}");
    let (_, msg) = parse_error(&data("box.xyz"));
    assert!(msg.contains("unknown mesh format `.xyz`"), "{msg}");
}

/// Writes `content` to a file named `name` in a fresh folder and loads it.
fn load_text(dir: &Path, name: &str, content: &[u8]) -> (Option<u64>, String) {
    let path = dir.join(name);
    std::fs::write(&path, content).unwrap();
    parse_error(&path)
}

#[test]
fn broken_files_of_every_format_say_what_and_where() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases: Vec<(&str, Vec<u8>, Option<u64>, &str)> = vec![
        (
            "a.obj",
            format!("{tri}v nan 0 0\nf 1 2 3\n").into(),
            Some(4),
            "not finite",
        ),
        (
            "b.obj",
            format!("{tri}v 1 x 2\nf 1 2 3\n").into(),
            Some(4),
            "position",
        ),
        (
            "c.obj",
            format!("{tri}f 1 2\n").into(),
            Some(4),
            "at least 3",
        ),
        (
            "d.obj",
            format!("{tri}f 0 1 2\n").into(),
            Some(4),
            "vertex 0",
        ),
        (
            "e.obj",
            format!("{tri}f -4 1 2\n").into(),
            Some(4),
            "vertex -4",
        ),
        (
            "f.obj",
            format!("{tri}f 1 2 three\n").into(),
            Some(4),
            "face",
        ),
        ("g.obj", tri.into(), None, "no triangles"),
        (
            "h.obj",
            b"\xff\xfe garbage\n".to_vec(),
            None,
            "no triangles",
        ),
        (
            "a.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
              end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"
                .to_vec(),
            Some(13),
            "vertex 3",
        ),
        (
            "b.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
              end_header\n0 0 0\n1 0 1e39\n0 1 0\n3 0 1 2\n"
                .to_vec(),
            Some(11),
            "not finite",
        ),
        (
            "c.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
              end_header\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n"
                .to_vec(),
            Some(13),
            "at least 3",
        ),
        (
            "d.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nelement face 1\nproperty list uchar float vertex_indices\n\
              end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
                .to_vec(),
            Some(7),
            "list of integers",
        ),
        (
            "e.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
                .to_vec(),
            None,
            "element face",
        ),
        (
            "f.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
              end_header\n0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"
                .to_vec(),
            Some(11),
            "",
        ),
        (
            "g.ply",
            b"plyx\nformat ascii 1.0\n".to_vec(),
            Some(1),
            "magic",
        ),
        (
            "h.ply",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
              property float y\nproperty float z\nelement face 1\n\
              property list uchar int vertex_indices\nend_header\n\0\0\0\0\0\0"
                .to_vec(),
            None,
            "end of file",
        ),
        (
            "a.stl",
            b"solid x\nfacet normal 0 0 0\nouter loop\nvertex 1 2\n".to_vec(),
            None,
            "ASCII",
        ),
        (
            "b.stl",
            b"solid x\nendsolid x\n".to_vec(),
            None,
            "no triangles",
        ),
        ("c.stl", b"not an stl".to_vec(), None, "too short"),
        ("d.stl", b"solid".to_vec(), None, "ASCII"),
    ];
    for (name, content, want_line, want_msg) in cases {
        let (line, msg) = load_text(d, name, &content);
        assert_eq!(line, want_line, "{name}: {msg}");
        assert!(msg.contains(want_msg), "{name}: `{msg}` lacks `{want_msg}`");
        assert!(!msg.contains('\n'), "{name}: `{msg}`");
    }
    // A binary STL with a NaN coordinate.
    let mut stl = std::fs::read(data("box_binary.stl")).unwrap();
    stl[84 + 50 * 3 + 12..84 + 50 * 3 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
    let (_, msg) = load_text(d, "nan.stl", &stl);
    assert!(
        msg.contains("triangle 3") && msg.contains("non-finite"),
        "{msg}"
    );
    // A missing file is an I/O error.
    assert!(matches!(
        load(&d.join("missing.obj")),
        Err(Error::Io { .. })
    ));
}

#[test]
fn cut_or_corrupted_files_never_panic() {
    let mut rng = Pcg64::seed_from_u64(11);
    for name in [
        "box.obj",
        "box_ascii.ply",
        "box_binary_le.ply",
        "box_binary_be.ply",
        "box_ascii.stl",
        "box_binary.stl",
    ] {
        let bytes = std::fs::read(data(name)).unwrap();
        let name = Path::new(name);
        for len in 0..bytes.len() {
            if let Ok(m) = load_bytes(name, &bytes[..len]) {
                assert!(m.validate().is_ok(), "{name:?}: loaded an invalid mesh");
            }
        }
        for _ in 0..1000 {
            let mut b = bytes.clone();
            for _ in 0..rng.random_range(1..4) {
                let at = rng.random_range(0..b.len());
                b[at] = rng.random_range(0..=255u8);
            }
            if let Ok(m) = load_bytes(name, &b) {
                assert!(m.validate().is_ok(), "{name:?}: loaded an invalid mesh");
            }
        }
    }
}
