//! The DEM step on every backend: physics checks against theory, conservation, a settled pile
//! (resting on the floor, which carries its weight), a long tumbling run (inside the box, where
//! gravity points), coincident spheres (a few, and groups of thousands that stack on the floor),
//! and the GPU steps against the cpu step on the same scene, also under rotating gravity resumed
//! at a later step; the wgpu-compute step's sorted-key build against its dense build. Every check fails for a step that does nothing.

mod common;

use mochi::dem::model::{ContactLaw, mass, stable_dt, stiffness_for_duration};
use mochi::dem::{Clock, Material, Particles, StepParams, Stepper};
use mochi::engines::BackendKind;
use mochi::engines::wgpu::compute::{
    BuildKind, GridBuild, GridStepOptions, GridStepper, Sorting, Structure,
};
use mochi::engines::wgpu::rq::RqStepper;
use mochi::engines::{DemSetup, KernelSet};
use mochi::engines::{Options, RebuildPolicy};
use mochi::proxy::ProxyMode;

use common::particles;

/// Each backend's stepper that runs here ([`common::dem_runs_here`]), with a label: the GPU
/// ones also with the compare-and-swap force path, wgpu-compute also on the multi-level grid,
/// optix under each rebuild policy.
fn steppers(particles: &Particles, params: StepParams) -> Vec<(String, Box<dyn Stepper>)> {
    let mut out: Vec<(String, Box<dyn Stepper>)> = Vec::new();
    for kind in common::DEM_BACKENDS {
        if !common::dem_runs_here(kind) {
            continue;
        }
        match kind {
            BackendKind::Cpu => {
                out.push((
                    "cpu".into(),
                    common::open_dem(kind, particles, params.clone(), &Options::default()),
                ));
            }
            BackendKind::WgpuCompute => {
                for atomics in [KernelSet::Auto, KernelSet::Portable] {
                    let setup = DemSetup::new(particles.clone(), params.clone(), ProxyMode::Mochi);
                    let options = GridStepOptions {
                        kernels: atomics,
                        ..GridStepOptions::default()
                    };
                    let s = GridStepper::open(setup, options).unwrap();
                    out.push((format!("wgpu-compute {atomics:?}"), Box::new(s)));
                }
                for (structure, grid_build, label) in [
                    (Structure::Mlgrid, GridBuild::Auto, "mlgrid"),
                    (Structure::Auto, GridBuild::Sorted, "sorted"),
                    (Structure::Mlgrid, GridBuild::Sorted, "mlgrid sorted"),
                ] {
                    let options = Options {
                        structure,
                        grid_build,
                        ..Options::default()
                    };
                    out.push((
                        format!("wgpu-compute {label}"),
                        common::open_dem(kind, particles, params.clone(), &options),
                    ));
                }
            }
            BackendKind::Optix => {
                for rebuild in [
                    RebuildPolicy::Every(1),
                    RebuildPolicy::Every(7),
                    RebuildPolicy::Auto,
                ] {
                    let options = Options {
                        rebuild,
                        ..Options::default()
                    };
                    let s = common::open_dem(kind, particles, params.clone(), &options);
                    assert!(s.refits());
                    out.push((format!("optix rebuild {rebuild}"), s));
                }
            }
            BackendKind::WgpuRq => {
                for atomics in [KernelSet::Auto, KernelSet::Portable] {
                    let setup = DemSetup::new(particles.clone(), params.clone(), ProxyMode::Mochi);
                    let s = RqStepper::open(setup, atomics).unwrap();
                    out.push((format!("wgpu-rq {atomics:?}"), Box::new(s)));
                }
            }
        }
    }
    out
}

fn params(material: Material, dt: f64, side: f64, gravity: [f64; 3], r_min: f32) -> StepParams {
    common::step_params(&material, dt, side, gravity, r_min)
}

#[test]
fn head_on_collision_reaches_the_configured_restitution() {
    for e in [0.3, 0.5, 0.9] {
        let r = 0.01f32;
        // A contact resolved in 400 steps (semi-implicit Euler damps first-order in dt: at the default 10 steps per contact its own
        // error lowers e by about 9%, at 100 steps by 2%).
        let m_eff = mass(500.0, r) as f64 / 2.0;
        let material = Material {
            restitution: e,
            stiffness: Some(stiffness_for_duration(m_eff, e, 400.0 * 1e-5)),
            ..Material::default()
        };
        let v0 = 0.5f32;
        let start = particles(
            vec![[0.489, 0.5, 0.5], [0.511, 0.5, 0.5]],
            vec![[v0, 0.0, 0.0], [-v0, 0.0, 0.0]],
            vec![r, r],
        );
        let p = params(material, 1e-5, 1.0, [0.0; 3], r);
        for (name, mut s) in steppers(&start, p) {
            // Approach 2 mm at 1 m/s closing speed (200 steps), contact 400 steps.
            s.advance(1000).unwrap();
            let end = s.particles().unwrap();
            let closing_after = end.velocities[1][0] - end.velocities[0][0];
            let got = closing_after / (2.0 * v0);
            assert!(
                (got as f64 - e).abs() <= 0.02 * e,
                "{name}: restitution {got}, configured {e}"
            );
            assert!(
                end.velocities.iter().all(|v| v[1] == 0.0 && v[2] == 0.0),
                "{name}"
            );
        }
    }
}

