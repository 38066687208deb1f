//! Every available backend against the brute-force oracle: exact pair sets, each pair once.
//!
//! The cpu and optix backends round every step of the rule as `src/proxy.rs` does, so they must
//! equal the oracle bit for bit. The wgpu backends may have their multiply-adds fused by the
//! device compiler: for them, and only for pairs off the axes within rounding of a threshold of
//! the rule (`proxy::near_boundary`), a difference is allowed. Tests whose pairs lie on a
//! threshold (touching lattices) put them on the axes, so every backend decides them exactly.

mod common;

use mochi::Backend;
use mochi::engines::wgpu::compute::GridBuild;
use mochi::engines::{BackendKind, Options};
use mochi::oracle::{brute_force_pairs, differences};
use mochi::scenes::{Layout, Scene, SceneSpec, generate};
use mochi::{Error, Pair, ProxyMode, SphereSet};
use proptest::prelude::*;
use std::sync::{LazyLock, Mutex};

const MODES: [ProxyMode; 2] = [ProxyMode::Mochi, ProxyMode::Nns];

/// The backends to test here. Under `CI=true` every backend CI can run (the wgpu ones run on
/// lavapipe) must be available, and optix where `MOCHI_EXPECT_OPTIX=1`: a missing one fails the
/// run instead of passing unnoticed.
fn backends() -> Vec<BackendKind> {
    BackendKind::ALL
        .into_iter()
        .filter(|kind| match kind.probe() {
            Ok(_) => true,
            Err(why) => {
                assert!(
                    !common::expected(*kind),
                    "this run expects backend {} to run, but: {why}",
                    kind.name()
                );
                eprintln!(
                    "note: backend {} is not tested on this machine: {why}",
                    kind.name()
                );
                false
            }
        })
        .collect()
}

type OpenSlot = Mutex<Option<Box<dyn Backend>>>;

/// The settings each backend is tested with, by label: its defaults, and for `wgpu-compute`
/// also each grid build forced (`auto` picks the dense one for most sets here).
fn settings(kind: BackendKind) -> Vec<(String, Options)> {
    let mut all = vec![(kind.name().to_owned(), Options::default())];
    if kind == BackendKind::WgpuCompute {
        for grid_build in [GridBuild::Dense, GridBuild::Sorted] {
            let label = format!("{} {}", kind.name(), grid_build.name());
            all.push((
                label,
                Options {
                    grid_build,
                    ..Options::default()
                },
            ));
        }
    }
    all
}

/// Opened backends, one per kind and settings, shared by the tests (opening a GPU device is
/// slow). A static is never dropped, so no device is torn down while a test thread exits.
static OPENED: LazyLock<Vec<(String, OpenSlot)>> = LazyLock::new(|| {
    BackendKind::ALL
        .into_iter()
        .flat_map(settings)
        .map(|(label, _)| (label, Mutex::new(None)))
        .collect()
});

/// Runs `f` on each available backend under each of its [`settings`], opened once per test
/// run; `f` gets the kind and the label.
fn with_each_backend(mut f: impl FnMut(BackendKind, &str, &mut dyn Backend)) {
    for kind in backends() {
        for (label, options) in settings(kind) {
            let slot = &OPENED.iter().find(|(l, _)| *l == label).unwrap().1;
            let mut slot = slot.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
            let backend = slot
                .get_or_insert_with(|| kind.open_with(&options).expect("a probed backend opens"));
            f(kind, &label, backend.as_mut());
        }
    }
}

/// Runs every backend in both modes; checks pairs, count and visits against the oracle.
fn check_exact(spheres: &SphereSet) -> Result<(), TestCaseError> {
    let mut want = brute_force_pairs(spheres);
    want.sort_unstable();
    let mut outcome = Ok(());
    with_each_backend(|kind, name, backend| {
        if outcome.is_ok() {
            outcome = check_backend(kind, name, backend, spheres, &want);
        }
    });
    outcome
}

