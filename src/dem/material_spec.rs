//! The `[[materials]]` and `[[material_pairs]]` tables of a scene file and the materials they
//! make (docs/method.md, "Several materials"). Their short forms are `[[materials]]` and
//! `[[material_pairs]]`.
//!
//! ```toml
//! [domain]
//! box_material = "steel"       # the box's walls (default: rigid)
//!
//! [material]
//! contact = "hertz-mindlin"
//! friction = 0.4               # the default of every material's missing keys
//!
//! [[materials]]                # material 0: spheres without a material column are of it
//! name = "glass"
//! young_modulus = 6.3e10       # Pa (hertz-mindlin)
//! poisson_ratio = 0.24
//! density = 2500               # kg/m³
//! restitution = 0.9
//! friction = 0.3
//! rolling_friction = 0.01
//!
//! [[materials]]
//! name = "steel"
//! young_modulus = 2.0e11
//! poisson_ratio = 0.3
//! density = 7800
//!
//! [[material_pairs]]           # overrides the mixing rules for one pair
//! materials = ["glass", "steel"]
//! restitution = 0.8
//! # surface_energy = 0.02      # Γ of the pair (cohesion = "jkr"; each material may give its own)
//! # contact_angle = 30         # θ of the liquid on the pair, degrees (cohesion = "capillary";
//! #                            # each material may give its own, the walls' too)
//! friction = 0.2
//!
//! [[wall]]
//! mesh = "hopper.stl"
//! material = "steel"           # a mesh wall's (default: rigid)
//! [[inflow]]
//! material = "glass"           # the spheres an inflow inserts (default: the first material)
//! ```
//!
//! Without `[[materials]]` tables the scene has one material, its `[material]`. Spheres choose
//! theirs by the `material` column of a CSV input, the 11th column of a `.npy` input (the
//! index in the order of the tables, from 0).

use super::model::{ContactLaw, LiquidBridge, MAX_MATERIALS, Material, Materials, PairOverride};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// One `[[materials]]` table: a name and the values that differ from the scene's defaults.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialConfig {
    /// What walls, inflows and pairs call it.
    pub name: String,
    /// Young's modulus \[Pa\] (`hertz-mindlin`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub young_modulus: Option<f64>,
    /// Poisson's ratio (`hertz-mindlin`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poisson_ratio: Option<f64>,
    /// Density \[kg/m³\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<f64>,
    /// Restitution coefficient of two spheres of it, in (0, 1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restitution: Option<f64>,
    /// Sliding friction coefficient of two spheres of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
    /// Rolling friction coefficient of two spheres of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rolling_friction: Option<f64>,
    /// Work of adhesion Γ of two surfaces of it \[J/m²\] (`cohesion = "jkr"`; 0: it does not
    /// adhere).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_energy: Option<f64>,
    /// Contact angle of the bridges' liquid on it \[degrees\] (`cohesion = "capillary"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_angle: Option<f64>,
}

/// One `[[material_pairs]]` table: the coefficients of a pair of materials, where the mixing
/// rules are not wanted.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialPairConfig {
    /// The two materials' names (the same name twice: the material with itself).
    pub materials: [String; 2],
    /// Restitution coefficient of the pair, in (0, 1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restitution: Option<f64>,
    /// Sliding friction coefficient of the pair.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
    /// Rolling friction coefficient of the pair.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rolling_friction: Option<f64>,
    /// Work of adhesion Γ of the pair \[J/m²\] (`cohesion = "jkr"`; default: the geometric
    /// mean of the two materials').
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_energy: Option<f64>,
    /// Contact angle of the bridges' liquid on the pair \[degrees\] (`cohesion = "capillary"`;
    /// default: mixed from the two materials', see
    /// [`PairBridge::mixed`](super::model::PairBridge::mixed)).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_angle: Option<f64>,
}

/// The error of a `contact_angle` in `what` of a scene whose cohesion is not capillary.
fn capillary_only(what: &str) -> Error {
    Error::InvalidConfig {
        what: format!("scene key contact_angle of {what}"),
        reason: "applies to cohesion = \"capillary\" (with a liquid_volume at the top of the \
                 scene)"
            .into(),
    }
}

