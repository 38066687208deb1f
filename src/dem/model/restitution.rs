//! The damping ratio ζ that makes a head-on contact part at the restitution e the material
//! asks for (docs/method.md, "Restitution").
//!
//! A dry contact cannot pull, so the step clamps the normal force at zero: a damped contact ends
//! when its force vanishes, before its overlap does, and the textbook ζ = −ln e/√(π² + ln² e)
//! (derived for a dashpot that pulls at the end) would part faster than e. Nor does the
//! integrator leave e alone: semi-implicit Euler dissipates by itself, ten steps per contact of
//! the linear law cost about 9 % of e. So ζ is the root of `rebound(ζ) = e`, where `rebound`
//! integrates a head-on contact in f64 exactly as the step does: the force from the overlap and
//! the closing speed at the start of the step, clamped at zero, then the speed, then the overlap.
//! In units where the impact speed is 1:
//!
//! - linear laws (one stiffness, or one per pair): time in 1/ω with ω = √(k/m*), so the step
//!   is h = ω·dt and the force per mass f = max(x + 2ζu, 0) for overlap x and closing speed u.
//!   The contact is first seen at an overlap between 0 and h (where within a step it began);
//!   at steps coarser than [`PHASED_STEP`] the rebound is the mean over [`PHASES`] such
//!   beginnings.
//! - Hertz with Tsuji's damping: overlap in (m*/(4/3·E*·√R*))^{2/5}, which makes the force per
//!   mass f = max(x^{3/2} + √5·ζ·x^{1/4}·u, 0) for every size, speed and modulus, so one ζ
//!   serves every contact. The step's own resolution is not modelled (the Rayleigh step gives
//!   a contact tens of steps and more): it is integrated at [`FINE_STEP`].
//!
//! Steps finer than [`FINE_STEP`] are integrated at it: a contact of more than about 15,000
//! steps, where the integrator's share of e is below 1e-4 of it.

use crate::error::{Error, Result};

/// The finest step the rebound is integrated at, in the units above.
pub const FINE_STEP: f64 = 2e-4;

/// How many beginnings within a step the linear laws' rebound averages over.
pub const PHASES: usize = 16;

/// The step from which the beginning within a step matters to the linear laws' rebound (a
/// contact of fewer than about 300 steps); finer ones begin half a step in.
pub const PHASED_STEP: f64 = 1e-2;

/// Rebound over impact speed of a head-on contact whose force per mass is `force(x, u)` at
/// overlap x and closing speed u, integrated with step `h` from the overlap `x0`; 0 when it
/// has not parted within `max_steps` (a contact held at rest).
fn rebound(force: impl Fn(f64, f64) -> f64, h: f64, x0: f64, max_steps: usize) -> f64 {
    let (mut x, mut u) = (x0, 1.0);
    for _ in 0..max_steps {
        u -= h * force(x, u).max(0.0);
        x += h * u;
        if x <= 0.0 {
            return -u;
        }
    }
    0.0
}

/// Steps enough for any contact these laws part from: a few contact durations (about π in
/// both unit systems) and the slow release of a heavily damped contact.
fn step_budget(h: f64, zeta: f64) -> usize {
    ((20.0 + 4.0 * zeta) / h).ceil() as usize
}

/// Rebound of the linear laws' head-on contact with damping ratio `zeta` at step `omega_dt`
/// (ω·dt; finer steps than [`FINE_STEP`] at it), the mean over [`PHASES`] beginnings at steps
/// from [`PHASED_STEP`] on.
pub fn linear_rebound(zeta: f64, omega_dt: f64) -> f64 {
    let h = omega_dt.max(FINE_STEP);
    let budget = step_budget(h, zeta);
    let phases = if h >= PHASED_STEP { PHASES } else { 1 };
    let sum: f64 = (0..phases)
        .map(|k| {
            let x0 = h * (k as f64 + 0.5) / phases as f64;
            rebound(|x, u| x + 2.0 * zeta * u, h, x0, budget)
        })
        .sum();
    sum / phases as f64
}

/// Rebound of a Hertz contact with Tsuji's damping at damping ratio `zeta`, for every size,
/// speed and modulus.
pub fn hertz_rebound(zeta: f64) -> f64 {
    let h = FINE_STEP;
    let tsuji = 5f64.sqrt() * zeta;
    let force = |x: f64, u: f64| {
        let q = x.sqrt().sqrt();
        x * x.sqrt() + tsuji * q * u
    };
    rebound(force, h, h / 2.0, step_budget(h, zeta))
}

/// The largest damping ratio the linear laws may have at step `omega_dt` = ω·dt: semi-implicit
/// Euler keeps the contact stable (ω·dt < 2(√(1 + ζ²) − ζ), so ζ < (1 − (ω·dt)²/4)/(ω·dt)),
/// and the damping alone never reverses the closing speed within a step (2ζ·ω·dt ≤ 1), beyond
/// which more damping makes a faster rebound.
fn most_damping(omega_dt: f64) -> f64 {
    ((1.0 - omega_dt * omega_dt / 4.0) / omega_dt).min(0.5 / omega_dt)
}

