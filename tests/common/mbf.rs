//! The theory of an oblique impact of an elastic sphere on a rigid plane with friction: Maw,
//! Barber & Fawcett, "The oblique impact of elastic spheres", Wear 38 (1976) 101–114, and "The
//! role of elastic tangential compliance in oblique impact", J. Lubr. Technol. 103 (1981)
//! 74–80 (MBF), the reference curves of Chung & Ooi's Tests 4–6 (Granular Matter 13 (2011)
//! 643–656) and of Thornton, Cummins & Cleary, Powder Technology 210 (2011) 189–197.
//!
//! MBF's model: Hertz's normal contact, Cattaneo–Mindlin's tangential one under the varying
//! normal load (a stuck centre and a slipping annulus, Mindlin & Deresiewicz), the two
//! uncoupled, and the sphere's rigid-body motion. MBF solved it numerically (the contact cut into
//! annuli); there is no closed form but in gross sliding. It is solved here by the method of
//! dimensionality reduction (Popov & Heß, *Method of Dimensionality Reduction in Contact
//! Mechanics and Friction*, Springer 2015; used for this very impact by Lyashenko & Popov, Sci.
//! Rep. 5 (2015) 8479), which is exact for this model: the contact is a row of independent
//! springs at 0 ≤ x ≤ a, each with normal stiffness E*·dx and tangential stiffness G*·dx, pressed
//! by w(x) = δ − x²/R; a spring's tangential displacement follows the contact's and slips where
//! G*·|u| would exceed μ·E*·w; springs that leave the contact let go. Their sums are Hertz's
//! force 4/3·E*·√R·δ^{3/2} and Mindlin's stiffness 8·a·G/(2 − ν) (G* = 4G/(2 − ν) for one
//! elastic body on a rigid one).
//!
//! Everything is in MBF's normalised variables, so one solution serves every material,
//! radius and speed: the incident angle x = v_ct/(μ·v_n) (v_ct the contact point's tangential
//! velocity, v_n the normal one, approaching), and the result as J, the tangential impulse over
//! μ·m·v_n. From J follow the paper's quantities (the contact point's tangential velocity
//! changes by −3.5·μ·J·v_n, the centre's by −μ·J·v_n, R·ω by 2.5·μ·J·v_n for a solid sphere).
//! In gross sliding J = 1 + e (Coulomb's law throughout the impact); MBF show that this holds
//! for x ≥ 7 − 1/κ at e = 1, with κ = 2(1 − ν)/(2 − ν) the ratio of Mindlin's tangential to
//! Hertz's normal stiffness.
//!
//! MBF is elastic (e = 1, Test 5). For Tests 4 and 6 (e = 0.98 and 0.5) the normal force here
//! is Hertz's with Tsuji's damping, held at ≥ 0 and calibrated to rebound at e (the step's
//! normal law), and the
//! pressure keeps Hertz's shape while carrying it (each spring's friction bound scaled by the
//! normal force over Hertz's), as Mindlin–Deresiewicz's theory takes a normal load: MBF's
//! tangential theory under a damped normal force, an extension of ours (what a
//! Mindlin–Deresiewicz tangential law with that normal law should give); at e = 1 it is MBF's.

/// How finely the reference is resolved: springs over the largest contact radius and steps per
/// Hertz contact time (at 200 springs and 5,000 steps the quantities agree with 400 and 20,000
/// to within 2e-4).
const SPRINGS: usize = 200;
const STEPS: usize = 5000;

/// Hertz's contact time in the units of [`impact`] (R = m = E* = v_n = 1).
const T_C: f64 = 2.87;

/// The rebound speed of a head-on impact (units of [`impact`]) whose normal force is Hertz's
/// with damping coefficient `c`·√(S_n) (S_n = 2·E*·a), held at ≥ 0.
fn normal_rebound(c: f64) -> f64 {
    let dt = T_C / STEPS as f64;
    let (mut d, mut vn) = (0.0f64, 1.0f64);
    loop {
        if d > 0.0 {
            let force = 4.0 / 3.0 * d.powf(1.5) + c * (2.0 * d.sqrt()).sqrt() * vn;
            vn -= force.max(0.0) * dt;
        }
        d += vn * dt;
        if d <= 0.0 && vn < 0.0 {
            return -vn;
        }
    }
}

