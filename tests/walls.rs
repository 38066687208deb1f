//! Mesh walls against analytic results (physics.md, "Analytic results", 5), on every backend
//! that runs here (`common::dem_backends`): a sphere on a mesh incline rolls, slides or is held
//! as the law of its friction says; a sphere rolling across a flat mesh of many triangles feels
//! one plane (the trajectory of the box's floor); an STL box gives the box walls' trajectories;
//! a rotating cylinder drags a resting sphere. On the cpu step, a run with a moving wall resumes
//! from a checkpoint bit for bit. Every backend runs mesh walls with the box walls on and off.
//! Tolerances are stated with each test.

mod common;

use glam::Vec3;
use mochi::dem::flow::FlowSet;
use mochi::dem::model::{ContactLaw, Material, RollingModel, TangentialModel};
use mochi::dem::scene::Start;
use mochi::dem::walls::{Rotation, WallConfig, WallSet};
use mochi::dem::{FIRST_MESH_WALL, Particles, StepParams, Stepper};
use mochi::engines::{BackendChoice, BackendKind, Options, open_scene};
use mochi::mesh::Mesh;
use mochi::proxy::ProxyMode;
use std::f32::consts::PI;

const G: f32 = 9.81;
const R: f32 = 0.01;
const DT: f64 = 1e-4;

/// Soft glass-like spheres (Hertz–Mindlin, E = 1e7 Pa): a Rayleigh time of 8.6e-4 s, so
/// `DT` is 0.12 of it.
fn material(friction: f64, rolling: f64, model: RollingModel) -> Material {
    Material {
        density: 2500.0,
        restitution: 0.5,
        contact: ContactLaw::HertzMindlin {
            young_modulus: 1e7,
            poisson_ratio: 0.3,
        },
        friction,
        rolling_friction: rolling,
        rolling_model: model,
        ..Material::default()
    }
}

fn params(m: &Material, lo: f64, hi: f64) -> StepParams {
    StepParams::new(m, DT, [lo; 3], [hi; 3], [0.0, 0.0, -G as f64], 0.0, R).unwrap()
}

fn one_sphere(c: Vec3, v: Vec3, w: Vec3) -> Particles {
    Particles {
        positions: vec![c.to_array()],
        velocities: vec![v.to_array()],
        angular_velocities: vec![w.to_array()],
        radii: vec![R],
        ..Particles::default()
    }
}

/// A flat square grid of `cells`² quads (two triangles each) of side `2·half` in the plane
/// z = 0, centred on the origin.
fn grid_mesh(half: f64, cells: u32) -> Mesh {
    let mut mesh = Mesh::default();
    let step = 2.0 * half / cells as f64;
    for j in 0..=cells {
        for i in 0..=cells {
            mesh.vertices
                .push([-half + i as f64 * step, -half + j as f64 * step, 0.0]);
        }
    }
    let at = |i: u32, j: u32| j * (cells + 1) + i;
    for j in 0..cells {
        for i in 0..cells {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            mesh.triangles.push([a, b, c]);
            mesh.triangles.push([a, c, d]);
        }
    }
    mesh
}

fn start(particles: Particles, params: StepParams, walls: WallSet) -> Start {
    Start {
        particles,
        params,
        mode: ProxyMode::Mochi,
        walls,
        flow: FlowSet::default(),
    }
}

fn stepper(
    kind: BackendKind,
    particles: Particles,
    p: StepParams,
    walls: WallSet,
) -> Box<dyn Stepper> {
    let choice = BackendChoice::Named(kind);
    let opened = open_scene(choice, start(particles, p, walls), &Options::default());
    opened
        .unwrap_or_else(|e| panic!("{} opens: {e}", kind.name()))
        .value
}

fn walls_of(configs: &[(WallConfig, &Mesh)], box_walls: bool, friction: f64) -> WallSet {
    let meshes = configs
        .iter()
        .enumerate()
        .map(|(k, (c, m))| {
            let mut wall = c.build_from(k, m, None).unwrap();
            wall.friction = Some(c.friction.unwrap_or(friction) as f32);
            wall
        })
        .collect();
    WallSet::new(box_walls, meshes).unwrap()
}

fn state(s: &mut dyn Stepper) -> (Vec3, Vec3, Vec3) {
    let p = s.particles().unwrap();
    (
        Vec3::from(p.positions[0]),
        Vec3::from(p.velocities[0]),
        Vec3::from(p.angular_velocities[0]),
    )
}

