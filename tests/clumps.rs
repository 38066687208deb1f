//! Clumps against their closed forms: the mass properties of a union of spheres (a sphere,
//! dimers apart, touching and overlapping, against a one-dimensional integration of their
//! profile), the principal frame of an asymmetric clump turned anywhere, and the rigid-body step:
//! a torque-free asymmetric body keeping its angular momentum and energy, turning as a
//! symmetric top must, and tumbling about its intermediate axis but not about the others; a
//! constant force and torque giving the momenta they must.

use glam::{DMat3, DQuat, DVec3};
use mochi::clump::{ClumpTemplate, Component, MassProperties, PrincipalInertia, RigidBody};
use std::f64::consts::PI;

fn template(spheres: &[([f64; 3], f64)]) -> ClumpTemplate {
    let components = spheres
        .iter()
        .map(|&(c, r)| Component {
            centre: DVec3::from_array(c),
            radius: r,
        })
        .collect();
    ClumpTemplate::new("test", components).unwrap()
}

fn close(got: f64, want: f64, tolerance: f64, what: &str) {
    assert!(
        (got - want).abs() <= tolerance * want.abs(),
        "{what}: {got}, not {want} (within {tolerance:e})"
    );
}

#[test]
fn a_sphere_has_the_volume_and_moments_of_a_sphere_wherever_it_lies() {
    let r = 0.5;
    let m = template(&[([0.3, -0.2, 0.1], r)]).mass_properties();
    let volume = 4.0 / 3.0 * PI * r * r * r;
    close(m.volume, volume, 1e-5, "volume");
    assert!((m.centre - DVec3::new(0.3, -0.2, 0.1)).length() < 1e-6 * r);
    for k in 0..3 {
        close(m.moments[k], 0.4 * volume * r * r, 1e-4, "moment");
    }
}

/// The volume and the moments about the axis and across it (about the centre) of the union of
/// two spheres of radius `r` whose centres lie `d` apart on the z axis, by the midpoint rule on
/// its profile ρ(z) with a million slices: ∫πρ² dz, ∫πρ⁴/2 dz, ∫(πρ⁴/4 + πρ²z²) dz.
fn dimer_by_slices(r: f64, d: f64) -> (f64, f64, f64) {
    let (lo, hi) = (-d / 2.0 - r, d / 2.0 + r);
    let slices = 1_000_000;
    let h = (hi - lo) / slices as f64;
    let (mut volume, mut axial, mut across) = (0.0, 0.0, 0.0);
    for k in 0..slices {
        let z = lo + (k as f64 + 0.5) * h;
        let rho2 = [-d / 2.0, d / 2.0]
            .map(|c| r * r - (z - c) * (z - c))
            .into_iter()
            .fold(0.0, f64::max);
        volume += PI * rho2 * h;
        axial += PI * rho2 * rho2 / 2.0 * h;
        across += (PI * rho2 * rho2 / 4.0 + PI * rho2 * z * z) * h;
    }
    (volume, axial, across)
}

#[test]
fn dimers_apart_touching_and_overlapping_have_the_mass_properties_of_their_union() {
    let r = 1e-3;
    for d in [3.0 * r, 2.0 * r, 1.2 * r, 0.4 * r] {
        // Along z, with their centre away from the origin.
        let at = DVec3::new(2e-3, -1e-3, 5e-4);
        let m = template(&[
            ((at - DVec3::Z * d / 2.0).to_array(), r),
            ((at + DVec3::Z * d / 2.0).to_array(), r),
        ])
        .mass_properties();
        let (volume, axial, across) = dimer_by_slices(r, d);
        close(m.volume, volume, 1e-4, &format!("volume at d = {d}"));
        assert!((m.centre - at).length() < 1e-5 * r, "centre at d = {d}");
        // The axial moment is the smallest (a dimer is longer than wide).
        close(
            m.moments[0],
            axial,
            2e-4,
            &format!("axial moment at d = {d}"),
        );
        close(
            m.moments[1],
            across,
            2e-4,
            &format!("moment across at d = {d}"),
        );
        close(
            m.moments[2],
            across,
            2e-4,
            &format!("moment across at d = {d}"),
        );
        assert!(m.axes.col(0).z.abs() > 1.0 - 1e-9, "the axis is z");
        // Apart, each sphere on its own: 2·(2/5)·m·r² and the parallel axes' m·(d/2)².
        if d >= 2.0 * r {
            let one = 4.0 / 3.0 * PI * r * r * r;
            close(m.volume, 2.0 * one, 1e-4, "two spheres' volume");
            close(
                m.moments[0],
                2.0 * 0.4 * one * r * r,
                2e-4,
                "two spheres' axial moment",
            );
            let parallel = 2.0 * (0.4 * one * r * r + one * d * d / 4.0);
            close(m.moments[1], parallel, 2e-4, "two spheres' moment across");
        }
    }
}

/// Three unequal spheres off any line: three distinct principal moments.
fn asymmetric() -> ClumpTemplate {
    template(&[
        ([0.0, 0.0, 0.0], 1.0),
        ([1.4, 0.2, 0.0], 0.7),
        ([-0.3, 1.1, 0.5], 0.5),
    ])
}

#[test]
fn a_clump_turned_and_moved_anywhere_has_the_same_principal_moments_and_its_frame() {
    let base = asymmetric().mass_properties();
    assert!(base.moments.x < base.moments.y && base.moments.y < base.moments.z);
    let turn = DQuat::from_axis_angle(DVec3::new(0.3, -0.8, 0.5).normalize(), 2.1);
    let shift = DVec3::new(10.0, -4.0, 3.0);
    let mut moved = asymmetric();
    for c in &mut moved.components {
        c.centre = turn * c.centre + shift;
    }
    let m = moved.mass_properties();
    close(m.volume, base.volume, 1e-4, "volume");
    assert!((m.centre - (turn * base.centre + shift)).length() < 1e-4);
    for k in 0..3 {
        close(m.moments[k], base.moments[k], 1e-3, "moment");
        // The same axes, turned (up to their sign).
        let axis = turn * base.axes.col(k);
        assert!(m.axes.col(k).dot(axis).abs() > 1.0 - 1e-6, "axis {k}");
    }
    assert!((m.axes.determinant() - 1.0).abs() < 1e-12, "a rotation");
    // In its principal frame its centre is the origin and its inertia diagonal.
    let (principal, said) = moved.in_principal_frame();
    let again: MassProperties = principal.mass_properties();
    assert!(again.centre.length() < 1e-4);
    let off = again.inertia - DMat3::from_diagonal(again.moments);
    let largest = off
        .to_cols_array()
        .into_iter()
        .fold(0.0, |a: f64, x| a.max(x.abs()));
    assert!(
        largest < 1e-4 * again.moments.z,
        "off the diagonal: {largest}"
    );
    for k in 0..3 {
        close(
            again.moments[k],
            said.moments[k],
            1e-3,
            "moment in the principal frame",
        );
        assert!(again.inertia.col(k)[k] > 0.0);
    }
}

