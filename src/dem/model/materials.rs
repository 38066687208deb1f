//! Several materials in one scene (docs/method.md, "Several materials"): each sphere has one
//! (an index into the scene's list), each wall one or none (rigid), and every pair of materials
//! one contact law, mixed from the two or given by the scene.
//!
//! Mixing rules, where the scene gives no `[[material_pairs]]` for a pair:
//! - E* and G* from both bodies: 1/E* = (1 − ν_a²)/E_a + (1 − ν_b²)/E_b and
//!   1/G* = 2(2 − ν_a)(1 + ν_a)/E_a + 2(2 − ν_b)(1 + ν_b)/E_b (a rigid wall adds nothing);
//! - restitution, sliding and rolling friction: the smaller of the two (as Yade mixes friction
//!   angles): the more dissipative, less adhesive surface sets the contact;
//! - a sphere on a wall without a material (rigid): the sphere's own restitution and rolling
//!   friction, and the scene's `wall_friction` (else the sphere's friction).
//!
//! - a liquid bridge: the mean of the two contact angles' cosines for its pull, of the angles for
//!   its rupture distance ([`PairBridge::mixed`]); on a rigid wall, the sphere's own angle.
//!
//! The step reads a contact's coefficients from [`MaterialTable`], one [`PairLaw`] and one
//! [`PairBridge`] per ordered pair (sphere material, partner material or rigid wall); the GPU
//! engines upload the two side by side ([`TableLaw`], 48 bytes an entry).

use super::linear::{stable_dt, stiffness_for_duration};
use super::material::{ContactLaw, LiquidBridge, Material, check_contact_angle};
use super::restitution::{hertz_damping, linear_damping};
use super::time_step::{RAYLEIGH_LIMIT, rayleigh_time};
use crate::error::{Error, Result};
use crate::numbers::shown;
use bytemuck::{Pod, Zeroable};

/// The most materials a scene may have: a sphere's material is one byte.
pub const MAX_MATERIALS: usize = 256;

/// What the scene says of one pair of materials, overriding the mixing rules.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PairOverride {
    /// The two materials' indices (in either order).
    pub a: usize,
    /// See `a`.
    pub b: usize,
    /// Restitution coefficient of a head-on collision of the pair, in (0, 1].
    pub restitution: Option<f64>,
    /// Sliding friction coefficient μ of the pair.
    pub friction: Option<f64>,
    /// Rolling friction coefficient μ_r of the pair.
    pub rolling_friction: Option<f64>,
    /// Work of adhesion Γ of the pair \[J/m²\] (JKR).
    pub surface_energy: Option<f64>,
    /// Contact angle θ of the liquid on the pair \[rad\] (capillary; default: the materials'
    /// mixed by [`PairBridge::mixed`]).
    pub contact_angle: Option<f64>,
}

/// The materials of a scene: at least one; all share the contact law's kind, the rolling and
/// tangential models, a fixed stiffness and the walls' default friction (those of the first),
/// and differ in density, restitution, friction, rolling friction and (Hertz–Mindlin) E and ν.
#[derive(Debug, Clone, PartialEq)]
pub struct Materials {
    /// The materials in the scene's order; a sphere's material is its index here.
    pub list: Vec<Material>,
    /// Their names (as long as `list`).
    pub names: Vec<String>,
    /// Pairs whose coefficients the scene gives.
    pub pairs: Vec<PairOverride>,
}

impl Materials {
    /// One material, named "default".
    pub fn one(material: Material) -> Self {
        Self {
            list: vec![material],
            names: vec!["default".into()],
            pairs: Vec::new(),
        }
    }

    /// The first material: the one whose law-wide settings every material follows.
    pub fn first(&self) -> &Material {
        &self.list[0]
    }

