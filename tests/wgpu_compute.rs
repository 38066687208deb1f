//! The `wgpu-compute` backend's multi-level grid (`--structure mlgrid`) and its sorted-key build
//! (`--grid-build sorted`) against the oracle, on random polydisperse sets, clusters and the
//! scenes; the single grid is covered by backends_exact.rs (both builds forced there too).
//! Runs on any adapter (lavapipe in CI); under `CI=true` a missing adapter fails.

mod common;

use mochi::Backend;
use mochi::engines::wgpu::compute::{GridBuild, Structure, WgpuComputeBackend};
use mochi::gpu::Need;
use mochi::oracle::{brute_force_pairs, differences};
use mochi::scenes::{Layout, Scene, SceneSpec, generate};
use mochi::{ProxyMode, SphereSet};
use rand::{RngExt, SeedableRng};

fn open(structure: Structure) -> Option<WgpuComputeBackend> {
    open_with(structure, GridBuild::Auto)
}

fn open_with(structure: Structure, grid_build: GridBuild) -> Option<WgpuComputeBackend> {
    common::adapter_for(Need::Compute, "wgpu-compute").then(|| {
        let backend = WgpuComputeBackend::new().expect("a probed adapter opens");
        backend
            .with_structure(structure)
            .with_grid_build(grid_build)
    })
}

/// The build the last `build` of `backend` made, from its description.
fn built_with(backend: &WgpuComputeBackend) -> String {
    let described = backend.structure().expect("built");
    ["sorted build", "dense build"]
        .into_iter()
        .find(|b| described.contains(b))
        .unwrap_or_else(|| panic!("no build named in {described:?}"))
        .to_owned()
}

/// Log-uniform radii over `ratio`, centres in a box sized for many contacts.
fn polydisperse(seed: u64, n: usize, ratio: f32) -> SphereSet {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let side = (n as f32 / 0.5).cbrt();
    let mut centers = Vec::with_capacity(n);
    let mut radii = Vec::with_capacity(n);
    for _ in 0..n {
        let t: f32 = rng.random_range(0.0..=1.0);
        radii.push(ratio.powf(-t));
        centers.push(std::array::from_fn(|_| rng.random_range(0.0..side)));
    }
    SphereSet::new(centers, radii).unwrap()
}

fn assert_exact(backend: &mut WgpuComputeBackend, spheres: &SphereSet, label: &str) -> u64 {
    let want = brute_force_pairs(spheres);
    backend.build(spheres.view(), ProxyMode::Mochi).unwrap();
    let (got, stats) = backend.find_pairs().unwrap();
    let mut seen = std::collections::HashSet::new();
    assert!(
        got.iter().all(|p| p.i < p.j && seen.insert(*p)),
        "{label}: duplicates"
    );
    let off = differences(&got, &want, spheres, true);
    assert!(off.is_empty(), "{label}: differs from the oracle: {off:?}");
    stats.candidates
}

#[test]
fn multi_level_grid_is_exact_on_random_polydisperse_sets() {
    let Some(mut backend) = open(Structure::Mlgrid) else {
        return;
    };
    for (seed, &ratio) in [1.0f32, 2.0, 12.0, 120.0, 1e4].iter().enumerate() {
        for n in [1, 2, 300, 3000] {
            let spheres = polydisperse(seed as u64 * 31 + n as u64, n, ratio);
            assert_exact(&mut backend, &spheres, &format!("ratio {ratio}, n {n}"));
        }
    }
    backend
        .build(SphereSet::default().view(), ProxyMode::Mochi)
        .unwrap();
    assert!(backend.find_pairs().unwrap().0.is_empty());
}

#[test]
fn multi_level_grid_tests_fewer_candidates_on_mixed_radii() {
    let Some(mut ml) = open(Structure::Mlgrid) else {
        return;
    };
    let Some(mut single) = open(Structure::Grid) else {
        return;
    };
    // Log-uniform radii over a ratio of 120 (like `polylog`), packed densely: a single grid's
    // cells, sized by the largest sphere, hold many small ones.
    let spheres = polydisperse(9, 20_000, 120.0);
    let spheres = SphereSet::new(
        spheres
            .centers()
            .iter()
            .map(|c| c.map(|x| x * 0.3))
            .collect(),
        spheres.radii().to_vec(),
    )
    .unwrap();
    let ml_candidates = assert_exact(&mut ml, &spheres, "mlgrid");
    // Its coarser levels are searched in cells finer than their class (the budget leaves room).
    let described = ml.structure().expect("built");
    assert!(described.contains("cells 1/"), "{described}");
    let single_candidates = assert_exact(&mut single, &spheres, "grid");
    assert!(
        ml_candidates * 2 < single_candidates,
        "mlgrid {ml_candidates} vs grid {single_candidates} candidates"
    );
}