/// Acceleration of a sphere set at rest on a mesh incline of `degrees` (64 × 64 quads, turned
/// about y: downhill is +x), measured along the slope between 0.05 s (the landing's bounce
/// has died out) and 0.25 s; and the distance it travelled in 0.25 s.
fn on_incline(kind: BackendKind, degrees: f32, m: &Material) -> (f32, f32) {
    let theta = degrees.to_radians();
    let downhill = Vec3::new(theta.cos(), 0.0, -theta.sin());
    let normal = Vec3::new(theta.sin(), 0.0, theta.cos());
    let mesh = grid_mesh(0.3, 64);
    let config = WallConfig {
        rotate: Some(Rotation {
            axis: [0.0, 1.0, 0.0],
            degrees: degrees as f64,
        }),
        ..WallConfig::of("incline")
    };
    let friction = m.friction;
    let walls = walls_of(&[(config, &mesh)], true, friction);
    let start = -0.1 * downhill + R * normal;
    let mut s = stepper(
        kind,
        one_sphere(start, Vec3::ZERO, Vec3::ZERO),
        params(m, -0.5, 0.5),
        walls,
    );
    s.advance(500).unwrap();
    let (_, v1, _) = state(s.as_mut());
    s.advance(2000).unwrap();
    let (c2, v2, _) = state(s.as_mut());
    let a = (v2 - v1).dot(downhill) / 0.2;
    (a, (c2 - start).dot(downhill))
}

// The semi-implicit step follows a constant acceleration exactly, and the landing's normal and
// tangential oscillations (periods of a few 1e-4 s, damped at e = 0.5) have died out long
// before 0.05 s: what is left is f32 rounding of the velocity over 2000 steps (measured: a
// few 1e-6 of the acceleration).
const INCLINE_TOLERANCE: f32 = 1e-4;

#[test]
fn a_sphere_on_a_mesh_incline_rolls_at_five_sevenths_g_sin_theta() {
    common::on_every_backend(a_sphere_on_a_mesh_incline_rolls_at_five_sevenths_g_sin_theta_on);
}

fn a_sphere_on_a_mesh_incline_rolls_at_five_sevenths_g_sin_theta_on(kind: BackendKind) {
    // μ = 0.5 ≥ 2/7·tan 20° = 0.104: rolling without slip.
    let theta = 20f32.to_radians();
    let (a, _) = on_incline(kind, 20.0, &material(0.5, 0.0, RollingModel::Epsd));
    let expected = 5.0 / 7.0 * G * theta.sin();
    assert!(
        (a / expected - 1.0).abs() < INCLINE_TOLERANCE,
        "a = {a}, 5/7 g sin θ = {expected}"
    );
}

#[test]
fn a_run_reopened_from_its_spheres_keeps_its_mesh_wall_springs() {
    common::on_every_backend(a_run_reopened_from_its_spheres_keeps_its_mesh_wall_springs_on);
}

fn a_run_reopened_from_its_spheres_keeps_its_mesh_wall_springs_on(kind: BackendKind) {
    // A sphere rolling down a mesh incline (tangential and EPSD rolling springs on the mesh
    // wall), read back halfway and stepped on by a step opened from what was read (as a
    // resumed run and a flow event's reopening are): one sphere, no sums in another order, so
    // the two runs agree bit for bit on every backend; springs lost on the way would not, nor
    // would the load histories of the Mindlin–Deresiewicz model.
    for model in [
        TangentialModel::Mindlin,
        TangentialModel::MindlinDeresiewicz,
    ] {
        let m = Material {
            tangential_model: model,
            ..material(0.5, 0.1, RollingModel::Epsd)
        };
        reopened_on_an_incline(kind, &m);
    }
}

