//! The physics of the DEM (docs/method.md, "The DEM step"): spheres of one material under
//! gravity in a box with six walls, a contact law between spheres and with the walls, and
//! semi-implicit Euler integration of positions and angular velocities.
//!
//! - [`linear`]: the stiffness and the stable time step of the paper's linear spring–dashpot.
//! - [`law`]: the law's parameters as the GPU steps read them, and its code on the devices.
//! - [`contact`]: the whole contact of the cpu step: linear or Hertz–Mindlin normal force,
//!   tangential spring with history and Coulomb cap, torque, rolling resistance.
//! - [`material`]: what a material says and the coefficients the step makes of it.
//! - [`time_step`]: the Rayleigh time and the Hertz impact formulas.

pub mod contact;
pub mod law;
pub mod linear;
pub mod material;
pub mod materials;
pub mod restitution;
pub mod time_step;

pub use law::{LawCode, LawParams};
pub use linear::{STEPS_PER_CONTACT, stable_dt, stiffness_for_duration};
pub use material::{
    ContactLaw, Elastic, Friction, LiquidBridge, MAX_FRICTION, Material, NormalLaw, RollingModel,
    TangentialModel,
};
pub use materials::{
    MAX_MATERIALS, MaterialTable, Materials, PairBridge, PairLaw, PairOverride, TableLaw,
};

use crate::error::{Error, Result};
use crate::numbers::shown;
use std::f64::consts::PI;
use std::sync::Arc;

/// Everything a step needs besides the particles. The scalar law fields (`stiffness` aside) are
/// the first material's with itself; each pair's are in `materials`.
#[derive(Debug, Clone, PartialEq)]
pub struct StepParams {
    /// Time step \[s\].
    pub dt: f32,
    /// Lower corner of the box \[m\].
    pub box_lo: [f32; 3],
    /// Upper corner of the box \[m\].
    pub box_hi: [f32; 3],
    /// Gravity at t = 0 \[m/s²\].
    pub gravity: [f32; 3],
    /// Angular velocity \[rad/s\] at which gravity turns about the y axis (in the XZ plane).
    pub gravity_spin: f32,
    /// Normal stiffness k \[N/m\].
    pub stiffness: f32,
    /// Damping ratio ζ of two spheres of the first material (from its restitution coefficient).
    pub damping_ratio: f32,
    /// Density of the first material \[kg/m³\].
    pub density: f32,
    /// The normal law; with [`NormalLaw::Linear`], `stiffness` is its k (with the others,
    /// `stiffness` is 0).
    pub law: NormalLaw,
    /// The largest friction coefficients of any pair, and the models (all 0: no tangential
    /// force, no torque).
    pub friction: Friction,
    /// Every pair of materials' law and each material's density.
    pub materials: Arc<MaterialTable>,
    /// The column of `materials` the six box walls take (their material, or a rigid wall).
    pub box_column: u32,
    /// The largest stable time step for these contacts and the lightest spheres \[s\].
    pub dt_limit: f32,
    /// Rayleigh time of the smallest sphere \[s\] (Hertz–Mindlin only).
    pub rayleigh_time: Option<f32>,
    /// The liquid bridges of capillary cohesion (`None`: none).
    pub bridge: Option<Bridge>,
    /// The cohesion energy density of LIGGGHTS' simplified JKR \[J/m³\] (0: none).
    pub cohesion_density: f32,
}

/// The liquid of the bridges as the step computes it ([`LiquidBridge`]'s liquid in f32; how
/// each pair of surfaces it wets pulls, and where its bridge ruptures, is the pair's
/// [`PairBridge`] in the material table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bridge {
    /// Liquid volume V \[m³\].
    pub volume: f32,
    /// The liquid's dynamic viscosity η \[Pa·s\] (0: no lubrication force).
    pub viscosity: f32,
}

impl Bridge {
    /// The liquid of `bridge` as the step computes it.
    pub fn of(bridge: &LiquidBridge) -> Self {
        Self {
            volume: bridge.volume as f32,
            viscosity: bridge.viscosity as f32,
        }
    }
}

