//! Several materials on every backend that runs here (`common::dem_backends`): a scene of two
//! materials built from its TOML (each contact's law from the material table, the box walls of
//! one material, a mesh wall of the other and a rigid one with its own friction) steps on the GPU
//! as on the cpu, its state (materials included) moves between them both ways, and spheres of
//! another material flowing into a pile keep their material and their mass in the flows' counts.

mod common;

use mochi::dem::scene::{Overrides, SceneConfig, Start};
use mochi::dem::{Particles, Stepper};
use mochi::engines::{BackendChoice, BackendKind, Options, open_scene};

/// Two Hertz–Mindlin materials that differ in every value a material has, a pair override,
/// the box walls of the second, a mesh wall of the first (the plane x = 0.0395) and a rigid one
/// with its own friction (y = 0.0395), in a box of 5 cm; the time step the scene derives (0.2
/// of the fastest material's Rayleigh time).
const PILE: &str = r#"
contact = "hertz-mindlin"
box_lo = [0.0, 0.0, 0.0]
box_hi = [0.05, 0.05, 0.05]
gravity = [0.0, 0.0, -9.81]
box_material = "stiff"

[[material]]
name = "soft"
young_modulus = 1e7
poisson_ratio = 0.3
density = 2500
restitution = 0.5
friction = 0.5
rolling_friction = 0.1

[[material]]
name = "stiff"
young_modulus = 5e7
poisson_ratio = 0.2
density = 7800
restitution = 0.8
friction = 0.3
rolling_friction = 0.05

[[material_pair]]
materials = ["soft", "stiff"]
restitution = 0.6
friction = 0.4
rolling_friction = 0.02

[[wall]]
mesh = "x.obj"
material = "soft"

[[wall]]
mesh = "y.obj"
friction = 0.2
"#;

/// A square of two triangles in the plane `axis` = 0.0395, across the box.
fn plane(axis: usize) -> String {
    let corners = [[0.0, 0.0], [0.05, 0.0], [0.05, 0.05], [0.0, 0.05]];
    let mut obj = String::new();
    for [u, v] in corners {
        let mut p = [u, v, v];
        p[axis] = 0.0395;
        p[(axis + 1) % 3] = u;
        p[(axis + 2) % 3] = v;
        obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    obj + "f 1 2 3\nf 1 3 4\n"
}

/// The scene `text` (its meshes written beside it) started from `particles`.
fn start(text: &str, particles: Particles) -> Start {
    let dir = tempfile::tempdir().unwrap();
    for (name, axis) in [("x.obj", 0), ("y.obj", 1)] {
        std::fs::write(dir.path().join(name), plane(axis)).unwrap();
    }
    let file = dir.path().join("scene.toml");
    let config = SceneConfig::parse(Some(text), Some(&file), &Overrides::default()).unwrap();
    config.start_from(particles).unwrap()
}

/// 4 × 4 × 4 spheres of radii 4.5–5.5 mm 9.9 mm apart (so touching their neighbours, the box's
/// low walls and the mesh walls), moving and turning a little; about a third of them of the
/// second material.
fn pile() -> Particles {
    let mut rand = common::noise(11);
    let mut p = Particles::default();
    for k in 0..64u32 {
        let at = [k % 4, (k / 4) % 4, k / 16].map(|i| 0.0049 + i as f32 * 0.0099);
        let r = 0.005 + 0.001 * rand();
        let v = [0; 3].map(|_| 0.02 * rand());
        p.push_of(at, v, r, (k * 7 % 3 == 0) as u8).unwrap();
        p.angular_velocities[k as usize] = [0; 3].map(|_| 2.0 * rand());
    }
    p
}

/// The step of backend `kind` over `start`.
fn open(kind: BackendKind, start: Start) -> Box<dyn Stepper> {
    open_scene(BackendChoice::Named(kind), start, &Options::default())
        .unwrap_or_else(|e| panic!("{} opens: {e}", kind.name()))
        .value
}

/// The largest difference of any component between `a` and `b`.
fn worst(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |k| (x[k] - y[k]).abs()))
        .fold(0.0, f32::max)
}

