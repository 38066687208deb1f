//! Many independent impacts in one stepper, read back a few times: what a GPU step on a software
//! adapter can afford (a read-back every step costs about as much as the step).
//!
//! - [`Staggered`]: copies of one head-on impact (a sphere falling on the floor, or two spheres
//!   meeting), copy k starting k·stride steps after copy 0. One state then shows the impact at
//!   every stride-th step of it, and the state one step later the force at each (from the
//!   change of velocity): the force–time and force–overlap curves of a single impact, from two
//!   read-backs.
//! - [`Oblique`]: spheres striking the floor each with its own tangential velocity and spin,
//!   far apart, read back once after every one has rebounded.

use super::particles;
use mochi::dem::{Material, StepParams};
use mochi::dem::{Particles, Stepper};

/// What a copy strikes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// The floor of the box (z = 0); the copy falls along −z.
    Floor,
    /// Another sphere of the same radius; the two meet head-on along x at ±speed/2.
    Partner,
}

/// `count` copies of one head-on impact at closing speed `speed` \[m/s\] of spheres of radius
/// `r`, with time step `dt`. Copy k starts (k·stride + ½) steps of approach away from contact,
/// so it first overlaps at step k·stride + 1 (the half step keeps the rounding of the start off
/// a step boundary). The copies stand on a square grid 4·r apart (a pair's centre on it), well
/// clear of each other and of the walls.
#[derive(Debug, Clone, Copy)]
pub struct Staggered {
    pub target: Target,
    pub r: f32,
    pub speed: f64,
    pub dt: f64,
    pub stride: u32,
    pub count: usize,
}

/// One impact sampled across its copies: see [`Staggered::sample`].
#[derive(Debug, Clone, Default)]
pub struct Samples {
    /// Overlap \[m\] and repulsive force \[N\] of each copy in contact in the first state.
    pub curve: Vec<(f64, f64)>,
    /// Durations \[s\] of the contacts of the copies that had ended by the first state.
    pub durations: Vec<f64>,
    /// Separation speed over the closing speed of every copy once all have ended.
    pub rebounds: Vec<f64>,
}

impl Samples {
    /// The deepest overlap sampled \[m\].
    pub fn peak_overlap(&self) -> f64 {
        self.curve.iter().map(|s| s.0).fold(0.0, f64::max)
    }

    /// The largest force sampled \[N\].
    pub fn peak_force(&self) -> f64 {
        self.curve.iter().map(|s| s.1).fold(0.0, f64::max)
    }
}

impl Staggered {
    /// Copies per row of the grid.
    fn row(&self) -> usize {
        (self.count as f64).sqrt().ceil() as usize
    }

    /// Grid spacing \[m\].
    fn spacing(&self) -> f64 {
        4.0 * self.r as f64
    }

    /// Where copy k's centre (a pair's midpoint) stands in the plane across its motion.
    fn cell(&self, k: usize) -> [f64; 2] {
        let n = self.row();
        let s = self.spacing();
        [((k % n) as f64 + 1.0) * s, ((k / n) as f64 + 1.0) * s]
    }

    /// Copy k's initial gap \[m\].
    pub fn gap(&self, k: usize) -> f64 {
        (k as f64 * self.stride as f64 + 0.5) * self.speed * self.dt
    }

    /// When copy k's contact begins \[s\] (its gap closed at `speed`).
    pub fn start(&self, k: usize) -> f64 {
        self.gap(k) / self.speed
    }

    /// The box: the grid across, and along the motion room for the approach of the last copy
    /// and `steps` of flight besides.
    fn bounds(&self, steps: u32) -> ([f64; 3], [f64; 3]) {
        let across = (self.row() as f64 + 1.0) * self.spacing();
        let travel = self.gap(self.count) + self.speed * self.dt * steps as f64;
        let r = self.r as f64;
        match self.target {
            Target::Floor => ([0.0; 3], [across, across, 4.0 * r + travel]),
            Target::Partner => {
                let half = 3.0 * r + travel;
                ([-half, 0.0, 0.0], [half, across, across])
            }
        }
    }