/// [`a_run_reopened_from_its_spheres_keeps_its_mesh_wall_springs`] under material `m`.
fn reopened_on_an_incline(kind: BackendKind, m: &Material) {
    let m = *m;
    let theta = 20f32.to_radians();
    let downhill = Vec3::new(theta.cos(), 0.0, -theta.sin());
    let normal = Vec3::new(theta.sin(), 0.0, theta.cos());
    let config = WallConfig {
        rotate: Some(Rotation {
            axis: [0.0, 1.0, 0.0],
            degrees: 20.0,
        }),
        ..WallConfig::of("incline")
    };
    let mesh = grid_mesh(0.3, 16);
    let walls = || walls_of(&[(config.clone(), &mesh)], true, m.friction);
    let sphere = one_sphere(-0.1 * downhill + 0.99 * R * normal, Vec3::ZERO, Vec3::ZERO);
    let p = params(&m, -0.5, 0.5);
    let mut straight = stepper(kind, sphere.clone(), p.clone(), walls());
    straight.advance(600).unwrap();
    let mut first = stepper(kind, sphere, p.clone(), walls());
    first.advance(300).unwrap();
    let halfway = first.particles().unwrap();
    assert!(
        halfway
            .history
            .contacts()
            .any(|(_, e)| e.partner == FIRST_MESH_WALL && e.rolling != [0.0; 3]),
        "the sphere holds springs of the mesh wall: {:?}",
        halfway.history
    );
    if m.tangential_model == TangentialModel::MindlinDeresiewicz {
        assert!(halfway.history.loads_of(0).iter().any(|l| l.normal > 0.0));
    }
    let mut reopened = stepper(kind, halfway, p, walls());
    reopened.advance(300).unwrap();
    assert_eq!(straight.particles().unwrap(), reopened.particles().unwrap());
}

#[test]
fn a_sphere_on_a_slippery_mesh_incline_slides_at_g_sin_minus_mu_cos() {
    common::on_every_backend(a_sphere_on_a_slippery_mesh_incline_slides_at_g_sin_minus_mu_cos_on);
}

fn a_sphere_on_a_slippery_mesh_incline_slides_at_g_sin_minus_mu_cos_on(kind: BackendKind) {
    // μ = 0.05 < 2/7·tan 20° = 0.104: sliding.
    let (theta, mu) = (20f32.to_radians(), 0.05);
    let (a, _) = on_incline(kind, 20.0, &material(mu as f64, 0.0, RollingModel::Epsd));
    let expected = G * (theta.sin() - mu * theta.cos());
    assert!(
        (a / expected - 1.0).abs() < INCLINE_TOLERANCE,
        "a = {a}, g (sin θ − μ cos θ) = {expected}"
    );
}

#[test]
fn constant_torque_rolling_resistance_holds_a_sphere_on_a_mesh_incline() {
    common::on_every_backend(
        constant_torque_rolling_resistance_holds_a_sphere_on_a_mesh_incline_on,
    );
}

fn constant_torque_rolling_resistance_holds_a_sphere_on_a_mesh_incline_on(kind: BackendKind) {
    // μ_r = 0.3 ≥ tan 10° = 0.176 holds it; μ_r = 0.1 does not. Held, the sphere creeps by the
    // one step of spin that friction gives before the rolling torque answers (ω = dt·F r/I,
    // v = 2.5·dt·g sin θ = 4e-4 m/s): 1.1e-4 m in 0.25 s, against 0.04 m rolling freely.
    let theta = 10f32.to_radians();
    let creep = 2.5 * DT as f32 * G * theta.sin() * 0.25;
    let (_, held) = on_incline(
        kind,
        10.0,
        &material(0.5, 0.3, RollingModel::ConstantTorque),
    );
    assert!(held.abs() < 2.0 * creep, "held sphere moved {held} m");
    // Not held, it rolls at 5/7·g·(sin θ − μ_r cos θ): 0.0164 m in 0.25 s, less the landing's
    // first steps.
    let (_, rolled) = on_incline(
        kind,
        10.0,
        &material(0.5, 0.1, RollingModel::ConstantTorque),
    );
    let expected = 0.5 * 5.0 / 7.0 * G * (theta.sin() - 0.1 * theta.cos()) * 0.25 * 0.25;
    assert!(
        (rolled / expected - 1.0).abs() < 0.02,
        "free sphere moved {rolled} m, expected {expected} m"
    );
}

