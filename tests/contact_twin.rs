//! The GPU engines' copies of the contact law compute the bits of `src/dem/model/contact.rs` on
//! a table of random contacts of every law and rolling model: a sphere pair from one side, the
//! partner's share as the partner's own side computes it (what the GPU's owner gives the
//! partner), the six walls with their springs and a moving surface (a mesh wall's contact); at
//! the size of the tests' spheres and at nanometres, where the products of masses, moments of
//! inertia and torques underflow f32. Each case carries its material table (one material, or
//! three that differ in E, ν, density, restitution, friction and rolling friction, with a pair
//! of its own), its spheres' materials and the walls' columns (a material's or rigid); the
//! Mindlin–Deresiewicz law has cases of its own (springs with a load history, on the virgin
//! curve and after a reversal, sticking and sliding). Two twins run the same cases:
//!
//! - The optix step's law, `optix/contact.cuh`, compiled as host C++ (`tests/contact_twin.cpp`
//!   supplies CUDA's vector types; no fused multiply-adds, as NVRTC compiles it for the GPU),
//!   again with `MOCHI_LOAD_HISTORY` for Mindlin–Deresiewicz. Needs a C++17 compiler (`c++`)
//!   and no GPU; skips with a note without one (CI has one).
//! - The wgpu steps' law, `wgsl/dem/dem_contact.wgsl` after `wgsl/dem/dem_params.wgsl` and a tangential
//!   model (`wgsl/dem/dem_tangential_mindlin.wgsl` or `wgsl/dem/dem_tangential_md.wgsl`), composed as
//!   the engines compose it, with a test kernel appended that calls the law on each case as the
//!   step's kernels call it (`contact_with` and `finish` of `wgsl/dem/dem_granular.wgsl`,
//!   `wall_contacts` of `wgsl/dem/dem_mesh_walls.wgsl`); and the paper's frictionless linear law of
//!   `wgsl/dem/dem_physics.wgsl` (`contact_force`, `wall_force`; one stiffness, or one per pair
//!   with its `PER_PAIR` constant) on the cases of one frictionless linear material, which the
//!   Rust law computes with the same operations.
//!
//! Values are compared bit for bit, ±0 equal. For the WGSL that takes two conditions. Its
//! operations must run as written: Vulkan lets a driver fuse (a·b + c into one fused
//! multiply-add) or reorder (reassociate sums) any floating-point operation that the SPIR-V does
//! not decorate NoContraction, which WGSL cannot ask for, and Mesa's compiler reassociates sums:
//! the SPIR-V wgpu makes of the law gives lavapipe other bits in 1436 of the 2000 one-material
//! cases with friction. So the kernels run as SPIR-V that naga translates from the WGSL with
//! every floating-point operation decorated NoContraction ([`exact_spirv`]), passed to the
//! driver as it is. And the adapter must round every operation as IEEE 754 does, as Rust does:
//! lavapipe (LLVM's operations on the CPU) does, while Vulkan lets division and square root be
//! off by a few ulp, which the law's cancellations (the overlap r_i + r_j − |d|, the push
//! F_el − c·v_n) amplify without bound: on an H200, 58 values of 10 000 cases differed from
//! the Rust law's by more than 10⁻⁴ of their vector's largest component, the largest by 8%, so
//! no tolerance is both tight and safe there. The WGSL twin therefore runs on lavapipe alone;
//! without it, it says so, and under `CI=true` (which has it) it fails.

mod common;

use glam::Vec3;
use mochi::dem::model::contact::{
    Body, Contact, Kept, LoadedSprings, Springs, WALLS, WallContacts, pair_contact,
    surface_contact, wall_contacts,
};
use mochi::dem::model::{
    ContactLaw, LiquidBridge, Material, Materials, NormalLaw, PairLaw, PairOverride, RollingModel,
    StepParams, TangentialModel, mass,
};
use mochi::gpu::shader::{Binding, BindingKind};
use naga::proc::Layouter;
use naga::{AddressSpace, Handle, Type, TypeInner, VectorSize};
use std::fmt::Write;
use std::path::Path;
use std::process::{Command, Stdio};
use wgpu::util::DeviceExt;

const DENSITY: f64 = 2500.0;

// ----------------------------------------------------------------------------------------------
// The cases, shared by both twins
// ----------------------------------------------------------------------------------------------

/// What a case keeps of a contact.
trait Twin: Kept {
    /// The names and sizes of its values, in the order of [`Twin::words`].
    const PARTS: &[(&str, usize)];
    /// `wgsl/dem_tangential_*.wgsl` of its model.
    const TANGENTIAL: &str;
    /// How the WGSL test kernel reads its `Springs` (`springs_at`, from `SPRINGS_WORDS` words)
    /// and writes them (`put_springs`), in the order of [`Twin::words`].
    const KERNEL_IO: &str;
    /// Its values: tangential, rolling (and under Mindlin–Deresiewicz the reversal and the
    /// normal force), the members of the WGSL `Springs` in their order.
    fn words(&self) -> Vec<f32>;
    /// Springs a contact of spheres at `scale` may have kept.
    fn old(scale: f32, rand: &mut impl FnMut() -> f32) -> Self;
    /// What the cases keep of wall `w`: (w, w, w)·1e-6 and the rolling one their negative
    /// (under Mindlin–Deresiewicz the reversal (w, −w, w)·1e-6 and the normal force w·1e-6).
    fn of_wall(w: u32) -> Self;

    /// Its values as the CUDA case table writes them.
    fn section(&self) -> String {
        let words: Vec<String> = self.words().into_iter().map(bits).collect();
        words.join(" ")
    }
}

impl Twin for Springs {
    const PARTS: &[(&str, usize)] = &[("tangential spring", 3), ("rolling spring", 3)];
    const TANGENTIAL: &str = include_str!("../wgsl/dem/dem_tangential_mindlin.wgsl");
    const KERNEL_IO: &str = "
const SPRINGS_WORDS: u32 = 6u;
fn springs_at(k: u32) -> Springs {
    return Springs(vec_at(k), vec_at(k + 3u));
}
fn put_springs(s: Springs) {
    put3(s.tangential);
    put3(s.rolling);
}
";

    fn words(&self) -> Vec<f32> {
        [self.tangential, self.rolling]
            .iter()
            .flat_map(|v| v.to_array())
            .collect()
    }

    fn old(scale: f32, rand: &mut impl FnMut() -> f32) -> Self {
        Springs {
            tangential: 1e-5 * scale * Vec3::new(rand(), rand(), rand()),
            rolling: 1e-5 * scale.powi(3) * Vec3::new(rand(), rand(), rand()),
        }
    }

    fn of_wall(w: u32) -> Self {
        let x = w as f32 * 1e-6;
        Springs {
            tangential: Vec3::splat(x),
            rolling: Vec3::splat(-x),
        }
    }
}

impl Twin for LoadedSprings {
    const PARTS: &[(&str, usize)] = &[
        ("tangential spring", 3),
        ("rolling spring", 3),
        ("reversal", 3),
        ("normal force kept", 1),
    ];
    const TANGENTIAL: &str = include_str!("../wgsl/dem/dem_tangential_md.wgsl");
    const KERNEL_IO: &str = "
const SPRINGS_WORDS: u32 = 10u;
fn springs_at(k: u32) -> Springs {
    return Springs(vec_at(k), vec_at(k + 3u), vec_at(k + 6u), cases[k + 9u]);
}
fn put_springs(s: Springs) {
    put3(s.tangential);
    put3(s.rolling);
    put3(s.reversal);
    put(s.normal);
}
";

    fn words(&self) -> Vec<f32> {
        let mut words = self.springs.words();
        words.extend(self.reversal.to_array());
        words.push(self.normal);
        words
    }

    fn old(scale: f32, rand: &mut impl FnMut() -> f32) -> Self {
        // Forces of the size of these contacts' (about a newton at scale 1, as the square of the
        // lengths below), on the virgin curve in half the cases.
        let force = scale * scale;
        let reversed = rand() > 0.0;
        LoadedSprings {
            springs: Springs {
                tangential: 0.5 * force * Vec3::new(rand(), rand(), rand()),
                rolling: 1e-5 * scale.powi(3) * Vec3::new(rand(), rand(), rand()),
            },
            reversal: match reversed {
                true => 0.5 * force * Vec3::new(rand(), rand(), rand()),
                false => Vec3::ZERO,
            },
            normal: 2.0 * force * rand().abs(),
        }
    }