#[test]
fn a_template_without_spheres_or_with_a_bad_one_is_refused() {
    let none = ClumpTemplate::new("empty", Vec::new())
        .unwrap_err()
        .to_string();
    assert!(
        none.contains("clump \"empty\"") && none.contains("no component"),
        "{none}"
    );
    for (centre, radius) in [
        ([f64::NAN, 0.0, 0.0], 1.0),
        ([0.0; 3], 0.0),
        ([0.0; 3], -1.0),
    ] {
        let bad = Component {
            centre: DVec3::from_array(centre),
            radius,
        };
        let e = ClumpTemplate::new("bad", vec![bad])
            .unwrap_err()
            .to_string();
        assert!(e.contains("component 0"), "{e}");
    }
}

/// An asymmetric body (principal moments 1, 2 and 3 kg·m²) of 1 kg at the origin.
fn body(angular_velocity: DVec3) -> (RigidBody, PrincipalInertia) {
    let inertia = PrincipalInertia {
        mass: 1.0,
        moments: DVec3::new(1.0, 2.0, 3.0),
    };
    let q = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 0.7);
    let b = RigidBody::new(DVec3::ZERO, q, DVec3::ZERO, q * angular_velocity, &inertia);
    (b, inertia)
}

#[test]
fn a_torque_free_asymmetric_body_keeps_its_angular_momentum_and_energy() {
    let (mut b, inertia) = body(DVec3::new(0.4, 0.9, -0.6));
    let (l0, e0) = (b.angular_momentum, b.kinetic_energy(&inertia));
    let dt = 1e-2;
    let mut turned = 0.0f64;
    for _ in 0..10_000 {
        let before = b.orientation;
        b.advance(&inertia, DVec3::ZERO, DVec3::ZERO, dt);
        turned += before.angle_between(b.orientation);
        close(b.kinetic_energy(&inertia), e0, 1e-4, "energy");
    }
    assert!((b.angular_momentum - l0).length() < 1e-12 * l0.length());
    assert!(turned > 50.0, "turned by {turned} rad in all");
    // The angular momentum in the body frame moves (on its polhode): a step that does
    // nothing would keep it.
    let (start, _) = body(DVec3::new(0.4, 0.9, -0.6));
    let drift = (b.orientation.inverse() * l0 - start.orientation.inverse() * l0).length();
    assert!(
        drift > 0.1 * l0.length(),
        "the body frame's L moved by {drift}"
    );
}

#[test]
fn a_body_spinning_about_a_principal_axis_turns_at_its_rate() {
    let inertia = PrincipalInertia {
        mass: 2.0,
        moments: DVec3::new(1.0, 2.0, 3.0),
    };
    for axis in 0..3 {
        let mut spin = DVec3::ZERO;
        spin[axis] = 3.0;
        let mut b = RigidBody::new(DVec3::ZERO, DQuat::IDENTITY, DVec3::ZERO, spin, &inertia);
        let dt = 1e-3;
        for _ in 0..500 {
            b.advance(&inertia, DVec3::ZERO, DVec3::ZERO, dt);
        }
        // 1.5 rad about the axis, exactly the rotation by ω·t.
        let want = DQuat::from_axis_angle(spin.normalize(), 1.5);
        assert!(b.orientation.angle_between(want) < 1e-9, "axis {axis}");
        assert!((b.angular_velocity(&inertia) - spin).length() < 1e-12);
    }
}

#[test]
fn a_body_tumbles_about_its_intermediate_axis_and_not_about_the_others() {
    // A spin about one principal axis, perturbed by a thousandth about the others: about the
    // smallest and the largest axis the body's spin stays; about the intermediate one it flips
    // (the tennis racket's, or Dzhanibekov's, instability), within a few of its periods.
    let dt = 1e-3;
    for axis in 0..3 {
        let mut w = DVec3::splat(1e-3);
        w[axis] = 1.0;
        let (mut b, inertia) = body(w);
        let mut least = f64::INFINITY;
        for _ in 0..60_000 {
            b.advance(&inertia, DVec3::ZERO, DVec3::ZERO, dt);
            least = least.min(b.body_angular_velocity(&inertia)[axis]);
        }
        match axis {
            1 => assert!(least < -0.9, "about the intermediate axis: {least}"),
            _ => assert!(least > 0.99, "about axis {axis}: {least}"),
        }
    }
}

#[test]
fn a_force_and_a_torque_change_the_momenta_as_newton_and_euler_say() {
    let inertia = PrincipalInertia {
        mass: 2.0,
        moments: DVec3::new(1.0, 2.0, 3.0),
    };
    let (v0, force, torque) = (
        DVec3::new(0.1, 0.0, -0.2),
        DVec3::new(0.0, 0.0, -19.62),
        DVec3::new(0.3, -0.1, 0.2),
    );
    let mut b = RigidBody::new(DVec3::ONE, DQuat::IDENTITY, v0, DVec3::ZERO, &inertia);
    let (dt, n) = (1e-3, 1000);
    for _ in 0..n {
        b.advance(&inertia, force, torque, dt);
    }
    let t = n as f64 * dt;
    let a = force / inertia.mass;
    assert!((b.velocity - (v0 + a * t)).length() < 1e-12);
    // The kick before the drift: x = x0 + v0·t + a·dt²·n(n+1)/2.
    let x = DVec3::ONE + v0 * t + a * dt * dt * (n * (n + 1)) as f64 / 2.0;
    assert!((b.position - x).length() < 1e-12);
    assert!((b.angular_momentum - torque * t).length() < 1e-12);
    // A component's velocity is the centre's plus ω × its arm.
    let arm = DVec3::new(0.1, 0.2, 0.0);
    let w = b.angular_velocity(&inertia);
    let want = b.velocity + w.cross(b.orientation * arm);
    assert!((b.point_velocity(&inertia, arm) - want).length() < 1e-15);
    assert!((b.world_point(arm) - (b.position + b.orientation * arm)).length() < 1e-15);
}

#[test]
fn the_built_in_shapes_have_the_symmetries_and_volumes_of_their_spheres() {
    let r = 1e-3;
    let one = 4.0 / 3.0 * PI * r * r * r;
    // Two spheres r apart: a lens of π(4r + d)(2r − d)²/12 counted once.
    let lens = |d: f64| PI * (4.0 * r + d) * (2.0 * r - d).powi(2) / 12.0;
    let dimer = ClumpTemplate::dimer(r).unwrap().mass_properties();
    close(dimer.volume, 2.0 * one - lens(r), 1e-4, "dimer's volume");
    let (_, axial, across) = dimer_by_slices(r, r);
    close(dimer.moments[0], axial, 2e-4, "dimer's axial moment");
    close(dimer.moments[2], across, 2e-4, "dimer's moment across");
    assert!(
        dimer.axes.col(0).x.abs() > 1.0 - 1e-9,
        "the dimer lies along x"
    );
    // A rod of n: n spheres less n − 1 lenses (only neighbours overlap), along x.
    let rod = ClumpTemplate::rod(5, r).unwrap();
    assert_eq!(rod.name, "rod 5");
    let m = rod.mass_properties();
    close(m.volume, 5.0 * one - 4.0 * lens(r), 1e-4, "rod's volume");
    assert!(m.centre.length() < 1e-6 * r);
    assert!(
        m.moments[2] > 5.0 * m.moments[0],
        "a rod is long: {:?}",
        m.moments
    );
    // A trimer is a symmetric top: its two moments in its plane are equal, the third (about the
    // normal, z) the largest.
    let m = ClumpTemplate::trimer(r).unwrap().mass_properties();
    close(
        m.moments[0],
        m.moments[1],
        1e-3,
        "trimer's moments in its plane",
    );
    assert!(m.moments[2] > 1.1 * m.moments[1]);
    assert!(
        m.axes.col(2).z.abs() > 1.0 - 1e-6,
        "the trimer's normal is z"
    );
    // A regular tetrahedron's inertia is the same about every axis.
    let m = ClumpTemplate::tetrahedron(r).unwrap().mass_properties();
    close(m.moments[0], m.moments[2], 1e-3, "tetrahedron's moments");
    assert!(m.centre.length() < 1e-6 * r);
    let t = ClumpTemplate::tetrahedron(r).unwrap();
    for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
        let edge = t.components[a].centre.distance(t.components[b].centre);
        close(edge, r, 1e-12, "tetrahedron's edge");
    }
    assert!(ClumpTemplate::rod(0, r).is_err());
    assert!(ClumpTemplate::dimer(-r).is_err());
}

