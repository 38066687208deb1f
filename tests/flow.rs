//! Inflow and outflow (`dem::flow`) on every backend: an inflow inserts ⌊rate·t⌋ spheres, each
//! where it overlaps nothing; mass is conserved (initial + inserted = present + removed);
//! without the box walls a sphere that falls below the box is removed, and the run takes new
//! motion after; every backend's flow events with the same `flow_every` insert and remove what
//! the cpu's do; a run with both resumes from a checkpoint bit for bit on cpu.

mod common;

use common::on_every_backend;
use mochi::ProxyMode;
use mochi::dem::flow::{FlowCounts, FlowSet, InflowConfig, OutflowConfig};
use mochi::dem::model::{Material, mass};
use mochi::dem::scene::Start;
use mochi::dem::walls::WallSet;
use mochi::dem::{Motion, Particles, StepParams, Stepper};
use mochi::engines::{BackendChoice, BackendKind, Options, open_scene};

const DT: f64 = 1e-4;
const RHO: f64 = 2500.0;

fn params(gravity: f64) -> StepParams {
    let m = Material {
        density: RHO,
        friction: 0.3,
        ..Material::default()
    };
    StepParams::new(&m, DT, [0.0; 3], [0.2; 3], [0.0, 0.0, gravity], 0.0, 0.004).unwrap()
}

/// A box inflow at the top of the box, 2000 spheres/s of radii 4–5 mm falling at 0.5 m/s.
fn top_inflow() -> InflowConfig {
    InflowConfig {
        lo: Some([0.02, 0.02, 0.15]),
        hi: Some([0.18, 0.18, 0.19]),
        rate: Some(2000.0),
        sphere_radii: Some([0.004, 0.005]),
        velocity: Some([0.0, 0.0, -0.5]),
        seed: Some(7),
        ..InflowConfig::default()
    }
}

/// The step of backend `kind`, or its refusal.
fn try_stepper(
    kind: BackendKind,
    particles: Particles,
    params: StepParams,
    flow: FlowSet,
    box_walls: bool,
) -> mochi::Result<Box<dyn Stepper>> {
    let start = Start {
        particles,
        params,
        mode: ProxyMode::Mochi,
        walls: WallSet::new(box_walls, Vec::new()).unwrap(),
        flow,
    };
    let choice = BackendChoice::Named(kind);
    Ok(open_scene(choice, start, &Options::default())?.value)
}

fn stepper(
    kind: BackendKind,
    particles: Particles,
    params: StepParams,
    flow: FlowSet,
    box_walls: bool,
) -> Box<dyn Stepper> {
    try_stepper(kind, particles, params, flow, box_walls).unwrap()
}

/// Asserts that backend `kind` (its flows' `counts`, its spheres `now`) inserted, refused and
/// removed what the cpu did (`cpu`) and holds the spheres the cpu holds (`placed`) at the same
/// places in the same order, and that on wgpu-compute `read_backs` of its flow events read the
/// spheres back.
fn assert_flows_as_the_cpu(
    kind: BackendKind,
    (counts, now): (&FlowCounts, &Particles),
    (cpu, placed): (&FlowCounts, &Particles),
    read_backs: u64,
) {
    let tally = |c: &FlowCounts| (c.inserted, c.refused, c.removed);
    assert_eq!(tally(counts), tally(cpu));
    assert_eq!(
        (&now.positions, &now.radii),
        (&placed.positions, &placed.radii)
    );
    if kind == BackendKind::WgpuCompute {
        assert_eq!(counts.read_backs, read_backs, "{counts:?}");
    }
}

fn total_mass(p: &Particles) -> f64 {
    p.radii.iter().map(|&r| mass(RHO as f32, r) as f64).sum()
}