/// The largest time step at which the lubrication force of bridges `bridge` damps the lightest
/// spheres (mass `m`, radius `r`) stably: m*/c at the largest damping coefficient c =
/// 6π·η·R*/[`BRIDGE_MIN_GAP`](contact::BRIDGE_MIN_GAP) (the gap at its least), half the explicit
/// step's limit of 2m*/c; the same for two such spheres and for one on a wall \[s\]. `None`
/// without a viscosity.
pub fn drag_dt_limit(bridge: &LiquidBridge, m: f64, r: f64) -> Option<f64> {
    (bridge.viscosity > 0.0).then(|| {
        m * contact::BRIDGE_MIN_GAP as f64 / (6.0 * std::f64::consts::PI * bridge.viscosity * r)
    })
}

/// Mass of a sphere of radius `r` \[kg\].
pub fn mass(density: f32, r: f32) -> f32 {
    density * (4.0 / 3.0 * std::f32::consts::PI) * r * r * r
}

/// Whether the laws can be evaluated in f32 for a sphere of radius `r` at `density`: half its
/// mass is a normal f32 number, so every effective mass m* ∈ [m_lo/2, m_lo] of its contacts
/// is one (docs/method.md, "Small spheres in f32").
pub fn mass_in_range(density: f32, r: f32) -> bool {
    (mass(density, r) / 2.0).is_normal()
}

/// Whether a sphere of radius `r` at `density` can turn in f32: half its moment of inertia
/// 2/5·m·r² (as the step computes it) is a normal f32 number, so every effective moment of
/// inertia I* ∈ [I_lo/2, I_lo] of its contacts is one and ω += dt·τ/I is defined.
pub fn inertia_in_range(density: f32, r: f32) -> bool {
    (contact::moment_of_inertia(mass(density, r), r) / 2.0).is_normal()
}

/// The smallest f32 radius `r` with `within(r)`, for a `within` that holds from some radius
/// on (up to where the quantity overflows), starting from the estimate `guess`.
fn smallest_radius_with(guess: f64, within: impl Fn(f32) -> bool) -> f32 {
    let mut r = (guess as f32).max(f32::MIN_POSITIVE);
    while !within(r) && r < f32::MAX {
        r = r.next_up();
    }
    while within(r.next_down()) {
        r = r.next_down();
    }
    r
}

/// The smallest radius whose sphere's mass at `density` is within [`mass_in_range`]:
/// ρ·4/3·π·r³ ≥ 2·2⁻¹²⁶ kg (2.2e-14 m at 500 kg/m³, below [`crate::MIN_RADIUS`]).
pub fn smallest_radius(density: f32) -> f32 {
    let volume = 2.0 * f32::MIN_POSITIVE as f64 / (density as f64 * 4.0 / 3.0 * PI);
    smallest_radius_with(volume.cbrt(), |r| mass_in_range(density, r))
}

/// The smallest radius whose sphere at `density` can turn ([`inertia_in_range`]):
/// 2/5·ρ·4/3·π·r⁵ ≥ 2·2⁻¹²⁶ kg·m² (7.8e-9 m at 500 kg/m³, 5.6e-9 m at 2500).
pub fn smallest_turning_radius(density: f32) -> f32 {
    let r5 = 2.0 * f32::MIN_POSITIVE as f64 / (0.4 * density as f64 * 4.0 / 3.0 * PI);
    smallest_radius_with(r5.powf(0.2), |r| inertia_in_range(density, r))
}

impl StepParams {
    /// Whether contacts attract (JKR, liquid bridges or LIGGGHTS' simplified JKR): the laws of
    /// the cpu step alone so far.
    pub fn adheres(&self) -> bool {
        self.friction.cohesive || self.cohesion_density > 0.0
    }

    /// How far beyond touching a contact of spheres of radii up to `r_max` may act \[m\]: the
    /// widest JKR neck of any adhering pair (0 where none adheres). A pair's neck breaks at
    /// [`jkr_break`](contact::jkr_break) of its R*, at most `r_max` (a sphere on a wall).
    pub fn reach_margin(&self, r_max: f32) -> f32 {
        self.materials
            .laws
            .iter()
            .filter(|l| l.adhesion > 0.0)
            .map(|l| -contact::jkr_break(r_max, l.e_star, l.adhesion))
            .fold(0.0, f32::max)
            .max(self.materials.widest_rupture())
    }