#[test]
fn a_grain_from_a_mesh_is_its_volume_filled_with_touching_spheres() {
    // A cube of 4 mm filled at a spacing of 1 mm: 4³ spheres of 0.5 mm, touching, not
    // overlapping (the union is their sum), its inertia a cube's, the same about every axis.
    let s = 4e-3;
    let vertices = (0..8)
        .map(|k| {
            [
                (k & 1) as f64 * s,
                ((k >> 1) & 1) as f64 * s,
                (k >> 2) as f64 * s,
            ]
        })
        .collect();
    let faces = [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    let cube = mochi::mesh::Mesh {
        vertices,
        triangles: faces.to_vec(),
    };
    let grain = ClumpTemplate::from_mesh("cube", &cube, 1e-3).unwrap();
    assert_eq!(grain.components.len(), 64);
    let m = grain.mass_properties();
    let one = 4.0 / 3.0 * PI * 0.5e-3f64.powi(3);
    close(m.volume, 64.0 * one, 1e-4, "the grain's volume");
    assert!((m.centre - DVec3::splat(s / 2.0)).length() < 1e-6 * s);
    close(m.moments[0], m.moments[2], 1e-3, "a cube's moments");
}

// ---- Clumps moved by their components' contacts ---------------------------------------------

use mochi::clump::{Clump, ClumpKind, ClumpSet, ComponentState};
use mochi::dem::StepParams;
use mochi::dem::model::contact::{Body, Springs, pair_contact, wall_contacts};
use mochi::dem::model::{ContactLaw, Material};
use std::collections::HashMap;

const DENSITY: f64 = 2500.0;

/// Hertz–Mindlin (E 1e7 Pa) with sliding friction `mu` in a 10 cm box, at a fifth of the
/// Rayleigh time of spheres of 1 mm.
fn law(mu: f64) -> StepParams {
    law_of(mu, 1e7)
}

/// [`law`] at Young's modulus `e` \[Pa\].
fn law_of(mu: f64, e: f64) -> StepParams {
    let material = Material {
        contact: ContactLaw::HertzMindlin {
            young_modulus: e,
            poisson_ratio: 0.3,
        },
        density: DENSITY,
        restitution: 0.5,
        friction: mu,
        rolling_friction: 0.0,
        ..Material::default()
    };
    let side = [0.1; 3];
    let probe = StepParams::new(&material, 1e-9, [0.0; 3], side, [0.0; 3], 0.0, 1e-3).unwrap();
    let dt = 0.5 * probe.dt_limit as f64;
    StepParams::new(&material, dt, [0.0; 3], side, [0.0; 3], 0.0, 1e-3).unwrap()
}

/// A component as the contact laws take it (in f32).
fn as_body(c: &ComponentState) -> Body {
    Body {
        c: c.centre.as_vec3(),
        v: c.velocity.as_vec3(),
        w: c.angular_velocity.as_vec3(),
        r: c.radius as f32,
        m: c.mass as f32,
        material: 0,
    }
}

/// One step of `set` under gravity −z on the box's floor and walls: each component's wall
/// contacts (their springs kept in `springs` by component and wall), then the clumps moved.
fn step_on_floor(set: &mut ClumpSet, p: &StepParams, springs: &mut HashMap<(usize, u32), Springs>) {
    let parts = set.components();
    let mut forces = vec![DVec3::ZERO; parts.len()];
    let mut torques = vec![DVec3::ZERO; parts.len()];
    let mut kept = HashMap::new();
    for (k, c) in parts.iter().enumerate() {
        let walls = wall_contacts(
            p,
            &as_body(c),
            |w| {
                springs
                    .get(&(k, w))
                    .map_or((Springs::default(), false), |&s| (s, true))
            },
            |w, s| {
                kept.insert((k, w), s);
            },
            |_, _, _, _| {},
        );
        forces[k] = (walls.normal + walls.tangential).as_dvec3();
        torques[k] = walls.torque.as_dvec3();
    }
    *springs = kept;
    set.advance(&forces, &torques, DVec3::new(0.0, 0.0, -9.81), p.dt as f64);
}

#[test]
fn a_dimer_dropped_flat_or_tilted_comes_to_rest_on_both_spheres() {
    let r = 1e-3;
    let p = law(0.5);
    let kind = ClumpKind::new(&ClumpTemplate::dimer(r).unwrap(), DENSITY);
    for tilt in [0.0f64, 30f64.to_radians()] {
        // Its axis along x, turned by `tilt` about y; its lowest point 0.5 mm above the floor.
        let orientation = DQuat::from_rotation_y(tilt);
        let lowest = r + 0.5 * r * tilt.sin();
        let body = RigidBody::new(
            DVec3::new(0.05, 0.05, lowest + 0.5e-3),
            orientation,
            DVec3::ZERO,
            DVec3::ZERO,
            &kind.inertia,
        );
        let mut set = ClumpSet {
            kinds: vec![kind.clone()],
            clumps: vec![Clump { kind: 0, body }],
        };
        let mut springs = HashMap::new();
        let steps = (0.4 / p.dt as f64) as usize;
        for _ in 0..steps {
            step_on_floor(&mut set, &p, &mut springs);
        }
        // Both spheres on the floor, pressed by half the weight each (a Hertz overlap well
        // under a micrometre), at rest.
        for c in set.components() {
            assert!(
                (c.centre.z - r).abs() < 2e-6,
                "tilt {tilt}: a sphere at z = {}",
                c.centre.z
            );
            assert!(
                c.velocity.length() < 1e-4,
                "tilt {tilt}: moving at {}",
                c.velocity
            );
        }
        let w = set.clumps[0].body.angular_velocity(&kind.inertia);
        assert!(w.length() < 0.1, "tilt {tilt}: turning at {w}");
    }
}

#[test]
fn two_frictionless_dimers_colliding_off_centre_keep_their_momenta_and_start_to_spin() {
    let r = 1e-3;
    let p = law(0.0);
    let kind = ClumpKind::new(&ClumpTemplate::dimer(r).unwrap(), DENSITY);
    // Two dimers along x flying at each other along y, off centre: the first's right sphere
    // meets the second's left one.
    let body = |x: f64, y: f64, vy: f64| RigidBody {
        position: DVec3::new(x, y, 0.05),
        orientation: DQuat::IDENTITY,
        velocity: DVec3::new(0.0, vy, 0.0),
        angular_momentum: DVec3::ZERO,
    };
    let mut set = ClumpSet {
        kinds: vec![kind.clone()],
        clumps: vec![
            Clump {
                kind: 0,
                body: body(0.05, 0.05 - 1.5 * r, 0.2),
            },
            Clump {
                kind: 0,
                body: body(0.05 + r, 0.05 + 1.5 * r, -0.2),
            },
        ],
    };
    let owners = set.owners();
    let (p0, l0) = set.momenta();
    let scale = kind.inertia.mass * 0.2 * r;
    for _ in 0..4000 {
        let parts = set.components();
        let mut forces = vec![DVec3::ZERO; parts.len()];
        // Each pair of components of different clumps, from both sides (as the cpu step).
        for (a, ca) in parts.iter().enumerate() {
            for (b, cb) in parts.iter().enumerate() {
                if owners[a] == owners[b] {
                    continue;
                }
                if let Some(c) =
                    pair_contact(&p, &as_body(ca), &as_body(cb), Springs::default(), false)
                {
                    forces[a] += c.force.as_dvec3();
                }
            }
        }
        let torques = vec![DVec3::ZERO; parts.len()];
        set.advance(&forces, &torques, DVec3::ZERO, p.dt as f64);
    }
    let (p1, l1) = set.momenta();
    assert!(
        (p1 - p0).length() < 1e-9 * kind.inertia.mass * 0.2,
        "momentum {p0} → {p1}"
    );
    assert!(
        (l1 - l0).length() < 1e-5 * scale,
        "angular momentum {l0} → {l1}"
    );
    // They met and turned each other: each now spins about z.
    for c in &set.clumps {
        let w = c.body.angular_velocity(&kind.inertia);
        assert!(w.z.abs() > 1.0, "spin {w}");
        assert!(c.body.velocity.y.abs() < 0.2, "{}", c.body.velocity);
    }
}

// ---- Clumps in the whole step, on every backend ----------------------------------------------

use mochi::ProxyMode;
use mochi::dem::{Particles, Stepper};
use mochi::engines::cpu::CpuStepper;
use mochi::engines::{BackendKind, DemSetup};

mod common;
use common::on_every_backend;

/// A dimer of spheres of 1 mm in `orientation` with its centre at `at`, at rest, as a run's
/// clumps, then the free spheres of `free`.
fn dimer_run(at: DVec3, orientation: DQuat, free: Particles) -> Particles {
    let kind = ClumpKind::new(&ClumpTemplate::dimer(1e-3).unwrap(), DENSITY);
    let body = RigidBody::new(at, orientation, DVec3::ZERO, DVec3::ZERO, &kind.inertia);
    let clumps = ClumpSet {
        kinds: vec![kind],
        clumps: vec![Clump { kind: 0, body }],
    };
    Particles::with_clumps(clumps, free).unwrap()
}

/// The step of backend `kind` of `particles` under `p`.
fn open(kind: BackendKind, particles: Particles, p: StepParams) -> Box<dyn Stepper> {
    mochi::engines::open_stepper(kind, particles, p, ProxyMode::Mochi, &Default::default()).unwrap()
}

/// The step of backend `kind` of `particles` under gravity −z in [`law`]'s box.
fn dropped(kind: BackendKind, particles: Particles, mu: f64) -> Box<dyn Stepper> {
    let p = law(mu).with_gravity([0.0, 0.0, -9.81], 1e-3).unwrap();
    open(kind, particles, p)
}

/// The cpu step of `particles` under gravity −z in [`law`]'s box.
fn cpu(particles: Particles, mu: f64) -> CpuStepper {
    let p = law(mu).with_gravity([0.0, 0.0, -9.81], 1e-3).unwrap();
    CpuStepper::open(DemSetup::new(particles, p, ProxyMode::Mochi)).unwrap()
}

/// How far a component may lie from where its clump's pose read back puts it \[m\]: the cpu
/// steps in f64, the GPU steps turn the components' arms in f32.
fn placed_within(kind: BackendKind) -> f64 {
    match kind {
        BackendKind::Cpu => 1e-12,
        _ => 1e-9,
    }
}

#[test]
fn a_dimer_lands_on_both_spheres_and_its_spheres_are_never_a_pair() {
    on_every_backend(|kind| {
        let r = 1e-3;
        // Tilted 30°, its lower sphere 0.5 mm above the floor.
        let tilt = 30f64.to_radians();
        let at = DVec3::new(0.05, 0.05, r + 0.5 * r * tilt.sin() + 0.5e-3);
        // And a sphere of 4 mm resting far from it: a grid of more than one level.
        let mut free = Particles::default();
        free.push([0.02, 0.02, 0.004], [0.0; 3], 4e-3).unwrap();
        let run = dimer_run(at, DQuat::from_rotation_y(tilt), free);
        let mut s = dropped(kind, run, 0.5);
        let dt = law(0.5).dt as f64;
        for _ in 0..((0.4 / dt) as u32 / 500) {
            // Its two spheres overlap by a radius, but are one body: no pair, ever.
            assert_eq!(s.advance(500).unwrap().contacts, 0);
        }
        let end = s.particles().unwrap();
        for k in 0..2 {
            let z = end.exact_position(k)[2];
            assert!((z - r).abs() < 2e-6, "a sphere at z = {z}");
            let v = DVec3::from_array(end.velocities[k].map(f64::from));
            assert!(v.length() < 1e-4, "moving at {v}");
        }
        // The state carries the clump; its components are where it puts them.
        let clump = end.clumps.clumps[0].body;
        let c = end.clumps.components();
        assert!((clump.position.z - r).abs() < 2e-6);
        for (k, component) in c.iter().enumerate() {
            let off = (DVec3::from_array(end.exact_position(k)) - component.centre).length();
            assert!(off < placed_within(kind), "sphere {k} {off} m off");
        }
    });
}

#[test]
fn a_sphere_dropped_on_a_dimer_comes_to_rest_on_it() {
    on_every_backend(|kind| {
        let r = 1e-3;
        // The dimer flat on the floor along x; a free sphere of 1 mm 0.5 mm above its middle.
        let mut free = Particles::default();
        free.push(
            [0.05, 0.05, (r + r * 3.75f64.sqrt() + 0.5e-3) as f32],
            [0.0; 3],
            1e-3,
        )
        .unwrap();
        let run = dimer_run(DVec3::new(0.05, 0.05, r), DQuat::IDENTITY, free);
        let mut s = dropped(kind, run, 0.5);
        let dt = law(0.5).dt as f64;
        let contacts = s.advance((0.4 / dt) as u32).unwrap().contacts;
        // It rests on both of the dimer's spheres, in the groove between them: 2r from each
        // centre, r/2 from each along x.
        assert_eq!(contacts, 2);
        let end = s.particles().unwrap();
        let z = end.exact_position(2)[2];
        assert!(
            (z - (r + r * 3.75f64.sqrt())).abs() < 1e-5,
            "the sphere at z = {z}"
        );
        assert!(end.velocities[2].iter().all(|v| v.abs() < 1e-3));
    });
}

#[test]
fn two_dimers_colliding_in_the_step_keep_their_momenta_and_start_to_spin() {
    on_every_backend(|kind| {
        // As the frictionless dimers above, through the whole step: off centre, along y.
        let r = 1e-3;
        let dimer = ClumpKind::new(&ClumpTemplate::dimer(r).unwrap(), DENSITY);
        let body = |x: f64, y: f64, vy: f64| RigidBody {
            position: DVec3::new(x, y, 0.05),
            orientation: DQuat::IDENTITY,
            velocity: DVec3::new(0.0, vy, 0.0),
            angular_momentum: DVec3::ZERO,
        };
        let set = ClumpSet {
            kinds: vec![dimer.clone()],
            clumps: vec![
                Clump {
                    kind: 0,
                    body: body(0.05, 0.05 - 1.5 * r, 0.2),
                },
                Clump {
                    kind: 0,
                    body: body(0.05 + r, 0.05 + 1.5 * r, -0.2),
                },
            ],
        };
        let run = Particles::with_clumps(set.clone(), Particles::default()).unwrap();
        let mut s = open(kind, run, law(0.0));
        let (p0, l0) = set.momenta();
        s.advance(4000).unwrap();
        let end = s.particles().unwrap().clumps;
        let (p1, l1) = end.momenta();
        let m = dimer.inertia.mass;
        assert!((p1 - p0).length() < 1e-6 * m * 0.2, "momentum {p0} → {p1}");
        let scale = m * 0.2 * r;
        assert!(
            (l1 - l0).length() < 1e-4 * scale,
            "angular momentum {l0} → {l1}"
        );
        // They met and turned each other: each now spins about z, and flies back.
        for (c, was) in end.clumps.iter().zip(&set.clumps) {
            let w = c.body.angular_velocity(&dimer.inertia);
            assert!(w.z.abs() > 1.0, "spin {w}");
            let v = c.body.velocity;
            assert!(v.y * was.body.velocity.y < 0.0 && v.y.abs() < 0.2, "{v}");
        }
    });
}

#[test]
fn a_run_of_clumps_resumed_from_its_checkpoint_goes_on_bit_for_bit() {
    let r = 1e-3;
    let at = DVec3::new(0.05, 0.05, 3.0 * r);
    let turn = DQuat::from_axis_angle(DVec3::new(1.0, 1.0, 0.0).normalize(), 0.4);
    let mut free = Particles::default();
    free.push([0.052, 0.05, 0.006], [0.0; 3], 1e-3).unwrap();
    let mut whole = cpu(dimer_run(at, turn, free), 0.5);
    whole.advance(3000).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.bin");
    mochi::io::write_checkpoint(&path, &whole.particles().unwrap(), "x", "").unwrap();
    let saved = mochi::io::read_checkpoint(&path).unwrap().particles;
    assert!(!saved.clumps.clumps.is_empty());
    let mut resumed = cpu(saved, 0.5);
    whole.advance(3000).unwrap();
    resumed.advance(3000).unwrap();
    assert!(whole.particles().unwrap() == resumed.particles().unwrap());
}

#[test]
fn a_batch_redone_with_more_history_slots_moves_each_clump_once() {
    on_every_backend(|kind| {
        // 24 spheres of 5 mm all overlapping one another: some sphere owns more contacts than
        // the 16 slots a run starts with, so the first batch starts over with more; a dimer far
        // from them flies at 1 m/s without gravity, and must have flown for the steps run, not
        // for those and the ones undone.
        let r = 0.005f32;
        let mut free = Particles::default();
        let mut rand = common::noise(5);
        for _ in 0..24 {
            let c = [0; 3].map(|_| 0.05 + 0.3 * r * rand());
            free.push(c, [0.0; 3], r).unwrap();
        }
        let mut run = dimer_run(DVec3::new(0.02, 0.02, 0.02), DQuat::IDENTITY, free);
        let inertia = run.clumps.kinds[0].inertia;
        let start = run.clumps.clumps[0].body.position;
        let v = DVec3::new(1.0, 0.5, 0.0);
        run.clumps.clumps[0].body =
            RigidBody::new(start, DQuat::IDENTITY, v, DVec3::ZERO, &inertia);
        run.place_clump_components().unwrap();
        let p = law(0.5);
        let mut s = open(kind, run, p.clone());
        s.advance(3).unwrap();
        if kind != BackendKind::Cpu {
            assert!(
                !s.describe().contains("history 16 slots"),
                "{}",
                s.describe()
            );
        }
        let end = s.particles().unwrap().clumps.clumps[0].body.position;
        let flown = end - start;
        let want = v * 3.0 * p.dt as f64;
        assert!(
            (flown - want).length() < 1e-6 * want.length(),
            "flew {flown}, not {want}"
        );
    });
}

#[test]
fn a_runs_kinetic_energy_counts_each_clump_once_as_a_rigid_body() {
    let mut free = Particles::default();
    free.push([0.02, 0.02, 0.02], [0.0, 0.0, -1.0], 1e-3)
        .unwrap();
    let mut run = dimer_run(DVec3::splat(0.05), DQuat::IDENTITY, free);
    let kind = run.clumps.kinds[0].clone();
    run.clumps.clumps[0].body = RigidBody::new(
        DVec3::splat(0.05),
        DQuat::IDENTITY,
        DVec3::X,
        DVec3::Z * 3.0,
        &kind.inertia,
    );
    let e = run.energies(&[DENSITY as f32]);
    let sphere = DENSITY * 4.0 / 3.0 * PI * 1e-9;
    close(
        e.translational,
        0.5 * kind.inertia.mass + 0.5 * sphere,
        1e-6,
        "translational",
    );
    close(
        e.rotational,
        0.5 * kind.inertia.moments.z * 9.0,
        1e-12,
        "rotational",
    );
}

#[test]
fn a_frame_of_a_run_of_clumps_names_each_spheres_clump() {
    let mut free = Particles::default();
    free.push([0.02, 0.02, 0.02], [0.0; 3], 1e-3).unwrap();
    let run = dimer_run(DVec3::splat(0.05), DQuat::IDENTITY, free);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.vtu");
    mochi::io::write_vtu(&path, &mochi::io::Frame::of(&run, 1e-5, None)).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    let tag = r#"<DataArray type="Int32" Name="clump" format="appended" offset=""#;
    let at = text.find(tag).expect("a clump array") + tag.len();
    let offset: usize = text[at..].split('"').next().unwrap().parse().unwrap();
    let data = bytes.windows(2).position(|w| w == b" _").unwrap() + 2 + offset;
    let length = u64::from_le_bytes(bytes[data..data + 8].try_into().unwrap());
    let clumps: Vec<i32> = bytes[data + 8..data + 8 + length as usize]
        .chunks_exact(4)
        .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    // The dimer's two spheres are clump 0's; the free sphere is none's.
    assert_eq!(clumps, [0, 0, -1]);
    // A run without clumps has no such array.
    let mut plain = Particles::default();
    plain.push([0.02, 0.02, 0.02], [0.0; 3], 1e-3).unwrap();
    mochi::io::write_vtu(&path, &mochi::io::Frame::of(&plain, 1e-5, None)).unwrap();
    assert!(!String::from_utf8_lossy(&std::fs::read(&path).unwrap()).contains("Name=\"clump\""));
}

/// The bytes of the appended array `name` of the `.vtu` `bytes` (after its length header).
fn appended<'a>(bytes: &'a [u8], name: &str) -> &'a [u8] {
    let text = String::from_utf8_lossy(bytes);
    let tag = format!("Name=\"{name}\"");
    let at = text.find(&tag).expect("the array") + tag.len();
    let offset: usize = text[at..]
        .split("offset=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let data = bytes.windows(2).position(|w| w == b" _").unwrap() + 2 + offset;
    let length = u64::from_le_bytes(bytes[data..data + 8].try_into().unwrap()) as usize;
    &bytes[data + 8..data + 8 + length]
}

