//! The whole contact of the cpu step (docs/method.md, "The DEM step"): a normal force by the
//! scene's law, and where the material has friction a tangential spring with history and a
//! Coulomb cap, the torque it exerts, and rolling resistance.
//!
//! Notation of `docs/method.md`: for sphere i touching j (or a wall), n is the unit normal from
//! c_i towards j, δ the overlap, m* and R* the effective mass and radius. The normal force on i
//! is −push·n with push = max(F_el(δ) − c_n·v_n, 0), v_n = (v_j − v_i)·n (a dry contact never
//! pulls; the damping ratio ζ is the one that gives the restitution with that clamp,
//! [`super::restitution`]):
//! - linear: F_el = k·δ, c_n = 2ζ√(k·m*) (k fixed, or m*·rate per contact);
//! - Hertz: S_n = 2E*√(R*δ), F_el = ⅔·S_n·δ = 4/3·E*·√R*·δ^{3/2}, c_n = 2√(5/6)·ζ·√(S_n·m*)
//!   (Tsuji et al. 1992; ζ = −β of the restitution).
//!
//! The tangential spring ξ (what i keeps of the contact) is first turned into the current
//! tangent plane (its normal part removed, its length kept), then grows by v_t·dt with v_t the
//! tangential velocity of i's surface relative to j's at the contact point; the force is
//! F_t = −k_t·ξ − c_t·v_t with k_t = 2/7·k (linear) or S_t = 8G*√(R*δ) (Mindlin 1949). When
//! |F_t| > μ·push the contact slides: F_t is scaled to the cap and ξ = −F_t/k_t, so
//! history never holds more than the cap. The torque on i is (r_i·n) × F_t. Rolling resistance
//! acts on the rolling part of ω_i − ω_j (its component along n, twisting, is not resisted).
//!
//! Computed from j's side every operation sees negated inputs (n, v_rel, ω_rel and, by
//! induction, j's springs are the exact negatives of i's), and the effective quantities are
//! symmetric in i and j ([`effective`]), so the forces and the rolling torques are equal and
//! opposite bit for bit. The GPU engines' copies of the law (`wgsl/dem/dem_physics.wgsl` for the
//! paper's frictionless linear law, `wgsl/dem/dem_contact.wgsl` and `optix/contact.cuh` for the
//! granular one) take the same operations in the same order: tests/contact_twin.rs compares them.
//!
//! Small spheres (docs/method.md, "Small spheres in f32"): masses and moments of inertia are
//! tiny (2e-33 kg at r = 1e-12 m), and their products underflow f32. So no law multiplies two
//! of them: m*, R* and I* come from [`effective`], every damping coefficient √(S·m*) is
//! [`root_product`]`(S, m*)`, and every length of a force, torque or spring is [`length`],
//! which squares nothing below its largest component. What remains in range is checked by
//! [`super::StepParams::new`]: half the mass of the smallest sphere, and where spheres turn
//! half its moment of inertia, are normal f32 numbers.

use super::material::{NormalLaw, RollingModel, TangentialModel};
use super::materials::{PairBridge, PairLaw};
use super::{Bridge, StepParams};
use crate::particles::{HistoryEntry, LoadEntry, LoadedEntry};
use glam::Vec3;
use std::f32::consts::PI;

/// 2·√(5/6): Tsuji's damping coefficient over ζ·√(S·m*).
const TSUJI: f32 = 1.825_741_9;

/// The effective value a·b/(a + b) of two positive values (m* of two masses, R* of two
/// radii, I* of two moments of inertia) without their product, which underflows f32 for small
/// spheres: lo/(1 + lo/hi) with lo ≤ hi. It lies in [lo/2, lo], so it is a normal number
/// wherever lo/2 is; lo/hi may underflow to 0 (then it is lo, correctly rounded). Symmetric
/// in a and b bit for bit (min and max are exact), so both sides of a pair compute the same.
/// Keep in sync with `effective` in wgsl/dem/dem_params.wgsl and `mochi_effective` in
/// optix/physics.cuh.
#[inline(always)]
pub fn effective(a: f32, b: f32) -> f32 {
    let (lo, hi) = (a.min(b), a.max(b));
    lo / (1.0 + lo / hi)
}

/// √(a·b) of two values ≥ 0 without their product, which underflows f32 for small spheres
/// (a stiffness times an effective mass: 1e-6 N/m × 1e-33 kg) or overflows for large ones:
/// √a·√b. Keep in sync with `root_product` in wgsl/dem/dem_params.wgsl and `mochi_root_product` in
/// optix/physics.cuh.
#[inline(always)]
pub fn root_product(a: f32, b: f32) -> f32 {
    a.sqrt() * b.sqrt()
}

/// The length of `v` without squaring anything below its largest component s: s·|v/s| (the
/// squares of v/s lie in [0, 1], one of them 1), where |v|² would underflow f32 for the forces
/// and torques of small spheres (a rolling torque of 1e-23 N·m). 0 for the zero vector. Keep
/// in sync with `length_of` in wgsl/dem/dem_contact.wgsl and `mochi_length` in optix/contact.cuh.
#[inline(always)]
pub fn length(v: Vec3) -> f32 {
    let s = v.x.abs().max(v.y.abs()).max(v.z.abs());
    if s > 0.0 {
        let u = v / s;
        s * u.dot(u).sqrt()
    } else {
        0.0
    }
}

/// A sphere as its contacts see it.
#[derive(Debug, Clone, Copy)]
pub struct Body {
    /// Centre \[m\].
    pub c: Vec3,
    /// Velocity \[m/s\].
    pub v: Vec3,
    /// Angular velocity \[rad/s\].
    pub w: Vec3,
    /// Radius \[m\].
    pub r: f32,
    /// Mass \[kg\].
    pub m: f32,
    /// Material (its row in [`super::MaterialTable`]).
    pub material: u32,
}

