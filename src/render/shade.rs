//! What every render path computes per pixel, in Rust: the ray–sphere test, the shading, the
//! background and the samples of a pixel. This is the CPU twin of `wgsl/render_common.wgsl`;
//! keep the two in sync line for line, so that the paths give the same picture up to rounding.

use super::camera::Grid;

/// "No hit" distance; keep in sync with `INF` in `wgsl/render_common.wgsl` (WGSL has no
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
const FLOOR_LIGHT: [f32; 3] = [0.86, 0.86, 0.84];
const FLOOR_DARK: [f32; 3] = [0.74, 0.74, 0.72];
const FLOOR_CELLS: f32 = 10.0;
/// Shadow rays from the floor start this far above it, relative to the floor's size.
const FLOOR_LIFT: f32 = 1e-5;

/// Background at the top and the bottom of the picture (a vertical gradient).
const SKY_TOP: [f32; 3] = [0.95, 0.96, 0.97];
const SKY_BOTTOM: [f32; 3] = [0.78, 0.80, 0.84];

/// Where the ray `o + t·d` (`d` a unit vector) enters the sphere `s = (x, y, z, r)` for `t > 0`
/// (or leaves it, for a ray starting inside), or [`INF`].
///
/// The squared distance of the centre from the ray comes from the perpendicular vector, not from
/// `|o - c|² - b²`, which would cancel catastrophically for spheres far smaller than their
/// distance from the eye.
pub(crate) fn hit_sphere(o: [f32; 3], d: [f32; 3], s: [f32; 4]) -> f32 {
    let oc = sub(o, [s[0], s[1], s[2]]);
    let b = dot(oc, d);
    let q = sub(oc, scale(d, b));
    let h = s[3] * s[3] - dot(q, q);
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

/// A horizontal rectangle under the spheres: `z = lo[2]`, `lo[0]..hi[0]` × `lo[1]..hi[1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Floor {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
}

/// Where the ray `o + t·d` meets the floor for `0 < t < t_max`, or [`INF`].
fn hit_floor(floor: &Floor, o: [f32; 3], d: [f32; 3], t_max: f32) -> f32 {
    if d[2] == 0.0 {
        return INF;
    }
    let t = (floor.lo[2] - o[2]) / d[2];
    let p = add(o, scale(d, t));
    let inside =
        p[0] >= floor.lo[0] && p[0] <= floor.hi[0] && p[1] >= floor.lo[1] && p[1] <= floor.hi[1];
    if t > 0.0 && t < t_max && inside {
        t
    } else {
        INF
    }
}

/// The checker grey of the floor at `p`.
fn floor_colour(floor: &Floor, p: [f32; 3]) -> [f32; 3] {
    let u = ((p[0] - floor.lo[0]) / (floor.hi[0] - floor.lo[0]) * FLOOR_CELLS).floor();
    let v = ((p[1] - floor.lo[1]) / (floor.hi[1] - floor.lo[1]) * FLOOR_CELLS).floor();
    if (u + v).rem_euclid(2.0) < 0.5 {
        FLOOR_LIGHT
    } else {
        FLOOR_DARK
    }
}