/// A sphere rolling without slip across a plane at z = 0, diagonally (over faces, edges and
/// vertices of the mesh): the trajectory over `steps` and the load on the wall at the end.
fn rolling_across(
    kind: BackendKind,
    walls: WallSet,
    box_lo: f64,
    steps: u32,
) -> (Vec<[f32; 3]>, Vec<[f64; 3]>) {
    let m = material(0.5, 0.0, RollingModel::Epsd);
    let dir = Vec3::new(1.0, 0.37, 0.0).normalize();
    let v = 0.5 * dir;
    let w = Vec3::Z.cross(v) / R;
    let p = StepParams {
        box_lo: [-0.3, -0.3, box_lo as f32],
        ..params(&m, -0.3, 0.3)
    };
    let c = Vec3::new(-0.12, -0.05, R);
    let mut s = stepper(kind, one_sphere(c, v, w), p, walls);
    let mut path = Vec::new();
    for _ in 0..steps / 10 {
        s.advance(10).unwrap();
        path.push(s.particles().unwrap().positions[0]);
    }
    let loads = s.wall_loads().iter().map(|l| l.force).collect();
    (path, loads)
}

#[test]
fn a_sphere_rolling_across_a_flat_mesh_of_many_triangles_feels_one_plane() {
    common::on_every_backend(
        a_sphere_rolling_across_a_flat_mesh_of_many_triangles_feels_one_plane_on,
    );
}

fn a_sphere_rolling_across_a_flat_mesh_of_many_triangles_feels_one_plane_on(kind: BackendKind) {
    // Quads of 13 mm under a sphere of radius 10 mm: it always touches several triangles, and
    // crosses about 20 edges and many vertices on its way. The box's floor is far below.
    let mesh = grid_mesh(0.25, 38);
    let walls = walls_of(&[(WallConfig::of("floor"), &mesh)], true, 0.5);
    let (on_mesh, loads) = rolling_across(kind, walls, -0.3, 3000);
    // The box's own floor at z = 0, no mesh.
    let (on_box, _) = rolling_across(kind, WallSet::default(), 0.0, 3000);
    // The same contact computed from a triangle's plane as from the box's: only the rounding
    // of the force's sum differs (measured: 5e-9 m after 3000 steps, an ulp of 0.1 m is 7e-9 m).
    let gap = on_mesh
        .iter()
        .zip(&on_box)
        .map(|(a, b)| (Vec3::from(*a) - Vec3::from(*b)).length())
        .fold(0.0, f32::max);
    assert!(
        gap < 1e-7,
        "the mesh's trajectory leaves the plane's by {gap} m"
    );
    // It keeps its speed (0.5 m/s over 0.3 s: 0.15 m) and its height.
    let last = Vec3::from(*on_mesh.last().unwrap());
    let travelled = (last - Vec3::new(-0.12, -0.05, R)).truncate().length();
    assert!(
        (travelled / 0.15 - 1.0).abs() < 1e-3,
        "travelled {travelled} m"
    );
    // Once the landing's bounce has died out (0.05 s), no bump lifts or sinks it.
    let heights = on_mesh[50..].iter().map(|c| c[2]);
    let (lo, hi) = heights.fold((f32::MAX, f32::MIN), |(l, h), z| (l.min(z), h.max(z)));
    assert!(hi - lo < 1e-8, "height ranges {lo} .. {hi}");
    // The floor carries the sphere's weight.
    let weight = 2500.0 * 4.0 / 3.0 * std::f64::consts::PI * (R as f64).powi(3) * G as f64;
    assert!(
        (loads[0][2] / -weight - 1.0).abs() < 1e-4,
        "load {:?}, weight {weight}",
        loads[0]
    );
}

/// An ASCII STL of the box `lo..hi`: 12 triangles, outward normals.
fn stl_box(lo: [f32; 3], hi: [f32; 3]) -> String {
    let corner = |k: usize| [0, 1, 2].map(|a| if k >> a & 1 == 1 { hi[a] } else { lo[a] });
    // Each face as four corner numbers in order around its outward normal.
    let faces = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let mut text = String::from("solid box\n");
    for f in faces {
        for tri in [[f[0], f[1], f[2]], [f[0], f[2], f[3]]] {
            text += "facet normal 0 0 0\nouter loop\n";
            for k in tri {
                let [x, y, z] = corner(k);
                text += &format!("vertex {x} {y} {z}\n");
            }
            text += "endloop\nendfacet\n";
        }
    }
    text + "endsolid box\n"
}

#[test]
fn an_stl_box_gives_the_trajectories_of_the_box_walls() {
    common::on_every_backend(an_stl_box_gives_the_trajectories_of_the_box_walls_on);
}

