//! What every render path computes per pixel, in Rust: the ray–sphere test, the shading, the
//! background and the samples of a pixel. This is the CPU twin of `wgsl/render/render_common.wgsl`;
//! keep the two in sync line for line, so that the paths give the same picture up to rounding.

use super::camera::Grid;
use glam::Vec3;

/// "No hit" distance; keep in sync with `INF` in `wgsl/render/render_common.wgsl` (WGSL has no
/// infinity literal).
pub(crate) const INF: f32 = 3.0e38;

/// Share of the base colour that every lit or unlit surface shows.
const AMBIENT: f32 = 0.2;
/// Share added for surfaces facing the viewer (a soft headlight).
const FACING: f32 = 0.15;
/// Share added by the key light (Lambert).
const DIFFUSE: f32 = 0.65;
/// Strength and exponent of the Blinn–Phong highlight.
const SPECULAR: f32 = 0.3;
const SHININESS: f32 = 40.0;
/// The shadow ray starts this far outside the sphere, relative to its radius.
const SHADOW_LIFT: f32 = 0.02;

/// The floor's two checker greys and its cells per side.
const FLOOR_LIGHT: Vec3 = Vec3::new(0.86, 0.86, 0.84);
const FLOOR_DARK: Vec3 = Vec3::new(0.74, 0.74, 0.72);
const FLOOR_CELLS: f32 = 10.0;
/// Shadow rays from the floor start this far above it, relative to the floor's size.
const FLOOR_LIFT: f32 = 1e-5;

/// The mesh walls' colour, and how much of their shade covers what lies behind them (walls are
/// drawn as a translucent skin over the spheres inside, the nearest one only, and cast no
/// shadow).
const WALL_COLOUR: Vec3 = Vec3::new(0.55, 0.60, 0.68);
const WALL_ALPHA: f32 = 0.35;

/// Background at the top and the bottom of the picture (a vertical gradient).
const SKY_TOP: Vec3 = Vec3::new(0.95, 0.96, 0.97);
const SKY_BOTTOM: Vec3 = Vec3::new(0.78, 0.80, 0.84);

/// Where the ray `o + t·d` (`d` a unit vector) enters the sphere `s = (x, y, z, r)` for `t > 0`
/// (or leaves it, for a ray starting inside), or [`INF`].
///
/// The squared distance of the centre from the ray comes from the perpendicular vector, not from
/// `|o - c|² - b²`, which would cancel catastrophically for spheres far smaller than their
/// distance from the eye.
pub(crate) fn hit_sphere(o: Vec3, d: Vec3, s: [f32; 4]) -> f32 {
    let oc = o - Vec3::new(s[0], s[1], s[2]);
    let b = oc.dot(d);
    let q = oc - d * b;
    let h = s[3] * s[3] - q.dot(q);
    if h < 0.0 {
        return INF;
    }
    let root = h.sqrt();
    let near = -b - root;
    if near > 0.0 {
        return near;
    }
    let far = -b + root;
    if far > 0.0 { far } else { INF }
}

/// Where the ray `o + t·d` meets triangle `k` of `walls` (three corners `x, y, z, 0` each) for
/// `t > 0`, from either side, or [`INF`] (Möller–Trumbore).
pub(crate) fn hit_triangle(o: Vec3, d: Vec3, walls: &[[f32; 4]], k: u32) -> f32 {
    let [a, b, c] = corners(walls, k);
    let e1 = b - a;
    let e2 = c - a;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return INF;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if u < 0.0 || v < 0.0 || u + v > 1.0 {
        return INF;
    }
    let t = e2.dot(q) * inv;
    if t > 0.0 { t } else { INF }
}

/// The corners of triangle `k` of `walls`.
fn corners(walls: &[[f32; 4]], k: u32) -> [Vec3; 3] {
    let at = 3 * k as usize;
    std::array::from_fn(|i| Vec3::from_slice(&walls[at + i][..3]))
}

/// `c`, seen through the wall triangle `k` of `walls` along `d`: its shade laid over `c`.
fn through_wall(c: Vec3, walls: &[[f32; 4]], k: u32, d: Vec3, light: Vec3) -> Vec3 {
    let [a, b, e] = corners(walls, k);
    let n = (b - a).cross(e - a).normalize();
    let n = if n.dot(d) > 0.0 { -n } else { n };
    c + (shade(WALL_COLOUR, n, -d, light, 1.0) - c) * WALL_ALPHA
}

/// A horizontal rectangle under the spheres: `z = lo[2]`, `lo[0]..hi[0]` × `lo[1]..hi[1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Floor {
    pub lo: Vec3,
    pub hi: Vec3,
}

/// Where the ray `o + t·d` meets the floor for `0 < t < t_max`, or [`INF`].
fn hit_floor(floor: &Floor, o: Vec3, d: Vec3, t_max: f32) -> f32 {
    if d.z == 0.0 {
        return INF;
    }
    let t = (floor.lo.z - o.z) / d.z;
    let p = o + d * t;
    let inside = p.x >= floor.lo.x && p.x <= floor.hi.x && p.y >= floor.lo.y && p.y <= floor.hi.y;
    if t > 0.0 && t < t_max && inside {
        t
    } else {
        INF
    }
}

/// The checker grey of the floor at `p`.
fn floor_colour(floor: &Floor, p: Vec3) -> Vec3 {
    let u = ((p.x - floor.lo.x) / (floor.hi.x - floor.lo.x) * FLOOR_CELLS).floor();
    let v = ((p.y - floor.lo.y) / (floor.hi.y - floor.lo.y) * FLOOR_CELLS).floor();
    if (u + v).rem_euclid(2.0) < 0.5 {
        FLOOR_LIGHT
    } else {
        FLOOR_DARK
    }
}

