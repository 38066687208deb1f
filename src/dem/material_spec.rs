//! The `[[material]]` and `[[material_pair]]` tables of a scene file and the materials they make
//! (docs/method.md, "Several materials").
//!
//! ```toml
//! contact = "hertz-mindlin"
//! friction = 0.4               # top-level keys: the default of every material's missing keys
//!
//! [[material]]                 # material 0: spheres without a material column are of it
//! name = "glass"
//! young_modulus = 6.3e10       # Pa (hertz-mindlin)
//! poisson_ratio = 0.24
//! density = 2500               # kg/m³
//! restitution = 0.9
//! friction = 0.3
//! rolling_friction = 0.01
//!
//! [[material]]
//! name = "steel"
//! young_modulus = 2.0e11
//! poisson_ratio = 0.3
//! density = 7800
//!
//! [[material_pair]]            # overrides the mixing rules for one pair
//! materials = ["glass", "steel"]
//! restitution = 0.8
//! friction = 0.2
//!
//! box_material = "steel"       # the box's walls (default: rigid)
//! [[wall]]
//! mesh = "hopper.stl"
//! material = "steel"           # a mesh wall's (default: rigid)
//! [[inflow]]
//! material = "glass"           # the spheres an inflow inserts (default: the first material)
//! ```
//!
//! Without `[[material]]` tables the scene has one material, the top-level keys'. Spheres choose
//! theirs by the `material` column of a CSV input, the 11th column of a `.npy` input (the
//! index in the order of the tables, from 0).

use super::model::{ContactLaw, MAX_MATERIALS, Material, Materials, PairOverride};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// One `[[material]]` table: a name and the values that differ from the scene's defaults.
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
}

