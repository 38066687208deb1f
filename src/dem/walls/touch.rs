//! Where a sphere touches one mesh wall, each contact resolved once.
//!
//! A sphere near a mesh is close to many triangles: on a flat mesh, every triangle within a
//! radius of the centre. Taking each triangle's closest point as a contact would press a
//! sphere above a vertex shared by six triangles six times as hard as one on a face. The rule
//! here: the candidates (each nearby triangle's closest point, within the radius) are taken in
//! order of distance, and one is kept only if it lies strictly in front of the tangent plane of
//! every contact kept before it (the plane through that contact's point, normal to the line
//! from the centre). What a kept contact's plane covers is the same surface seen again:
//! - a flat mesh, whatever the triangles: every closest point lies in the one plane, so the
//!   nearest is kept and the rest are covered: the sphere feels one plane at any position,
//!   on a face, an edge or a vertex;
//! - a convex ridge or corner: the neighbours' closest points lie behind the plane of the
//!   nearest (the surface turns away): one contact;
//! - a concave corner (a floor meeting a side wall, the inside of a drum): the second face
//!   rises in front of the first's plane and is kept: a contact per face, as a sphere in the
//!   corner of the analytic box has one per wall.

use super::motion::Pose;
use super::triangles::TriangleMesh;
use glam::Vec3;

/// Candidates within this fraction of the radius behind a kept contact's tangent plane count as
/// on it (rounding of coordinates puts the points of a flat mesh a few ulps off its plane).
const ON_PLANE: f32 = 1e-4;

/// One contact of a sphere with a mesh wall, in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceTouch {
    /// The contact point on the wall \[m\].
    pub point: Vec3,
    /// Unit normal from the sphere's centre towards the point.
    pub normal: Vec3,
    /// How far the sphere reaches through the wall: radius − distance \[m\] (> 0 but where a
    /// reach beyond touching was asked for).
    pub overlap: f32,
}

/// Where [`touches`] works, kept between calls so that a pass over many spheres allocates once.
#[derive(Debug, Clone, Default)]
pub struct Touches {
    /// (distance², closest point in the rest geometry) of the candidates.
    near: Vec<(f32, Vec3)>,
    /// (rest normal, distance) of the contacts kept.
    kept: Vec<(Vec3, f32)>,
    /// The contacts found by the last call.
    pub found: Vec<SurfaceTouch>,
}

/// The contacts of the sphere (centre `c`, radius `r`) with `mesh` in `pose`, nearest first,
/// each once (module docs), into `at.found` (replacing what was there): where the surface is
/// within `r` of the centre, or within `r + reach` (a cohesive contact that may hold past
/// touching: its overlap is then negative). A centre exactly on the surface has no normal and
/// no contact.
pub fn touches(
    mesh: &TriangleMesh,
    pose: &Pose,
    c: Vec3,
    (r, reach): (f32, f32),
    at: &mut Touches,
) {
    let Touches { near, kept, found } = at;
    near.clear();
    kept.clear();
    found.clear();
    let p = pose.to_rest(c);
    let within = r + reach;
    // In the hierarchy's fixed order.
    mesh.for_each_near(p, within, |t| {
        let q = t.closest_point(p);
        let d2 = (q - p).length_squared();
        if d2 < within * within && d2 > 0.0 {
            near.push((d2, q));
        }
    });
    // Stable: equal distances keep the hierarchy's order, so the result depends on the state
    // alone.
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    let slack = ON_PLANE * r;
    for &(d2, q) in near.iter() {
        let to = q - p;
        let covered = kept.iter().any(|&(n, d)| to.dot(n) >= d - slack);
        if covered {
            continue;
        }
        let d = d2.sqrt();
        let n = to / d;
        kept.push((n, d));
        found.push(SurfaceTouch {
            point: pose.to_world(q),
            normal: pose.turn(n),
            overlap: r - d,
        });
    }
}
