//! What a scene's material says (in SI units, as the user gives it) and what the step makes of
//! it (f32 coefficients): the normal law, the effective elastic moduli of Hertz–Mindlin, and the
//! friction coefficients.

use super::linear::{STEPS_PER_CONTACT, stiffness_for_duration};
use super::time_step::rayleigh_time;
use crate::error::{Error, Result};
use crate::numbers::shown;
use serde::{Deserialize, Serialize};

/// The normal contact law and where its stiffness comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactLaw {
    /// Linear spring–dashpot with one stiffness for every contact: [`Material::stiffness`], or
    /// derived so that the lightest pair's contact lasts
    /// [`STEPS_PER_CONTACT`] steps (the paper's model).
    Linear,
    /// Linear spring–dashpot whose stiffness follows each contact's effective mass,
    /// k = m*·(π² + ln² e)/t_c², so every contact lasts `contact_time` t_c \[s\]
    /// (`None`: [`STEPS_PER_CONTACT`] time steps).
    LinearPerPair {
        /// Contact duration t_c \[s\].
        contact_time: Option<f64>,
    },
    /// Hertz normal force and Mindlin tangential spring, Tsuji damping (Hertz 1882, Mindlin
    /// 1949, Tsuji et al. 1992).
    HertzMindlin {
        /// Young's modulus E \[Pa\]; soft values (1e6–1e8 Pa instead of GPa) are usual practice,
        /// as the time step grows with 1/√E.
        young_modulus: f64,
        /// Poisson's ratio ν, in (−1, 0.5).
        poisson_ratio: f64,
    },
}

/// How rolling is resisted (Ai et al., Powder Technology 206 (2011) 269–282).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[repr(u32)]
pub enum RollingModel {
    /// Elastic–plastic spring (Ai et al.'s type C, LIGGGHTS `epsd2`): a rolling spring of
    /// stiffness 2.25·S_n·μ_r²·R*² accumulates torque, capped at μ_r·R*·|F_n|. Holds a heap's
    /// slope at rest.
    #[default]
    Epsd = 0,
    /// Constant torque μ_r·R*·|F_n| against the relative rolling (Ai et al.'s type A, EDEM's
    /// default), clipped so it never reverses the rolling within a step.
    ConstantTorque = 1,
}

impl RollingModel {
    /// The model's code on the devices (`ROLLING_*` in `wgsl/dem/dem_contact.wgsl`,
    /// `MOCHI_ROLLING_*` in `optix/contact.cuh`).
    pub fn code(self) -> u32 {
        self as u32
    }
}

/// How the tangential force follows the tangential displacement of a contact
/// (docs/method.md, "Friction, rotation and rolling resistance").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TangentialModel {
    /// Mindlin's no-slip spring (Mindlin 1949): a spring ξ of stiffness S_t = 8G*√(R*δ) holds
    /// F_t = −S_t·ξ up to Coulomb's cap (LIGGGHTS `tangential history`, EDEM's Hertz–Mindlin).
    /// Follows gross sliding; in the stick regime of oblique impacts it releases its force
    /// with the contact's stiffness, not with its load history.
    #[default]
    Mindlin,
    /// Mindlin and Deresiewicz's load-history dependent stiffness (Mindlin & Deresiewicz
    /// 1953) in the incremental form of Thornton & Yin (1991) as Thornton, Cummins & Cleary
    /// (2011) restate it: the stiffness falls as the force nears μ·N on the virgin curve, or
    /// twice that from the last reversal, and the force follows the normal force's changes.
    /// Hertz–Mindlin only.
    MindlinDeresiewicz,
}

/// A material and its contact law, as the user describes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Density \[kg/m³\] (default 500).
    pub density: f64,
    /// Restitution coefficient of a head-on collision, in (0, 1] (default 0.5).
    pub restitution: f64,
    /// Normal stiffness k \[N/m\] of [`ContactLaw::Linear`]; `None` derives it so that a
    /// collision of the two lightest spheres lasts
    /// [`STEPS_PER_CONTACT`] time steps. Only for that law.
    pub stiffness: Option<f64>,
    /// The normal law (default: [`ContactLaw::Linear`]).
    pub contact: ContactLaw,
    /// Sliding friction coefficient μ between spheres, ≥ 0 (default 0: no tangential force).
    pub friction: f64,
    /// Sliding friction coefficient with the walls, ≥ 0 (`None`: `friction`).
    pub wall_friction: Option<f64>,
    /// Rolling friction coefficient μ_r, ≥ 0 (default 0: no rolling resistance).
    pub rolling_friction: f64,
    /// Rolling resistance model (default: EPSD).
    pub rolling_model: RollingModel,
    /// Tangential model (default: Mindlin's no-slip spring).
    pub tangential_model: TangentialModel,
    /// Work of adhesion Γ of two surfaces of this material \[J/m²\] (JKR cohesion, with
    /// Hertz–Mindlin; default 0: dry). Two spheres pull off at 1.5·π·Γ·R*.
    pub adhesion: f64,
    /// The liquid bridges between the spheres and with the walls (capillary cohesion; default
    /// none: dry).
    pub bridge: Option<LiquidBridge>,
    /// Cohesion energy density k \[J/m³\] of LIGGGHTS' simplified JKR (`sjkr`): touching
    /// bodies attract with k times their contact area (default 0: none).
    pub cohesion_density: f64,
}

