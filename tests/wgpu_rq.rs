//! The `wgpu-rq` backend beyond the shared exactness suite: scenes split over several BLAS,
//! growing the pair buffer, and what it reports. Runs on any adapter with ray queries (lavapipe
//! in CI); under `CI=true` a missing adapter fails.

mod common;

use mochi::Backend;
use mochi::engines::wgpu::rq::WgpuRqBackend;
use mochi::gpu::Need;
use mochi::oracle::{brute_force_pairs, differences};
use mochi::scenes::{Layout, Scene, SceneSpec, generate};
use mochi::{ProxyMode, SphereSet};

/// The backend, or `None` where no adapter has ray queries (see `common::adapter_for`).
fn open() -> Option<WgpuRqBackend> {
    common::adapter_for(Need::RayQuery, "wgpu-rq")
        .then(|| WgpuRqBackend::new().expect("a probed adapter opens"))
}

fn scene(scene: Scene, n: usize, layout: Layout) -> SphereSet {
    generate(&SceneSpec {
        scene,
        n,
        seed: 21,
        layout,
    })
    .unwrap()
}

#[test]
fn scenes_split_over_several_blas_stay_exact() {
    let Some(backend) = open() else { return };
    let mut backend = backend.with_blas_capacity(777);
    let spheres = scene(Scene::Slab, 5000, Layout::Random);
    let want = brute_force_pairs(&spheres);
    assert!(!want.is_empty());
    for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
        backend.build(spheres.view(), mode).unwrap();
        let (got, stats) = backend.find_pairs().unwrap();
        let off = differences(&got, &want, &spheres, true);
        assert!(off.is_empty(), "{mode:?}: differs from the oracle: {off:?}");
        assert_eq!(stats.pairs, want.len() as u64);
    }
}

#[test]
fn a_dense_scene_grows_the_pair_buffer() {
    let Some(mut backend) = open() else { return };
    // Many more pairs than spheres: the first pass overflows the initial buffer.
    let spheres = scene(Scene::Slab, 3000, Layout::Random);
    let grown: Vec<_> = spheres.radii().iter().map(|r| r * 40.0).collect();
    let spheres = SphereSet::new(spheres.centers().to_vec(), grown).unwrap();
    let want = brute_force_pairs(&spheres);
    assert!(want.len() > 4 * spheres.len(), "{} pairs", want.len());
    backend.build(spheres.view(), ProxyMode::Mochi).unwrap();
    let got = backend.find_pairs().unwrap().0;
    assert!(differences(&got, &want, &spheres, true).is_empty());
}

#[test]
fn mochi_mode_tests_fewer_candidates_than_nns_on_mixed_radii() {
    let Some(mut backend) = open() else { return };
    let spheres = scene(Scene::Poly120, 8000, Layout::Random);
    backend.build(spheres.view(), ProxyMode::Mochi).unwrap();
    let mochi = backend.count_pairs().unwrap();
    backend.build(spheres.view(), ProxyMode::Nns).unwrap();
    let nns = backend.count_pairs().unwrap();
    assert_eq!(mochi.pairs, nns.pairs);
    // Every ray also meets its own box: compare the candidates beyond those.
    let n = spheres.len() as u64;
    assert!(
        (mochi.candidates - n) * 3 < nns.candidates - n,
        "{mochi:?} vs {nns:?}"
    );
}

#[test]
fn reports_its_adapter_and_limits() {
    let Some(backend) = open() else { return };
    let info = backend.info();
    assert_eq!(info.name, "wgpu-rq");
    assert!(!info.device.is_empty());
    assert!(info.max_spheres >= 1 << 20, "{info:?}");
}
