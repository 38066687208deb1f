//! GPU backends' binning (build) and detection on 10k, 100k and 1M spheres of `slab`, `poly120`
//! and `polylog`, both modes. Criterion's time here is the **GPU time** from timestamps (build +
//! detection pass, without uploads or read-back), the figure the paper's kernels compare to;
//! backends or devices without timestamps are timed on the host instead.
//!
//! Run: `cargo bench --bench gpu` (needs an adapter; lists what it skipped and why).

use criterion::{Criterion, criterion_group, criterion_main};
use mochi::Backend;
use mochi::engines::BackendKind;
use mochi::scenes::{Layout, Scene, SceneSpec, generate};
use mochi::{ProxyMode, SphereSet};
use std::time::{Duration, Instant};

const GPU_BACKENDS: [BackendKind; 2] = [BackendKind::WgpuCompute, BackendKind::WgpuRq];

fn scene(scene: Scene, n: usize, layout: Layout) -> SphereSet {
    generate(&SceneSpec {
        scene,
        n,
        seed: 1,
        layout,
    })
    .expect("benchmark scene")
}

/// One build and one counting detection; GPU time where measured, else host time.
fn step(backend: &mut dyn Backend, spheres: &SphereSet, mode: ProxyMode) -> Duration {
    let t = Instant::now();
    backend.build(spheres.view(), mode).expect("build");
    backend.count_pairs().expect("detect");
    let host = t.elapsed();
    let gpu = backend.gpu_times();
    match (gpu.build_ms, gpu.detect_ms) {
        (Some(b), Some(d)) => Duration::from_secs_f64((b + d) * 1e-3),
        _ => host,
    }
}

fn bench(c: &mut Criterion) {
    for kind in GPU_BACKENDS {
        let mut backend = match kind.open() {
            Ok(b) => b,
            Err(e) => {
                eprintln!("{}: not benchmarked here: {e}", kind.name());
                continue;
            }
        };
        for n in [10_000, 100_000, 1_000_000] {
            for (name, spheres) in [
                ("slab_lattice", scene(Scene::Slab, n, Layout::Lattice)),
                ("slab_random", scene(Scene::Slab, n, Layout::Random)),
                ("poly120_random", scene(Scene::Poly120, n, Layout::Random)),
                ("polylog_random", scene(Scene::Polylog, n, Layout::Random)),
            ] {
                let mut group = c.benchmark_group(format!("{}/{name}/{n}", kind.name()));
                group
                    .sample_size(20)
                    .measurement_time(Duration::from_secs(3));
                for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
                    group.bench_function(format!("{}/build+detect", mode.name()), |b| {
                        b.iter_custom(|iters| {
                            (0..iters)
                                .map(|_| step(backend.as_mut(), &spheres, mode))
                                .sum()
                        })
                    });
                }
                group.finish();
            }
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