/// One `[[material_pair]]` table: the coefficients of a pair of materials, where the mixing
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
                    format!("names material \"{name}\", but the scene has no [[material]] tables")
                }
                false => format!(
                    "names material \"{name}\", which is not one of the [[material]] tables ({})",
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
                what: "scene key material_pair".into(),
                reason: "needs [[material]] tables to name".into(),
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
            Ok(Material {
                density: t.density.unwrap_or(base.density),
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
                a: material_index(tables, a, "material_pair.materials")?,
                b: material_index(tables, b, "material_pair.materials")?,
                restitution: p.restitution,
                friction: p.friction,
                rolling_friction: p.rolling_friction,
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

#[cfg(test)]
mod tests {
    use crate::dem::model::{ContactLaw, StepParams};
    use crate::dem::scene::SceneConfig;

    fn scene(text: &str) -> crate::error::Result<SceneConfig> {
        SceneConfig::parse(Some(text), None, &[])
    }

    const TWO: &str = r#"
        friction = 0.4
        [[material]]
        name = "glass"
        young_modulus = 6.3e10
        poisson_ratio = 0.24
        density = 2500
        restitution = 0.9
        rolling_friction = 0.01
        [[material]]
        name = "steel"
        young_modulus = 2.0e11
        poisson_ratio = 0.3
        density = 7800
        friction = 0.3
        [[material_pair]]
        materials = ["steel", "glass"]
        restitution = 0.8
    "#;

    #[test]
    fn material_tables_take_the_top_level_keys_as_defaults_and_pairs_override_the_mixing() {
        let s = scene(TWO).unwrap();
        let m = s.materials().unwrap();
        assert_eq!(m.names, ["glass", "steel"]);
        let (glass, steel) = (&m.list[0], &m.list[1]);
        assert_eq!((glass.friction, steel.friction), (0.4, 0.3));
        assert_eq!((glass.density, steel.density), (2500.0, 7800.0));
        // The scene's default restitution (0.5) where a table gives none.
        assert_eq!((glass.restitution, steel.restitution), (0.9, 0.5));
        assert!(matches!(
            steel.contact,
            ContactLaw::HertzMindlin { young_modulus, .. } if young_modulus == 2.0e11
        ));
        // Restitution: the pair's own; friction and rolling friction: the smaller.
        // (Steel's rolling friction is the scene's default, 0.1.)
        assert_eq!(m.coefficients(0, Some(1)), (0.8, 0.3, 0.01));
        assert_eq!(m.coefficients(1, Some(0)), (0.8, 0.3, 0.01));
        assert_eq!(m.coefficients(0, Some(0)), (0.9, 0.4, 0.01));
        // A rigid wall: the sphere's own, friction the scene's wall friction (here μ).
        assert_eq!(m.coefficients(1, None), (0.5, 0.3, 0.1));
    }

    #[test]
    fn the_table_mixes_the_moduli_of_both_bodies_and_the_time_step_follows_the_stiffest() {
        let s = scene(TWO).unwrap();
        let m = s.materials().unwrap();
        let p =
            StepParams::with_materials(&m, Some(1), 1e-7, [0.0; 3], [1.0; 3], [0.0; 3], 0.0, 0.001)
                .unwrap();
        let t = &p.materials;
        assert_eq!((t.count, t.laws.len(), p.box_column), (2, 6, 1));
        let c = |e: f64, nu: f64| (1.0 - nu * nu) / e;
        let mixed = 1.0 / (c(6.3e10, 0.24) + c(2.0e11, 0.3));
        assert_eq!(t.law(0, 1).e_star, mixed as f32);
        assert_eq!(t.law(1, 0), t.law(0, 1));
        assert_eq!(t.law(0, 0).e_star, (1.0 / (2.0 * c(6.3e10, 0.24))) as f32);
        assert_eq!(
            t.law(0, 2).e_star,
            (1.0 / c(6.3e10, 0.24)) as f32,
            "rigid wall"
        );
        assert_eq!((t.law(0, 1).sliding, t.law(0, 0).rolling), (0.3, 0.01));
        assert_eq!(t.densities, [2500.0, 7800.0]);
        // The shorter Rayleigh time (glass's, by 1%) sets the limit.
        let rayleigh = |e: f64, nu: f64, rho: f64| {
            crate::dem::model::time_step::rayleigh_time(0.001, rho, e, nu)
        };
        let limit = 0.5 * rayleigh(6.3e10, 0.24, 2500.0);
        assert!(rayleigh(6.3e10, 0.24, 2500.0) < rayleigh(2.0e11, 0.3, 7800.0));
        assert!(
            (p.dt_limit as f64 / limit - 1.0).abs() < 1e-6,
            "{} {limit}",
            p.dt_limit
        );
        let e = StepParams::with_materials(
            &m,
            None,
            1.01 * limit,
            [0.0; 3],
            [1.0; 3],
            [0.0; 3],
            0.0,
            0.001,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("\"glass\""), "{e}");
    }

    #[test]
    fn bad_material_tables_are_one_clear_error() {
        let err = |text: &str| {
            let s = scene(text).and_then(|s| s.build().map(|_| s));
            s.unwrap_err().to_string()
        };
        let e = err("[[material]]\nname = \"a\"\n[[material]]\nname = \"a\"\n");
        assert!(e.contains("\"a\" is given twice"), "{e}");
        let e = err("box_material = \"b\"\n[[material]]\nname = \"a\"\n");
        assert!(
            e.contains("box_material") && e.contains("\"b\"") && e.contains("\"a\""),
            "{e}"
        );
        let e = err("box_material = \"b\"\n");
        assert!(e.contains("no [[material]] tables"), "{e}");
        let e = err("[[material]]\nname = \"a\"\nrestitution = 1.5\n[[material]]\nname = \"b\"\n");
        assert!(
            e.contains("material \"a\"") && e.contains("restitution"),
            "{e}"
        );
        let e = err("contact = \"linear\"\n[[material]]\nname = \"a\"\nyoung_modulus = 1e9\n");
        assert!(e.contains("hertz-mindlin"), "{e}");
        let e = err("[[material]]\nname = \"a\"\n[[material_pair]]\nmaterials = [\"a\", \"c\"]\n");
        assert!(e.contains("\"c\""), "{e}");
        let e = err("[[material]]\nname = \"a\"\ncolour = 3\n");
        assert!(e.contains("colour"), "{e}");
        let many: String = (0..257)
            .map(|k| format!("[[material]]\nname = \"m{k}\"\n"))
            .collect();
        assert!(err(&many).contains("at most 256"));
    }
}
