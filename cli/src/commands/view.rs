//! What a picture of a frame shows and from where (`mochi render`, `simulate --render-every`):
//! the region the default camera frames, the mesh walls drawn, and whether the simulation
//! box's floor is drawn. The camera's direction and distance for a region are
//! [`Camera::framing`]'s.
//!
//! The rules, each so that nothing in the picture is unexplained and the spheres fill it:
//! - `--fit auto` frames the walls drawn and every sphere (the equipment, what it holds and what
//!   flows out of it), or without walls most spheres ([`core_bounds`]: a heap rather than the
//!   few that rolled far); `--fit spheres` every sphere and wall, `--fit box` the simulation
//!   box;
//! - a mesh wall that moves and started within [`WALL_REACH`] largest radii of the spheres is
//!   drawn only while it is still that near: a hopper's gate that has slid away no longer
//!   floats beside it (a wall that moves towards the spheres from afar, a lid coming down, is
//!   drawn all the way);
//! - the box's bottom is drawn as a floor only where the spheres come within [`FLOOR_REACH`]
//!   largest radii of it: a heap stands on it, a hopper's stream (removed half-way down) does
//!   not hang over it.

use super::args::Fit;
use mochi::dem::walls::WallSet;
use mochi::render::{Camera, Picture};

/// Lower and upper corners \[m\].
pub type Bounds = ([f64; 3], [f64; 3]);

/// A wall triangle's three corners \[m\].
pub type Triangle = [[f32; 3]; 3];

/// Share of the centres, on each side of each axis, that [`core_bounds`] leaves out.
const CORE_TAIL: f64 = 0.01;

/// A moving wall is near the spheres while its box comes within this many largest radii of the
/// box around them.
const WALL_REACH: f64 = 2.0;

/// The box's floor is drawn where the lowest sphere's bottom comes within this many largest
/// radii of it.
const FLOOR_REACH: f64 = 4.0;

/// One mesh wall where it is at a frame.
pub struct WallAt {
    /// Its triangles.
    pub triangles: Vec<Triangle>,
    /// For a wall that moves (translates or turns), the box around it where it starts (its rest
    /// pose); `None` for one that stands still.
    pub start: Option<Bounds>,
}

impl WallAt {
    /// Whether the wall moves.
    pub fn moves(&self) -> bool {
        self.start.is_some()
    }
}

/// The mesh walls of `walls` where they are at time `t` \[s\], in the scene's order.
pub fn walls_at(walls: &WallSet, t: f64) -> Vec<WallAt> {
    let wall = |m: &mochi::dem::walls::MeshWall| WallAt {
        triangles: m.triangles_at(&m.motion.pose_at(t)),
        start: m
            .motion
            .moves()
            .then(|| triangle_bounds(&m.triangles_at(&m.motion.pose_at(m.motion.start))))
            .flatten(),
    };
    walls.meshes.iter().map(wall).collect()
}

/// What a frame puts in view.
pub struct Framed {
    /// The region the default camera frames.
    pub region: Bounds,
    /// Whether a sphere comes within [`FLOOR_REACH`] largest radii of the box's floor.
    pub reaches_floor: bool,
    /// The wall triangles drawn.
    pub walls: Vec<Triangle>,
}

/// Where the camera stands and what the picture is like.
pub struct View {
    /// Width and height \[px\].
    pub size: (u32, u32),
    /// `--eye`, where given.
    pub eye: Option<[f64; 3]>,
    /// `--look-at`, where given.
    pub look_at: Option<[f64; 3]>,
    /// Vertical field of view \[degrees\].
    pub fov: f64,
    /// Rays per pixel side.
    pub samples: u32,
    /// Whether to cast shadow rays.
    pub shadows: bool,
    /// What the default camera frames.
    pub fit: Fit,
    /// The simulation box, when known.
    pub sim_box: Option<Bounds>,
    /// The box whose bottom may be drawn as the floor (`None`: unknown, or `--no-floor`).
    pub floor_box: Option<Bounds>,
    /// For the frames of a whole run: the region every picture frames and whether each has
    /// the floor, so that the camera and the floor stay put from picture to picture.
    pub run: Option<(Bounds, bool)>,
}