#[test]
fn a_free_cluster_conserves_momentum() {
    // 300 spheres thrown together, no gravity, walls far away.
    let mut positions = Vec::new();
    let mut velocities = Vec::new();
    let mut radii = Vec::new();
    let mut noise = common::noise(12345);
    let mut rand = move || noise() + 0.5;
    for k in 0..300 {
        let (x, y, z) = ((k % 7) as f32, ((k / 7) % 7) as f32, (k / 49) as f32);
        positions.push([5.0 + 0.021 * x, 5.0 + 0.021 * y, 5.0 + 0.021 * z]);
        velocities.push([rand() - 0.5, rand() - 0.5, rand() - 0.5]);
        radii.push(0.008 + 0.004 * rand());
    }
    let start = particles(positions, velocities, radii);
    let p = params(Material::default(), 2e-5, 10.0, [0.0; 3], 0.008);
    let momentum = |s: &Particles| {
        let mut m = [0.0f64; 3];
        for (v, &r) in s.velocities.iter().zip(&s.radii) {
            for a in 0..3 {
                m[a] += mass(500.0, r) as f64 * v[a] as f64;
            }
        }
        m
    };
    let before = momentum(&start);
    let scale: f64 = start
        .velocities
        .iter()
        .zip(&start.radii)
        .map(|(v, &r)| mass(500.0, r) as f64 * v.iter().map(|x| x.abs() as f64).sum::<f64>())
        .sum();
    for (name, mut s) in steppers(&start, p) {
        // Neighbours overlap from the start.
        let first = s.advance(1).unwrap();
        assert!(first.contacts > 0, "{name}: the cluster should collide");
        s.advance(499).unwrap();
        let after = momentum(&s.particles().unwrap());
        for k in 0..3 {
            assert!(
                (after[k] - before[k]).abs() <= 1e-5 * scale,
                "{name}: momentum {after:?} vs {before:?}"
            );
        }
    }
}

/// `n_side`³ spheres of radius 0.008–0.01 on a lattice of `spacing` from 0.02, every other sphere
/// nudged along x by up to `jitter`.
fn pile(n_side: usize, spacing: f32, jitter: f32) -> Particles {
    let mut positions = Vec::new();
    let mut radii = Vec::new();
    for k in 0..n_side * n_side * n_side {
        let idx = [k % n_side, (k / n_side) % n_side, k / (n_side * n_side)];
        let nudge = ((k * 7919) % 11) as f32 / 10.0 * jitter;
        positions.push(std::array::from_fn(|a| {
            0.02 + spacing * idx[a] as f32 + if a == 0 { nudge } else { 0.0 }
        }));
        radii.push(0.01 - ((k * 31) % 5) as f32 * 0.0005);
    }
    let n = positions.len();
    particles(positions, vec![[0.0; 3]; n], radii)
}

#[test]
fn a_settled_pile_comes_to_rest_with_small_overlaps() {
    let start = pile(6, 0.025, 0.002);
    let material = Material {
        stiffness: Some(5e3),
        restitution: 0.1,
        ..Material::default()
    };
    let r_min = start.radius_range().0;
    let m_eff = mass(500.0, r_min) as f64 / 2.0;
    let dt = (stable_dt(5e3, m_eff, 0.59) / 5.0).min(2e-4);
    // Frictionless spheres slide sideways for ever on an open floor: walls close around the
    // pile so every motion ends in a (damped) normal contact, and a low restitution damps
    // the rattling of the top layer (the cpu step's exactly symmetric forces keep the lattice
    // from rattling at all; a GPU's rounding does not).
    let p = StepParams::new(
        &material,
        dt,
        [0.0; 3],
        [0.16, 0.16, 0.2],
        [0.0, 0.0, -9.81],
        0.0,
        r_min,
    )
    .unwrap();
    let steps = (1.2 / dt) as u32;
    for (name, mut s) in steppers(&start, p.clone()) {
        s.advance(steps).unwrap();
        let end = s.particles().unwrap();
        let speed = end
            .velocities
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .fold(0.0f32, f32::max);
        assert!(speed < 0.01, "{name}: still moving at {speed} m/s");
        let mut worst = 0.0f32;
        for i in 0..end.len() {
            for j in i + 1..end.len() {
                let (a, b) = (end.positions[i], end.positions[j]);
                let d =
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
                let overlap = end.radii[i] + end.radii[j] - d;
                worst = worst.max(overlap / end.radii[i].min(end.radii[j]));
            }
        }
        assert!(
            worst < 0.01,
            "{name}: max overlap {:.3}% of r",
            worst * 100.0
        );
        // The pile fell: a layer of at least its 36 columns rests on the floor (the columns
        // topple into a denser one), each sphere pressed in by about its own weight over k or
        // more (neighbours lean on it) but not by much more than its column's, and the floor
        // carries the whole pile (the side walls are frictionless: they carry none of it).
        let (k, g) = (p.stiffness, 9.81f32);
        let heaviest = mass(p.density, 0.01);
        let bottom: Vec<usize> = (0..end.len())
            .filter(|&i| end.positions[i][2] < 0.015)
            .collect();
        assert!(bottom.len() >= 36, "{name}: {} on the floor", bottom.len());
        for &i in &bottom {
            let (z, r) = (end.positions[i][2], end.radii[i]);
            let own = mass(p.density, r) * g / k;
            assert!(
                z <= r - 0.5 * own && z >= r - 20.0 * heaviest * g / k,
                "{name}: sphere {i} of radius {r} rests at z = {z}"
            );
        }
        let floor: f32 = (0..end.len())
            .map(|i| k * (end.radii[i] - end.positions[i][2]).max(0.0))
            .sum();
        let weight: f32 = end.radii.iter().map(|&r| mass(p.density, r) * g).sum();
        assert!(
            (floor - weight).abs() <= 1e-3 * weight,
            "{name}: the floor carries {floor} N of the pile's {weight} N"
        );
    }
}

