//! `mochi bench` end to end at a tiny scale: every experiment gets a Markdown table, the JSON
//! parses back with numbers that agree with each other and with the brute-force oracle, and the
//! SVG plots are written. On the cpu backend, and on wgpu-compute where an adapter exists
//! (lavapipe in CI, where a missing adapter fails). No timing assertions: speed belongs in
//! benchmarks.

mod common;

use mochi::dem::Clock;
use mochi_cli::bench::plan::Experiment;
use mochi_cli::bench::report::{DemRow, DetectRow, Report, SCHEMA_VERSION, pairs_digest};
use mochi_cli::bench::stats::Spread;

use mochi::gpu::Need;
use mochi::oracle::brute_force_pairs;
use mochi::scenes::{Layout, Scene, SceneSpec, generate};
use std::path::Path;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_mochi");
/// Spheres of experiments 1–4: enough for poly120 to have a few pairs, few for the oracle.
const N: usize = 10_000;
const REPEATS: usize = 2;
const STEPS: u32 = 2;
/// The head of the report's table of performance targets, met or not.
const TARGETS_TABLE: &str = "\n## Performance targets\n\n| target | measured | met |\n";

fn mochi(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(BIN)
        .args(args)
        .output()
        .expect("the binary runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn assert_spread(s: &Spread, what: &str) {
    assert_eq!(s.samples, REPEATS, "{what}");
    assert!(
        s.min >= 0.0 && s.min <= s.q1 && s.q1 <= s.median && s.median <= s.q3 && s.q3 <= s.max,
        "{what}: {s:?}"
    );
}

fn scene_of(name: &str) -> Scene {
    use clap::ValueEnum;
    Scene::from_str(name, false).expect("a scene name from the report")
}

fn check_detect(rows: &[DetectRow], backends: &[&str]) {
    assert_eq!(
        rows.len(),
        6 * backends.len(),
        "3 scenes × 2 modes per backend"
    );
    let mut pairs_seen = 0;
    for scene in ["poly1.2", "poly12", "poly120"] {
        let spheres = generate(&SceneSpec {
            scene: scene_of(scene),
            n: N,
            seed: 1,
            layout: Layout::Random,
        })
        .unwrap();
        let oracle = brute_force_pairs(&spheres);
        pairs_seen += oracle.len();
        for backend in backends {
            let of = |mode: &str| {
                rows.iter()
                    .find(|r| {
                        r.backend.name() == *backend
                            && r.scene.name() == scene
                            && r.mode.name() == mode
                    })
                    .unwrap_or_else(|| panic!("no {backend} {scene} {mode} row"))
            };
            let (mochi, nns) = (of("mochi"), of("nns"));
            for row in [mochi, nns] {
                let what = format!("{backend} {scene} {}", row.mode.name());
                assert_eq!(row.n, N, "{what}");
                assert_eq!(row.layout, Layout::Random, "{what}");
                assert_eq!(row.pairs, oracle.len() as u64, "{what}: pairs = oracle");
                assert_eq!(
                    row.pairs_digest,
                    pairs_digest(&oracle),
                    "{what}: same pairs"
                );
                assert!(row.candidates >= row.pairs, "{what}");
                let per = row.candidates as f64 / N as f64;
                assert!((row.candidates_per_sphere - per).abs() < 1e-9, "{what}");
                for (s, part) in [(&row.build_ms, "build"), (&row.detect_ms, "detect")] {
                    assert_spread(s, &format!("{what} {part}"));
                }
                assert_spread(&row.total_ms, &what);
                assert_spread(&row.wall_total_ms, &what);
                if *backend == "cpu" {
                    assert_eq!(row.clock, Clock::Wall, "{what}");
                    assert_eq!(row.speedup_vs_cpu, None, "{what}");
                } else {
                    let cpu = rows
                        .iter()
                        .find(|r| {
                            r.backend.name() == "cpu"
                                && r.scene.name() == scene
                                && r.mode == row.mode
                        })
                        .expect("a cpu row");
                    let want = cpu.total_ms.median / row.total_ms.median;
                    assert!((row.speedup_vs_cpu.unwrap() - want).abs() < 1e-9, "{what}");
                }
            }
            let want = nns.detect_ms.median / mochi.detect_ms.median;
            assert!((mochi.detect_speedup_vs_nns.unwrap() - want).abs() < 1e-9);
            assert_eq!(nns.detect_speedup_vs_nns, None);
        }
    }
    assert!(pairs_seen > 0, "the scenes should have pairs to check");
}

fn check_dem(rows: &[DemRow], backends: &[&str]) {
    let expect = [
        (Experiment::Freefall, "freefall", vec![N]),
        (Experiment::Rotating, "rotating", vec![N]),
        (Experiment::Rebuild, "freefall", vec![N]),
        (Experiment::Scaling, "freefall", vec![1000, 10_000]),
    ];
    let mut count = 0;
    for (experiment, scene, sizes) in expect {
        for backend in backends {
            for &n in &sizes {
                let what = format!("{experiment:?} {backend} n={n}");
                let row = rows
                    .iter()
                    .find(|r| {
                        r.experiment == experiment && r.backend.name() == *backend && r.n == n
                    })
                    .unwrap_or_else(|| panic!("no row for {what}"));
                count += 1;
                assert_eq!(row.scene.name(), scene, "{what}");
                assert_eq!(row.mode.name(), "mochi", "{what}");
                assert_eq!(row.steps, STEPS, "{what}");
                // From the start, one run continuing the last: 1 warm-up run, then the timed.
                assert_eq!(row.dt, Some(1e-4), "{what}");
                assert_eq!(row.settled, 0, "{what}");
                let timed = row.timed.expect("a DEM row says the steps it timed");
                assert_eq!(
                    (timed.from, timed.to, timed.each_run),
                    (STEPS as u64, (1 + REPEATS as u64) * STEPS as u64, false),
                    "{what}"
                );
                // No backend here refits (only a future OptiX step will): one row each.
                assert!(!row.refits, "{what}");
                assert_eq!(row.rebuild, "every step", "{what}");
                for s in [&row.build_ms, &row.dcd_ms, &row.update_ms, &row.total_ms] {
                    assert_spread(s, &what);
                }
                assert!(row.total_ms.median > 0.0, "{what}");
                if *backend == "cpu" {
                    assert_eq!(row.clock, Clock::Wall, "{what}");
                } else {
                    assert!(row.speedup_vs_cpu.is_some(), "{what}");
                }
            }
        }
    }
    // Experiment 6: the landed slab, polylog in mochi mode (grid and mlgrid side by side on
    // wgpu-compute) and in nns mode.
    for backend in backends {
        let of = |scene: &str, mode: &str| -> Vec<&DemRow> {
            rows.iter()
                .filter(|r| {
                    r.experiment == Experiment::Targets
                        && r.backend.name() == *backend
                        && r.scene.name() == scene
                        && r.mode.name() == mode
                })
                .collect()
        };
        assert_eq!(of("slab", "mochi").len(), 1, "{backend}");
        assert_eq!(of("polylog", "nns").len(), 1, "{backend}");
        // The slab after its 10 settling steps, the pile after its 20 pouring steps (per-pair
        // stiffness, dt 1e-4), both timed from there.
        for (scene, settled) in [("slab", 10), ("polylog", 20)] {
            for row in of(scene, "mochi").into_iter().chain(of(scene, "nns")) {
                assert_eq!((row.settled, row.dt), (settled, Some(1e-4)), "{row:?}");
                let timed = row.timed.expect("a DEM row says the steps it timed");
                assert_eq!(timed.from, settled + STEPS as u64, "{row:?}");
            }
        }
        let structures: Vec<String> = of("polylog", "mochi")
            .iter()
            .map(|r| r.structure.name().to_owned())
            .collect();
        if *backend == "wgpu-compute" {
            assert_eq!(structures, ["grid", "mlgrid"]);
        } else {
            assert_eq!(structures.len(), 1, "{backend}");
        }
        count += 2 + structures.len();
    }
    for r in rows.iter().filter(|r| r.backend.name() != "cpu") {
        let cpu = rows
            .iter()
            .find(|c| {
                c.backend.name() == "cpu"
                    && c.experiment == r.experiment
                    && c.scene == r.scene
                    && c.n == r.n
                    && c.mode == r.mode
            })
            .expect("a cpu row for every row");
        let want = cpu.total_ms.median / r.total_ms.median;
        assert!((r.speedup_vs_cpu.unwrap() - want).abs() < 1e-9, "{r:?}");
    }
    assert_eq!(
        rows.len(),
        count,
        "one row per experiment, backend and size"
    );
}

fn check_svg(path: &Path, title: &str) {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    assert_eq!(doc.root_element().tag_name().name(), "svg", "{path:?}");
    assert!(text.contains(title), "{path:?} should be titled {title:?}");
}

#[test]
fn bench_small_reports_every_experiment_as_markdown_json_and_svg() {
    let mut backends = vec!["cpu"];
    if common::adapter_for(Need::Compute, "mochi bench on wgpu-compute") {
        backends.insert(0, "wgpu-compute");
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    let list = backends.join(",");
    let (n, steps, repeats) = (N.to_string(), STEPS.to_string(), REPEATS.to_string());
    let args = [
        "bench",
        "--scale",
        "small",
        "--spheres",
        &n,
        "--max-spheres",
        "10000",
        "--backends",
        &list,
        "--repeats",
        &repeats,
        "--warmup",
        "1",
        "--steps",
        &steps,
        "--settle",
        "10",
        "--pile",
        "20",
        "--experiments",
        "1,2,3,4,5,6",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
    ];
    let (code, stdout, stderr) = mochi(&args);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");

    for e in PAPER {
        let heading = format!("## {}. {}", e.number(), e.title());
        let at = stdout
            .find(&heading)
            .unwrap_or_else(|| panic!("no section {heading:?}\n{stdout}"));
        let workload = stdout[at..].lines().nth(2).unwrap_or_default();
        assert!(workload.starts_with("Workload: "), "{heading}: {workload}");
        let table = stdout[at..].lines().nth(4).unwrap_or_default();
        assert!(table.starts_with("| backend |"), "{heading}: {table}");
    }
    assert!(!stdout.contains("Not measured"), "{stdout}");
    let md = std::fs::read_to_string(out.join("bench.md")).unwrap();
    assert_eq!(md, stdout);

    let json = std::fs::read_to_string(out.join("bench.json")).unwrap();
    let report: Report = serde_json::from_str(&json).unwrap();
    assert_eq!(report.schema_version, SCHEMA_VERSION);
    assert!(
        report.command.contains("bench --scale small"),
        "{}",
        report.command
    );
    assert!(report.date.starts_with("20") && report.date.ends_with('Z'));
    assert_eq!(report.settings.experiments, PAPER.to_vec());
    assert_eq!(
        (report.settings.repeats, report.settings.steps),
        (REPEATS, STEPS)
    );
    for b in &report.backends {
        let chosen = backends.contains(&b.name.name());
        assert_eq!(b.left_out.is_none(), chosen, "{b:?}");
        assert!(!chosen || b.device.is_some(), "{b:?}");
    }
    check_detect(&report.detect, &backends);
    check_dem(&report.dem, &backends);
    assert!(report.skipped.is_empty(), "{:?}", report.skipped);
    assert_eq!(report.settings.settle, 10);
    // Every target is reported; at this size only the 2-core cpu one could be judged, and the
    // DEM ones measured here say why they were not.
    assert_eq!(report.targets.len(), 8);
    for t in &report.targets {
        assert!(!t.measured.is_empty(), "{t:?}");
        if !t.target.starts_with("cpu backend") {
            assert_eq!(t.met, None, "{t:?}");
        }
        if t.target.contains("slab 1M") || t.target.contains("polylog pile 1M") {
            let why = t.not_judged.as_deref().unwrap_or_default();
            assert!(why.starts_with("not judged: "), "{t:?}");
            assert!(t.measured.contains("contacts at the end"), "{t:?}");
        }
    }
    assert!(stdout.contains(TARGETS_TABLE), "{stdout}");

    for e in PAPER {
        check_svg(&out.join(format!("{}.svg", e.name())), e.title());
    }
}

/// The paper's experiments (1–6), which every backend runs.
const PAPER: [Experiment; 6] = [
    Experiment::Dcd,
    Experiment::Freefall,
    Experiment::Rotating,
    Experiment::Rebuild,
    Experiment::Scaling,
    Experiment::Targets,
];

#[test]
fn bench_friction_reports_the_frictional_step_with_its_history() {
    // The cpu step runs it; a GPU backend whose step does not run Hertz–Mindlin yet reports
    // why, as "Not measured", and one that does gets its row.
    let mut backends = vec!["cpu"];
    if common::adapter_for(Need::Compute, "mochi bench friction on wgpu-compute") {
        backends.insert(0, "wgpu-compute");
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    let list = backends.join(",");
    let args = [
        "bench",
        "--scale",
        "small",
        "--experiments",
        "friction",
        "--spheres",
        "1500",
        "--backends",
        &list,
        "--repeats",
        "2",
        "--warmup",
        "0",
        "--steps",
        "2",
        "--settle",
        "1500",
        "--pour",
        "300",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
    ];
    let (code, stdout, stderr) = mochi(&args);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    let heading = format!("## 7. {}", Experiment::Friction.title());
    assert!(stdout.contains(&heading), "{stdout}");
    assert!(
        stdout.contains("history read back [bytes/sphere]"),
        "{stdout}"
    );

    let json = std::fs::read_to_string(out.join("bench.json")).unwrap();
    let report: Report = serde_json::from_str(&json).unwrap();
    assert_eq!(report.settings.experiments, [Experiment::Friction]);
    for backend in &backends {
        let row = report
            .dem
            .iter()
            .find(|r| r.backend.name() == *backend && r.scene.name() == "slab");
        let skipped = report.skipped.iter().find(|s| s.backend.name() == *backend);
        match (row, skipped) {
            (Some(row), None) => {
                assert_eq!((row.scene.name(), row.n), ("slab", 1500));
                // 1,500 steps of 3.9 µs: the first layers have just met.
                assert!(row.contacts > 0, "the slab is landing: {row:?}");
                let history = row.history.expect("a frictional row reports its history");
                // Both spheres of a pair hold it, and walls add theirs.
                assert!(history.entries >= 2 * row.contacts, "{history:?}");
                assert!(history.slots >= 1);
                assert_eq!(history.bytes_per_sphere, 28 * history.slots + 4);
                for phase in [&row.build_ms, &row.dcd_ms, &row.update_ms] {
                    assert_eq!(phase.samples, 2);
                }
            }
            (None, Some(skipped)) => {
                assert_ne!(*backend, "cpu", "the cpu step runs it");
                assert!(!skipped.reason.is_empty(), "{skipped:?}");
                assert!(stdout.contains("Not measured"), "{stdout}");
            }
            other => panic!("{backend}: {other:?}"),
        }
        // The polylog pile poured for 300 steps (still falling apart): its row beside the
        // slab's, a frictional one.
        if let Some(pile) = report
            .dem
            .iter()
            .find(|r| r.backend.name() == *backend && r.scene.name() == "polylog")
        {
            assert_eq!((pile.n, pile.steps), (1500, 2));
            assert!(pile.history.is_some(), "{pile:?}");
        } else {
            assert!(
                row.is_none(),
                "{backend}: a slab row without the polylog row"
            );
        }
    }
    check_svg(&out.join("friction.svg"), Experiment::Friction.title());
}

#[test]
fn bench_clustered_runs_at_the_small_scale() {
    // 14 filled meshes (the built-in torus) at `--scale small` with 1,000 spheres' worth: about
    // 1,300 spheres, dropped at dt 1e-4 for the whole 5,000 steps in their box and in one 10×
    // wider, wgpu-compute with both grid builds.
    let mut backends = vec!["cpu"];
    if common::adapter_for(Need::Compute, "mochi bench clustered on wgpu-compute") {
        backends.insert(0, "wgpu-compute");
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    let list = backends.join(",");
    // A peer's figure, printed beside mochi's.
    let peers = dir.path().join("peers.json");
    std::fs::write(
        &peers,
        r#"[{"experiment": "clustered", "peer": "Taichi", "ms_per_step": 0.983,
             "workload": "14 bunnies, 5,000 steps at dt 1e-4", "spheres": 1151878,
             "device": "H100", "date": "2026-11-28"}]"#,
    )
    .unwrap();
    let args = [
        "bench",
        "--scale",
        "small",
        "--experiments",
        "clustered",
        "--compare",
        peers.to_str().unwrap(),
        "--backends",
        &list,
        "--spheres",
        "1000",
        "--repeats",
        "2",
        "--warmup",
        "0",
        "--steps",
        "2",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
    ];
    let (code, stdout, stderr) = mochi(&args);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    let heading = format!("## 8. {}", Experiment::Clustered.title());
    assert!(
        stdout.contains("dt 1e-4 s") && stdout.contains("steps 0–5000"),
        "the workload is stated: {stdout}"
    );
    // The row's time step, steps timed and contacts are printed.
    assert!(
        stdout.contains("| 1e-4 | 0–5000 (every run from the start) |"),
        "{stdout}"
    );
    assert!(stdout.contains(&heading), "{stdout}");
    assert!(stdout.contains("mesh, box ×10"), "{stdout}");

    let json = std::fs::read_to_string(out.join("bench.json")).unwrap();
    let report: Report = serde_json::from_str(&json).unwrap();
    assert_eq!(report.settings.experiments, [Experiment::Clustered]);
    assert!(report.skipped.is_empty(), "{:?}", report.skipped);
    for backend in &backends {
        let rows: Vec<&DemRow> = report
            .dem
            .iter()
            .filter(|r| r.backend.name() == *backend)
            .collect();
        let setups: Vec<(Option<u32>, Option<&str>)> = rows
            .iter()
            .map(|r| (r.box_scale, r.grid_build.as_deref()))
            .collect();
        // wgpu-compute with both builds side by side, in both boxes; the others once each.
        let want = match *backend {
            "wgpu-compute" => vec![
                (None, Some("dense")),
                (None, Some("sorted")),
                (Some(10), Some("dense")),
                (Some(10), Some("sorted")),
            ],
            _ => vec![(None, None), (Some(10), None)],
        };
        assert_eq!(setups, want, "{backend}");
        for row in &rows {
            assert_eq!(row.scene.name(), "mesh");
            assert!(
                (900..1_600).contains(&row.n),
                "{backend}: {} spheres",
                row.n
            );
            assert_eq!(
                row.n, rows[0].n,
                "{backend}: the same spheres in both boxes"
            );
            // The whole drop at the paper's dt, every run from the start, `--steps 2`
            // notwithstanding; the meshes have landed by its end.
            assert_eq!((row.steps, row.dt, row.settled), (5000, Some(1e-4), 0));
            let timed = row.timed.expect("the steps timed");
            assert_eq!((timed.from, timed.to, timed.each_run), (0, 5000, true));
            assert!(row.contacts > 0, "{backend}: contacts at the end: {row:?}");
            for phase in [&row.build_ms, &row.dcd_ms, &row.update_ms] {
                assert_eq!(phase.samples, 2);
            }
        }
    }
    // The clustered-scene targets: the whole drop is judged only with a mesh given and at 1M
    // spheres, the wide box against its own at any size (both end with contacts).
    let target = |start: &str| {
        let found = report.targets.iter().find(|t| t.target.starts_with(start));
        found.unwrap_or_else(|| panic!("no target {start:?}: {:?}", report.targets))
    };
    assert_eq!(target("14 meshes dropped").met, None);
    assert!(
        target("14 meshes dropped")
            .not_judged
            .as_deref()
            .is_some_and(|why| why.contains("torus")),
        "{:?}",
        report.targets
    );
    assert!(target("experiment 8 in a box 10× wider").met.is_some());
    assert!(stdout.contains(TARGETS_TABLE), "{stdout}");
    check_svg(&out.join("clustered.svg"), Experiment::Clustered.title());
    // The peer ran the paper's 1,151,878 spheres, mochi about 1,300 here: no ratio.
    assert!(stdout.contains("## Against other codes"), "{stdout}");
    let compared = &report.comparisons[0];
    assert_eq!(compared.peer.peer, "Taichi");
    assert_eq!(compared.mochi_faster, None);
    assert!(
        compared.note.as_deref().unwrap().contains("not compared"),
        "{compared:?}"
    );
}

#[test]
fn bad_bench_arguments_fail_cleanly() {
    for (args, says) in [
        (&["bench", "--experiments", "1,9"][..], "unknown experiment"),
        (&["bench", "--backends", "cpu,gpu"][..], "unknown backend"),
        (
            &["bench", "--backends", "cpu", "--repeats", "0"][..],
            "--repeats",
        ),
        (
            &["bench", "--backends", "cpu", "--max-spheres", "10"][..],
            "--max-spheres",
        ),
    ] {
        let (code, _, stderr) = mochi(args);
        assert_eq!(
            code.map(|c| c != 0 && c != 101),
            Some(true),
            "{args:?}: {stderr}"
        );
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
    // `--compare` files are read and checked before anything runs.
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.json");
    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        r#"[{"experiment": "clustered", "peer": "Taichi", "ms_per_step": 0}]"#,
    )
    .unwrap();
    let empty = dir.path().join("empty.json");
    std::fs::write(&empty, "[]").unwrap();
    for (file, says) in [
        (&missing, "cannot read it"),
        (&bad, "missing field `workload`"),
        (&empty, "no figures"),
    ] {
        let args = [
            "bench",
            "--backends",
            "cpu",
            "--compare",
            file.to_str().unwrap(),
            "-o",
            dir.path().to_str().unwrap(),
        ];
        let (code, _, stderr) = mochi(&args);
        assert_eq!(
            code.map(|c| c != 0 && c != 101),
            Some(true),
            "{args:?}: {stderr}"
        );
        assert!(
            stderr.contains("--compare") && stderr.contains(says),
            "{args:?}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}