impl Body {
    /// Moment of inertia of the solid sphere, 2/5·m·r² \[kg·m²\].
    pub fn inertia(&self) -> f32 {
        moment_of_inertia(self.m, self.r)
    }
}

/// Moment of inertia of a solid sphere of mass `m` and radius `r`: 2/5·m·r² \[kg·m²\].
pub fn moment_of_inertia(m: f32, r: f32) -> f32 {
    0.4 * m * r * r
}

/// What a contact carries from one step to the next under Mindlin's spring
/// ([`TangentialModel::Mindlin`]), as the sphere holding it sees it (its partner holds the
/// exact negatives). Zero for a new contact.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Springs {
    /// Tangential spring ξ \[m\].
    pub tangential: Vec3,
    /// Rolling spring torque of the EPSD model \[N·m\].
    pub rolling: Vec3,
}

/// What a contact carries from one step to the next under the Mindlin–Deresiewicz model
/// ([`TangentialModel::MindlinDeresiewicz`]), as the sphere holding it sees it (its partner
/// holds the exact negatives of the vectors and the same normal force). Zero for a new contact.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LoadedSprings {
    /// The elastic tangential force on the sphere \[N\] (in the spring's place) and the
    /// rolling spring torque \[N·m\].
    pub springs: Springs,
    /// The elastic tangential force on the sphere at the last reversal of the loading \[N\]
    /// (zero: on the virgin curve, no reversal since the contact began or last slid).
    pub reversal: Vec3,
    /// The elastic normal force of the last step \[N\].
    pub normal: f32,
}

/// What a contact keeps from one step to the next under a tangential model: [`Springs`]
/// (Mindlin's spring) or [`LoadedSprings`] (Mindlin–Deresiewicz). The laws are generic in it, so
/// that a step compiles each model on its own and the spring's code is as it was without the
/// other.
pub trait Kept: Copy + Default + PartialEq + std::fmt::Debug + Send + Sync {
    /// The model it is kept under.
    const MODEL: TangentialModel;
    /// A slot of the history holding it.
    type Slot: crate::particles::Slot;
    /// Rolling spring torque \[N·m\].
    fn rolling(&self) -> Vec3;
    /// Sets the rolling spring torque \[N·m\].
    fn set_rolling(&mut self, m: Vec3);
    /// The tangential force on i (`load`, unit normal `n`, tangential velocity `v_t`) from
    /// what i kept (`old`); what it keeps of it into `new`.
    fn tangential(load: &Load, n: Vec3, v_t: Vec3, old: &Self, new: &mut Self) -> Vec3;
    /// The slot of `partner` holding it.
    fn slot(&self, partner: u32) -> Self::Slot;
    /// What `entry` (with the load history `load`, where kept) holds.
    fn of_entry(entry: &HistoryEntry, load: Option<&LoadEntry>) -> Self;
    /// As the partner sees it: the vectors negated.
    fn negated(&self) -> Self;
}

impl Kept for Springs {
    const MODEL: TangentialModel = TangentialModel::Mindlin;
    type Slot = HistoryEntry;

    #[inline(always)]
    fn rolling(&self) -> Vec3 {
        self.rolling
    }

    #[inline(always)]
    fn set_rolling(&mut self, m: Vec3) {
        self.rolling = m;
    }

    /// Mindlin's spring: ξ turned into the tangent plane grows by v_t·dt,
    /// F_t = −k_t·ξ − c_t·v_t up to Coulomb's cap, where ξ = −F_t/k_t.
    #[inline(always)]
    fn tangential(load: &Load, n: Vec3, v_t: Vec3, old: &Self, new: &mut Self) -> Vec3 {
        let mut xi = into_plane(old.tangential, n) + v_t * load.dt;
        let mut f_t = -load.k_t * xi - load.c_t * v_t;
        let cap = load.mu * load.pressing;
        let len = length(f_t);
        if len > cap {
            f_t *= cap / len;
            xi = -f_t / load.k_t;
        }
        new.tangential = xi;
        f_t
    }

    #[inline(always)]
    fn slot(&self, partner: u32) -> HistoryEntry {
        HistoryEntry {
            partner,
            tangential: self.tangential.to_array(),
            rolling: self.rolling.to_array(),
        }
    }

    #[inline(always)]
    fn of_entry(entry: &HistoryEntry, _: Option<&LoadEntry>) -> Self {
        Springs {
            tangential: Vec3::from_array(entry.tangential),
            rolling: Vec3::from_array(entry.rolling),
        }
    }

    fn negated(&self) -> Self {
        Springs {
            tangential: -self.tangential,
            rolling: -self.rolling,
        }
    }
}

impl Kept for LoadedSprings {
    const MODEL: TangentialModel = TangentialModel::MindlinDeresiewicz;
    type Slot = LoadedEntry;

    #[inline(always)]
    fn rolling(&self) -> Vec3 {
        self.springs.rolling
    }

    #[inline(always)]
    fn set_rolling(&mut self, m: Vec3) {
        self.springs.rolling = m;
    }

    #[inline(always)]
    fn tangential(load: &Load, n: Vec3, v_t: Vec3, old: &Self, new: &mut Self) -> Vec3 {
        load_history(load, n, v_t, old, new)
    }

    #[inline(always)]
    fn slot(&self, partner: u32) -> LoadedEntry {
        LoadedEntry {
            entry: self.springs.slot(partner),
            load: LoadEntry {
                reversal: self.reversal.to_array(),
                normal: self.normal,
            },
        }
    }

    #[inline(always)]
    fn of_entry(entry: &HistoryEntry, load: Option<&LoadEntry>) -> Self {
        let load = load.copied().unwrap_or_default();
        LoadedSprings {
            springs: Springs::of_entry(entry, None),
            reversal: Vec3::from_array(load.reversal),
            normal: load.normal,
        }
    }

    fn negated(&self) -> Self {
        LoadedSprings {
            springs: self.springs.negated(),
            reversal: -self.reversal,
            normal: self.normal,
        }
    }
}