fn f64s(bytes: &[u8]) -> Vec<f64> {
    bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

#[test]
fn a_series_of_a_run_of_clumps_writes_each_clumps_pose_beside_its_frame() {
    let mut free = Particles::default();
    free.push([0.02, 0.02, 0.02], [0.0; 3], 1e-3).unwrap();
    let turn = DQuat::from_rotation_z(0.3);
    let run = dimer_run(DVec3::new(0.05, 0.04, 0.03), turn, free);
    let dir = tempfile::tempdir().unwrap();
    let mut series = mochi::io::FrameSeries::create(dir.path()).unwrap();
    for step in [10, 20] {
        let mut p = run.clone();
        p.step = step;
        series
            .write(&mochi::io::Frame::of(&p, 1e-5, None), false)
            .unwrap();
    }
    let bytes = std::fs::read(dir.path().join("clumps_00000020.vtu")).unwrap();
    let body = run.clumps.clumps[0].body;
    assert_eq!(f64s(appended(&bytes, "Points")), body.position.to_array());
    let q = body.orientation;
    assert_eq!(f64s(appended(&bytes, "orientation")), [q.w, q.x, q.y, q.z]);
    let mass = run.clumps.kinds[0].inertia.mass;
    assert_eq!(f64s(appended(&bytes, "mass")), [mass]);
    assert_eq!(appended(&bytes, "spheres"), 2u32.to_le_bytes());
    // Their collection lists each frame's; a run resumed from step 10 forgets step 20's.
    let index = dir.path().join(mochi::io::CLUMPS_INDEX);
    let text = std::fs::read_to_string(&index).unwrap();
    assert!(text.contains("clumps_00000010.vtu") && text.contains("clumps_00000020.vtu"));
    mochi::io::FrameSeries::open_for_resume(dir.path(), 10).unwrap();
    let text = std::fs::read_to_string(&index).unwrap();
    assert!(text.contains("clumps_00000010.vtu") && !text.contains("clumps_00000020.vtu"));
    // A run without clumps writes neither.
    let plain = tempfile::tempdir().unwrap();
    let mut series = mochi::io::FrameSeries::create(plain.path()).unwrap();
    let mut p = Particles::default();
    p.push([0.02, 0.02, 0.02], [0.0; 3], 1e-3).unwrap();
    series
        .write(&mochi::io::Frame::of(&p, 1e-5, None), false)
        .unwrap();
    assert!(!plain.path().join(mochi::io::CLUMPS_INDEX).exists());
}

/// The angle of repose \[°\] of the heap the scene `pour` of `grains` grains (spheres, or clumps
/// of `[[clump]]` table `clump`) makes on the floor without rolling resistance, 0.42 s after
/// they start to fall: atan(top / base), the base the radius that holds 95 % of the spheres
/// about the heap's axis.
fn heap_angle(grains: usize, clump: &str) -> f64 {
    use mochi::dem::scene::{Overrides, SceneConfig};
    let text = format!(
        "[source]\nscene = \"pour\"\nspheres = {grains}\n[run]\ndt = 1.4e-5\n\
         [material]\nrolling_friction = 0\n{clump}"
    );
    let config = SceneConfig::parse(Some(&text), None, &Overrides::default()).unwrap();
    let start = config.build().unwrap();
    let choice = mochi::engines::BackendChoice::Named(BackendKind::Cpu);
    let mut s = mochi::engines::open_scene(choice, start, &Default::default())
        .unwrap()
        .value;
    s.advance(30_000).unwrap();
    let p = s.particles().unwrap();
    let at: Vec<[f64; 3]> = (0..p.len()).map(|i| p.exact_position(i)).collect();
    let n = at.len() as f64;
    let (cx, cy) = (
        at.iter().map(|c| c[0]).sum::<f64>() / n,
        at.iter().map(|c| c[1]).sum::<f64>() / n,
    );
    let mut out: Vec<f64> = at.iter().map(|c| (c[0] - cx).hypot(c[1] - cy)).collect();
    out.sort_by(f64::total_cmp);
    let base = out[(0.95 * n) as usize];
    let top = (0..p.len())
        .map(|i| at[i][2] + p.radii[i] as f64)
        .fold(0.0, f64::max);
    (top / base).atan().to_degrees()
}

#[test]
fn a_heap_of_tetrahedra_stands_steeper_than_a_heap_of_spheres() {
    // The same pour and material, without rolling resistance: spheres roll apart into a layer
    // (5.6° measured), tetrahedra interlock (12.9°).
    let spheres = heap_angle(120, "");
    let tetrahedra = heap_angle(120, "[[clump]]\nshape = \"tetrahedron\"\n");
    eprintln!("angle of repose: spheres {spheres:.1}°, tetrahedra {tetrahedra:.1}°");
    assert!(
        tetrahedra > 1.6 * spheres,
        "tetrahedra {tetrahedra}°, spheres {spheres}°"
    );
    assert!(tetrahedra > 10.0, "tetrahedra {tetrahedra}°");
}

#[test]
fn a_clumps_spheres_keep_the_motion_of_their_clump() {
    on_every_backend(|kind| {
        let mut free = Particles::default();
        free.push([0.02, 0.02, 0.02], [0.0; 3], 1e-3).unwrap();
        let run = dimer_run(DVec3::splat(0.05), DQuat::IDENTITY, free);
        let mut s = dropped(kind, run, 0.5);
        let p = s.particles().unwrap();
        // The free sphere's velocity may change, the components' rows given as they are.
        let mut v = p.velocities.clone();
        v[2] = [0.0, 0.0, 1.0];
        fn motion(v: &[[f32; 3]]) -> mochi::dem::Motion<'_> {
            mochi::dem::Motion {
                velocities: Some(v),
                ..Default::default()
            }
        }
        s.set_motion(&motion(&v)).unwrap();
        assert_eq!(s.particles().unwrap().velocities[2], [0.0, 0.0, 1.0]);
        v[0] = [1.0, 0.0, 0.0];
        let e = s.set_motion(&motion(&v)).unwrap_err().to_string();
        assert!(e.contains("clump"), "{e}");
        let mut x: Vec<[f64; 3]> = (0..3).map(|i| p.exact_position(i)).collect();
        x[1][2] += 1e-3;
        let e = s
            .set_motion(&mochi::dem::Motion {
                positions: Some(&x),
                ..Default::default()
            })
            .unwrap_err()
            .to_string();
        assert!(e.contains("clump"), "{e}");
    });
}

