//! The paper's contact law, kept as the GPU engines run it: a linear spring–dashpot normal force
//! between spheres and with the six walls of a box, no friction, no rotation.
//!
//! The force on sphere i from a touching sphere j, with n the unit vector from c_i to c_j,
//! overlap δ = r_i + r_j − |c_j − c_i| and normal relative velocity v_n = (v_j − v_i)·n, is
//! F_i = −max(k·δ − c·v_n, 0)·n with c = 2ζ·√(k·m_eff), m_eff = m_i·m_j/(m_i + m_j), and ζ the
//! damping ratio that gives the restitution coefficient e ([`super::restitution`]): a dry
//! contact pushes or does nothing, it never pulls. Walls act the same way with m_eff = m_i. Neither product is formed (they underflow f32 for small spheres):
//! m_eff is [`effective`]`(m_i, m_j)` and √(k·m_eff) is [`root_product`]`(k, m_eff)`. Computed
//! from j's side, every operation sees negated inputs and m_eff is symmetric, so F_j = −F_i
//! exactly. Coincident centres (distance 0) have no contact normal and get no force: the
//! steppers never see them, as `Particles::separate_coincident` spreads such spheres about their
//! centre when a stepper is made. `wgsl/dem_physics.wgsl` follows [`contact_force`] and
//! [`wall_force`] line by line; the cpu step's [`super::contact`] computes the same normal
//! force with the same operations, so both give the same bits for this law.

use super::StepParams;
use super::contact::{effective, root_product};
use std::f64::consts::PI;

/// Contact durations per time step that the default stiffness gives the lightest pair.
pub const STEPS_PER_CONTACT: f64 = 10.0;

/// Largest stable time step of semi-implicit Euler for a contact of effective mass `m_eff`:
/// ω·dt < 2(√(1 + ζ²) − ζ) with ω = √(k/m_eff).
pub fn stable_dt(stiffness: f64, m_eff: f64, zeta: f64) -> f64 {
    2.0 * ((1.0 + zeta * zeta).sqrt() - zeta) / (stiffness / m_eff).sqrt()
}

/// Stiffness that makes a contact of effective mass `m_eff` with restitution `e` last `t_c` \[s\]
/// as a dashpot that pulls would (ω_d = π/t_c with ζ = −ln e/√(π² + ln² e)); the clamped contact
/// of the step, damped for e by [`super::restitution`], lasts about as long.
pub fn stiffness_for_duration(m_eff: f64, e: f64, t_c: f64) -> f64 {
    let l = e.ln();
    m_eff * (PI * PI + l * l) / (t_c * t_c)
}

/// Force on sphere i (centre `c_i`, velocity `v_i`, radius `r_i`, mass `m_i`) from sphere j, or
/// `None` when they do not touch (or their centres coincide: no normal, no force).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn contact_force(
    p: &StepParams,
    c_i: [f32; 3],
    v_i: [f32; 3],
    r_i: f32,
    m_i: f32,
    c_j: [f32; 3],
    v_j: [f32; 3],
    r_j: f32,
    m_j: f32,
) -> Option<[f32; 3]> {
    let d = [c_j[0] - c_i[0], c_j[1] - c_i[1], c_j[2] - c_i[2]];
    let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let reach = r_i + r_j;
    if d2 > reach * reach || d2 == 0.0 {
        return None;
    }
    let dist = d2.sqrt();
    let n = [d[0] / dist, d[1] / dist, d[2] / dist];
    let overlap = reach - dist;
    let dv = [v_j[0] - v_i[0], v_j[1] - v_i[1], v_j[2] - v_i[2]];
    let vn = dv[0] * n[0] + dv[1] * n[1] + dv[2] * n[2];
    let m_eff = effective(m_i, m_j);
    let c = 2.0 * p.damping_ratio * root_product(p.stiffness, m_eff);
    let push = (p.stiffness * overlap - c * vn).max(0.0);
    Some([-push * n[0], -push * n[1], -push * n[2]])
}

/// Force of the box walls on a sphere at `c` with velocity `v`, radius `r` and mass `m`.
#[inline(always)]
pub fn wall_force(p: &StepParams, c: [f32; 3], v: [f32; 3], r: f32, m: f32) -> [f32; 3] {
    let damping = 2.0 * p.damping_ratio * root_product(p.stiffness, m);
    std::array::from_fn(|a| {
        let mut f = 0.0;
        let below = r - (c[a] - p.box_lo[a]);
        if below > 0.0 {
            f += (p.stiffness * below - damping * v[a]).max(0.0);
        }
        let above = r - (p.box_hi[a] - c[a]);
        if above > 0.0 {
            f -= (p.stiffness * above + damping * v[a]).max(0.0);
        }
        f
    })
}