    fn of_wall(w: u32) -> Self {
        let x = w as f32 * 1e-6;
        LoadedSprings {
            springs: Springs::of_wall(w),
            reversal: Vec3::new(x, -x, x),
            normal: x,
        }
    }
}

/// One contact case: the step's parameters (with the box walls' column of its own), two spheres
/// about touching with the springs `i` kept of their contact, and `i` on a surface.
struct Case<S> {
    p: StepParams,
    i: Body,
    j: Body,
    old: S,
    /// The surface: the unit normal from i's centre, the overlap, the velocity of its point at
    /// the contact, its column of the material table and its own friction (`None`: the pair's).
    n: Vec3,
    overlap: f32,
    moving: Vec3,
    column: u32,
    given: Option<f32>,
    /// Whether the pair was in contact at the last step (a cohesive pair may hold past touching
    /// then); the box walls always were.
    bonded: bool,
}

/// What the Rust law computes of a case.
struct Expected<S> {
    /// The pair from i's side and from j's (given the negated springs).
    from_i: Option<Contact<S>>,
    from_j: Option<Contact<S>>,
    walls: WallContacts,
    /// The springs kept of each touching wall, in order.
    kept: Vec<(u32, S)>,
    surface: Contact<S>,
}

impl<S: Twin> Case<S> {
    fn expected(&self) -> Expected<S> {
        let mut kept = Vec::new();
        let walls = wall_contacts(
            &self.p,
            &self.i,
            |w| (S::of_wall(w), true),
            |w, s| kept.push((w, s)),
            |_, _, _, _| {},
        );
        Expected {
            from_i: pair_contact(&self.p, &self.i, &self.j, self.old, self.bonded),
            from_j: pair_contact(&self.p, &self.j, &self.i, self.old.negated(), self.bonded),
            walls,
            kept,
            surface: surface_contact(
                &self.p,
                &self.i,
                self.n,
                self.overlap,
                self.moving,
                self.column,
                self.given,
                self.old,
            ),
        }
    }
}

/// 200 cases of `materials`: pairs of random materials at about touching distance (some apart),
/// spinning, with old springs, near the walls of a 0.1 m box of a random column (a material's
/// or rigid), and a sphere on a moving surface of a random column, with its own friction in a
/// third of the cases; all of it scaled by `scale` (lengths and times, velocities kept: spins
/// by 1/scale, rolling springs by scale³).
fn cases<S: Twin>(
    materials: &Materials,
    dt: f64,
    scale: f32,
    rand: &mut impl FnMut() -> f32,
    out: &mut Vec<Case<S>>,
) {
    let s = scale as f64;
    let p = StepParams::with_materials(
        materials,
        None,
        dt * s,
        [0.0; 3],
        [0.1 * s; 3],
        [0.0, 0.0, -9.81 / s],
        0.0,
        0.004 * scale,
    )
    .unwrap();
    assert_eq!(p.friction.tangential_model, S::MODEL);
    let count = materials.list.len();
    let pick = |rand: &mut dyn FnMut() -> f32, of: usize| {
        (((rand() + 0.5) * of as f32) as usize).min(of - 1) as u32
    };
    let body = |c: Vec3, rand: &mut dyn FnMut() -> f32| {
        let r = (0.005 + 0.002 * rand()) * scale;
        let v = Vec3::new(rand(), rand(), rand());
        let w = 50.0 / scale * Vec3::new(rand(), rand(), rand());
        let material = pick(rand, count);
        Body {
            c,
            v,
            w,
            r,
            m: mass(materials.list[material as usize].density as f32, r),
            material,
        }
    };
    for _ in 0..200 {
        // The box's walls and the surface: a material's, or rigid (column `count`).
        let p = StepParams {
            box_column: pick(rand, count + 1),
            ..p.clone()
        };
        let c = Vec3::new(rand(), rand(), rand()) * 0.1 + Vec3::splat(0.05);
        let c = c.clamp(Vec3::splat(0.003), Vec3::splat(0.097)) * scale;
        let i = body(c, rand);
        let towards = Vec3::new(rand(), rand(), rand()).normalize();
        let at = i.c + towards * ((0.0095 + 0.002 * rand()) * scale);
        let j = body(at, rand);
        let old = S::old(scale, rand);
        let n = Vec3::new(rand(), rand(), rand()).normalize();
        let overlap = i.r * (0.001 + 0.01 * (rand() + 0.5));
        let moving = 0.5 * Vec3::new(rand(), rand(), rand());
        let column = pick(rand, count + 1);
        let given = (rand() < -0.2).then(|| rand() + 0.5);
        out.push(Case {
            p,
            i,
            j,
            old,
            n,
            overlap,
            moving,
            column,
            given,
            bonded: false,
        });
    }
}

/// `cases` made cohesive ones: in most, the pair at a gap from a third of `margin` deep to
/// 1.2 times it apart (the margin: how far past touching its contacts may hold), most of them
/// bonded; the sphere at such a gap from a random box wall and the surface at such an overlap.
fn near_misses<S: Twin>(cases: &mut [Case<S>], rand: &mut impl FnMut() -> f32) {
    for case in cases {
        let margin = case.p.reach_margin(case.i.r.max(case.j.r));
        let gap = |rand: &mut dyn FnMut() -> f32| margin * (1.5 * rand() + 0.45);
        case.bonded = rand() < 0.3;
        if rand() < -0.2 {
            continue;
        }
        let axis = (((rand() + 0.5) * 3.0) as usize).min(2);
        case.i.c[axis] = case.p.box_lo[axis] + case.i.r + gap(rand);
        let towards = (case.j.c - case.i.c).normalize();
        case.j.c = case.i.c + towards * (case.i.r + case.j.r + gap(rand));
        case.overlap = -gap(rand);
    }
}

/// Asserts that most of `cases` touch (the rest check that apart is apart).
fn assert_most_touch<S: Twin>(cases: &[Case<S>]) {
    let touching = cases
        .iter()
        .filter(|c| pair_contact(&c.p, &c.i, &c.j, c.old, false).is_some())
        .count();
    let count = cases.len();
    assert!(
        touching > count / 2,
        "only {touching} of {count} cases touch"
    );
}

/// Cases of one material under every law and rolling model, with and without friction.
fn one_material_cases() -> Vec<Case<Springs>> {
    let mut rand = common::noise(3);
    let hertz = ContactLaw::HertzMindlin {
        young_modulus: 1e7,
        poisson_ratio: 0.3,
    };
    let per_pair = ContactLaw::LinearPerPair {
        contact_time: Some(1e-4),
    };
    let materials = [
        (hertz, 0.5, 0.1, RollingModel::Epsd, 1e-6),
        (hertz, 0.3, 0.05, RollingModel::ConstantTorque, 1e-6),
        (hertz, 0.0, 0.0, RollingModel::Epsd, 1e-6),
        (per_pair, 0.4, 0.1, RollingModel::Epsd, 1e-6),
        (
            ContactLaw::Linear,
            0.4,
            0.1,
            RollingModel::ConstantTorque,
            1e-5,
        ),
        (ContactLaw::Linear, 0.0, 0.1, RollingModel::Epsd, 1e-5),
        (per_pair, 0.0, 0.0, RollingModel::Epsd, 1e-6),
        (ContactLaw::Linear, 0.0, 0.0, RollingModel::Epsd, 1e-5),
    ];
    // At the tests' size; at radii of about 1e-8 m (above the smallest that turns, 5.6e-9 m at
    // this density); and without friction at about 2e-12 m.
    let mut out = Vec::new();
    for scale in [1.0, 2e-6, 4e-10] {
        for (contact, mu, mu_r, rolling_model, dt) in materials {
            let turns = mu > 0.0 || mu_r > 0.0;
            if scale < 1e-9 && turns {
                continue;
            }
            let material = Material {
                density: DENSITY,
                contact: scaled(contact, scale),
                friction: mu,
                rolling_friction: mu_r,
                rolling_model,
                ..Material::default()
            };
            cases(&Materials::one(material), dt, scale, &mut rand, &mut out);
        }
    }
    assert_most_touch(&out);
    out
}