    /// The step parameters of `material` for these copies of an impact lasting about `contact`
    /// steps: no gravity, the box of [`Staggered::bounds`] over [`Staggered::steps`].
    pub fn params(&self, material: &Material, contact: u32) -> StepParams {
        let (lo, hi) = self.bounds(self.steps(contact));
        StepParams::new(material, self.dt, lo, hi, [0.0; 3], 0.0, self.r)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// The copies at their start, not spinning.
    pub fn particles(&self) -> Particles {
        let r = self.r as f64;
        let mut p = particles(Vec::new(), Vec::new(), Vec::new());
        for k in 0..self.count {
            let [a, b] = self.cell(k);
            let g = self.gap(k);
            let v = self.speed as f32;
            match self.target {
                Target::Floor => {
                    p.positions.push([a as f32, b as f32, (r + g) as f32]);
                    p.velocities.push([0.0, 0.0, -v]);
                }
                Target::Partner => {
                    let x = (r + g / 2.0) as f32;
                    p.positions.push([-x, a as f32, b as f32]);
                    p.velocities.push([v / 2.0, 0.0, 0.0]);
                    p.positions.push([x, a as f32, b as f32]);
                    p.velocities.push([-v / 2.0, 0.0, 0.0]);
                }
            }
        }
        let n = p.positions.len();
        p.radii = vec![self.r; n];
        p.angular_velocities = vec![[0.0; 3]; n];
        p
    }

    /// Copy k's overlap in `p` \[m\] (negative: the gap).
    pub fn overlap(&self, p: &Particles, k: usize) -> f64 {
        let r = self.r as f64;
        match self.target {
            Target::Floor => r - p.positions[k][2] as f64,
            Target::Partner => {
                2.0 * r - (p.positions[2 * k + 1][0] as f64 - p.positions[2 * k][0] as f64)
            }
        }
    }

    /// The rate at which copy k's surfaces part in `p` \[m/s\] (negative while approaching).
    pub fn parting(&self, p: &Particles, k: usize) -> f64 {
        match self.target {
            Target::Floor => p.velocities[k][2] as f64,
            Target::Partner => p.velocities[2 * k + 1][0] as f64 - p.velocities[2 * k][0] as f64,
        }
    }

    /// The repulsive force \[N\] on a sphere of mass `m` of copy k during the step from
    /// `before` to `after`: semi-implicit Euler adds dt·F/m to each velocity, and the force is
    /// that of `before`'s positions.
    pub fn force(&self, before: &Particles, after: &Particles, k: usize, m: f64) -> f64 {
        let change = self.parting(after, k) - self.parting(before, k);
        match self.target {
            Target::Floor => m * change / self.dt,
            // Both spheres take the force: the parting speed changes twice as fast.
            Target::Partner => m * change / (2.0 * self.dt),
        }
    }

    /// Runs the copies on `s` (opened over [`Staggered::particles`] with
    /// [`Staggered::params`]) and samples the impact of spheres of
    /// mass `m`, lasting about `contact` steps: the state after `count·stride` steps (every copy
    /// has begun, copy k is k·stride steps behind copy 0) and one step later give each copy's
    /// overlap and force; the copies already apart then give the contact's duration, from the
    /// time they began and the time their gap says they parted (they part at their rebound
    /// speed, no force acting); and once every copy has ended, each one's rebound.
    pub fn sample(&self, s: &mut dyn Stepper, m: f64, contact: u32) -> Samples {
        let first = self.count as u32 * self.stride;
        s.advance(first).unwrap();
        let a = s.particles().unwrap();
        s.advance(1).unwrap();
        let b = s.particles().unwrap();
        let t = first as f64 * self.dt;
        let mut out = Samples::default();
        for k in 0..self.count {
            let d = self.overlap(&a, k);
            let parting = self.parting(&a, k);
            if d > 0.0 {
                out.curve.push((d, self.force(&a, &b, k, m)));
            } else if parting > 0.0 && self.start(k) < t {
                out.durations.push(t + d / parting - self.start(k));
            }
        }
        s.advance(self.steps(contact) - first - 1).unwrap();
        let end = s.particles().unwrap();
        for k in 0..self.count {
            assert!(
                self.overlap(&end, k) < 0.0 && self.parting(&end, k) > 0.0,
                "copy {k} has not rebounded after {} steps",
                self.steps(contact)
            );
            out.rebounds.push(self.parting(&end, k) / self.speed);
        }
        out
    }

    /// Steps until every copy of an impact lasting about `contact` steps has ended (a fifth
    /// more, for contacts longer than the elastic one).
    pub fn steps(&self, contact: u32) -> u32 {
        self.count as u32 * self.stride + contact + contact / 5 + 10
    }
}

/// One sphere of an [`Oblique`] run: how it comes in.
#[derive(Debug, Clone, Copy)]
pub struct Incoming {
    /// Normal speed towards the floor \[m/s\].
    pub normal: f64,
    /// Velocity of its centre along x \[m/s\].
    pub tangential: f64,
    /// Angular velocity about −y \[rad/s\]: with it the contact point moves at
    /// `tangential + r·spin` along x.
    pub spin: f64,
}

/// What an impact of an [`Oblique`] run did to its sphere.
#[derive(Debug, Clone, Copy)]
pub struct Outgoing {
    /// Normal rebound speed over the normal approach speed.
    pub restitution: f64,
    /// The tangential impulse from the change of the centre's velocity, over μ·m·v_n.
    pub impulse_from_velocity: f64,
    /// The same from the change of the spin (2.5·μ·v_n·J/r for a solid sphere).
    pub impulse_from_spin: f64,
    /// The contact point's tangential velocity after the impact \[m/s\].
    pub contact_velocity: f64,
    /// The normal rebound speed \[m/s\].
    pub normal: f64,
}

/// Spheres of radius `r` striking the floor, each its own impact, 4·r apart along y (moving in
/// x–z only, so they never meet).
pub struct Oblique {
    pub r: f32,
    pub incoming: Vec<Incoming>,
}

impl Oblique {
    /// The spheres half a step of approach above the floor at time step `dt`, so each overlaps
    /// from the first step.
    pub fn particles(&self, dt: f64) -> Particles {
        let r = self.r as f64;
        let mut p = particles(Vec::new(), Vec::new(), Vec::new());
        for (k, c) in self.incoming.iter().enumerate() {
            p.positions.push([
                (4.0 * r) as f32,
                (4.0 * r * (k + 1) as f64) as f32,
                (r + 0.5 * c.normal * dt) as f32,
            ]);
            p.velocities
                .push([c.tangential as f32, 0.0, -c.normal as f32]);
            p.angular_velocities.push([0.0, -c.spin as f32, 0.0]);
            p.radii.push(self.r);
        }
        p
    }