    /// Refuses lists no step can use: none or more than [`MAX_MATERIALS`] materials, names
    /// given twice, materials that differ in what all share, a value out of range (named by
    /// the material), pairs naming no material.
    pub fn check(&self) -> Result<()> {
        let bad = |reason: String| {
            Err(Error::InvalidConfig {
                what: "scene materials".into(),
                reason,
            })
        };
        let n = self.list.len();
        if n == 0 || n > MAX_MATERIALS || self.names.len() != n {
            return bad(format!(
                "a scene has 1 to {MAX_MATERIALS} materials, got {n} (and {} names)",
                self.names.len()
            ));
        }
        for (k, name) in self.names.iter().enumerate() {
            if self.names[..k].contains(name) {
                return bad(format!("the material name \"{name}\" is given twice"));
            }
        }
        let first = self.first();
        for (m, name) in self.list.iter().zip(&self.names) {
            // One material is the scene's top-level keys: their own errors name them.
            match n {
                1 => m.check()?,
                _ => m.check().map_err(|e| Error::InvalidConfig {
                    what: format!("material \"{name}\""),
                    reason: e.to_string(),
                })?,
            }
            // A bridge's liquid is the scene's: each material differs only in how it wets.
            let liquid =
                |m: &Material| m.bridge.map(|b| (b.volume, b.surface_tension, b.viscosity));
            if liquid(m) != liquid(first) {
                return bad(format!(
                    "material \"{name}\" has a liquid other than the first's: give \
                     liquid_volume, surface_tension and liquid_viscosity once, at the top of \
                     the scene (each material may give its own contact_angle)"
                ));
            }
            let same_kind = std::mem::discriminant(&m.contact)
                == std::mem::discriminant(&first.contact)
                && match (m.contact, first.contact) {
                    (
                        ContactLaw::LinearPerPair { contact_time: a },
                        ContactLaw::LinearPerPair { contact_time: b },
                    ) => a == b,
                    _ => true,
                };
            if !same_kind
                || m.stiffness != first.stiffness
                || m.rolling_model != first.rolling_model
                || m.tangential_model != first.tangential_model
                || m.wall_friction != first.wall_friction
            {
                return bad(format!(
                    "material \"{name}\" differs from the first in what all materials share (the \
                     contact law, stiffness, contact_time, rolling_model, tangential_model, \
                     wall_friction): give those once, at the top of the scene"
                ));
            }
        }
        for p in &self.pairs {
            if p.a >= n || p.b >= n {
                return bad(format!(
                    "a material pair names material {} of {n}",
                    p.a.max(p.b)
                ));
            }
            let check = |key: &str, value: Option<f64>, ok: &dyn Fn(f64) -> bool| match value {
                Some(x) if !ok(x) => bad(format!(
                    "the pair \"{}\"–\"{}\" has {key} = {x}, out of range",
                    self.names[p.a], self.names[p.b]
                )),
                _ => Ok(()),
            };
            let coefficient = |x: f64| (0.0..=super::MAX_FRICTION).contains(&x);
            check("restitution", p.restitution, &|e| e > 0.0 && e <= 1.0)?;
            check("friction", p.friction, &coefficient)?;
            check("rolling_friction", p.rolling_friction, &coefficient)?;
            let energy = |g: f64| g == 0.0 || (g > 0.0 && (g as f32).is_normal());
            check("surface_energy", p.surface_energy, &energy)?;
            if let Some(angle) = p.contact_angle {
                if first.bridge.is_none() {
                    return bad(format!(
                        "the pair \"{}\"–\"{}\" has a contact_angle, which applies to \
                         cohesion = \"capillary\"",
                        self.names[p.a], self.names[p.b]
                    ));
                }
                check_contact_angle(angle).map_err(|e| Error::InvalidConfig {
                    what: format!("the pair \"{}\"–\"{}\"", self.names[p.a], self.names[p.b]),
                    reason: e.to_string(),
                })?;
            }
        }
        Ok(())
    }

    /// The override of the pair (a, b), if the scene gives one.
    fn pair_override(&self, a: usize, b: usize) -> PairOverride {
        self.pairs
            .iter()
            .rev()
            .find(|p| (p.a, p.b) == (a, b) || (p.a, p.b) == (b, a))
            .copied()
            .unwrap_or_default()
    }