#[test]
fn an_inflow_inserts_at_its_rate_where_nothing_is_and_never_overlaps() {
    // No gravity and no velocity: the spheres stay where they are put, so any overlap would be
    // one the inflow made. 2000 spheres/s into a slab that holds a few hundred: it fills, then
    // refuses. Every backend puts the same spheres at the same places as the cpu does at the
    // same flow events (every 50 steps, as set).
    let inflow = InflowConfig {
        velocity: None,
        ..top_inflow()
    };
    let run = |kind| {
        let flow = FlowSet {
            inflows: vec![inflow.build(0, RHO, 0).unwrap()],
            every: Some(50),
            ..FlowSet::default()
        };
        let mut s = stepper(kind, Particles::default(), params(0.0), flow, true);
        for _ in 0..100 {
            let advance = s.advance(10).unwrap();
            assert_eq!(advance.contacts, 0, "an inserted sphere overlaps another");
        }
        (s.flow_counts().unwrap(), s.particles().unwrap())
    };
    let (cpu, placed) = run(BackendKind::Cpu);
    on_every_backend(|kind| {
        let (counts, now) = run(kind);
        // ⌊2000/s · 1000 dt⌋ (dt in f32: 0.1 s less 2.5e-10), each inserted or refused (the
        // last flow event is at step 1000).
        let due = (2000.0 * 1000.0 * params(0.0).dt as f64).floor() as u64;
        assert_eq!(due, 199);
        assert_eq!(counts.inserted + counts.refused, due);
        assert!(counts.inserted > 100, "{counts:?}");
        assert_eq!(now.len() as u64, counts.inserted);
        // On wgpu-compute the flow events append on the device: none reads the spheres back.
        assert_flows_as_the_cpu(kind, (&counts, &now), (&cpu, &placed), 0);
    });
}

#[test]
fn mass_is_conserved_through_an_inflow_and_an_outflow() {
    // Spheres rain onto the floor, where an outflow 2 cm deep removes them.
    on_every_backend(|kind| {
        let flow = FlowSet {
            inflows: vec![top_inflow().build(0, RHO, 0).unwrap()],
            outflows: vec![
                OutflowConfig {
                    lo: [0.0; 3],
                    hi: [0.2, 0.2, 0.02],
                }
                .build(0)
                .unwrap(),
            ],
            ..FlowSet::default()
        };
        let first = Particles {
            positions: vec![[0.1, 0.1, 0.1]],
            velocities: vec![[0.0; 3]],
            angular_velocities: vec![[0.0; 3]],
            radii: vec![0.006],
            ..Particles::default()
        };
        let initial = total_mass(&first);
        let mut s = stepper(kind, first, params(-9.81), flow, true);
        s.advance(3000).unwrap();
        let c = s.flow_counts().unwrap();
        let now = s.particles().unwrap();
        assert!(c.inserted > 500 && c.removed > 100, "{c:?}");
        assert_eq!(1 + c.inserted, now.len() as u64 + c.removed);
        let balance = initial + c.inserted_mass - (total_mass(&now) + c.removed_mass);
        // Sums of a few thousand f32 masses in f64: rounding far below a single sphere's mass.
        assert!(
            balance.abs() < 1e-9 * initial,
            "mass balance off by {balance} kg"
        );
        now.validate().unwrap();
    });
}

#[test]
fn without_box_walls_a_sphere_below_the_box_is_removed() {
    let falling = Particles {
        positions: vec![[0.1, 0.1, 0.02]],
        velocities: vec![[0.0, 0.0, -1.0]],
        angular_velocities: vec![[0.0; 3]],
        radii: vec![0.005],
        ..Particles::default()
    };
    let flow = FlowSet {
        floor: Some(0.0),
        ..FlowSet::default()
    };
    on_every_backend(|kind| {
        let opened = try_stepper(kind, falling.clone(), params(-9.81), flow.clone(), false);
        let mut s = opened.unwrap();
        s.advance(300).unwrap();
        assert_eq!(s.particles().unwrap().len(), 0);
        let c = s.flow_counts().unwrap();
        assert_eq!(c.removed, 1);
        assert!((c.removed_mass - mass(RHO as f32, 0.005) as f64).abs() < 1e-12);
        // With no sphere left the run goes on, waiting for an inflow.
        s.advance(50).unwrap();
        assert_eq!(s.particles().unwrap().step, 350);
    });
}

