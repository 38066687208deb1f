//! A wall's prescribed motion and its pose at a time: a translation at constant velocity and a
//! rotation at constant angular velocity about an axis through a centre, both from a start
//! time on. The pose is a function of the time alone (never accumulated step by step), so a
//! resumed run puts every wall exactly where the uninterrupted run had it.

use glam::{DQuat, DVec3, Quat, Vec3};

/// How a wall moves: at rest until `start`, then translated at `velocity` and turned at
/// `omega` about `axis` through `centre` (the centre travels with the translation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// Velocity of the translation \[m/s\].
    pub velocity: DVec3,
    /// Angular speed \[rad/s\] (right-handed about `axis`).
    pub omega: f64,
    /// Unit axis of the rotation.
    pub axis: DVec3,
    /// A point of the rotation axis at `start` \[m\]; the wall's torques are taken about it.
    pub centre: DVec3,
    /// Time the motion starts \[s\].
    pub start: f64,
}

impl Default for Motion {
    fn default() -> Self {
        Self {
            velocity: DVec3::ZERO,
            omega: 0.0,
            axis: DVec3::Z,
            centre: DVec3::ZERO,
            start: 0.0,
        }
    }
}

impl Motion {
    /// Whether the wall ever moves.
    pub fn moves(&self) -> bool {
        self.velocity != DVec3::ZERO || self.omega != 0.0
    }

    /// The pose at time `t` \[s\], mapping the wall's rest geometry (where it is before
    /// `start`) to where it is at `t`.
    pub fn pose_at(&self, t: f64) -> Pose {
        let running = t > self.start;
        let tau = if running { t - self.start } else { 0.0 };
        let rotation = DQuat::from_axis_angle(self.axis, self.omega * tau);
        let centre = self.centre + self.velocity * tau;
        // x = R·(x_rest − c₀) + c₀ + v·τ = R·x_rest + (centre − R·c₀).
        let offset = centre - rotation * self.centre;
        let (velocity, spin) = match running {
            true => (self.velocity, self.axis * self.omega),
            false => (DVec3::ZERO, DVec3::ZERO),
        };
        Pose {
            rotation: rotation.as_quat(),
            offset: offset.as_vec3(),
            centre: centre.as_vec3(),
            velocity: velocity.as_vec3(),
            spin: spin.as_vec3(),
        }
    }
}

/// Where a wall is at one time and how its points move then.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation from the rest geometry.
    pub rotation: Quat,
    /// Translation after the rotation \[m\]: x = rotation·x_rest + offset.
    pub offset: Vec3,
    /// The rotation centre now \[m\] (torques on the wall are about it).
    pub centre: Vec3,
    /// Velocity of the translation \[m/s\].
    pub velocity: Vec3,
    /// Angular velocity \[rad/s\].
    pub spin: Vec3,
}

impl Pose {
    /// The rest-geometry point that is at `x` now.
    #[inline]
    pub fn to_rest(&self, x: Vec3) -> Vec3 {
        self.rotation.inverse() * (x - self.offset)
    }

    /// Where the rest-geometry point `x` is now.
    #[inline]
    pub fn to_world(&self, x: Vec3) -> Vec3 {
        self.rotation * x + self.offset
    }

    /// A rest-geometry direction turned to now.
    #[inline]
    pub fn turn(&self, d: Vec3) -> Vec3 {
        self.rotation * d
    }

    /// Velocity of the wall's material point at `x` (now) \[m/s\].
    #[inline]
    pub fn velocity_at(&self, x: Vec3) -> Vec3 {
        self.velocity + self.spin.cross(x - self.centre)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_rests_until_its_start_then_turns_about_its_centre() {
        let m = Motion {
            omega: std::f64::consts::FRAC_PI_2,
            axis: DVec3::Z,
            centre: DVec3::new(1.0, 0.0, 0.0),
            start: 1.0,
            ..Motion::default()
        };
        let x = Vec3::new(2.0, 0.0, 0.0);
        let before = m.pose_at(0.5);
        assert_eq!(before.to_world(x), x);
        assert_eq!(before.velocity_at(x), Vec3::ZERO);
        // A quarter turn a second after the start: (2, 0) about (1, 0) goes to (1, 1).
        let after = m.pose_at(2.0);
        assert!((after.to_world(x) - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-6);
        assert!((after.to_rest(after.to_world(x)) - x).length() < 1e-6);
        let v = after.velocity_at(Vec3::new(1.0, 1.0, 0.0));
        assert!((v - Vec3::new(-std::f32::consts::FRAC_PI_2, 0.0, 0.0)).length() < 1e-6);
    }

    #[test]
    fn a_translating_wall_carries_its_centre() {
        let m = Motion {
            velocity: DVec3::new(0.0, 2.0, 0.0),
            ..Motion::default()
        };
        let pose = m.pose_at(0.25);
        assert_eq!(pose.to_world(Vec3::ZERO), Vec3::new(0.0, 0.5, 0.0));
        assert_eq!(pose.centre, Vec3::new(0.0, 0.5, 0.0));
        assert_eq!(pose.velocity_at(Vec3::ONE), Vec3::new(0.0, 2.0, 0.0));
    }
}