#[test]
fn a_dimer_on_its_side_rolls_down_an_incline_as_a_rigid_body_must() {
    // A soft modulus for 0.05 s, and glass's (7e10 Pa, a step 84 times shorter) for 0.005 s.
    on_every_backend(|kind| {
        rolls_down_an_incline(kind, 1e7, 0.05);
        rolls_down_an_incline(kind, 7e10, 0.005);
    });
}

/// [`a_dimer_on_its_side_rolls_down_an_incline_as_a_rigid_body_must`] on backend `backend` at
/// Young's modulus `e` \[Pa\] for `time` \[s\].
fn rolls_down_an_incline(backend: BackendKind, e: f64, time: f64) {
    // A dimer of spheres of 1 mm lying across a 20° incline (its axis horizontal, along y),
    // friction 0.8 (it rolls without slipping: tan 20° ≪ 0.8·(1 + m·r²/I)), no rolling
    // resistance: its centre accelerates at g·sin α/(1 + I/(m·r²)), I its moment about its
    // axis, the union's (a sphere's 2/5 would give a different figure).
    let r = 1e-3;
    let alpha = 20f64.to_radians();
    let kind = ClumpKind::new(&ClumpTemplate::dimer(r).unwrap(), DENSITY);
    let ratio = kind.inertia.moments.x / (kind.inertia.mass * r * r);
    // 0.425 for this dimer: a sphere's 2/5 would roll 1.8 % farther than the tolerance below.
    assert!((ratio - 0.4).abs() > 0.02, "I/(m·r²) = {ratio}");
    let g = 9.81;
    let expected = g * alpha.sin() / (1.0 + ratio);
    // The incline is the floor, gravity turned by α about y.
    let mut p = law_of(0.8, e);
    p = p
        .with_gravity([g * alpha.sin(), 0.0, -g * alpha.cos()], 1e-3)
        .unwrap();
    let at = DVec3::new(0.02, 0.05, r);
    let run = dimer_run(
        at,
        DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
        Particles::default(),
    );
    let mut s = open(backend, run, p.clone());
    let steps = (time / p.dt as f64) as u32;
    s.advance(steps).unwrap();
    let t = steps as f64 * p.dt as f64;
    let end = s.particles().unwrap();
    let travel = end.clumps.clumps[0].body.position.x - at.x;
    let rolled = 0.5 * expected * t * t;
    assert!(
        (travel / rolled - 1.0).abs() < 0.003,
        "E {e:e}: travelled {travel} m, rolling says {rolled} m"
    );
    // It rolls: about y, at v/r.
    let body = end.clumps.clumps[0].body;
    let w = body.angular_velocity(&end.clumps.kinds[0].inertia);
    assert!(
        (w.y * r / body.velocity.x - 1.0).abs() < 0.003,
        "ω {w}, v {}",
        body.velocity
    );
}

