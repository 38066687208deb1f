//! Clumps in motion: the bodies of a run, each of a kind (a template in its principal frame at a
//! density), and the coupling of their component spheres to the rigid-body step. The contact
//! laws see each component as a sphere; what they give it (a force, and a torque about its own
//! centre) moves the clump: the force acts at the component's centre, so about the clump's
//! centre it adds the arm's moment, (c_k − x) × f_k, to the torque.

use super::rigid::{PrincipalInertia, RigidBody};
use super::template::{ClumpTemplate, MassProperties};
use glam::DVec3;

/// A kind of clump: a template in its principal frame and the inertia it has at its density.
#[derive(Debug, Clone, PartialEq)]
pub struct ClumpKind {
    /// The template, its centre the origin and its principal axes x, y and z.
    pub template: ClumpTemplate,
    /// Mass and principal moments at the kind's density.
    pub inertia: PrincipalInertia,
}

impl ClumpKind {
    /// Clumps of `template` at `density` \[kg/m³\] (the union of the components, overlaps
    /// counted once).
    pub fn new(template: &ClumpTemplate, density: f64) -> Self {
        Self::with_properties(template, &template.mass_properties(), density)
    }

    /// [`new`](Self::new) with the template's mass properties `m` (its
    /// [`ClumpTemplate::mass_properties`]) given.
    pub fn with_properties(template: &ClumpTemplate, m: &MassProperties, density: f64) -> Self {
        let (template, properties) = template.moved_to_principal_frame(m);
        Self {
            template,
            inertia: PrincipalInertia {
                mass: density * properties.volume,
                moments: density * properties.moments,
            },
        }
    }
}

impl ClumpKind {
    /// This kind, of density 1, scaled by `factor` at `density` \[kg/m³\]: the components'
    /// centres and radii times the factor, the mass times density·factor³ and the moments
    /// density·factor⁵ (exact for a scaled union: no integration again).
    pub fn scaled(&self, factor: f64, density: f64) -> Self {
        let mut template = self.template.clone();
        for c in &mut template.components {
            c.centre *= factor;
            c.radius *= factor;
        }
        Self {
            template,
            inertia: PrincipalInertia {
                mass: density * self.inertia.mass * factor.powi(3),
                moments: density * self.inertia.moments * factor.powi(5),
            },
        }
    }
}

/// One clump: its kind (an index into [`ClumpSet::kinds`]) and its rigid-body state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clump {
    /// Its kind.
    pub kind: usize,
    /// Its centre, orientation and momenta.
    pub body: RigidBody,
}

/// A component sphere of a clump as the contact laws see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComponentState {
    /// Centre in the world \[m\].
    pub centre: DVec3,
    /// Radius \[m\].
    pub radius: f64,
    /// Velocity of the clump's material at the centre \[m/s\].
    pub velocity: DVec3,
    /// The clump's angular velocity \[rad/s\].
    pub angular_velocity: DVec3,
    /// The clump's mass \[kg\]: the mass the laws damp a component's contacts with.
    pub mass: f64,
}

/// The clumps of a run and their kinds. Their components are numbered clump by clump, each
/// clump's in its template's order ([`Self::components`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ClumpSet {
    /// The kinds the clumps are of.
    pub kinds: Vec<ClumpKind>,
    /// The clumps.
    pub clumps: Vec<Clump>,
}

impl ClumpSet {
    /// Every clump's components, clump by clump.
    pub fn components(&self) -> Vec<ComponentState> {
        let mut out = Vec::with_capacity(self.component_count());
        self.for_each_component(|_, c| out.push(c));
        out
    }