/// Cases of the Mindlin–Deresiewicz law of one material: the sliding coefficient, with the
/// walls, the rolling resistance and the damping such that some slide and others stick; a
/// reversal point in half of them.
fn loaded_cases() -> Vec<Case<LoadedSprings>> {
    let mut rand = common::noise(5);
    let hertz = ContactLaw::HertzMindlin {
        young_modulus: 1e7,
        poisson_ratio: 0.3,
    };
    let materials = [
        (0.5, None, 0.1, RollingModel::Epsd, 0.5),
        (0.3, Some(0.1), 0.05, RollingModel::ConstantTorque, 0.9),
        (2.0, Some(0.0), 0.0, RollingModel::Epsd, 1.0),
        (0.0, Some(0.4), 0.0, RollingModel::Epsd, 0.7),
    ];
    let mut out = Vec::new();
    for scale in [1.0, 2e-6] {
        for (mu, wall_mu, mu_r, rolling_model, restitution) in materials {
            let material = Material {
                density: DENSITY,
                restitution,
                contact: hertz,
                friction: mu,
                wall_friction: wall_mu,
                rolling_friction: mu_r,
                rolling_model,
                tangential_model: TangentialModel::MindlinDeresiewicz,
                ..Material::default()
            };
            cases(&Materials::one(material), 1e-6, scale, &mut rand, &mut out);
        }
    }
    assert_most_touch(&out);
    out
}

/// Cases of cohesive materials of `S`'s tangential model: JKR (Γ of its own for a pair of
/// materials), liquid bridges (a contact angle of its own for a pair; with and without a
/// viscosity) and the simplified JKR, under Hertz–Mindlin with and without friction and rolling
/// resistance, and (Mindlin's spring) bridges and the simplified JKR under the linear laws; at
/// the tests' size and at radii of about 1e-8 m.
fn cohesive_cases<S: Twin>(seed: u64) -> Vec<Case<S>> {
    let mut rand = common::noise(seed);
    let hertz = ContactLaw::HertzMindlin {
        young_modulus: 1e7,
        poisson_ratio: 0.3,
    };
    let per_pair = ContactLaw::LinearPerPair {
        contact_time: Some(1e-4),
    };
    let bridge_of = |scale: f32, viscosity: f64| {
        Some(LiquidBridge {
            volume: 1e-9 * (scale as f64).powi(3),
            surface_tension: 0.072,
            contact_angle: 0.3,
            viscosity,
        })
    };
    let bridge = |scale: f32| bridge_of(scale, 0.0);
    // A viscous liquid: the bridges' lubrication force too (its viscosity scaled with the size,
    // so that the time step stays within the drag's limit, `drag_dt_limit`).
    let viscous = |scale: f32| bridge_of(scale, 0.1 * scale as f64);
    let mut out = Vec::new();
    for scale in [1.0f32, 2e-6] {
        let kinds = [
            (hertz, 0.5, None, 0.0),
            (hertz, 0.05, None, 0.0),
            (hertz, 0.0, bridge(scale), 0.0),
            (hertz, 0.0, viscous(scale), 0.0),
            (hertz, 0.0, None, 1e5),
            (per_pair, 0.0, bridge(scale), 0.0),
            (per_pair, 0.0, viscous(scale), 0.0),
            (ContactLaw::Linear, 0.0, None, 1e5),
        ];
        for (contact, adhesion, bridge, cohesion_density) in kinds {
            let hertz = matches!(contact, ContactLaw::HertzMindlin { .. });
            if S::MODEL == TangentialModel::MindlinDeresiewicz && !hertz {
                continue;
            }
            for (mu, mu_r, rolling_model) in [
                (0.5, 0.1, RollingModel::Epsd),
                (0.3, 0.05, RollingModel::ConstantTorque),
                (0.0, 0.0, RollingModel::Epsd),
            ] {
                let material = |k: usize| Material {
                    density: [DENSITY, 1200.0][k],
                    contact: match contact {
                        ContactLaw::HertzMindlin { .. } => ContactLaw::HertzMindlin {
                            young_modulus: [1e7, 4e7][k],
                            poisson_ratio: 0.3,
                        },
                        other => scaled(other, scale),
                    },
                    friction: mu,
                    rolling_friction: mu_r,
                    rolling_model,
                    tangential_model: S::MODEL,
                    adhesion: [adhesion, 2.0 * adhesion][k],
                    // The second material wets less: its pairs' bridges pull less and
                    // rupture farther.
                    bridge: bridge.map(|b| LiquidBridge {
                        contact_angle: [b.contact_angle, 1.2][k],
                        ..b
                    }),
                    cohesion_density,
                    ..Material::default()
                };
                // One material, or two whose pair adheres with a Γ and wets with a contact angle
                // of its own.
                let two = Materials {
                    list: vec![material(0), material(1)],
                    names: ["a", "b"].map(String::from).to_vec(),
                    pairs: Vec::new(),
                };
                let first = out.len();
                for materials in [Materials::one(material(0)), two] {
                    cases(&materials, 1e-6, scale, &mut rand, &mut out);
                }
                near_misses(&mut out[first..], &mut rand);
            }
        }
    }
    assert!(out.iter().all(|c| c.p.adheres()));
    let held = out.iter().filter(|c| {
        let gap = c.j.c.distance(c.i.c) - c.i.r - c.j.r;
        gap > 0.0 && pair_contact(&c.p, &c.i, &c.j, c.old, c.bonded).is_some()
    });
    assert!(held.count() > out.len() / 10, "pairs held past touching");
    let contacts = out
        .iter()
        .filter(|c| pair_contact(&c.p, &c.i, &c.j, c.old, c.bonded).is_some());
    assert!(contacts.count() > out.len() / 3, "contacts");
    out
}

/// Cases of [`three_materials`] under every law and rolling model, with and without friction
/// (Mindlin's spring), and under Mindlin–Deresiewicz.
fn several_materials_cases() -> (Vec<Case<Springs>>, Vec<Case<LoadedSprings>>) {
    let mut rand = common::noise(7);
    let hertz = ContactLaw::HertzMindlin {
        young_modulus: 1e7,
        poisson_ratio: 0.3,
    };
    let per_pair = ContactLaw::LinearPerPair {
        contact_time: Some(1e-4),
    };
    let mindlin = TangentialModel::Mindlin;
    let laws = [
        (hertz, RollingModel::Epsd, 1e-6),
        (hertz, RollingModel::ConstantTorque, 1e-6),
        (per_pair, RollingModel::Epsd, 1e-6),
        (ContactLaw::Linear, RollingModel::ConstantTorque, 1e-5),
    ];
    let mut spring = Vec::new();
    // At the tests' size and at radii of about 1e-8 m; without friction at about 2e-12 m too.
    for scale in [1.0, 2e-6, 4e-10] {
        for (contact, rolling_model, dt) in laws {
            let materials = three_materials(scaled(contact, scale), rolling_model, mindlin);
            if scale > 1e-9 {
                cases(&materials, dt, scale, &mut rand, &mut spring);
            }
            cases(&frictionless(materials), dt, scale, &mut rand, &mut spring);
        }
    }
    assert_most_touch(&spring);
    let mut loaded = Vec::new();
    for scale in [1.0, 2e-6] {
        for rolling_model in [RollingModel::Epsd, RollingModel::ConstantTorque] {
            let md = TangentialModel::MindlinDeresiewicz;
            let materials = three_materials(hertz, rolling_model, md);
            cases(&materials, 1e-6, scale, &mut rand, &mut loaded);
        }
    }
    assert_most_touch(&loaded);
    (spring, loaded)
}

/// `contact` for spheres at `scale`: a per-pair law's contact time scaled with them.
fn scaled(contact: ContactLaw, scale: f32) -> ContactLaw {
    match contact {
        ContactLaw::LinearPerPair {
            contact_time: Some(t),
        } => ContactLaw::LinearPerPair {
            contact_time: Some(t * scale as f64),
        },
        other => other,
    }
}