    /// How far past touching the GPU steps search for contacts of spheres of radii up to
    /// `r_max` \[m\]: [`reach_margin`](Self::reach_margin) and a part in a thousand more, so
    /// that a search's rounding of r_i + r_j + margin never loses a contact the law holds.
    pub fn search_margin(&self, r_max: f32) -> f32 {
        self.reach_margin(r_max) * 1.001
    }

    /// Checks and completes the parameters for spheres of radii from `r_min` up: derives the
    /// stiffness when the material has none, and refuses a time step too large for it, and
    /// spheres too small for the laws in f32 (docs/method.md, "Small spheres in f32"): half
    /// the mass of a sphere of `r_min` must be a normal f32 number ([`mass_in_range`]), and
    /// where the material has friction or rolling resistance half its moment of inertia too
    /// ([`inertia_in_range`]); [`smallest_radius`] and [`smallest_turning_radius`] give the
    /// limits.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        material: &Material,
        dt: f64,
        box_lo: [f64; 3],
        box_hi: [f64; 3],
        gravity: [f64; 3],
        gravity_spin: f64,
        r_min: f32,
    ) -> Result<Self> {
        let one = Materials::one(*material);
        Self::with_materials(&one, None, dt, box_lo, box_hi, gravity, gravity_spin, r_min)
    }

    /// As [`Self::new`], for several materials (`box_material`: the box walls' material, or
    /// `None` for rigid walls): the time step must suit the stiffest pair, and the lightest
    /// sphere is the smallest at the lowest density.
    #[allow(clippy::too_many_arguments)]
    pub fn with_materials(
        materials: &Materials,
        box_material: Option<usize>,
        dt: f64,
        box_lo: [f64; 3],
        box_hi: [f64; 3],
        gravity: [f64; 3],
        gravity_spin: f64,
        r_min: f32,
    ) -> Result<Self> {
        let bad = |reason: &str| {
            Err(Error::InvalidConfig {
                what: "scene".into(),
                reason: reason.to_owned(),
            })
        };
        materials.check()?;
        if let Some(b) = box_material.filter(|&b| b >= materials.list.len()) {
            return bad(&format!(
                "box_material is material {b}, of {}",
                materials.list.len()
            ));
        }
        let m = materials.first();
        // Every parameter is used as an f32: each must be a normal f32 number (no overflow to
        // inf, no underflow to 0).
        let normal = |x: f64| x > 0.0 && (x as f32).is_normal();
        if !normal(dt) {
            return bad(&format!(
                "time step must be positive and within f32's range ({} .. {} s), got {}",
                shown(f32::MIN_POSITIVE),
                shown(f32::MAX),
                shown(dt)
            ));
        }
        // The time step as a saved scene gives it back (its f32 by the shortest decimal), so
        // that a run from the saved scene derives the same damping, rates and limits from it.
        let dt = crate::numbers::widened(dt as f32);
        if gravity
            .iter()
            .chain([&gravity_spin])
            .any(|&g| !(g as f32).is_finite())
        {
            return bad("gravity and its spin must be finite (in f32)");
        }
        let (lo32, hi32) = (box_lo.map(|x| x as f32), box_hi.map(|x| x as f32));
        if (0..3).any(|a| !(lo32[a].is_finite() && hi32[a].is_finite() && lo32[a] < hi32[a])) {
            return bad(&format!(
                "the box must have finite corners with lo < hi on every axis (in f32), got \
                 {box_lo:?} .. {box_hi:?}"
            ));
        }
        let lightest = materials.lightest_density();
        let density = lightest as f32;
        let m_eff = mass(density, r_min) as f64 / 2.0;
        if !mass_in_range(density, r_min) {
            return bad(&format!(
                "the lightest spheres (r = {} m, density {} kg/m³) have mass {} kg, outside \
                 f32's range for the contact laws (half of it must be a normal f32 number; the \
                 smallest radius at this density is {} m)",
                shown(r_min),
                shown(lightest),
                shown(2.0 * m_eff),
                shown(smallest_radius(density))
            ));
        }
        let law = m.law(dt, r_min, m_eff)?;
        if let Some(sticky) = materials.list.iter().find(|m| m.adhesion != 0.0) {
            if !(sticky.adhesion > 0.0 && (sticky.adhesion as f32).is_normal()) {
                return bad(&format!(
                    "surface_energy must be a positive number (J/m²), got {}",
                    sticky.adhesion
                ));
            }
            if !matches!(law.law, NormalLaw::Hertz { .. }) {
                return bad(
                    "cohesion = \"jkr\" (surface_energy) needs contact = \"hertz-mindlin\"",
                );
            }
        }
        if let Some(b) = &m.bridge {
            let positive = |x: f64| x > 0.0 && (x as f32).is_normal();
            if !(positive(b.volume) && positive(b.surface_tension)) {
                return bad(&format!(
                    "a liquid bridge needs a positive liquid_volume and surface_tension (in \
                     f32), got {} m³ and {} N/m",
                    shown(b.volume),
                    shown(b.surface_tension)
                ));
            }
            let eta = b.viscosity;
            if !(eta == 0.0 || (eta > 0.0 && (eta as f32).is_normal())) {
                return bad(&format!(
                    "liquid_viscosity must be 0 or a positive number (Pa·s), got {eta}"
                ));
            }
            if m.adhesion > 0.0 {
                return bad("one cohesion law at a time: a liquid bridge or JKR adhesion");
            }
        }
        if m.cohesion_density != 0.0 {
            let k = m.cohesion_density;
            if !(k > 0.0 && (k as f32).is_normal()) {
                return bad(&format!(
                    "cohesion_energy_density must be a positive number (J/m³), got {k}"
                ));
            }
            if m.adhesion > 0.0 || m.bridge.is_some() {
                return bad("one cohesion law at a time");
            }
        }
        let resolved = MaterialTable::resolve(materials, dt, law.stiffness, r_min, m_eff)?;
        let table = resolved.table;
        let friction = Friction {
            sliding: table.largest_sliding(),
            wall_sliding: table.largest_rigid_wall_sliding(),
            rolling: table.largest_rolling(),
            rolling_model: m.rolling_model,
            tangential_model: m.tangential_model,
            cohesive: table.laws.iter().any(|l| l.adhesion > 0.0) || m.bridge.is_some(),
        };
        if friction.turns() && !inertia_in_range(density, r_min) {
            return bad(&format!(
                "the smallest spheres (r = {} m, density {} kg/m³) have moment of inertia {} \
                 kg·m², outside f32's range (half of it must be a normal f32 number): with \
                 friction or rolling resistance the spheres turn, and the smallest radius that \
                 can turn at this density is {} m; use larger spheres, a higher density, or no \
                 friction and no rolling resistance",
                shown(r_min),
                shown(lightest),
                shown(contact::moment_of_inertia(mass(density, r_min), r_min)),
                shown(smallest_turning_radius(density))
            ));
        }
        if dt > resolved.dt_limit {
            return bad(&format!(
                "time step {} s is too large for {}: the stable limit is {} s",
                shown(dt),
                resolved.limited_by,
                shown(resolved.dt_limit)
            ));
        }
        if let Some(limit) = m
            .bridge
            .and_then(|b| drag_dt_limit(&b, 2.0 * m_eff, r_min as f64))
            && dt > limit
        {
            return bad(&format!(
                "time step {} s is too large for the bridges' lubrication force \
                 (liquid_viscosity {} Pa·s on spheres of r = {} m): the stable limit is {} s",
                shown(dt),
                shown(m.bridge.map_or(0.0, |b| b.viscosity)),
                shown(r_min),
                shown(limit)
            ));
        }
        if let Err(reason) = check_gravity(gravity, dt, r_min) {
            return bad(&reason);
        }
        Ok(Self {
            dt: dt as f32,
            box_lo: lo32,
            box_hi: hi32,
            gravity: gravity.map(|x| x as f32),
            gravity_spin: gravity_spin as f32,
            stiffness: law.stiffness as f32,
            damping_ratio: table.law(0, 0).damping_ratio,
            density: m.density as f32,
            law: law.law,
            friction,
            dt_limit: resolved.dt_limit as f32,
            box_column: box_material.map_or(table.column_of_rigid_wall(), |b| b as u32),
            materials: Arc::new(table),
            rayleigh_time: law.rayleigh_time.map(|t| t as f32),
            bridge: m.bridge.as_ref().map(Bridge::of),
            cohesion_density: m.cohesion_density as f32,
        })
    }

    /// A warning when the heaviest sphere (radius `r_max`) resting on the floor would sink
    /// deeper than a tenth of its radius (m·|g|/k): with one stiffness for all contacts, a wide
    /// spread of masses needs a stiffness (and a time step) chosen for the heaviest sphere. Says
    /// which stiffness keeps that overlap at 1% and the time step it then needs.
    pub fn overlap_warning(&self, r_min: f32, r_max: f32) -> Option<String> {
        if self.law != NormalLaw::Linear {
            // Stiffness follows each contact's masses (or the Hertz law's radii).
            return None;
        }
        let g = self
            .gravity
            .iter()
            .map(|&x| x as f64 * x as f64)
            .sum::<f64>()
            .sqrt();
        let volume = |r: f32| 4.0 / 3.0 * PI * (r as f64).powi(3);
        let densities = &self.materials.densities;
        let heaviest = densities.iter().copied().fold(0.0, f32::max) as f64;
        let lightest = densities.iter().copied().fold(f32::INFINITY, f32::min) as f64;
        let heavy = heaviest * volume(r_max);
        let sink = heavy * g / self.stiffness as f64;
        if sink <= 0.1 * r_max as f64 {
            return None;
        }
        let k = heavy * g / (0.01 * r_max as f64);
        let m_eff = lightest * volume(r_min) / 2.0;
        let zeta = self.damping_ratio as f64;
        let t_c = PI / ((k / m_eff).sqrt() * (1.0 - zeta * zeta).sqrt());
        let dt = t_c / STEPS_PER_CONTACT;
        // Advice only where f32 holds it.
        let advice = if (k as f32).is_normal() && (dt as f32).is_normal() {
            format!(
                "for 1% use --set stiffness={k:.3e} with --dt {dt:.2e} (a 10-step contact for the lightest pair)"
            )
        } else {
            format!(
                "no stiffness and time step within f32's range keep it at 1% (that needs \
                 stiffness {k:.3e} N/m at dt {dt:.2e} s): lower the gravity or the spread of radii"
            )
        };
        Some(format!(
            "the heaviest spheres (r = {} m) would sink {:.0}% of their radius into what they \
             rest on at stiffness {} N/m; {advice}",
            shown(r_max),
            100.0 * sink / r_max as f64,
            shown(self.stiffness),
        ))
    }

    /// The time step and the contact law in words, for a run's summary line: the stiffness or
    /// the Rayleigh time the step follows from, and the friction where there is any (with
    /// several materials, the largest of any pair; [`Materials::describe`] names them).
    pub fn describe(&self) -> String {
        match self.describe_cohesion() {
            Some(cohesion) => format!("{} | {cohesion}", self.describe_dry()),
            None => self.describe_dry(),
        }
    }

    /// The cohesion law and its parameters in words (`None`: dry).
    fn describe_cohesion(&self) -> Option<String> {
        let adhesion = self
            .materials
            .laws
            .iter()
            .map(|l| l.adhesion)
            .fold(0.0, f32::max);
        if adhesion > 0.0 {
            return Some(format!("cohesion jkr (Γ up to {adhesion} J/m²)"));
        }
        if let Some(b) = self.bridge {
            let viscous = match b.viscosity > 0.0 {
                true => format!(", η {} Pa·s", b.viscosity),
                false => String::new(),
            };
            // Two spheres of the first material's; where the materials wet differently, the
            // range over every pair.
            let first = self.materials.bridge(0, 0);
            let wetting = match self.materials.bridges.iter().all(|w| w == first) {
                true => format!(
                    "γ·cos θ {} N/m, rupture at {:.3e} m",
                    first.tension, first.rupture
                ),
                false => {
                    let (lo, hi) = self.materials.bridges.iter().fold(
                        ((f32::INFINITY, f32::INFINITY), (0.0f32, 0.0f32)),
                        |(lo, hi), w| {
                            (
                                (lo.0.min(w.tension), lo.1.min(w.rupture)),
                                (hi.0.max(w.tension), hi.1.max(w.rupture)),
                            )
                        },
                    );
                    format!(
                        "γ·cos θ {}–{} N/m, rupture at {:.3e}–{:.3e} m by pair",
                        lo.0, hi.0, lo.1, hi.1
                    )
                }
            };
            return Some(format!(
                "cohesion capillary (V {:e} m³, {wetting}{viscous})",
                b.volume
            ));
        }
        (self.cohesion_density > 0.0)
            .then(|| format!("cohesion sjkr (k {:e} J/m³)", self.cohesion_density))
    }

    /// [`describe`](Self::describe) but for cohesion.
    fn describe_dry(&self) -> String {
        let dt = crate::numbers::significant(self.dt as f64, 4);
        let law = match self.law {
            NormalLaw::Linear => format!(
                "dt {dt} s (stable limit {:.3e} s) | stiffness {:.4e} N/m",
                self.dt_limit, self.stiffness
            ),
            NormalLaw::LinearPerPair { contact_time, .. } => format!(
                "dt {dt} s (stable limit {:.3e} s) | per-pair stiffness, contact time \
                 {contact_time:.3e} s",
                self.dt_limit,
            ),
            NormalLaw::Hertz { .. } => {
                let t_r = self.rayleigh_time.unwrap_or(f32::NAN) as f64;
                format!(
                    "dt {dt} s = {:.3} Rayleigh time of the smallest sphere ({t_r:.3e} s; \
                     limit {:.3e} s) | hertz-mindlin",
                    self.dt as f64 / t_r,
                    self.dt_limit
                )
            }
        };
        let f = &self.friction;
        if !f.turns() {
            return law;
        }
        let model = match f.rolling_model {
            RollingModel::Epsd => "epsd",
            RollingModel::ConstantTorque => "constant-torque",
        };
        let tangential = match f.keeps_load() {
            true => " (mindlin-deresiewicz)",
            false => "",
        };
        let up_to = match self.materials.count {
            1 => "",
            _ => "up to ",
        };
        format!(
            "{law} | friction {up_to}{} (walls {up_to}{}){tangential}, rolling {up_to}{} \
             ({model})",
            f.sliding, f.wall_sliding, f.rolling
        )
    }

    /// These parameters with `gravity` at t = 0 (turned by `gravity_spin · t` from there),
    /// checked as a scene's is for spheres of smallest radius `r_min`.
    pub fn with_gravity(&self, gravity: [f64; 3], r_min: f32) -> Result<StepParams> {
        check_gravity(gravity, self.dt as f64, r_min).map_err(|reason| Error::InvalidConfig {
            what: "gravity".into(),
            reason,
        })?;
        Ok(StepParams {
            gravity: gravity.map(|g| g as f32),
            ..self.clone()
        })
    }

    /// Gravity at step `step` (time `step · dt`), turned about the y axis by `gravity_spin · t`.
    pub fn gravity_at(&self, step: u64) -> [f32; 3] {
        let angle = self.gravity_spin * (step as f32 * self.dt);
        let (s, c) = angle.sin_cos();
        let [gx, gy, gz] = self.gravity;
        [gx * c + gz * s, gy, gz * c - gx * s]
    }
}