/// Both structures with the sorted build forced.
fn sorted_backends() -> Option<Vec<(&'static str, WgpuComputeBackend)>> {
    Some(vec![
        ("grid", open_with(Structure::Grid, GridBuild::Sorted)?),
        ("mlgrid", open_with(Structure::Mlgrid, GridBuild::Sorted)?),
    ])
}

#[test]
fn sorted_build_is_exact_on_random_polydisperse_sets() {
    let Some(backends) = sorted_backends() else {
        return;
    };
    for (name, mut backend) in backends {
        for (seed, &ratio) in [1.0f32, 2.0, 12.0, 120.0, 1e4].iter().enumerate() {
            for n in [1, 2, 300, 3000] {
                let spheres = polydisperse(seed as u64 * 31 + n as u64, n, ratio);
                let label = format!("sorted {name}, ratio {ratio}, n {n}");
                assert_exact(&mut backend, &spheres, &label);
                assert_eq!(built_with(&backend), "sorted build", "{label}");
            }
        }
        backend
            .build(SphereSet::default().view(), ProxyMode::Mochi)
            .unwrap();
        assert!(backend.find_pairs().unwrap().0.is_empty(), "sorted {name}");
    }
}

/// `clusters` tight clusters of `per_cluster` spheres (radii 0.01 to 0.03), `spread` apart.
fn clusters(seed: u64, clusters: usize, per_cluster: usize, spread: f32) -> SphereSet {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut centers = Vec::new();
    let mut radii = Vec::new();
    for k in 0..clusters {
        let at: [f32; 3] = std::array::from_fn(|a| spread * ((k * (a + 1) * 7) % 5) as f32);
        for _ in 0..per_cluster {
            centers.push(std::array::from_fn(|a| at[a] + rng.random_range(0.0..0.5)));
            radii.push(rng.random_range(0.01..0.03));
        }
    }
    SphereSet::new(centers, radii).unwrap()
}

#[test]
fn sorted_build_is_exact_on_clusters_in_a_huge_box() {
    let Some(backends) = sorted_backends() else {
        return;
    };
    for (name, mut backend) in backends {
        // Clusters a few units apart (a sorted layout of many empty cells), then a thousand
        // units apart (more cells than the keys hold at the mode's size: grown or hashed).
        for (spread, n) in [(3.0, 2000), (1e3, 1500)] {
            let spheres = clusters(4, 6, n, spread);
            let label = format!("sorted {name}, clusters {spread} apart");
            assert_exact(&mut backend, &spheres, &label);
            assert_eq!(built_with(&backend), "sorted build", "{label}");
        }
    }
}

#[test]
fn sorted_build_is_exact_with_one_sphere_and_with_all_in_one_cell() {
    let Some(backends) = sorted_backends() else {
        return;
    };
    for (name, mut backend) in backends {
        let one = SphereSet::new(vec![[0.5, -2.0, 3.0]], vec![0.1]).unwrap();
        assert_eq!(assert_exact(&mut backend, &one, name), 0);
        // 200 spheres of radius 1 within 0.2 of each other: one cell holds them all, every pair
        // touches.
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let centers: Vec<[f32; 3]> = (0..200)
            .map(|_| std::array::from_fn(|_| rng.random_range(0.0..0.2)))
            .collect();
        let crowded = SphereSet::new(centers, vec![1.0; 200]).unwrap();
        let label = format!("sorted {name}, all in one cell");
        assert_exact(&mut backend, &crowded, &label);
        let (pairs, _) = backend.find_pairs().unwrap();
        assert_eq!(pairs.len(), 200 * 199 / 2, "{label}");
    }
}

#[test]
fn sorted_build_finds_the_same_pairs_as_the_dense_build_on_the_scenes() {
    let Some(mut sorted) = open_with(Structure::Auto, GridBuild::Sorted) else {
        return;
    };
    let Some(mut dense) = open_with(Structure::Auto, GridBuild::Dense) else {
        return;
    };
    for scene in [Scene::Slab, Scene::Poly12, Scene::Polylog] {
        let spheres = generate(&SceneSpec {
            scene,
            n: 20_000,
            seed: 2,
            layout: Layout::Random,
        })
        .unwrap();
        for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
            let mut found = Vec::new();
            for backend in [&mut sorted, &mut dense] {
                backend.build(spheres.view(), mode).unwrap();
                let mut pairs = backend.find_pairs().unwrap().0;
                pairs.sort_unstable();
                found.push((built_with(backend), pairs));
            }
            let label = format!("{scene:?} {}", mode.name());
            assert_eq!(found[0].0, "sorted build", "{label}");
            assert_eq!(found[1].0, "dense build", "{label}");
            assert!(
                found[0].1 == found[1].1,
                "{label}: the builds' pairs differ"
            );
        }
    }
}