/// Three materials of `contact` (under Hertz–Mindlin with E and ν of their own) that differ in
/// density, restitution, friction (none on the second) and rolling friction (none on the
/// third), the first and the third a pair with coefficients of its own: pairs that slide and
/// roll, only slide, only roll, or neither.
fn three_materials(
    contact: ContactLaw,
    rolling_model: RollingModel,
    tangential_model: TangentialModel,
) -> Materials {
    let moduli = [(1e7, 0.3), (5e7, 0.2), (2e6, 0.45)];
    let list = (0..3)
        .map(|k| Material {
            density: [2500.0, 1200.0, 7800.0][k],
            restitution: [0.5, 0.9, 0.3][k],
            contact: match contact {
                ContactLaw::HertzMindlin { .. } => ContactLaw::HertzMindlin {
                    young_modulus: moduli[k].0,
                    poisson_ratio: moduli[k].1,
                },
                other => other,
            },
            friction: [0.5, 0.0, 0.8][k],
            rolling_friction: [0.1, 0.05, 0.0][k],
            rolling_model,
            tangential_model,
            ..Material::default()
        })
        .collect();
    Materials {
        list,
        names: ["glass", "wax", "steel"].map(String::from).to_vec(),
        pairs: vec![PairOverride {
            a: 2,
            b: 0,
            restitution: Some(0.7),
            friction: Some(0.1),
            rolling_friction: Some(0.2),
            ..PairOverride::default()
        }],
    }
}

/// Materials as [`three_materials`] without friction and rolling resistance.
fn frictionless(mut materials: Materials) -> Materials {
    for m in &mut materials.list {
        m.friction = 0.0;
        m.rolling_friction = 0.0;
    }
    materials.pairs.clear();
    materials
}

fn bits(x: f32) -> String {
    format!("{:08x}", x.to_bits())
}

// ----------------------------------------------------------------------------------------------
// The CUDA twin: optix/contact.cuh as host C++
// ----------------------------------------------------------------------------------------------

fn vec3(v: Vec3) -> String {
    format!("{} {} {}", bits(v.x), bits(v.y), bits(v.z))
}

/// How far past touching the cases' contacts may hold: a search margin of spheres as large as
/// the box (larger than the cases' spheres: it only gates which walls are looked up).
fn reach(p: &StepParams) -> f32 {
    p.search_margin(p.box_hi[0])
}

/// The parameters' section of a case (the order `contact_twin.cpp` reads): the law, the
/// models, dt, k, the box, the material table's columns and the box walls' column, the liquid
/// bridge's volume, tension and rupture gap, the cohesion energy density and the reach, then
/// every entry's nine values (its law's seven, its bridge's two), row by row.
fn params_section(p: &StepParams) -> String {
    let law = p.law.code();
    let f = p.friction;
    let model = f.rolling_model.code();
    let table = &p.materials;
    let laws: Vec<String> = table
        .laws
        .iter()
        .zip(&table.bridges)
        .flat_map(|(l, b)| {
            [
                l.rate,
                l.e_star,
                l.g_star,
                l.damping_ratio,
                l.sliding,
                l.rolling,
                l.adhesion,
                b.tension,
                b.rupture,
            ]
        })
        .map(bits)
        .collect();
    let first = table.bridge(0, 0);
    let bridge = [
        p.bridge.map_or(0.0, |b| b.volume),
        first.tension,
        first.rupture,
    ];
    let cohesion: Vec<String> = bridge
        .into_iter()
        .chain([
            p.cohesion_density,
            reach(p),
            p.bridge.map_or(0.0, |b| b.viscosity),
        ])
        .map(bits)
        .collect();
    format!(
        "{law} {model} {} {} {} {} {} {} {} {} {} {}",
        f.turns() as u32,
        f.has_history() as u32,
        bits(p.dt),
        bits(p.stiffness),
        vec3(Vec3::from_array(p.box_lo)),
        vec3(Vec3::from_array(p.box_hi)),
        table.count + 1,
        p.box_column,
        cohesion.join(" "),
        laws.join(" "),
    )
}

fn body_section(b: &Body) -> String {
    format!(
        "{} {} {} {} {} {}",
        vec3(b.c),
        vec3(b.v),
        vec3(b.w),
        bits(b.r),
        bits(b.m),
        b.material
    )
}

fn contact_section<S: Twin>(c: Option<Contact<S>>) -> String {
    match c {
        Some(c) => format!(
            "1 {} {} {}",
            vec3(c.force),
            vec3(c.torque),
            c.springs.section()
        ),
        None => "0".into(),
    }
}

/// A case as a line of the case table `contact_twin.cpp` reads: the inputs and what the Rust
/// law computes of them.
fn table_line<S: Twin>(case: &Case<S>) -> String {
    let e = case.expected();
    let kept: String = e
        .kept
        .iter()
        .map(|(w, s)| format!("{w} {} ", s.section()))
        .collect();
    format!(
        "{} | {} | {} | {} | {} | {} | {} {} {} {kept}{} | {} {} {} {} {} | {} | {}\n",
        params_section(&case.p),
        body_section(&case.i),
        body_section(&case.j),
        case.old.section(),
        contact_section(e.from_i),
        contact_section(e.from_j),
        vec3(e.walls.normal),
        vec3(e.walls.tangential),
        vec3(e.walls.torque),
        e.kept.len(),
        vec3(case.n),
        bits(case.overlap),
        vec3(case.moving),
        case.column,
        // No friction of its own: negative, as the device reads it.
        bits(case.given.unwrap_or(-1.0)),
        contact_section(Some(e.surface)),
        case.bonded as u32,
    )
}

/// `tests/contact_twin.cpp` compiled into `dir` (with `optix/contact.cuh` of the
/// Mindlin–Deresiewicz model where `loaded`), or `None` without a C++ compiler (outside CI).
fn compile_twin(dir: &Path, loaded: bool) -> Option<std::path::PathBuf> {
    compile_twin_of(dir, loaded, false)
}

/// [`compile_twin`], with the cohesion laws compiled in where `cohesive`.
fn compile_twin_of(dir: &Path, loaded: bool, cohesive: bool) -> Option<std::path::PathBuf> {
    let mut name = String::from("contact_twin");
    let mut defines = Vec::new();
    if loaded {
        name += "_md";
        defines.push("MOCHI_LOAD_HISTORY");
    }
    if cohesive {
        name += "_cohesive";
        defines.push("MOCHI_COHESIVE=true");
    }
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/contact_twin.cpp");
    common::twin::compile(&source, &dir.join(name), &defines, "the CUDA contact law")
}

/// Runs `binary` on the case table of `cases`: no bit differs.
fn compare_cuda<S: Twin>(binary: &Path, cases: &[Case<S>]) {
    let table: String = cases.iter().map(table_line).collect();
    let mut run = Command::new(binary)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    std::io::Write::write_all(&mut run.stdin.take().unwrap(), table.as_bytes()).unwrap();
    let out = run.wait_with_output().unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{report}");
    let count = cases.len();
    assert!(
        report
            .trim_end()
            .ends_with(&format!("{count} cases, 0 differences")),
        "{report}"
    );
}

#[test]
fn the_cuda_contact_law_computes_the_bits_of_the_rust_one() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = compile_twin(dir.path(), false) else {
        return;
    };
    compare_cuda(&binary, &one_material_cases());
}

#[test]
fn the_cuda_mindlin_deresiewicz_law_computes_the_bits_of_the_rust_one() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = compile_twin(dir.path(), true) else {
        return;
    };
    compare_cuda(&binary, &loaded_cases());
}

#[test]
fn the_cuda_law_of_several_materials_computes_the_bits_of_the_rust_one() {
    let dir = tempfile::tempdir().unwrap();
    let (Some(spring), Some(loaded)) = (
        compile_twin(dir.path(), false),
        compile_twin(dir.path(), true),
    ) else {
        return;
    };
    let (spring_cases, loaded_cases) = several_materials_cases();
    compare_cuda(&spring, &spring_cases);
    compare_cuda(&loaded, &loaded_cases);
}