/// The ζ in `[0, most]` at which the decreasing `rebound` equals `e` (Illinois' regula falsi
/// in a bracket doubled from ζ = 1/2), or `None` where even `most` parts faster than `e`.
/// ζ = 0 where e = 1 or where the undamped contact already parts slower than e (the
/// integrator's own loss; nothing to add).
fn solve(rebound: impl Fn(f64) -> f64, e: f64, most: f64) -> Option<f64> {
    let mut fa = rebound(0.0) - e;
    if e >= 1.0 || fa <= 0.0 {
        return Some(0.0);
    }
    let (mut a, mut b) = (0.0, most.min(0.5));
    let mut fb = rebound(b) - e;
    while fb > 0.0 {
        if b >= most {
            return None;
        }
        (a, fa) = (b, fb);
        b = (2.0 * b).min(most);
        fb = rebound(b) - e;
    }
    let mut side = 0;
    for _ in 0..100 {
        let c = (a * fb - b * fa) / (fb - fa);
        let fc = rebound(c) - e;
        if fc.abs() <= 1e-12 || (b - a) <= 1e-12 * b {
            return Some(c);
        }
        if fc > 0.0 {
            (a, fa) = (c, fc);
            if side == 1 {
                fb /= 2.0;
            }
            side = 1;
        } else {
            (b, fb) = (c, fc);
            if side == -1 {
                fa /= 2.0;
            }
            side = -1;
        }
    }
    Some((a + b) / 2.0)
}

/// The damping ratio that makes a head-on contact of the linear laws part at `e`, at step
/// `omega_dt` = ω·dt of the contact (ω = √(k/m*)); an error where no stable damping does. At
/// ω·dt ≥ 2 not even an undamped step is stable: the ratio of fine steps is returned, for the
/// caller's check of the time step ([`super::stable_dt`]) to refuse it with its limit.
pub fn linear_damping(e: f64, omega_dt: f64) -> Result<f64> {
    let h = if omega_dt < 2.0 { omega_dt } else { 0.0 };
    let most = if h > 0.0 {
        most_damping(h)
    } else {
        f64::INFINITY
    };
    solve(|zeta| linear_rebound(zeta, h), e, most.min(100.0)).ok_or_else(|| Error::InvalidConfig {
        what: "material".into(),
        reason: format!(
            "restitution {e} needs more damping than a contact of {:.1} steps can take (ω·dt \
             = {h:.3}; a stable step that does not reverse the closing speed by damping alone \
             has ζ ≤ {most:.3}): choose a smaller time step",
            std::f64::consts::PI / h
        ),
    })
}

/// The damping ratio that makes a Hertz contact with Tsuji's damping part at `e`.
pub fn hertz_damping(e: f64) -> f64 {
    // Tsuji's damping parts at any e > 0 below ζ = 100.
    solve(hertz_rebound, e, 100.0).unwrap_or(100.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn an_undamped_contact_parts_at_its_impact_speed() {
        assert!(
            (hertz_rebound(0.0) - 1.0).abs() < 1e-6,
            "{}",
            hertz_rebound(0.0)
        );
        assert!((linear_rebound(0.0, 1e-3) - 1.0).abs() < 1e-6);
        assert_eq!(linear_damping(1.0, 0.3).unwrap(), 0.0);
        assert_eq!(hertz_damping(1.0), 0.0);
    }

    #[test]
    fn fine_linear_contacts_part_at_the_clamped_dashpots_closed_form() {
        // A linear dashpot whose force is clamped at zero parts when x + 2ζu first vanishes:
        // with ω_d = √(1 − ζ²), at ω_d·t = π − atan2(2ζω_d, 1 − 2ζ²), at the speed
        // e^{−ζt}(ζ/ω_d·sin ω_d t − cos ω_d t) (Schwager & Pöschel, Granular Matter 9 (2007)
        // 465–469).
        for zeta in [0.05f64, 0.2, 0.5, 0.8] {
            let w = (1.0 - zeta * zeta).sqrt();
            let t = (PI - (2.0 * zeta * w).atan2(1.0 - 2.0 * zeta * zeta)) / w;
            let exact = (-zeta * t).exp() * (zeta / w * (w * t).sin() - (w * t).cos());
            let got = linear_rebound(zeta, 0.0);
            assert!(
                (got / exact - 1.0).abs() < 2e-4,
                "ζ {zeta}: {got} vs {exact}"
            );
            // Higher than the dashpot that pulls, e^{−ζπ/ω_d}.
            assert!(got > (-zeta * PI / w).exp());
        }
    }

    #[test]
    fn the_damping_found_gives_the_restitution_asked_for() {
        for e in [0.1, 0.2, 0.5, 0.9, 0.99] {
            for omega_dt in [0.0, 0.01, 0.33] {
                let zeta = linear_damping(e, omega_dt).unwrap();
                let got = linear_rebound(zeta, omega_dt);
                assert!((got - e).abs() < 1e-9, "e {e}, ω·dt {omega_dt}: {got}");
            }
            let zeta = hertz_damping(e);
            assert!((hertz_rebound(zeta) - e).abs() < 1e-9);
        }
        // Three steps per contact: damping may not exceed 1/(2ω·dt), which parts at 0.5.
        assert!(linear_damping(0.5, 1.0).is_ok() && linear_damping(0.4, 1.0).is_err());
        // Ten steps per contact lose restitution by themselves: less damping makes it up.
        let coarse = linear_damping(0.5, 0.33).unwrap();
        let fine = linear_damping(0.5, 0.0).unwrap();
        assert!(coarse < fine, "{coarse} {fine}");
    }

    #[test]
    fn damping_beyond_the_stable_step_is_refused() {
        // At ω·dt = 1.9, ζ may not exceed 0.05: e = 0.1 needs far more.
        let err = linear_damping(0.1, 1.9).unwrap_err().to_string();
        assert!(err.contains("smaller time step"), "{err}");
    }
}