fn check_backend(
    kind: BackendKind,
    name: &str,
    backend: &mut dyn Backend,
    spheres: &SphereSet,
    want: &[Pair],
) -> Result<(), TestCaseError> {
    {
        for mode in MODES {
            let label = format!("{name} {}", mode.name());
            #[cfg(feature = "optix")]
            if kind == BackendKind::Optix && beyond_optix_reach(spheres) {
                // OptiX drops boxes that far out: the backend must refuse, not answer wrongly.
                let err = backend
                    .build(spheres.view(), mode)
                    .expect_err("optix refuses far-out sets");
                prop_assert!(err.to_string().contains("beyond"), "{}: {}", label, err);
                continue;
            }
            backend.build(spheres.view(), mode).expect("build");
            let (pairs, stats) = backend.find_pairs().expect("find_pairs");
            assert_pairs_well_formed(&pairs, &label)?;
            let mut got = pairs.clone();
            got.sort_unstable();
            let off = differences(&got, want, spheres, fused(kind));
            prop_assert!(
                off.is_empty(),
                "{}: differs from the oracle in {} pairs (got {}, want {}): {:?}",
                label,
                off.len(),
                got.len(),
                want.len(),
                &off[..off.len().min(20)]
            );
            if !fused(kind) {
                prop_assert_eq!(got.len(), want.len(), "{}: pair count", label);
            }
            prop_assert_eq!(stats.pairs, got.len() as u64, "{}: stats.pairs", label);
            prop_assert!(
                stats.candidates >= stats.pairs,
                "{}: candidates < pairs",
                label
            );

            let again = backend.find_pairs().expect("find_pairs").0;
            prop_assert_eq!(&again, &pairs, "{}: order differs between runs", label);
            // Every backend returns its pairs sorted (the wgpu engines sort them on the GPU,
            // src/gpu/pair_sort.rs; the cpu one by counting).
            prop_assert!(
                pairs.windows(2).all(|w| w[0] < w[1]),
                "{}: pairs not sorted",
                label
            );
            let mut taken = Vec::new();
            let taken_stats = backend
                .take_pairs(&mut |p| taken = p.to_vec())
                .expect("take_pairs");
            prop_assert_eq!(&taken, &pairs, "{}: take_pairs", label);
            prop_assert_eq!(taken_stats, stats, "{}: take_pairs' stats", label);
            let count = backend.count_pairs().expect("count_pairs");
            prop_assert_eq!(count, stats, "{}: count_pairs", label);

            let visited = Mutex::new(Vec::new());
            let visit_stats = backend
                .for_each_contact(&|p| visited.lock().unwrap().push(p))
                .expect("for_each_contact");
            let mut visited = visited.into_inner().unwrap();
            visited.sort_unstable();
            prop_assert_eq!(&visited, &got, "{}: for_each_contact", label);
            prop_assert_eq!(visit_stats, stats, "{}: for_each_contact stats", label);
        }
    }
    Ok(())
}

/// Whether `kind`'s device compiler may fuse multiply-adds (WGSL allows it; the optix programs
/// are compiled without).
fn fused(kind: BackendKind) -> bool {
    matches!(kind, BackendKind::WgpuCompute | BackendKind::WgpuRq)
}

/// Whether a proxy box of `spheres` reaches beyond what the optix backend accepts.
#[cfg(feature = "optix")]
fn beyond_optix_reach(spheres: &SphereSet) -> bool {
    let r_max = spheres.max_radius();
    spheres.xyzr().any(|[x, y, z, _]| {
        x.abs().max(y.abs()).max(z.abs()) + 4.0 * r_max > mochi::engines::optix::MAX_COORDINATE
    })
}

fn assert_pairs_well_formed(pairs: &[Pair], label: &str) -> Result<(), TestCaseError> {
    let mut seen = std::collections::HashSet::new();
    for p in pairs {
        prop_assert!(p.i < p.j, "{}: pair {:?} not ordered", label, p);
        prop_assert!(seen.insert(*p), "{}: pair {:?} reported twice", label, p);
    }
    Ok(())
}

