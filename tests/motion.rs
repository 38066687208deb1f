//! Setting the spheres' motion, gravity and external loads between steps ([`Stepper::set_motion`],
//! [`Stepper::set_external_loads`]) on every backend that runs here: the state read back is what
//! was set with the rest of it (radii, materials, contact history) kept, and the next steps start
//! from it as a cpu step opened on that state does; and the contacts of a state
//! (`CpuStepper::contact_data`) are the forces each backend's next step applies.

mod common;

use mochi::dem::contacts::box_wall_id;
use mochi::dem::scene::Overrides;
use mochi::dem::walls::spec::NewMotion;
use mochi::dem::{ExternalLoads, Material, Motion, Particles, StepParams, Stepper};
use mochi::engines::cpu::CpuStepper;
use mochi::engines::{BackendChoice, BackendKind, Options};
use mochi::run::RunStart;

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

/// Spheres apart in the middle of a 0.3 m box: nothing but gravity and their loads act.
fn apart() -> Particles {
    let positions: Vec<[f32; 3]> = (0..8)
        .map(|i| [0.05 + 0.03 * i as f32, 0.15, 0.15])
        .collect();
    common::particles(positions, vec![[0.0; 3]; 8], vec![0.01; 8])
}

#[test]
fn external_loads_act_every_step_until_changed() {
    let p = params(&common::granular_material());
    let (dt, g) = (p.dt, p.gravity);
    let m = p.materials.mass(0, 0.01);
    let inertia = 0.4 * m * 0.01 * 0.01;
    let forces: Vec<[f32; 3]> = (0..8).map(|i| [1e-3 * i as f32, -2e-3, 5e-4]).collect();
    let torques: Vec<[f32; 3]> = (0..8).map(|i| [0.0, 1e-7 * i as f32, -2e-7]).collect();
    let close =
        |a: [f32; 3], b: [f32; 3], scale: f32| (0..3).all(|k| (a[k] - b[k]).abs() <= 1e-5 * scale);
    for kind in common::dem_backends() {
        let name = kind.name();
        let mut s = open(kind, &apart(), &p);
        let loads = ExternalLoads {
            forces: forces.clone(),
            torques: torques.clone(),
        };
        s.set_external_loads(&loads).unwrap();
        s.advance(10).unwrap();
        let now = s.particles().unwrap();
        for i in 0..8 {
            let v: [f32; 3] = std::array::from_fn(|k| 10.0 * dt * (forces[i][k] / m + g[k]));
            let w: [f32; 3] = std::array::from_fn(|k| 10.0 * dt * torques[i][k] / inertia);
            assert!(
                close(now.velocities[i], v, 1.0),
                "{name}: sphere {i} moves at {:?}, not {v:?}",
                now.velocities[i]
            );
            assert!(
                close(now.angular_velocities[i], w, 1.0),
                "{name}: sphere {i} turns at {:?}, not {w:?}",
                now.angular_velocities[i]
            );
        }
        // Removed: gravity alone from the next step.
        s.set_external_loads(&ExternalLoads::default()).unwrap();
        s.advance(10).unwrap();
        let later = s.particles().unwrap();
        for i in 0..8 {
            let v: [f32; 3] = std::array::from_fn(|k| now.velocities[i][k] + 10.0 * dt * g[k]);
            assert!(
                close(later.velocities[i], v, 1.0),
                "{name}: sphere {i} moves at {:?}, not {v:?}",
                later.velocities[i]
            );
            assert_eq!(
                later.angular_velocities[i], now.angular_velocities[i],
                "{name}"
            );
        }
        // Refused, the loads kept: rows of another count, values that are not finite.
        let short = ExternalLoads {
            forces: vec![[1.0; 3]; 3],
            ..ExternalLoads::default()
        };
        let e = s.set_external_loads(&short).unwrap_err().to_string();
        assert!(
            e.contains("external forces of 3 spheres given to a step of 8"),
            "{name}: {e}"
        );
        let mut bad = forces.clone();
        bad[2][1] = f32::NAN;
        let e = s
            .set_external_loads(&ExternalLoads {
                forces: bad,
                ..ExternalLoads::default()
            })
            .unwrap_err()
            .to_string();
        assert!(e.contains("sphere 2"), "{name}: {e}");
    }
    // The paper's step turns nothing: a torque is refused there, a force acts.
    let paper = params(&Material::default());
    for kind in common::dem_backends() {
        let mut s = open(kind, &apart(), &paper);
        let e = s
            .set_external_loads(&ExternalLoads {
                torques: torques.clone(),
                ..ExternalLoads::default()
            })
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("does not turn its spheres"),
            "{}: {e}",
            kind.name()
        );
        s.set_external_loads(&ExternalLoads {
            forces: forces.clone(),
            ..ExternalLoads::default()
        })
        .unwrap();
        s.advance(3).unwrap();
        let v = s.particles().unwrap().velocities[7];
        let want: [f32; 3] = std::array::from_fn(|k| 3.0 * dt * (forces[7][k] / m + g[k]));
        assert!(close(v, want, 1.0), "{}: {v:?}, not {want:?}", kind.name());
    }
}