#[test]
fn a_long_run_stays_finite_and_inside_the_box() {
    let start = pile(5, 0.025, 0.002);
    let r_min = start.radius_range().0;
    let side = 0.2f32;
    // Rotating gravity keeps the pile tumbling against every wall.
    let p = StepParams::new(
        &Material::default(),
        1e-4,
        [0.0; 3],
        [side as f64; 3],
        [0.0, 0.0, -9.81],
        std::f64::consts::PI,
        r_min,
    )
    .unwrap();
    let centroid = |s: &Particles| {
        let n = s.len() as f32;
        [0, 1, 2].map(|a| s.positions.iter().map(|c| c[a]).sum::<f32>() / n)
    };
    for (name, mut s) in steppers(&start, p.clone()) {
        let mut contacts = 0;
        for _ in 0..10 {
            contacts = s.advance(300).unwrap().contacts;
            let now = s.particles().unwrap();
            // Every centre stays in the box, no sphere pressed into a wall by half its radius.
            for (c, &r) in now.positions.iter().zip(&now.radii) {
                assert!(
                    c.iter()
                        .all(|&x| x.is_finite() && x >= r / 2.0 && x <= side - r / 2.0),
                    "{name}: sphere of radius {r} at {c:?} is in a wall by step {}",
                    now.step
                );
            }
        }
        let end = s.particles().unwrap();
        assert!(contacts > 0, "{name}: the pile lies in a heap");
        // The pile has gone where gravity points now: down and, turned by 0.3π, towards x = 0.
        let (before, after) = (centroid(&start), centroid(&end));
        let g = p.gravity_at(end.step);
        let along: f32 = (0..3).map(|a| (after[a] - before[a]) * g[a] / 9.81).sum();
        assert!(
            along > 0.02,
            "{name}: the centroid moved {along} m along gravity"
        );
    }
}

#[test]
fn every_step_times_its_phases_within_the_wall_clock() {
    // A GPU step times each batch as a whole and splits it in the proportions of the batch's
    // first step: every phase must take time, and all of them no longer than the host waited.
    let start = pile(6, 0.025, 0.002);
    let p = params(Material::default(), 1e-4, 0.3, [0.0, 0.0, -9.81], 0.008);
    for (name, mut s) in steppers(&start, p) {
        let clock = std::time::Instant::now();
        let advance = s.advance(250).unwrap();
        let wall_ms = clock.elapsed().as_secs_f64() * 1e3;
        let t = advance.times;
        if advance.clock == Clock::None {
            assert!(
                !common::ci(),
                "{name}: CI's adapter has GPU timestamps, so every phase must be timed"
            );
            eprintln!("note: {name} has no GPU timestamps here: its phases are not timed");
            continue;
        }
        for (phase, ms) in [
            ("build", t.build_ms),
            ("DCD", t.dcd_ms),
            ("update", t.update_ms),
        ] {
            assert!(ms.is_finite() && ms > 0.0, "{name}: {phase} took {ms} ms");
        }
        assert!(
            t.total_ms() <= wall_ms,
            "{name}: {} ms of phases in {wall_ms} ms of wall clock",
            t.total_ms()
        );
    }
}

#[test]
fn gpu_steps_follow_the_cpu_step_on_the_same_scene() {
    // A compressed lattice: every sphere touches its axis neighbours from step 0 (the closest
    // pair's distance is 0.0002 from its contact threshold, far from any rounding).
    assert_gpu_steps_follow_the_cpu_step(pile(8, 0.0162, 0.0));
}

#[test]
fn gpu_steps_follow_the_cpu_step_with_two_sizes_of_spheres() {
    // Two levels of the multi-level grid.
    assert_gpu_steps_follow_the_cpu_step(checkerboard(9));
}

#[test]
fn gpu_steps_follow_the_cpu_step_with_unequal_spheres_touching_on_one_level() {
    // The compressed lattice of spheres of 8–10 mm with every seventh shrunk to 2 mm (touching
    // nothing): the large ones share the top level of a multi-level grid, each touching pair of
    // unequal spheres, with friction and rolling resistance (the granular step: each pair's
    // history kept by the sphere that finds it, in a walk of several levels).
    let mut start = pile(9, 0.0162, 0.0);
    for r in start.radii.iter_mut().step_by(7) {
        *r = 0.002;
    }
    let material = Material {
        friction: 0.5,
        rolling_friction: 0.1,
        ..Material::default()
    };
    let r_min = start.radius_range().0;
    let p = params(material, 1e-4, 0.3, [0.0, 0.0, -9.81], r_min);
    assert_gpu_steps_follow_the_cpu_step_with(start, p);
}