/// What one contact does to the sphere computing it.
#[derive(Debug, Clone, Copy)]
pub struct Contact<S = Springs> {
    /// Force on the sphere \[N\].
    pub force: Vec3,
    /// Its normal part (`force` less the tangential force) \[N\].
    pub normal: Vec3,
    /// Torque on the sphere about its centre \[N·m\].
    pub torque: Vec3,
    /// Springs to keep for the next step.
    pub springs: S,
}

/// The normal force's magnitude (≥ 0: it pushes the bodies apart or does nothing), its elastic
/// part (no damping) and the normal stiffness; the load that caps friction and rolling (the
/// push, or with JKR adhesion the push plus twice the pull-off force) and the contact radius of
/// JKR (0 for the other laws).
#[derive(Debug, Clone, Copy)]
struct Normal {
    push: f32,
    elastic: f32,
    stiffness: f32,
    load: f32,
    radius: f32,
}

/// A touching contact from sphere i's side, as friction needs it.
struct Touch {
    /// Unit normal from i towards its partner.
    n: Vec3,
    overlap: f32,
    normal: Normal,
    m_eff: f32,
    r_eff: f32,
    /// Effective moment of inertia I_i·I_j/(I_i + I_j) ([`effective`]; I_i on a wall).
    i_eff: f32,
    /// Distance from i's centre to the contact point.
    lever: f32,
    /// Velocity of i's surface relative to the partner's at the contact point.
    v_rel: Vec3,
    /// ω_i − ω_j (ω_i on a wall).
    w_rel: Vec3,
}

/// The pull-off force of a JKR contact of effective radius `r_eff` and work of adhesion
/// `adhesion` Γ (load control): 1.5·π·Γ·R* \[N\].
#[inline(always)]
pub fn jkr_pull_off(r_eff: f32, adhesion: f32) -> f32 {
    1.5 * PI * adhesion * r_eff
}

/// The overlap at which a JKR neck breaks (negative): δ_c = −¾·(π²Γ²R*/E*²)^⅓ \[m\]. A
/// contact forms at δ = 0 and lasts while δ > δ_c.
#[inline(always)]
pub fn jkr_break(r_eff: f32, e_star: f32, adhesion: f32) -> f32 {
    let g = PI * adhesion / e_star;
    -0.75 * cube_root(g * g * r_eff)
}

/// The contact radius a of a JKR contact with overlap `overlap` (above [`jkr_break`]): the
/// root of δ = a²/R* − √(2πΓa/E*) on the stable branch, by Newton's method on x = √a, whose
/// x⁴/R* − c·x − δ (c = √(2πΓ/E*)) is convex: from a start above the root (where
/// x⁴/R* ≥ 2·max(δ, 0) and ≥ 2c·x) every step stays above it and comes down to it.
#[inline(always)]
pub fn jkr_radius(overlap: f32, r_eff: f32, e_star: f32, adhesion: f32) -> f32 {
    let c = (2.0 * PI * adhesion / e_star).sqrt();
    let mut x = (2.0 * r_eff * overlap.max(0.0))
        .sqrt()
        .sqrt()
        .max(cube_root(2.0 * c * r_eff));
    for _ in 0..JKR_ITERATIONS {
        let x3 = x * x * x;
        let slope = 4.0 * x3 / r_eff - c;
        if slope <= 0.0 {
            break;
        }
        let next = x - (x3 * x / r_eff - c * x - overlap) / slope;
        // Converged: every later step would repeat this one, on every backend.
        if next == x {
            break;
        }
        x = next;
    }
    x * x
}

/// Most Newton steps of [`jkr_radius`]: from its start within a factor of 2^¼ or so of the
/// root, enough to reach it in f32 (quadratic convergence). A step that changes nothing ends
/// the iteration, on every backend alike (the same operations give the same bits).
const JKR_ITERATIONS: usize = 12;

/// The normal force of a contact of law `law` with overlap `overlap` > 0 and normal relative
/// velocity `vn`.
#[inline(always)]
fn normal_force(
    p: &StepParams,
    law: &PairLaw,
    overlap: f32,
    vn: f32,
    m_eff: f32,
    r_eff: f32,
) -> Normal {
    match p.law {
        NormalLaw::Linear => {
            let c = 2.0 * law.damping_ratio * root_product(p.stiffness, m_eff);
            let elastic = p.stiffness * overlap;
            let push = (elastic - c * vn).max(0.0);
            Normal {
                push,
                elastic,
                stiffness: p.stiffness,
                load: push,
                radius: 0.0,
            }
        }
        NormalLaw::LinearPerPair { .. } => {
            let k = m_eff * law.rate;
            let c = 2.0 * law.damping_ratio * root_product(k, m_eff);
            let elastic = k * overlap;
            let push = (elastic - c * vn).max(0.0);
            Normal {
                push,
                elastic,
                stiffness: k,
                load: push,
                radius: 0.0,
            }
        }
        NormalLaw::Hertz { .. } if law.adhesion > 0.0 => {
            // JKR: the contact radius of the overlap (negative on the neck), its force (an
            // attraction on the neck and at small overlaps) and Tsuji's damping with the
            // stiffness 2E*a of that radius; no clamp, the neck pulls.
            let a = jkr_radius(overlap, r_eff, law.e_star, law.adhesion);
            let s_n = 2.0 * law.e_star * a;
            let c = TSUJI * law.damping_ratio * root_product(s_n, m_eff);
            let elastic = 2.0 / 3.0 * s_n * a * a / r_eff
                - (8.0 * PI * law.adhesion * law.e_star * a * a * a).sqrt();
            let push = elastic - c * vn;
            Normal {
                push,
                elastic,
                stiffness: s_n,
                load: (push + 2.0 * jkr_pull_off(r_eff, law.adhesion)).max(0.0),
                radius: a,
            }
        }
        NormalLaw::Hertz { .. } => {
            // R*·δ ≥ R*·ulp(r_i + r_j)/2 when δ > 0: a normal number from r = 1e-12 m up.
            let s_n = 2.0 * law.e_star * (r_eff * overlap).sqrt();
            let c = TSUJI * law.damping_ratio * root_product(s_n, m_eff);
            let elastic = 2.0 / 3.0 * s_n * overlap;
            let push = (elastic - c * vn).max(0.0);
            Normal {
                push,
                elastic,
                stiffness: s_n,
                load: push,
                radius: 0.0,
            }
        }
    }
}