/// The damping coefficient c (over √S_n) that rebounds at `e` ([`normal_rebound`]), by
/// bisection: Tsuji's 2·√(5/6)·ζ(e) rebounds above e once the force is held at ≥ 0, so the
/// step calibrates its damping this way too.
fn damping_for(e: f64) -> f64 {
    if e >= 1.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0f64, 10.0f64);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if normal_rebound(mid) > e {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// What an oblique impact on a rigid plane does, in MBF's normalised variables.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rebound {
    /// The tangential impulse over μ·m·v_n (v_n the approach speed): 1 + e in gross sliding.
    pub impulse: f64,
    /// The normal rebound speed over the approach speed.
    pub restitution: f64,
}

impl Rebound {
    /// The rebound in gross sliding (Coulomb's law throughout): J = 1 + e.
    pub fn sliding(restitution: f64) -> Self {
        Self {
            impulse: 1.0 + restitution,
            restitution,
        }
    }

    /// The normalised recoil angle v_ct'/(μ·v_n') after an impact at normalised incident angle
    /// `x` (Chung & Ooi's Test 5 ordinate): (x − 3.5·J)/e.
    pub fn recoil(&self, x: f64) -> f64 {
        (x - 3.5 * self.impulse) / self.restitution
    }

    /// The normalised spin R·ω'/(μ·v_n) (Test 5's other ordinate): 2.5·J.
    pub fn spin(&self) -> f64 {
        2.5 * self.impulse
    }
}

/// The ratio κ = 2(1 − ν)/(2 − ν) of Mindlin's tangential stiffness to Hertz's normal one for a
/// sphere of Poisson's ratio `nu` on a rigid plane (8·a·G/(2 − ν) over 2·a·E/(1 − ν²)).
pub fn stiffness_ratio(nu: f64) -> f64 {
    2.0 * (1.0 - nu) / (2.0 - nu)
}

/// The smallest normalised incident angle at which MBF's sphere slides throughout the impact,
/// at e = 1: x = 7 − 1/κ (MBF's Ψ₁ = 4χ − 1 in our variables).
pub fn gross_sliding_from(nu: f64) -> f64 {
    7.0 - 1.0 / stiffness_ratio(nu)
}

/// The impact of a solid sphere (Poisson's ratio `nu`, friction `mu`, restitution `e`) on a
/// rigid plane at normalised incident angle `x` = v_ct/(μ·v_n), by MBF's model (see the
/// module's doc).
pub fn impact(x: f64, nu: f64, mu: f64, e: f64) -> Rebound {
    // Units: R = 1, m = 1, E* = 1, v_n = 1; G* = κ·E*.
    let kappa = stiffness_ratio(nu);
    let damping = damping_for(e);
    let dt = T_C / STEPS as f64;
    let a_max = (15.0f64 / 16.0).powf(0.4).sqrt();
    let dx = 1.05 * a_max / SPRINGS as f64;
    let mut u = vec![0.0f64; SPRINGS];
    let (mut d, mut vn, mut vct) = (0.0f64, 1.0f64, mu * x);
    let mut impulse = 0.0;
    let mut touched = false;
    // The normal force over Hertz's (1 at e = 1).
    let mut scale = 1.0;
    for _ in 0..100 * STEPS {
        // Forces from the present state, then velocities, then positions (symplectic Euler).
        let (mut n_force, mut t_force) = (0.0, 0.0);
        if d > 0.0 {
            let a = d.sqrt();
            let elastic = 4.0 / 3.0 * d.powf(1.5);
            n_force = (elastic + damping * (2.0 * a).sqrt() * vn).max(0.0);
            // The pressure keeps Hertz's shape and carries the whole normal force.
            scale = n_force / elastic;
            let inside = ((a / dx) as usize + 1).min(SPRINGS);
            t_force = 2.0 * kappa * dx * u[..inside].iter().sum::<f64>();
        }
        vn -= n_force * dt;
        vct -= 3.5 * t_force * dt;
        impulse += t_force * dt;
        d += vn * dt;
        if d > 0.0 {
            touched = true;
            for (i, u) in u.iter_mut().enumerate() {
                let x = (i as f64 + 0.5) * dx;
                let w = d - x * x;
                if w <= 0.0 {
                    *u = 0.0;
                    continue;
                }
                *u += vct * dt;
                let limit = mu * scale * w / kappa;
                *u = u.clamp(-limit, limit);
            }
        } else if touched {
            return Rebound {
                impulse: impulse / mu,
                restitution: -vn,
            };
        }
    }
    panic!("MBF's impact at x = {x} did not end");
}