/// The colour of a pixel: the mean of `samples`×`samples` rays on a regular grid inside it;
/// `trace(o, d, t_max, first)` is the path's nearest-hit search (see [`super::bvh::trace`]).
#[allow(clippy::too_many_arguments)] // the shader's inputs, one by one
pub(crate) fn pixel(
    grid: &Grid,
    (x, y): (u32, u32),
    (samples, height): (u32, u32),
    shadows: bool,
    floor: Option<&Floor>,
    spheres: &[[f32; 4]],
    colours: &[u32],
    trace: impl Fn([f32; 3], [f32; 3], f32, bool) -> (f32, u32),
) -> u32 {
    let mut sum = [0f32; 3];
    for sy in 0..samples {
        for sx in 0..samples {
            let fx = x as f32 + (sx as f32 + 0.5) / samples as f32;
            let fy = y as f32 + (sy as f32 + 0.5) / samples as f32;
            let d = normalize(add(
                add(grid.corner, scale(grid.right, fx)),
                scale(grid.down, fy),
            ));
            let (t, k) = trace(grid.eye, d, INF, false);
            let t_floor = match floor {
                Some(f) => hit_floor(f, grid.eye, d, t),
                None => INF,
            };
            let c = if let (Some(f), true) = (floor, t_floor < INF) {
                let p = add(grid.eye, scale(d, t_floor));
                let n = [0.0, 0.0, if d[2] < 0.0 { 1.0 } else { -1.0 }];
                let mut lit = 1.0;
                if shadows && dot(n, grid.light) > 0.0 {
                    let lift = FLOOR_LIFT * (f.hi[0] - f.lo[0] + f.hi[1] - f.lo[1]);
                    let start = add(p, scale(n, lift));
                    if trace(start, grid.light, INF, true).1 != u32::MAX {
                        lit = 0.0;
                    }
                }
                shade(floor_colour(f, p), n, scale(d, -1.0), grid.light, lit)
            } else if k == u32::MAX {
                background(fy / height as f32)
            } else {
                let s = spheres[k as usize];
                let center = [s[0], s[1], s[2]];
                let n = normalize(sub(add(grid.eye, scale(d, t)), center));
                let facing_light = dot(n, grid.light);
                let mut lit = 1.0;
                if shadows && facing_light > 0.0 {
                    let start = add(center, scale(n, s[3] * (1.0 + SHADOW_LIFT)));
                    if trace(start, grid.light, INF, true).1 != u32::MAX {
                        lit = 0.0;
                    }
                }
                shade(
                    unpack(colours[k as usize]),
                    n,
                    scale(d, -1.0),
                    grid.light,
                    lit,
                )
            };
            sum = add(sum, c);
        }
    }
    pack(scale(sum, 1.0 / (samples * samples) as f32))
}

/// Ambient, facing, Lambert and Blinn–Phong terms of a surface of colour `base` with unit normal
/// `n`, seen along `v` (towards the eye), lit from `l` unless `lit` is 0.
fn shade(base: [f32; 3], n: [f32; 3], v: [f32; 3], l: [f32; 3], lit: f32) -> [f32; 3] {
    let diffuse = dot(n, l).max(0.0) * lit;
    let facing = dot(n, v).max(0.0);
    let h = normalize(add(l, v));
    let highlight = dot(n, h).max(0.0).powf(SHININESS) * SPECULAR * lit;
    let k = AMBIENT + FACING * facing + DIFFUSE * diffuse;
    base.map(|c| c * k + highlight)
}

/// The background at height `v` (0 at the top of the picture, 1 at the bottom).
pub(crate) fn background(v: f32) -> [f32; 3] {
    let v = v.clamp(0.0, 1.0);
    [0, 1, 2].map(|k| SKY_TOP[k] + (SKY_BOTTOM[k] - SKY_TOP[k]) * v)
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

fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    a.map(|x| x * s)
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: [f32; 3]) -> [f32; 3] {
    scale(a, 1.0 / dot(a, a).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ray_hits_a_small_far_sphere_where_it_should() {
        // r = 5e-4 at distance 3: |o - c|² - r² would lose the radius entirely in f32.
        let s = [0.0, 3.0, 0.0, 5e-4];
        let t = hit_sphere([0.0; 3], [0.0, 1.0, 0.0], s);
        assert!((t - (3.0 - 5e-4)).abs() < 1e-6, "{t}");
        assert_eq!(hit_sphere([0.0; 3], [0.0, -1.0, 0.0], s), INF);
        assert_eq!(hit_sphere([1e-3, 0.0, 0.0], [0.0, 1.0, 0.0], s), INF);
    }

    #[test]
    fn packing_round_trips_bytes() {
        let c = 0xff00_80ff;
        assert_eq!(pack(unpack(c)), c);
    }
}