/// The contact of sphere `i` with sphere `j`, from i's side, given the springs i kept of it
/// (`old`, of the parameters' tangential model), or `None` when they do not touch (or their
/// centres coincide: no normal, no force). `bonded`: whether they were in contact at the last
/// step, where a pair adheres (JKR's neck then holds them down to [`jkr_break`]).
#[inline(always)]
pub fn pair_contact<S: Kept>(
    p: &StepParams,
    i: &Body,
    j: &Body,
    old: S,
    bonded: bool,
) -> Option<Contact<S>> {
    let d = j.c - i.c;
    let d2 = d.dot(d);
    let reach = i.r + j.r;
    // Touching by the squared distance (as every backend's search tests it), whatever the
    // rounding of the overlap; beyond, a bond may hold.
    let apart = d2 > reach * reach;
    if (apart && !bonded) || d2 == 0.0 {
        return None;
    }
    let dist = d2.sqrt();
    let n = d / dist;
    let overlap = reach - dist;
    let vn = (j.v - i.v).dot(n);
    let m_eff = effective(i.m, j.m);
    let r_eff = effective(i.r, j.r);
    let law = p.materials.law(i.material, j.material);
    let wet = p.materials.bridge(i.material, j.material);
    if apart && !holds(p, law, wet, r_eff, overlap) {
        return None;
    }
    let mut pull = p
        .bridge
        .map_or(0.0, |b| bridge_pull(&b, wet, r_eff, overlap));
    let drag = p
        .bridge
        .map_or(0.0, |b| bridge_drag(&b, r_eff, overlap, vn));
    if p.cohesion_density > 0.0 && !apart {
        // The area of the circle where the two spheres' surfaces meet, in terms symmetric in
        // i and j (the partner's side computes the same bits).
        let spread = (i.r - j.r).abs();
        let area =
            PI / 4.0 * ((reach - dist) * (reach + dist) * (dist - spread) * (dist + spread)) / d2;
        pull += p.cohesion_density * area.max(0.0);
    }
    if apart && law.adhesion == 0.0 {
        // A liquid bridge across a gap: its pull alone, and its drag.
        let force = dragged(pull, drag) * n;
        return Some(Contact {
            force,
            normal: force,
            torque: Vec3::ZERO,
            springs: S::default(),
        });
    }
    let mut normal = normal_force(p, law, overlap, vn, m_eff, r_eff);
    let along = match pull > 0.0 {
        true => {
            // The bridge presses the contact as a load does.
            normal.load += pull;
            pull - normal.push
        }
        false => -normal.push,
    };
    let force = dragged(along, drag) * n;
    if !p.friction.turns() {
        return Some(Contact {
            force,
            normal: force,
            torque: Vec3::ZERO,
            springs: S::default(),
        });
    }
    let touch = Touch {
        n,
        overlap,
        normal,
        m_eff,
        r_eff,
        i_eff: effective(i.inertia(), j.inertia()),
        lever: i.r,
        v_rel: (i.v + i.w.cross(i.r * n)) - (j.v - j.w.cross(j.r * n)),
        w_rel: i.w - j.w,
    };
    let (f_t, torque, springs) = friction(p, law, &touch, law.sliding, old);
    Some(Contact {
        force: force + f_t,
        normal: force,
        torque,
        springs,
    })
}

/// Whether a contact of `law` and bridge `wet` that touched at the last step and now overlaps
/// by `overlap` ≤ 0 still holds: a JKR neck that has not broken, or a liquid bridge that has not
/// ruptured.
#[inline(always)]
fn holds(p: &StepParams, law: &PairLaw, wet: &PairBridge, r_eff: f32, overlap: f32) -> bool {
    (law.adhesion > 0.0 && overlap > jkr_break(r_eff, law.e_star, law.adhesion))
        || (p.bridge.is_some() && -overlap < wet.rupture)
}

/// The pull of a bridge of liquid `b` wetting the pair as `wet` says, between bodies of
/// effective radius `r_eff` (a sphere on a wall: its radius) overlapping by `overlap` (a gap
/// where negative), in the closed form of Willett et al. (2000) with the Derjaguin radius
/// R = 2R*: 2πRγ·cos θ/(1 + 2.1·s + 10·s²), s = (gap/2)·√(R/V) (0 where they overlap) \[N\].
#[inline(always)]
pub fn bridge_pull(b: &Bridge, wet: &PairBridge, r_eff: f32, overlap: f32) -> f32 {
    let r = 2.0 * r_eff;
    let s = 0.5 * (-overlap).max(0.0) * (r / b.volume).sqrt();
    2.0 * PI * r * wet.tension / (1.0 + 2.1 * s + 10.0 * s * s)
}

/// `along` with a bridge's `drag` added, where there is one (no drag: `along`'s own bits).
#[inline(always)]
fn dragged(along: f32, drag: f32) -> f32 {
    match drag != 0.0 {
        true => along + drag,
        false => along,
    }
}

/// The smallest gap the lubrication force of a bridge takes, as a fraction of the bodies'
/// effective radius (the surfaces' roughness: the force is finite at contact).
pub const BRIDGE_MIN_GAP: f32 = 0.01;

