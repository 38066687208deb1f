//! The `wgpu-compute` backend's multi-level grid (`--structure mlgrid`) against the oracle, on
//! random polydisperse sets and the scenes; the single grid is covered by backends_exact.rs.
//! Runs on any adapter (lavapipe in CI); under `CI=true` a missing adapter fails.

mod common;

use mochi::Backend;
use mochi::engines::wgpu_compute::{Structure, WgpuComputeBackend};
use mochi::gpu::Need;
use mochi::oracle::{brute_force_pairs, differences};
use mochi::{ProxyMode, SphereSet};
use rand::{RngExt, SeedableRng};

fn open(structure: Structure) -> Option<WgpuComputeBackend> {
    common::adapter_for(Need::Compute, "wgpu-compute").then(|| {
        let backend = WgpuComputeBackend::new().expect("a probed adapter opens");
        backend.with_structure(structure)
    })
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
    backend.build(spheres, ProxyMode::Mochi).unwrap();
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
        .build(&SphereSet::default(), ProxyMode::Mochi)
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
    let single_candidates = assert_exact(&mut single, &spheres, "grid");
    assert!(
        ml_candidates * 2 < single_candidates,
        "mlgrid {ml_candidates} vs grid {single_candidates} candidates"
    );
}