fn an_stl_box_gives_the_trajectories_of_the_box_walls_on(kind: BackendKind) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.stl");
    std::fs::write(&path, stl_box([0.0; 3], [0.2; 3])).unwrap();
    let m = material(0.5, 0.1, RollingModel::Epsd);
    let p = params(&m, 0.0, 0.2);
    // Three spheres apart from each other, thrown at a wall, an edge and a corner, spinning.
    let particles = Particles {
        positions: vec![[0.05, 0.1, 0.05], [0.15, 0.05, 0.1], [0.1, 0.15, 0.15]],
        velocities: vec![[-0.8, 0.1, 0.0], [0.6, -0.7, 0.2], [0.5, 0.6, 0.4]],
        angular_velocities: vec![[0.0, 20.0, 0.0], [-10.0, 0.0, 5.0], [0.0; 3]],
        radii: vec![R; 3],
        ..Particles::default()
    };
    let mut stl = WallConfig::of(&path).build(0, None).unwrap();
    stl.friction = Some(0.5);
    // Inside the STL box, the box's own walls 0.1 m beyond it, never reached.
    let mut mesh_run = stepper(
        kind,
        particles.clone(),
        params(&m, -0.1, 0.3),
        WallSet::new(true, vec![stl]).unwrap(),
    );
    let mut box_run = stepper(kind, particles, p, WallSet::default());
    // 0.3 s: each sphere hits its walls, bounces, lands and rolls on the floor.
    let mut worst = 0.0f32;
    for _ in 0..30 {
        mesh_run.advance(100).unwrap();
        box_run.advance(100).unwrap();
        let (a, b) = (mesh_run.particles().unwrap(), box_run.particles().unwrap());
        for (x, y) in a.positions.iter().zip(&b.positions) {
            worst = worst.max((Vec3::from(*x) - Vec3::from(*y)).length());
        }
    }
    // A face contact is computed as the box's wall contact is (distance along the face's
    // normal): measured, the same bits. Allowed: rounding differences grown by the bounces,
    // a ten-thousandth of the radius.
    assert!(
        worst < 1e-6,
        "the STL box's trajectories leave the box's by {worst} m"
    );
}

/// A sphere resting at the bottom of a horizontal cylinder (axis y, radius 0.1 m, 96 sides)
/// turning at `omega`; its state after 0.05 s.
fn in_drum(kind: BackendKind, omega: f64) -> (Vec3, Vec3, Vec3, Vec3) {
    let radius = 0.1;
    let sides = 96u32;
    let mut mesh = Mesh::default();
    for k in 0..sides {
        let phi = 2.0 * std::f64::consts::PI * k as f64 / sides as f64;
        for y in [-0.05, 0.05] {
            mesh.vertices
                .push([radius * phi.cos(), y, radius * phi.sin()]);
        }
    }
    for k in 0..sides {
        let (a, b) = (2 * k, 2 * ((k + 1) % sides));
        mesh.triangles.push([a, b, b + 1]);
        mesh.triangles.push([a, b + 1, a + 1]);
    }
    let config = WallConfig {
        omega: Some(omega),
        axis: Some([0.0, 1.0, 0.0]),
        ..WallConfig::of("drum")
    };
    let m = material(0.5, 0.0, RollingModel::Epsd);
    let walls = walls_of(&[(config, &mesh)], true, 0.5);
    let bottom = -(radius as f32) * (PI / sides as f32).cos();
    let c = Vec3::new(0.0, 0.0, bottom + R);
    let mut s = stepper(
        kind,
        one_sphere(c, Vec3::ZERO, Vec3::ZERO),
        params(&m, -0.15, 0.15),
        walls,
    );
    s.advance(500).unwrap();
    let (c, v, w) = state(s.as_mut());
    // The wall's velocity at the contact point below the sphere, and the slip along it (the
    // facet's normal differs from the radial direction by up to π/96).
    let n = Vec3::new(c.x, 0.0, c.z).normalize();
    let point = c + R * n;
    let wall = Vec3::new(0.0, omega as f32, 0.0).cross(point);
    let along = Vec3::Y.cross(n);
    let slip = (v + w.cross(R * n) - wall).dot(along) * along;
    (c, v, slip, wall)
}

#[test]
fn a_rotating_cylinder_drags_a_resting_sphere_into_rolling_with_it() {
    common::on_every_backend(a_rotating_cylinder_drags_a_resting_sphere_into_rolling_with_it_on);
}

