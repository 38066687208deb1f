//! The optix backend's device programs compile with NVRTC 13.0 (CI installs it from PyPI, so a
//! broken `.cu` cannot land), and a machine without an NVIDIA driver gets a reason, not a
//! panic. The CUDA copy of the proxy rule (`optix/device.cuh`) decides the boundary cases of
//! `common/rule_cases.rs` exactly as `src/proxy.rs` does (it rounds every step as the cpu:
//! no fused multiply-adds). Its exactness is tested with every other backend in
//! backends_exact.rs.
#![cfg(feature = "optix")]

mod common;

use common::rule_cases::{assert_same_decisions, cases, records};
use cudarc::driver::{CudaContext, LaunchConfig, PushKernelArg};
use mochi::ProxyMode;
use mochi::engines::BackendKind;
use mochi::engines::optix::programs::{self, GranularLaw, Unit};

/// Runs `mochi_keep` of `optix/device.cuh` on each case record (`common::rule_cases::records`).
const RULE_KERNEL: &str = r#"
struct MochiCase { float4 a; float4 b; unsigned int i, j, mode, pad; };
extern "C" __global__ void rule_cases(const MochiCase* cases, unsigned int* kept, unsigned int n) {
    unsigned int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n) {
        return;
    }
    MochiCase c = cases[k];
    kept[k] = mochi_keep(c.mode, c.i, c.a, c.j, c.b) ? 1u : 0u;
}
"#;

/// A CUDA context on GPU 0, or why there is none.
fn cuda_context() -> Result<std::sync::Arc<CudaContext>, String> {
    // SAFETY: only tries to open the library.
    if !unsafe { cudarc::driver::sys::is_culib_present() } {
        return Err("no NVIDIA driver (libcuda.so) found".into());
    }
    CudaContext::new(0).map_err(|e| format!("opening GPU 0: {e}"))
}

#[test]
fn cuda_rule_matches_the_rust_rule() {
    let ptx = match programs::compile_with_rule("rule_cases.cu", RULE_KERNEL) {
        Ok(ptx) => ptx,
        Err(why) if !programs::nvrtc_present() => {
            assert!(!common::ci(), "CI expects NVRTC: {why}");
            eprintln!("note: the CUDA rule is not tested on this machine: {why}");
            return;
        }
        Err(why) => panic!("{why}"),
    };
    let context = match cuda_context() {
        Ok(context) => context,
        Err(why) => {
            assert!(
                !common::expected(BackendKind::Optix),
                "optix expected here, but the CUDA rule cannot run: {why}"
            );
            eprintln!("note: the CUDA rule is not run on this machine: {why}");
            return;
        }
    };
    let stream = context.default_stream();
    let module = context
        .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
        .unwrap();
    let function = module.load_function("rule_cases").unwrap();
    let cases = cases();
    let n = cases.len() as u32;
    for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
        let input = stream.clone_htod(&records(&cases, mode)).unwrap();
        let mut output = stream.alloc_zeros::<u32>(cases.len()).unwrap();
        let mut launch = stream.launch_builder(&function);
        launch.arg(&input).arg(&mut output).arg(&n);
        // SAFETY: the kernel reads n records of 12 words from `input` and writes n words.
        unsafe { launch.launch(LaunchConfig::for_num_elems(n)) }.unwrap();
        let kept = stream.clone_dtoh(&output).unwrap();
        // No fused multiply-adds: every case, on the boundary or not, as the cpu decides it.
        assert_same_decisions(mode, &cases, &kept, false);
    }
}

#[test]
fn device_programs_compile_with_nvrtc() {
    if !programs::nvrtc_present() {
        assert!(
            !common::ci(),
            "CI expects NVRTC (libnvrtc.so.13) on the library path: scripts/test.sh installs it"
        );
        eprintln!("note: NVRTC is not installed here; the device programs are not compiled");
        return;
    }
    let mut entries: Vec<(Unit, &[&str])> = vec![
        (
            Unit::Detect,
            &["__raygen__detect", "__intersection__detect", "params"],
        ),
        (
            Unit::Kernels,
            &["proxy_boxes", "dem_boxes", "dem_integrate", "dem_permute"],
        ),
        (
            Unit::Dem,
            &["__raygen__dem", "__intersection__dem", "params"],
        ),
    ];
    for law in GranularLaw::ALL {
        entries.push((
            Unit::Granular(law),
            &["__raygen__granular", "__intersection__granular", "params"],
        ));
        entries.push((
            Unit::GranularKernels(law),
            &["granular_integrate", "permute_rows"],
        ));
    }
    let mut compiled = Vec::new();
    for (unit, names) in entries {
        let ptx = programs::compile(unit).unwrap_or_else(|e| panic!("{e}"));
        for name in names {
            assert!(ptx.contains(name), "{}: no {name} in the PTX", unit.name());
        }
        compiled.push(ptx);
    }
    // Each law's programs are others than every other law's.
    let granular = &compiled[3..];
    for (k, a) in granular.iter().enumerate() {
        assert!(granular[k + 1..].iter().all(|b| a != b), "unit {k} twice");
    }
}

