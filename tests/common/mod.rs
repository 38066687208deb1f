//! Shared by the tests: which GPU tests run (CI runs them on lavapipe and must fail, not skip,
//! without an adapter), the steppers of the backends that run here, and small scene builders.
#![allow(dead_code)] // each test file uses the part it needs

pub mod impacts;
pub mod mbf;
pub mod rule_cases;
pub mod twin;

use mochi::ProxyMode;
use mochi::dem::{Material, Particles, StepParams, Stepper};
use mochi::engines::{BackendKind, Options, open_stepper};
use mochi::gpu::{self, Gpu, Need};

/// True when running under CI (`CI=true`), where every GPU test must find an adapter.
pub fn ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// Whether this run must test backend `kind` (a missing one fails it): under CI every backend
/// but optix (CI machines have no NVIDIA GPU); optix where `MOCHI_EXPECT_OPTIX=1`.
pub fn expected(kind: BackendKind) -> bool {
    match kind {
        BackendKind::Optix => std::env::var("MOCHI_EXPECT_OPTIX").is_ok_and(|v| v == "1"),
        _ => ci(),
    }
}

/// Every backend whose DEM step runs here: cpu always, and each GPU backend that this run
/// expects (`common::expected`: wgpu-compute and wgpu-rq under CI, optix with
/// `MOCHI_EXPECT_OPTIX=1`) or that probes here anyway.
pub fn dem_backends() -> Vec<BackendKind> {
    BackendKind::ALL
        .into_iter()
        .filter(|&kind| kind == BackendKind::Cpu || expected(kind) || kind.probe().is_ok())
        .collect()
}

/// Runs `test` on every backend of [`dem_backends`], naming the backend of a failure.
pub fn on_every_backend(test: impl Fn(BackendKind)) {
    for kind in dem_backends() {
        let _named = Naming(kind);
        test(kind);
    }
}

/// Names its backend when a test panics while it lives.
pub struct Naming(pub BackendKind);

impl Drop for Naming {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("(on the {} backend)", self.0.name());
        }
    }
}

/// Whether an adapter for `need` exists. Without one: a panic under CI, else a printed note
/// saying that `what` is not tested on this machine, and `false`.
pub fn adapter_for(need: Need, what: &str) -> bool {
    match gpu::probe(need) {
        Ok(_) => true,
        Err(why) => {
            assert!(!ci(), "CI expects a GPU adapter for {what}: {why}");
            eprintln!("note: {what} is not tested on this machine: {why}");
            false
        }
    }
}

/// An open compute device, or `None` as [`adapter_for`] decides.
pub fn open_gpu(what: &str) -> Option<Gpu> {
    adapter_for(Need::Compute, what)
        .then(|| Gpu::open(Need::Compute).expect("a probed adapter opens"))
}

/// Like [`open_gpu`], with the device's `max_compute_workgroups_per_dimension` lowered to `max`
/// (the device then rejects any dispatch wider than that).
pub fn open_gpu_lowered(what: &str, max: u32) -> Option<Gpu> {
    adapter_for(Need::Compute, what).then(|| {
        Gpu::open_limited(Need::Compute, |limits| {
            limits.max_compute_workgroups_per_dimension = max;
        })
        .expect("a probed adapter opens")
    })
}

/// Like [`open_gpu`], with the device's `max_storage_buffer_binding_size` lowered to `bytes`
/// (what sizes its buffers by that limit splits or refuses at small sizes).
pub fn open_gpu_with_bindings_of(what: &str, bytes: u64) -> Option<Gpu> {
    adapter_for(Need::Compute, what).then(|| {
        Gpu::open_limited(Need::Compute, |limits| {
            limits.max_storage_buffer_binding_size = bytes;
        })
        .expect("a probed adapter opens")
    })
}

/// The largest difference of one coordinate between the same sphere in `a` and in `b` [m].
pub fn largest_gap(a: &mochi::dem::Particles, b: &mochi::dem::Particles) -> f32 {
    gaps(a, b).last().copied().unwrap_or(0.0)
}

/// The difference of the same sphere's centre in `a` and in `b` (its largest coordinate) [m], for
/// every sphere, in increasing order.
pub fn gaps(a: &mochi::dem::Particles, b: &mochi::dem::Particles) -> Vec<f32> {
    assert_eq!(a.len(), b.len());
    let mut gaps: Vec<f32> = a
        .positions
        .iter()
        .zip(&b.positions)
        .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).abs()).fold(0.0, f32::max))
        .collect();
    gaps.sort_by(f32::total_cmp);
    gaps
}

/// The backends whose DEM step the tests run, in the order they are reported.
pub const DEM_BACKENDS: [BackendKind; 4] = [
    BackendKind::Cpu,
    BackendKind::WgpuCompute,
    BackendKind::Optix,
    BackendKind::WgpuRq,
];

/// Whether this run tests the DEM step of `kind`: cpu always; a wgpu backend where its adapter
/// exists (as [`adapter_for`] decides; wgpu-rq needs ray queries, which lavapipe has); optix
/// where it is [`expected`] or probes.
pub fn dem_runs_here(kind: BackendKind) -> bool {
    match kind {
        BackendKind::Cpu => true,
        BackendKind::WgpuCompute => adapter_for(Need::Compute, "the wgpu-compute DEM step"),
        BackendKind::WgpuRq => adapter_for(Need::RayQuery, "the wgpu-rq DEM step"),
        BackendKind::Optix => expected(kind) || kind.probe().is_ok(),
    }
}

/// `kind`'s stepper over `particles` in proxy mode mochi (a backend [`dem_runs_here`] opens).
pub fn open_dem(
    kind: BackendKind,
    particles: &Particles,
    params: StepParams,
    options: &Options,
) -> Box<dyn Stepper> {
    open_stepper(kind, particles.clone(), params, ProxyMode::Mochi, options)
        .unwrap_or_else(|e| panic!("{} runs here but does not open: {e}", kind.name()))
}