    /// The coefficients (e, μ, μ_r) of material `a` against `b`, or against a rigid wall
    /// (`None`), by the rules of this module.
    pub fn coefficients(&self, a: usize, b: Option<usize>) -> (f64, f64, f64) {
        let ma = &self.list[a];
        match b {
            None => (
                ma.restitution,
                ma.wall_friction.unwrap_or(ma.friction),
                ma.rolling_friction,
            ),
            Some(b) => {
                let mb = &self.list[b];
                let given = self.pair_override(a, b);
                (
                    given
                        .restitution
                        .unwrap_or(ma.restitution.min(mb.restitution)),
                    given.friction.unwrap_or(ma.friction.min(mb.friction)),
                    given
                        .rolling_friction
                        .unwrap_or(ma.rolling_friction.min(mb.rolling_friction)),
                )
            }
        }
    }

    /// The smallest density of the materials \[kg/m³\]: the lightest sphere of a radius has it.
    pub fn lightest_density(&self) -> f64 {
        self.list
            .iter()
            .map(|m| m.density)
            .fold(f64::INFINITY, f64::min)
    }

    /// The largest density \[kg/m³\].
    pub fn heaviest_density(&self) -> f64 {
        self.list.iter().map(|m| m.density).fold(0.0, f64::max)
    }

    /// The materials in words for a run's summary line, where there are several: "3 materials:
    /// glass, steel, rubber", and how many pairs the scene gives; `None` for one material.
    pub fn describe(&self) -> Option<String> {
        let n = self.list.len();
        (n > 1).then(|| {
            let pairs = match self.pairs.len() {
                0 => String::new(),
                1 => " (1 pair given)".into(),
                k => format!(" ({k} pairs given)"),
            };
            format!("{n} materials: {}{pairs}", self.names.join(", "))
        })
    }
}

/// The law of one ordered pair of materials as the step computes it (f32), the layout the GPU
/// engines upload (`PairLaw` in wgsl/dem/dem_contact.wgsl, checked by `tests/bindings.rs`, and in
/// optix/contact.cuh).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, encase::ShaderType)]
pub struct PairLaw {
    /// k/m* of the per-pair linear law \[1/s²\] (0 for the others).
    pub rate: f32,
    /// E* of Hertz–Mindlin \[Pa\] (0 for the linear laws).
    pub e_star: f32,
    /// G* of Hertz–Mindlin \[Pa\] (0 for the linear laws).
    pub g_star: f32,
    /// Damping ratio ζ giving the pair's restitution.
    pub damping_ratio: f32,
    /// Sliding friction μ.
    pub sliding: f32,
    /// Rolling friction μ_r.
    pub rolling: f32,
    /// Work of adhesion Γ of the pair \[J/m²\] (JKR; 0: dry): the geometric mean of the two
    /// materials', or the sphere's own on a rigid wall. (Two scalars of 32 bytes, not an
    /// array: a uniform buffer holds this struct too.)
    pub adhesion: f32,
    /// Padding to 32 bytes.
    pub _pad1: f32,
}

/// The liquid bridge of one ordered pair of materials as the step computes it (f32; zeros
/// where the scene has no bridges), the layout the GPU engines upload beside [`PairLaw`]
/// ([`TableLaw`]).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, encase::ShaderType)]
pub struct PairBridge {
    /// γ·cos θ of the pair \[N/m\]: the bridge's pull at contact is 2π·2R*·γ·cos θ.
    pub tension: f32,
    /// The gap at which the bridge ruptures, (1 + θ/2)·V^⅓ (Lian et al. 1993) \[m\].
    pub rupture: f32,
    /// Padding to 16 bytes.
    pub _pad0: f32,
    /// Padding to 16 bytes.
    pub _pad1: f32,
}

