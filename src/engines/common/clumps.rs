//! Clumps as the GPU steps hold them (`wgsl/dem/dem_clumps.wgsl`, `optix/clumps.cuh`): each
//! clump's rigid-body state in a row ([`ClumpBodyRow`], its centre as a rounded value and its
//! residual as a sphere's), each kind's mass, principal moments and components
//! ([`ClumpShapeRow`], the components' centres and radii in `parts`), and each component's clump
//! by its stable id. The rows are in f32; [`ClumpRows::bodies_into`] turns them back into the
//! f64 bodies of a [`ClumpSet`].

use crate::clump::{ClumpSet, RigidBody};
use crate::gpu::shader::{SharedStruct, Vec3f, Vec4f, shared_struct};
use crate::particles::position::split;
use bytemuck::{Pod, Zeroable};
use glam::{DQuat, DVec3};

/// One clump's state; WGSL twin `ClumpBody`, CUDA twin `MochiClumpBody`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable, encase::ShaderType)]
pub struct ClumpBodyRow {
    /// The centre of mass, rounded to f32 \[m\].
    pub centre: Vec3f,
    /// The stable id of its first component (its components follow it).
    pub first: u32,
    /// The centre's rounding error (`centre + residual` is the centre).
    pub residual: Vec3f,
    /// Its row of the shapes (its kind).
    pub shape: u32,
    /// x, y, z, w: the rotation from its principal frame to the world.
    pub orientation: Vec4f,
    /// Velocity of the centre \[m/s\].
    pub velocity: Vec3f,
    pub _pad0: u32,
    /// Angular momentum about the centre, world frame \[kg·m²/s\].
    pub momentum: Vec3f,
    pub _pad1: u32,
}

/// One kind of clump; WGSL twin `ClumpShape`, CUDA twin `MochiClumpShape`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable, encase::ShaderType)]
pub struct ClumpShapeRow {
    /// Principal moments of inertia \[kg·m²\].
    pub moments: Vec3f,
    /// Mass \[kg\].
    pub mass: f32,
    /// Its first component's row of the parts.
    pub first_part: u32,
    /// Its components.
    pub parts: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

/// The field lists of [`ClumpBodyRow`] and [`ClumpShapeRow`] for a layout check (`$check`:
/// `shared_struct` or `cuda_layout`) under the names `$body` and `$shape`.
macro_rules! clump_rows_fields {
    ($check:ident, $body:literal, $shape:literal) => {
        [
            $check!(
                $body,
                ClumpBodyRow {
                    centre,
                    first,
                    residual,
                    shape,
                    orientation,
                    velocity,
                    _pad0,
                    momentum,
                    _pad1,
                }
            ),
            $check!(
                $shape,
                ClumpShapeRow {
                    moments,
                    mass,
                    first_part,
                    parts,
                    _pad0,
                    _pad1,
                }
            ),
        ]
    };
}
#[cfg(feature = "optix")]
pub(crate) use clump_rows_fields;

/// The clumps' structs shared with WGSL.
pub fn clump_structs() -> [SharedStruct; 2] {
    clump_rows_fields!(shared_struct, "ClumpBody", "ClumpShape")
}

/// A run's clumps as rows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ClumpRows {
    /// Each component's clump, by stable id.
    pub of: Vec<u32>,
    /// Each clump's state.
    pub bodies: Vec<ClumpBodyRow>,
    /// Each kind's, by its index in [`ClumpSet::kinds`].
    pub shapes: Vec<ClumpShapeRow>,
    /// The kinds' components, kind by kind: centre in the principal frame and radius.
    pub parts: Vec<[f32; 4]>,
}

