//! Several materials in one scene (docs/method.md, "Several materials"), as whole steps on every
//! backend against the analytic impacts: spheres of two materials meeting head-on last as long
//! as Hertz says with the mixed E* (1/E* = (1 − ν_a²)/E_a + (1 − ν_b²)/E_b), leave with the
//! velocities their masses and the pair's restitution give (the smaller of the two, or the
//! pair's own), and a sphere of one material on a floor of another rebounds and slides as
//! that pair's restitution and friction say.

mod common;

use common::{on_every_backend, particles};
use mochi::dem::model::time_step::hertz_contact_time;
use mochi::dem::model::{ContactLaw, Material, Materials, PairOverride, mass};
use mochi::dem::{Particles, StepParams, Stepper};
use mochi::engines::BackendKind;

/// Steps per elastic contact: semi-implicit Euler's error, O(dt/t_c), is then a quarter of a
/// percent.
const STEPS: f64 = 400.0;

/// A Hertz–Mindlin material: E \[Pa\], ν, density \[kg/m³\], restitution, friction.
fn solid(young: f64, poisson: f64, density: f64, e: f64, mu: f64) -> Material {
    Material {
        density,
        restitution: e,
        contact: ContactLaw::HertzMindlin {
            young_modulus: young,
            poisson_ratio: poisson,
        },
        friction: mu,
        rolling_friction: 0.0,
        ..Material::default()
    }
}

/// Glass (E 4.8e10 Pa, ν 0.2, 2800 kg/m³) and steel (2.08e11 Pa, 0.3, 7850 kg/m³), Chung & Ooi's.
fn glass(e: f64, mu: f64) -> Material {
    solid(4.8e10, 0.20, 2800.0, e, mu)
}

fn steel(e: f64, mu: f64) -> Material {
    solid(2.08e11, 0.30, 7850.0, e, mu)
}

fn nylon(e: f64, mu: f64) -> Material {
    solid(2.5e9, 0.40, 1000.0, e, mu)
}

/// E* of two bodies of materials `a` and `b` (`b` `None`: a rigid wall).
fn e_star(a: &Material, b: Option<&Material>) -> f64 {
    let compliance = |m: &Material| match m.contact {
        ContactLaw::HertzMindlin {
            young_modulus,
            poisson_ratio,
        } => (1.0 - poisson_ratio * poisson_ratio) / young_modulus,
        _ => unreachable!("Hertz–Mindlin materials only"),
    };
    1.0 / (compliance(a) + b.map_or(0.0, compliance))
}

fn materials(list: Vec<Material>, pairs: Vec<PairOverride>) -> Materials {
    Materials {
        names: (0..list.len()).map(|k| format!("m{k}")).collect(),
        list,
        pairs,
    }
}

fn open(kind: BackendKind, p: &Particles, params: StepParams) -> Box<dyn Stepper> {
    common::open_dem_shared(kind, p, params)
}

/// One head-on pair of a [`head_on`] run: sphere a (material `a`, radius `r_a`) moving along +x
/// towards sphere b (material `b`, radius `r_b`).
struct Pair {
    a: u8,
    b: u8,
    r_a: f32,
    r_b: f32,
}