#[test]
fn a_clump_file_places_each_clump_of_its_template_where_its_row_says() {
    use mochi::dem::scene::{Overrides, SceneConfig};
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("clumps.csv");
    // A bean (its spheres given about an origin that is not its centre), turned 90° about z,
    // moving, and a rod of three at rest.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    std::fs::write(
        &input,
        format!(
            "{}\n0.05,0.05,0.02,{s},0,0,{s},0.1,0,0,0,0,2,bean\n\n\
             0.03,0.04,0.01,1,0,0,0,0,0,0,0,0,0,rod 3\n",
            mochi::io::CLUMP_HEADER
        ),
    )
    .unwrap();
    let scene = format!(
        "scene = \"input\"\ninput = {:?}\n[[clump]]\nname = \"bean\"\n\
         spheres = [[0.001, 0, 0, 0.001], [0.0022, 0, 0, 0.0008]]\n\
         [[clump]]\nshape = \"rod\"\ncount = 3\nradius = 0.002\n",
        input.to_str().unwrap()
    );
    let config = SceneConfig::parse(Some(&scene), None, &Overrides::default()).unwrap();
    let start = config.build().unwrap();
    let p = &start.particles;
    assert_eq!(p.clumps.clumps.len(), 2);
    assert_eq!(p.len(), 5);
    // The bean's spheres where its row puts them: its origin at (0.05, 0.05, 0.02), its x
    // axis along y.
    let bean = [[0.05, 0.051, 0.02], [0.05, 0.0522, 0.02]];
    for (k, want) in bean.iter().enumerate() {
        let got = DVec3::from_array(p.exact_position(k));
        assert!(
            (got - DVec3::from_array(*want)).length() < 1e-12,
            "sphere {k}: {got}"
        );
        assert_eq!(p.radii[k], [0.001, 0.0008][k]);
    }
    // Its origin moves at 0.1 m/s along x and it turns at 2 rad/s about z: a sphere 1 mm out
    // along y moves at v − ω·1 mm along x.
    let v = p.velocities[0];
    assert!((v[0] as f64 - (0.1 - 2.0 * 0.001)).abs() < 1e-7, "{v:?}");
    // A rod of three spheres of its table's radius (at its own size: scaled by nothing).
    assert_eq!(p.radii[2..], [0.002; 3]);
    // An unknown template is refused naming it and the tables.
    std::fs::write(
        &input,
        format!(
            "{}\n0,0,0,1,0,0,0,0,0,0,0,0,0,pebble\n",
            mochi::io::CLUMP_HEADER
        ),
    )
    .unwrap();
    let e = config.build().map(|_| ()).unwrap_err().to_string();
    assert!(
        e.contains("\"pebble\"") && e.contains("\"bean\", \"rod 3\""),
        "{e}"
    );
    // A sphere file where a clump file is wanted, a bad row: one error each.
    std::fs::write(&input, "x,y,z,r\n0,0,0,1\n").unwrap();
    let e = config.build().map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("clump file"), "{e}");
    std::fs::write(
        &input,
        format!(
            "{}\n0,0,0,0,0,0,0,0,0,0,0,0,0,bean\n",
            mochi::io::CLUMP_HEADER
        ),
    )
    .unwrap();
    let e = config.build().map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("clumps.csv:2:") && e.contains("length 0"), "{e}");
}