impl PairBridge {
    /// The bridge of liquid `liquid` between two surfaces it wets at angles `a` and `b` \[rad\]:
    /// the pull's γ·cos θ the mean of the two, γ·(cos θ_a + cos θ_b)/2 (the Derjaguin
    /// approximation of a bridge between unlike surfaces, which Willett et al.'s closed form
    /// takes for equal ones), and the rupture gap at the mean angle, (1 + (θ_a + θ_b)/4)·V^⅓.
    /// Of one angle (a = b), exactly γ·cos θ and (1 + θ/2)·V^⅓.
    pub fn mixed(liquid: &LiquidBridge, a: f64, b: f64) -> Self {
        Self {
            tension: (liquid.surface_tension * ((a.cos() + b.cos()) / 2.0)) as f32,
            rupture: ((1.0 + (a + b) / 2.0 / 2.0) * liquid.volume.cbrt()) as f32,
            ..Self::default()
        }
    }
}

/// One entry of the material table as the GPU engines upload it: a pair's law and its bridge
/// (`TableLaw` in wgsl/dem/dem_contact.wgsl and `MochiTableLaw` in optix/physics.cuh).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, encase::ShaderType)]
pub struct TableLaw {
    /// The pair's law.
    pub law: PairLaw,
    /// The pair's liquid bridge.
    pub bridge: PairBridge,
}

/// Every pair's law: row a (a sphere of material a), column b < count (a sphere or a wall of
/// material b) or column `count` (a rigid wall); and each material's density.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialTable {
    /// Materials.
    pub count: usize,
    /// count × (count + 1) laws, row by row.
    pub laws: Vec<PairLaw>,
    /// The pairs' liquid bridges, as `laws` (zeros where the scene has no bridges).
    pub bridges: Vec<PairBridge>,
    /// Density of each material \[kg/m³\].
    pub densities: Vec<f32>,
}

/// What resolving the materials gives besides the table.
#[derive(Debug, Clone)]
pub(super) struct Resolved {
    pub table: MaterialTable,
    /// The largest stable time step over all pairs \[s\].
    pub dt_limit: f64,
    /// What sets it, in words.
    pub limited_by: String,
}

impl MaterialTable {
    /// The column of a rigid wall (a wall without a material).
    pub fn column_of_rigid_wall(&self) -> u32 {
        self.count as u32
    }

    /// The law of a sphere of material `a` against a sphere or wall of material `b`, or a
    /// rigid wall (`b` = [`Self::column_of_rigid_wall`]).
    #[inline(always)]
    pub fn law(&self, a: u32, b: u32) -> &PairLaw {
        &self.laws[a as usize * (self.count + 1) + b as usize]
    }

    /// The liquid bridge of a sphere of material `a` against column `b` (as [`Self::law`]).
    #[inline(always)]
    pub fn bridge(&self, a: u32, b: u32) -> &PairBridge {
        &self.bridges[a as usize * (self.count + 1) + b as usize]
    }

    /// The table as the GPU engines upload it: each pair's law beside its bridge.
    pub fn device_laws(&self) -> Vec<TableLaw> {
        self.laws
            .iter()
            .zip(&self.bridges)
            .map(|(&law, &bridge)| TableLaw { law, bridge })
            .collect()
    }

    /// The widest gap at which any pair's bridge holds \[m\] (0 without bridges).
    pub fn widest_rupture(&self) -> f32 {
        self.bridges.iter().map(|b| b.rupture).fold(0.0, f32::max)
    }

    /// Mass of a sphere of material `a` and radius `r` \[kg\].
    #[inline(always)]
    pub fn mass(&self, a: u32, r: f32) -> f32 {
        super::mass(self.densities[a as usize], r)
    }

    /// The largest of `f` over the laws of the columns `columns` of every row.
    fn largest(&self, columns: std::ops::Range<usize>, f: impl Fn(&PairLaw) -> f32) -> f32 {
        self.laws
            .chunks(self.count + 1)
            .flat_map(|row| &row[columns.clone()])
            .map(f)
            .fold(0.0, f32::max)
    }