    /// The step parameters of `material` at time step `dt` for `steps` steps: a box long enough
    /// along x for the fastest sphere, no gravity.
    pub fn params(&self, material: &Material, dt: f64, steps: u32) -> StepParams {
        let r = self.r as f64;
        let fastest = self
            .incoming
            .iter()
            .map(|c| c.tangential.abs() + c.normal)
            .fold(0.0, f64::max);
        let reach = 8.0 * r + fastest * dt * steps as f64;
        let hi = [
            2.0 * reach,
            4.0 * r * (self.incoming.len() + 2) as f64,
            reach,
        ];
        StepParams::new(material, dt, [-reach, 0.0, 0.0], hi, [0.0; 3], 0.0, self.r)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// Runs `steps` steps on `s` (opened over [`Oblique::particles`]) with friction `mu`, and
    /// what each impact did; every sphere must have left the floor.
    pub fn run(&self, s: &mut dyn Stepper, steps: u32, mu: f64) -> Vec<Outgoing> {
        s.advance(steps).unwrap();
        let end = s.particles().unwrap();
        let r = self.r as f64;
        self.incoming
            .iter()
            .enumerate()
            .map(|(k, c)| {
                let (v, w) = (end.velocities[k], end.angular_velocities[k]);
                assert!(
                    end.positions[k][2] as f64 > r && v[2] > 0.0,
                    "sphere {k} has not rebounded after {steps} steps: {:?} {v:?}",
                    end.positions[k]
                );
                let spin = -w[1] as f64;
                Outgoing {
                    restitution: v[2] as f64 / c.normal,
                    impulse_from_velocity: (c.tangential - v[0] as f64) / (mu * c.normal),
                    impulse_from_spin: r * (c.spin - spin) / (2.5 * mu * c.normal),
                    contact_velocity: v[0] as f64 + r * spin,
                    normal: v[2] as f64,
                }
            })
            .collect()
    }
}
