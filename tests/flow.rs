//! Inflow and outflow on the cpu step (`dem::flow`): an inflow inserts ⌊rate·t⌋ spheres, each
//! where it overlaps nothing; mass is conserved (initial + inserted = present + removed);
//! without the box walls a sphere that falls below the box is removed; a run with both resumes
//! from a checkpoint bit for bit.

use mochi::ProxyMode;
use mochi::dem::flow::{FlowSet, InflowConfig, OutflowConfig};
use mochi::dem::model::{Material, mass};
use mochi::dem::scene::Start;
use mochi::dem::walls::WallSet;
use mochi::dem::{Particles, StepParams, Stepper};
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

fn stepper(
    particles: Particles,
    params: StepParams,
    flow: FlowSet,
    box_walls: bool,
) -> Box<dyn Stepper> {
    let start = Start {
        particles,
        params,
        mode: ProxyMode::Mochi,
        walls: WallSet::new(box_walls, Vec::new()).unwrap(),
        flow,
    };
    let choice = BackendChoice::Named(BackendKind::Cpu);
    open_scene(choice, start, &Options::default()).unwrap().0
}

fn total_mass(p: &Particles) -> f64 {
    p.radii.iter().map(|&r| mass(RHO as f32, r) as f64).sum()
}

#[test]
fn an_inflow_inserts_at_its_rate_where_nothing_is_and_never_overlaps() {
    // No gravity and no velocity: the spheres stay where they are put, so any overlap would be
    // one the inflow made. 2000 spheres/s into a slab that holds a few hundred: it fills, then
    // refuses.
    let inflow = InflowConfig {
        velocity: None,
        ..top_inflow()
    };
    let flow = FlowSet {
        inflows: vec![inflow.build(0, RHO).unwrap()],
        ..FlowSet::default()
    };
    let mut s = stepper(Particles::default(), params(0.0), flow, true);
    for _ in 0..100 {
        let advance = s.advance(10).unwrap();
        assert_eq!(advance.contacts, 0, "an inserted sphere overlaps another");
    }
    let counts = s.flow_counts().unwrap();
    // ⌊2000/s · 1000 dt⌋ (dt in f32: 0.1 s less 2.5e-10), each inserted or refused.
    let due = (2000.0 * 1000.0 * params(0.0).dt as f64).floor() as u64;
    assert_eq!(due, 199);
    assert_eq!(counts.inserted + counts.refused, due);
    assert!(counts.inserted > 100, "{counts:?}");
    assert_eq!(s.particles().unwrap().len() as u64, counts.inserted);
}

#[test]
fn mass_is_conserved_through_an_inflow_and_an_outflow() {
    // Spheres rain onto the floor, where an outflow 2 cm deep removes them.
    let flow = FlowSet {
        inflows: vec![top_inflow().build(0, RHO).unwrap()],
        outflows: vec![
            OutflowConfig {
                lo: [0.0; 3],
                hi: [0.2, 0.2, 0.02],
            }
            .build(0)
            .unwrap(),
        ],
        floor: None,
    };
    let first = Particles {
        positions: vec![[0.1, 0.1, 0.1]],
        velocities: vec![[0.0; 3]],
        angular_velocities: vec![[0.0; 3]],
        radii: vec![0.006],
        ..Particles::default()
    };
    let initial = total_mass(&first);
    let mut s = stepper(first, params(-9.81), flow, true);
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
    let mut s = stepper(falling, params(-9.81), flow, false);
    s.advance(300).unwrap();
    assert_eq!(s.particles().unwrap().len(), 0);
    let c = s.flow_counts().unwrap();
    assert_eq!(c.removed, 1);
    assert!((c.removed_mass - mass(RHO as f32, 0.005) as f64).abs() < 1e-12);
}

#[test]
fn a_run_with_inflow_and_outflow_resumes_from_its_checkpoint_bit_for_bit() {
    let flow = || FlowSet {
        inflows: vec![top_inflow().build(0, RHO).unwrap()],
        // A corner of the floor drains; elsewhere the spheres pile up and touch.
        outflows: vec![(glam::Vec3::ZERO, glam::Vec3::new(0.06, 0.2, 0.05))],
        floor: None,
    };
    let p = params(-9.81);
    let mut straight = stepper(Particles::default(), p, flow(), true);
    straight.advance(2400).unwrap();
    let mut first = stepper(Particles::default(), p, flow(), true);
    first.advance(1200).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("checkpoint.bin");
    mochi::io::write_checkpoint(&file, &first.particles().unwrap(), "").unwrap();
    let (saved, _) = mochi::io::read_checkpoint(&file).unwrap();
    let mut resumed = stepper(saved, p, flow(), true);
    resumed.advance(1200).unwrap();
    let (a, b) = (straight.particles().unwrap(), resumed.particles().unwrap());
    assert!(
        straight.flow_counts().unwrap().removed > 0,
        "the outflow was used"
    );
    assert!(!a.history.is_empty(), "the run had contact history");
    assert_eq!(a, b);
}
