//! A run decomposed over ranks (threads of this process, `LocalComm`) is the whole run bit for
//! bit on the cpu backend: a poured pile with friction, rolling resistance and its history,
//! spheres crossing the slabs' faces, on 2, 3 and 4 ranks, ghosts exchanged every step or every
//! few steps; the contacts each counts; new motion (a sphere put in another rank's slab),
//! external loads and gravity between steps; spheres pouring in and leaving; the faces moved to
//! balance the work; frames and checkpoints written in pieces, one a rank, read back as the
//! gathered ones, and a checkpoint in pieces resumed on another number of ranks (each rank
//! reading the whole history, or its own spheres' alone); clumps among
//! spheres, and clumps pouring in. On a GPU backend it matches the whole run on it.

mod common;

use mochi::clump::{Clump, ClumpKind, ClumpSet, ClumpTemplate, RigidBody};
use mochi::dem::flow::{FlowSet, InflowConfig, OutflowConfig};
use mochi::dem::scene::{Overrides, SceneConfig};
use mochi::dem::{Particles, Snapshot, Stepper};
use mochi::distributed::{Comm, Leader, LocalComm, RankStepper, Slabs, follow, owned_at_opening};
use mochi::engines::BackendChoice::Named;
use mochi::engines::cpu::CpuStepper;
use mochi::engines::{BackendKind, DemSetup, Options, open_setup};
use mochi::io::{
    Frame, FrameSeries, OwnedFrame, piece_folder_for, read_checkpoint,
    read_checkpoint_keeping_history, read_frame, write_checkpoint_index, write_vtu,
};
use std::path::Path;

/// The start of the scene of `scene` (flat keys), as a step opens it.
fn setup_of(scene: &str) -> DemSetup {
    let start = SceneConfig::parse(Some(scene), None, &Overrides::default())
        .and_then(|c| c.build())
        .unwrap();
    DemSetup {
        particles: start.particles,
        params: start.params,
        mode: start.mode,
        walls: start.walls,
    }
}

/// A poured pile of polydisperse spheres in mid-fall and landing: contacts with history,
/// walls, and spheres moving across the box.
fn landing() -> DemSetup {
    landing_with("")
}

/// [`landing`] of the scene with `more` lines.
fn landing_with(more: &str) -> DemSetup {
    let scene = format!("scene = \"pour\"\nspheres = 400\nseed = 5\n{more}");
    let scene = scene.as_str();
    let setup = setup_of(scene);
    // Into the pour, till the first spheres have landed.
    let mut whole = CpuStepper::open(setup.clone()).unwrap();
    let mut contacts = 0;
    for _ in 0..40 {
        contacts = whole.advance(250).unwrap().contacts;
        if contacts > 100 {
            break;
        }
    }
    assert!(contacts > 100, "{contacts} contacts");
    // Swept along the axis the slabs cut, by a fifth of the box over the test's steps, so
    // that spheres cross the faces.
    let particles = whole.particles().unwrap();
    swept(DemSetup { particles, ..setup }, 0.2)
}

/// `setup` with gravity along the axis two slabs would cut, towards its high end: the spheres
/// slide into the second slab.
fn tilted(mut setup: DemSetup) -> DemSetup {
    let p = &mut setup.params;
    let (lo, hi) = (p.box_lo.map(f64::from), p.box_hi.map(f64::from));
    let axis = Slabs::along_longest(lo, hi, 2).unwrap().axis;
    let g = glam::Vec3::from(p.gravity).length();
    p.gravity = [0.0; 3];
    p.gravity[axis] = g;
    setup
}

/// `setup` with every sphere sped up along the axis two slabs would cut, by `fraction` of the
/// box over the test's steps.
fn swept(mut setup: DemSetup, fraction: f64) -> DemSetup {
    let p = &setup.params;
    let (lo, hi) = (p.box_lo.map(f64::from), p.box_hi.map(f64::from));
    let axis = Slabs::along_longest(lo, hi, 2).unwrap().axis;
    let speed = fraction * (hi[axis] - lo[axis]) / (STEPS as f64 * p.dt as f64);
    for v in &mut setup.particles.velocities {
        v[axis] += speed as f32;
    }
    setup
}

/// The steps each run takes from the landing.
const STEPS: u32 = 400;

/// What a test does to a step (every rank of a decomposed run does the same): the contacts
/// each of its advances reported.
type Script = fn(&mut dyn Stepper, &DemSetup) -> Vec<u64>;

/// `script` run on the whole of `setup` alone: the particles after, the contacts.
fn alone(setup: &DemSetup, flow: &FlowSet, script: Script) -> (Particles, Vec<u64>) {
    let mut whole = CpuStepper::open(setup.clone())
        .unwrap()
        .with_flow(flow.clone(), setup.mode);
    let contacts = script(&mut whole, setup);
    (whole.particles().unwrap(), contacts)
}