/// Each sphere's material.
fn materials(p: &Particles) -> Vec<u32> {
    (0..p.len()).map(|i| p.material(i)).collect()
}

/// Asserts that `got` follows the cpu step's `expected` within the tolerances of
/// `tests/physics.rs` (`assert_follows`, which says why): the same materials and contacts,
/// positions within 1e-7 m, velocities, spins and springs within 1e-4 of their largest.
fn assert_follows(what: &str, got: &Particles, expected: &Particles) {
    let largest = |x: &[[f32; 3]]| worst(x, &vec![[0.0; 3]; x.len()]);
    assert_eq!(got.step, expected.step, "{what}");
    assert_eq!(materials(got), materials(expected), "{what}: materials");
    let x_gap = worst(&got.positions, &expected.positions);
    assert!(x_gap <= 1e-7, "{what}: positions {x_gap} m from the cpu's");
    for (name, a, b) in [
        ("velocities", &got.velocities, &expected.velocities),
        (
            "spins",
            &got.angular_velocities,
            &expected.angular_velocities,
        ),
    ] {
        let gap = worst(a, b);
        assert!(
            gap <= 1e-4 * largest(b),
            "{what}: {name} {gap} from the cpu's"
        );
    }
    let (tangential, rolling): (Vec<[f32; 3]>, Vec<[f32; 3]>) = expected
        .history
        .contacts()
        .map(|(_, e)| (e.tangential, e.rolling))
        .unzip();
    let (xi_max, roll_max) = (largest(&tangential), largest(&rolling));
    for i in 0..expected.len() {
        let held = |p: &Particles| {
            let mut held = p.history.of(i).to_vec();
            held.sort_by_key(|e| e.partner);
            held
        };
        let (a, b) = (held(got), held(expected));
        let partners =
            |h: &[mochi::dem::HistoryEntry]| h.iter().map(|e| e.partner).collect::<Vec<_>>();
        assert_eq!(
            partners(&a),
            partners(&b),
            "{what}: the contacts of sphere {i}"
        );
        for (x, y) in a.iter().zip(&b) {
            let gap = worst(&[x.tangential], &[y.tangential]);
            assert!(
                gap <= 1e-4 * xi_max,
                "{what}: sphere {i}'s spring with {}",
                x.partner
            );
            let gap = worst(&[x.rolling], &[y.rolling]);
            assert!(
                gap <= 1e-4 * roll_max,
                "{what}: sphere {i}'s rolling with {}",
                x.partner
            );
        }
    }
}

#[test]
fn a_pile_of_two_materials_steps_on_every_backend_as_on_the_cpu_and_moves_between_them() {
    let start = start(PILE, pile());
    let p = &start.params;
    assert_eq!(p.materials.count, 2);
    assert_eq!(p.box_column, 1, "the box walls are of the second material");
    let with = |particles: Particles| Start {
        particles,
        ..start.clone()
    };
    let mut cpu = open(BackendKind::Cpu, start.clone());
    cpu.advance(10).unwrap();
    let halfway = cpu.particles().unwrap();
    cpu.advance(10).unwrap();
    let expected = cpu.particles().unwrap();
    // Both materials in contacts with each other, the box walls and both mesh walls.
    let partners: Vec<u32> = expected
        .history
        .contacts()
        .map(|(_, e)| e.partner)
        .collect();
    assert!(partners.len() > 150, "the pile holds contacts");
    for wall in [mochi::dem::FIRST_MESH_WALL, mochi::dem::FIRST_MESH_WALL + 1] {
        assert!(partners.contains(&wall), "spheres touch mesh wall {wall}");
    }
    for kind in common::dem_backends() {
        if kind == BackendKind::Cpu {
            continue;
        }
        let name = kind.name();
        let mut gpu = open(kind, start.clone());
        gpu.advance(20).unwrap();
        assert_follows(name, &gpu.particles().unwrap(), &expected);
        // cpu, then the GPU; the GPU, then cpu.
        let mut gpu = open(kind, with(halfway.clone()));
        gpu.advance(10).unwrap();
        let what = format!("cpu, then {name}");
        assert_follows(&what, &gpu.particles().unwrap(), &expected);
        let mut gpu = open(kind, start.clone());
        gpu.advance(10).unwrap();
        let mut cpu = open(BackendKind::Cpu, with(gpu.particles().unwrap()));
        cpu.advance(10).unwrap();
        let what = format!("{name}, then cpu");
        assert_follows(&what, &cpu.particles().unwrap(), &expected);
    }
}