/// Every launch-parameter struct (and history entry) that the host hands the device code has,
/// in CUDA, the size and field offsets of its Rust twin: NVRTC compiles each unit followed by
/// `static_assert`s that the host writes from `offset_of!`.
#[test]
fn shared_structs_lie_where_the_device_code_reads_them() {
    if !programs::nvrtc_present() {
        assert!(!common::ci(), "CI expects NVRTC on the library path");
        eprintln!("note: NVRTC is not installed here; the layouts are not compared");
        return;
    }
    for unit in Unit::ALL {
        let checks = mochi::engines::optix::layout_checks(unit);
        assert!(checks.contains("static_assert(sizeof("), "{}", unit.name());
        programs::compile_with_checks(unit, &checks).unwrap_or_else(|e| panic!("{e}"));
    }
    // A wrong offset is caught.
    let spring = Unit::Granular(GranularLaw::default());
    let wrong = mochi::engines::optix::layout_checks(spring)
        .replace("LawParams, slots) == ", "LawParams, slots) == 4 + ");
    let err = programs::compile_with_checks(spring, &wrong).expect_err("a wrong offset");
    assert!(err.to_string().contains("LawParams.slots"), "{err}");
}

#[test]
fn optix_is_available_or_says_why() {
    match BackendKind::Optix.probe() {
        Ok(device) => {
            assert!(device.contains("OptiX ABI 105"), "{device}");
            let backend = BackendKind::Optix.open().expect("a probed device opens");
            assert_eq!(backend.info().name, "optix");
        }
        Err(why) => {
            assert!(
                !common::expected(BackendKind::Optix),
                "optix expected here: {why}"
            );
            assert!(!why.is_empty());
            let err = BackendKind::Optix
                .open()
                .err()
                .expect("open fails as probe did");
            assert!(err.to_string().contains("optix"), "{err}");
        }
    }
}

/// Every counter index of the device programs (`i & MASKu`) masks to `COUNTER_SLOTS`, the
/// length of the counter buffers the host allocates.
#[test]
fn counter_masks_match_the_counter_buffers() {
    use mochi::engines::optix::COUNTER_SLOTS;
    assert!(COUNTER_SLOTS.is_power_of_two());
    for (name, source) in [
        ("detect.cu", include_str!("../optix/detect.cu")),
        ("dem.cu", include_str!("../optix/dem.cu")),
        ("granular.cu", include_str!("../optix/granular.cu")),
    ] {
        let masks: Vec<usize> = source
            .split("& ")
            .skip(1)
            .filter_map(|rest| {
                let digits =
                    rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len();
                (digits > 0 && rest[digits..].starts_with('u'))
                    .then(|| rest[..digits].parse().unwrap())
            })
            .collect();
        assert!(!masks.is_empty(), "{name}: no counter index");
        for mask in masks {
            assert_eq!(
                mask,
                COUNTER_SLOTS - 1,
                "{name}: a counter index masked by {mask}"
            );
        }
    }
}

