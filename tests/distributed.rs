//! A run decomposed over ranks (threads of this process, `LocalComm`) is the whole run bit for
//! bit on the cpu backend: a poured pile with friction, rolling resistance and its history,
//! spheres crossing the slabs' faces, on 2, 3 and 4 ranks.

use mochi::dem::Stepper;
use mochi::dem::scene::{Overrides, SceneConfig};
use mochi::distributed::{LocalComm, RankStepper, Slabs};
use mochi::engines::DemSetup;
use mochi::engines::cpu::CpuStepper;

/// A poured pile of polydisperse spheres in mid-fall and landing: contacts with history,
/// walls, and spheres moving across the box.
fn landing() -> DemSetup {
    let scene = "scene = \"pour\"\nspheres = 400\nseed = 5\n";
    let start = SceneConfig::parse(Some(scene), None, &Overrides::default())
        .and_then(|c| c.build())
        .unwrap();
    let setup = DemSetup {
        particles: start.particles,
        params: start.params,
        mode: start.mode,
        walls: start.walls,
    };
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
    let mut particles = whole.particles().unwrap();
    let p = &setup.params;
    let (lo, hi) = (p.box_lo.map(f64::from), p.box_hi.map(f64::from));
    let axis = Slabs::along_longest(lo, hi, 2).unwrap().axis;
    let speed = 0.2 * (hi[axis] - lo[axis]) / (STEPS as f64 * p.dt as f64);
    for v in &mut particles.velocities {
        v[axis] += speed as f32;
    }
    DemSetup { particles, ..setup }
}

/// The steps each run takes from the landing.
const STEPS: u32 = 400;

/// `setup` stepped `steps` steps on `ranks` ranks, gathered; with the spheres each rank owned
/// at the start and at the end.
fn decomposed(
    setup: &DemSetup,
    ranks: usize,
    steps: u32,
) -> (mochi::dem::Particles, Vec<[usize; 2]>) {
    let group = LocalComm::group(ranks).unwrap();
    let results: Vec<_> = std::thread::scope(|scope| {
        let handles: Vec<_> = group
            .into_iter()
            .map(|comm| {
                scope.spawn(move || {
                    let mut rank = RankStepper::new(comm, setup).unwrap();
                    let first = rank.own_spheres();
                    rank.advance(steps).unwrap();
                    (rank.gather().unwrap(), [first, rank.own_spheres()])
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let owned = results.iter().map(|(_, o)| *o).collect();
    let whole = results.into_iter().find_map(|(p, _)| p).unwrap();
    (whole, owned)
}

#[test]
fn a_run_on_several_ranks_is_the_whole_run_bit_for_bit() {
    let setup = landing();
    let steps = STEPS;
    let mut whole = CpuStepper::open(setup.clone()).unwrap();
    let advanced = whole.advance(steps).unwrap();
    assert!(
        advanced.contacts > 50,
        "{} contacts at the end",
        advanced.contacts
    );
    let expected = whole.particles().unwrap();
    for ranks in [2, 3, 4] {
        let (got, owned) = decomposed(&setup, ranks, steps);
        let n = expected.len();
        assert_eq!(got.len(), n);
        // Each sphere held once, and some crossed a face.
        let held = |k: usize| owned.iter().map(|o| o[k]).sum::<usize>();
        assert_eq!((held(0), held(1)), (n, n), "{owned:?}");
        assert!(
            owned.iter().any(|o| o[0] != o[1]),
            "none moved across: {owned:?}"
        );
        assert_eq!(got.step, expected.step);
        for i in 0..n {
            let bits = |p: &mochi::dem::Particles| {
                let x = p.exact_position(i).map(f64::to_bits);
                let v = p.velocities[i].map(f32::to_bits);
                let w = p.angular_velocities[i].map(f32::to_bits);
                (x, v, w)
            };
            assert_eq!(bits(&got), bits(&expected), "{ranks} ranks, sphere {i}");
            assert_eq!(
                got.history.of(i),
                expected.history.of(i),
                "{ranks} ranks, the contacts of sphere {i}"
            );
        }
    }
}