#[test]
fn the_cohesive_cuda_law_computes_the_bits_of_the_rust_one() {
    let dir = tempfile::tempdir().unwrap();
    let (Some(spring), Some(loaded)) = (
        compile_twin_of(dir.path(), false, true),
        compile_twin_of(dir.path(), true, true),
    ) else {
        return;
    };
    compare_cuda(&spring, &cohesive_cases::<Springs>(11));
    compare_cuda(&loaded, &cohesive_cases::<LoadedSprings>(13));
}

// ----------------------------------------------------------------------------------------------
// The WGSL twin: wgsl/dem/dem_contact.wgsl and wgsl/dem/dem_physics.wgsl on lavapipe
// ----------------------------------------------------------------------------------------------

const PARAMS: &str = include_str!("../wgsl/dem/dem_params.wgsl");
const CONTACT: &str = include_str!("../wgsl/dem/dem_contact.wgsl");
const PAPER: &str = include_str!("../wgsl/dem/dem_physics.wgsl");

/// The test kernels' bindings (numbers the law's modules leave free).
const CASES: Binding = Binding::read(0, "cases");
const RESULTS: Binding = Binding::read_write(2, "results");

/// What both test kernels share: case k's words are `cases[k · CASE_WORDS ..]`, its results
/// `results[k · RESULT_WORDS ..]`, each written by `put` after the one before.
const KERNEL_IO: &str = r#"
@group(0) @binding(0) var<storage, read> cases: array<f32>;
@group(0) @binding(2) var<storage, read_write> results: array<f32>;

// The result word `put` writes next.
var<private> next: u32;

fn put(x: f32) {
    results[next] = x;
    next += 1u;
}

fn put3(v: vec3<f32>) {
    put(v.x);
    put(v.y);
    put(v.z);
}

fn vec_at(k: u32) -> vec3<f32> {
    return vec3(cases[k], cases[k + 1u], cases[k + 2u]);
}
"#;

/// The granular law's test kernel (after `KERNEL_IO` and the model's [`Twin::KERNEL_IO`]). A
/// case's words ([`contact_words`]): the bodies i and j, the springs i kept of their contact,
/// those of each box wall, then the surface's normal, overlap, velocity, column (its bits) and
/// own friction (negative: none). Its results: whether the pair touches (1 or 0); i's force,
/// torque and springs; the partner's; the surface's; then a slot for each box wall: whether it
/// touches, and its force, torque and springs.
const CONTACT_KERNEL: &str = r#"
const CASE_WORDS: u32 = 34u + 7u * SPRINGS_WORDS;
const CONTACT_WORDS: u32 = 6u + SPRINGS_WORDS;
const WALL_WORDS: u32 = 1u + CONTACT_WORDS;
const RESULT_WORDS: u32 = 1u + 3u * CONTACT_WORDS + 6u * WALL_WORDS;

fn body_at(k: u32) -> Body {
    let material = bitcast<u32>(cases[k + 11u]);
    return Body(vec_at(k), vec_at(k + 3u), vec_at(k + 6u), cases[k + 9u], cases[k + 10u], material);
}

fn put_contact(force: vec3<f32>, torque: vec3<f32>, springs: Springs) {
    put3(force);
    put3(torque);
    put_springs(springs);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&cases) / CASE_WORDS {
        return;
    }
    let at = k * CASE_WORDS;
    let i = body_at(at);
    let old = springs_at(at + 24u);
    next = k * RESULT_WORDS;
    let s = at + 24u + 7u * SPRINGS_WORDS;
    // The pair from i's side; the partner's share as contact_with (dem_granular.wgsl) gives it,
    // with the springs the partner reads of i's entry.
    let c = pair_contact(i, body_at(at + 12u), old, cases[s + 9u] != 0.0);
    put(select(0.0, 1.0, c.touching));
    put_contact(c.force, c.torque_i, c.springs);
    put_contact(-c.force, c.torque_j, springs_from(entry_of(0u, c.springs), -1.0));
    // The surface, as wall_contacts (dem_mesh_walls.wgsl) meets a mesh wall's point.
    let column = bitcast<u32>(cases[s + 7u]);
    let law = law_of(i.material, column);
    let own = cases[s + 8u];
    let mu = select(law.sliding, own, own >= 0.0);
    let wet = bridge_of(i.material, column);
    let m = surface_contact(i, vec_at(s), cases[s + 3u], vec_at(s + 4u), law, wet, mu, old);
    put_contact(m.force, m.torque, m.springs);
    // The box walls, as finish (dem_granular.wgsl) meets them.
    let box_law = law_of(i.material, dem.box_column);
    let box_wet = bridge_of(i.material, dem.box_column);
    for (var axis = 0u; axis < 3u; axis += 1u) {
        let below = i.r - (i.c[axis] - dem.box_lo[axis]);
        let above = i.r - (dem.box_hi[axis] - i.c[axis]);
        for (var side = 0u; side < 2u; side += 1u) {
            let wall = 2u * axis + side;
            next = k * RESULT_WORDS + 1u + 3u * CONTACT_WORDS + wall * WALL_WORDS;
            let overlap = select(below, above, side == 1u);
            // Every wall of a case touched at the last step.
            let held = COHESIVE && holds(box_law, box_wet, i.r, overlap);
            if overlap <= 0.0 && !held {
                put(0.0);
                continue;
            }
            var kept = no_springs();
            if dem.slots > 0u {
                kept = springs_at(at + 24u + (1u + wall) * SPRINGS_WORDS);
            }
            var n = vec3(0.0);
            n[axis] = select(-1.0, 1.0, side == 1u);
            let w =
                surface_contact(i, n, overlap, vec3(0.0), box_law, box_wet, box_law.sliding, kept);
            put(1.0);
            put_contact(w.force, w.torque, w.springs);
        }
    }
}
"#;

/// The paper's law's test kernel (after `KERNEL_IO`). A case's words: the bodies i and j
/// ([`body_words`]). Its results: `contact_force` on i from j and on j from i (the force, then
/// 1 where they touch), and `wall_force` on i.
const PAPER_KERNEL: &str = r#"
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&cases) / 24u {
        return;
    }
    let i = k * 24u;
    let j = i + 12u;
    let c_i = vec_at(i);
    let v_i = vec_at(i + 3u);
    let c_j = vec_at(j);
    let v_j = vec_at(j + 3u);
    let r_i = cases[i + 9u];
    let m_i = cases[i + 10u];
    let r_j = cases[j + 9u];
    let m_j = cases[j + 10u];
    next = k * 11u;
    let f = contact_force(c_i, v_i, r_i, m_i, c_j, v_j, r_j, m_j);
    let g = contact_force(c_j, v_j, r_j, m_j, c_i, v_i, r_i, m_i);
    put3(f.xyz);
    put(f.w);
    put3(g.xyz);
    put(g.w);
    put3(wall_force(c_i, v_i, r_i, m_i));
}
"#;

/// A body's words in the test kernels' cases: centre, velocity, angular velocity, radius, mass
/// and material (its bits).
fn body_words(b: &Body) -> Vec<f32> {
    let mut words = [b.c, b.v, b.w].map(|v| v.to_array()).concat();
    words.extend([b.r, b.m, f32::from_bits(b.material)]);
    words
}

/// A case's words in the granular law's test kernel.
fn contact_words<S: Twin>(case: &Case<S>) -> Vec<f32> {
    let mut words = [body_words(&case.i), body_words(&case.j), case.old.words()].concat();
    for wall in 0..WALLS {
        words.extend(S::of_wall(wall).words());
    }
    words.extend(case.n.to_array());
    words.push(case.overlap);
    words.extend(case.moving.to_array());
    words.push(f32::from_bits(case.column));
    words.push(case.given.unwrap_or(-1.0));
    words.push(case.bonded as u32 as f32);
    words
}

