//! The mesh walls of the GPU engines' granular steps as their device code reads them
//! (`wgsl/dem/dem_mesh_walls.wgsl`, `optix/mesh_walls.cuh`): each wall's triangles in their rest
//! geometry, listed in the cells of a uniform grid over them that they pass through; each wall's
//! motion, from which the device takes its pose at the step's time; and the loads on the walls,
//! summed in lanes in the last step of each advance and added up here ([`wall_loads`]).

use crate::dem::model::MaterialTable;
use crate::dem::walls::{TriangleMesh, WallLoad, WallSet};
use crate::error::{Error, Result};
use crate::gpu::shader::{SharedStruct, Vec3f, Vec3u, shared_struct};
use glam::Vec3;
use rayon::prelude::*;

/// Candidates within a sphere's radius kept per wall (`MESH_NEAR` in the shader).
const MESH_NEAR: u32 = 16;

/// Partial sums of each wall load at most (spheres touching a wall add to different lanes),
/// and the words of all lanes of all walls a run keeps at most.
const MAX_LOAD_LANES: usize = 1024;
const LOAD_WORDS: usize = 1 << 20;

/// Cells of a wall's grid at most: this many per triangle, or [`MIN_CELLS`] (16 MB of
/// offsets) where that is more.
const CELLS_PER_TRIANGLE: usize = 8;
const MIN_CELLS: usize = 1 << 22;

/// The walls' uniform; WGSL twin `MeshParams`.
#[derive(Debug, Clone, Copy, Default, PartialEq, encase::ShaderType)]
pub struct MeshParams {
    pub walls: u32,
    pub box_walls: u32,
    pub loads_step: u32,
    pub load_lanes: u32,
    /// The loads sum the spheres whose centre c lies in `own_lo <= c < own_hi` (infinite:
    /// every sphere; a rank's step: its box, the spheres it owns, not its ghosts).
    pub own_lo: Vec3f,
    pub own_hi: Vec3f,
}

pub fn mesh_params() -> SharedStruct {
    shared_struct!(
        "MeshParams",
        MeshParams {
            walls,
            box_walls,
            loads_step,
            load_lanes,
            own_lo,
            own_hi
        }
    )
}

/// [`MeshWallRow::own_friction`] of a wall without a friction of its own: each sphere takes
/// the pair's (its material's row, the wall's column).
pub const NO_FRICTION: f32 = -1.0;

/// One wall as the shader reads it; WGSL twin `MeshWall` (and `MochiMeshWall` in
/// `optix/mesh_walls.cuh`).
#[derive(Debug, Clone, Copy, Default, PartialEq, encase::ShaderType)]
pub struct MeshWallRow {
    lo: Vec3f,
    cell: f32,
    dims: Vec3u,
    first_cell: u32,
    velocity: Vec3f,
    omega: f32,
    axis: Vec3f,
    start: f32,
    centre: Vec3f,
    /// The wall's column of the material table (its material, or a rigid wall's).
    column: u32,
    /// The wall's own μ, or [`NO_FRICTION`]: each sphere then takes its pair's, by `column`.
    own_friction: f32,
}

pub fn mesh_wall_row() -> SharedStruct {
    shared_struct!(
        "MeshWall",
        MeshWallRow {
            lo,
            cell,
            dims,
            first_cell,
            velocity,
            omega,
            axis,
            start,
            centre,
            column,
            own_friction,
        }
    )
}

/// A wall's grid: its rest-geometry corner, cell side, cells per axis and each cell's triangles
/// (cell c's are `listed[starts[c]..starts[c + 1]]`).
struct WallGrid {
    lo: Vec3,
    cell: f32,
    dims: [u32; 3],
    starts: Vec<u32>,
    listed: Vec<u32>,
}

impl WallGrid {
    /// The triangles cell `at` lists.
    #[cfg(test)]
    fn cell(&self, at: usize) -> &[u32] {
        &self.listed[self.starts[at] as usize..self.starts[at + 1] as usize]
    }
}

