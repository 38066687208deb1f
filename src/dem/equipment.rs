//! The built-in scenes with equipment, their meshes made in code: `hopper` (a cylinder with a
//! flat or conical bottom and a circular orifice, closed by a gate that slides away at
//! `open`; the spheres that fall out are removed and counted in `flow.csv`) and `drum`
//! (a cylinder about the y axis, 40% filled, turning at `omega`; the box's walls close
//! its ends), both sized from the number of spheres, of radii U[0.9, 1.1]·`grain_radius`
//! on a jittered lattice; and `agglomerate` (a ball of bonded grains dropped on the floor at
//! `speed`). [`mass_flow_rate`] and [`free_surface_angle`] measure what the first two are for,
//! [`fragments`] what the last one is.

use super::flow::OutflowConfig;
use super::walls::{Rotation, WallConfig};
use crate::error::{Error, Result, try_vec};
use crate::mesh::{Mesh, revolution};
use crate::spheres::SphereSet;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

/// Sides of the generated cylinders and cones.
const SIDES: u32 = 64;
/// Triangles of a drum's tube at most.
const MAX_TRIANGLES: u64 = 1 << 24;
/// Lattice spacing over the largest radius.
const SPACING: f64 = 2.2;

/// The `[source]` of scene `hopper`: a cylinder of `orifice` diameter below, filled, then
/// opened.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Hopper {
    /// Spheres.
    pub spheres: usize,
    /// Seed of the radii and the jitter.
    pub seed: u64,
    /// Mean sphere radius \[m\] (radii U\[0.9, 1.1\] of it).
    pub grain_radius: f64,
    /// Orifice diameter \[m\] (short form `hopper_orifice`).
    pub orifice: f64,
    /// Angle of the bottom from the horizontal \[°\] (0: flat; short form `hopper_angle`).
    pub angle: f64,
    /// Time the gate under the orifice slides away \[s\] (short form `hopper_open`).
    pub open: f64,
}

impl Default for Hopper {
    fn default() -> Self {
        Hopper {
            spheres: DEFAULT_SPHERES,
            seed: 1,
            grain_radius: DEFAULT_GRAIN_RADIUS,
            orifice: 0.04,
            angle: 0.0,
            open: 0.2,
        }
    }
}

/// The `[source]` of scene `drum`: a tube about the y axis, 40% filled, turning.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Drum {
    /// Spheres.
    pub spheres: usize,
    /// Seed of the radii and the jitter.
    pub seed: u64,
    /// Mean sphere radius \[m\] (radii U\[0.9, 1.1\] of it).
    pub grain_radius: f64,
    /// Angular speed about y \[rad/s\] (short form `drum_omega`).
    pub omega: f64,
    /// Sides of the tube around, at least 3 (short form `drum_sides`).
    pub sides: u32,
    /// Rings of the tube along its length, at least 1 (short form `drum_rings`).
    pub rings: u32,
}

impl Default for Drum {
    fn default() -> Self {
        Drum {
            spheres: DEFAULT_SPHERES,
            seed: 1,
            grain_radius: DEFAULT_GRAIN_RADIUS,
            omega: 3.0,
            sides: 64,
            rings: 1,
        }
    }
}

/// The `[source]` of scene `agglomerate`: a ball of `spheres` grains of radius `grain_radius`,
/// packed face-centred cubic and pressed a thousandth of a radius into each other (every
/// neighbour touches, so each contact bonds where the material adheres: with the scene's default
/// material, by a liquid bridge), its lowest grain half a radius above the floor, all moving
/// down at `speed`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Agglomerate {
    /// Grains.
    pub spheres: usize,
    /// Grain radius \[m\].
    pub grain_radius: f64,
    /// Speed at which the ball moves down at t = 0 \[m/s\] (short form `agglomerate_speed`).
    pub speed: f64,
}

impl Default for Agglomerate {
    fn default() -> Self {
        Agglomerate {
            spheres: 500,
            grain_radius: 0.001,
            speed: 1.0,
        }
    }
}

impl Agglomerate {
    /// The liquid of a bridge of the scene's default material \[m³\]: 2.4e-4 of a grain's
    /// volume (1 nl between 1 mm grains), whose bridges rupture at a tenth of a radius.
    pub fn liquid_volume(&self) -> f64 {
        2.4e-4 * 4.0 / 3.0 * std::f64::consts::PI * self.grain_radius.powi(3)
    }