/// `kind`'s stepper over `particles` in proxy mode mochi with default options, as [`open_dem`]
/// opens it, but the wgpu engines' on one device per engine for the whole test binary (their
/// `open_on`, the path a reopened step takes): every stepper after the first reuses the modules
/// and pipelines compiled on it, where a fresh device compiles them again (over a second for
/// wgpu-compute's granular step on lavapipe). For tests that open a stepper per case.
pub fn open_dem_shared(
    kind: BackendKind,
    particles: &Particles,
    params: StepParams,
) -> Box<dyn Stepper> {
    let setup = mochi::engines::DemSetup::new(particles.clone(), params, ProxyMode::Mochi);
    open_setup_shared(kind, setup)
}

/// As [`open_dem_shared`], for a whole setup (walls included).
pub fn open_setup_shared(kind: BackendKind, setup: mochi::engines::DemSetup) -> Box<dyn Stepper> {
    use mochi::engines::KernelSet;
    use mochi::engines::wgpu::compute::{GridStepOptions, GridStepper};
    use mochi::engines::wgpu::rq::RqStepper;
    use std::sync::OnceLock;
    static COMPUTE: OnceLock<Gpu> = OnceLock::new();
    static RAY_QUERY: OnceLock<Gpu> = OnceLock::new();
    let shared = |cell: &'static OnceLock<Gpu>, need: Need| {
        cell.get_or_init(|| Gpu::open(need).expect("a probed adapter opens"))
            .clone()
    };
    let opened: mochi::Result<Box<dyn Stepper>> = match kind {
        BackendKind::WgpuCompute => GridStepper::open_on(
            shared(&COMPUTE, Need::Compute),
            setup,
            GridStepOptions::default(),
        )
        .map(|s| Box::new(s) as Box<dyn Stepper>),
        BackendKind::WgpuRq => {
            RqStepper::open_on(shared(&RAY_QUERY, Need::RayQuery), setup, KernelSet::Auto)
                .map(|s| Box::new(s) as Box<dyn Stepper>)
        }
        _ => mochi::engines::open_setup(kind, setup, &Options::default()),
    };
    opened.unwrap_or_else(|e| panic!("{} runs here but does not open: {e}", kind.name()))
}

/// One stepper with default options per backend that [`dem_runs_here`], named as on the
/// command line.
pub fn default_steppers(
    particles: &Particles,
    params: StepParams,
) -> Vec<(&'static str, Box<dyn Stepper>)> {
    DEM_BACKENDS
        .into_iter()
        .filter(|&kind| dem_runs_here(kind))
        .map(|kind| {
            let stepper = open_dem(kind, particles, params.clone(), &Options::default());
            (kind.name(), stepper)
        })
        .collect()
}

/// Step parameters of `material` in the box `[0, side]³` with `gravity`, no gravity spin and
/// smallest radius `r_min`.
pub fn step_params(
    material: &Material,
    dt: f64,
    side: f64,
    gravity: [f64; 3],
    r_min: f32,
) -> StepParams {
    StepParams::new(material, dt, [0.0; 3], [side; 3], gravity, 0.0, r_min).unwrap()
}

/// Non-rotating spheres at `positions` with `velocities` and `radii`, at step 0.
pub fn particles(
    positions: Vec<[f32; 3]>,
    velocities: Vec<[f32; 3]>,
    radii: Vec<f32>,
) -> Particles {
    Particles {
        angular_velocities: vec![[0.0; 3]; radii.len()],
        positions,
        velocities,
        radii,
        ..Particles::default()
    }
}

/// The scenes' default material: Hertz–Mindlin (E 1e7 Pa, ν 0.3), μ 0.5, μ_r 0.1 (EPSD), at
/// the default density and restitution.
pub fn granular_material() -> Material {
    Material {
        contact: mochi::dem::model::ContactLaw::HertzMindlin {
            young_modulus: 1e7,
            poisson_ratio: 0.3,
        },
        friction: 0.5,
        rolling_friction: 0.1,
        ..Material::default()
    }
}

/// A seeded source of numbers in [−0.5, 0.5) (a linear congruential generator: the same
/// numbers on every machine).
pub fn noise(seed: u64) -> impl FnMut() -> f32 {
    let mut seed = seed;
    move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 40) as f32) / (1u64 << 24) as f32 - 0.5
    }
}

/// `n` spheres of 5 mm within 2 mm of (0.5, 0.5, 0.5), moving every which way at up to 0.05 m/s
/// (a fixed pseudo-random draw): every pair touches, so the sphere that owns the others' pairs
/// holds far more contacts than the 16 history slots a run starts with.
pub fn clump(n: usize) -> Particles {
    let mut rand = noise(5);
    let mut start = particles(Vec::new(), Vec::new(), Vec::new());
    for _ in 0..n {
        start.positions.push([0; 3].map(|_| 0.5 + 0.002 * rand()));
        start.velocities.push([0; 3].map(|_| 0.1 * rand()));
        start.angular_velocities.push([0.0; 3]);
        start.radii.push(0.005);
    }
    start
}

/// Asserts that every sphere of `got` (a [`clump`]) keeps a contact with every other one.
pub fn assert_keeps_every_pair(what: &str, got: &Particles) {
    let n = got.len();
    for i in 0..n {
        let mut partners: Vec<u32> = got.history.of(i).iter().map(|e| e.partner).collect();
        partners.sort();
        let all: Vec<u32> = (0..n as u32).filter(|&j| j != i as u32).collect();
        assert_eq!(partners, all, "{what}: the contacts sphere {i} kept");
    }
}