fn a_rotating_cylinder_drags_a_resting_sphere_into_rolling_with_it_on(kind: BackendKind) {
    // Wall speed 0.2 m/s: the slip dies within 2·v/(7 μ g) ≈ 0.012 s of sliding, after which
    // the sphere rolls on the wall. At 0.05 s: slip under 1% of the wall's speed, and the
    // sphere carried the way the wall moves (−x at the bottom for ω about +y).
    let (c, v, slip, wall) = in_drum(kind, 2.0);
    assert!(wall.x < -0.19, "wall velocity {wall}");
    assert!(
        slip.length() < 0.01 * wall.length(),
        "slip {slip}, wall {wall}"
    );
    assert!(v.x < -0.02 && c.x < -1e-3, "sphere at {c} moving {v}");
    // A drum at rest leaves it at rest.
    let (c, v, _, _) = in_drum(kind, 0.0);
    assert!(
        v.length() < 1e-4 && c.x.abs() < 1e-6,
        "sphere at {c} moving {v}"
    );
}

#[test]
fn a_run_with_a_turning_wall_resumes_from_its_checkpoint_bit_for_bit() {
    let mesh = grid_mesh(0.2, 16);
    let config = WallConfig {
        rotate: Some(Rotation {
            axis: [1.0, 0.0, 0.0],
            degrees: 5.0,
        }),
        omega: Some(0.5),
        axis: Some([0.0, 0.0, 1.0]),
        start: Some(0.01),
        ..WallConfig::of("plate")
    };
    let m = material(0.5, 0.1, RollingModel::Epsd);
    let walls = || walls_of(&[(config.clone(), &mesh)], false, 0.5);
    let particles = Particles {
        positions: (0..8)
            .map(|k| [-0.1 + 0.025 * k as f32, 0.05, 0.015 + 0.0005 * k as f32])
            .collect(),
        velocities: vec![[0.0; 3]; 8],
        angular_velocities: vec![[0.0; 3]; 8],
        radii: vec![R; 8],
        ..Particles::default()
    };
    let p = params(&m, -0.3, 0.3);
    let cpu = BackendKind::Cpu;
    let mut straight = stepper(cpu, particles.clone(), p.clone(), walls());
    straight.advance(400).unwrap();
    let mut first = stepper(cpu, particles, p.clone(), walls());
    first.advance(200).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("checkpoint.bin");
    mochi::io::write_checkpoint(&file, &first.particles().unwrap(), "", "").unwrap();
    let saved = mochi::io::read_checkpoint(&file).unwrap().particles;
    assert!(
        saved
            .history
            .contacts()
            .any(|(_, e)| e.partner == FIRST_MESH_WALL),
        "the checkpoint holds mesh-wall history"
    );
    let mut resumed = stepper(cpu, saved, p, walls());
    resumed.advance(200).unwrap();
    let (a, b) = (straight.particles().unwrap(), resumed.particles().unwrap());
    assert_eq!(a, b);
    assert_eq!(straight.wall_loads(), resumed.wall_loads());
}

#[test]
fn every_backend_runs_mesh_walls_with_and_without_the_box() {
    let mesh = grid_mesh(0.2, 2);
    let m = material(0.5, 0.0, RollingModel::Epsd);
    let p = params(&m, -0.3, 0.3);
    let sphere = one_sphere(Vec3::new(0.0, 0.0, 0.1), Vec3::ZERO, Vec3::ZERO);
    let open = |choice, box_walls| {
        let walls = walls_of(&[(WallConfig::of("floor"), &mesh)], box_walls, 0.0);
        open_scene(
            choice,
            start(sphere.clone(), p.clone(), walls),
            &Options::default(),
        )
    };
    for kind in common::dem_backends() {
        let _named = common::Naming(kind);
        for box_walls in [false, true] {
            let opened = open(BackendChoice::Named(kind), box_walls).unwrap();
            let (mut s, named) = (opened.value, opened.kind);
            assert_eq!(named, kind);
            s.advance(10).unwrap();
            assert_eq!(s.wall_loads().len(), 1);
        }
    }
    let opened = open(BackendChoice::Auto, false).unwrap();
    let kind = opened.kind;
    assert!(opened.value.describe().contains("1 mesh wall") || kind != BackendKind::Cpu);
    assert!(opened.reason.unwrap().contains(kind.name()));
}