    /// Builds the agglomerate (the struct's docs).
    pub fn build(&self) -> Result<Built> {
        let (n, r) = (self.spheres, self.grain_radius);
        if !(r.is_finite() && r > 0.0 && self.speed.is_finite()) {
            return Err(refused(
                "agglomerate",
                format!(
                    "grain_radius must be positive and agglomerate_speed finite, got {r} m and \
                     {} m/s",
                    self.speed
                ),
            ));
        }
        crate::spheres::check_count(n)?;
        // Neighbours 2r(1 − 1e-3) apart: the sites are the points of a cubic lattice of
        // spacing `half` whose coordinates sum to an even number, neighbours √2·half apart.
        let neighbour = 2.0 * r * (1.0 - 1e-3);
        let half = neighbour / std::f64::consts::SQRT_2;
        // The points of a cube of the lattice that holds a ball of n of its sites (4 a cube
        // cell of side 2·half), nearest the centre first (ties in the order made).
        let ball = (3.0 * n as f64 * (2.0 * half).powi(3) / (16.0 * std::f64::consts::PI)).cbrt();
        let k = (ball / half).ceil() as i64 + 2;
        let mut sites = Vec::new();
        for i in -k..=k {
            for j in -k..=k {
                for l in -k..=k {
                    if (i + j + l).rem_euclid(2) == 0 {
                        sites.push([i, j, l].map(|x| x as f64 * half));
                    }
                }
            }
        }
        let norm = |c: &[f64; 3]| c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        sites.sort_by(|a, b| norm(a).total_cmp(&norm(b)));
        sites.truncate(n);
        let extent = sites.iter().map(|c| norm(c).sqrt()).fold(0.0, f64::max) + r;
        // A box four balls wide and three tall, the ball above the middle of its floor.
        let side = 8.0 * extent;
        let bottom = sites.iter().map(|c| c[2]).fold(0.0, f64::min);
        let lift = 1.5 * r - bottom;
        let centers = sites
            .iter()
            .map(|c| [c[0] + side / 2.0, c[1] + side / 2.0, c[2] + lift].map(|x| x as f32))
            .collect();
        Ok(Built {
            spheres: SphereSet::new(centers, vec![r as f32; n])?,
            box_lo: [0.0; 3],
            box_hi: [side, side, 6.0 * extent],
            walls: Vec::new(),
            outflows: Vec::new(),
            velocity: [0.0, 0.0, -self.speed],
        })
    }
}

/// The pieces of an agglomerate: the sizes of the groups of spheres joined by the contacts of
/// `history` (bonds: a pair with a history entry), largest first.
pub fn fragments(history: &crate::particles::ContactHistory, n: usize) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for e in history.of(i) {
            let j = e.partner as usize;
            if j < n {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a] = b;
            }
        }
    }
    let mut sizes = vec![0; n];
    for i in 0..n {
        sizes[root(&mut parent, i)] += 1;
    }
    sizes.retain(|&s| s > 0);
    sizes.sort_unstable_by(|a, b| b.cmp(a));
    sizes
}

/// Spheres of a built-in scene when the scene gives no number.
const DEFAULT_SPHERES: usize = 4_000;
/// Mean sphere radius of a built-in scene when the scene gives none \[m\].
const DEFAULT_GRAIN_RADIUS: f64 = 0.004;

/// A built-in scene: its spheres, box, walls (mesh and pose) and outflows.
#[derive(Debug, Clone)]
pub struct Built {
    /// The spheres at t = 0.
    pub spheres: SphereSet,
    /// The box \[m\].
    pub box_lo: [f64; 3],
    /// The box \[m\].
    pub box_hi: [f64; 3],
    /// The walls.
    pub walls: Vec<(WallConfig, Mesh)>,
    /// The outflows.
    pub outflows: Vec<OutflowConfig>,
    /// Every sphere's velocity at t = 0 \[m/s\].
    pub velocity: [f64; 3],
}

/// What the grains of a built-in scene (`what`, for errors) of `n` spheres of mean radius `r`
/// take: the lattice spacing and the volume of its cells.
fn grains(what: &str, n: usize, r: f64) -> Result<(f64, f64)> {
    if !(r.is_finite() && r > 0.0) {
        return Err(refused(
            what,
            format!("grain_radius must be positive, got {r}"),
        ));
    }
    crate::spheres::check_count(n)?;
    let cell = SPACING * 1.1 * r;
    Ok((cell, n as f64 * cell.powi(3)))
}

/// The error of scene `what`'s parameters.
fn refused(what: &str, reason: String) -> Error {
    Error::InvalidConfig {
        what: format!("scene \"{what}\""),
        reason,
    }
}

