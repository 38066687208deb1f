//! Setting the spheres' motion between steps ([`Stepper::set_motion`]) on every backend that runs
//! here: the state read back is what was set with the rest of it (radii, materials, contact
//! history) kept, and the next steps start from it as a cpu step opened on that state does.

mod common;

use mochi::dem::{Material, Motion, Particles, StepParams, Stepper};
use mochi::engines::{BackendKind, Options};

/// A 3×3×3 lattice of 1 cm spheres 19.9 mm apart (every neighbour pressed a little), in a box
/// of 0.3 m under gravity, at rest.
fn lattice() -> Particles {
    let mut positions = Vec::new();
    for k in 0..27 {
        let at = [k % 3, (k / 3) % 3, k / 9];
        positions.push(at.map(|i| 0.1 + 0.0199 * i as f32));
    }
    common::particles(positions, vec![[0.0; 3]; 27], vec![0.01; 27])
}

/// `material`'s step over [`lattice`].
fn params(material: &Material) -> StepParams {
    common::step_params(material, 1e-5, 0.3, [0.0, 0.0, -9.81], 0.01)
}

/// The stepper of `kind` over `start`.
fn open(kind: BackendKind, start: &Particles, p: &StepParams) -> Box<dyn Stepper> {
    match kind {
        BackendKind::Cpu => common::open_dem(kind, start, p.clone(), &Options::default()),
        _ => common::open_dem_shared(kind, start, p.clone()),
    }
}

#[test]
fn motion_set_between_steps_is_what_the_next_step_starts_from() {
    // The granular step (friction, rotation, history) and the paper's (frictionless, no spin:
    // on a GPU its skin must re-bin moved spheres).
    for (law, material) in [
        ("granular", common::granular_material()),
        ("paper", Material::default()),
    ] {
        motion_set_between_steps_of(law, &material);
    }
}

/// [`motion_set_between_steps_is_what_the_next_step_starts_from`] with `material` (`law`).
fn motion_set_between_steps_of(law: &str, material: &Material) {
    let p = params(material);
    let turns = law == "granular";
    for kind in common::dem_backends() {
        let name = format!("{} ({law})", kind.name());
        let mut s = open(kind, &lattice(), &p);
        s.advance(20).unwrap();
        let before = s.particles().unwrap();
        assert!(
            before.history.is_empty() != turns,
            "{name}: the lattice's contacts keep springs where friction acts"
        );
        let n = before.len();
        let positions: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let x = before.exact_position(i);
                [x[0] + 0.05, x[1], x[2] + 1e-9 * i as f64]
            })
            .collect();
        let velocities: Vec<[f32; 3]> = (0..n).map(|i| [0.01 * i as f32, 0.0, -0.02]).collect();
        let spins: Vec<[f32; 3]> = (0..n).map(|i| [0.0, 0.5, 0.1 * i as f32]).collect();
        let motion = Motion {
            positions: Some(&positions),
            velocities: Some(&velocities),
            angular_velocities: turns.then_some(&spins[..]),
        };
        s.set_motion(&motion).unwrap();
        let after = s.particles().unwrap();
        let mut expected = before.clone();
        motion.apply(&mut expected).unwrap();
        assert!(
            after == expected,
            "{name}: the state read back is not the one set"
        );
        assert!(after.velocities == velocities && after.history == before.history);
        // The next steps start from it: a cpu step opened on it takes the same steps.
        let mut reference = open(BackendKind::Cpu, &after, &p);
        let (a, b) = (s.advance(5).unwrap(), reference.advance(5).unwrap());
        let (got, want) = (s.particles().unwrap(), reference.particles().unwrap());
        assert_eq!(a.contacts, b.contacts, "{name}");
        let worst = common::largest_gap(&got, &want);
        match kind {
            BackendKind::Cpu => assert!(got == want, "cpu: not the step of the state set"),
            // GPUs add forces by atomics in any order: nanometres, not bits.
            _ => assert!(worst < 1e-7, "{name}: {worst} m from the cpu step"),
        }
        // Only some of it: the rest stays.
        let still = got.clone();
        let v: Vec<[f32; 3]> = vec![[0.0; 3]; n];
        s.set_motion(&Motion {
            velocities: Some(&v),
            ..Motion::default()
        })
        .unwrap();
        let now = s.particles().unwrap();
        assert_eq!(now.velocities, v, "{name}");
        assert!(
            now.positions == still.positions && now.angular_velocities == still.angular_velocities
        );
    }
}

