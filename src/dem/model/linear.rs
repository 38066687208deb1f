//! The paper's contact law's numbers: the stiffness that gives a contact its duration and the
//! largest stable time step of a linear spring–dashpot. The law itself (a linear normal force
//! between spheres and with the six walls of a box, no friction, no rotation: the granular law
//! with `NormalLaw::Linear` and no friction) is the one of the contact module, which the GPU
//! engines follow line by line.

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