/// The grid over `mesh`'s rest geometry grown by `reach`, the farthest a sphere's centre acts
/// from a wall (the largest radius, plus how far past touching a contact may hold where contacts
/// adhere): cells of twice that, larger where the bounds would need more cells than the budget;
/// each triangle listed in every cell whose box grown by `reach` it meets (a sphere's candidates
/// are then the triangles of the one cell holding its centre, each once). The boxes are grown
/// by 1 % more of a cell: rounding where the shader finds a centre's cell then never misses one.
fn wall_grid(mesh: &TriangleMesh, reach: f32, first_triangle: u32) -> WallGrid {
    let triangles = mesh.triangles();
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for t in triangles {
        for c in t.corners {
            lo = lo.min(c);
            hi = hi.max(c);
        }
    }
    let (lo, hi) = (lo - Vec3::splat(reach), hi + Vec3::splat(reach));
    let budget = CELLS_PER_TRIANGLE * triangles.len();
    let (cell, dims) = grid_cell(hi - lo, 2.0 * reach, budget);
    let lo = lo - Vec3::splat(0.5 * cell);
    let grown = 0.5 * cell * 1.01 + reach;
    let index = |x: f32| x.floor().max(0.0) as u32;
    // Each triangle's cells, found on every core, as (cell, triangle) pairs.
    let mut hits: Vec<(usize, u32)> = (triangles.par_iter().enumerate())
        .flat_map_iter(|(k, t)| {
            let (tlo, thi) = t
                .corners
                .iter()
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &c| {
                    (a.min(c), b.max(c))
                });
            let from = ((tlo - Vec3::splat(reach) - lo) / cell - 0.01)
                .to_array()
                .map(index);
            let to = ((thi + Vec3::splat(reach) - lo) / cell + 0.01).to_array();
            let to: [u32; 3] = std::array::from_fn(|a| index(to[a]).min(dims[a] - 1));
            let boxes = (from[2]..=to[2]).flat_map(move |z| {
                (from[1]..=to[1]).flat_map(move |y| (from[0]..=to[0]).map(move |x| [x, y, z]))
            });
            boxes.filter_map(move |[x, y, z]| {
                let centre = lo + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * cell;
                let at =
                    x as usize + dims[0] as usize * (y as usize + dims[1] as usize * z as usize);
                meets_box(&t.corners, centre, grown).then_some((at, first_triangle + k as u32))
            })
        })
        .collect();
    // Each cell lists its triangles in their order, cell after cell.
    hits.par_sort_unstable();
    let cells: usize = dims.iter().map(|&d| d as usize).product();
    let mut starts = vec![0u32; cells + 1];
    for &(at, _) in &hits {
        starts[at + 1] += 1;
    }
    for c in 0..cells {
        starts[c + 1] += starts[c];
    }
    let listed = hits.into_iter().map(|(_, triangle)| triangle).collect();
    WallGrid {
        lo,
        cell,
        dims,
        starts,
        listed,
    }
}

/// The cell side and cells per axis of a grid over bounds of size `extent` with a margin of
/// half a cell on each side (no triangle corner lies on its outer faces): cells of side
/// `reach`, grown until there are at most `budget` of them (or [`MIN_CELLS`]).
fn grid_cell(extent: Vec3, reach: f32, budget: usize) -> (f32, [u32; 3]) {
    let extent = extent.max(Vec3::splat(f32::MIN_POSITIVE));
    let budget = budget.max(MIN_CELLS) as f64;
    let dims_at = |cell: f32| (extent / cell).ceil().max(Vec3::ONE).as_uvec3() + 1;
    let mut cell = reach.max(extent.max_element() * 1e-6);
    while dims_at(cell).as_dvec3().element_product() > budget {
        cell *= 1.25;
    }
    (cell, dims_at(cell).to_array())
}

/// Whether the triangle `corners` meets the cube of half-side `half` about `centre`: no axis
/// separates them (the cube's three, the triangle's normal, and the nine cross products of
/// their edges).
fn meets_box(corners: &[Vec3; 3], centre: Vec3, half: f32) -> bool {
    let v = corners.map(|c| c - centre);
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let apart = |axis: Vec3| {
        let p = v.map(|x| x.dot(axis));
        let reach = half * axis.abs().element_sum();
        p[0].min(p[1]).min(p[2]) > reach || p[0].max(p[1]).max(p[2]) < -reach
    };
    let axes = [Vec3::X, Vec3::Y, Vec3::Z];
    if axes.iter().any(|&a| apart(a)) || apart(edges[0].cross(edges[1])) {
        return false;
    }
    !axes
        .iter()
        .any(|a| edges.iter().any(|e| apart(a.cross(*e))))
}