fn exact(spheres: &SphereSet) {
    check_exact(spheres).unwrap();
}

fn set(spheres: &[([f32; 3], f32)]) -> SphereSet {
    SphereSet::new(
        spheres.iter().map(|s| s.0).collect(),
        spheres.iter().map(|s| s.1).collect(),
    )
    .unwrap()
}

/// Spheres with log-uniform radii over `ratio` and centres in a box sized for many contacts.
fn polydisperse() -> impl Strategy<Value = SphereSet> {
    (0usize..400, 1.0f32..1e4, 0.05f32..2.0, any::<u64>()).prop_map(|(n, ratio, density, seed)| {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let r_max = 1.0f32;
        let r_min = r_max / ratio;
        let side = (n as f32 / density).cbrt().max(0.1) * r_max;
        let offset = rng.random_range(-100.0f32..100.0);
        let mut centers = Vec::with_capacity(n);
        let mut radii = Vec::with_capacity(n);
        for _ in 0..n {
            let t: f32 = rng.random_range(0.0..=1.0);
            radii.push(r_min * (r_max / r_min).powf(t));
            centers.push(std::array::from_fn(|_| {
                offset + rng.random_range(0.0..side)
            }));
        }
        SphereSet::new(centers, radii).unwrap()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]
    #[test]
    fn random_polydisperse_sets_match_the_oracle(spheres in polydisperse()) {
        check_exact(&spheres)?;
    }
}

#[test]
fn empty_one_and_two_spheres() {
    exact(&SphereSet::default());
    exact(&set(&[([1.0, 2.0, 3.0], 0.5)]));
    exact(&set(&[([0.0; 3], 1.0), ([2.0, 0.0, 0.0], 1.0)])); // touching
    exact(&set(&[([0.0; 3], 1.0), ([2.5, 0.0, 0.0], 1.0)])); // apart
}

#[test]
fn exactly_touching_spheres_in_every_direction() {
    // Distances and radii are exact in binary, so d = r_i + r_j holds exactly.
    let mut spheres = vec![([0.0f32; 3], 0.75f32)];
    for dir in [
        [1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [-1.0, 0.0, 0.0],
    ] {
        spheres.push((dir.map(|d: f32| d * 1.0), 0.25));
        spheres.push((dir.map(|d: f32| d * 1.75), 0.5)); // touches the small one
    }
    let s = set(&spheres);
    assert_eq!(brute_force_pairs(&s).len(), 8);
    exact(&s);
}

#[test]
fn one_sphere_touching_thousands_of_later_ones() {
    // Sphere 0 (radius 1) touched by small spheres spread over a shell around it, none touching
    // another: its pairs all have first index 0, one bucket of the GPU pair sort longer than it
    // orders in place (src/gpu/pair_sort.rs), then one it does order.
    for count in [1500, 300] {
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let mut spheres = vec![([0.0; 3], 1.0)];
        for k in 0..count {
            let z = 1.0 - 2.0 * (k as f32 + 0.5) / count as f32;
            let ring = (1.0 - z * z).sqrt();
            let a = golden * k as f32;
            let d = 1.005;
            spheres.push(([d * ring * a.cos(), d * ring * a.sin(), d * z], 0.01));
        }
        exact(&set(&spheres));
    }
}

#[test]
fn coincident_centres() {
    let mut spheres: Vec<_> = (0..50).map(|k| ([3.0, 3.0, 3.0], 0.1 + k as f32)).collect();
    spheres.push(([3.0, 3.0, 3.0 + 0.2], 0.15));
    let s = set(&spheres);
    assert_eq!(brute_force_pairs(&s).len(), 51 * 50 / 2);
    exact(&s);
}

#[test]
fn radius_ratio_ten_thousand() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let mut spheres = vec![([0.0; 3], 1.0f32)];
    for _ in 0..3000 {
        let c = std::array::from_fn(|_| rng.random_range(-1.2f32..1.2));
        spheres.push((c, 1e-4));
    }
    exact(&set(&spheres));
}

#[test]
fn touching_lattice() {
    // Spacing 1, radius 0.5: every lattice neighbour touches exactly.
    let mut spheres = Vec::new();
    for z in 0..12 {
        for y in 0..12 {
            for x in 0..12 {
                spheres.push(([x as f32, y as f32, z as f32], 0.5));
            }
        }
    }
    let s = set(&spheres);
    assert_eq!(brute_force_pairs(&s).len(), 3 * 11 * 12 * 12);
    exact(&s);
}

#[test]
fn flat_and_far_apart_layouts() {
    // All centres on a line, on a plane, and two clusters 1e15 apart (cells grow to fit the keys).
    let line: Vec<_> = (0..500)
        .map(|k| ([k as f32 * 0.3, 0.0, 0.0], 0.2))
        .collect();
    exact(&set(&line));
    let plane: Vec<_> = (0..900)
        .map(|k| ([(k % 30) as f32 * 0.45, 7.0, (k / 30) as f32 * 0.45], 0.25))
        .collect();
    exact(&set(&plane));
    let mut far = plane.clone();
    far.extend(
        plane
            .iter()
            .map(|&(c, r)| ([c[0] + 1e15, c[1], c[2] - 1e15], r)),
    );
    exact(&set(&far));
}

#[test]
fn outliers_at_the_coordinate_limit() {
    // Two spheres at the origin and two outliers: 10^20 cells of the mode's size lie between them.
    for far in [1e17, mochi::MAX_MAGNITUDE] {
        let rows = [
            ([-far, 0.0, 0.0], 0.001),
            ([far, 0.0, 0.0], 0.001),
            ([0.0; 3], 0.001),
            ([0.0; 3], 0.001),
        ];
        let s = set(&rows);
        assert_eq!(brute_force_pairs(&s), vec![Pair::new(2, 3)]);
        exact(&s);
        // A cluster at the origin, outliers on every axis and corner.
        let mut spheres: Vec<_> = (0..200)
            .map(|k| {
                (
                    [(k % 10) as f32 * 0.0015, (k / 10) as f32 * 0.002, 0.0],
                    0.001,
                )
            })
            .collect();
        for corner in 0..8 {
            let at = |bit: usize| if corner >> bit & 1 == 1 { far } else { -far };
            spheres.push(([at(0), at(1), at(2)], 0.001));
        }
        spheres.push(([0.0, far, 0.0], 0.5));
        spheres.push(([0.0, far, 0.5], 0.5));
        exact(&set(&spheres));
    }
}

/// Pairs of `spheres` counted in `f64` from the `f32` input (no rounding to speak of here).
fn pairs_in_f64(spheres: &SphereSet) -> usize {
    let (c, r) = (spheres.centers(), spheres.radii());
    (0..c.len())
        .map(|i| {
            (i + 1..c.len())
                .filter(|&j| {
                    let d2: f64 = (0..3)
                        .map(|a| (c[i][a] as f64 - c[j][a] as f64).powi(2))
                        .sum();
                    d2 <= (r[i] as f64 + r[j] as f64).powi(2)
                })
                .count()
        })
        .sum()
}

#[test]
fn the_smallest_radii_do_not_underflow() {
    // A gap of 10^5 radii (at radii of 1e-30 its square underflowed to 0: reported touching).
    let r = mochi::MIN_RADIUS;
    let s = set(&[
        ([0.0; 3], r),
        ([1e5 * r, 0.0, 0.0], r),
        ([10.0, 10.0, 10.0], 1.0),
    ]);
    assert_eq!(brute_force_pairs(&s), vec![]);
    exact(&s);
    // 2,000 of the smallest spheres in a cube of 100 radii (a few dozen touch), inside one giant.
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(16);
    let mut spheres: Vec<_> = (0..2000)
        .map(|_| (std::array::from_fn(|_| rng.random_range(0.0..100.0 * r)), r))
        .collect();
    spheres.push(([0.5, 0.0, 0.0], 1.0));
    let s = set(&spheres);
    let want = brute_force_pairs(&s).len();
    assert_eq!(want, pairs_in_f64(&s));
    assert!((2010..2200).contains(&want), "{want} pairs");
    exact(&s);
}

#[test]
fn scenes_of_twenty_thousand_spheres() {
    for (scene, layout) in [
        (Scene::Poly120, Layout::Random),
        (Scene::Poly12, Layout::Random),
        (Scene::Slab, Layout::Random),
        (Scene::Freefall, Layout::Lattice),
    ] {
        let spec = SceneSpec {
            scene,
            n: 20_000,
            seed: 11,
            layout,
        };
        exact(&generate(&spec).unwrap());
    }
}

#[test]
fn update_after_moving_gives_the_new_exact_set() {
    let spec = SceneSpec {
        scene: Scene::Poly12,
        n: 5000,
        seed: 3,
        layout: Layout::Random,
    };
    let original = generate(&spec).unwrap();
    with_each_backend(|_, name, backend| {
        let mut spheres = original.clone();
        backend.build(spheres.view(), ProxyMode::Mochi).unwrap();
        for step in 0..3 {
            let moved = spheres
                .centers()
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let shift = ((i * 7 + step) % 13) as f32 * 0.02 - 0.12;
                    [c[0] + shift, c[1] - 0.5 * shift, c[2]]
                })
                .collect();
            spheres.set_centers(moved).unwrap();
            backend.update(spheres.view()).unwrap();
            let mut got = backend.find_pairs().unwrap().0;
            got.sort_unstable();
            assert_eq!(got, brute_force_pairs(&spheres), "{name} step {step}");
        }
        // Misuse of the library, not bad input: Usage.
        let wrong_size = SphereSet::default();
        let result = backend.update(wrong_size.view());
        assert!(matches!(result, Err(Error::Usage(_))), "{result:?}");
    });
}