#[test]
fn gpu_steps_follow_the_cpu_step_across_a_refined_coarse_level() {
    // A lattice of spheres of 9.5–10 mm at spacing 0.0162 (axis neighbours pressed together),
    // one of 5.5 mm at the centre of each lattice cube (touching its corners) and one of 2.4 mm
    // at the centre of each z-face (touching the face's corners, 0.2 mm from the cube centres'):
    // radii over a factor of 4.2, so a multi-level grid whose tables leave room to search its top
    // level in cells of half its class. The small spheres meet the large ones through that level's
    // finer cells; friction and rolling resistance, every GPU step against the cpu step.
    let (n, spacing) = (8, 0.0162f32);
    let at = |i: usize, j: usize, k: usize, off: [f32; 3]| -> [f32; 3] {
        let idx = [i, j, k];
        std::array::from_fn(|a| 0.02 + spacing * (idx[a] as f32 + off[a]))
    };
    let (mut positions, mut radii) = (Vec::new(), Vec::new());
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                positions.push(at(i, j, k, [0.0; 3]));
                radii.push(if (i + j + k) % 2 == 0 { 0.01 } else { 0.0095 });
                if i + 1 < n && j + 1 < n {
                    positions.push(at(i, j, k, [0.5, 0.5, 0.0]));
                    radii.push(0.0024);
                    if k + 1 < n {
                        positions.push(at(i, j, k, [0.5, 0.5, 0.5]));
                        radii.push(0.0055);
                    }
                }
            }
        }
    }
    let count = positions.len();
    let start = particles(positions, vec![[0.0; 3]; count], radii);
    let material = Material {
        friction: 0.5,
        rolling_friction: 0.1,
        ..Material::default()
    };
    let p = params(material, 1e-4, 0.3, [0.0, 0.0, -9.81], 0.0024);
    // The dense builds (`auto` takes the multi-level grid here) refine the top level.
    for (name, mut s) in steppers(&start, p.clone()) {
        if name.starts_with("wgpu-compute") && !name.contains("sorted") {
            s.advance(1).unwrap();
            let described = s.describe();
            assert!(
                described.contains("2 levels (level 1's cells 1/2"),
                "{name}: {described}"
            );
        }
    }
    assert_gpu_steps_follow_the_cpu_step_with(start, p);
}

/// A 3-D checkerboard of spheres of radius 0.01 and 0.005 at spacing 0.0145: every sphere
/// touches its axis neighbours, no two big ones touch, and every distance is at least 0.0005
/// from its contact threshold.
fn checkerboard(n_side: usize) -> Particles {
    let mut start = pile(n_side, 0.0145, 0.0);
    for (k, r) in start.radii.iter_mut().enumerate() {
        let parity = k % n_side + (k / n_side) % n_side + k / (n_side * n_side);
        *r = if parity.is_multiple_of(2) {
            0.01
        } else {
            0.005
        };
    }
    start
}

#[test]
fn gpu_steps_follow_the_cpu_step_with_a_stiffness_per_pair() {
    // The checkerboard pressed 0.0005 into the low walls of x and z: per-pair stiffness between
    // spheres of two masses and on the walls, no friction (the paper's kernels with the
    // per-pair law on the GPUs).
    let mut start = checkerboard(9);
    for c in &mut start.positions {
        c[0] -= 0.0105;
        c[2] -= 0.0105;
    }
    let dt = 1e-4;
    let material = Material {
        contact: ContactLaw::LinearPerPair {
            contact_time: Some(10.0 * dt),
        },
        ..Material::default()
    };
    let r_min = start.radius_range().0;
    let p = params(material, dt, 0.3, [0.0, 0.0, -9.81], r_min);
    assert_gpu_steps_follow_the_cpu_step_with(start, p);
}

#[test]
fn gpu_steps_follow_the_cpu_step_where_a_sphere_meets_more_contacts_than_it_lists_at_once() {
    // 30 spheres of one size spread within a cube of side r, no gravity: every pair touches, so
    // the first spheres in sorted order meet up to 29 contacts, more than the paper's resolve
    // kernels list before resolving them (8): they walk again for the rest. The per-pair law
    // (the paper's kernels on the GPUs).
    let r = 0.01f32;
    let n = 30;
    // A low-discrepancy spread: no two centres coincide.
    let spread = |k: usize, a: f32| 0.5 + r * (k as f32 * a).fract();
    let positions: Vec<[f32; 3]> = (0..n)
        .map(|k| {
            [
                spread(k, 0.618_034),
                spread(k, 0.754_878),
                spread(k, 0.569_840),
            ]
        })
        .collect();
    let start = particles(positions, vec![[0.0; 3]; n], vec![r; n]);
    let dt = 1e-4;
    let material = Material {
        contact: ContactLaw::LinearPerPair {
            contact_time: Some(10.0 * dt),
        },
        ..Material::default()
    };
    let p = params(material, dt, 1.0, [0.0; 3], r);
    let mut all = steppers(&start, p);
    let (_, mut cpu) = all.remove(0);
    let reference: Vec<_> = (0..4)
        .map(|_| {
            let a = cpu.advance(1).unwrap();
            (a.contacts, cpu.particles().unwrap())
        })
        .collect();
    assert_eq!(
        reference[0].0,
        (n * (n - 1) / 2) as u64,
        "every pair touches"
    );
    for (name, mut s) in all {
        for (k, (contacts, expected)) in reference.iter().enumerate() {
            let a = s.advance(1).unwrap();
            assert_eq!(a.contacts, *contacts, "{name}: contacts at step {k}");
            let worst = common::largest_gap(&s.particles().unwrap(), expected);
            assert!(
                worst < 1e-6,
                "{name}: {worst} m from the cpu step at step {k}"
            );
        }
    }
}

#[test]
fn gpu_steps_follow_the_cpu_step_under_rotating_gravity_from_a_later_step() {
    // Resumed at step 12,000 (1.2 s) of gravity turning at 2 rad/s: it points 2.4 rad away from
    // -z, so a step that took its phase from step 0 would pull the wrong way.
    let mut start = pile(8, 0.0162, 0.0);
    start.step = 12_000;
    let r_min = start.radius_range().0;
    let p = StepParams::new(
        &Material::default(),
        1e-4,
        [0.0; 3],
        [0.3; 3],
        [0.0, 0.0, -9.81],
        2.0,
        r_min,
    )
    .unwrap();
    assert_gpu_steps_follow_the_cpu_step_with(start, p);
}