    /// The largest sliding friction of two spheres' or a sphere's and a wall of a material.
    pub fn largest_sliding(&self) -> f32 {
        self.largest(0..self.count, |l| l.sliding)
    }

    /// The largest sliding friction with a rigid wall.
    pub fn largest_rigid_wall_sliding(&self) -> f32 {
        self.largest(self.count..self.count + 1, |l| l.sliding)
    }

    /// The largest rolling friction of any pair.
    pub fn largest_rolling(&self) -> f32 {
        self.largest(0..self.count + 1, |l| l.rolling)
    }

    /// Resolves `materials` (checked) for time step `dt`, a fixed stiffness `stiffness` (0 for
    /// the other laws) and the lightest pair's effective mass `m_eff` (the smallest density at
    /// the smallest radius `r_min`).
    pub(super) fn resolve(
        materials: &Materials,
        dt: f64,
        stiffness: f64,
        r_min: f32,
        m_eff: f64,
    ) -> Result<Resolved> {
        let count = materials.list.len();
        let mut laws = Vec::with_capacity(count * (count + 1));
        let mut bridges = Vec::with_capacity(count * (count + 1));
        let mut dt_limit = f64::INFINITY;
        let mut limited_by = String::new();
        let mut limit = |t: f64, why: &dyn Fn() -> String| {
            if t < dt_limit {
                dt_limit = t;
                limited_by = why();
            }
        };
        let name = |b: Option<usize>| match b {
            Some(b) => format!("\"{}\"", materials.names[b]),
            None => "a rigid wall".into(),
        };
        for a in 0..count {
            let ma = &materials.list[a];
            for b in (0..count).map(Some).chain([None]) {
                let (e, mu, mu_r) = materials.coefficients(a, b);
                let adhesion = match b {
                    Some(b) => materials
                        .pair_override(a, b)
                        .surface_energy
                        .unwrap_or((ma.adhesion * materials.list[b].adhesion).sqrt()),
                    None => ma.adhesion,
                };
                let angle = |m: &Material| m.bridge.map_or(0.0, |b| b.contact_angle);
                bridges.push(match ma.bridge {
                    None => PairBridge::default(),
                    Some(liquid) => match b {
                        Some(b) => match materials.pair_override(a, b).contact_angle {
                            Some(theta) => PairBridge::mixed(&liquid, theta, theta),
                            None => {
                                PairBridge::mixed(&liquid, angle(ma), angle(&materials.list[b]))
                            }
                        },
                        None => PairBridge::mixed(&liquid, angle(ma), angle(ma)),
                    },
                });
                let mut law = PairLaw {
                    sliding: mu as f32,
                    rolling: mu_r as f32,
                    adhesion: adhesion as f32,
                    ..PairLaw::default()
                };
                let pair = || format!("\"{}\" on {}", materials.names[a], name(b));
                match ma.contact {
                    ContactLaw::Linear => {
                        let zeta = linear_damping(e, dt * (stiffness / m_eff).sqrt())?;
                        law.damping_ratio = zeta as f32;
                        limit(stable_dt(stiffness, m_eff, zeta), &|| {
                            format!(
                                "stiffness {} N/m, the lightest spheres (r = {} m, density \
                                 {}) and {} (e = {e})",
                                shown(stiffness),
                                shown(r_min),
                                shown(materials.lightest_density()),
                                pair()
                            )
                        });
                    }
                    ContactLaw::LinearPerPair { contact_time } => {
                        let t_c = contact_time.unwrap_or(super::STEPS_PER_CONTACT * dt);
                        let rate = stiffness_for_duration(1.0, e, t_c);
                        let zeta = linear_damping(e, dt * rate.sqrt())?;
                        law.rate = rate as f32;
                        law.damping_ratio = zeta as f32;
                        limit(stable_dt(rate, 1.0, zeta), &|| {
                            format!(
                                "a per-pair stiffness with contact time {} s ({}, e = {e})",
                                shown(t_c),
                                pair()
                            )
                        });
                    }
                    ContactLaw::HertzMindlin {
                        young_modulus,
                        poisson_ratio,
                    } => {
                        let compliance = |m: &Material| match m.contact {
                            ContactLaw::HertzMindlin {
                                young_modulus: y,
                                poisson_ratio: nu,
                            } => ((1.0 - nu * nu) / y, 2.0 * (2.0 - nu) * (1.0 + nu) / y),
                            _ => (0.0, 0.0),
                        };
                        let (ca, ga) = compliance(ma);
                        let (cb, gb) = b.map_or((0.0, 0.0), |b| compliance(&materials.list[b]));
                        law.e_star = (1.0 / (ca + cb)) as f32;
                        law.g_star = (1.0 / (ga + gb)) as f32;
                        law.damping_ratio = hertz_damping(e) as f32;
                        if !(law.e_star.is_normal() && law.g_star.is_normal()) {
                            return Err(Error::InvalidConfig {
                                what: format!("material \"{}\"", materials.names[a]),
                                reason: format!(
                                    "young_modulus {} Pa gives effective moduli outside \
                                     f32's range with {}",
                                    shown(young_modulus),
                                    name(b)
                                ),
                            });
                        }
                        if b.is_none() {
                            let t_r = rayleigh_time(
                                r_min as f64,
                                ma.density,
                                young_modulus,
                                poisson_ratio,
                            );
                            limit(RAYLEIGH_LIMIT * t_r, &|| {
                                format!(
                                    "Hertz–Mindlin with E = {} Pa, ν = {poisson_ratio}, \
                                     density {} (material \"{}\") and the smallest spheres (r \
                                     = {} m, Rayleigh time {} s; the limit is \
                                     {RAYLEIGH_LIMIT} of it)",
                                    shown(young_modulus),
                                    shown(ma.density),
                                    materials.names[a],
                                    shown(r_min),
                                    shown(t_r)
                                )
                            });
                        }
                    }
                }
                laws.push(law);
            }
        }
        Ok(Resolved {
            table: MaterialTable {
                count,
                laws,
                bridges,
                densities: materials.list.iter().map(|m| m.density as f32).collect(),
            },
            dt_limit,
            limited_by,
        })
    }
}