#[test]
fn contact_data_sums_to_the_forces_the_next_step_applies() {
    // The lattice pressed together and moving, in contact with the floor: spheres and walls,
    // normal and friction forces.
    let p = params(&common::granular_material());
    let mut start = lattice();
    for (i, c) in start.positions.iter_mut().enumerate() {
        c[2] -= 0.0901 + 1e-5 * i as f32;
    }
    for (i, v) in start.velocities.iter_mut().enumerate() {
        *v = [0.02 * (i % 3) as f32, -0.01, 0.0];
    }
    let setup = mochi::engines::DemSetup::new(start.clone(), p.clone(), mochi::ProxyMode::Mochi);
    let data = CpuStepper::open(setup).unwrap().contact_data().unwrap();
    let floor = box_wall_id(4);
    assert!(
        data.pairs.iter().filter(|pair| pair[1] >= 0).count() >= 50,
        "{:?}",
        data.pairs
    );
    assert_eq!(
        data.pairs.iter().filter(|pair| pair[1] == floor).count(),
        9,
        "the bottom layer on the floor"
    );
    // Each pair once, the first partner the lower index; normals push the partners apart.
    let mut sums = vec![[0.0f64; 3]; 27];
    for (k, &[i, j]) in data.pairs.iter().enumerate() {
        let (n, t) = (data.normal_force[k], data.tangential_force[k]);
        assert!(data.overlap[k] > 0.0, "contact {k}");
        let apart: [f32; 3] = match j {
            j if j >= 0 => {
                assert!(i < j, "{i}, {j}");
                std::array::from_fn(|a| {
                    start.positions[i as usize][a] - start.positions[j as usize][a]
                })
            }
            _ => [0.0, 0.0, 1.0],
        };
        let along: f32 = (0..3).map(|a| n[a] * apart[a]).sum();
        assert!(along > 0.0, "contact {k} ({i}, {j}) pulls: {n:?}");
        for a in 0..3 {
            let f = (n[a] + t[a]) as f64;
            sums[i as usize][a] += f;
            if j >= 0 {
                sums[j as usize][a] -= f;
            }
        }
    }
    let largest = data
        .forces
        .iter()
        .flatten()
        .fold(0.0f32, |m, f| m.max(f.abs()));
    assert!(
        data.tangential_force
            .iter()
            .flatten()
            .any(|&f| f.abs() > 1e-3 * largest),
        "friction acts"
    );
    for (i, (sum, force)) in sums.iter().zip(&data.forces).enumerate() {
        let gap = (0..3).fold(0.0f64, |g, a| g.max((sum[a] - force[a] as f64).abs()));
        assert!(
            gap <= 1e-5 * largest as f64,
            "sphere {i}: {sum:?} vs {force:?}"
        );
    }
    // The forces are what each backend's next step applies: m·Δv/dt − m·g.
    let m = p.materials.mass(0, 0.01);
    for kind in common::dem_backends() {
        let mut s = open(kind, &start, &p);
        s.advance(1).unwrap();
        let after = s.particles().unwrap();
        for i in 0..27 {
            for a in 0..3 {
                let applied =
                    m * (after.velocities[i][a] - start.velocities[i][a]) / p.dt - m * p.gravity[a];
                let gap = (applied - data.forces[i][a]).abs();
                assert!(
                    gap <= 1e-3 * largest,
                    "{}: sphere {i} gets {applied} along {a}, not {}",
                    kind.name(),
                    data.forces[i][a]
                );
            }
        }
    }
}