/// Every GPU stepper, over the first 40 steps from `start` (which must start in contact), finds
/// in each batch of 5 steps the contacts the cpu step finds from the same state and stays within
/// 1e-7 m of its positions.
fn assert_gpu_steps_follow_the_cpu_step(start: Particles) {
    let r_min = start.radius_range().0;
    let p = params(Material::default(), 1e-4, 0.3, [0.0, 0.0, -9.81], r_min);
    assert_gpu_steps_follow_the_cpu_step_with(start, p);
}

/// [`assert_gpu_steps_follow_the_cpu_step`] with the step parameters `p`.
///
/// The GPU's run goes on through all 40 steps (its sorting, binning and skin carry on), and
/// the cpu step starts again from the GPU's state at each batch: the GPUs add forces by atomics
/// in any order, so the two runs part by ulps that grow, and within tens of steps a pair at the
/// threshold of touching (the lattices have pairs within a nanometre of it) may be decided the
/// other way by either, a different contact from then on. From one state, 5 steps part by
/// nanometres (a step whose physics differed would part by far more).
fn assert_gpu_steps_follow_the_cpu_step_with(start: Particles, p: StepParams) {
    let mut all = steppers(&start, p.clone());
    let (_, mut cpu) = all.remove(0);
    let first = cpu.advance(5).unwrap();
    assert!(first.contacts > 1000, "the lattice starts in contact");
    for (name, mut s) in all {
        let mut from = start.clone();
        for k in 0..8 {
            let mut cpu = common::open_dem(BackendKind::Cpu, &from, p.clone(), &Options::default());
            let c = cpu.advance(5).unwrap();
            let expected = cpu.particles().unwrap();
            let a = s.advance(5).unwrap();
            let got = s.particles().unwrap();
            assert_eq!(got.step, expected.step, "{name}");
            assert_eq!(a.contacts, c.contacts, "{name}: contacts at batch {k}");
            // GPUs fuse multiply-adds and add forces in any order: close, not identical.
            let worst = common::largest_gap(&got, &expected);
            assert!(
                worst < 1e-7,
                "{name}: {worst} m from the cpu step at step {}",
                got.step
            );
            from = got;
        }
    }
}

#[test]
fn refitting_steps_follow_the_cpu_step_past_a_morton_resort() {
    // A lattice spun about its centre (each sphere moving along its tangent, so the spheres only
    // drift apart), no gravity, walls far away: no contacts, so every backend does the same
    // arithmetic. It turns by about a radian, past the optix step's Morton re-sort (every
    // RESORT_EVERY steps), which permutes its state on the GPU in a new order.
    let mut start = pile(4, 0.05, 0.0);
    let centre = 0.02 + 1.5 * 0.05;
    for (c, v) in start.positions.iter_mut().zip(start.velocities.iter_mut()) {
        let (x, y) = (c[0] - centre, c[1] - centre);
        *v = [-5.0 * y, 5.0 * x, 0.1];
        *c = [c[0] + 4.9, c[1] + 4.9, c[2] + 4.9];
    }
    let p = params(
        Material::default(),
        1e-4,
        10.0,
        [0.0; 3],
        start.radius_range().0,
    );
    let mut all = steppers(&start, p);
    let (_, mut cpu) = all.remove(0);
    let steps = 2100;
    cpu.advance(steps).unwrap();
    let expected = cpu.particles().unwrap();
    for (name, mut s) in all {
        let a = s.advance(steps).unwrap();
        assert_eq!(a.contacts, 0, "{name}");
        let got = s.particles().unwrap();
        let worst = common::largest_gap(&got, &expected);
        assert!(worst < 1e-4, "{name}: {worst} m from the cpu step");
    }
}

#[test]
fn coincident_spheres_are_spread_apart() {
    // Five spheres at one point and a pair at another, no gravity: no contact normal at distance
    // 0, so every stepper first spreads each group over the nearest points of a lattice about
    // its centre, a diameter and a thousandth of a radius apart: none of them touch.
    let r = 0.01f32;
    let mut positions = vec![[0.5f32; 3]; 5];
    positions.extend([[0.3, 0.6, 0.4]; 2]);
    let n = positions.len();
    let start = particles(positions, vec![[0.0; 3]; n], vec![r; n]);
    let p = params(Material::default(), 1e-4, 1.0, [0.0; 3], r);
    for (name, mut s) in steppers(&start, p) {
        let first = s.advance(1).unwrap();
        assert_eq!(first.contacts, 0, "{name}: coincident spheres still touch");
        s.advance(20).unwrap();
        let end = s.particles().unwrap();
        for i in 0..n {
            for j in i + 1..n {
                let (a, b) = (end.positions[i], end.positions[j]);
                let d = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f32>().sqrt();
                assert!(d > 2.0 * r, "{name}: spheres {i} and {j} still {d} m apart");
            }
            assert_eq!(end.velocities[i], [0.0; 3], "{name}: sphere {i} moves");
        }
    }
}

#[test]
fn large_coincident_groups_stack_on_the_floor_under_every_law() {
    common::on_every_backend(large_coincident_groups_stack_on_the_floor_under_every_law_on);
}