impl View {
    /// What the frame of spheres at `positions` with `radii` and the mesh walls `walls` puts
    /// in view (the module's rules).
    pub fn frame(&self, positions: &[[f32; 3]], radii: &[f32], walls: &[WallAt]) -> Framed {
        let r_max = radii.iter().copied().fold(0.0f32, f32::max) as f64;
        let spheres = sphere_bounds(positions, radii);
        let near = |wall: Option<Bounds>| match (spheres, wall) {
            (Some(s), Some(w)) => overlap(widen(s, WALL_REACH * r_max), w),
            _ => true,
        };
        // A moving wall that started near the spheres and has left them.
        let moved_clear = |w: &WallAt| {
            w.start.is_some_and(|start| near(Some(start))) && !near(triangle_bounds(&w.triangles))
        };
        let walls: Vec<Triangle> = walls
            .iter()
            .filter(|w| !moved_clear(w))
            .flat_map(|w| w.triangles.iter().copied())
            .collect();
        let wall_box = triangle_bounds(&walls);
        let all = join(spheres, wall_box).unwrap_or(([-1.0; 3], [1.0; 3]));
        let region = match (self.fit, self.sim_box) {
            (Fit::Box, Some(b)) => b,
            (Fit::Auto, _) if wall_box.is_none() => core_bounds(positions, radii).unwrap_or(all),
            _ => all,
        };
        let reaches_floor = match (self.floor_box, spheres) {
            (Some((lo, _)), Some((low, _))) => low[2] - lo[2] <= FLOOR_REACH * r_max,
            _ => false,
        };
        Framed {
            region,
            reaches_floor,
            walls,
        }
    }

    /// The picture of `framed` (or, for a run, of the run's region).
    pub fn picture(&self, framed: &Framed) -> Picture {
        let (region, floor) = self.run.unwrap_or((framed.region, framed.reaches_floor));
        let aspect = self.size.0 as f64 / self.size.1 as f64;
        let mut camera = Camera::framing(region.0, region.1, aspect, self.fov);
        if let Some(look_at) = self.look_at {
            camera.look_at = look_at;
        }
        if let Some(eye) = self.eye {
            camera.eye = eye;
        }
        Picture {
            samples: self.samples,
            shadows: self.shadows,
            floor: self.floor_box.filter(|_| floor),
            ..Picture::new(self.size.0, self.size.1, camera)
        }
    }
}

/// The box around both `a` and `b`.
pub fn union(a: Bounds, b: Bounds) -> Bounds {
    (
        std::array::from_fn(|k| a.0[k].min(b.0[k])),
        std::array::from_fn(|k| a.1[k].max(b.1[k])),
    )
}

/// The box around those of `a` and `b` there are.
fn join(a: Option<Bounds>, b: Option<Bounds>) -> Option<Bounds> {
    match (a, b) {
        (Some(a), Some(b)) => Some(union(a, b)),
        (a, b) => a.or(b),
    }
}

/// `b` grown by `by` on every side.
fn widen((lo, hi): Bounds, by: f64) -> Bounds {
    (lo.map(|x| x - by), hi.map(|x| x + by))
}