#[test]
fn spheres_of_two_materials_meet_head_on_as_hertz_says_with_their_mixed_moduli() {
    // Three pairs of glass (r 10 mm) on steel (r 5 mm, 2.8 times denser), closing at 1 m/s
    // (each 0.5 m/s towards the other), in one stepper of six materials: elastic (e 1 both),
    // at the smaller restitution of the two (0.9 and 0.7 → 0.7), and at a pair's own (0.6,
    // where the two say 0.95 and 0.9). The second pair's glass is sphere b, so the table is read
    // both ways.
    let list = vec![
        glass(1.0, 0.0),
        steel(1.0, 0.0),
        glass(0.9, 0.0),
        steel(0.7, 0.0),
        glass(0.95, 0.0),
        steel(0.9, 0.0),
    ];
    let given = PairOverride {
        a: 5,
        b: 4,
        restitution: Some(0.6),
        ..PairOverride::default()
    };
    let set = materials(list.clone(), vec![given]);
    let pairs = [
        (
            Pair {
                a: 0,
                b: 1,
                r_a: 0.01,
                r_b: 0.005,
            },
            1.0,
        ),
        (
            Pair {
                a: 3,
                b: 2,
                r_a: 0.005,
                r_b: 0.01,
            },
            0.7,
        ),
        (
            Pair {
                a: 4,
                b: 5,
                r_a: 0.01,
                r_b: 0.005,
            },
            0.6,
        ),
    ];
    let m = |material: u8, r: f32| mass(list[material as usize].density as f32, r) as f64;
    let (v, r_min) = (1.0, 0.005f32);
    let elastic = &pairs[0].0;
    let (m_a, m_b) = (m(elastic.a, elastic.r_a), m(elastic.b, elastic.r_b));
    let m_eff = m_a * m_b / (m_a + m_b);
    let r_eff = (elastic.r_a * elastic.r_b / (elastic.r_a + elastic.r_b)) as f64;
    let e_mixed = e_star(&list[0], Some(&list[1]));
    let t_c = hertz_contact_time(m_eff, r_eff, e_mixed, v);
    let dt = t_c / STEPS;
    // Each pair first overlaps half a step in; along y 5 cm apart.
    let gap = 0.5 * v * dt;
    let mut start = particles(Vec::new(), Vec::new(), Vec::new());
    for (k, (p, _)) in pairs.iter().enumerate() {
        let y = 0.05 * (k + 1) as f64;
        let x_a = -(p.r_a as f64 + gap / 2.0);
        let x_b = p.r_b as f64 + gap / 2.0;
        start.positions.push([x_a as f32, y as f32, 0.05]);
        start.positions.push([x_b as f32, y as f32, 0.05]);
        start.velocities.push([(v / 2.0) as f32, 0.0, 0.0]);
        start.velocities.push([-(v / 2.0) as f32, 0.0, 0.0]);
        start.radii.extend([p.r_a, p.r_b]);
        start.materials.extend([p.a, p.b]);
    }
    start.angular_velocities = vec![[0.0; 3]; start.radii.len()];
    let steps = (1.3 * STEPS) as u32;
    let reach = 0.03 + v * dt * steps as f64;
    let params = StepParams::with_materials(
        &set,
        None,
        dt,
        [-reach, 0.0, 0.0],
        [reach, 0.25, 0.1],
        [0.0; 3],
        0.0,
        r_min,
    )
    .unwrap();
    on_every_backend(|kind| {
        let mut s = open(kind, &start, params.clone());
        s.advance(steps).unwrap();
        let end = s.particles().unwrap();
        assert_eq!(
            end.materials, start.materials,
            "each sphere keeps its material"
        );
        for (k, (p, e)) in pairs.iter().enumerate() {
            let (i, j) = (2 * k, 2 * k + 1);
            let (m_a, m_b) = (m(p.a, p.r_a), m(p.b, p.r_b));
            let (u_a, u_b) = (end.velocities[i][0] as f64, end.velocities[j][0] as f64);
            let what = format!("pair {k} (e {e})");
            // Newton's law of restitution with momentum: the velocity changes are
            // (1 + e)·v·m_b/(m_a + m_b) and (1 + e)·v·m_a/(m_a + m_b), within O(dt/t_c).
            let want_a = v / 2.0 - (1.0 + e) * v * m_b / (m_a + m_b);
            let want_b = -v / 2.0 + (1.0 + e) * v * m_a / (m_a + m_b);
            assert!(
                (u_a - want_a).abs() <= 2.5e-3 * v && (u_b - want_b).abs() <= 2.5e-3 * v,
                "{what}: left at {u_a} and {u_b} m/s, Newton's law says {want_a} and {want_b}"
            );
            let momentum = m_a * u_a + m_b * u_b;
            let before = m_a * v / 2.0 - m_b * v / 2.0;
            assert!(
                (momentum - before).abs() <= 1e-5 * (m_a + m_b) * v,
                "{what}: momentum {momentum:e} kg·m/s, {before:e} before"
            );
            let gap =
                end.positions[j][0] as f64 - end.positions[i][0] as f64 - (p.r_a + p.r_b) as f64;
            assert!(gap > 0.0, "{what}: still in contact after {steps} steps");
            if *e == 1.0 {
                // Parted at u_b − u_a since the contact ended: the duration from the gap.
                let parted = steps as f64 * dt - gap / (u_b - u_a);
                let duration = parted - 0.5 * dt;
                assert!(
                    (duration - t_c).abs() <= 2.0 * dt + 1e-3 * t_c,
                    "{what}: lasted {duration:e} s, Hertz with the mixed E* {t_c:e} s"
                );
                // Glass on glass would last (2^(2/5)) 1.3 times as long as with the mixed
                // E* of glass and steel: the duration tells the moduli apart.
                let glass_only =
                    hertz_contact_time(m_eff, r_eff, e_star(&list[0], Some(&list[0])), v);
                assert!(glass_only > 1.2 * t_c);
            }
        }
    });
}