/// What the GPU steps read of the mesh walls, on the host: each wall's row, the grids' offsets
/// and triangle indices, the triangles (three corners and the normal, rest geometry) and the
/// walls' parameters. The wgpu engines upload them to their buffers, the optix engine to its.
pub(crate) struct WallTables {
    pub params: MeshParams,
    pub rows: Vec<MeshWallRow>,
    pub grid: Vec<u32>,
    pub tris: Vec<[f32; 4]>,
}

impl WallTables {
    /// The tables of `walls` for spheres whose centres act on a wall from at most `reach` away
    /// (the largest radius, plus the law's search margin where contacts adhere), refusing grids
    /// of more than `max_words` words (the `engine` step's limit).
    pub fn new(
        walls: &WallSet,
        table: &MaterialTable,
        reach: f32,
        max_words: u64,
        engine: &str,
    ) -> Result<Self> {
        let mut rows = Vec::with_capacity(walls.meshes.len());
        let mut offsets: Vec<u32> = Vec::new();
        let mut listed: Vec<u32> = Vec::new();
        let mut tris: Vec<[f32; 4]> = Vec::new();
        for wall in &walls.meshes {
            let first_triangle = (tris.len() / 4) as u32;
            for t in wall.triangles.triangles() {
                tris.extend(
                    t.corners
                        .iter()
                        .chain([&t.normal])
                        .map(|v| v.extend(0.0).to_array()),
                );
            }
            let g = wall_grid(&wall.triangles, reach, first_triangle);
            let m = wall.motion;
            let column = wall.column(table);
            rows.push(MeshWallRow {
                lo: g.lo.into(),
                cell: g.cell,
                dims: Vec3u(g.dims),
                first_cell: offsets.len() as u32,
                velocity: m.velocity.as_vec3().into(),
                omega: m.omega as f32,
                axis: m.axis.as_vec3().into(),
                start: m.start as f32,
                centre: m.centre.as_vec3().into(),
                column,
                own_friction: wall.friction.unwrap_or(NO_FRICTION),
            });
            let first = listed.len() as u32;
            offsets.extend(g.starts[..g.starts.len() - 1].iter().map(|&s| first + s));
            listed.extend(g.listed);
        }
        // Offsets past the cells' own words (and the end of the last cell).
        let head = offsets.len() as u64 + 1;
        let words = head + listed.len() as u64;
        let limit = max_words.min(u32::MAX as u64);
        if words > limit {
            return Err(Error::TooLarge {
                what: format!("words of the mesh walls' grids for the {engine} step"),
                got: words,
                limit,
            });
        }
        let mut grid: Vec<u32> = offsets.iter().map(|&o| o + head as u32).collect();
        grid.push(words as u32);
        grid.extend(listed);
        let load_lanes = (LOAD_WORDS / (8 * rows.len().max(1))).clamp(1, MAX_LOAD_LANES) as u32;
        let params = MeshParams {
            walls: rows.len() as u32,
            box_walls: walls.box_walls as u32,
            loads_step: u32::MAX,
            load_lanes,
            own_lo: Vec3f([f32::NEG_INFINITY; 3]),
            own_hi: Vec3f([f32::INFINITY; 3]),
        };
        Ok(Self {
            params,
            rows,
            grid,
            tris,
        })
    }

    /// Words of the loads' buffer: 8 per wall and lane, then the most candidates a sphere had.
    pub fn load_words(&self) -> usize {
        8 * self.rows.len() * self.params.load_lanes as usize + 1
    }
}

