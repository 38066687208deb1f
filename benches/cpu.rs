//! The cpu backend's build (binning), update and detection, on the reference workloads:
//! 100k `poly120` spheres and 1M `freefall` spheres, both modes. `update` is the refit path of
//! [`Backend::update`] after every sphere moved a little, as in one DEM step (the cpu backend
//! re-bins; a BVH backend would refit).
//!
//! Run: `cargo bench --bench cpu` (add `-- poly120` to pick a group).

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use mochi::Backend;
use mochi::engines::cpu::CpuBackend;
use mochi::scenes::{Layout, Scene, SceneSpec, generate};
use mochi::{ProxyMode, SphereSet};
use std::hint::black_box;
use std::time::Duration;

fn scene(scene: Scene, n: usize, layout: Layout) -> SphereSet {
    generate(&SceneSpec {
        scene,
        n,
        seed: 1,
        layout,
    })
    .expect("benchmark scene")
}

fn workloads() -> Vec<(&'static str, SphereSet)> {
    vec![
        (
            "poly120_100k_random",
            scene(Scene::Poly120, 100_000, Layout::Random),
        ),
        (
            "poly120_100k_lattice",
            scene(Scene::Poly120, 100_000, Layout::Lattice),
        ),
        (
            "freefall_1m",
            scene(Scene::Freefall, 1_000_000, Layout::Lattice),
        ),
        (
            "slab_1m_random",
            scene(Scene::Slab, 1_000_000, Layout::Random),
        ),
    ]
}

/// `spheres` with every centre moved by `dx` along x, as after a small time step.
fn moved(spheres: &SphereSet, dx: f32) -> SphereSet {
    let centers = spheres
        .centers()
        .iter()
        .map(|c| [c[0] + dx, c[1], c[2]])
        .collect();
    SphereSet::new(centers, spheres.radii().to_vec()).expect("moved spheres stay valid")
}

fn bench(c: &mut Criterion) {
    for (name, spheres) in workloads() {
        // Two states a tenth of the smallest radius apart: each update sees moved spheres.
        let states = [moved(&spheres, 5e-5), spheres.clone()];
        let mut group = c.benchmark_group(format!("cpu/{name}"));
        group
            .sample_size(20)
            .measurement_time(Duration::from_secs(4));
        for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
            let mut cpu = CpuBackend::new();
            cpu.build(spheres.view(), mode).unwrap();
            group.bench_function(format!("{}/build+find_pairs", mode.name()), |b| {
                b.iter(|| {
                    cpu.build(spheres.view(), mode).unwrap();
                    black_box(cpu.find_pairs().unwrap())
                })
            });
            group.bench_function(format!("{}/build", mode.name()), |b| {
                b.iter(|| cpu.build(spheres.view(), mode).unwrap())
            });
            let mut next = 0;
            group.bench_function(format!("{}/update", mode.name()), |b| {
                b.iter(|| {
                    next = 1 - next;
                    cpu.update(states[next].view()).unwrap()
                })
            });
            group.bench_function(format!("{}/find_pairs", mode.name()), |b| {
                b.iter_batched(
                    || (),
                    |()| black_box(cpu.find_pairs().unwrap()),
                    BatchSize::SmallInput,
                )
            });
            group.bench_function(format!("{}/count_pairs", mode.name()), |b| {
                b.iter(|| black_box(cpu.count_pairs().unwrap()))
            });
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