/// `$check!("PairLaw", PairLaw { every field })`: the one list of [`PairLaw`]'s fields, which
/// the WGSL layout check and the CUDA one (`MochiPairLaw`) both take.
macro_rules! pair_law_fields {
    ($check:ident, $cuda:literal) => {
        $check!(
            $cuda,
            PairLaw {
                rate,
                e_star,
                g_star,
                damping_ratio,
                sliding,
                rolling,
                adhesion,
                _pad1,
            }
        )
    };
}
pub(crate) use pair_law_fields;

/// `$check!("PairBridge", PairBridge { every field })`: the one list of [`PairBridge`]'s
/// fields, for the WGSL and the CUDA layout checks (`MochiPairBridge`).
macro_rules! pair_bridge_fields {
    ($check:ident, $cuda:literal) => {
        $check!(
            $cuda,
            PairBridge {
                tension,
                rupture,
                _pad0,
                _pad1,
            }
        )
    };
}
pub(crate) use pair_bridge_fields;

/// `$check!("TableLaw", TableLaw { every field })`: the one list of [`TableLaw`]'s fields, for
/// the WGSL and the CUDA layout checks (`MochiTableLaw`).
macro_rules! table_law_fields {
    ($check:ident, $cuda:literal) => {
        $check!($cuda, TableLaw { law, bridge })
    };
}
pub(crate) use table_law_fields;

impl crate::gpu::shader::FirstWord for PairLaw {
    fn first_word(&self) -> u32 {
        self.rate.to_bits()
    }
}

impl crate::gpu::shader::FirstWord for PairBridge {
    fn first_word(&self) -> u32 {
        self.tension.to_bits()
    }
}