impl ClumpRows {
    /// The rows of `set`.
    pub fn of(set: &ClumpSet) -> Self {
        let mut parts = Vec::new();
        let shapes = set
            .kinds
            .iter()
            .map(|kind| {
                let first_part = parts.len() as u32;
                let components = &kind.template.components;
                parts.extend(components.iter().map(|c| {
                    let x = c.centre.as_vec3();
                    [x.x, x.y, x.z, c.radius as f32]
                }));
                ClumpShapeRow {
                    moments: kind.inertia.moments.as_vec3().into(),
                    mass: kind.inertia.mass as f32,
                    first_part,
                    parts: components.len() as u32,
                    ..Default::default()
                }
            })
            .collect();
        let mut first = 0;
        let bodies = set
            .clumps
            .iter()
            .map(|clump| {
                let b = &clump.body;
                let halves = b.position.to_array().map(split);
                let row = ClumpBodyRow {
                    centre: Vec3f(halves.map(|h| h.0)),
                    first,
                    residual: Vec3f(halves.map(|h| h.1)),
                    shape: clump.kind as u32,
                    orientation: Vec4f(b.orientation.as_quat().to_array()),
                    velocity: b.velocity.as_vec3().into(),
                    momentum: b.angular_momentum.as_vec3().into(),
                    ..Default::default()
                };
                first += set.kinds[clump.kind].template.components.len() as u32;
                row
            })
            .collect();
        ClumpRows {
            of: set.owners(),
            bodies,
            shapes,
            parts,
        }
    }

    /// `set` with the bodies of `bodies` (rows of its clumps, read back).
    pub fn bodies_into(set: &ClumpSet, bodies: &[ClumpBodyRow]) -> ClumpSet {
        let mut out = set.clone();
        for (clump, row) in out.clumps.iter_mut().zip(bodies) {
            let wide = |v: Vec3f| DVec3::from_array(v.0.map(f64::from));
            let [x, y, z, w] = row.orientation.0.map(f64::from);
            clump.body = RigidBody {
                position: wide(row.centre) + wide(row.residual),
                orientation: DQuat::from_xyzw(x, y, z, w).normalize(),
                velocity: wide(row.velocity),
                angular_momentum: wide(row.momentum),
            };
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clump::{Clump, ClumpKind, ClumpTemplate};

    #[test]
    fn clumps_go_to_rows_and_come_back_to_f32_precision() {
        let dimer = ClumpKind::new(&ClumpTemplate::dimer(1e-3).unwrap(), 2500.0);
        let rod = ClumpKind::new(&ClumpTemplate::rod(3, 5e-4).unwrap(), 2500.0);
        let body = |x: f64, kind: &ClumpKind| {
            let turn = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), x);
            RigidBody::new(
                DVec3::new(x, 0.25 + x, 0.123456789),
                turn,
                DVec3::new(0.1, -x, 0.0),
                DVec3::new(1.0, 2.0, x),
                &kind.inertia,
            )
        };
        let set = ClumpSet {
            clumps: vec![
                Clump {
                    kind: 1,
                    body: body(0.3, &rod),
                },
                Clump {
                    kind: 0,
                    body: body(0.7, &dimer),
                },
            ],
            kinds: vec![dimer, rod],
        };
        let rows = ClumpRows::of(&set);
        assert_eq!(rows.of, [0, 0, 0, 1, 1]);
        assert_eq!([rows.bodies[0].first, rows.bodies[1].first], [0, 3]);
        assert_eq!([rows.bodies[0].shape, rows.bodies[1].shape], [1, 0]);
        assert_eq!(
            [rows.shapes[0].first_part, rows.shapes[1].first_part],
            [0, 2]
        );
        assert_eq!(rows.parts.len(), 5);
        let back = ClumpRows::bodies_into(&set, &rows.bodies);
        for (a, b) in set.clumps.iter().zip(&back.clumps) {
            // The centre keeps its residual: far below f32's rounding of it.
            assert!((a.body.position - b.body.position).length() < 1e-14);
            assert!(a.body.orientation.angle_between(b.body.orientation) < 1e-6);
            assert!((a.body.velocity - b.body.velocity).length() < 1e-7);
            let l = a.body.angular_momentum.length();
            assert!((a.body.angular_momentum - b.body.angular_momentum).length() < 1e-6 * l);
        }
    }
}