#[test]
fn a_run_takes_new_motion_after_a_sphere_left_it() {
    // Sphere 0 falls out through the floor; sphere 1, left alone, is then given a new place and
    // velocity: the run's first sphere now, whichever rows the step keeps it in.
    let two = Particles {
        positions: vec![[0.1, 0.1, 0.02], [0.1, 0.1, 0.1]],
        velocities: vec![[0.0, 0.0, -1.0], [0.0; 3]],
        angular_velocities: vec![[0.0; 3]; 2],
        radii: vec![0.005; 2],
        ..Particles::default()
    };
    let flow = FlowSet {
        floor: Some(0.0),
        ..FlowSet::default()
    };
    on_every_backend(|kind| {
        let mut s = stepper(kind, two.clone(), params(0.0), flow.clone(), false);
        s.advance(300).unwrap();
        assert_eq!(s.flow_counts().unwrap().removed, 1);
        let (place, speed) = ([[0.05, 0.06, 0.07]], [[0.1, 0.0, 0.0]]);
        s.set_motion(&Motion {
            positions: Some(&place),
            velocities: Some(&speed),
            angular_velocities: None,
        })
        .unwrap();
        let now = s.particles().unwrap();
        let at = now.exact_positions().unwrap();
        assert_eq!(at.len(), 1);
        assert!(
            (0..3).all(|a| (at[0][a] - place[0][a]).abs() < 1e-12),
            "{at:?}"
        );
        assert_eq!(now.velocities, speed);
    });
}

#[test]
fn every_backend_inserts_and_removes_what_the_cpu_does_at_the_same_flow_events() {
    // Spheres fall from the inflow at 0.5 m/s through an outflow band 1 cm under it: no two
    // touch, so every backend moves them alike and its flow events (every 50 steps, as set)
    // see the same spheres.
    let flow = FlowSet {
        inflows: vec![top_inflow().build(0, RHO, 0).unwrap()],
        outflows: vec![(
            glam::Vec3::new(0.0, 0.0, 0.12),
            glam::Vec3::new(0.2, 0.2, 0.13),
        )],
        every: Some(50),
        ..FlowSet::default()
    };
    let run = |kind| {
        let mut s = stepper(
            kind,
            Particles::default(),
            params(-9.81),
            flow.clone(),
            true,
        );
        s.advance(730).unwrap();
        (s.flow_counts().unwrap(), s.particles().unwrap())
    };
    let (counts, cpu) = run(BackendKind::Cpu);
    assert!(counts.inserted > 100 && counts.removed > 10, "{counts:?}");
    on_every_backend(|kind| {
        let (c, now) = run(kind);
        assert_eq!(
            (c.inserted, c.refused, c.removed),
            (counts.inserted, counts.refused, counts.removed)
        );
        if kind == BackendKind::WgpuCompute {
            // Its flow events remove and insert on the device: none reads the spheres back.
            assert_eq!(c.read_backs, 0, "{c:?}");
        }
        assert_eq!(now.radii, cpu.radii, "the same spheres, in the same order");
        for (a, b) in now.positions.iter().zip(&cpu.positions) {
            let off = glam::Vec3::from(*a).distance(glam::Vec3::from(*b));
            // Free fall for at most 730 steps in f32: far below a radius.
            assert!(off < 1e-5, "{a:?} vs {b:?}");
        }
    });
}

#[test]
fn a_run_with_inflow_and_outflow_resumes_from_its_checkpoint_bit_for_bit() {
    let flow = || FlowSet {
        inflows: vec![top_inflow().build(0, RHO, 0).unwrap()],
        // A corner of the floor drains; elsewhere the spheres pile up and touch.
        outflows: vec![(glam::Vec3::ZERO, glam::Vec3::new(0.06, 0.2, 0.05))],
        ..FlowSet::default()
    };
    let p = params(-9.81);
    let stepper = |particles, p, flow| stepper(BackendKind::Cpu, particles, p, flow, true);
    let mut straight = stepper(Particles::default(), p.clone(), flow());
    straight.advance(2400).unwrap();
    let mut first = stepper(Particles::default(), p.clone(), flow());
    first.advance(1200).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("checkpoint.bin");
    mochi::io::write_checkpoint(&file, &first.particles().unwrap(), "", "").unwrap();
    let saved = mochi::io::read_checkpoint(&file).unwrap().particles;
    let mut resumed = stepper(saved, p, flow());
    resumed.advance(1200).unwrap();
    let (a, b) = (straight.particles().unwrap(), resumed.particles().unwrap());
    assert!(
        straight.flow_counts().unwrap().removed > 0,
        "the outflow was used"
    );
    assert!(!a.history.is_empty(), "the run had contact history");
    assert_eq!(a, b);
}