fn large_coincident_groups_stack_on_the_floor_under_every_law_on(kind: BackendKind) {
    // 200 and 2000 spheres of 1 cm at one point, under gravity, with Hertz–Mindlin (friction
    // and EPSD rolling resistance, the scene's defaults, at 0.2 Rayleigh times) and the linear
    // law (one stiffness, dt 1e-4 s), the floor just under the lowest sphere of the cluster the
    // group spreads into. Were they moved apart by a fraction of a radius, their N(N − 1)/2
    // overlaps of almost 2r would fling them out at 1 to 3 km/s (stored energy), faster still
    // in the first step (from 200 up, their collective stiffness is beyond the step's stability),
    // and through the walls, where a Hertz contact stiffens without bound: the step diverges.
    // Spread, they fall onto the floor and stack: 100 steps stay finite and slow, their overlaps
    // small.
    let r = 0.01f32;
    let hertz = common::granular_material();
    let t_r = mochi::dem::model::time_step::rayleigh_time(r as f64, 500.0, 1e7, 0.3);
    for n in [200, 2000] {
        let start = particles(vec![[0.5; 3]; n], vec![[0.0; 3]; n], vec![r; n]);
        let mut spread = start.clone();
        spread.separate_coincident().unwrap();
        let lowest = spread.positions.iter().map(|c| c[2]).fold(1.0f32, f32::min);
        let floor = (lowest - 1.0005 * r) as f64;
        for (law, material, dt) in [
            ("hertz-mindlin", hertz, 0.2 * t_r),
            ("linear", Material::default(), 1e-4),
        ] {
            let p = StepParams::new(
                &material,
                dt,
                [0.0, 0.0, floor],
                [1.0; 3],
                [0.0, 0.0, -9.81],
                0.0,
                r,
            )
            .unwrap();
            let what = format!("{n} spheres, {law}, {}", kind.name());
            let mut s = common::open_dem(kind, &start, p, &Options::default());
            let last = s.advance(100).unwrap_or_else(|e| panic!("{what}: {e}"));
            // The ball of spheres lands on its lowest one and settles onto it.
            assert!(
                last.contacts > n as u64 / 20,
                "{what}: {} contacts",
                last.contacts
            );
            let end = s.particles().unwrap();
            // Free fall for 100 steps reaches 0.1 m/s at most.
            let fastest = end
                .velocities
                .iter()
                .map(|v| v.iter().map(|x| x * x).sum::<f32>().sqrt())
                .fold(0.0f32, f32::max);
            assert!(fastest < 0.2, "{what}: a sphere moves at {fastest} m/s");
            let deepest_in_floor = end
                .positions
                .iter()
                .map(|c| r - (c[2] - floor as f32))
                .fold(f32::MIN, f32::max);
            assert!(
                deepest_in_floor < 0.05 * r,
                "{what}: a sphere {deepest_in_floor} m into the floor"
            );
            let mut deepest = 0.0f32;
            for i in 0..n {
                for j in i + 1..n {
                    let (a, b) = (end.positions[i], end.positions[j]);
                    let d = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f32>().sqrt();
                    deepest = deepest.max(2.0 * r - d);
                }
            }
            assert!(
                deepest < 0.05 * r,
                "{what}: spheres {deepest} m into each other"
            );
        }
    }
}

/// A `wgpu-compute` step over `start` binned by `grid_build` (`None` where no adapter runs it).
fn grid_stepper(start: &Particles, p: StepParams, grid_build: GridBuild) -> Option<GridStepper> {
    grid_stepper_with(start, p, grid_build, KernelSet::Auto)
}

/// As [`grid_stepper`], running `kernels`.
fn grid_stepper_with(
    start: &Particles,
    p: StepParams,
    grid_build: GridBuild,
    kernels: KernelSet,
) -> Option<GridStepper> {
    common::dem_runs_here(BackendKind::WgpuCompute).then(|| {
        let setup = DemSetup::new(start.clone(), p, ProxyMode::Mochi);
        let options = GridStepOptions {
            kernels,
            grid_build,
            ..GridStepOptions::default()
        };
        GridStepper::open(setup, options).unwrap()
    })
}

#[test]
fn the_sorted_build_steps_like_the_dense_build() {
    // A compressed, jittered pile, with the paper's law and with friction (the granular step):
    // over 40 steps both builds find the same contacts and stay within the GPU tolerance of
    // each other, as the GPU steps do of the cpu step (contacts are met in another order within a
    // cell, and float atomics add in any order: close, not identical).
    let start = pile(10, 0.0165, 0.001);
    let r_min = start.radius_range().0;
    let frictional = Material {
        friction: 0.5,
        ..Material::default()
    };
    for material in [Material::default(), frictional] {
        let p = params(material, 1e-4, 0.3, [0.0, 0.0, -9.81], r_min);
        let Some(mut dense) = grid_stepper(&start, p.clone(), GridBuild::Dense) else {
            return;
        };
        let mut sorted = grid_stepper(&start, p, GridBuild::Sorted).unwrap();
        assert_eq!(dense.build(), BuildKind::Dense);
        assert_eq!(sorted.build(), BuildKind::Sorted);
        assert!(sorted.describe().contains("sorted build"));
        let friction = material.friction;
        let mut touched = 0;
        for batch in 0..8 {
            let a = dense.advance(5).unwrap();
            let b = sorted.advance(5).unwrap();
            assert_eq!(a.contacts, b.contacts, "friction {friction}, batch {batch}");
            touched += a.contacts;
            let worst =
                common::largest_gap(&dense.particles().unwrap(), &sorted.particles().unwrap());
            assert!(
                worst < 1e-6,
                "friction {friction}, batch {batch}: {worst} m apart"
            );
        }
        assert!(touched > 1000, "friction {friction}: the pile touches");
    }
}