/// The lubrication force of a liquid bridge `b` between bodies of effective radius `r_eff`
/// overlapping by `overlap` (a gap where negative) whose gap grows at `vn` (negative where they
/// approach): 6π·η·R*²·v_n/s (Reynolds' thin film between spheres; Adams & Perchard 1985), s the
/// gap but at least [`BRIDGE_MIN_GAP`]·R*, positive where it pulls the bodies together \[N\];
/// 0 without a viscosity.
#[inline(always)]
pub fn bridge_drag(b: &Bridge, r_eff: f32, overlap: f32, vn: f32) -> f32 {
    if b.viscosity == 0.0 {
        return 0.0;
    }
    let gap = (-overlap).max(BRIDGE_MIN_GAP * r_eff);
    6.0 * PI * b.viscosity * r_eff * (r_eff / gap) * vn
}

/// Partner id of wall `w` in the contact history: walls 0..6 are the low and high walls of x,
/// y and z (`2·axis + side`).
pub const WALLS: u32 = 6;

/// What the six walls of the box do to one sphere.
#[derive(Debug, Clone, Copy)]
pub struct WallContacts {
    /// Normal forces, summed per axis low wall first \[N\].
    pub normal: Vec3,
    /// Tangential forces \[N\].
    pub tangential: Vec3,
    /// Torque about the centre \[N·m\].
    pub torque: Vec3,
}

/// The walls touching sphere `b`: `old(w)` gives the springs it kept of wall `w` (zero for none)
/// and whether it touched the wall at the last step, and `keep(w, springs)` receives those to
/// keep, for each touching wall in order, where the material has history;
/// `seen(w, normal, tangential, overlap)` receives each touching wall's forces on the sphere.
#[inline(always)]
pub fn wall_contacts<S: Kept>(
    p: &StepParams,
    b: &Body,
    old: impl Fn(u32) -> (S, bool),
    mut keep: impl FnMut(u32, S),
    mut seen: impl FnMut(u32, Vec3, Vec3, f32),
) -> WallContacts {
    let turns = p.friction.turns();
    let keeps = p.friction.has_history();
    let law = p.materials.law(b.material, p.box_column);
    let wet = p.materials.bridge(b.material, p.box_column);
    let (c, v) = (b.c.to_array(), b.v.to_array());
    let mut normal = [0.0f32; 3];
    let mut tangential = Vec3::ZERO;
    let mut torque = Vec3::ZERO;
    for a in 0..3 {
        let mut f = 0.0;
        // Low wall (normal −e_a from the centre, v_n = v_a), then high wall (+e_a, v_n = −v_a).
        let below = b.r - (c[a] - p.box_lo[a]);
        let above = b.r - (p.box_hi[a] - c[a]);
        for (side, overlap, vn) in [(0, below, v[a]), (1, above, -v[a])] {
            let wall = 2 * a as u32 + side;
            let held = p.friction.cohesive && old(wall).1 && holds(p, law, wet, b.r, overlap);
            if overlap <= 0.0 && !held {
                continue;
            }
            let mut pull = p
                .bridge
                .map_or(0.0, |bridge| bridge_pull(&bridge, wet, b.r, overlap));
            let drag = p
                .bridge
                .map_or(0.0, |bridge| bridge_drag(&bridge, b.r, overlap, vn));
            if p.cohesion_density > 0.0 && overlap > 0.0 {
                // The area of the circle where the sphere meets the wall's plane.
                pull += p.cohesion_density * PI * overlap * (2.0 * b.r - overlap);
            }
            let bridged = overlap <= 0.0 && law.adhesion == 0.0;
            let mut nf = match bridged {
                // A liquid bridge across a gap: its pull alone, no friction.
                true => Normal {
                    push: 0.0,
                    elastic: 0.0,
                    stiffness: 0.0,
                    load: 0.0,
                    radius: 0.0,
                },
                false => normal_force(p, law, overlap, vn, b.m, b.r),
            };
            // The push away from the wall, less a bridge's pull and drag.
            let push = match pull > 0.0 {
                true => {
                    nf.load += pull;
                    nf.push - pull
                }
                false => nf.push,
            };
            let push = match drag != 0.0 {
                true => push - drag,
                false => push,
            };
            match side {
                0 => f += push,
                _ => f -= push,
            }
            let pushed = [push, -push][side as usize] * Vec3::AXES[a];
            if !turns || bridged {
                seen(wall, pushed, Vec3::ZERO, overlap);
                // An adhering contact is remembered without springs.
                if keeps {
                    keep(wall, S::default());
                }
            } else {
                let n = if side == 0 {
                    -Vec3::AXES[a]
                } else {
                    Vec3::AXES[a]
                };
                let touch = Touch {
                    n,
                    overlap,
                    normal: nf,
                    m_eff: b.m,
                    r_eff: b.r,
                    i_eff: b.inertia(),
                    lever: b.r,
                    v_rel: b.v + b.w.cross(b.r * n),
                    w_rel: b.w,
                };
                let (f_t, t, springs) = friction(p, law, &touch, law.sliding, old(wall).0);
                seen(wall, pushed, f_t, overlap);
                tangential += f_t;
                torque += t;
                if keeps {
                    keep(wall, springs);
                }
            }
        }
        normal[a] = f;
    }
    WallContacts {
        normal: Vec3::from_array(normal),
        tangential,
        torque,
    }
}

/// Whether a contact of sphere `b` with a surface of column `column` that touched at the last
/// step and now overlaps by `overlap` ≤ 0 still holds (a JKR neck, a liquid bridge).
#[inline(always)]
pub fn surface_holds(p: &StepParams, b: &Body, column: u32, overlap: f32) -> bool {
    let (law, wet) = (
        p.materials.law(b.material, column),
        p.materials.bridge(b.material, column),
    );
    holds(p, law, wet, b.r, overlap)
}