/// The loads on `walls` walls summed in `lanes` lanes (`words` as the loads' buffer holds them,
/// f32 bits), refusing a step in which some sphere came within its radius of more triangles of
/// one wall than the `engine` step keeps.
pub(crate) fn wall_loads(
    words: &[u32],
    walls: usize,
    lanes: usize,
    engine: &str,
) -> Result<Vec<WallLoad>> {
    let most = words[8 * walls * lanes];
    if most > MESH_NEAR {
        return Err(Error::TooLarge {
            what: format!(
                "triangles of one mesh wall within a sphere's radius (and its adhesion's reach) \
                 in the {engine} step (a mesh much finer than the spheres; the cpu backend takes \
                 any number)"
            ),
            got: most as u64,
            limit: MESH_NEAR as u64,
        });
    }
    // Lane by lane, in order: the sum depends on the lanes' partial sums alone.
    let f = |k: usize| -> f64 {
        (0..lanes)
            .map(|l| f32::from_bits(words[8 * walls * l + k]) as f64)
            .sum()
    };
    Ok((0..walls)
        .map(|w| WallLoad {
            force: [f(8 * w), f(8 * w + 1), f(8 * w + 2)],
            torque: [f(8 * w + 4), f(8 * w + 5), f(8 * w + 6)],
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    #[test]
    fn every_point_near_a_triangle_is_in_a_cell_that_lists_it_and_no_cell_lists_a_far_one() {
        // A tilted square, so that its faces and edges cross the cells anywhere.
        let v = [
            Vec3::new(0.0, 0.0, 0.3),
            Vec3::new(1.0, 0.1, 0.5),
            Vec3::new(1.1, 1.0, 0.7),
            Vec3::new(0.1, 1.1, 0.5),
        ];
        let mesh = TriangleMesh::new(&v, &[[0, 1, 2], [0, 2, 3]]);
        let r_max = 0.025;
        let g = wall_grid(&mesh, r_max, 7);
        assert_eq!(g.cell, 0.05);
        let cell_of = |p: Vec3| {
            let c = ((p - g.lo) / g.cell).floor().as_uvec3();
            c.x as usize + g.dims[0] as usize * (c.y as usize + g.dims[1] as usize * c.z as usize)
        };
        let triangles = mesh.triangles();
        // Points around the square, off its faces and edges by up to r_max in each direction.
        let mut rng = Pcg64::seed_from_u64(5);
        let mut checked = 0;
        for _ in 0..20_000 {
            let (a, b) = (rng.random_range(-0.1..1.1), rng.random_range(-0.1..1.1));
            let on = v[0] + (v[1] - v[0]) * a + (v[3] - v[0]) * b;
            let off = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let p = on + off * r_max;
            for (k, t) in triangles.iter().enumerate() {
                if t.closest_point(p).distance(p) < r_max {
                    let listed = g.cell(cell_of(p));
                    assert!(listed.contains(&(7 + k as u32)), "{p} lacks {k}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 10_000, "{checked} points near the square");
        // A cell lists a triangle only where its box grown by r_max meets it (its centre then
        // within √3 times the grown half side).
        let reach = 3f32.sqrt() * (0.5 * g.cell * 1.01 + r_max);
        let cells = g.starts.len() - 1;
        for (at, listed) in (0..cells).map(|at| (at, g.cell(at))) {
            let d = g.dims.map(|d| d as usize);
            let c = Vec3::new(
                (at % d[0]) as f32,
                (at / d[0] % d[1]) as f32,
                (at / d[0] / d[1]) as f32,
            );
            let centre = g.lo + (c + 0.5) * g.cell;
            for &t in listed {
                let t = &triangles[t as usize - 7];
                assert!(
                    t.closest_point(centre).distance(centre) <= reach,
                    "cell {c} lists a far triangle"
                );
            }
        }
        // Each cell lists its triangles once, in the mesh's order (the order the steps sum
        // them in).
        let lists = || (0..cells).map(|at| g.cell(at));
        assert!(lists().all(|l| l.windows(2).all(|w| w[0] < w[1])));
        assert!(lists().filter(|l| l.len() == 2).count() > 10);
        // A triangle off to the side of a cell is not listed in it.
        let far = [
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(1.0, 2.0, 0.0),
        ];
        assert!(!meets_box(&far, Vec3::ZERO, 0.9));
        assert!(meets_box(&far, Vec3::new(1.2, 1.2, 0.5), 0.6));
        // One crossing a cell's corner region diagonally, its corners all outside the box.
        let slanted = [
            Vec3::new(-2.0, 0.5, 0.0),
            Vec3::new(0.5, -2.0, 0.0),
            Vec3::new(0.5, 0.5, 3.0),
        ];
        assert!(meets_box(&slanted, Vec3::ZERO, 1.0));
    }

    #[test]
    fn the_grid_stays_within_its_budget() {
        let (cell, dims) = grid_cell(Vec3::new(100.0, 100.0, 0.0), 1e-3, 10);
        let cells: usize = dims.iter().map(|&d| d as usize).product();
        assert!(cells <= MIN_CELLS, "{cells} cells");
        assert!(cells > MIN_CELLS / 4, "{cells} cells of {cell} m");
        // Where the budget allows, cells are as wide as a sphere.
        assert_eq!(grid_cell(Vec3::ONE, 0.01, 10).0, 0.01);
    }
}