#[test]
fn a_run_changes_its_friction_and_moves_its_walls_between_steps_on_every_backend() {
    let dir = tempfile::tempdir().unwrap();
    let plate = dir.path().join("plate.obj");
    std::fs::write(
        &plate,
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    for kind in common::dem_backends() {
        let name = kind.name();
        // A sphere sliding on the floor, a plate 2 cm above it, at rest.
        let sliding =
            common::particles(vec![[0.1, 0.5, 0.0099]], vec![[0.5, 0.0, 0.0]], vec![0.01]);
        let wall = format!(
            "wall=[{{mesh = {:?}, translate = [0, 0, 0.04]}}]",
            plate.display().to_string()
        );
        let keys = Overrides::parse(&[
            "box_lo=[0, 0, 0]",
            "box_hi=[1, 1, 1]",
            "dt=1e-5",
            wall.as_str(),
        ])
        .unwrap();
        let start = RunStart::of_particles(sliding, &keys).unwrap();
        let mut run = start
            .open(BackendChoice::Named(kind), &Options::default())
            .unwrap();
        run.stepper.advance(200).unwrap();
        let slowed = run.stepper.particles().unwrap().velocities[0][0];
        assert!(
            slowed < 0.49,
            "{name}: friction slows the sphere to {slowed}"
        );
        run.change(&Overrides::parse(&["friction=0", "rolling_friction=0"]).unwrap())
            .unwrap();
        run.stepper.advance(200).unwrap();
        let v = run.stepper.particles().unwrap().velocities[0][0];
        assert!(
            (v - slowed).abs() < 1e-5 * slowed,
            "{name}: {v} after {slowed} without friction"
        );
        // A time step of half: the clock goes on from the time now (400 steps of 1e-5 s).
        run.change(&Overrides::parse(&["dt=5e-6"]).unwrap())
            .unwrap();
        assert_eq!(run.stepper.step(), 800, "{name}");
        let x = run.stepper.particles().unwrap().exact_position(0)[0];
        run.stepper.advance(200).unwrap();
        let moved = run.stepper.particles().unwrap().exact_position(0)[0] - x;
        let want = v as f64 * 200.0 * 5e-6;
        assert!(
            (moved - want).abs() < 1e-4 * want,
            "{name}: {moved} m, not {want}"
        );
        run.change(&Overrides::parse(&["dt=1e-5"]).unwrap())
            .unwrap();
        // The plate comes down 2.1 cm onto the sphere, then stays where it is.
        let down = NewMotion {
            velocity: Some([0.0, 0.0, -1.0]),
            ..NewMotion::default()
        };
        run.set_wall_motion(0, &down).unwrap();
        run.stepper.advance(2100).unwrap();
        run.set_wall_motion(
            0,
            &NewMotion {
                velocity: Some([0.0; 3]),
                ..NewMotion::default()
            },
        )
        .unwrap();
        run.stepper.advance(10).unwrap();
        let pressed = run.stepper.wall_loads()[0].force[2];
        assert!(
            pressed > 0.0,
            "{name}: the plate presses on the sphere ({pressed} N)"
        );
        let e = run
            .change(&Overrides::parse(&["box_hi=[2, 2, 2]"]).unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("domain.box_hi"), "{name}: {e}");
    }
}