/// A member's value in a uniform or storage block.
enum Value {
    U(u32),
    F(f32),
    V([f32; 3]),
    Struct(Vec<(&'static str, Value)>),
}

fn pair_law(l: &PairLaw) -> Value {
    use Value::F;
    Value::Struct(vec![
        ("rate", F(l.rate)),
        ("e_star", F(l.e_star)),
        ("g_star", F(l.g_star)),
        ("damping_ratio", F(l.damping_ratio)),
        ("sliding", F(l.sliding)),
        ("rolling", F(l.rolling)),
        ("adhesion", F(l.adhesion)),
    ])
}

/// The blocks the laws read of `p`, for each global of `module` that holds one, with its bytes:
/// the step's parameters with the law's (`dem`), the cohesion laws (`cohesion`) and the
/// material table (`material_laws`, row by row), as the engines fill them. Each value lies where
/// naga lays its member out; a member named here that the WGSL lacks or types otherwise, or one
/// of the WGSL's (but padding, `_*`) not named here, fails.
fn uploads(p: &StepParams, module: &naga::Module) -> Vec<(Binding, Vec<u8>)> {
    use Value::{F, Struct, U, V};
    let (f, table) = (&p.friction, &p.materials);
    let blocks = [
        (
            "dem",
            vec![Struct(vec![
                ("box_lo", V(p.box_lo)),
                // The laws read neither the spheres' count nor the dispatch's rows.
                ("n", U(0)),
                ("box_hi", V(p.box_hi)),
                ("row", U(0)),
                ("gravity", V(p.gravity)),
                ("dt", F(p.dt)),
                ("stiffness", F(p.stiffness)),
                ("damping_ratio", F(p.damping_ratio)),
                ("gravity_spin", F(p.gravity_spin)),
                ("law", U(p.law.code())),
                ("rolling_model", U(f.rolling_model.code())),
                ("turns", U(f.turns() as u32)),
                // Slots where contacts keep springs: the kernel reads the walls' then.
                ("slots", U(f.has_history() as u32)),
                ("spheres_per_part", U(1)),
                ("columns", U(table.count as u32 + 1)),
                ("box_column", U(p.box_column)),
                // The laws read no external loads (the integrations do).
                ("loaded", U(0)),
                ("reach", F(reach(p))),
                ("sphere_law", pair_law(table.law(0, 0))),
            ])],
        ),
        (
            "cohesion",
            vec![Struct(vec![
                ("bridge_volume", F(p.bridge.map_or(0.0, |b| b.volume))),
                ("bridge_tension", F(table.bridge(0, 0).tension)),
                ("bridge_rupture", F(table.bridge(0, 0).rupture)),
                ("density", F(p.cohesion_density)),
                ("bridge_viscosity", F(p.bridge.map_or(0.0, |b| b.viscosity))),
            ])],
        ),
        (
            "material_laws",
            table
                .laws
                .iter()
                .zip(&table.bridges)
                .map(|(l, b)| {
                    Struct(vec![
                        ("law", pair_law(l)),
                        (
                            "bridge",
                            Struct(vec![("tension", F(b.tension)), ("rupture", F(b.rupture))]),
                        ),
                    ])
                })
                .collect(),
        ),
    ];
    let mut layouter = Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    blocks
        .into_iter()
        .filter_map(|(name, rows)| {
            let (_, g) = module
                .global_variables
                .iter()
                .find(|(_, g)| g.name.as_deref() == Some(name))?;
            let at = g.binding.as_ref().expect("a block is bound");
            let (ty, stride) = match module.types[g.ty].inner {
                TypeInner::Array { base, stride, .. } => (base, stride as usize),
                _ => (g.ty, layouter[g.ty].size as usize),
            };
            let mut bytes = vec![0; rows.len() * stride];
            for (row, value) in bytes.chunks_mut(stride).zip(&rows) {
                place(module, ty, value, row, name);
            }
            let binding = match g.space {
                AddressSpace::Uniform => Binding::uniform(at.binding, name),
                _ => Binding::read(at.binding, name),
            };
            Some((binding, bytes))
        })
        .collect()
}

/// Writes `value` into `bytes` as the WGSL type `ty` lays it out (`what` names it).
fn place(module: &naga::Module, ty: Handle<Type>, value: &Value, bytes: &mut [u8], what: &str) {
    let inner = &module.types[ty].inner;
    let words: Vec<u32> = match (inner, value) {
        (TypeInner::Scalar(s), Value::U(x)) if *s == naga::Scalar::U32 => vec![*x],
        (TypeInner::Scalar(s), Value::F(x)) if *s == naga::Scalar::F32 => vec![x.to_bits()],
        (
            TypeInner::Vector {
                size: VectorSize::Tri,
                scalar,
            },
            Value::V(v),
        ) if *scalar == naga::Scalar::F32 => v.map(f32::to_bits).to_vec(),
        (TypeInner::Struct { members, .. }, Value::Struct(values)) => {
            for m in members {
                let name = m.name.as_deref().unwrap_or_default();
                let given = values.iter().find(|(n, _)| *n == name);
                match given {
                    Some((_, v)) => place(module, m.ty, v, &mut bytes[m.offset as usize..], name),
                    None => assert!(name.starts_with('_'), "{what}.{name} is given no value"),
                }
            }
            for (name, _) in values {
                assert!(
                    members.iter().any(|m| m.name.as_deref() == Some(name)),
                    "{what} has no member {name} in the WGSL"
                );
            }
            return;
        }
        _ => panic!("{what} is of type {inner:?} in the WGSL"),
    };
    for (k, w) in words.into_iter().enumerate() {
        bytes[4 * k..4 * k + 4].copy_from_slice(&w.to_le_bytes());
    }
}

/// `module` as SPIR-V for a device of [`SpirvDevice`]: with the override values `constants`, its
/// globals bound at 0, 1, … in the order of `bindings` (wgpu's Vulkan backend numbers a bind
/// group's bindings so, and translates the WGSL's numbers only for the shaders it compiles
/// itself), and every floating-point operation decorated NoContraction. A Vulkan driver may
/// then neither fuse an operation with another (a·b + c into a fused multiply-add) nor reorder
/// it (Mesa's compiler reassociates sums otherwise, so lavapipe computes other bits from the
/// SPIR-V wgpu makes of the WGSL): the operations run as the WGSL writes them.
fn exact_spirv(
    module: &naga::Module,
    constants: &naga::back::PipelineConstants,
    bindings: &[Binding],
) -> Vec<u32> {
    use naga::back::spv;
    use naga::proc::{BoundsCheckPolicies, BoundsCheckPolicy};
    use naga::valid::{Capabilities, ValidationFlags, Validator};
    let info = Validator::new(ValidationFlags::all(), Capabilities::all())
        .validate(module)
        .unwrap();
    let (module, info) =
        naga::back::pipeline_constants::process_overrides(module, &info, None, constants).unwrap();
    let binding_map = bindings
        .iter()
        .enumerate()
        .map(|(k, b)| {
            let at = naga::ResourceBinding {
                group: b.group,
                binding: b.binding,
            };
            let info = spv::BindingInfo {
                descriptor_set: 0,
                binding: k as u32,
                binding_array_size: None,
            };
            (at, info)
        })
        .collect();
    let restrict = BoundsCheckPolicy::Restrict;
    let options = spv::Options {
        lang_version: (1, 3),
        binding_map,
        bounds_check_policies: BoundsCheckPolicies {
            index: restrict,
            buffer: restrict,
            image_load: restrict,
            binding_array: restrict,
        },
        ..spv::Options::default()
    };
    no_contraction(&spv::write_vec(&module, &info, &options, None).unwrap())
}

/// SPIR-V `words` with the result of every floating-point arithmetic instruction decorated
/// NoContraction, after the module's other decorations (where SPIR-V's layout puts them).
fn no_contraction(words: &[u32]) -> Vec<u32> {
    // OpFNegate, OpFAdd, OpFSub, OpFMul, OpFDiv, OpFRem, OpFMod, OpVectorTimesScalar, OpDot:
    // their result's id is their third word.
    const ARITHMETIC: [u32; 9] = [127, 129, 131, 133, 136, 140, 141, 142, 148];
    // OpDecorate, OpMemberDecorate, OpDecorationGroup, OpGroupDecorate, OpGroupMemberDecorate,
    // OpDecorateId.
    const ANNOTATIONS: [u32; 6] = [71, 72, 73, 74, 75, 332];
    const OP_DECORATE: u32 = 71;
    const NO_CONTRACTION: u32 = 42;
    let (header, body) = words.split_at(5);
    let mut decorations = Vec::new();
    let mut annotations_end = 0;
    let mut at = 0;
    while at < body.len() {
        let (op, count) = (body[at] & 0xffff, (body[at] >> 16) as usize);
        if ARITHMETIC.contains(&op) {
            decorations.extend([3 << 16 | OP_DECORATE, body[at + 2], NO_CONTRACTION]);
        }
        if ANNOTATIONS.contains(&op) {
            annotations_end = at + count;
        }
        at += count;
    }
    assert!(
        annotations_end > 0,
        "a module with bindings has decorations"
    );
    let (before, after) = body.split_at(annotations_end);
    [header, before, &decorations, after].concat()
}

/// A Vulkan device that takes SPIR-V as given (wgpu's PASSTHROUGH_SHADERS), to run the test
/// kernels as [`exact_spirv`] makes them.
struct SpirvDevice {
    device: wgpu::Device,
    queue: wgpu::Queue,
}

impl SpirvDevice {
    /// A device on lavapipe, the Vulkan adapter whose operations round as IEEE 754 does (the
    /// comparison's rule, see the module's documentation); without it, a note that `what` is not
    /// tested here (a panic under CI, which has it).
    fn open(what: &str) -> Option<SpirvDevice> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            flags: wgpu::InstanceFlags::from_build_config().with_env(),
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let needs = wgpu::Features::PASSTHROUGH_SHADERS;
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
        let Some(adapter) = adapters
            .into_iter()
            .find(|a| a.get_info().driver == "llvmpipe" && a.features().contains(needs))
        else {
            let why = "no lavapipe that takes SPIR-V as given";
            assert!(!common::ci(), "CI expects one for {what}: {why}");
            eprintln!("note: {what} is not tested on this machine: {why}");
            return None;
        };
        let descriptor = wgpu::DeviceDescriptor {
            required_features: needs,
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&descriptor))
            .expect("an adapter opens with its own features and limits");
        Some(SpirvDevice { device, queue })
    }

