//! The optix granular step's contact law, `optix/contact.cuh`, is the twin of
//! `src/dem/model/contact.rs` bit for bit: compiled as host C++ (`tests/contact_twin.cpp`
//! supplies CUDA's vector types; no fused multiply-adds, as NVRTC compiles it for the GPU), it
//! computes the same forces, torques and springs as the Rust law on a table of random contacts
//! of every law and rolling model: a sphere pair from one side, the partner's share as the
//! partner's own side computes it (what the GPU's owner adds to the partner), the six walls
//! with their springs and a moving surface (a mesh wall's contact); at the size of the tests'
//! spheres and at nanometres, where the products of masses, moments of inertia and torques
//! underflow f32. Each case carries its material table (one material, or three that differ in
//! E, ν, density, restitution, friction and rolling friction, with a pair of its own), its
//! spheres' materials and the walls' columns (a material's or rigid). Compiled again with
//! `MOCHI_LOAD_HISTORY`, the Mindlin–Deresiewicz law on cases of its own (springs with a load
//! history, on the virgin curve and after a reversal, sticking and sliding). Needs a C++17
//! compiler (`c++`) and no GPU; skips with a note without one (CI has one).

mod common;

use glam::Vec3;
use mochi::dem::model::contact::{
    Body, Contact, Kept, LoadedSprings, Springs, pair_contact, surface_contact, wall_contacts,
};
use mochi::dem::model::{
    ContactLaw, Material, Materials, PairOverride, RollingModel, StepParams, TangentialModel, mass,
};
use std::fmt::Write;
use std::path::Path;
use std::process::{Command, Stdio};

const DENSITY: f64 = 2500.0;

fn bits(x: f32) -> String {
    format!("{:08x}", x.to_bits())
}

fn vec3(v: Vec3) -> String {
    format!("{} {} {}", bits(v.x), bits(v.y), bits(v.z))
}