#[test]
fn spheres_leaving_a_frictional_pile_on_the_device_leave_the_others_contacts_as_on_the_cpu() {
    // A 4×4×4 lattice of touching spheres (radii 4.96–5 mm, 9.9 mm apart) on the floor, with
    // friction and rolling resistance: contacts with springs everywhere. An outflow takes the
    // layer at x < 9 mm at the first flow event (step 10); 20 steps later every backend holds
    // the cpu's spheres, in its order, with the cpu's contacts and springs.
    let m = Material {
        density: RHO,
        ..common::granular_material()
    };
    let p = StepParams::new(
        &m,
        2e-5,
        [0.0; 3],
        [0.2; 3],
        [0.0, 0.0, -9.81],
        0.0,
        0.00496,
    )
    .unwrap();
    let mut pile = Particles::default();
    for k in 0..64u32 {
        let at = [k % 4, (k / 4) % 4, k / 16].map(|i| 0.0049 + i as f32 * 0.0099);
        pile.push(
            at,
            [0.0; 3],
            0.00496 + 0.00004 * ((k * 37) % 11) as f32 / 10.0,
        )
        .unwrap();
    }
    let flow = FlowSet {
        outflows: vec![(glam::Vec3::ZERO, glam::Vec3::new(0.009, 0.2, 0.2))],
        every: Some(10),
        ..FlowSet::default()
    };
    let run = |kind| {
        let mut s = stepper(kind, pile.clone(), p.clone(), flow.clone(), true);
        s.advance(30).unwrap();
        (s.flow_counts().unwrap(), s.particles().unwrap())
    };
    let (cpu_counts, cpu) = run(BackendKind::Cpu);
    assert_eq!(cpu_counts.removed, 16);
    assert!(
        cpu.history.contacts().count() > 200,
        "the pile keeps springs"
    );
    let largest = |x: &mut dyn Iterator<Item = f32>| x.fold(0.0f32, |m, v| m.max(v.abs()));
    let xi_max = largest(&mut cpu.history.contacts().flat_map(|(_, e)| e.tangential));
    on_every_backend(|kind| {
        let (counts, got) = run(kind);
        assert_eq!(counts.removed, 16);
        if kind == BackendKind::WgpuCompute {
            assert_eq!(counts.read_backs, 0, "{counts:?}");
        }
        assert_eq!(got.radii, cpu.radii, "the same spheres, in the same order");
        for (a, b) in got.positions.iter().zip(&cpu.positions) {
            let gap = glam::Vec3::from(*a).distance(glam::Vec3::from(*b));
            assert!(gap < 1e-6, "{a:?} vs the cpu's {b:?}");
        }
        for i in 0..cpu.len() {
            let mut a = got.history.of(i).to_vec();
            let mut b = cpu.history.of(i).to_vec();
            a.sort_by_key(|e| e.partner);
            b.sort_by_key(|e| e.partner);
            let partners =
                |h: &[mochi::dem::HistoryEntry]| h.iter().map(|e| e.partner).collect::<Vec<_>>();
            assert_eq!(partners(&a), partners(&b), "the contacts of sphere {i}");
            for (x, y) in a.iter().zip(&b) {
                for k in 0..3 {
                    let gap = (x.tangential[k] - y.tangential[k]).abs();
                    assert!(
                        gap <= 1e-3 * xi_max,
                        "sphere {i}'s spring with {}",
                        x.partner
                    );
                }
            }
        }
    });
}

