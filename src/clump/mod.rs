//! Rigid clumps of spheres (docs/method.md, "Clumps"): a grain of any shape as the union of
//! component spheres fixed in a body frame. [`template`] holds a clump's shape and what follows
//! from it (volume, centre, principal moments and axes of the union), [`shapes`] the built-in
//! templates, [`rigid`] the motion of a rigid body under the forces and torques its components'
//! contacts sum to, [`set`] the clumps of a run and how their components' contacts move them.

pub mod rigid;
pub mod set;
pub mod shapes;
pub mod template;

pub use rigid::{PrincipalInertia, RigidBody};
pub use set::{Clump, ClumpKind, ClumpSet, ComponentState};
pub use template::{ClumpTemplate, Component, MassProperties};