/// Whether the boxes `a` and `b` share a point.
fn overlap(a: Bounds, b: Bounds) -> bool {
    (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
}

/// The box around every sphere (`None` for none).
fn sphere_bounds(positions: &[[f32; 3]], radii: &[f32]) -> Option<Bounds> {
    positions
        .iter()
        .zip(radii)
        .map(|(c, &r)| {
            let r = r as f64;
            (c.map(|x| x as f64 - r), c.map(|x| x as f64 + r))
        })
        .reduce(union)
}

/// The box around every corner of `triangles` (`None` for none).
fn triangle_bounds(triangles: &[Triangle]) -> Option<Bounds> {
    let corners = triangles.iter().flatten();
    corners
        .map(|c| (c.map(f64::from), c.map(f64::from)))
        .reduce(union)
}

/// Where most spheres are: on each axis, the centres from the 1st to the 99th percentile,
/// widened by the largest radius (`None` for no spheres). A heap on a floor with a few spheres
/// rolled far away is framed by its heap.
fn core_bounds(positions: &[[f32; 3]], radii: &[f32]) -> Option<Bounds> {
    let n = positions.len();
    let r_max = radii.iter().copied().fold(0.0f32, f32::max) as f64;
    let (lo_at, hi_at) = ((CORE_TAIL * n as f64) as usize, n.checked_sub(1)?);
    let hi_at = hi_at - lo_at;
    let mut bounds = ([0.0; 3], [0.0; 3]);
    let mut axis: Vec<f32> = Vec::with_capacity(n);
    for a in 0..3 {
        axis.clear();
        axis.extend(positions.iter().map(|c| c[a]));
        let lo = *axis.select_nth_unstable_by(lo_at, f32::total_cmp).1;
        let hi = *axis.select_nth_unstable_by(hi_at, f32::total_cmp).1;
        bounds.0[a] = lo as f64 - r_max;
        bounds.1[a] = hi as f64 + r_max;
    }
    Some(bounds)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A view of a 1 m box with its floor, framing automatically.
    fn in_a_box() -> View {
        let b = ([0.0; 3], [1.0; 3]);
        View {
            size: (400, 300),
            eye: None,
            look_at: None,
            fov: 40.0,
            samples: 1,
            shadows: false,
            fit: Fit::Auto,
            sim_box: Some(b),
            floor_box: Some(b),
            run: None,
        }
    }

    /// A square plate of side 0.1 at height `z` with its corner at `x`, `y`.
    fn plate([x, y, z]: [f32; 3]) -> Vec<Triangle> {
        let [a, b, c, d] =
            [[x, y], [x + 0.1, y], [x + 0.1, y + 0.1], [x, y + 0.1]].map(|[x, y]| [x, y, z]);
        vec![[a, b, c], [a, c, d]]
    }

    /// A plate at `now` that started at `start` (`None`: one that stands still).
    fn wall(now: [f32; 3], start: Option<[f32; 3]>) -> WallAt {
        WallAt {
            triangles: plate(now),
            start: start.and_then(|at| triangle_bounds(&plate(at))),
        }
    }

    #[test]
    fn a_wall_that_moved_clear_of_the_spheres_is_not_drawn_nor_framed() {
        let view = in_a_box();
        let positions = [[0.5, 0.5, 0.52], [0.52, 0.5, 0.52]];
        let radii = [0.01; 2];
        let under = [0.45, 0.45, 0.5];
        // A gate still under the spheres, one slid far away from there, a plate that never
        // moves as far away, and a lid coming down from far above, still as far.
        let gate = wall(under, Some(under));
        let opened = wall([0.85, 0.45, 0.5], Some(under));
        let fixed = wall([0.85, 0.05, 0.5], None);
        let lid = wall([0.45, 0.45, 0.9], Some([0.45, 0.45, 0.95]));
        let framed = view.frame(&positions, &radii, &[gate, opened, fixed, lid]);
        assert_eq!(framed.walls.len(), 6, "all but the opened gate");
        let opened_gate = |c: &[f32; 3]| c[0] > 0.8 && c[1] > 0.4;
        assert!(!framed.walls.iter().flatten().any(opened_gate));
        let (lo, hi) = framed.region;
        assert!(
            hi[0] < 0.96 && lo[1] < 0.06 && hi[2] > 0.89,
            "{lo:?}..{hi:?}"
        );
        // The opened gate alone: the region the camera frames is the spheres'.
        let framed = view.frame(&positions, &radii, &[wall([0.85, 0.45, 0.5], Some(under))]);
        assert!(framed.walls.is_empty());
        let (lo, hi) = framed.region;
        assert!(hi[0] < 0.6 && lo[0] > 0.4, "{lo:?}..{hi:?}");
        // --fit box frames the box whatever the walls.
        let whole = View {
            fit: Fit::Box,
            ..in_a_box()
        };
        let framed = whole.frame(&positions, &radii, &[wall(under, None)]);
        assert_eq!(framed.region, ([0.0; 3], [1.0; 3]));
    }

    #[test]
    fn the_floor_is_drawn_where_spheres_come_near_it() {
        let view = in_a_box();
        let radii = [0.01];
        let resting = view.frame(&[[0.5, 0.5, 0.01]], &radii, &[]);
        let hanging = view.frame(&[[0.5, 0.5, 0.3]], &radii, &[]);
        assert!(resting.reaches_floor && !hanging.reaches_floor);
        assert!(view.picture(&resting).floor.is_some());
        assert!(view.picture(&hanging).floor.is_none());
        // A run's choice holds for each of its pictures.
        let run = View {
            run: Some((resting.region, true)),
            ..in_a_box()
        };
        assert!(run.picture(&hanging).floor.is_some());
        assert_eq!(run.picture(&hanging).camera, view.picture(&resting).camera);
        // Without a box, or with --no-floor, none.
        let no_floor = View {
            floor_box: None,
            ..in_a_box()
        };
        assert!(
            no_floor
                .picture(&no_floor.frame(&[[0.5, 0.5, 0.01]], &radii, &[]))
                .floor
                .is_none()
        );
    }

    #[test]
    fn a_heap_in_a_large_box_is_framed_from_low_and_fills_the_picture() {
        // 400 spheres in a low square heap in the middle of the box, two strays at corners.
        let view = in_a_box();
        let mut positions: Vec<[f32; 3]> = (0..400)
            .map(|k| {
                let (i, j, l) = (k % 20, (k / 20) % 20, k / 400);
                [
                    0.4 + 0.01 * i as f32,
                    0.4 + 0.01 * j as f32,
                    0.005 + 0.01 * l as f32,
                ]
            })
            .collect();
        positions.extend([[0.02, 0.02, 0.005], [0.98, 0.97, 0.005]]);
        let radii = vec![0.005; positions.len()];
        let framed = view.frame(&positions, &radii, &[]);
        let (lo, hi) = framed.region;
        assert!(
            lo[0] > 0.35 && hi[0] < 0.65 && hi[2] < 0.05,
            "{lo:?}..{hi:?}"
        );
        assert!(framed.reaches_floor);
        let camera = view.picture(&framed).camera;
        let d = glam::DVec3::from(camera.eye) - glam::DVec3::from(camera.look_at);
        let elevation = (d.z / d.length()).asin().to_degrees();
        assert!(elevation < 15.0, "{elevation}° above the horizon");
    }
}