#[test]
fn an_event_that_lists_thousands_of_spheres_leaving_and_near_an_inflow_matches_the_cpu() {
    // 10,648 spheres of 2 mm on a 6 mm lattice (none touching, no gravity): an outflow takes
    // the 4,840 at x ≤ 0.06 m, an inflow drops 2 mm spheres among the 5,324 at x ≥ 0.07 m: more
    // than the scan's first lists hold on either side.
    let mut lattice = Particles::default();
    for k in 0..22u32.pow(3) {
        let at = [k % 22, (k / 22) % 22, k / 484].map(|i| 0.004 + i as f32 * 0.006);
        lattice.push(at, [0.0; 3], 0.002).unwrap();
    }
    let inflow = InflowConfig {
        lo: Some([0.07, 0.0, 0.0]),
        hi: Some([0.13, 0.13, 0.13]),
        rate: Some(50_000.0),
        sphere_radius: Some(0.002),
        seed: Some(3),
        ..InflowConfig::default()
    };
    let flow = FlowSet {
        inflows: vec![inflow.build(0, RHO, 0).unwrap()],
        outflows: vec![(glam::Vec3::ZERO, glam::Vec3::new(0.061, 0.2, 0.2))],
        every: Some(10),
        ..FlowSet::default()
    };
    let run = |kind| {
        let mut s = stepper(kind, lattice.clone(), params(0.0), flow.clone(), true);
        let advance = s.advance(10).unwrap();
        assert_eq!(advance.contacts, 0, "an inserted sphere overlaps another");
        (s.flow_counts().unwrap(), s.particles().unwrap())
    };
    let (cpu, placed) = run(BackendKind::Cpu);
    assert!(cpu.removed == 4840 && cpu.inserted > 20, "{cpu:?}");
    on_every_backend(|kind| {
        let (counts, now) = run(kind);
        assert_flows_as_the_cpu(kind, (&counts, &now), (&cpu, &placed), 0);
    });
}

#[test]
fn an_inflow_that_outgrows_the_rows_kept_for_it_reopens_the_step_and_matches_the_cpu() {
    // One sphere at first, so the step keeps rows for 4096 more; 2,000,000 spheres/s of 1 mm
    // into a 0.18 m cube without gravity: about 2000 an event (every 10 steps), which outgrows
    // the rows at the third event.
    let first = Particles {
        positions: vec![[0.1, 0.1, 0.195]],
        velocities: vec![[0.0; 3]],
        angular_velocities: vec![[0.0; 3]],
        radii: vec![0.001],
        ..Particles::default()
    };
    let inflow = InflowConfig {
        lo: Some([0.01, 0.01, 0.01]),
        hi: Some([0.19, 0.19, 0.19]),
        rate: Some(2e6),
        sphere_radius: Some(0.001),
        ..InflowConfig::default()
    };
    let flow = FlowSet {
        inflows: vec![inflow.build(0, RHO, 0).unwrap()],
        every: Some(10),
        ..FlowSet::default()
    };
    let run = |kind| {
        let mut s = stepper(kind, first.clone(), params(0.0), flow.clone(), true);
        let advance = s.advance(40).unwrap();
        assert_eq!(advance.contacts, 0, "an inserted sphere overlaps another");
        (s.flow_counts().unwrap(), s.particles().unwrap())
    };
    let (cpu, placed) = run(BackendKind::Cpu);
    assert!(cpu.inserted > 5000, "{cpu:?}");
    on_every_backend(|kind| {
        let (counts, now) = run(kind);
        // On wgpu-compute the one event that found no room read the spheres back and reopened
        // the step.
        assert_flows_as_the_cpu(kind, (&counts, &now), (&cpu, &placed), 1);
    });
}

#[test]
fn auto_prefers_wgpu_compute_where_spheres_flow() {
    let start = Start {
        particles: Particles::default(),
        params: params(-9.81),
        mode: ProxyMode::Mochi,
        walls: WallSet::default(),
        flow: FlowSet {
            floor: Some(0.0),
            ..FlowSet::default()
        },
    };
    let opened = open_scene(BackendChoice::Auto, start, &Options::default()).unwrap();
    let (kind, reason) = (opened.kind, opened.reason.unwrap());
    assert!(reason.contains("where spheres flow"), "{reason}");
    // Where wgpu-compute runs (and is no software adapter), auto takes it before optix and
    // wgpu-rq; else it says why it passed over it.
    if kind != BackendKind::WgpuCompute {
        assert!(reason.contains("skipped wgpu-compute"), "{reason}");
    }
    if common::expected(BackendKind::Optix) {
        assert!(reason.starts_with("auto picked wgpu-compute"), "{reason}");
    }
}