/// An NVRTC failure is a typed compile error carrying the compiler's log, and converts into the
/// crate's one OptiX/CUDA variant; a missing NVRTC is an unavailable backend instead.
#[test]
fn compile_errors_carry_the_nvrtc_log() {
    use mochi::{Error, OptixError};
    let broken = r#"extern "C" __global__ void broken() { undeclared_name = 1; }"#;
    let err = programs::compile_with_rule("broken.cu", broken).expect_err("does not compile");
    if !programs::nvrtc_present() {
        assert!(!common::ci(), "CI expects NVRTC: {err}");
        assert!(matches!(
            Error::from(err),
            Error::BackendUnavailable {
                backend: "optix",
                ..
            }
        ));
        return;
    }
    match &err {
        OptixError::Compile { unit, log } => {
            assert_eq!(unit, "broken.cu");
            assert!(log.contains("undeclared_name"), "{log}");
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(Error::from(err), Error::Optix(_)));
}

// ---- The granular step (GPU only: each test says why it skips without one) -------------------

use mochi::dem::flow::FlowSet;
use mochi::dem::model::time_step::rayleigh_time;
use mochi::dem::model::{
    ContactLaw, Material, Materials, PairOverride, RollingModel, TangentialModel,
};
use mochi::dem::scene::Start;
use mochi::dem::walls::{WallConfig, WallSet};
use mochi::dem::{Particles, StepParams, Stepper};
use mochi::engines::{BackendChoice, Options, open_scene};
use mochi::mesh::Mesh;

const E: f64 = 1e7;
const RHO: f64 = 2500.0;

/// The step of `backend` over `particles` in the box, or `None` (with a note) where optix does
/// not run here and is not expected.
fn stepper(backend: BackendKind, particles: &Particles, p: StepParams) -> Option<Box<dyn Stepper>> {
    stepper_in(backend, particles, p, &WallSet::default())
}

/// As [`stepper`], inside `walls`.
fn stepper_in(
    backend: BackendKind,
    particles: &Particles,
    p: StepParams,
    walls: &WallSet,
) -> Option<Box<dyn Stepper>> {
    if backend == BackendKind::Optix
        && let Err(why) = BackendKind::Optix.probe()
    {
        assert!(
            !common::expected(BackendKind::Optix),
            "optix expected here: {why}"
        );
        eprintln!("note: the optix granular step is not run here: {why}");
        return None;
    }
    let start = Start {
        particles: particles.clone(),
        params: p,
        mode: ProxyMode::Mochi,
        walls: walls.clone(),
        flow: FlowSet::default(),
    };
    let choice = BackendChoice::Named(backend);
    Some(
        open_scene(choice, start, &Options::default())
            .unwrap()
            .value,
    )
}

/// A material with friction `mu` and rolling resistance `mu_r` of `model` under `contact`.
fn frictional(contact: ContactLaw, mu: f64, mu_r: f64, model: RollingModel) -> Material {
    Material {
        density: RHO,
        restitution: 0.5,
        contact,
        friction: mu,
        rolling_friction: mu_r,
        rolling_model: model,
        ..Material::default()
    }
}

/// 48 spheres of radius `r` in 3 layers of 4 × 4, a little closer than touching (1.96·r apart,
/// jittered by 0.05·r) on the floor of the middle of a box of side `side`, moving and
/// turning at random (a fixed seed).
fn pressed_layers(r: f32, side: f32) -> Particles {
    let mut rand = common::noise(11);
    let spacing = 1.96 * r;
    let mut p = Particles::default();
    for k in 0..48 {
        let at = [k % 4, (k / 4) % 4, k / 16].map(|i| i as f32);
        let x = side / 2.0 + (at[0] - 1.5) * spacing + 0.05 * r * rand();
        let y = side / 2.0 + (at[1] - 1.5) * spacing + 0.05 * r * rand();
        let z = 0.98 * r + at[2] * spacing + 0.05 * r * rand();
        p.positions.push([x, y, z]);
        p.velocities.push([0; 3].map(|_| 0.2 * rand()));
        p.angular_velocities.push([0; 3].map(|_| 20.0 * rand()));
        p.radii.push(r);
    }
    p
}

/// `n` spheres of radius `r` whose centres lie within half a radius of one another (every
/// pair overlaps) in the middle of a box of side `side`, moving at random.
fn clump(n: usize, r: f32, side: f32) -> Particles {
    let mut rand = common::noise(5);
    let mut p = Particles::default();
    for k in 0..n {
        let t = k as f32 * 2.4;
        let h = 0.4 * r * (k as f32 / n as f32 - 0.5);
        p.positions.push([
            side / 2.0 + 0.3 * r * t.cos(),
            side / 2.0 + 0.3 * r * t.sin(),
            side / 2.0 + h,
        ]);
        p.velocities.push([0; 3].map(|_| 0.2 * rand()));
        p.angular_velocities.push([0.0; 3]);
        p.radii.push(r);
    }
    p
}

/// Largest difference of `of` between the same sphere of `a` and `b`.
fn gap(a: &Particles, b: &Particles, of: impl Fn(&Particles, usize) -> [f32; 3]) -> f32 {
    (0..a.len())
        .flat_map(|i| {
            let (x, y) = (of(a, i), of(b, i));
            (0..3).map(move |k| (x[k] - y[k]).abs())
        })
        .fold(0.0, f32::max)
}

/// Largest magnitude of a component of `of` over the spheres of `a`.
fn largest(a: &Particles, of: impl Fn(&Particles, usize) -> [f32; 3]) -> f32 {
    (0..a.len())
        .flat_map(|i| of(a, i))
        .fold(0.0, |m, x| m.max(x.abs()))
}

/// The history of `p` as sorted (owner, partner) pairs with their springs and load histories
/// (zero where none are kept).
fn contacts(p: &Particles) -> Vec<(u32, u32, [f32; 10])> {
    let loads: Vec<_> = p.history.contact_loads().copied().collect();
    let mut out: Vec<_> = (p.history.contacts().enumerate())
        .map(|(k, (owner, e))| {
            let [a, b, c] = e.tangential;
            let [d, f, g] = e.rolling;
            let l = loads.get(k).copied().unwrap_or_default();
            let [h, i, j] = l.reversal;
            (owner, e.partner, [a, b, c, d, f, g, h, i, j, l.normal])
        })
        .collect();
    out.sort_by_key(|&(o, q, _)| (o, q));
    out
}

/// Runs `particles` for `steps` steps on the cpu and on optix and compares positions,
/// velocities, angular velocities, materials and the contact history (both sides); returns both
/// ends.
fn compare_with_cpu(particles: &Particles, p: StepParams, steps: u32) -> Option<[Particles; 2]> {
    compare_with_cpu_in(particles, p, &WallSet::default(), steps).map(|(ends, _)| ends)
}

/// As [`compare_with_cpu`], inside `walls`; returns the optix step too.
fn compare_with_cpu_in(
    particles: &Particles,
    p: StepParams,
    walls: &WallSet,
    steps: u32,
) -> Option<([Particles; 2], Box<dyn Stepper>)> {
    let mut gpu = stepper_in(BackendKind::Optix, particles, p.clone(), walls)?;
    let mut cpu = stepper_in(BackendKind::Cpu, particles, p, walls).unwrap();
    cpu.advance(steps).unwrap();
    gpu.advance(steps).unwrap();
    let (a, b) = (cpu.particles().unwrap(), gpu.particles().unwrap());
    assert_eq!(a.materials, b.materials, "materials");
    let r = particles.radius_range().0;
    // The two differ only in the order of the force sums (atomics on the GPU): f32 rounding,
    // far below a millionth of a radius over a few steps.
    let dx = gap(&a, &b, |p, i| p.positions[i]);
    assert!(dx <= 1e-5 * r, "positions differ by {dx:e} m");
    let v = largest(&a, |p, i| p.velocities[i]);
    let dv = gap(&a, &b, |p, i| p.velocities[i]);
    assert!(dv <= 1e-3 * v.max(1e-3), "velocities differ by {dv:e} m/s");
    let w = largest(&a, |p, i| p.angular_velocities[i]);
    let dw = gap(&a, &b, |p, i| p.angular_velocities[i]);
    assert!(
        dw <= 1e-3 * w.max(1e-3),
        "angular velocities differ by {dw:e} rad/s"
    );
    let (ca, cb) = (contacts(&a), contacts(&b));
    assert_eq!(
        a.history.has_loads(),
        b.history.has_loads(),
        "load histories kept"
    );
    let pairs = |c: &[(u32, u32, [f32; 10])]| c.iter().map(|&(o, q, _)| (o, q)).collect::<Vec<_>>();
    assert_eq!(pairs(&ca), pairs(&cb), "the two hold different contacts");
    // The springs against their largest value, the reversals and the normal forces of the
    // load histories against theirs.
    let largest = |ks: std::ops::Range<usize>| {
        ca.iter()
            .flat_map(|c| c.2[ks.clone()].to_vec())
            .fold(0.0f32, |m, x| m.max(x.abs()))
    };
    let scales = [largest(0..6), largest(6..9), largest(9..10)];
    for ((o, q, x), (_, _, y)) in ca.iter().zip(&cb) {
        for k in 0..10 {
            let scale = scales[[0, 0, 0, 0, 0, 0, 1, 1, 1, 2][k]];
            assert!(
                (x[k] - y[k]).abs() <= 1e-3 * scale,
                "springs of {o} with {q}: cpu {x:?}, optix {y:?}"
            );
        }
    }
    Some(([a, b], gpu))
}

#[test]
fn the_granular_step_follows_the_cpu_step() {
    let r = 0.005f32;
    let hertz = ContactLaw::HertzMindlin {
        young_modulus: E,
        poisson_ratio: 0.3,
    };
    let dt = 0.2 * rayleigh_time(r as f64, RHO, E, 0.3);
    let per_pair = ContactLaw::LinearPerPair {
        contact_time: Some(20.0 * dt),
    };
    let start = pressed_layers(r, 0.1);
    for material in [
        frictional(hertz, 0.5, 0.1, RollingModel::Epsd),
        frictional(hertz, 0.3, 0.05, RollingModel::ConstantTorque),
        frictional(per_pair, 0.4, 0.0, RollingModel::Epsd),
        // No friction: the granular programs for the Hertz law alone.
        frictional(hertz, 0.0, 0.0, RollingModel::Epsd),
        // Mindlin–Deresiewicz: its programs and load histories.
        Material {
            tangential_model: TangentialModel::MindlinDeresiewicz,
            ..frictional(hertz, 0.5, 0.1, RollingModel::Epsd)
        },
    ] {
        let p =
            StepParams::new(&material, dt, [0.0; 3], [0.1; 3], [0.0, 0.0, -9.81], 0.0, r).unwrap();
        let Some([cpu, _]) = compare_with_cpu(&start, p, 20) else {
            return;
        };
        assert_eq!(cpu.history.is_empty(), material.friction == 0.0);
    }
}

#[test]
fn a_clump_with_more_contacts_than_history_slots_keeps_every_one() {
    // 24 spheres all overlapping one another: whichever ray owns a pair, some sphere owns more
    // contacts than the 16 slots a run starts with, so the first batch starts over with more.
    let r = 0.005f32;
    let start = clump(24, r, 0.1);
    let material = frictional(
        ContactLaw::HertzMindlin {
            young_modulus: E,
            poisson_ratio: 0.3,
        },
        0.5,
        0.1,
        RollingModel::Epsd,
    );
    let dt = 0.02 * rayleigh_time(r as f64, RHO, E, 0.3);
    let p = StepParams::new(&material, dt, [0.0; 3], [0.1; 3], [0.0; 3], 0.0, r).unwrap();
    let Some([cpu, gpu]) = compare_with_cpu(&start, p.clone(), 3) else {
        return;
    };
    for (i, held) in (0..24).map(|i| (i, gpu.history.of(i))) {
        assert_eq!(held.len(), 23, "sphere {i} holds {} contacts", held.len());
    }
    assert_eq!(contacts(&cpu).len(), 24 * 23);
    let mut s = stepper(BackendKind::Optix, &start, p).unwrap();
    s.advance(1).unwrap();
    assert!(
        !s.describe().contains("granular step, 16 history slots"),
        "{}",
        s.describe()
    );
}

#[test]
fn a_granular_state_reads_back_as_it_went_up() {
    // A cpu run's state, springs (both sides) and spins included, read back from optix before
    // any step is the same state: it resumes on any backend.
    let r = 0.005f32;
    let material = frictional(
        ContactLaw::HertzMindlin {
            young_modulus: E,
            poisson_ratio: 0.3,
        },
        0.5,
        0.1,
        RollingModel::Epsd,
    );
    let dt = 0.2 * rayleigh_time(r as f64, RHO, E, 0.3);
    let p = StepParams::new(&material, dt, [0.0; 3], [0.1; 3], [0.0, 0.0, -9.81], 0.0, r).unwrap();
    let mut cpu = stepper(BackendKind::Cpu, &pressed_layers(r, 0.1), p.clone()).unwrap();
    cpu.advance(10).unwrap();
    let state = cpu.particles().unwrap();
    assert!(!state.history.is_empty() && state.spin());
    let Some(mut gpu) = stepper(BackendKind::Optix, &state, p) else {
        return;
    };
    assert_eq!(gpu.particles().unwrap(), state);
    // So does one under Mindlin–Deresiewicz, its load histories included.
    let md = Material {
        tangential_model: TangentialModel::MindlinDeresiewicz,
        ..material
    };
    let p = StepParams::new(&md, dt, [0.0; 3], [0.1; 3], [0.0, 0.0, -9.81], 0.0, r).unwrap();
    let mut cpu = stepper(BackendKind::Cpu, &pressed_layers(r, 0.1), p.clone()).unwrap();
    cpu.advance(10).unwrap();
    let state = cpu.particles().unwrap();
    assert!(state.history.has_loads());
    let mut gpu = stepper(BackendKind::Optix, &state, p).unwrap();
    assert_eq!(gpu.particles().unwrap(), state);
}

/// A square of side `2·half` standing on the floor in the plane x = `x` (`axis` 0) or y = `x`
/// (`axis` 1), centred on `c` in the other horizontal coordinate: two triangles.
fn square(axis: usize, x: f64, c: f64, half: f64) -> Mesh {
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let vertices = corners
        .map(|(u, v)| {
            let (u, v) = (c + u * half, (1.0 + v) * half);
            match axis {
                0 => [x, u, v],
                _ => [u, x, v],
            }
        })
        .to_vec();
    Mesh {
        vertices,
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

#[test]
fn several_materials_follow_the_cpu_step() {
    // Two Hertz–Mindlin materials that differ in E, ν, density, restitution, friction and
    // rolling friction, their pair with coefficients of its own, spheres of both mixed; the box
    // of the second material, a mesh wall of the first, and a rigid one with friction of its
    // own, each touched by the outer spheres of one side.
    let r = 0.005f32;
    let hertz = |young_modulus, poisson_ratio| ContactLaw::HertzMindlin {
        young_modulus,
        poisson_ratio,
    };
    let glass = frictional(hertz(E, 0.3), 0.5, 0.1, RollingModel::Epsd);
    let steel = Material {
        density: 7800.0,
        restitution: 0.8,
        ..frictional(hertz(5.0 * E, 0.2), 0.3, 0.05, RollingModel::Epsd)
    };
    let materials = Materials {
        list: vec![glass, steel],
        names: vec!["glass".into(), "steel".into()],
        pairs: vec![PairOverride {
            a: 0,
            b: 1,
            restitution: Some(0.6),
            friction: Some(0.2),
            rolling_friction: Some(0.02),
            ..PairOverride::default()
        }],
    };
    let dt = 0.2
        * rayleigh_time(r as f64, RHO, E, 0.3).min(rayleigh_time(r as f64, 7800.0, 5.0 * E, 0.2));
    let gravity = [0.0, 0.0, -9.81];
    let (side, box_material) = (0.1, Some(1));
    let p = StepParams::with_materials(
        &materials,
        box_material,
        dt,
        [0.0; 3],
        [side; 3],
        gravity,
        0.0,
        r,
    )
    .unwrap();
    let mut start = pressed_layers(r, side as f32);
    start.materials = (0..start.len()).map(|k| (k % 3 == 1) as u8).collect();
    // The layers' outer centres lie 1.5 spacings (1.96·r) from the middle, give or take 0.05·r.
    let reach = 1.5 * 1.96 * r as f64 + 0.98 * r as f64;
    let (mid, half) = (side / 2.0, 6.0 * r as f64);
    let wall = |k: usize, mesh: &Mesh, material: Option<u32>, friction: Option<f32>| {
        let mut wall = WallConfig::of(format!("side {k}"))
            .build_from(k, mesh, material)
            .unwrap();
        wall.friction = friction;
        wall
    };
    let walls = WallSet::new(
        true,
        vec![
            wall(0, &square(0, mid + reach, mid, half), Some(0), None),
            wall(1, &square(1, mid - reach, mid, half), None, Some(0.7)),
        ],
    )
    .unwrap();
    let Some(([cpu, _], mut gpu)) = compare_with_cpu_in(&start, p, &walls, 20) else {
        return;
    };
    // Both mesh walls and both materials were touched.
    for wall in [0, 1] {
        let partner = mochi::dem::FIRST_MESH_WALL + wall;
        assert!(
            (0..cpu.len()).any(|i| cpu.history.of(i).iter().any(|e| e.partner == partner)),
            "no sphere touches mesh wall {wall}"
        );
    }
    // The materials travel with their spheres through the Morton re-sorts (every 2,000 steps).
    gpu.advance(4000).unwrap();
    assert_eq!(gpu.particles().unwrap().materials, start.materials);
}