#[test]
fn a_sphere_of_one_material_rebounds_and_slides_on_a_floor_of_another_as_the_pair_says() {
    // The box is steel (box_material); glass, steel and nylon spheres all elastic, friction
    // 0.5, but the pair nylon–steel has its own restitution 0.6 and friction 0.2. A glass
    // sphere (r 10 mm) falls on the floor at 0.5 m/s: Hertz with glass's and steel's E*, and an
    // elastic rebound; a nylon sphere the same way rebounds at 0.6; a nylon sphere striking at
    // 0.5 m/s while sliding at 2 m/s (far into gross sliding, x = 2/(0.2·0.5) = 20) takes a
    // tangential impulse μ·(1 + e)·m·v_n with μ = 0.2 (the mixing rule would give 0.5).
    let list = vec![glass(1.0, 0.5), steel(1.0, 0.5), nylon(1.0, 0.5)];
    let given = PairOverride {
        a: 2,
        b: 1,
        restitution: Some(0.6),
        friction: Some(0.2),
        ..PairOverride::default()
    };
    let set = materials(list.clone(), vec![given]);
    let (r, v_n, v_t) = (0.01f32, 0.5, 2.0);
    let m = |material: usize| mass(list[material].density as f32, r) as f64;
    let e_mixed = e_star(&list[0], Some(&list[1]));
    let t_c = hertz_contact_time(m(0), r as f64, e_mixed, v_n);
    // The nylon's contacts are the longest: time them by glass's, and run long enough for
    // nylon's.
    let t_nylon = hertz_contact_time(m(2), r as f64, e_star(&list[2], Some(&list[1])), v_n);
    let dt = t_c / STEPS;
    let steps = (1.3 * t_nylon / dt) as u32 + 10;
    let incoming = [(0u8, 0.0), (2, 0.0), (2, v_t)];
    let mut start = particles(Vec::new(), Vec::new(), Vec::new());
    for (k, &(material, slide)) in incoming.iter().enumerate() {
        let z = r as f64 + 0.5 * v_n * dt;
        start
            .positions
            .push([0.05, 0.05 * (k + 1) as f32, z as f32]);
        start.velocities.push([slide as f32, 0.0, -v_n as f32]);
        start.radii.push(r);
        start.materials.push(material);
    }
    start.angular_velocities = vec![[0.0; 3]; 3];
    let reach = 0.1 + v_t * dt * steps as f64;
    let params = StepParams::with_materials(
        &set,
        Some(1),
        dt,
        [-reach, 0.0, 0.0],
        [reach, 0.2, 0.2],
        [0.0; 3],
        0.0,
        r,
    )
    .unwrap();
    on_every_backend(|kind| {
        let mut s = open(kind, &start, params.clone());
        s.advance(steps).unwrap();
        let end = s.particles().unwrap();
        let rebound = |k: usize| end.velocities[k][2] as f64 / v_n;
        // Glass: elastic, and the duration from the height it has risen since it parted.
        assert!(
            (rebound(0) - 1.0).abs() <= 2.5e-3,
            "glass rebounds at {}",
            rebound(0)
        );
        let risen = end.positions[0][2] as f64 - r as f64;
        let duration = steps as f64 * dt - risen / end.velocities[0][2] as f64 - 0.5 * dt;
        assert!(
            (duration - t_c).abs() <= 2.0 * dt + 1e-3 * t_c,
            "glass on steel lasted {duration:e} s, Hertz with the mixed E* {t_c:e} s"
        );
        // Nylon on steel: the pair's restitution.
        for k in [1, 2] {
            assert!(
                (rebound(k) - 0.6).abs() <= 2.5e-3,
                "nylon {k} rebounds at {}, the pair's restitution is 0.6",
                rebound(k)
            );
        }
        // Gross sliding: J = μ·(1 + e′)·m·v_n, e′ the rebound measured.
        let impulse = (v_t - end.velocities[2][0] as f64) * m(2);
        let want = 0.2 * (1.0 + rebound(2)) * m(2) * v_n;
        assert!(
            (impulse / want - 1.0).abs() <= 1e-3,
            "the sliding nylon took {impulse:e} N·s, Coulomb with the pair's μ 0.2 says {want:e}"
        );
    });
}