#[test]
fn detection_before_build_is_an_error() {
    for kind in backends() {
        let mut backend = kind.open().unwrap();
        let found = backend.find_pairs();
        assert!(
            matches!(found, Err(Error::Usage(_))),
            "{}: {found:?}",
            kind.name()
        );
        let counted = backend.count_pairs();
        assert!(
            matches!(counted, Err(Error::Usage(_))),
            "{}: {counted:?}",
            kind.name()
        );
        let updated = backend.update(SphereSet::default().view());
        assert!(
            matches!(updated, Err(Error::Usage(_))),
            "{}: {updated:?}",
            kind.name()
        );
    }
}

#[test]
fn far_away_outliers_keep_the_search_linear() {
    // A dense cluster plus a few spheres a thousand units away (a million cells of the cluster's
    // size): a dense grid over the bounding box would put the whole cluster in a few cells.
    // Exact, and few candidates per sphere.
    let cluster = generate(&SceneSpec {
        scene: Scene::Slab,
        n: 20_000,
        seed: 5,
        layout: Layout::Random,
    })
    .unwrap();
    let mut centers = cluster.centers().to_vec();
    let mut radii = cluster.radii().to_vec();
    for k in 0..10 {
        centers.push([1e3 + k as f32 * 1e-3, -1e3, 5e2]);
        radii.push(0.0006);
    }
    let spheres = SphereSet::new(centers, radii).unwrap();
    let mut want = brute_force_pairs(&spheres);
    want.sort_unstable();
    with_each_backend(|kind, name, backend| {
        backend.build(spheres.view(), ProxyMode::Mochi).unwrap();
        let (mut got, stats) = backend.find_pairs().unwrap();
        got.sort_unstable();
        let off = differences(&got, &want, &spheres, fused(kind));
        assert!(off.is_empty(), "{name}: differs from the oracle: {off:?}");
        let per_sphere = stats.candidates as f64 / spheres.len() as f64;
        assert!(
            per_sphere < 40.0,
            "{name}: {per_sphere} candidates per sphere"
        );
    });
}