    /// Runs the test kernel `main` of `source` over `cases` (the words of each from `words`,
    /// `out` result words each): the cases of one set of parameters in one dispatch, bound to
    /// the blocks [`uploads`] makes of them, the law specialised for one material where the
    /// engines specialise it (`DemModule::constants`). The results, case after case.
    fn run<S>(
        &self,
        source: &str,
        cases: &[Case<S>],
        words: impl Fn(&Case<S>) -> Vec<f32>,
        out: usize,
    ) -> Vec<f32> {
        let device = &self.device;
        let module = naga::front::wgsl::parse_str(source)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
        let mut groups: Vec<(&StepParams, Vec<usize>)> = Vec::new();
        for (k, case) in cases.iter().enumerate() {
            match groups.iter_mut().rev().find(|(p, _)| **p == case.p) {
                Some((_, group)) => group.push(k),
                None => groups.push((&case.p, vec![k])),
            }
        }
        let blocks: Vec<_> = groups.iter().map(|(p, _)| uploads(p, &module)).collect();
        let bindings: Vec<Binding> = [CASES, RESULTS]
            .into_iter()
            .chain(blocks[0].iter().map(|(b, _)| *b))
            .collect();
        let entries: Vec<_> = bindings
            .iter()
            .enumerate()
            .map(|(k, b)| {
                Binding {
                    binding: k as u32,
                    ..*b
                }
                .layout_entry(false, None)
            })
            .collect();
        let label = Some("mochi.test.contact_twin");
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label,
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label,
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let declares = |name: &str| {
            let mut overrides = module.overrides.iter();
            overrides.any(|(_, o)| o.name.as_deref() == Some(name))
        };
        let (one_material, per_pair) = (declares("ONE_MATERIAL"), declares("PER_PAIR"));
        let (cohesive, viscous) = (declares("COHESIVE"), declares("VISCOUS"));
        let pipeline = |(one_material, per_pair, cohesive, viscous): (bool, bool, bool, bool)| {
            let mut constants = naga::back::PipelineConstants::default();
            for (name, on) in [
                ("ONE_MATERIAL", one_material),
                ("PER_PAIR", per_pair),
                ("COHESIVE", cohesive),
                ("VISCOUS", viscous),
            ] {
                if on {
                    constants.insert(name.into(), 1.0);
                }
            }
            let spirv = exact_spirv(&module, &constants, &bindings);
            let entry_point = wgpu::PassthroughShaderEntryPoint {
                name: "main".into(),
                workgroup_size: (64, 1, 1),
            };
            // SAFETY: naga's SPIR-V of a module it validated, bound as `layout` lays it out.
            let shader = unsafe {
                device.create_shader_module_passthrough(wgpu::ShaderModuleDescriptorPassthrough {
                    label,
                    entry_points: vec![entry_point].into(),
                    spirv: Some(spirv.into()),
                    ..Default::default()
                })
            };
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label,
                layout: Some(&pipeline_layout),
                module: &shader,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let mut pipelines = std::collections::HashMap::new();
        let buffer = |contents: &[u8], usage| {
            let descriptor = wgpu::util::BufferInitDescriptor {
                label,
                contents,
                usage,
            };
            device.create_buffer_init(&descriptor)
        };
        let bytes = (cases.len() * out * 4) as u64;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label,
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        let mut at = 0;
        for ((p, group), blocks) in groups.iter().zip(blocks) {
            // As DemModule::open sets the constants.
            let key = (
                one_material && p.materials.count == 1,
                per_pair && matches!(p.law, NormalLaw::LinearPerPair { .. }),
                cohesive && p.adheres(),
                viscous && p.bridge.is_some_and(|b| b.viscosity > 0.0),
            );
            let pipeline = pipelines.entry(key).or_insert_with(|| pipeline(key));
            let input: Vec<f32> = group.iter().flat_map(|&k| words(&cases[k])).collect();
            let size = (group.len() * out * 4) as u64;
            let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
            let mut buffers = vec![
                buffer(bytemuck::cast_slice(&input), wgpu::BufferUsages::STORAGE),
                device.create_buffer(&wgpu::BufferDescriptor {
                    label,
                    size,
                    usage,
                    mapped_at_creation: false,
                }),
            ];
            for (binding, bytes) in blocks {
                let usage = match binding.kind {
                    BindingKind::Uniform => wgpu::BufferUsages::UNIFORM,
                    _ => wgpu::BufferUsages::STORAGE,
                };
                buffers.push(buffer(&bytes, usage));
            }
            let entries: Vec<_> = (0..)
                .zip(&buffers)
                .map(|(binding, b)| wgpu::BindGroupEntry {
                    binding,
                    resource: b.as_entire_binding(),
                })
                .collect();
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label,
                layout: &layout,
                entries: &entries,
            });
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &bind, &[]);
                pass.dispatch_workgroups((group.len() as u32).div_ceil(64), 1, 1);
            }
            encoder.copy_buffer_to_buffer(&buffers[1], 0, &staging, at, size);
            at += size;
        }
        self.queue.submit([encoder.finish()]);
        staging
            .slice(..)
            .map_async(wgpu::MapMode::Read, |mapped| mapped.unwrap());
        device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
        let view = staging.slice(..).get_mapped_range().unwrap();
        let got: &[f32] = bytemuck::cast_slice(&view);
        let mut all = vec![0.0; cases.len() * out];
        let rows = groups.iter().flat_map(|(_, group)| group);
        for (&k, r) in rows.zip(got.chunks(out)) {
            all[k * out..(k + 1) * out].copy_from_slice(r);
        }
        all
    }
}

/// The differences of the WGSL's results from the Rust law's, the first 20 in words.
#[derive(Default)]
struct Differences {
    found: usize,
    report: String,
}

impl Differences {
    /// Notes a difference of case `case` (counted from 1, as the CUDA twin's table lines).
    fn note(&mut self, case: usize, what: std::fmt::Arguments) {
        self.found += 1;
        if self.found <= 20 {
            writeln!(self.report, "case {case} {what}").unwrap();
        }
    }

