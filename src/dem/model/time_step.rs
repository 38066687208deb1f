//! The time step a material needs: Rayleigh time for Hertz–Mindlin, the contact's period for
//! the linear laws (docs/method.md, "Time step").

use std::f64::consts::PI;

/// The time step of a Hertz–Mindlin run when none is given, as a fraction of the Rayleigh time
/// of the smallest sphere (common practice is 0.1–0.3; EDEM suggests 0.2).
pub const RAYLEIGH_FRACTION: f64 = 0.2;

/// The largest time step accepted for Hertz–Mindlin, as a fraction of the Rayleigh time: at
/// half of it, semi-implicit Euler stays stable on the tangential spring (the stiffer one) up
/// to overlaps of tens of percent of the radius, where at the whole Rayleigh time it fails at
/// a few percent.
pub const RAYLEIGH_LIMIT: f64 = 0.5;

/// Rayleigh time \[s\] of a sphere of radius `r` \[m\]: how long a Rayleigh wave takes to
/// cross it, T_R = π·r·√(ρ/G) / (0.1631·ν + 0.8766) with G = E/(2(1 + ν)).
pub fn rayleigh_time(r: f64, density: f64, young_modulus: f64, nu: f64) -> f64 {
    let shear_modulus = young_modulus / (2.0 * (1.0 + nu));
    PI * r * (density / shear_modulus).sqrt() / (0.1631 * nu + 0.8766)
}

/// Duration \[s\] of an elastic Hertz impact at normal speed `v` \[m/s\] for effective mass
/// `m_eff` \[kg\], radius `r_eff` \[m\] and modulus `e_star` \[Pa\] (Johnson 1985):
/// t_c = 2.87·(m*² / (R*·E*²·v))^(1/5).
pub fn hertz_contact_time(m_eff: f64, r_eff: f64, e_star: f64, v: f64) -> f64 {
    2.87 * (m_eff * m_eff / (r_eff * e_star * e_star * v)).powf(0.2)
}

/// Deepest overlap \[m\] of an elastic Hertz impact at normal speed `v`:
/// δ_max = (15·m*·v² / (16·E*·√R*))^(2/5).
pub fn hertz_peak_overlap(m_eff: f64, r_eff: f64, e_star: f64, v: f64) -> f64 {
    (15.0 * m_eff * v * v / (16.0 * e_star * r_eff.sqrt())).powf(0.4)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rayleigh_time_of_a_soft_millimetre_sphere() {
        // r 0.5 mm, ρ 2500, E 1e7 Pa, ν 0.3: G = 3.85e6 Pa, T_R ≈ 4.3e-5 s.
        let t = rayleigh_time(5e-4, 2500.0, 1e7, 0.3);
        assert!((t - 4.3e-5).abs() < 0.05e-5, "{t}");
    }

    #[test]
    fn the_hertz_impact_formulas_agree_with_each_other() {
        // Energy: ½m*v² = (8/15)·E*·√R*·δ_max^(5/2).
        let (m, r, e, v) = (1e-3, 0.01, 1e7, 0.5);
        let d = hertz_peak_overlap(m, r, e, v);
        let stored = 8.0 / 15.0 * e * r.sqrt() * d.powf(2.5);
        assert!((stored / (0.5 * m * v * v) - 1.0).abs() < 1e-12);
        // The duration is 2.94·δ_max/v (Johnson).
        let t = hertz_contact_time(m, r, e, v);
        assert!((t * v / d - 2.94).abs() < 0.01, "{}", t * v / d);
    }
}