/// Pendular liquid bridges: each contact that forms wets a bridge of one volume, which pulls
/// the bodies together until it ruptures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiquidBridge {
    /// Liquid volume of a bridge V \[m³\].
    pub volume: f64,
    /// Surface tension of the liquid γ \[N/m\].
    pub surface_tension: f64,
    /// Contact angle θ of the liquid on the solid \[rad\], in [0, π/2).
    pub contact_angle: f64,
    /// Dynamic viscosity η of the liquid \[Pa·s\]: the bridge's lubrication force (the contact
    /// law's `bridge_drag`) resists the bodies' normal motion; 0: none.
    pub viscosity: f64,
}

/// Refuses a contact angle `angle` \[rad\] outside [0, π/2): a liquid that does not wet the
/// solid makes no pendular bridge that pulls.
pub(super) fn check_contact_angle(angle: f64) -> Result<()> {
    match (0.0..std::f64::consts::FRAC_PI_2).contains(&angle) {
        true => Ok(()),
        false => Err(Error::InvalidConfig {
            what: "scene key contact_angle".into(),
            reason: format!(
                "must be from 0 up to (not including) 90°, got {}°",
                angle.to_degrees()
            ),
        }),
    }
}

impl Default for Material {
    fn default() -> Self {
        Self {
            density: 500.0,
            restitution: 0.5,
            stiffness: None,
            contact: ContactLaw::Linear,
            friction: 0.0,
            wall_friction: None,
            rolling_friction: 0.0,
            rolling_model: RollingModel::Epsd,
            tangential_model: TangentialModel::Mindlin,
            adhesion: 0.0,
            bridge: None,
            cohesion_density: 0.0,
        }
    }
}

/// The normal law as the step computes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NormalLaw {
    /// k = [`StepParams::stiffness`](super::StepParams::stiffness) for every contact.
    Linear,
    /// k = m*·`rate` for each contact \[1/s²\] (`rate` = (π² + ln² e)/t_c²).
    LinearPerPair {
        /// k/m* of every contact \[1/s²\].
        rate: f32,
        /// The contact duration it gives \[s\].
        contact_time: f32,
    },
    /// Hertz–Mindlin with the effective moduli of a sphere pair and of a sphere on a wall.
    Hertz {
        /// Two spheres of the material.
        pair: Elastic,
        /// A sphere on a rigid wall.
        wall: Elastic,
    },
}

/// Effective moduli of a contact (physics notation: E*, G*).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Elastic {
    /// E* \[Pa\]: 1/E* = Σ (1 − ν²)/E over the two bodies (a rigid wall adds nothing).
    pub e_star: f32,
    /// G* \[Pa\]: 1/G* = Σ 2(2 − ν)(1 + ν)/E over the two bodies (a rigid wall adds nothing).
    pub g_star: f32,
}

impl Elastic {
    /// Two spheres of modulus `young_modulus` and Poisson's ratio `nu`.
    pub fn pair(young_modulus: f64, nu: f64) -> Self {
        Self::of_bodies(young_modulus, nu, 2.0)
    }

    /// A sphere on a rigid wall.
    pub fn wall(young_modulus: f64, nu: f64) -> Self {
        Self::of_bodies(young_modulus, nu, 1.0)
    }

    fn of_bodies(e: f64, nu: f64, bodies: f64) -> Self {
        Self {
            e_star: (e / (bodies * (1.0 - nu * nu))) as f32,
            g_star: (e / (bodies * 2.0 * (2.0 - nu) * (1.0 + nu))) as f32,
        }
    }
}