#[test]
fn binning_steps_follow_the_cpu_step_whatever_the_order_of_the_state() {
    // A compressed pile given in a scrambled order, its spheres moving every which way at up to
    // 0.5 m/s: never sorted, the dense build's step bins the scrambled state by index at every
    // step (and resolves and integrates it where it is); sorted at every step, or every
    // SORT_EVERY steps, it moves the state. Every way, on one level and on several, with the
    // grid laid out again after every batch (what the last step counted into the cells is then
    // dropped and counted again), steps as the first way does (the same contacts, within 1e-6
    // m: only the order in which forces add differs), and follows the cpu step over three
    // batches: with the paper's law, batches of 16 steps, the cpu's contacts and within 1e-6 m;
    // with Hertz–Mindlin, friction and rolling resistance (the granular step, whose history is
    // kept by state row between sortings; its spins follow the cpu's too), batches of 8.
    // A frictional pile may meet a contact whose tangential force is within a rounding of the
    // Coulomb cap: the cpu and a GPU, rounding differently, then slide and stick there, and that
    // contact's neighbourhood drifts apart by a few 1e-5 m in 8 steps (an H200 does, in batch 0,
    // docs/performance-log/2026-11-28-h200-issue-43.md, "The dem test's drift on this card"),
    // spreading through the pile's contacts. So against the cpu the granular step keeps its
    // contacts within 1 %, half of its spheres within 1e-6 m (and of their spins within 5e-3 of
    // the fastest) and every one within 2e-4 m; a wrong row or history moves most spheres by far
    // more.
    let start = pile(10, 0.0165, 0.001);
    let n = start.len();
    let mut scrambled = start.clone();
    for k in 0..n {
        let i = (k * 7919) % n;
        scrambled.positions[k] = start.positions[i];
        scrambled.radii[k] = start.radii[i];
        let turn = k as f32 * 2.39996;
        scrambled.velocities[k] = [0.5 * turn.cos(), 0.5 * turn.sin(), 0.3 * (0.7 * turn).sin()];
    }
    let r_min = scrambled.radius_range().0;
    let granular = common::granular_material();
    for (material, batch) in [(Material::default(), 16), (granular, 8)] {
        let frictional = material.friction > 0.0;
        let p = params(material, 1e-4, 0.3, [0.0, 0.0, -9.81], r_min);
        let Some(any) = grid_stepper(&scrambled, p.clone(), GridBuild::Dense) else {
            return;
        };
        drop(any);
        let mut cpu =
            common::open_dem(BackendKind::Cpu, &scrambled, p.clone(), &Options::default());
        let mut reference = Vec::new();
        for _ in 0..3 {
            let a = cpu.advance(batch).unwrap();
            reference.push((a.contacts, cpu.particles().unwrap()));
        }
        let contacts: Vec<u64> = reference.iter().map(|r| r.0).collect();
        assert!(
            contacts[0] > 500,
            "the pile starts in contact: {contacts:?}"
        );
        let spin = reference[2].1.angular_velocities.iter().flatten();
        let spin = spin.fold(0.0f32, |a, w| a.max(w.abs()));
        assert!(!frictional || spin > 1.0, "friction turns the spheres");
        // The batches of the first way: contacts and state.
        let mut first_way: Vec<(u64, Particles)> = Vec::new();
        for sorting in [Sorting::Never, Sorting::Every(1), Sorting::Every(7)] {
            for structure in [Structure::Auto, Structure::Mlgrid] {
                let name = format!("{:?} {sorting:?} {structure:?}", material.contact);
                let mut s = grid_stepper(&scrambled, p.clone(), GridBuild::Dense)
                    .unwrap()
                    .with_structure(structure)
                    .with_sorting(sorting);
                for (k, (contacts, expected)) in reference.iter().enumerate() {
                    let a = s.advance(batch).unwrap();
                    let got = s.particles().unwrap();
                    if let Some((first_contacts, first)) = first_way.get(k) {
                        assert_eq!(a.contacts, *first_contacts, "{name}: contacts at batch {k}");
                        let worst = common::largest_gap(&got, first);
                        assert!(
                            worst < 1e-6,
                            "{name}: {worst} m from the first way at batch {k}"
                        );
                    }
                    let gaps = common::gaps(&got, expected);
                    let (half, worst) = (gaps[gaps.len() / 2], gaps[gaps.len() - 1]);
                    if frictional {
                        let off = a.contacts.abs_diff(*contacts);
                        assert!(
                            off * 100 <= *contacts,
                            "{name}: {} contacts against the cpu's {contacts} at batch {k}",
                            a.contacts
                        );
                        assert!(
                            half < 1e-6 && worst < 2e-4,
                            "{name}: half of the spheres within {half} m of the cpu step's, \
                             all within {worst} m, at batch {k}"
                        );
                    } else {
                        assert_eq!(a.contacts, *contacts, "{name}: contacts at batch {k}");
                        assert!(
                            worst < 1e-6,
                            "{name}: {worst} m from the cpu step at batch {k}"
                        );
                    }
                    let spins = got.angular_velocities.iter().flatten();
                    let cpu_spins = expected.angular_velocities.iter().flatten();
                    let mut spin_gaps: Vec<f32> =
                        spins.zip(cpu_spins).map(|(a, b)| (a - b).abs()).collect();
                    spin_gaps.sort_by(f32::total_cmp);
                    let spin_gap = spin_gaps[spin_gaps.len() / 2];
                    assert!(
                        spin_gap <= 5e-3 * spin.max(1.0),
                        "{name}: half of the spins within {spin_gap} rad/s of the cpu step's at \
                         batch {k}"
                    );
                    if first_way.len() == k {
                        first_way.push((a.contacts, got));
                    }
                    // Laid out again at the next advance.
                    s = s.with_structure(structure);
                }
            }
        }
    }
}