#[test]
fn bad_motion_is_refused_and_changes_nothing() {
    let p = params(&common::granular_material());
    for kind in common::dem_backends() {
        let name = kind.name();
        let mut s = open(kind, &lattice(), &p);
        let before = s.particles().unwrap();
        let short = vec![[0.0f32; 3]; 5];
        let e = s
            .set_motion(&Motion {
                velocities: Some(&short),
                ..Motion::default()
            })
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("velocities of 5 spheres given to a step of 27"),
            "{name}: {e}"
        );
        let mut far: Vec<[f64; 3]> = (0..27).map(|i| before.exact_position(i)).collect();
        far[4] = [f64::NAN, 0.1, 0.1];
        let e = s
            .set_motion(&Motion {
                positions: Some(&far),
                ..Motion::default()
            })
            .unwrap_err()
            .to_string();
        assert!(e.contains("sphere 4"), "{name}: {e}");
        far[4] = [1e40, 0.1, 0.1];
        assert!(
            s.set_motion(&Motion {
                positions: Some(&far),
                ..Motion::default()
            })
            .is_err()
        );
        assert!(
            s.particles().unwrap() == before,
            "{name}: a refused motion changed the state"
        );
    }
    // The paper's frictionless step keeps no spin on a GPU: an angular velocity is refused there.
    let paper = params(&Material::default());
    let spins = vec![[0.0f32, 0.0, 1.0]; 27];
    for kind in common::dem_backends() {
        let mut s = open(kind, &lattice(), &paper);
        let set = s.set_motion(&Motion {
            angular_velocities: Some(&spins),
            ..Motion::default()
        });
        match kind {
            BackendKind::Cpu => set.unwrap(),
            _ => {
                let e = set.unwrap_err().to_string();
                assert!(
                    e.contains("does not turn its spheres"),
                    "{}: {e}",
                    kind.name()
                );
            }
        }
    }
}

#[test]
fn gravity_set_between_steps_acts_from_the_next_step() {
    // Spheres apart in the middle of the box: nothing but gravity acts on them.
    let positions: Vec<[f32; 3]> = (0..8)
        .map(|i| [0.05 + 0.03 * i as f32, 0.15, 0.15])
        .collect();
    let start = common::particles(positions, vec![[0.0; 3]; 8], vec![0.01; 8]);
    let p = params(&common::granular_material());
    let dt = p.dt;
    for kind in common::dem_backends() {
        let name = kind.name();
        let mut s = open(kind, &start, &p);
        s.advance(10).unwrap();
        let before = s.particles().unwrap().velocities;
        s.set_gravity([1.0, 0.0, 2.0]).unwrap();
        s.advance(10).unwrap();
        let after = s.particles().unwrap().velocities;
        for (i, (a, b)) in after.iter().zip(&before).enumerate() {
            let expected = [b[0] + 10.0 * dt * 1.0, b[1], b[2] + 10.0 * dt * 2.0];
            for k in 0..3 {
                assert!(
                    (a[k] - expected[k]).abs() < 1e-6,
                    "{name}: sphere {i} moves at {a:?}, not {expected:?}"
                );
            }
        }
    }
    // A gravity no step could hold is refused before it reaches a step.
    let e = p
        .with_gravity([0.0, 0.0, -1e9], 0.01)
        .unwrap_err()
        .to_string();
    assert!(e.contains("single step"), "{e}");
    assert!(p.with_gravity([0.0, f64::NAN, 0.0], 0.01).is_err());
}
