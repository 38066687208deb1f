//! Each cause of failure is its own [`Error`] variant: a bad setting is `InvalidConfig` naming
//! it, a simulation that blows up is `Unstable` with the step and the sphere (in input order) on
//! every backend that runs here. (`auto` finding no backend, `NoBackend`, is tested beside the
//! `auto` rule in `engines::registry`, where every backend can be made to fail.)

mod common;

use mochi::dem::scene::Overrides;
use mochi::dem::{Material, Particles, StepParams};
use mochi::render::parse_size;
use mochi::{Error, SphereSet};

#[test]
fn bad_settings_are_invalid_config_naming_the_setting() {
    let bad_restitution = Material {
        restitution: 2.0,
        ..Material::default()
    };
    match StepParams::new(
        &bad_restitution,
        1e-4,
        [0.0; 3],
        [1.0; 3],
        [0.0; 3],
        0.0,
        0.01,
    ) {
        Err(Error::InvalidConfig { what, reason }) => {
            assert_eq!(what, "scene key restitution");
            assert!(reason.contains("(0, 1]"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
    match Overrides::parse(&["dt"]) {
        Err(Error::InvalidConfig { what, reason }) => {
            assert_eq!(what, "--set \"dt\"");
            assert_eq!(reason, "expected key=value");
        }
        other => panic!("{other:?}"),
    }
    match parse_size("960") {
        Err(e @ Error::InvalidConfig { .. }) => {
            assert_eq!(e.to_string(), "size \"960\": expected WxH such as 960x720");
        }
        other => panic!("{other:?}"),
    }
}

/// Sphere `BLOWN` of four starts so far below the floor that the wall's force overflows `f32`:
/// its velocity and position stop being finite in the first step.
const BLOWN: usize = 2;

fn exploding() -> (Particles, StepParams) {
    let centers = vec![
        [0.5, 0.5, 0.5],
        [0.2, 0.5, 0.5],
        [0.5, 0.5, 0.2],
        [0.8, 0.5, 0.5],
    ];
    let spheres = SphereSet::new(centers, vec![0.01; 4]).unwrap();
    let mut particles = Particles::at_rest(&spheres).unwrap();
    // Finite, so the state is valid input; beyond any sphere set's bounds, so no file gives it.
    particles.positions[BLOWN][2] = -1e34;
    particles.step = 7;
    let params = common::step_params(&Material::default(), 1e-4, 1.0, [0.0, 0.0, -9.81], 0.01);
    (particles, params)
}

#[test]
fn an_exploding_simulation_is_unstable_with_its_step_and_sphere() {
    let (particles, params) = exploding();
    let steppers = common::default_steppers(&particles, params);
    for (name, mut stepper) in steppers {
        // A stepper checks its state where it reads it: after the steps (cpu), at a re-layout
        // (wgpu-compute) or when the particles are read back (every backend).
        let result = stepper.advance(3).and_then(|_| stepper.particles());
        match result {
            Err(Error::Unstable { step, sphere, what }) => {
                assert_eq!(sphere, BLOWN, "{name}: {what}");
                assert!((8..=10).contains(&step), "{name}: step {step}");
                assert!(what.contains("position"), "{name}: {what}");
            }
            other => panic!("{name}: {:?}", other.map(|p| p.positions)),
        }
    }
}