/// The parameters' section of a case (the order `contact_twin.cpp` reads): the law, the
/// models, dt, k, the box, then the material table (its columns, the box walls' column and
/// every law's six values, row by row).
fn params_section(p: &StepParams) -> String {
    let law = p.law.code();
    let f = p.friction;
    let model = f.rolling_model.code();
    let table = &p.materials;
    let laws: Vec<String> = table
        .laws
        .iter()
        .flat_map(|l| {
            [
                l.rate,
                l.e_star,
                l.g_star,
                l.damping_ratio,
                l.sliding,
                l.rolling,
            ]
        })
        .map(bits)
        .collect();
    format!(
        "{law} {model} {} {} {} {} {} {} {} {} {}",
        f.turns() as u32,
        f.has_history() as u32,
        bits(p.dt),
        bits(p.stiffness),
        vec3(Vec3::from_array(p.box_lo)),
        vec3(Vec3::from_array(p.box_hi)),
        table.count + 1,
        p.box_column,
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

/// What the cases keep of a contact, as the case table writes it.
trait Twin: Kept {
    /// The values: tangential, rolling (and under Mindlin–Deresiewicz the reversal and the
    /// normal force).
    fn section(&self) -> String;
    /// Springs a contact of spheres at `scale` may have kept.
    fn old(scale: f32, rand: &mut impl FnMut() -> f32) -> Self;
    /// What the cases keep of wall `w`: (w, w, w)·1e-6 and the rolling one their negative
    /// (under Mindlin–Deresiewicz the reversal (w, −w, w)·1e-6 and the normal force w·1e-6).
    fn of_wall(w: u32) -> Self;
}

impl Twin for Springs {
    fn section(&self) -> String {
        format!("{} {}", vec3(self.tangential), vec3(self.rolling))
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
    fn section(&self) -> String {
        let (r, n) = (vec3(self.reversal), bits(self.normal));
        format!("{} {r} {n}", self.springs.section())
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

/// Cases of `materials`: pairs of random materials at about touching distance (some apart),
/// spinning, with old springs, near the walls of a 0.1 m box of a random column (a material's
/// or rigid), and a sphere on a moving surface of a random column, with its own friction in a
/// third of the cases; all of it scaled by `scale` (lengths and times, velocities kept: spins
/// by 1/scale, rolling springs by scale³).
fn cases<S: Twin>(
    materials: &Materials,
    dt: f64,
    scale: f32,
    rand: &mut impl FnMut() -> f32,
    out: &mut String,
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
        let back = old.negated();
        let mut kept = String::new();
        let mut held = 0;
        let walls = wall_contacts(&p, &i, S::of_wall, |w, s: S| {
            held += 1;
            write!(kept, "{w} {} ", s.section()).unwrap();
        });
        let n = Vec3::new(rand(), rand(), rand()).normalize();
        let overlap = i.r * (0.001 + 0.01 * (rand() + 0.5));
        let moving = 0.5 * Vec3::new(rand(), rand(), rand());
        let column = pick(rand, count + 1);
        let given = (rand() < -0.2).then(|| rand() + 0.5);
        let surface = surface_contact(&p, &i, n, overlap, moving, column, given, old);
        writeln!(
            out,
            "{} | {} | {} | {} | {} | {} | {} {} {} {kept}{held} | {} {} {} {column} {} | {}",
            params_section(&p),
            body_section(&i),
            body_section(&j),
            old.section(),
            contact_section(pair_contact(&p, &i, &j, old)),
            contact_section(pair_contact(&p, &j, &i, back)),
            vec3(walls.normal),
            vec3(walls.tangential),
            vec3(walls.torque),
            vec3(n),
            bits(overlap),
            vec3(moving),
            // No friction of its own: negative, as the device reads it.
            bits(given.unwrap_or(-1.0)),
            contact_section(Some(surface)),
        )
        .unwrap();
    }
}

/// `tests/contact_twin.cpp` compiled into `dir` (with `optix/contact.cuh` of the
/// Mindlin–Deresiewicz model where `loaded`), or `None` without a C++ compiler (outside CI).
fn compile_twin(dir: &Path, loaded: bool) -> Option<std::path::PathBuf> {
    let (name, defines): (_, &[&str]) = match loaded {
        true => ("contact_twin_md", &["MOCHI_LOAD_HISTORY"]),
        false => ("contact_twin", &[]),
    };
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/contact_twin.cpp");
    common::twin::compile(&source, &dir.join(name), defines, "the CUDA contact law")
}

/// Runs `binary` on the case `table` of `count` cases: no bit differs.
fn compare(binary: &Path, table: &str, count: usize) {
    let mut run = Command::new(binary)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    std::io::Write::write_all(&mut run.stdin.take().unwrap(), table.as_bytes()).unwrap();
    let out = run.wait_with_output().unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{report}");
    assert!(
        report
            .trim_end()
            .ends_with(&format!("{count} cases, 0 differences")),
        "{report}"
    );
    // Most cases touch (the rest check that apart is apart).
    let touching = table
        .lines()
        .filter(|l| l.split('|').nth(4) != Some(" 0 "))
        .count();
    assert!(
        touching > count / 2,
        "only {touching} of {count} cases touch"
    );
}

#[test]
fn the_cuda_mindlin_deresiewicz_law_computes_the_bits_of_the_rust_one() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = compile_twin(dir.path(), true) else {
        return;
    };
    let mut rand = common::noise(5);
    let hertz = ContactLaw::HertzMindlin {
        young_modulus: 1e7,
        poisson_ratio: 0.3,
    };
    let mut table = String::new();
    let mut count = 0;
    // The sliding coefficient, with the walls, the rolling resistance and the damping: sliding
    // in some cases, sticking in others; a reversal point in half of them.
    let materials = [
        (0.5, None, 0.1, RollingModel::Epsd, 0.5),
        (0.3, Some(0.1), 0.05, RollingModel::ConstantTorque, 0.9),
        (2.0, Some(0.0), 0.0, RollingModel::Epsd, 1.0),
        (0.0, Some(0.4), 0.0, RollingModel::Epsd, 0.7),
    ];
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
            cases::<LoadedSprings>(
                &Materials::one(material),
                1e-6,
                scale,
                &mut rand,
                &mut table,
            );
            count += 200;
        }
    }
    compare(&binary, &table, count);
}

#[test]
fn the_cuda_contact_law_computes_the_bits_of_the_rust_one() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = compile_twin(dir.path(), false) else {
        return;
    };
    let mut rand = common::noise(3);
    let hertz = ContactLaw::HertzMindlin {
        young_modulus: 1e7,
        poisson_ratio: 0.3,
    };
    let per_pair = ContactLaw::LinearPerPair {
        contact_time: Some(1e-4),
    };
    let mut table = String::new();
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
    let mut count = 0;
    for scale in [1.0, 2e-6, 4e-10] {
        for (contact, mu, mu_r, rolling_model, dt) in materials {
            let turns = mu > 0.0 || mu_r > 0.0;
            if scale < 1e-9 && turns {
                continue;
            }
            let contact = match contact {
                ContactLaw::LinearPerPair {
                    contact_time: Some(t),
                } => ContactLaw::LinearPerPair {
                    contact_time: Some(t * scale as f64),
                },
                other => other,
            };
            let material = Material {
                density: DENSITY,
                contact,
                friction: mu,
                rolling_friction: mu_r,
                rolling_model,
                ..Material::default()
            };
            cases::<Springs>(&Materials::one(material), dt, scale, &mut rand, &mut table);
            count += 200;
        }
    }
    compare(&binary, &table, count);
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

#[test]
fn the_cuda_law_of_several_materials_computes_the_bits_of_the_rust_one() {
    let dir = tempfile::tempdir().unwrap();
    let (Some(spring), Some(loaded)) = (
        compile_twin(dir.path(), false),
        compile_twin(dir.path(), true),
    ) else {
        return;
    };
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
    let (mut table, mut count) = (String::new(), 0);
    // At the tests' size and at radii of about 1e-8 m; without friction at about 2e-12 m too.
    for scale in [1.0, 2e-6, 4e-10] {
        for (contact, rolling_model, dt) in laws {
            let contact = match contact {
                ContactLaw::LinearPerPair {
                    contact_time: Some(t),
                } => ContactLaw::LinearPerPair {
                    contact_time: Some(t * scale as f64),
                },
                other => other,
            };
            let materials = three_materials(contact, rolling_model, mindlin);
            if scale > 1e-9 {
                cases::<Springs>(&materials, dt, scale, &mut rand, &mut table);
                count += 200;
            }
            cases::<Springs>(&frictionless(materials), dt, scale, &mut rand, &mut table);
            count += 200;
        }
    }
    compare(&spring, &table, count);
    let (mut table, mut count) = (String::new(), 0);
    for scale in [1.0, 2e-6] {
        for rolling_model in [RollingModel::Epsd, RollingModel::ConstantTorque] {
            let md = TangentialModel::MindlinDeresiewicz;
            let materials = three_materials(hertz, rolling_model, md);
            cases::<LoadedSprings>(&materials, 1e-6, scale, &mut rand, &mut table);
            count += 200;
        }
    }
    compare(&loaded, &table, count);
}