/// The colour of a pixel: the mean of `samples`×`samples` rays on a regular grid inside it;
/// `trace(o, d, t_max, first)` is the path's nearest-sphere search and `trace_walls(o, d,
/// t_max)` its nearest-wall search (the BVH's `trace`).
#[allow(clippy::too_many_arguments)] // the shader's inputs, one by one
pub(crate) fn pixel(
    grid: &Grid,
    (x, y): (u32, u32),
    (samples, height): (u32, u32),
    shadows: bool,
    floor: Option<&Floor>,
    (spheres, colours, walls): (&[[f32; 4]], &[u32], &[[f32; 4]]),
    trace: impl Fn(Vec3, Vec3, f32, bool) -> (f32, u32),
    trace_walls: impl Fn(Vec3, Vec3, f32) -> (f32, u32),
) -> u32 {
    let mut sum = Vec3::ZERO;
    for sy in 0..samples {
        for sx in 0..samples {
            let fx = x as f32 + (sx as f32 + 0.5) / samples as f32;
            let fy = y as f32 + (sy as f32 + 0.5) / samples as f32;
            let d = (grid.corner + grid.right * fx + grid.down * fy).normalize();
            let (t, k) = trace(grid.eye, d, INF, false);
            let t_floor = match floor {
                Some(f) => hit_floor(f, grid.eye, d, t),
                None => INF,
            };
            let c = if let (Some(f), true) = (floor, t_floor < INF) {
                let p = grid.eye + d * t_floor;
                let n = Vec3::new(0.0, 0.0, if d.z < 0.0 { 1.0 } else { -1.0 });
                let mut lit = 1.0;
                if shadows && n.dot(grid.light) > 0.0 {
                    let lift = FLOOR_LIFT * (f.hi.x - f.lo.x + f.hi.y - f.lo.y);
                    let start = p + n * lift;
                    if trace(start, grid.light, INF, true).1 != u32::MAX {
                        lit = 0.0;
                    }
                }
                shade(floor_colour(f, p), n, -d, grid.light, lit)
            } else if k == u32::MAX {
                background(fy / height as f32)
            } else {
                let s = spheres[k as usize];
                let center = Vec3::new(s[0], s[1], s[2]);
                let n = (grid.eye + d * t - center).normalize();
                let facing_light = n.dot(grid.light);
                let mut lit = 1.0;
                if shadows && facing_light > 0.0 {
                    let start = center + n * (s[3] * (1.0 + SHADOW_LIFT));
                    if trace(start, grid.light, INF, true).1 != u32::MAX {
                        lit = 0.0;
                    }
                }
                let base = Vec3::from(unpack(colours[k as usize]));
                shade(base, n, -d, grid.light, lit)
            };
            let wall = trace_walls(grid.eye, d, t.min(t_floor)).1;
            let c = match wall {
                u32::MAX => c,
                w => through_wall(c, walls, w, d, grid.light),
            };
            sum += c;
        }
    }
    pack((sum * (1.0 / (samples * samples) as f32)).to_array())
}

/// Ambient, facing, Lambert and Blinn–Phong terms of a surface of colour `base` with unit normal
/// `n`, seen along `v` (towards the eye), lit from `l` unless `lit` is 0.
fn shade(base: Vec3, n: Vec3, v: Vec3, l: Vec3, lit: f32) -> Vec3 {
    let diffuse = n.dot(l).max(0.0) * lit;
    let facing = n.dot(v).max(0.0);
    let h = (l + v).normalize();
    let highlight = n.dot(h).max(0.0).powf(SHININESS) * SPECULAR * lit;
    let k = AMBIENT + FACING * facing + DIFFUSE * diffuse;
    base * k + highlight
}

/// The background at height `v` (0 at the top of the picture, 1 at the bottom).
pub(crate) fn background(v: f32) -> Vec3 {
    SKY_TOP + (SKY_BOTTOM - SKY_TOP) * v.clamp(0.0, 1.0)
}

/// `rgba8` (red in the low byte) as WGSL's `pack4x8unorm` packs it, with alpha 1.
pub(crate) fn pack(c: [f32; 3]) -> u32 {
    let byte = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u32;
    byte(c[0]) | byte(c[1]) << 8 | byte(c[2]) << 16 | 255 << 24
}

/// The inverse of [`pack`] (alpha dropped).
pub(crate) fn unpack(c: u32) -> [f32; 3] {
    [0, 8, 16].map(|shift| ((c >> shift) & 0xff) as f32 / 255.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ray_hits_a_small_far_sphere_where_it_should() {
        // r = 5e-4 at distance 3: |o - c|² - r² would lose the radius entirely in f32.
        let s = [0.0, 3.0, 0.0, 5e-4];
        let t = hit_sphere(Vec3::ZERO, Vec3::Y, s);
        assert!((t - (3.0 - 5e-4)).abs() < 1e-6, "{t}");
        assert_eq!(hit_sphere(Vec3::ZERO, Vec3::NEG_Y, s), INF);
        assert_eq!(hit_sphere(Vec3::new(1e-3, 0.0, 0.0), Vec3::Y, s), INF);
    }

    #[test]
    fn packing_round_trips_bytes() {
        let c = 0xff00_80ff;
        assert_eq!(pack(unpack(c)), c);
    }
}