#[test]
fn auto_takes_the_dense_build_for_a_dense_set_and_the_sorted_one_for_a_sparse_set() {
    let Some(mut backend) = open(Structure::Auto) else {
        return;
    };
    let dense = generate(&SceneSpec {
        scene: Scene::Slab,
        n: 20_000,
        seed: 1,
        layout: Layout::Random,
    })
    .unwrap();
    backend.build(dense.view(), ProxyMode::Mochi).unwrap();
    assert_eq!(built_with(&backend), "dense build");
    // The same spheres spread over a box 40 times wider per side: 64,000 times the cells.
    let sparse = SphereSet::new(
        dense
            .centers()
            .iter()
            .map(|c| c.map(|x| x * 40.0))
            .collect(),
        dense.radii().to_vec(),
    )
    .unwrap();
    backend.build(sparse.view(), ProxyMode::Mochi).unwrap();
    assert_eq!(built_with(&backend), "sorted build");
    let want = brute_force_pairs(&sparse);
    let mut got = backend.find_pairs().unwrap().0;
    got.sort_unstable();
    assert!(differences(&got, &want, &sparse, true).is_empty());
}

/// `spheres` with every centre coordinate x moved to `x · scale + shift`.
fn scaled(spheres: &SphereSet, scale: f32, shift: f32) -> SphereSet {
    let mut s = spheres.clone();
    let centers = s
        .centers()
        .iter()
        .map(|c| c.map(|x| x * scale + shift))
        .collect();
    s.set_centers(centers).unwrap();
    s
}

#[test]
fn spheres_that_barely_move_keep_their_layout_and_spheres_that_spread_get_a_new_one() {
    let Some(mut backend) = open(Structure::Auto) else {
        return;
    };
    let spheres = polydisperse(11, 4000, 4.0);
    assert_exact(&mut backend, &spheres, "first build");
    let first = backend.structure().unwrap();
    let moved = |scale: f32, shift: f32| scaled(&spheres, scale, shift);
    // A small shift: the same layout, the pairs still exact.
    let shifted = moved(1.0, 0.05);
    backend.update(shifted.view()).unwrap();
    let mut got = backend.find_pairs().unwrap().0;
    got.sort_unstable();
    assert_eq!(got, brute_force_pairs(&shifted));
    assert_eq!(backend.structure().unwrap(), first);
    // Spread to three times the size: a layout over the new bounds.
    let spread = moved(3.0, 0.0);
    backend.update(spread.view()).unwrap();
    let mut got = backend.find_pairs().unwrap().0;
    got.sort_unstable();
    assert_eq!(got, brute_force_pairs(&spread));
    assert_ne!(backend.structure().unwrap(), first);
}

#[test]
fn centres_moved_straight_in_stay_exact_and_a_refused_move_keeps_the_build() {
    let Some(mut backend) = open(Structure::Auto) else {
        return;
    };
    let spheres = polydisperse(12, 4000, 4.0);
    assert_exact(&mut backend, &spheres, "first build");
    let first = backend.structure().unwrap();
    let moved = |scale: f32, shift: f32| scaled(&spheres, scale, shift);
    let pairs = |backend: &mut WgpuComputeBackend| {
        let mut got = Vec::new();
        backend.take_pairs(&mut |p| got = p.to_vec()).unwrap();
        assert!(got.windows(2).all(|w| w[0] < w[1]), "taken sorted");
        got
    };
    // A small shift: taken straight in, the same layout, exact.
    let shifted = moved(1.0, 0.05);
    assert!(backend.move_centers(shifted.centers()).unwrap());
    assert_eq!(pairs(&mut backend), brute_force_pairs(&shifted));
    assert_eq!(backend.structure().unwrap(), first);
    // A centre that is not finite, anywhere: refused with its index, the build as it was.
    for bad in [0, 1234, 3999] {
        let mut centers = spheres.centers().to_vec();
        centers[bad][1] = f32::NAN;
        let refused = backend.move_centers(&centers);
        assert!(
            matches!(refused, Err(mochi::Error::InvalidSphere { index, .. }) if index == bad),
            "{refused:?}"
        );
        assert_eq!(pairs(&mut backend), brute_force_pairs(&shifted));
    }
    // A count unlike the build's: misuse of the library.
    let short = backend.move_centers(&shifted.centers()[1..]);
    assert!(matches!(short, Err(mochi::Error::Usage(_))), "{short:?}");
    // Spread to three times the size: a layout over the new bounds (the radii read back).
    let spread = moved(3.0, 0.0);
    assert!(backend.move_centers(spread.centers()).unwrap());
    assert_eq!(pairs(&mut backend), brute_force_pairs(&spread));
    assert_ne!(backend.structure().unwrap(), first);
    // And a move after that build.
    let back = moved(3.0, 0.1);
    assert!(backend.move_centers(back.centers()).unwrap());
    assert_eq!(pairs(&mut backend), brute_force_pairs(&back));
}