    /// Compares the values `got` with `want`, bit for bit (±0 equal).
    fn check(&mut self, case: usize, what: &str, got: &[f32], want: &[f32]) {
        for (k, (&g, &w)) in got.iter().zip(want).enumerate() {
            if g.to_bits() != w.to_bits() && !(g == 0.0 && w == 0.0) {
                let value = match got.len() {
                    3 => format!("{what} {}", ["x", "y", "z"][k]),
                    _ => what.to_owned(),
                };
                let (gb, wb) = (bits(g), bits(w));
                self.note(
                    case,
                    format_args!("{value}: got {gb} ({g:e}), contact.rs {wb} ({w:e})"),
                );
            }
        }
    }

    /// Compares springs, `got` their words.
    fn springs<S: Twin>(&mut self, case: usize, whose: &str, got: &[f32], want: &S) {
        let want = want.words();
        let mut at = 0;
        for (part, size) in S::PARTS {
            let what = format!("{whose} {part}");
            self.check(case, &what, &got[at..at + size], &want[at..at + size]);
            at += size;
        }
    }

    /// Compares a contact, `got` its force, torque and springs.
    fn contact<S: Twin>(&mut self, case: usize, whose: &str, got: &[f32], want: &Contact<S>) {
        let (force, torque) = (want.force.to_array(), want.torque.to_array());
        self.check(case, &format!("{whose} force"), &got[..3], &force);
        self.check(case, &format!("{whose} torque"), &got[3..6], &torque);
        self.springs(case, whose, &got[6..], &want.springs);
    }

    /// Fails with the report where anything differed among `count` cases.
    fn assert_none(self, count: usize) {
        assert!(
            self.found == 0,
            "{}{count} cases, {} differences",
            self.report,
            self.found
        );
    }
}

/// Runs the granular law of the WGSL on `cases` on `gpu`: every value it computes is the Rust
/// law's.
fn compare_wgsl<S: Twin>(gpu: &SpirvDevice, cases: &[Case<S>]) {
    let source = format!(
        "{PARAMS}{}{CONTACT}{KERNEL_IO}{}{CONTACT_KERNEL}",
        S::TANGENTIAL,
        S::KERNEL_IO
    );
    let contact = 6 + S::PARTS.iter().map(|(_, size)| size).sum::<usize>();
    let out = 1 + 3 * contact + WALLS as usize * (1 + contact);
    let results = gpu.run(&source, cases, contact_words, out);
    let mut d = Differences::default();
    for (k, (case, got)) in cases.iter().zip(results.chunks(out)).enumerate() {
        let number = k + 1;
        let e = case.expected();
        let touching = got[0] == 1.0;
        let (pair, rest) = got[1..].split_at(contact);
        let (partner, rest) = rest.split_at(contact);
        let (surface, walls) = rest.split_at(contact);
        match (e.from_i, e.from_j) {
            (Some(a), Some(b)) if touching => {
                d.contact(number, "pair's", pair, &a);
                d.contact(number, "partner's", partner, &b);
            }
            (None, None) if !touching => {}
            (a, b) => {
                let (a, b) = (a.is_some(), b.is_some());
                d.note(
                    number,
                    format_args!("touching {touching}, contact.rs {a} and {b}"),
                );
            }
        }
        d.contact(number, "surface's", surface, &e.surface);
        // The walls' sums as wall_contacts forms them: a wall's normal force is its force's
        // component along its axis (the tangential force lies in the wall's plane), its
        // tangential force the other two components.
        let mut normal = Vec3::ZERO;
        let mut tangential = Vec3::ZERO;
        let mut torque = Vec3::ZERO;
        let mut kept = Vec::new();
        for (wall, slot) in walls.chunks(1 + contact).enumerate() {
            if slot[0] == 0.0 {
                continue;
            }
            let axis = wall / 2;
            let mut force = Vec3::from_slice(&slot[1..4]);
            normal[axis] += force[axis];
            force[axis] = 0.0;
            tangential += force;
            torque += Vec3::from_slice(&slot[4..7]);
            if case.p.friction.has_history() {
                kept.push((wall as u32, &slot[7..]));
            }
        }
        let sums = [
            ("walls' normal force", normal, e.walls.normal),
            ("walls' tangential force", tangential, e.walls.tangential),
            ("walls' torque", torque, e.walls.torque),
        ];
        for (what, got, want) in sums {
            d.check(number, what, &got.to_array(), &want.to_array());
        }
        let walls: Vec<u32> = kept.iter().map(|(w, _)| *w).collect();
        let want: Vec<u32> = e.kept.iter().map(|(w, _)| *w).collect();
        if walls != want {
            d.note(
                number,
                format_args!("walls kept {walls:?}, contact.rs {want:?}"),
            );
            continue;
        }
        for ((wall, got), (_, want)) in kept.iter().zip(&e.kept) {
            d.springs(number, &format!("wall {wall}'s"), got, want);
        }
    }
    d.assert_none(cases.len());
}

/// Runs the paper's law of the WGSL on `cases` (of one frictionless linear material, of one
/// stiffness or one per pair) on `gpu`: its forces are the Rust law's.
fn compare_paper(gpu: &SpirvDevice, cases: &[Case<Springs>]) {
    let source = format!("{PARAMS}{PAPER}{KERNEL_IO}{PAPER_KERNEL}");
    let words = |c: &Case<Springs>| [body_words(&c.i), body_words(&c.j)].concat();
    let results = gpu.run(&source, cases, words, 11);
    let mut d = Differences::default();
    for (k, (case, got)) in cases.iter().zip(results.chunks(11)).enumerate() {
        let number = k + 1;
        let e = case.expected();
        for (whose, got, want) in [("i's", &got[..4], e.from_i), ("j's", &got[4..8], e.from_j)] {
            match want {
                Some(c) if got[3] == 1.0 => d.check(
                    number,
                    &format!("{whose} force"),
                    &got[..3],
                    &c.force.to_array(),
                ),
                None if got[3] == 0.0 => {}
                _ => {
                    let (touching, want) = (got[3] == 1.0, want.is_some());
                    d.note(
                        number,
                        format_args!("{whose} touching {touching}, contact.rs {want}"),
                    );
                }
            }
        }
        d.check(
            number,
            "walls' force",
            &got[8..],
            &e.walls.normal.to_array(),
        );
    }
    d.assert_none(cases.len());
}

#[test]
fn the_wgsl_contact_law_computes_the_bits_of_the_rust_one() {
    let Some(gpu) = SpirvDevice::open("the WGSL contact law") else {
        return;
    };
    compare_wgsl(&gpu, &one_material_cases());
}

#[test]
fn the_wgsl_mindlin_deresiewicz_law_computes_the_bits_of_the_rust_one() {
    let Some(gpu) = SpirvDevice::open("the WGSL Mindlin–Deresiewicz law") else {
        return;
    };
    compare_wgsl(&gpu, &loaded_cases());
}

#[test]
fn the_wgsl_law_of_several_materials_computes_the_bits_of_the_rust_one() {
    let Some(gpu) = SpirvDevice::open("the WGSL contact law of several materials") else {
        return;
    };
    let (spring, loaded) = several_materials_cases();
    compare_wgsl(&gpu, &spring);
    compare_wgsl(&gpu, &loaded);
}

#[test]
fn the_cohesive_wgsl_law_computes_the_bits_of_the_rust_one() {
    let Some(gpu) = SpirvDevice::open("the cohesive WGSL contact law") else {
        return;
    };
    compare_wgsl(&gpu, &cohesive_cases::<Springs>(11));
    compare_wgsl(&gpu, &cohesive_cases::<LoadedSprings>(13));
}

#[test]
fn the_papers_wgsl_law_computes_the_bits_of_the_rust_one() {
    let Some(gpu) = SpirvDevice::open("the paper's WGSL law") else {
        return;
    };
    let paper: Vec<_> = one_material_cases()
        .into_iter()
        .filter(|c| !c.p.friction.turns())
        .filter(|c| matches!(c.p.law, NormalLaw::Linear | NormalLaw::LinearPerPair { .. }))
        .collect();
    assert_most_touch(&paper);
    let per_pair = paper.iter().filter(|c| c.p.law != NormalLaw::Linear);
    assert!(per_pair.count() >= 100, "cases of a stiffness per pair");
    compare_paper(&gpu, &paper);
}
