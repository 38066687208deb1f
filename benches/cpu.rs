//! The cpu backend's build (binning), update and detection, on the reference workloads:
//! 100k `poly120` spheres and 1M `freefall` spheres, both modes.
//!
//! Run: `cargo bench --bench cpu` (add `-- poly120` to pick a group).

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use mochi::backend::{Backend, cpu::CpuBackend};
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

fn bench(c: &mut Criterion) {
    for (name, spheres) in workloads() {
        let mut group = c.benchmark_group(format!("cpu/{name}"));
        group
            .sample_size(20)
            .measurement_time(Duration::from_secs(4));
        for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
            let mut cpu = CpuBackend::new();
            cpu.build(&spheres, mode).unwrap();
            group.bench_function(format!("{}/build+find_pairs", mode.name()), |b| {
                b.iter(|| {
                    cpu.build(&spheres, mode).unwrap();
                    black_box(cpu.find_pairs().unwrap())
                })
            });
            group.bench_function(format!("{}/build", mode.name()), |b| {
                b.iter(|| cpu.build(&spheres, mode).unwrap())
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