/// Friction coefficients as the step uses them.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Friction {
    /// μ between spheres.
    pub sliding: f32,
    /// μ with the walls.
    pub wall_sliding: f32,
    /// μ_r, between spheres and with the walls.
    pub rolling: f32,
    /// How rolling is resisted.
    pub rolling_model: RollingModel,
    /// How the tangential force follows the displacement.
    pub tangential_model: TangentialModel,
    /// Whether some pair adheres (JKR): its contacts outlast their overlap, so every contact
    /// is remembered from step to step.
    pub cohesive: bool,
}

impl Friction {
    /// Whether any contact has a tangential force or a rolling torque: the spheres then turn.
    pub fn turns(&self) -> bool {
        self.sliding > 0.0 || self.wall_sliding > 0.0 || self.rolling > 0.0
    }

    /// Whether contacts carry springs from one step to the next (tangential, or EPSD rolling).
    pub fn has_history(&self) -> bool {
        self.cohesive
            || self.sliding > 0.0
            || self.wall_sliding > 0.0
            || (self.rolling > 0.0 && self.rolling_model == RollingModel::Epsd)
    }

    /// Whether contacts keep the Mindlin–Deresiewicz model's load history besides their
    /// springs (its tangential force, the force at its last reversal, its last normal force).
    pub fn keeps_load(&self) -> bool {
        self.tangential_model == TangentialModel::MindlinDeresiewicz
            && (self.sliding > 0.0 || self.wall_sliding > 0.0)
    }
}

/// The normal law a material resolves to for a time step and the lightest spheres (each pair's
/// damping and the stable time step: [`super::MaterialTable`]).
#[derive(Debug, Clone)]
pub(super) struct ResolvedLaw {
    pub law: NormalLaw,
    /// k of [`NormalLaw::Linear`] \[N/m\] (0 for the other laws).
    pub stiffness: f64,
    /// Rayleigh time of the smallest sphere \[s\] (Hertz–Mindlin).
    pub rayleigh_time: Option<f64>,
}

/// Whether `x` is positive and a normal f32 (the step computes in f32).
fn normal_f32(x: f64) -> bool {
    x > 0.0 && (x as f32).is_normal()
}

/// The largest friction coefficient (sliding, with the walls, rolling) a scene may give: the
/// laws multiply it into forces and torques in single precision, and a coefficient this large
/// already never lets a contact slide or roll.
pub const MAX_FRICTION: f64 = 1e6;

impl Material {
    /// Refuses values no contact law can work with, naming the scene key: a restitution outside
    /// (0, 1], a density, Young's modulus or Poisson's ratio outside their ranges (each a normal
    /// `f32`), a friction coefficient outside 0 ..= [`MAX_FRICTION`]. Checked before the time
    /// step is derived from them.
    pub fn check(&self) -> Result<()> {
        let bad = |key: &str, reason: String| {
            Err(Error::InvalidConfig {
                what: format!("scene key {key}"),
                reason,
            })
        };
        if !(self.restitution > 0.0 && self.restitution <= 1.0) {
            return bad(
                "restitution",
                format!("must be in (0, 1], got {}", self.restitution),
            );
        }
        if !normal_f32(self.density) {
            return bad(
                "density",
                format!(
                    "must be positive and within single precision's range ({} .. {} kg/m³), \
                     got {}",
                    shown(f32::MIN_POSITIVE),
                    shown(f32::MAX),
                    shown(self.density)
                ),
            );
        }
        if let ContactLaw::HertzMindlin {
            young_modulus,
            poisson_ratio,
        } = self.contact
        {
            if !normal_f32(young_modulus) {
                return bad(
                    "young_modulus",
                    format!(
                        "must be positive and within single precision's range ({} .. {} Pa), \
                         got {}",
                        shown(f32::MIN_POSITIVE),
                        shown(f32::MAX),
                        shown(young_modulus)
                    ),
                );
            }
            if !(poisson_ratio > -1.0 && poisson_ratio < 0.5) {
                return bad(
                    "poisson_ratio",
                    format!("must be in (−1, 0.5), got {poisson_ratio}"),
                );
            }
        }
        let coefficients = [
            ("friction", self.friction),
            ("wall_friction", self.wall_friction.unwrap_or(self.friction)),
            ("rolling_friction", self.rolling_friction),
        ];
        for (key, mu) in coefficients {
            if !(0.0..=MAX_FRICTION).contains(&mu) {
                return bad(
                    key,
                    format!("must be a coefficient from 0 to {MAX_FRICTION:e}, got {mu}"),
                );
            }
        }
        if let Some(angle) = self.bridge.map(|b| b.contact_angle) {
            check_contact_angle(angle)?;
        }
        Ok(())
    }