/// The contact of sphere `b` with a surface (a mesh wall) of column `column` in the material
/// table (its material, or a rigid wall): `n` the unit normal from the centre towards the
/// contact point, `overlap` > 0 (or ≤ 0 where [`surface_holds`]), `surface_velocity` the velocity of the surface's material
/// point at the contact, `friction` the wall's own sliding coefficient (`None`: the pair's),
/// `old` the springs the sphere kept of this contact. The same law as a box wall's
/// ([`wall_contacts`]), with the surface's own velocity subtracted from the sphere's: a moving
/// wall drags what touches it.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn surface_contact<S: Kept>(
    p: &StepParams,
    b: &Body,
    n: Vec3,
    overlap: f32,
    surface_velocity: Vec3,
    column: u32,
    friction_given: Option<f32>,
    old: S,
) -> Contact<S> {
    let law = p.materials.law(b.material, column);
    let wet = p.materials.bridge(b.material, column);
    let mu = friction_given.unwrap_or(law.sliding);
    // v_n as for a pair: the partner's (the surface's) velocity minus b's, along n.
    let vn = (surface_velocity - b.v).dot(n);
    let mut pull = p
        .bridge
        .map_or(0.0, |bridge| bridge_pull(&bridge, wet, b.r, overlap));
    let drag = p
        .bridge
        .map_or(0.0, |bridge| bridge_drag(&bridge, b.r, overlap, vn));
    if p.cohesion_density > 0.0 && overlap > 0.0 {
        // The area of the circle where the sphere meets the surface's plane.
        pull += p.cohesion_density * PI * overlap * (2.0 * b.r - overlap);
    }
    if overlap <= 0.0 && law.adhesion == 0.0 {
        // A liquid bridge across a gap: its pull alone, and its drag.
        let force = dragged(pull, drag) * n;
        return Contact {
            force,
            normal: force,
            torque: Vec3::ZERO,
            springs: S::default(),
        };
    }
    let mut normal = normal_force(p, law, overlap, vn, b.m, b.r);
    let along = match pull > 0.0 {
        true => {
            normal.load += pull;
            pull - normal.push
        }
        false => -normal.push,
    };
    let force = dragged(along, drag) * n;
    if !p.friction.turns() {
        return Contact {
            force,
            normal: force,
            torque: Vec3::ZERO,
            springs: S::default(),
        };
    }
    let touch = Touch {
        n,
        overlap,
        normal,
        m_eff: b.m,
        r_eff: b.r,
        i_eff: b.inertia(),
        lever: b.r,
        v_rel: b.v + b.w.cross(b.r * n) - surface_velocity,
        w_rel: b.w,
    };
    let (f_t, torque, springs) = friction(p, law, &touch, mu, old);
    Contact {
        force: force + f_t,
        normal: force,
        torque,
        springs,
    }
}

/// `x` turned into the plane normal to `n`: its normal part removed, its length kept.
#[inline(always)]
fn into_plane(x: Vec3, n: Vec3) -> Vec3 {
    let t = x - x.dot(n) * n;
    let len = length(t);
    if len > 0.0 { t * (length(x) / len) } else { t }
}

/// The cube root of a normal `x` > 0, by the same operations on every backend (WGSL has no cube
/// root, and the libraries' are not the same function): a start from the bits (the exponent
/// divided by three, within a few per cent at any scale), then three Newton steps,
/// y ← (2y + x/y²)/3, which bring it within an ulp or two of ∛x. 0 for x ≤ 0. Keep in sync
/// with `cube_root` in wgsl/dem/dem_contact.wgsl and `mochi_cube_root` in optix/contact.cuh.
#[inline(always)]
pub fn cube_root(x: f32) -> f32 {
    if x <= 0.0 {
        return 0.0;
    }
    let mut y = f32::from_bits(x.to_bits() / 3 + 0x2a51_37a0);
    for _ in 0..3 {
        y = (y + y + x / (y * y)) / 3.0;
    }
    y
}

/// What the tangential force of a contact needs besides its springs.
#[derive(Debug, Clone, Copy)]
pub struct Load {
    /// Mindlin's full tangential stiffness S_t = 8G*√(R*δ) (linear laws: 2/7·k) \[N/m\].
    pub k_t: f32,
    /// Tangential damping coefficient \[N·s/m\].
    pub c_t: f32,
    /// Sliding friction coefficient.
    pub mu: f32,
    /// Elastic normal force N \[N\].
    pub elastic: f32,
    /// The normal force that caps the tangential one (push, ≥ 0) \[N\].
    pub pressing: f32,
    /// Time step \[s\].
    pub dt: f32,
}