impl Hopper {
    /// Builds the hopper (module docs).
    pub fn build(&self) -> Result<Built> {
        let r = self.grain_radius;
        let (cell, volume) = grains("hopper", self.spheres, r)?;
        let bad = |reason| refused("hopper", reason);
        let (d, angle) = (self.orifice, self.angle);
        if !(d.is_finite() && d > 2.0 * r) {
            return Err(bad(format!(
                "hopper_orifice must exceed a sphere's diameter, got {d} m"
            )));
        }
        if !(0.0..80.0).contains(&angle) || !self.open.is_finite() {
            return Err(bad(format!(
                "hopper_angle must be in [0, 80) degrees and hopper_open finite, got {angle} and {}",
                self.open
            )));
        }
        // A cylinder 5 orifices wide, as tall as twice the fill (at least two lattice layers
        // above the bottom's rim, so that any number of spheres finds room).
        let radius = 2.5 * d;
        let cone = (radius - d / 2.0) * angle.to_radians().tan();
        let fill = volume / (std::f64::consts::PI * (radius - cell).powi(2)) + cone;
        let height = cone + 2.0 * fill.max(2.0 * cell);
        let bottom = |rho: f64| (rho - d / 2.0).max(0.0) * angle.to_radians().tan();
        let inside = |c: [f64; 3]| {
            let rho = c[0].hypot(c[1]);
            rho < radius - cell / 2.0 && c[2] > bottom(rho + cell / 2.0) + cell / 2.0
        };
        let lo = [-radius, -radius, 0.0];
        let hi = [radius, radius, height];
        let spheres = lattice(self.spheres, self.seed, r, cell, [lo, hi], inside)?;
        let body = revolution(&[(d / 2.0, 0.0), (radius, cone), (radius, height)], SIDES);
        // A square plate under the orifice: two triangles (a disc of fan triangles would meet
        // at its centre, every one of them within a sphere's reach there).
        let h = d / 2.0 + 2.0 * cell;
        let gate = Mesh {
            vertices: vec![[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
        // A quarter radius below the bottom: what rests on the bottom never touches it, and
        // no sphere touches both (they are separate meshes, each contact resolved per mesh).
        let gate_config = WallConfig {
            translate: Some([0.0, 0.0, -0.25 * r]),
            velocity: Some([1.0, 0.0, 0.0]),
            start: Some(self.open),
            ..WallConfig::of("gate (generated)")
        };
        let margin = 0.1 * radius;
        Ok(Built {
            spheres,
            box_lo: [-radius - margin, -radius - margin, -height],
            box_hi: [radius + margin, radius + margin, height + margin],
            walls: vec![
                (WallConfig::of("hopper (generated)"), body),
                (gate_config, gate),
            ],
            // Spheres a hopper's height below the orifice have left.
            outflows: vec![OutflowConfig {
                lo: [-radius - margin, -radius - margin, -height],
                hi: [radius + margin, radius + margin, -0.5 * height],
            }],
            velocity: [0.0; 3],
        })
    }
}

impl Drum {
    /// Builds the drum (module docs).
    pub fn build(&self) -> Result<Built> {
        let r = self.grain_radius;
        let (cell, volume) = grains("drum", self.spheres, r)?;
        let triangles = 2 * self.sides as u64 * self.rings as u64;
        if self.sides < 3 || self.rings < 1 || triangles > MAX_TRIANGLES {
            return Err(refused(
                "drum",
                format!(
                    "drum_sides must be at least 3 and drum_rings at least 1, with 2·sides·rings \
                     at most {MAX_TRIANGLES} triangles; got {} sides and {} rings",
                    self.sides, self.rings
                ),
            ));
        }
        // Radius 12 lattice cells at the corners of its polygon; the length holds the spheres
        // at 40% of the polygon's area. The spheres start inside the circle the sides touch.
        let radius = 12.0 * cell;
        let sides = self.sides as f64;
        let inradius = radius * (std::f64::consts::PI / sides).cos();
        let area = 0.5 * sides * radius * radius * (std::f64::consts::TAU / sides).sin();
        let length = (volume / (0.4 * area)).max(3.0 * cell);
        let inside = |c: [f64; 3]| c[0].hypot(c[2]) < inradius - cell / 2.0;
        let lo = [-radius, -length / 2.0, -radius];
        let hi = [radius, length / 2.0, radius];
        let spheres = lattice(self.spheres, self.seed, r, cell, [lo, hi], inside)?;
        let rings = self.rings;
        let profile: Vec<(f64, f64)> = (0..=rings)
            .map(|j| (radius, -length / 2.0 + length * j as f64 / rings as f64))
            .collect();
        let tube = revolution(&profile, self.sides);
        let config = WallConfig {
            rotate: Some(Rotation {
                axis: [1.0, 0.0, 0.0],
                degrees: 90.0,
            }),
            omega: Some(self.omega),
            axis: Some([0.0, 1.0, 0.0]),
            ..WallConfig::of("drum (generated)")
        };
        let margin = 0.05 * radius;
        Ok(Built {
            spheres,
            box_lo: [-radius - margin, -length / 2.0, -radius - margin],
            box_hi: [radius + margin, length / 2.0, radius + margin],
            walls: vec![(config, tube)],
            outflows: Vec::new(),
            velocity: [0.0; 3],
        })
    }
}

/// `n` spheres of mean radius `r` (from `seed`) on the lattice of spacing `cell` in
/// `lo..hi`, lowest layers first, at the points `inside` keeps, each jittered within its cell.
fn lattice(
    n: usize,
    seed: u64,
    r: f64,
    cell: f64,
    [lo, hi]: [[f64; 3]; 2],
    inside: impl Fn([f64; 3]) -> bool,
) -> Result<SphereSet> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let counts: [usize; 3] = std::array::from_fn(|a| ((hi[a] - lo[a]) / cell).floor() as usize);
    let what = || format!("{} spheres", n);
    let mut centers = try_vec(n, what)?;
    let mut radii = try_vec(n, what)?;
    let room = 0.5 * cell - 1.1 * r;
    'fill: for k in 0..counts[2] {
        for j in 0..counts[1] {
            for i in 0..counts[0] {
                if centers.len() == n {
                    break 'fill;
                }
                let at = [i, j, k].map(|x| x as f64 + 0.5);
                let c: [f64; 3] = std::array::from_fn(|a| lo[a] + at[a] * cell);
                if !inside(c) {
                    continue;
                }
                let c = c.map(|x| (x + rng.random_range(-room..=room)) as f32);
                centers.push(c);
                radii.push((r * rng.random_range(0.9..=1.1)) as f32);
            }
        }
    }
    if centers.len() < n {
        return Err(Error::InvalidConfig {
            what: "scene".into(),
            reason: format!(
                "only {} of the {} spheres fit in the equipment",
                centers.len(),
                n
            ),
        });
    }
    SphereSet::new(centers, radii)
}

/// The steady mass flow rate \[kg/s\] of a discharge given as (time, mass out so far) samples:
/// the slope of the line fitted by least squares to the samples between 20% and 80% of the
/// final mass out (where the flow is steady: the start-up and the last grains left out).
/// `None` with fewer than three such samples.
pub fn mass_flow_rate(samples: &[(f64, f64)]) -> Option<f64> {
    let total = samples.last()?.1;
    let steady: Vec<(f64, f64)> = samples
        .iter()
        .copied()
        .filter(|&(_, m)| m >= 0.2 * total && m <= 0.8 * total)
        .collect();
    slope(&steady)
}

/// The angle \[°\] of a drum's free surface to the horizontal: the surface's height (the top of
/// the highest sphere) in 10 bins across the middle 60% of the spheres' extent in x, and the
/// slope of the line fitted to them. `None` with fewer than three bins holding spheres.
pub fn free_surface_angle(positions: &[[f32; 3]], radii: &[f32]) -> Option<f64> {
    let (lo, hi) = positions
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), c| (l.min(c[0]), h.max(c[0])));
    let (from, width) = (lo + 0.2 * (hi - lo), 0.6 * (hi - lo));
    let mut top = [f32::MIN; 10];
    for (c, r) in positions.iter().zip(radii) {
        let bin = ((c[0] - from) / width * 10.0).floor();
        if (0.0..10.0).contains(&bin) {
            let t = &mut top[bin as usize];
            *t = t.max(c[2] + r);
        }
    }
    let points: Vec<(f64, f64)> = (0..10)
        .filter(|&b| top[b] > f32::MIN)
        .map(|b| {
            (
                (from + (b as f32 + 0.5) * width / 10.0) as f64,
                top[b] as f64,
            )
        })
        .collect();
    slope(&points).map(|s| s.atan().to_degrees().abs())
}

/// The least-squares slope of `points`; `None` for fewer than three or no spread in x.
fn slope(points: &[(f64, f64)]) -> Option<f64> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxx: f64 = points.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_discharge_and_a_tilted_surface_are_measured() {
        // 2 kg/s after a start-up, then a tail.
        let mut samples = vec![(0.0, 0.0), (0.1, 0.01)];
        samples.extend((1..=20).map(|k| (0.1 + 0.05 * k as f64, 0.01 + 0.1 * k as f64)));
        samples.push((2.0, 2.02));
        let w = mass_flow_rate(&samples).unwrap();
        assert!((w - 2.0).abs() < 1e-9, "{w}");
        // Spheres whose tops lie on a line at 30°.
        let t = 30f64.to_radians().tan();
        let positions: Vec<[f32; 3]> = (0..100)
            .map(|k| {
                let x = -0.05 + 0.001 * k as f64;
                [x as f32, 0.0, (x * t) as f32]
            })
            .collect();
        let angle = free_surface_angle(&positions, &vec![0.0; 100]).unwrap();
        assert!((angle - 30.0).abs() < 0.5, "{angle}");
    }
}