/// Refuses `gravity` that is not finite in `f32`, or that moves a sphere more than the smallest
/// radius `r_min` in one step of `dt` (no contact or wall could hold it).
fn check_gravity(gravity: [f64; 3], dt: f64, r_min: f32) -> std::result::Result<(), String> {
    if gravity.iter().any(|&g| !(g as f32).is_finite()) {
        return Err(format!("must be finite (in f32), got {gravity:?}"));
    }
    let g = gravity.iter().map(|x| x * x).sum::<f64>().sqrt();
    if g * dt * dt > r_min as f64 {
        return Err(format!(
            "gravity of {} m/s² moves a sphere {} m in a single step of {} s, more than the \
             smallest radius ({} m): no contact or wall could hold it; lower the gravity or the \
             time step",
            shown(g),
            shown(g * dt * dt),
            shown(dt),
            shown(r_min)
        ));
    }
    Ok(())
}

/// One semi-implicit Euler step of a sphere under `force` and gravity `g`: v += dt·(F/m + g),
/// then its position (centre `c`, residual `lo`) moves by dt·v without losing the displacement
/// to the rounding of `c` ([`crate::particles::position::advance`]).
#[inline(always)]
pub fn integrate(
    dt: f32,
    (c, lo): (&mut [f32; 3], &mut [f32; 3]),
    v: &mut [f32; 3],
    force: [f32; 3],
    m: f32,
    g: [f32; 3],
) {
    for a in 0..3 {
        v[a] += dt * (force[a] / m + g[a]);
        crate::particles::position::advance(&mut c[a], &mut lo[a], dt * v[a]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> StepParams {
        StepParams::new(
            &Material::default(),
            1e-4,
            [0.0; 3],
            [1.0; 3],
            [0.0, 0.0, -9.81],
            0.0,
            0.0005,
        )
        .unwrap()
    }

    #[test]
    fn default_stiffness_gives_ten_step_contacts_and_is_stable() {
        // k = m*·(π² + ln² e)/t_c² with t_c ten steps: ω·dt = √(π² + ln² e)/10.
        let p = params();
        let m_eff = mass(500.0, 0.0005) as f64 / 2.0;
        let omega_dt = (p.stiffness as f64 / m_eff).sqrt() * 1e-4;
        let l = 0.5f64.ln();
        assert!((omega_dt - (PI * PI + l * l).sqrt() / STEPS_PER_CONTACT).abs() < 1e-6);
        let zeta = p.damping_ratio as f64;
        assert_eq!(
            zeta as f32,
            restitution::linear_damping(0.5, omega_dt).unwrap() as f32
        );
        assert!(stable_dt(p.stiffness as f64, m_eff, zeta) > 1e-4);
    }

    #[test]
    fn too_large_a_step_is_refused_with_the_limit() {
        let stiff = Material {
            stiffness: Some(1e6),
            ..Material::default()
        };
        let err = StepParams::new(&stiff, 1e-4, [0.0; 3], [1.0; 3], [0.0; 3], 0.0, 0.0005)
            .unwrap_err()
            .to_string();
        assert!(err.contains("stable limit"), "{err}");
    }

    #[test]
    fn the_papers_contact_forces_are_equal_and_opposite_bit_for_bit() {
        use contact::{Body, Springs, pair_contact};
        use glam::Vec3;
        let p = params();
        let body = |c: [f32; 3], v: [f32; 3], r: f32, m: f32| Body {
            c: Vec3::from_array(c),
            v: Vec3::from_array(v),
            w: Vec3::ZERO,
            r,
            m,
            material: 0,
        };
        let i = body([0.1, 0.2, 0.3], [0.01, -0.3, 0.2], 0.0005, 2e-7);
        let j = body([0.1007, 0.2003, 0.2996], [-0.2, 0.1, 0.05], 0.0006, 3e-7);
        let f = pair_contact(&p, &i, &j, Springs::default(), false)
            .unwrap()
            .force;
        let g = pair_contact(&p, &j, &i, Springs::default(), false)
            .unwrap()
            .force;
        assert_eq!(f, -g);
        // Repulsive: pushes i away from j.
        assert!(f.x < 0.0 && f.y < 0.0 && f.z > 0.0);
    }

    #[test]
    fn soft_contacts_for_heavy_spheres_are_warned_about() {
        let p = params();
        assert_eq!(p.overlap_warning(0.0005, 0.0006), None);
        assert!(
            p.overlap_warning(0.0005, 0.06)
                .is_some_and(|w| w.contains("stiffness="))
        );
        let stiff = StepParams {
            stiffness: 1e4,
            ..p
        };
        assert_eq!(stiff.overlap_warning(0.0005, 0.06), None);
    }

    #[test]
    fn parameters_outside_f32_or_beyond_any_contact_are_refused() {
        let m = Material::default();
        let new = |dt: f64, lo: f64, hi: f64, g: f64, r: f32| {
            StepParams::new(&m, dt, [lo; 3], [hi; 3], [0.0, 0.0, g], 0.0, r)
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        assert_eq!(new(1e-4, 0.0, 1.0, -9.81, 0.0005), Ok(()));
        // A derived stiffness of about 1e52 N/m.
        let e = new(1e-30, 0.0, 1.0, -9.81, 0.0005).unwrap_err();
        assert!(e.contains("derived stiffness") && e.contains("f32"), "{e}");
        let e = new(1e-50, 0.0, 1.0, -9.81, 0.0005).unwrap_err();
        assert!(e.contains("time step"), "{e}");
        let e = new(1e-4, 0.0, 1e39, -9.81, 0.0005).unwrap_err();
        assert!(e.contains("box"), "{e}");
        let e = new(1e-4, 0.0, 1.0, 1e30, 0.0005).unwrap_err();
        assert!(e.contains("gravity") && e.contains("single step"), "{e}");
        let e = new(1e-4, 0.0, 1.0, -9.81, 1e-20).unwrap_err();
        assert!(e.contains("mass"), "{e}");
        let given = Material {
            stiffness: Some(1e40),
            ..m
        };
        let e = StepParams::new(&given, 1e-4, [0.0; 3], [1.0; 3], [0.0; 3], 0.0, 0.0005)
            .unwrap_err()
            .to_string();
        assert!(e.contains("stiffness"), "{e}");
    }

    #[test]
    fn radii_are_accepted_down_to_where_masses_and_moments_of_inertia_fit_f32() {
        let new = |m: &Material, r: f32| {
            let side = 100.0 * r as f64;
            StepParams::new(m, 1e-15, [0.0; 3], [side; 3], [0.0; 3], 0.0, r)
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        // Without friction: the smallest radius there is, at the default density.
        let frictionless = Material::default();
        assert!(smallest_radius(500.0) < crate::MIN_RADIUS);
        assert_eq!(new(&frictionless, crate::MIN_RADIUS), Ok(()));
        // At 1e-6 kg/m³, 1e-12 m weighs 4e-42 kg: below the smallest radius, refused.
        let light = Material {
            density: 1e-6,
            ..frictionless
        };
        let r = smallest_radius(1e-6);
        assert!((1e-11..1e-10).contains(&r), "{r:e}");
        assert_eq!(new(&light, r), Ok(()));
        let e = new(&light, r.next_down()).unwrap_err();
        assert!(
            e.contains("mass") && e.contains(&format!("{} m", shown(r))),
            "{e}"
        );
        // Turning spheres: the moment of inertia sets the limit, 7.8e-9 m at 500 kg/m³.
        let r = smallest_turning_radius(500.0);
        assert!((7.7e-9..7.9e-9).contains(&r), "{r:e}");
        for turning in [
            Material {
                friction: 0.5,
                ..frictionless
            },
            Material {
                rolling_friction: 0.1,
                ..frictionless
            },
            Material {
                wall_friction: Some(0.1),
                ..frictionless
            },
        ] {
            assert_eq!(new(&turning, r), Ok(()));
            let e = new(&turning, r.next_down()).unwrap_err();
            assert!(
                e.contains("moment of inertia") && e.contains(&format!("{} m", shown(r))),
                "{e}"
            );
            // Where it does not turn, the same radius is accepted.
            assert_eq!(new(&frictionless, r.next_down()), Ok(()));
        }
        // Denser spheres turn smaller.
        assert!((5.5e-9..5.7e-9).contains(&smallest_turning_radius(2500.0)));
        // A per-pair stiffness m*·(π² + ln² e)/t_c² below f32's range for the lightest pair.
        let slow = Material {
            contact: ContactLaw::LinearPerPair {
                contact_time: Some(1e4),
            },
            ..frictionless
        };
        let e = new(&slow, crate::MIN_RADIUS).unwrap_err();
        assert!(e.contains("stiffness") && e.contains("contact time"), "{e}");
        assert_eq!(new(&slow, 1e-6), Ok(()));
    }

    #[test]
    fn the_soft_contact_advice_never_names_inf_or_a_zero_step() {
        let under = |g: f32| {
            let p = StepParams {
                gravity: [0.0, 0.0, g],
                ..params()
            };
            let w = p.overlap_warning(0.0005, 0.06).unwrap();
            assert!(!w.contains("inf") && !w.contains("--dt 0"), "{w}");
            w
        };
        // |g|² overflows f32, not the advice.
        assert!(under(-1e30).contains("--set stiffness="));
        // The stiffness for 1% overflows f32: no advice to set it.
        let w = under(-1e37);
        assert!(w.contains("no stiffness and time step within f32"), "{w}");
        assert!(!w.contains("--set stiffness"), "{w}");
    }

    #[test]
    fn rotating_gravity_turns_in_the_xz_plane() {
        let p = StepParams {
            gravity_spin: std::f32::consts::FRAC_PI_2,
            dt: 0.5,
            ..params()
        };
        let g = p.gravity_at(2); // a quarter turn
        assert!(
            (g[0] + 9.81).abs() < 1e-4 && g[1] == 0.0 && g[2].abs() < 1e-4,
            "{g:?}"
        );
    }
}