/// The Mindlin–Deresiewicz tangential force on i (docs/method.md, "Friction, rotation and
/// rolling resistance"): Thornton & Yin's incremental form (Powder Technol. 65 (1991) 153–166;
/// as restated by Thornton, Cummins & Cleary, Powder Technol. 210 (2011) 189–197) in vectors.
/// The elastic force F (kept in `springs.tangential`) changes by
/// ΔF = −S_t·θ·Δξ + μ·ΔN·(1 − θ)·ê, Δξ = v_t·dt, ê the direction F moves in away from the last
/// reversal point F* (`springs.reversal`), with θ³ = 1 − (|F − F*| + c·μ·ΔN)/(c·μ·N), c = 1 on
/// the virgin curve (F* = 0) and 2 after a reversal (Masing's rule); θ = 1 where the normal
/// force grows faster than the tangential one would (μ·ΔN > S_t·|Δξ|: no new slip). A reversal
/// (Δξ driving F back towards F*) makes F* = F; F*'s size follows the normal force by μ·ΔN;
/// past the mirror point (|F| ≥ |F*| on the far side) the virgin curve holds again; |F| ≤ μ·N
/// (full slip: virgin again). The damping −c_t·v_t is added and Coulomb's cap μ·push
/// applied as for Mindlin's spring. Every operation is odd in the vectors, so the partner's
/// side (all vectors negated, N the same) gets the exact negatives.
#[inline(always)]
fn load_history(
    load: &Load,
    n: Vec3,
    v_t: Vec3,
    old: &LoadedSprings,
    springs: &mut LoadedSprings,
) -> Vec3 {
    let mu = load.mu;
    let mut f = into_plane(old.springs.tangential, n);
    let mut r = into_plane(old.reversal, n);
    let dn = load.elastic - old.normal;
    let d = v_t * load.dt;
    // A reversal: the displacement drives the force back towards the last reversal point.
    let back = f - r;
    if length(back) > 0.0 && back.dot(d) > 0.0 {
        r = f;
    }
    // The reversal point follows the normal force (Thornton & Yin's T* += μΔN); where it
    // shrinks to nothing the virgin curve holds.
    if r != Vec3::ZERO {
        let size = length(r);
        let grown = size + mu * dn;
        r = if grown > 0.0 {
            r * (grown / size)
        } else {
            Vec3::ZERO
        };
    }
    let c = if r != Vec3::ZERO { 2.0 } else { 1.0 };
    let scale = c * mu * load.elastic;
    let away = f - r;
    let gone = length(away);
    let mut theta = 0.0;
    if scale > 0.0 {
        theta = cube_root(1.0 - (gone + c * mu * dn) / scale);
    }
    let step = length(d);
    if mu * dn > load.k_t * step {
        theta = 1.0;
    }
    let e = if gone > 0.0 {
        away / gone
    } else if step > 0.0 {
        d / -step
    } else {
        Vec3::ZERO
    };
    f = f - d * (load.k_t * theta) + e * (mu * dn * (1.0 - theta));
    // Past the mirror point of the last reversal: back on the virgin curve.
    if r != Vec3::ZERO && f.dot(r) < 0.0 && length(f) >= length(r) {
        r = Vec3::ZERO;
    }
    // Never more than μN: full slip, and the virgin curve from there.
    let most = mu * load.elastic;
    let len = length(f);
    if len > most {
        f *= most / len;
        r = Vec3::ZERO;
    }
    let mut f_t = f - load.c_t * v_t;
    let cap = mu * load.pressing;
    let len = length(f_t);
    if len > cap {
        f_t *= cap / len;
        f = f_t;
        r = Vec3::ZERO;
    }
    springs.springs.tangential = f;
    springs.reversal = r;
    springs.normal = load.elastic;
    f_t
}

/// Tangential force of a contact of law `law` with sliding coefficient `mu`, the torque on i
/// (from it and from rolling resistance) and the springs to keep.
#[inline(always)]
fn friction<S: Kept>(p: &StepParams, law: &PairLaw, t: &Touch, mu: f32, old: S) -> (Vec3, Vec3, S) {
    debug_assert!(!p.friction.has_history() || p.friction.tangential_model == S::MODEL);
    let n = t.n;
    let pressing = t.normal.load;
    let mut force = Vec3::ZERO;
    let mut torque = Vec3::ZERO;
    let mut springs = S::default();
    if mu > 0.0 {
        let (k_t, c_t) = match p.law {
            NormalLaw::Linear | NormalLaw::LinearPerPair { .. } => {
                let k_t = 2.0 / 7.0 * t.normal.stiffness;
                (k_t, 2.0 * law.damping_ratio * root_product(k_t, t.m_eff))
            }
            NormalLaw::Hertz { .. } => {
                let a = match law.adhesion > 0.0 {
                    true => t.normal.radius,
                    false => (t.r_eff * t.overlap).sqrt(),
                };
                let s_t = 8.0 * law.g_star * a;
                (s_t, TSUJI * law.damping_ratio * root_product(s_t, t.m_eff))
            }
        };
        let v_t = t.v_rel - t.v_rel.dot(n) * n;
        let load = Load {
            k_t,
            c_t,
            mu,
            elastic: t.normal.elastic,
            pressing,
            dt: p.dt,
        };
        let f_t = S::tangential(&load, n, v_t, &old, &mut springs);
        force = f_t;
        torque = (t.lever * n).cross(f_t);
    }
    let mu_r = law.rolling;
    if mu_r > 0.0 {
        let w_roll = t.w_rel - t.w_rel.dot(n) * n;
        let cap = mu_r * t.r_eff * pressing;
        let rolling = match p.friction.rolling_model {
            RollingModel::Epsd => {
                let k_r = 2.25 * t.normal.stiffness * mu_r * mu_r * t.r_eff * t.r_eff;
                let mut m = into_plane(old.rolling(), n) - k_r * p.dt * w_roll;
                let len = length(m);
                if len > cap {
                    m *= cap / len;
                }
                springs.set_rolling(m);
                m
            }
            RollingModel::ConstantTorque => {
                let speed = length(w_roll);
                if speed > 0.0 {
                    // Never more than stops the relative rolling within the step.
                    let size = cap.min(t.i_eff * speed / p.dt);
                    w_roll * (-size / speed)
                } else {
                    Vec3::ZERO
                }
            }
        };
        torque += rolling;
    }
    (force, torque, springs)
}