    /// The normal law for time step `dt` and lightest spheres of radius `r_min` (effective mass
    /// `m_eff` of two of them), for a material that passed [`Material::check`]; refuses
    /// impossible values.
    pub(super) fn law(&self, dt: f64, r_min: f32, m_eff: f64) -> Result<ResolvedLaw> {
        let bad = |reason: String| {
            Err(Error::InvalidConfig {
                what: "material".into(),
                reason,
            })
        };
        if self.tangential_model == TangentialModel::MindlinDeresiewicz
            && !matches!(self.contact, ContactLaw::HertzMindlin { .. })
        {
            return Err(Error::InvalidConfig {
                what: "scene key tangential_model".into(),
                reason: "\"mindlin-deresiewicz\" follows the Hertz contact's radius and needs \
                         contact = \"hertz-mindlin\""
                    .into(),
            });
        }
        if self.stiffness.is_some() && self.contact != ContactLaw::Linear {
            return bad(
                "a stiffness in N/m is for contact = \"linear\" with one stiffness only".into(),
            );
        }
        match self.contact {
            ContactLaw::Linear => {
                let stiffness = match self.stiffness {
                    Some(k) if normal_f32(k) => k,
                    Some(k) => {
                        return bad(format!(
                            "stiffness must be positive and within f32's range, got {}",
                            shown(k)
                        ));
                    }
                    None => {
                        let k =
                            stiffness_for_duration(m_eff, self.restitution, STEPS_PER_CONTACT * dt);
                        if !normal_f32(k) {
                            return bad(format!(
                                "the derived stiffness {} N/m (a {STEPS_PER_CONTACT}-step \
                                 contact at dt {} s for spheres of r = {} m) is outside f32's \
                                 range: choose a larger dt, or give a stiffness",
                                shown(k),
                                shown(dt),
                                shown(r_min)
                            ));
                        }
                        k
                    }
                };
                Ok(ResolvedLaw {
                    law: NormalLaw::Linear,
                    // As a saved scene gives it back (its f32 by the shortest decimal), so that
                    // a run from the saved scene derives the same damping and limits from it.
                    stiffness: crate::numbers::widened(stiffness as f32),
                    rayleigh_time: None,
                })
            }
            ContactLaw::LinearPerPair { contact_time } => {
                let t_c = contact_time.unwrap_or(STEPS_PER_CONTACT * dt);
                if !normal_f32(t_c) {
                    return bad(format!(
                        "contact_time must be positive and within f32's range, got {} s",
                        shown(t_c)
                    ));
                }
                // k/m* is the same for every contact.
                let rate = stiffness_for_duration(1.0, self.restitution, t_c);
                if !normal_f32(rate) {
                    return bad(format!(
                        "contact_time {} s gives k/m* = {} 1/s², outside f32's range",
                        shown(t_c),
                        shown(rate)
                    ));
                }
                // The lightest pair's k = m*·rate, as the step computes it.
                let k = m_eff as f32 * rate as f32;
                if !k.is_normal() {
                    return bad(format!(
                        "contact_time {} s gives the lightest spheres (r = {} m) a stiffness \
                         of {} N/m, outside f32's range: choose a shorter contact time",
                        shown(t_c),
                        shown(r_min),
                        shown(k)
                    ));
                }
                Ok(ResolvedLaw {
                    law: NormalLaw::LinearPerPair {
                        rate: rate as f32,
                        contact_time: t_c as f32,
                    },
                    stiffness: 0.0,
                    rayleigh_time: None,
                })
            }
            ContactLaw::HertzMindlin {
                young_modulus,
                poisson_ratio,
            } => {
                let t_r = rayleigh_time(r_min as f64, self.density, young_modulus, poisson_ratio);
                let (pair, wall) = (
                    Elastic::pair(young_modulus, poisson_ratio),
                    Elastic::wall(young_modulus, poisson_ratio),
                );
                if !(pair.e_star.is_normal() && wall.g_star.is_normal()) {
                    return bad(format!(
                        "young_modulus {} Pa gives effective moduli outside f32's range",
                        shown(young_modulus)
                    ));
                }
                Ok(ResolvedLaw {
                    law: NormalLaw::Hertz { pair, wall },
                    stiffness: 0.0,
                    rayleigh_time: Some(t_r),
                })
            }
        }
    }
}