#[test]
fn steps_that_skip_their_binning_follow_the_cpu_step_as_spheres_cross_cells() {
    // A lattice of 10 mm spheres 1 mm apart flying apart and into each other at up to 2 m/s, no
    // gravity: each step moves a sphere up to 0.2 mm, so the paper's step on the dense build
    // (whose skin is a fifth of its 2 cm cells) skips its binning for several steps at a time and
    // re-bins when the GPU finds a sphere may have moved the skin; spheres meet partners they
    // were not near at the last binning, and the walls. Over three batches it finds the cpu
    // step's contacts and stays within the GPU tolerance of its positions. One size of sphere:
    // the windows then have no room to spare beyond the skin, so with the skin's widening left
    // out, or each walker starting from its current cell's row instead of its binned one, pairs
    // are missed and it fails.
    let mut start = pile(8, 0.021, 0.0);
    start.radii.fill(0.01);
    for (k, v) in start.velocities.iter_mut().enumerate() {
        let turn = k as f32 * 2.39996;
        let speed = 1.0 + (k % 3) as f32 * 0.5;
        *v = [
            speed * turn.cos(),
            speed * turn.sin(),
            speed * (0.7 * turn).sin(),
        ];
    }
    let r_min = start.radius_range().0;
    let p = params(Material::default(), 1e-4, 0.3, [0.0; 3], r_min);
    let Some(mut gpu) = grid_stepper(&start, p.clone(), GridBuild::Dense) else {
        return;
    };
    let mut cpu = common::open_dem(BackendKind::Cpu, &start, p, &Options::default());
    let batch = 30;
    let mut touched = 0;
    for k in 0..3 {
        let expected = cpu.advance(batch).unwrap();
        let got = gpu.advance(batch).unwrap();
        assert_eq!(got.contacts, expected.contacts, "contacts at batch {k}");
        touched += got.contacts;
        let worst = common::largest_gap(&gpu.particles().unwrap(), &cpu.particles().unwrap());
        assert!(worst < 1e-5, "{worst} m from the cpu step at batch {k}");
    }
    assert!(touched > 20, "the spheres meet: {touched} contacts");
    // The GPU re-binned between the batches' starts, and skipped most steps' binning.
    let described = gpu.describe();
    let rebins: u64 = described
        .split("re-binned at ")
        .nth(1)
        .and_then(|rest| rest.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no re-binnings reported: {described}"));
    assert!(
        (6..45).contains(&rebins),
        "{rebins} of 90 steps re-binned: {described}"
    );
}

#[test]
fn a_batch_of_binning_steps_redone_with_more_history_slots_keeps_every_contact() {
    // 40 spheres of 5 mm within 2 mm of one point, every pair touching: the sphere that owns
    // the others' pairs needs far more than the 16 slots a run starts with, so the first batch
    // is redone with more, from the state set and history it began from, whether its steps
    // sort the state (moving it between the two sets) or bin it by index (leaving it); on one
    // level (the walk and the contacts in one kernel) and on several (in two), the walk listing
    // 16 candidates within reach at a time; the lists shared among a subgroup's lanes (owners
    // of 39 contacts down to none side by side) and resolved by each thread alone.
    let start = common::clump(40);
    let material = Material {
        contact: ContactLaw::HertzMindlin {
            young_modulus: 1e7,
            poisson_ratio: 0.3,
        },
        friction: 0.5,
        ..Material::default()
    };
    let p = params(material, 1e-7, 1.0, [0.0; 3], 0.005);
    let Some(any) = grid_stepper(&start, p.clone(), GridBuild::Dense) else {
        return;
    };
    drop(any);
    let mut cpu = common::open_dem(BackendKind::Cpu, &start, p.clone(), &Options::default());
    cpu.advance(6).unwrap();
    let expected = cpu.particles().unwrap();
    let ways = [Sorting::Never, Sorting::Every(1), Sorting::Every(2)]
        .into_iter()
        .flat_map(|sorting| [(sorting, Structure::Auto), (sorting, Structure::Mlgrid)])
        .flat_map(|way| [(way, KernelSet::Auto), (way, KernelSet::Portable)]);
    for ((sorting, structure), kernels) in ways {
        let mut s = grid_stepper_with(&start, p.clone(), GridBuild::Dense, kernels)
            .unwrap()
            .with_structure(structure)
            .with_sorting(sorting);
        // Three steps a batch: sorting every other step, the first batch ends in the other
        // set; the second reads the history the grown slots kept.
        s.advance(3).unwrap();
        s.advance(3).unwrap();
        assert!(
            !s.describe().contains("history 16 slots"),
            "{}",
            s.describe()
        );
        let got = s.particles().unwrap();
        assert_eq!(
            got.step, expected.step,
            "{sorting:?} {structure:?} {kernels:?}: the step count"
        );
        let worst = common::largest_gap(&got, &expected);
        assert!(
            worst < 1e-7,
            "{sorting:?} {structure:?} {kernels:?}: {worst} m from the cpu step"
        );
        common::assert_keeps_every_pair(&format!("{sorting:?} {structure:?} {kernels:?}"), &got);
    }
}

#[test]
fn auto_bins_a_packed_pile_densely_and_a_sparse_cloud_by_sorted_keys() {
    let packed = pile(10, 0.0195, 0.0);
    let r_min = packed.radius_range().0;
    let p = params(Material::default(), 1e-4, 0.3, [0.0; 3], r_min);
    let Some(stepper) = grid_stepper(&packed, p, GridBuild::Auto) else {
        return;
    };
    assert_eq!(stepper.build(), BuildKind::Dense);
    // The same spheres spread 30 times wider per side, in a box to match.
    let mut sparse = packed.clone();
    for c in &mut sparse.positions {
        *c = c.map(|x| x * 30.0);
    }
    let p = params(Material::default(), 1e-4, 10.0, [0.0; 3], r_min);
    let mut stepper = grid_stepper(&sparse, p, GridBuild::Auto).unwrap();
    assert_eq!(stepper.build(), BuildKind::Sorted);
    stepper.advance(3).unwrap();
}