/// `script` run on `ranks` ranks: the particles after (gathered on rank 0; every rank's own
/// read of them is the same), the contacts, and the spheres each rank owned at the start and
/// at the end.
fn decomposed(
    setup: &DemSetup,
    (ranks, every, rebalance): (usize, u32, u64),
    flow: &FlowSet,
    script: Script,
) -> (Particles, Vec<u64>, Vec<[usize; 2]>) {
    let group = LocalComm::group(ranks).unwrap();
    let results: Vec<_> = std::thread::scope(|scope| {
        let handles: Vec<_> = group
            .into_iter()
            .map(|comm| {
                scope.spawn(move || {
                    let mut rank = RankStepper::new(comm, setup)
                        .and_then(|rank| rank.exchanging_every(every))
                        .and_then(|rank| rank.with_flow(flow.clone()))
                        .unwrap()
                        .rebalancing_every(rebalance);
                    let first = rank.own_spheres();
                    let faces = rank.grid().clone();
                    let contacts = script(&mut rank, setup);
                    // Rebalanced, the faces moved.
                    assert_eq!(*rank.grid() != faces, rebalance > 0);
                    let gathered = rank.gather().unwrap();
                    let everywhere = rank.particles().unwrap();
                    let owned = [first, rank.own_spheres()];
                    (gathered, everywhere, contacts, owned)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let owned = results.iter().map(|r| r.3).collect();
    let contacts = results[0].2.clone();
    assert!(
        results.iter().all(|r| r.2 == contacts),
        "every rank counts alike"
    );
    assert!(
        results[1..].iter().all(|r| r.0.is_none()),
        "gathered on rank 0"
    );
    let gathered = results[0].0.clone().expect("gathered on rank 0");
    for r in &results {
        assert_eq!(
            r.1.positions, gathered.positions,
            "every rank reads the run"
        );
    }
    (gathered, contacts, owned)
}

/// Whether `got` is `expected` bit for bit: every centre, residual, velocity, spin, contact
/// history entry and clump.
fn assert_same(got: &Particles, expected: &Particles, ranks: usize) {
    assert_eq!(got.len(), expected.len());
    assert_eq!(got.step, expected.step);
    assert!(
        got.clumps == expected.clumps,
        "{ranks} ranks: the clumps differ"
    );
    for i in 0..expected.len() {
        let bits = |p: &Particles| {
            let x = p.exact_position(i).map(f64::to_bits);
            let v = p.velocities[i].map(f32::to_bits);
            let w = p.angular_velocities[i].map(f32::to_bits);
            (x, v, w)
        };
        assert_eq!(bits(got), bits(expected), "{ranks} ranks, sphere {i}");
        assert_eq!(
            got.history.of(i),
            expected.history.of(i),
            "{ranks} ranks, the contacts of sphere {i}"
        );
    }
}

/// `script` on `setup` with `flow` decomposed each way of `runs` (ranks, steps between
/// exchanges, steps between rebalancings): each the whole run's `expected` particles and its
/// `reported` numbers bit for bit. Returns the spheres each rank owned at the start and at the
/// end, by run.
fn each_is_the_whole_run(
    (setup, flow, script): (&DemSetup, &FlowSet, Script),
    runs: &[(usize, u32, u64)],
    (expected, reported): (&Particles, &[u64]),
) -> Vec<Vec<[usize; 2]>> {
    let mut owned = Vec::new();
    for &(ranks, every, rebalance) in runs {
        let (got, got_reported, each) = decomposed(setup, (ranks, every, rebalance), flow, script);
        let how = format!("{ranks} ranks, every {every} steps, rebalanced every {rebalance}");
        assert_eq!(got_reported, reported, "{how}");
        assert_same(&got, expected, ranks);
        owned.push(each);
    }
    owned
}

#[test]
fn a_run_on_several_ranks_is_the_whole_run_bit_for_bit() {
    let setup = landing();
    let script: Script = |s, _| vec![s.advance(STEPS).unwrap().contacts];
    let (expected, contacts) = alone(&setup, &FlowSet::default(), script);
    assert!(contacts[0] > 50, "{contacts:?} contacts at the end");
    // Ghosts exchanged every step, or every 5 or 8 (their halo that many cells deep); the
    // faces moved every 50 or 40 steps to balance the ranks' work.
    let runs = [
        (2, 1, 0),
        (3, 1, 0),
        (4, 1, 0),
        (2, 5, 0),
        (3, 8, 0),
        (3, 1, 50),
        (4, 5, 40),
    ];
    let how = (&setup, &FlowSet::default(), script);
    for owned in each_is_the_whole_run(how, &runs, (&expected, &contacts)) {
        // Each sphere held once, and some crossed a face.
        let held = |k: usize| owned.iter().map(|o| o[k]).sum::<usize>();
        assert_eq!(
            (held(0), held(1)),
            (expected.len(), expected.len()),
            "{owned:?}"
        );
        assert!(
            owned.iter().any(|o| o[0] != o[1]),
            "none moved across: {owned:?}"
        );
    }
}

#[test]
fn a_decomposed_run_takes_new_motion_loads_and_gravity_as_the_whole_run_does() {
    let setup = landing();
    let script: Script = |s, setup| {
        let mut contacts = vec![s.advance(100).unwrap().contacts];
        // Sphere 0 put on the sphere farthest along the slabs' axis (in another rank's slab,
        // beyond the halo of its own: it meets that sphere only where it migrates), every
        // sphere slowed to half its speed.
        let mut now = s.particles().unwrap();
        let p = &setup.params;
        let axis = Slabs::along_longest(p.box_lo.map(f64::from), p.box_hi.map(f64::from), 2)
            .unwrap()
            .axis;
        let mut x = now.exact_positions().unwrap();
        let far = (0..x.len())
            .max_by(|&a, &b| x[a][axis].total_cmp(&x[b][axis]))
            .unwrap();
        x[0] = x[far];
        x[0][2] += 0.95 * (now.radii[0] + now.radii[far]) as f64;
        for v in &mut now.velocities {
            *v = v.map(|c| 0.5 * c);
        }
        let motion = mochi::dem::Motion {
            positions: Some(&x),
            velocities: Some(&now.velocities),
            ..Default::default()
        };
        s.set_motion(&motion).unwrap();
        // A push along the axis on every sphere, and a twist.
        let n = now.len();
        let loads = mochi::dem::ExternalLoads {
            forces: (0..n).map(|i| [1e-6 * (i % 7) as f32, 0.0, 2e-6]).collect(),
            torques: vec![[0.0, 0.0, 1e-10]; n],
        };
        s.set_external_loads(&loads).unwrap();
        contacts.push(s.advance(100).unwrap().contacts);
        s.set_gravity([0.0, 0.0, -5.0]).unwrap();
        contacts.push(s.advance(100).unwrap().contacts);
        contacts
    };
    let (expected, contacts) = alone(&setup, &FlowSet::default(), script);
    for (ranks, every, rebalance) in [(2, 1, 0), (4, 1, 0), (2, 7, 0), (3, 1, 60)] {
        let (got, got_contacts, _) = decomposed(
            &setup,
            (ranks, every, rebalance),
            &FlowSet::default(),
            script,
        );
        assert_eq!(got_contacts, contacts, "{ranks} ranks");
        assert_same(&got, &expected, ranks);
    }
}

#[test]
fn a_decomposed_run_keeps_each_contacts_load_history() {
    // The Mindlin–Deresiewicz model keeps each contact's load history beside its spring: it
    // crosses the faces with its sphere, and with a ghost for a round of several steps.
    let setup = landing_with("tangential_model = \"mindlin-deresiewicz\"\n");
    assert!(setup.params.friction.keeps_load());
    let script: Script = |s, _| vec![s.advance(STEPS).unwrap().contacts];
    let (expected, contacts) = alone(&setup, &FlowSet::default(), script);
    assert!(expected.history.has_loads());
    assert!(expected.history.contact_loads().any(|l| l.normal > 0.0));
    for (ranks, every, rebalance) in [(2, 1, 0), (3, 5, 60)] {
        let no_flow = &FlowSet::default();
        let (got, got_contacts, _) = decomposed(&setup, (ranks, every, rebalance), no_flow, script);
        assert_eq!(got_contacts, contacts, "{ranks} ranks");
        assert_same(&got, &expected, ranks);
        for i in 0..expected.len() {
            let (g, e) = (got.history.loads_of(i), expected.history.loads_of(i));
            assert_eq!(g, e, "{ranks} ranks, the load histories of sphere {i}");
        }
    }
}

#[test]
fn a_decomposed_run_with_an_inflow_and_an_outflow_is_the_whole_run_bit_for_bit() {
    // Spheres pour in over the whole width of the box, across the slabs, and an outflow in
    // one corner of the floor takes those that land there.
    let setup = landing();
    let p = &setup.params;
    let at = |a: usize, f: f64| p.box_lo[a] as f64 + f * (p.box_hi[a] - p.box_lo[a]) as f64;
    let (r_min, r_max) = setup.particles.radius_range();
    let inflow = InflowConfig {
        lo: Some([at(0, 0.05), at(1, 0.05), at(2, 0.8)]),
        hi: Some([at(0, 0.95), at(1, 0.95), at(2, 0.95)]),
        rate: Some(1.5e4),
        sphere_radii: Some([r_min as f64, r_max as f64]),
        velocity: Some([0.0, 0.0, -0.5]),
        seed: Some(3),
        ..InflowConfig::default()
    };
    let outflow = OutflowConfig {
        lo: [at(0, 0.0), at(1, 0.0), at(2, 0.0)],
        hi: [at(0, 0.4), at(1, 1.0), at(2, 0.15)],
    };
    let density = p.materials.densities[0] as f64;
    let flow = FlowSet {
        inflows: vec![inflow.build(0, density, 0).unwrap()],
        outflows: vec![outflow.build(0).unwrap()],
        ..FlowSet::default()
    };
    let script: Script = |s, _| {
        let contacts = s.advance(STEPS).unwrap().contacts;
        let c = s.flow_counts().unwrap();
        vec![contacts, c.inserted, c.removed, c.refused, c.events]
    };
    let (expected, counts) = alone(&setup, &flow, script);
    assert!(
        counts[1] > 50 && counts[2] > 5,
        "inserted, removed: {counts:?}"
    );
    assert_ne!(expected.len(), setup.particles.len());
    let runs = [(2, 1, 0), (3, 4, 0), (3, 1, 50)];
    each_is_the_whole_run((&setup, &flow, script), &runs, (&expected, &counts));
}

/// The `drum` scene of 200 spheres run till they lie in the drum and it lifts them.
fn drum() -> DemSetup {
    let scene = "scene = \"drum\"\nspheres = 200\n";
    let setup = setup_of(scene);
    assert!(!setup.walls.meshes.is_empty());
    let mut whole = CpuStepper::open(setup.clone()).unwrap();
    let mut contacts = 0;
    for _ in 0..40 {
        contacts = whole.advance(500).unwrap().contacts;
        if contacts > 100 {
            break;
        }
    }
    assert!(contacts > 100, "{contacts} contacts");
    DemSetup {
        particles: whole.particles().unwrap(),
        ..setup
    }
}

#[test]
fn a_decomposed_run_in_a_turning_drum_is_the_whole_run_bit_for_bit_and_loads_the_drum_alike() {
    // The drum is a mesh wall turning about its axis: every rank turns its own copy, steps its
    // spheres' contacts with it, and counts its own spheres' loads on it (not its ghosts').
    let setup = drum();
    let script: Script = |s, _| {
        let contacts = s.advance(STEPS).unwrap().contacts;
        let load = s.wall_loads()[0];
        let mut out = vec![contacts];
        out.extend(load.force.iter().chain(&load.torque).map(|x| x.to_bits()));
        out
    };
    let (expected, counts) = alone(&setup, &FlowSet::default(), script);
    let load = |c: &[u64]| -> Vec<f64> { c[1..].iter().map(|&b| f64::from_bits(b)).collect() };
    let wall = load(&counts);
    let largest = wall.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(counts[0] > 50 && largest > 0.0, "{counts:?}");
    for (ranks, every, rebalance) in [(2, 1, 0), (3, 3, 40)] {
        let (got, got_counts, owned) = decomposed(
            &setup,
            (ranks, every, rebalance),
            &FlowSet::default(),
            script,
        );
        assert!(owned.iter().all(|o| o[1] > 0), "{owned:?}");
        assert_eq!(got_counts[0], counts[0], "{ranks} ranks");
        assert_same(&got, &expected, ranks);
        // The same loads on the drum, summed in another order.
        for (g, w) in load(&got_counts).iter().zip(&wall) {
            assert!(
                (g - w).abs() <= 1e-9 * largest,
                "{ranks} ranks: {g} against {w}"
            );
        }
    }
}

/// The grains of the clumps' pour and the clumps it makes of them (`[[clump]]` tables).
const GRAINS: &str = "[source]\nscene = \"pour\"\nspheres = 160\nseed = 7\n";
const SHAPES: &str = "[[clump]]\nshape = \"tetrahedron\"\n[[clump]]\nshape = \"rod\"\n";

/// Dimers and tetrahedra among free spheres, landing: the pour of [`GRAINS`] with its first
/// half of grains clumps of [`SHAPES`] (each in its grain's place) and its second half spheres,
/// run till they touch, then every grain swept along the axis two slabs would cut by a fifth
/// of the box over the test's steps (clumps and spheres cross the faces).
fn clumps_among_spheres() -> DemSetup {
    let clumped = setup_of(&format!("{GRAINS}{SHAPES}"));
    let spheres = setup_of(GRAINS).particles;
    let mut set = clumped.particles.clumps.clone();
    let half = set.clumps.len() / 2;
    set.clumps.truncate(half);
    let mut free = Particles::default();
    for k in half..spheres.len() {
        let (c, v, r) = (
            spheres.positions[k],
            spheres.velocities[k],
            spheres.radii[k],
        );
        free.push(c, v, r).unwrap();
    }
    let particles = Particles::with_clumps(set, free).unwrap();
    let setup = DemSetup {
        particles,
        ..clumped
    };
    let mut whole = CpuStepper::open(setup.clone()).unwrap();
    let mut contacts = 0;
    for _ in 0..40 {
        contacts = whole.advance(250).unwrap().contacts;
        if contacts > 30 {
            break;
        }
    }
    assert!(contacts > 30, "{contacts} contacts");
    let mut particles = whole.particles().unwrap();
    let p = &setup.params;
    let (lo, hi) = (p.box_lo.map(f64::from), p.box_hi.map(f64::from));
    let axis = Slabs::along_longest(lo, hi, 2).unwrap().axis;
    let speed = 0.2 * (hi[axis] - lo[axis]) / (STEPS as f64 * p.dt as f64);
    for clump in &mut particles.clumps.clumps {
        clump.body.velocity[axis] += speed;
    }
    let components = particles.clumps.component_count();
    for v in &mut particles.velocities[components..] {
        v[axis] += speed as f32;
    }
    particles.place_clump_components().unwrap();
    DemSetup { particles, ..setup }
}

#[test]
fn a_run_of_clumps_among_spheres_on_several_ranks_is_the_whole_run_bit_for_bit() {
    // A clump is stepped by the rank that holds its centre, with all its components; as a
    // ghost it goes whole, with every component, to each rank within whose halo one lies.
    let setup = clumps_among_spheres();
    let clumps = setup.particles.clumps.clumps.len();
    assert!(clumps > 50 && setup.particles.len() > setup.particles.clumps.component_count());
    let script: Script = |s, _| vec![s.advance(STEPS).unwrap().contacts];
    let (expected, contacts) = alone(&setup, &FlowSet::default(), script);
    assert!(contacts[0] > 20, "{contacts:?} contacts at the end");
    let runs = [
        (2, 1, 0),
        (3, 1, 0),
        (4, 1, 0),
        (2, 6, 0),
        (3, 1, 50),
        (4, 5, 40),
    ];
    let how = (&setup, &FlowSet::default(), script);
    for owned in each_is_the_whole_run(how, &runs, (&expected, &contacts)) {
        assert!(
            owned.iter().any(|o| o[0] != o[1]),
            "none moved across: {owned:?}"
        );
    }
}

#[test]
fn a_run_of_clumps_pouring_in_on_several_ranks_is_the_whole_run_bit_for_bit() {
    // The inflow inserts clumps across the slabs over the clumps and spheres there; an outflow
    // in a corner of the floor takes what lands there, or one over the lower three quarters of
    // the box takes every clump there is at once (the clumps poured in after take kinds after
    // the kinds of those that left).
    let setup = clumps_among_spheres();
    let p = &setup.params;
    let at = |a: usize, f: f64| p.box_lo[a] as f64 + f * (p.box_hi[a] - p.box_lo[a]) as f64;
    let (r_min, r_max) = setup.particles.radius_range();
    for outflow_hi in [[0.3, 0.5, 0.15], [1.0, 1.0, 0.75]] {
        let scene = format!(
            "{GRAINS}{SHAPES}[[inflow]]\nlo = [{}, {}, {}]\nhi = [{}, {}, {}]\nrate = 1e4\n\
             sphere_radii = [{r_min}, {r_max}]\nvelocity = [0, 0, -0.5]\nseed = 3\n\
             [[outflow]]\nlo = [{}, {}, {}]\nhi = [{}, {}, {}]\n",
            at(0, 0.05),
            at(1, 0.05),
            at(2, 0.8),
            at(0, 0.95),
            at(1, 0.95),
            at(2, 0.95),
            at(0, 0.0),
            at(1, 0.0),
            at(2, 0.0),
            at(0, outflow_hi[0]),
            at(1, outflow_hi[1]),
            at(2, outflow_hi[2]),
        );
        let flow = SceneConfig::parse(Some(&scene), None, &Overrides::default())
            .and_then(|c| c.build())
            .unwrap()
            .flow;
        assert!(flow.clumps.is_some());
        let script: Script = |s, _| {
            let contacts = s.advance(STEPS).unwrap().contacts;
            let c = s.flow_counts().unwrap();
            vec![contacts, c.inserted, c.removed, c.events]
        };
        let (expected, counts) = alone(&setup, &flow, script);
        assert!(
            counts[1] > 20 && counts[2] > 0,
            "inserted, removed: {counts:?}"
        );
        // What comes in are clumps: the free spheres do not grow in number.
        let free = |p: &Particles| p.len() - p.clumps.component_count();
        assert!(free(&expected) <= free(&setup.particles));
        let runs = [(2, 1, 0), (3, 4, 50)];
        each_is_the_whole_run((&setup, &flow, script), &runs, (&expected, &counts));
    }
}

#[test]
fn a_clump_across_a_face_feels_the_spheres_its_far_end_touches() {
    // Rods of eight spheres lie across the face of two slabs, each centre on one side, and a
    // sphere of the other side touches each rod's far end: farther from the face than any
    // sphere's partners reach (a cell), so the halo holds the rods' span beyond a cell.
    let setup = setup_of(GRAINS);
    let p = &setup.params;
    let (lo, hi) = (p.box_lo.map(f64::from), p.box_hi.map(f64::from));
    let slabs = Slabs::along_longest(lo, hi, 2).unwrap();
    let axis = slabs.axis;
    let face = 0.5 * (lo[axis] + hi[axis]);
    let r = 0.5 * setup.particles.radius_range().0 as f64;
    let density = p.materials.densities[0] as f64;
    let rod = ClumpKind::new(&ClumpTemplate::rod(8, r).unwrap(), density);
    let along = |k: usize| glam::DVec3::from_array(std::array::from_fn(|a| (a == k) as u8 as f64));
    // The template's long axis, turned onto the slabs' axis.
    let long = (0..3)
        .max_by(|&a, &b| {
            let extent = |a: usize| {
                rod.template
                    .components
                    .iter()
                    .map(|c| c.centre[a].abs())
                    .fold(0.0, f64::max)
            };
            extent(a).total_cmp(&extent(b))
        })
        .unwrap();
    let turn = glam::DQuat::from_rotation_arc(along(long), along(axis));
    let span = 3.5 * r;
    let mut clumps = Vec::new();
    let mut free = Particles::default();
    let across = (axis + 1) % 3;
    for k in 0..6 {
        // Alternately on the low side of the face and on the high.
        let side = if k % 2 == 0 { -1.0 } else { 1.0 };
        let mut centre = [0.0; 3];
        centre[2] = lo[2] + 0.3 * (hi[2] - lo[2]);
        centre[across] = lo[across] + (k as f64 + 1.0) / 7.0 * (hi[across] - lo[across]);
        centre[axis] = face + side * 0.5 * r;
        let mut touching = centre;
        touching[axis] = face + side * (0.5 * r - span - 1.9 * r);
        let at = glam::DVec3::from_array(centre);
        let body = RigidBody::new(at, turn, glam::DVec3::ZERO, glam::DVec3::ZERO, &rod.inertia);
        clumps.push(Clump { kind: 0, body });
        free.push(touching.map(|x| x as f32), [0.0; 3], r as f32)
            .unwrap();
    }
    let set = ClumpSet {
        kinds: vec![rod],
        clumps,
    };
    let particles = Particles::with_clumps(set, free).unwrap();
    let setup = DemSetup { particles, ..setup };
    let script: Script = |s, _| {
        let first = s.advance(4).unwrap().contacts;
        vec![first, s.advance(16).unwrap().contacts]
    };
    let (expected, contacts) = alone(&setup, &FlowSet::default(), script);
    assert_eq!(contacts[0], 6, "each rod touches its sphere: {contacts:?}");
    for (ranks, every) in [(2, 1), (2, 4)] {
        let (got, got_contacts, owned) =
            decomposed(&setup, (ranks, every, 0), &FlowSet::default(), script);
        assert!(owned.iter().all(|o| o[0] == 3 * 8 + 3), "{owned:?}");
        assert_eq!(got_contacts, contacts);
        assert_same(&got, &expected, ranks);
    }
}

#[test]
fn a_run_of_clumps_on_two_ranks_of_each_gpu_backend_matches_the_whole_run_on_it() {
    // A GPU rank with clumps opens its step again each round (its kept step exchanges spheres
    // alone), and writes whole frames and checkpoints: the same clumps as the whole run on
    // that backend, to its sums' order.
    let setup = clumps_among_spheres();
    let gpus = common::dem_backends()
        .into_iter()
        .filter(|&k| k != BackendKind::Cpu);
    for kind in gpus {
        let _named = common::Naming(kind);
        let mut whole = open_setup(kind, setup.clone(), &Options::default()).unwrap();
        let contacts = whole.advance(STEPS).unwrap().contacts;
        let expected = whole.particles().unwrap();
        let out = tempfile::tempdir().unwrap();
        let ranks = on_two_ranks(kind, &setup, (None, 0), |rank| {
            let contacts = rank.advance(STEPS).unwrap().contacts;
            assert!(rank.write_pieces(out.path()).unwrap().is_none());
            let folder = piece_folder_for(&out.path().join("checkpoint.bin"), STEPS as u64);
            assert!(rank.write_checkpoint_pieces(&folder).unwrap().is_none());
            let snapshot = rank.snapshot().unwrap();
            (
                contacts,
                rank.particles().unwrap(),
                snapshot,
                rank.ghost_spheres(),
            )
        });
        let (got_contacts, got, snapshot, _) = &ranks[0];
        assert!(ranks.iter().any(|r| r.3 > 0), "no ghosts");
        assert!(
            snapshot.particles.clumps == got.clumps,
            "frames show the clumps"
        );
        let clumps = |p: &Particles| p.clumps.clumps.len();
        assert_eq!(clumps(got), clumps(&expected));
        let (r_min, _) = expected.radius_range();
        let gap = common::largest_gap(got, &expected);
        let more = *got_contacts as f64 / contacts as f64 - 1.0;
        eprintln!(
            "{}: largest gap {gap:.3e} m (r_min {r_min:.3e}), contacts {got_contacts} against \
             {contacts}",
            kind.name()
        );
        assert!(gap < 1e-3 * r_min, "largest gap {gap} m");
        assert!(
            more.abs() < 0.02,
            "{got_contacts} contacts against {contacts}"
        );
    }
}

#[test]
fn new_motion_for_a_clumps_sphere_is_refused_on_every_rank() {
    let setup = clumps_among_spheres();
    let refused = on_cpu_ranks(3, &setup, |mut rank| {
        rank.advance(10).unwrap();
        let now = rank.particles().unwrap();
        let mut v = now.velocities.clone();
        // The last clump's last component: its rank alone sees it changed.
        v[now.clumps.component_count() - 1][0] += 1.0;
        let motion = mochi::dem::Motion {
            velocities: Some(&v),
            ..Default::default()
        };
        let e = rank.set_motion(&motion).unwrap_err().to_string();
        // A free sphere's new motion is taken.
        let mut v = now.velocities.clone();
        v[now.len() - 1][0] += 1.0;
        let motion = mochi::dem::Motion {
            velocities: Some(&v),
            ..Default::default()
        };
        rank.set_motion(&motion).unwrap();
        e
    });
    for e in refused {
        assert!(e.contains("clump"), "{e}");
    }
}

/// `run` on each of two ranks (threads) of `setup` stepping on backend `kind` (keeping rows
/// for `spare` spheres to come where given, the faces moved every `rebalance` steps where not
/// 0), rank 0's first.
fn on_two_ranks<T: Send>(
    kind: BackendKind,
    setup: &DemSetup,
    how: (Option<usize>, u64),
    run: impl Fn(&mut RankStepper<LocalComm>) -> T + Sync,
) -> Vec<T> {
    on_ranks(2, kind, setup, how, run)
}

/// [`on_two_ranks`] on `ranks` ranks.
fn on_ranks<T: Send>(
    ranks: usize,
    kind: BackendKind,
    setup: &DemSetup,
    (spare, rebalance): (Option<usize>, u64),
    run: impl Fn(&mut RankStepper<LocalComm>) -> T + Sync,
) -> Vec<T> {
    let options = Options::default();
    std::thread::scope(|scope| {
        let handles: Vec<_> = LocalComm::group(ranks)
            .unwrap()
            .into_iter()
            .map(|comm| {
                let (options, run) = (&options, &run);
                scope.spawn(move || {
                    let opened = RankStepper::new(comm, setup)
                        .map(|rank| rank.rebalancing_every(rebalance))
                        .map(|rank| match spare {
                            Some(spare) => rank.keeping_rows_for(spare),
                            None => rank,
                        })
                        .and_then(|rank| rank.on_backend(Named(kind), options))
                        .unwrap();
                    assert_eq!(opened.kind, kind);
                    run(&mut { opened.value })
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

#[test]
fn a_run_in_a_turning_drum_on_two_ranks_of_each_gpu_backend_loads_it_as_the_whole_run() {
    // Each rank's step sums its own spheres' loads on the drum, not its ghosts' (their owners
    // count them): the loads of the last step within 0.5 % of the largest component of the whole
    // run's on the same backend.
    let setup = drum();
    let gpus = common::dem_backends()
        .into_iter()
        .filter(|&k| k != BackendKind::Cpu);
    for kind in gpus {
        let _named = common::Naming(kind);
        let mut whole = open_setup(kind, setup.clone(), &Options::default()).unwrap();
        whole.advance(STEPS).unwrap();
        let components = |s: &dyn Stepper| -> Vec<f64> {
            let load = s.wall_loads()[0];
            load.force.iter().chain(&load.torque).copied().collect()
        };
        let expected = components(&*whole);
        let largest = expected.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(largest > 0.0, "{expected:?}");
        let ranks = on_two_ranks(kind, &setup, (None, 0), |rank| {
            rank.advance(STEPS).unwrap();
            (components(rank), rank.ghost_spheres())
        });
        let got = &ranks[0].0;
        assert!(
            ranks.iter().all(|r| &r.0 == got),
            "every rank's loads alike"
        );
        assert!(ranks.iter().any(|r| r.1 > 0), "no ghosts");
        let gap = got
            .iter()
            .zip(&expected)
            .fold(0.0f64, |m, (g, e)| m.max((g - e).abs()));
        eprintln!("{}: loads {got:?} against {expected:?}", kind.name());
        assert!(gap < 5e-3 * largest, "loads {got:?} against {expected:?}");
    }
}

/// The kinetic energy of translation of `p` (unit density) \[J·m⁻³\].
fn kinetic(p: &Particles) -> f64 {
    (0..p.len())
        .map(|i| {
            let v2: f32 = p.velocities[i].iter().map(|c| c * c).sum();
            (p.radii[i] as f64).powi(3) * v2 as f64
        })
        .sum()
}

/// The frame of `snapshot` of a run of `setup`, as a `.vtu` holds it (written, read back).
fn frame_of(snapshot: &Snapshot, setup: &DemSetup) -> OwnedFrame {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("whole.vtu");
    let kept = setup.params.friction.has_history();
    let contacts = kept.then_some(&snapshot.contacts[..]);
    let frame = Frame::of(&snapshot.particles, setup.params.dt, contacts);
    write_vtu(&path, &frame).unwrap();
    read_frame(&path).unwrap()
}

/// The frame the ranks wrote in `pieces` into `dir` at their last step, named by a `.pvtu`
/// (written here, as rank 0 writes it), read back.
fn read_pieces(dir: &Path, pieces: &[u64], setup: &DemSetup) -> OwnedFrame {
    let mut series = FrameSeries::create(dir).unwrap();
    let step = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| {
            e.unwrap()
                .file_name()
                .to_str()?
                .strip_prefix("frame_")?
                .parse()
                .ok()
        })
        .max()
        .expect("a folder of pieces");
    let time = step as f64 * setup.params.dt as f64;
    let kept = setup.params.friction.has_history();
    let pvtu = series.add_pieces(step, time, pieces.len(), kept).unwrap();
    read_frame(&pvtu).unwrap()
}

/// `run` on each of `ranks` cpu ranks (threads) of `setup`, rank 0's result first.
fn on_cpu_ranks<T: Send>(
    ranks: usize,
    setup: &DemSetup,
    run: impl Fn(RankStepper<LocalComm>) -> T + Sync,
) -> Vec<T> {
    std::thread::scope(|scope| {
        let handles: Vec<_> = LocalComm::group(ranks)
            .unwrap()
            .into_iter()
            .map(|comm| {
                let run = &run;
                scope.spawn(move || run(RankStepper::new(comm, setup).unwrap()))
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

#[test]
fn a_frame_in_pieces_over_ranks_led_from_rank_0_is_the_whole_runs_frame() {
    let setup = landing();
    let mut whole = CpuStepper::open(setup.clone()).unwrap();
    whole.advance(STEPS).unwrap();
    let expected = frame_of(&whole.snapshot().unwrap(), &setup);
    assert!(expected.contacts.iter().any(|&c| c > 0), "no contacts");
    let out = tempfile::tempdir().unwrap();
    let pieces = on_cpu_ranks(3, &setup, |rank| {
        if rank.comm().rank() != 0 {
            return follow(rank).map(|()| None).unwrap();
        }
        // Rank 0 leads: each call goes to the others, which make it too.
        let mut lead = Leader::new(rank).unwrap();
        lead.advance(STEPS).unwrap();
        lead.write_pieces(out.path()).unwrap()
    });
    let [Some(pieces), None, None] = &pieces[..] else {
        panic!("the pieces' spheres on rank 0 alone: {pieces:?}");
    };
    assert_eq!(pieces.len(), 3);
    assert_eq!(pieces.iter().sum::<u64>() as usize, expected.radii.len());
    assert!(pieces.iter().filter(|&&n| n > 0).count() > 1, "{pieces:?}");
    // The same spheres bit for bit, in the order of their ids.
    assert_eq!(read_pieces(out.path(), pieces, &setup), expected);
}

#[test]
fn a_checkpoint_in_pieces_over_ranks_is_the_gathered_one_and_resumes_on_other_ranks_exactly() {
    // Each contact with its spring and its load history (Mindlin–Deresiewicz).
    let setup = landing_with("tangential_model = \"mindlin-deresiewicz\"\n");
    let out = tempfile::tempdir().unwrap();
    let checkpoint = out.path().join("checkpoint.bin");
    let folder = piece_folder_for(&checkpoint, setup.particles.step + STEPS as u64);
    let gathered = on_cpu_ranks(3, &setup, |rank| {
        if rank.comm().rank() != 0 {
            return follow(rank).map(|()| None).unwrap();
        }
        let mut lead = Leader::new(rank).unwrap();
        lead.advance(STEPS).unwrap();
        let pieces = lead
            .write_checkpoint_pieces(&folder)
            .unwrap()
            .expect("pieces");
        assert_eq!(pieces.len(), 3);
        assert!(
            pieces.iter().filter(|p| p.spheres > 0).count() > 1,
            "{pieces:?}"
        );
        let at = (folder.as_path(), lead.step());
        write_checkpoint_index(&checkpoint, at, ("scene", "state"), &pieces).unwrap();
        Some(lead.particles().unwrap())
    });
    let [Some(gathered), None, None] = &gathered[..] else {
        panic!("gathered on rank 0 alone");
    };
    assert!(gathered.history.contact_loads().any(|l| l.normal > 0.0));
    let read = read_checkpoint(&checkpoint).unwrap();
    assert_eq!(
        (read.scene.as_str(), read.state.as_str()),
        ("scene", "state")
    );
    assert_eq!(&read.particles, gathered);
    // Resumed on two ranks, the run goes on as the whole run does, bit for bit.
    let resumed = DemSetup {
        particles: read.particles,
        ..setup.clone()
    };
    let script: Script = |s, _| vec![s.advance(STEPS).unwrap().contacts];
    let (expected, contacts) = alone(&resumed, &FlowSet::default(), script);
    let mut whole = CpuStepper::open(setup.clone()).unwrap();
    whole.advance(2 * STEPS).unwrap();
    assert_same(&whole.particles().unwrap(), &expected, 1);
    let (got, got_contacts, _) = decomposed(&resumed, (2, 1, 0), &FlowSet::default(), script);
    assert_eq!(got_contacts, contacts);
    assert_same(&got, &expected, 2);
    // Each of three ranks reading the contact history of its own spheres alone (two of them
    // some) goes on alike.
    let (lo, hi) = (setup.params.box_lo, setup.params.box_hi);
    let own_history = |at: (usize, usize)| {
        let owned = |_: &str, p: &Particles| owned_at_opening(p, (lo, hi), at);
        read_checkpoint_keeping_history(&checkpoint, &owned).unwrap()
    };
    let total = resumed.particles.history.len();
    let mut read_by_ranks = Vec::new();
    let group = LocalComm::group(3).unwrap();
    let results: Vec<_> = std::thread::scope(|scope| {
        let handles: Vec<_> = (group.into_iter())
            .map(|comm| {
                let (read, kept) = own_history((comm.rank(), comm.size()));
                read_by_ranks.push(kept.contacts.len());
                let setup = DemSetup {
                    particles: read.particles,
                    ..resumed.clone()
                };
                scope.spawn(move || {
                    let mut rank = RankStepper::with_own_history(comm, &setup, &kept).unwrap();
                    let contacts = script(&mut rank, &setup);
                    (rank.gather().unwrap(), contacts)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(read_by_ranks.iter().sum::<usize>(), total);
    assert!(
        read_by_ranks.iter().all(|&n| n < total),
        "{read_by_ranks:?}"
    );
    assert_eq!(results[0].1, contacts);
    assert_same(results[0].0.as_ref().expect("gathered"), &expected, 3);
    // A rank given another's history is refused before it opens.
    let (read, kept) = own_history((0, 3));
    let setup = DemSetup {
        particles: read.particles,
        ..resumed.clone()
    };
    let other = LocalComm::group(3).unwrap().remove(1);
    let e = RankStepper::with_own_history(other, &setup, &kept)
        .err()
        .unwrap();
    assert!(e.to_string().contains("is rank 1's"), "{e}");
}

#[test]
fn a_piece_one_rank_cannot_write_fails_the_frame_on_every_rank_naming_it() {
    let setup = landing();
    let out = tempfile::tempdir().unwrap();
    // Where rank 1's piece of the first frame goes lies a folder: its write fails.
    let blocked = mochi::io::piece_path(out.path(), setup.particles.step, 1);
    std::fs::create_dir_all(&blocked).unwrap();
    let said = on_cpu_ranks(3, &setup, |mut rank| {
        rank.write_pieces(out.path()).unwrap_err().to_string()
    });
    // Rank 1 says what failed; the others that it was process 1.
    assert!(
        said[1].contains(&blocked.display().to_string()),
        "{}",
        said[1]
    );
    for k in [0, 2] {
        assert!(
            said[k].contains("process 1 could not write its piece"),
            "{}",
            said[k]
        );
    }
}

#[test]
fn a_run_over_ranks_of_each_backend_matches_the_whole_run_on_it() {
    let landing = landing();
    let options = Options::default();
    common::on_every_backend(|kind| {
        // wgpu-compute keeps each rank's step from round to round, with rows to spare for the
        // spheres that come; with none to spare, and the spheres swept across the box, the
        // ranks open their steps again whenever more come than leave.
        // Faces moved every 8 steps as well: a kept step stays where they move less than the
        // halo.
        // On wgpu-compute four ranks too: a grid of 2 x 2 boxes, whose corners go to three.
        let mut cases = vec![(landing.clone(), (None, 0), 2)];
        if kind == BackendKind::WgpuCompute {
            cases.push((tilted(landing.clone()), (Some(0), 0), 2));
            cases.push((landing.clone(), (None, 8), 2));
            cases.push((landing.clone(), (None, 0), 4));
        }
        for (setup, spare, ranks) in cases {
            let out = tempfile::tempdir().unwrap();
            // Named once for every rank, as rank 0 names it in a run it leads.
            let checkpoint = out.path().join("checkpoint.bin");
            let folder = piece_folder_for(&checkpoint, STEPS as u64);
            let mut whole = open_setup(kind, setup.clone(), &options).unwrap();
            let contacts = whole.advance(STEPS).unwrap().contacts;
            let expected = whole.particles().unwrap();
            let snapshot = whole.snapshot().unwrap();
            assert_eq!(snapshot.contacts, expected.history.counts(expected.len()));
            assert!(snapshot.particles.history.is_empty());
            assert_eq!(snapshot.particles.positions, expected.positions);
            assert_eq!(snapshot.particles.radii, expected.radii);
            let ranks = on_ranks(ranks, kind, &setup, spare, |rank| {
                let (mut contacts, mut ghosts) = (0, 0);
                for call in 0..4 {
                    // Calls that need not their contacts report those counted last: none yet.
                    contacts = match call {
                        3 => rank.advance(STEPS / 4).unwrap().contacts,
                        _ => {
                            let uncounted = rank.advance_uncounted(STEPS / 4).unwrap();
                            assert_eq!(uncounted.contacts, 0);
                            uncounted.contacts
                        }
                    };
                    ghosts = ghosts.max(rank.ghost_spheres());
                    // Read between calls (a kept step stays), as frames are.
                    if call == 1 {
                        assert_eq!(rank.particles().unwrap().len(), setup.particles.len());
                    }
                }
                let every = rank.steps_between_exchanges();
                let grid = rank.grid().describe();
                // What frames show: the same spheres, each sphere's contacts those of the
                // history, gathered without it on rank 0 alone.
                let snapshot = rank.snapshot().unwrap();
                let now = rank.particles().unwrap();
                assert_eq!(snapshot.contacts, now.history.counts(now.len()));
                assert!(
                    snapshot.contacts.iter().any(|&c| c > 0),
                    "no contacts counted"
                );
                assert!(snapshot.particles.history.is_empty());
                assert_eq!(snapshot.particles.positions, now.positions);
                assert_eq!(
                    snapshot.particles.position_residuals,
                    now.position_residuals
                );
                assert_eq!(snapshot.particles.velocities, now.velocities);
                assert_eq!(
                    snapshot.particles.angular_velocities,
                    now.angular_velocities
                );
                let on_zero = rank.gather_snapshot().unwrap();
                assert_eq!(on_zero.is_some(), rank.comm().rank() == 0);
                // The frame in pieces, one a rank, none gathered: the gathered frame.
                let pieces = rank.write_pieces(out.path()).unwrap().expect("pieces");
                assert_eq!(pieces.iter().sum::<u64>() as usize, now.len());
                if let Some(whole) = on_zero {
                    assert_eq!(
                        read_pieces(out.path(), &pieces, &setup),
                        frame_of(&whole, &setup)
                    );
                }
                // The checkpoint in pieces, one a rank, none gathered: the gathered spheres
                // with their history, bit for bit.
                let pieces = rank.write_checkpoint_pieces(&folder).unwrap();
                let pieces = pieces.expect("pieces");
                assert_eq!(
                    pieces.iter().map(|p| p.spheres).sum::<u64>() as usize,
                    now.len()
                );
                if rank.comm().rank() == 0 {
                    let at = (folder.as_path(), now.step);
                    write_checkpoint_index(&checkpoint, at, ("", ""), &pieces).unwrap();
                    assert_eq!(read_checkpoint(&checkpoint).unwrap().particles, now);
                }
                (contacts, now, (every, grid), ghosts)
            });
            let (got_contacts, got, (every, grid), _) = &ranks[0];
            assert!(
                ranks
                    .iter()
                    .all(|r| r.0 == *got_contacts && r.1.positions == got.positions)
            );
            let ghosts: usize = ranks.iter().map(|r| r.3).sum();
            assert!(ghosts > 0, "no ghosts");
            // The same sphere a thousandth of the smallest radius from where the whole run has
            // it (the two runs sum their forces in other orders), the same contacts and energy.
            let (r_min, _) = expected.radius_range();
            let gap = common::largest_gap(got, &expected);
            let energy = kinetic(got) / kinetic(&expected) - 1.0;
            let more = *got_contacts as f64 / contacts as f64 - 1.0;
            eprintln!(
                "{} on {grid} (rows to spare, steps between rebalancings: {spare:?}): ghosts \
                 exchanged every {every} step(s), {ghosts} at most; largest gap {gap:.3e} m (r_min {r_min:.3e}), energy {energy:+.2e}, \
                 contacts {got_contacts} against {contacts}",
                kind.name()
            );
            if kind == BackendKind::Cpu {
                assert_same(got, &expected, 2);
            }
            assert!(gap < 1e-3 * r_min, "largest gap {gap} m");
            assert!(energy.abs() < 1e-3, "kinetic energy {energy:+.2e}");
            assert!(
                more.abs() < 0.01,
                "{got_contacts} contacts against {contacts}"
            );
        }
    });
}