/// A linear, frictionless scene of two materials (the granular step runs it on the GPUs: the
/// paper's kernels read one law): a row of spheres of the first on the floor, a third of them
/// in an outflow, and an inflow of the second (2000 spheres/s falling at 0.5 m/s) through an
/// outflow band 1 cm under it; flow events every 50 steps.
const FLOWS: &str = r#"
contact = "linear"
dt = 1e-4
box_lo = [0.0, 0.0, 0.0]
box_hi = [0.2, 0.2, 0.2]
gravity = [0.0, 0.0, -9.81]
flow_every = 50

[[material]]
name = "light"
density = 2500
restitution = 0.5

[[material]]
name = "heavy"
density = 7800
restitution = 0.8

[[inflow]]
material = "heavy"
lo = [0.02, 0.02, 0.15]
hi = [0.18, 0.18, 0.19]
rate = 2000
sphere_radii = [0.004, 0.005]
velocity = [0.0, 0.0, -0.5]
seed = 7

[[outflow]]
lo = [0.0, 0.0, 0.0]
hi = [0.05, 0.2, 0.02]

[[outflow]]
lo = [0.0, 0.0, 0.12]
hi = [0.2, 0.2, 0.13]
"#;

#[test]
fn spheres_of_another_material_flow_into_a_pile_with_their_material_and_mass() {
    let mut row = Particles::default();
    for k in 0..12 {
        let x = 0.01 + 0.012 * k as f32;
        row.push([x, 0.1, 0.005], [0.0; 3], 0.005).unwrap();
    }
    let start = start(FLOWS, row);
    let run = |kind| {
        let mut s = open(kind, start.clone());
        s.advance(700).unwrap();
        (s.flow_counts().unwrap(), s.particles().unwrap())
    };
    let (counts, cpu) = run(BackendKind::Cpu);
    let of = |m: u32| materials(&cpu).iter().filter(|&&x| x == m).count();
    assert!(counts.inserted > 100 && counts.removed > 14, "{counts:?}");
    assert!(
        of(0) > 0 && of(0) < 12 && of(1) > 10,
        "both materials stay and leave"
    );
    for kind in common::dem_backends() {
        if kind == BackendKind::Cpu {
            continue;
        }
        let _named = common::Naming(kind);
        let (c, now) = run(kind);
        let tally = |c: &mochi::dem::flow::FlowCounts| (c.inserted, c.refused, c.removed);
        assert_eq!(tally(&c), tally(&counts));
        // Sums of a few hundred f32 masses of one size in f64: exact in any order.
        assert_eq!(c.inserted_mass, counts.inserted_mass);
        assert_eq!(c.removed_mass, counts.removed_mass);
        if kind == BackendKind::WgpuCompute {
            // Its flow events remove and insert on the device, materials and all.
            assert_eq!(c.read_backs, 0, "{c:?}");
        }
        assert_eq!(now.radii, cpu.radii, "the same spheres, in the same order");
        assert_eq!(materials(&now), materials(&cpu));
        for (a, b) in now.positions.iter().zip(&cpu.positions) {
            let off = glam::Vec3::from(*a).distance(glam::Vec3::from(*b));
            assert!(off < 1e-5, "{a:?} vs {b:?}");
        }
    }
}