#[test]
fn a_clump_table_gives_its_spheres_material_and_may_give_its_mass_and_inertia() {
    use mochi::dem::clump_spec::{ClumpConfig, ClumpMaker};
    use mochi::dem::material_spec::MaterialConfig;
    use mochi::dem::scene::{Overrides, SceneConfig};
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("clumps.csv");
    // A bean at rest, unturned, and a rod of three.
    std::fs::write(
        &input,
        format!(
            "{}\n0.05,0.05,0.02,1,0,0,0,0,0,0,0,0,0,bean\n\
             0.03,0.04,0.01,1,0,0,0,0,0,0,0,0,0,rod 3\n",
            mochi::io::CLUMP_HEADER
        ),
    )
    .unwrap();
    let materials = "[[materials]]\nname = \"glass\"\ndensity = 2500\n\
                     [[materials]]\nname = \"steel\"\ndensity = 7800\n";
    // The bean's own mass and inertia: the tensor's principal moments 2, 4 and 5 (×1e-11),
    // its axes (1, −1, 0), (1, 1, 0) and z; of steel. The rod of the first material.
    let bean = "[[clump]]\nname = \"bean\"\nspheres = [[0.001, 0, 0, 0.001], [0.0022, 0, 0, 0.0008]]\n\
                mass = 2e-5\ninertia = [3e-11, 3e-11, 5e-11, 1e-11, 0, 0]\nmaterial = \"steel\"\n";
    let rod = "[[clump]]\nshape = \"rod\"\ncount = 3\nradius = 0.002\n";
    let scene = format!(
        "scene = \"input\"\ninput = {:?}\n{materials}{bean}{rod}",
        input.to_str().unwrap()
    );
    let config = SceneConfig::parse(Some(&scene), None, &Overrides::default()).unwrap();
    let p = config.build().unwrap().particles;
    assert_eq!(p.materials, [1, 1, 0, 0, 0]);
    let kinds = &p.clumps.kinds;
    let inertia = kinds[0].inertia;
    assert_eq!(inertia.mass, 2e-5);
    let moments = inertia.moments / 1e-11;
    assert!(
        (moments - DVec3::new(2.0, 4.0, 5.0)).abs().max_element() < 1e-9,
        "{moments}"
    );
    // In its principal frame the bean's axis (x as given) lies along (1, ±1, 0).
    let axis = kinds[0].template.components[1].centre - kinds[0].template.components[0].centre;
    assert!(
        (axis.x.abs() - axis.y.abs()).abs() < 1e-12 && axis.z.abs() < 1e-12,
        "{axis}"
    );
    // Placed where its row says whatever its principal frame.
    for (k, x) in [0.051, 0.0522].into_iter().enumerate() {
        let got = DVec3::from_array(p.exact_position(k));
        assert!((got - DVec3::new(x, 0.05, 0.02)).length() < 1e-12, "{got}");
    }
    // The rod: its union's mass at the first material's density.
    let volume = ClumpTemplate::rod(3, 0.002)
        .unwrap()
        .mass_properties()
        .volume;
    assert!((kinds[1].inertia.mass / (2500.0 * volume) - 1.0).abs() < 1e-9);

    // Generated and inflowing clumps take their table's material and its density.
    let table = ClumpConfig {
        shape: Some("dimer".into()),
        material: Some("steel".into()),
        ..ClumpConfig::default()
    };
    let named = |name: &str| MaterialConfig {
        name: name.into(),
        ..MaterialConfig::default()
    };
    let maker = ClumpMaker::new(&[table], &[named("glass"), named("steel")]).unwrap();
    let mut rand = mochi::dem::clump_spec::clump_stream(1);
    let at = (DVec3::ZERO, 0.002f32, DVec3::ZERO);
    let (kind, _, material) = maker.make(&mut rand, at, 0, &[2500.0, 7800.0]);
    assert_eq!(material, 1);
    let volume = kind.template.mass_properties().volume;
    assert!((kind.inertia.mass / (7800.0 * volume) - 1.0).abs() < 1e-6);
}