/// One semi-implicit Euler step of a sphere's rotation: ω += dt·τ/I.
#[inline(always)]
pub fn integrate_rotation(dt: f32, w: &mut [f32; 3], torque: Vec3, inertia: f32) {
    let t = torque.to_array();
    for a in 0..3 {
        w[a] += dt * (t[a] / inertia);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effective_values_of_small_spheres_are_their_products_over_their_sums_without_the_product() {
        // Masses of spheres of 1e-12 m: their product underflows f32 to 0.
        let (a, b) = (2e-33f32, 3e-33f32);
        assert_eq!(a * b / (a + b), 0.0);
        let exact = a as f64 * b as f64 / (a as f64 + b as f64);
        for got in [effective(a, b), effective(b, a)] {
            assert!(
                (got as f64 / exact - 1.0).abs() < 3e-7,
                "{got:e}, {exact:e}"
            );
        }
        // Symmetric bit for bit, equal values halve exactly, a vanishing ratio gives lo.
        for (x, y) in [(1.7f32, 0.3), (1e-30, 7e-31), (3.0, 3.0), (1e-30, 1e20)] {
            assert_eq!(effective(x, y).to_bits(), effective(y, x).to_bits());
        }
        assert_eq!(effective(3.0, 3.0), 1.5);
        assert_eq!(effective(1e-30, 1e20), 1e-30);
    }

    #[test]
    fn root_products_and_lengths_of_small_quantities_do_not_underflow() {
        // A stiffness and an effective mass of 1e-12 m spheres whose product is below f32's
        // smallest subnormal number.
        let (k, m) = (1e-13f32, 1e-33f32);
        assert_eq!((k * m).sqrt(), 0.0);
        assert!((root_product(k, m) as f64 / 1e-46f64.sqrt() - 1.0).abs() < 1e-6);
        // A rolling torque of a 1e-8 m sphere: its square is 0 in f32.
        let v = Vec3::new(3e-24, -4e-24, 0.0);
        assert_eq!(v.length(), 0.0);
        assert!((length(v) / 5e-24 - 1.0).abs() < 1e-6, "{}", length(v));
        assert_eq!(length(Vec3::ZERO), 0.0);
        assert_eq!(length(Vec3::new(0.0, -2.0, 0.0)), 2.0);
        let w = Vec3::new(0.3, -1.7, 2.9);
        assert!((length(w) / w.length() - 1.0).abs() < 3e-7);
    }

    #[test]
    fn the_cube_root_is_within_two_ulps_from_1e_minus_36_to_1e36() {
        assert_eq!(cube_root(0.0), 0.0);
        assert_eq!(cube_root(-1.0), 0.0);
        assert_eq!(cube_root(1.0), 1.0);
        let mut x = 1e36f32;
        while x > 1e-36 {
            for y in [x, x * 0.7, x * 0.3] {
                let got = cube_root(y);
                let want = (y as f64).cbrt() as f32;
                let ulps = (got.to_bits() as i64 - want.to_bits() as i64).abs();
                assert!(ulps <= 2, "∛{y:e}: {got:e}, {want:e}");
            }
            x *= 0.5;
        }
    }

    #[test]
    fn the_mindlin_deresiewicz_contact_is_equal_and_opposite_through_loading_and_reversals() {
        use super::super::{ContactLaw, Material, TangentialModel, mass};
        let material = Material {
            contact: ContactLaw::HertzMindlin {
                young_modulus: 1e7,
                poisson_ratio: 0.3,
            },
            friction: 0.5,
            restitution: 0.7,
            tangential_model: TangentialModel::MindlinDeresiewicz,
            ..Material::default()
        };
        let r = 0.01;
        let p = StepParams::new(&material, 1e-6, [0.0; 3], [1.0; 3], [0.0; 3], 0.0, r).unwrap();
        let body = |c: Vec3, v: Vec3, w: Vec3| Body {
            c,
            v,
            w,
            r,
            m: mass(500.0, r),
            material: 0,
        };
        let (mut a, mut b) = (LoadedSprings::default(), LoadedSprings::default());
        let mut reversed = false;
        // Tangential speeds that load, turn back and load again while the pair approaches.
        for (k, side) in [0.3f32, 0.2, -0.4, -0.1, 0.5, 0.6].into_iter().enumerate() {
            let gap = 1.99 - 0.002 * k as f32;
            let i = body(Vec3::splat(0.5), Vec3::new(0.1, side, 0.0), Vec3::Z);
            let j = body(
                i.c + Vec3::new(gap * r, 0.0, 0.0),
                Vec3::new(-0.1, -side, 0.05),
                -Vec3::Y,
            );
            let f = pair_contact(&p, &i, &j, a, false).unwrap();
            let g = pair_contact(&p, &j, &i, b, false).unwrap();
            assert_eq!(f.force, -g.force, "step {k}");
            assert_eq!(f.springs, g.springs.negated());
            assert_eq!(f.springs.springs.tangential, -g.springs.springs.tangential);
            assert_eq!(f.springs.reversal, -g.springs.reversal);
            assert_eq!(f.springs.normal, g.springs.normal);
            assert!(f.springs.normal > 0.0);
            reversed |= f.springs.reversal != Vec3::ZERO;
            (a, b) = (f.springs, g.springs);
        }
        // The turn back left a reversal point on the way.
        assert!(reversed);
    }

    #[test]
    fn the_contact_of_the_smallest_spheres_that_turn_is_equal_and_opposite_and_damped() {
        use super::super::{ContactLaw, Material, mass, smallest_turning_radius};
        let r = smallest_turning_radius(500.0);
        let material = Material {
            contact: ContactLaw::HertzMindlin {
                young_modulus: 1e7,
                poisson_ratio: 0.3,
            },
            friction: 0.5,
            rolling_friction: 0.1,
            ..Material::default()
        };
        let side = 100.0 * r as f64;
        let p = StepParams::new(&material, 1e-11, [0.0; 3], [side; 3], [0.0; 3], 0.0, r).unwrap();
        let body = |c: Vec3, v: Vec3, w: Vec3| Body {
            c,
            v,
            w,
            r,
            m: mass(500.0, r),
            material: 0,
        };
        let i = body(Vec3::splat(50.0 * r), Vec3::new(0.5, 0.1, 0.0), Vec3::Y / r);
        let j = body(
            i.c + Vec3::new(1.98 * r, 0.0, 0.0),
            Vec3::new(-0.5, 0.0, 0.2),
            Vec3::Z / r,
        );
        let f = pair_contact(&p, &i, &j, Springs::default(), false).unwrap();
        let g = pair_contact(&p, &j, &i, Springs::default(), false).unwrap();
        assert_eq!(f.force, -g.force);
        assert_eq!(f.springs.rolling, -g.springs.rolling);
        // Closing at 1 m/s: the damping pushes harder than the spring alone.
        let elastic = pair_contact(
            &p,
            &Body { v: Vec3::ZERO, ..i },
            &Body { v: Vec3::ZERO, ..j },
            Springs::default(),
            false,
        )
        .unwrap();
        assert!(f.force.x < 1.01 * elastic.force.x && elastic.force.x < 0.0);
        // Rolling resistance acts.
        assert_ne!(f.springs.rolling, Vec3::ZERO);
    }
}