/// The error of a `surface_energy` in `what` of a scene whose cohesion is not JKR.
fn jkr_only(what: &str) -> Error {
    Error::InvalidConfig {
        what: format!("scene key surface_energy of {what}"),
        reason: "applies to cohesion = \"jkr\" (with a surface_energy at the top of the scene)"
            .into(),
    }
}

/// The index of the material called `name` in `tables`, or an error naming `user` (the key
/// that named it) and the names there are.
pub fn material_index(tables: &[MaterialConfig], name: &str, user: &str) -> Result<usize> {
    tables
        .iter()
        .position(|m| m.name == name)
        .ok_or_else(|| Error::InvalidConfig {
            what: format!("scene key {user}"),
            reason: match tables.is_empty() {
                true => {
                    format!("names material \"{name}\", but the scene has no [[materials]] tables")
                }
                false => format!(
                    "names material \"{name}\", which is not one of the [[materials]] tables ({})",
                    tables
                        .iter()
                        .map(|m| format!("\"{}\"", m.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            },
        })
}

/// The materials of `tables` and `pairs`, each missing key taken from `base` (the scene's
/// top-level material); `base` alone where there are no tables.
pub fn materials(
    base: &Material,
    tables: &[MaterialConfig],
    pairs: &[MaterialPairConfig],
) -> Result<Materials> {
    if tables.is_empty() {
        if !pairs.is_empty() {
            return Err(Error::InvalidConfig {
                what: "scene key material_pairs".into(),
                reason: "needs [[materials]] tables to name".into(),
            });
        }
        return Ok(Materials::one(*base));
    }
    if tables.len() > MAX_MATERIALS {
        return Err(Error::InvalidConfig {
            what: "scene key material".into(),
            reason: format!(
                "a scene has at most {MAX_MATERIALS} materials, got {}",
                tables.len()
            ),
        });
    }
    let list = tables
        .iter()
        .map(|t| {
            let contact = match base.contact {
                ContactLaw::HertzMindlin {
                    young_modulus,
                    poisson_ratio,
                } => ContactLaw::HertzMindlin {
                    young_modulus: t.young_modulus.unwrap_or(young_modulus),
                    poisson_ratio: t.poisson_ratio.unwrap_or(poisson_ratio),
                },
                other => {
                    if t.young_modulus.is_some() || t.poisson_ratio.is_some() {
                        return Err(Error::InvalidConfig {
                            what: format!("material \"{}\"", t.name),
                            reason: "young_modulus and poisson_ratio apply to contact = \
                                     \"hertz-mindlin\" only"
                                .into(),
                        });
                    }
                    other
                }
            };
            if t.surface_energy.is_some() && base.adhesion == 0.0 {
                return Err(jkr_only(&format!("material \"{}\"", t.name)));
            }
            let bridge = match (base.bridge, t.contact_angle) {
                (Some(liquid), Some(degrees)) => Some(LiquidBridge {
                    contact_angle: degrees.to_radians(),
                    ..liquid
                }),
                (None, Some(_)) => return Err(capillary_only(&format!("material \"{}\"", t.name))),
                (liquid, None) => liquid,
            };
            Ok(Material {
                bridge,
                density: t.density.unwrap_or(base.density),
                adhesion: t.surface_energy.unwrap_or(base.adhesion),
                restitution: t.restitution.unwrap_or(base.restitution),
                friction: t.friction.unwrap_or(base.friction),
                rolling_friction: t.rolling_friction.unwrap_or(base.rolling_friction),
                contact,
                ..*base
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let pairs = pairs
        .iter()
        .map(|p| {
            let [a, b] = &p.materials;
            Ok(PairOverride {
                a: material_index(tables, a, "material_pairs.materials")?,
                b: material_index(tables, b, "material_pairs.materials")?,
                restitution: p.restitution,
                friction: p.friction,
                rolling_friction: p.rolling_friction,
                surface_energy: match (p.surface_energy, base.adhesion) {
                    (Some(_), 0.0) => return Err(jkr_only("a [[material_pairs]] table")),
                    (given, _) => given,
                },
                contact_angle: match (p.contact_angle, base.bridge) {
                    (Some(_), None) => return Err(capillary_only("a [[material_pairs]] table")),
                    (given, _) => given.map(f64::to_radians),
                },
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let materials = Materials {
        list,
        names: tables.iter().map(|t| t.name.clone()).collect(),
        pairs,
    };
    materials.check()?;
    Ok(materials)
}