#[test]
fn a_run_of_clumps_changes_its_friction_between_steps_but_not_its_density() {
    use mochi::dem::scene::Overrides;
    use mochi::engines::{BackendChoice, Options};
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    let text = "[source]\nscene = \"freefall\"\nspheres = 8\n[[clump]]\nshape = \"dimer\"\n";
    std::fs::write(&scene, text).unwrap();
    let none = Overrides::default();
    let start = mochi::run::RunStart::new(Some(&scene), &Default::default(), &none).unwrap();
    let mut run = start
        .open(BackendChoice::Named(BackendKind::Cpu), &Options::default())
        .unwrap();
    run.stepper.advance(10).unwrap();
    run.change(&Overrides::parse(&["friction=0.2"]).unwrap())
        .unwrap();
    let e = run
        .change(&Overrides::parse(&["density=5000"]).unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("clumps") && e.contains("density"), "{e}");
    // And the run goes on as it was.
    run.stepper.advance(10).unwrap();
    assert_eq!(run.stepper.particles().unwrap().clumps.clumps.len(), 8);
}

#[test]
fn clumps_drain_from_a_hopper_whole_through_its_outflow() {
    on_every_backend(|kind| {
        use mochi::dem::scene::{Overrides, SceneConfig};
        let text = "[source]\nscene = \"hopper\"\nspheres = 100\nopen = 0.01\nangle = 45\n\
                    orifice = 0.04\n[[clump]]\nshape = \"dimer\"\n";
        let config = SceneConfig::parse(Some(text), None, &Overrides::default()).unwrap();
        let start = config.build().unwrap();
        let mass = |set: &ClumpSet| -> f64 {
            set.clumps
                .iter()
                .map(|c| set.kinds[c.kind].inertia.mass)
                .sum()
        };
        let before = mass(&start.particles.clumps);
        let choice = mochi::engines::BackendChoice::Named(kind);
        let mut s = mochi::engines::open_scene(choice, start, &Default::default())
            .unwrap()
            .value;
        let mut left = 0;
        for _ in 0..24 {
            s.advance(500).unwrap();
            left = s.flow_counts().unwrap().removed;
            if left >= 3 {
                break;
            }
        }
        assert!(left >= 3, "{left} clumps left");
        let end = s.particles().unwrap();
        let set = &end.clumps;
        // Each left whole: its spheres with it, its mass counted once.
        assert_eq!(set.clumps.len() as u64, 100 - left);
        assert_eq!(end.len(), 2 * set.clumps.len());
        let counts = s.flow_counts().unwrap();
        let removed = before - mass(set);
        assert!(
            (counts.removed_mass / removed - 1.0).abs() < 1e-9,
            "{} kg counted, {removed} kg gone",
            counts.removed_mass
        );
        // The clumps that stay are where their spheres are.
        for (k, c) in set.components().iter().enumerate() {
            let off = (DVec3::from_array(end.exact_position(k)) - c.centre).length();
            assert!(off < placed_within(kind), "sphere {k} {off} m off");
        }
    });
}

#[test]
fn an_inflow_of_a_scene_with_clump_tables_pours_clumps_that_never_overlap_as_they_come() {
    on_every_backend(|kind| {
        use mochi::dem::scene::{Overrides, SceneConfig};
        // One trimer falling; trimers rain in from above at 4000 a second.
        let text = "[source]\nscene = \"freefall\"\nspheres = 1\n[[clump]]\nshape = \"trimer\"\n\
                    [[inflow]]\nlo = [0.05, 0.05, 0.25]\nhi = [0.25, 0.25, 0.3]\nrate = 4000\n\
                    sphere_radius = 0.004\n[run]\nflow_every = 100\n";
        let config = SceneConfig::parse(Some(text), None, &Overrides::default()).unwrap();
        let start = config.build().unwrap();
        let dt = start.params.dt as f64;
        let choice = mochi::engines::BackendChoice::Named(kind);
        let mut s = mochi::engines::open_scene(choice, start, &Default::default())
            .unwrap()
            .value;
        let steps = (0.01 / dt) as u32 / 100 * 100;
        s.advance(steps).unwrap();
        let counts = s.flow_counts().unwrap();
        let end = s.particles().unwrap();
        let set = &end.clumps;
        assert!(counts.inserted >= 20, "{} inserted", counts.inserted);
        // Every inserted sphere a clump of three spheres, after the first clump's.
        assert_eq!(set.clumps.len() as u64, 1 + counts.inserted);
        assert_eq!(end.len(), 3 * set.clumps.len());
        assert!(set.kinds.iter().all(|k| k.template.name == "trimer"));
        let mass: f64 = set.clumps[1..]
            .iter()
            .map(|c| set.kinds[c.kind].inertia.mass)
            .sum();
        assert!(
            (counts.inserted_mass / mass - 1.0).abs() < 1e-9,
            "{} kg counted, {mass} kg in",
            counts.inserted_mass
        );
        // Falling in their own time, apart: no two clumps touch yet (each came where its
        // bounding sphere overlapped nothing).
        assert_eq!(s.advance(1).unwrap().contacts, 0);
        for (k, c) in set.components().iter().enumerate() {
            let off = (DVec3::from_array(end.exact_position(k)) - c.centre).length();
            assert!(off < placed_within(kind), "sphere {k} {off} m off");
        }
    });
}