    /// Calls `visit` with each component's index and state, in the order of
    /// [`Self::components`] (without gathering them).
    pub fn for_each_component(&self, mut visit: impl FnMut(usize, ComponentState)) {
        let mut k = 0;
        for clump in &self.clumps {
            let kind = &self.kinds[clump.kind];
            let w = clump.body.angular_velocity(&kind.inertia);
            for c in &kind.template.components {
                let arm = clump.body.orientation * c.centre;
                visit(
                    k,
                    ComponentState {
                        centre: clump.body.position + arm,
                        radius: c.radius,
                        velocity: clump.body.velocity + w.cross(arm),
                        angular_velocity: w,
                        mass: kind.inertia.mass,
                    },
                );
                k += 1;
            }
        }
    }

    /// The number of component spheres of all the clumps.
    pub fn component_count(&self) -> usize {
        self.clumps
            .iter()
            .map(|c| self.kinds[c.kind].template.components.len())
            .sum()
    }

    /// The clump each component belongs to, in the order of [`Self::components`].
    pub fn owners(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.component_count());
        for (k, clump) in self.clumps.iter().enumerate() {
            let n = self.kinds[clump.kind].template.components.len();
            out.extend(std::iter::repeat_n(k as u32, n));
        }
        out
    }

    /// The mass of each component's clump, in the order of [`Self::components`]: the mass its
    /// contacts see \[kg\].
    pub fn component_masses(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.component_count());
        for clump in &self.clumps {
            let kind = &self.kinds[clump.kind];
            out.extend(std::iter::repeat_n(
                kind.inertia.mass,
                kind.template.components.len(),
            ));
        }
        out
    }

    /// One step of `dt` for every clump under gravity `gravity` and the forces `forces` and
    /// torques `torques` (each about its component's centre) on its components, in the order
    /// of [`Self::components`].
    pub fn advance(&mut self, forces: &[DVec3], torques: &[DVec3], gravity: DVec3, dt: f64) {
        self.advance_by(|k| forces[k], |k| torques[k], gravity, dt);
    }

    /// [`advance`](Self::advance) with component k's force `force(k)` and torque `torque(k)`.
    pub fn advance_by(
        &mut self,
        force: impl Fn(usize) -> DVec3,
        torque: impl Fn(usize) -> DVec3,
        gravity: DVec3,
        dt: f64,
    ) {
        let mut next = 0;
        for clump in &mut self.clumps {
            let kind = &self.kinds[clump.kind];
            let mut sum = gravity * kind.inertia.mass;
            let mut moment = DVec3::ZERO;
            for c in &kind.template.components {
                let arm = clump.body.orientation * c.centre;
                let f = force(next);
                sum += f;
                moment += arm.cross(f) + torque(next);
                next += 1;
            }
            clump.body.advance(&kind.inertia, sum, moment, dt);
        }
    }

    /// The clumps in words for a run's summary line, "300 clumps (tetrahedron 152, dimer
    /// 148)", each name counted over its kinds (one a size); `None` without clumps.
    pub fn describe(&self) -> Option<String> {
        if self.clumps.is_empty() {
            return None;
        }
        let mut counts: Vec<(&str, usize)> = Vec::new();
        for c in &self.clumps {
            let name = self.kinds[c.kind].template.name.as_str();
            match counts.iter_mut().find(|(n, _)| *n == name) {
                Some((_, k)) => *k += 1,
                None => counts.push((name, 1)),
            }
        }
        let each: Vec<String> = counts.iter().map(|(n, k)| format!("{n} {k}")).collect();
        Some(format!(
            "{} clumps ({})",
            self.clumps.len(),
            each.join(", ")
        ))
    }

    /// The clumps' linear momentum \[kg·m/s\] and angular momentum about the origin \[kg·m²/s\].
    pub fn momenta(&self) -> (DVec3, DVec3) {
        self.clumps
            .iter()
            .fold((DVec3::ZERO, DVec3::ZERO), |(p, l), c| {
                let m = self.kinds[c.kind].inertia.mass;
                let b = &c.body;
                (
                    p + m * b.velocity,
                    l + b.position.cross(m * b.velocity) + b.angular_momentum,
                )
            })
    }
}
