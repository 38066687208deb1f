//! The paper's datasets (docs/method.md, "The paper's workloads") and the default DEM scene, `pour`,
//! generated from a seed: the same seed gives the same spheres.
//!
//! Two layouts: `lattice` (the default) puts each sphere at a random place inside its own cell of
//! a lattice, shrunk by its radius, so no two spheres overlap (a DEM start state); `random`
//! places centres uniformly, overlaps included (a collision-detection workload).

use crate::error::{Error, Result, try_vec};
use crate::spheres::{SphereSet, check_count};
use glam::DVec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use std::array::from_fn;
use std::f64::consts::PI;

/// A named scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Scene {
    /// Paper dataset 1: radii U[0.0005, 0.0006] filling the unit cube.
    Freefall,
    /// Radii U[0.0005, 0.0006] on a lattice of spacing 2.2·r_max: a dense slab centred in the
    /// lower part of the unit box (from z = 0.1), about 2.7 layers deep and as wide as that
    /// takes, at most 0.8 (reached at a million spheres).
    Slab,
    /// Paper dataset 2, r_max/r_min = 1.2: radii U[0.0005, 0.0006] in a 16-unit cube.
    #[cfg_attr(feature = "clap", value(name = "poly1.2"))]
    Poly1_2,
    /// Paper dataset 2, r_max/r_min = 12: radii U[0.0005, 0.006] in a 16-unit cube.
    Poly12,
    /// Paper dataset 2, r_max/r_min = 120: radii U[0.0005, 0.06] in a 16-unit cube.
    Poly120,
    /// Log-uniform radii over [0.0005, 0.06]: as many small spheres per octave as large ones.
    /// `random` packs them at a solid fraction of about 0.6 (counting overlaps) in a cube sized
    /// for `n`; `lattice` stacks them without overlaps in layers of like-sized spheres (each
    /// layer a square lattice of spacing 2.1·its largest radius, the layers in random order)
    /// filling the lower part of a cube only about twice the volume of the pile they pour into.
    Polylog,
    /// A polydisperse pour onto a floor (the default DEM scene): radii U[0.003, 0.006] in a
    /// loose column of layers of like-sized spheres (as `polylog`'s, 2.1·the layer's largest
    /// radius apart, in random order) standing on the middle of the floor, about half as tall
    /// as it is wide; it collapses and spreads into a heap. The column's width grows with
    /// n^(1/3) (0.2 m at 4,000 spheres) and the box is 4 times as wide.
    Pour,
}

/// Width of the `pour` column at [`POUR_SPHERES`] spheres \[m\].
const POUR_WIDTH: f64 = 0.2;
/// The number of spheres the `pour` column is [`POUR_WIDTH`] wide for.
const POUR_SPHERES: f64 = 4000.0;
/// Side of the `pour` box over the column's width.
const POUR_BOX: f64 = 4.0;

/// Height of the underside of the `slab` lattice over the box's side.
pub const SLAB_BASE: f64 = 0.1;

/// Where the centres go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    /// Jittered lattice, no overlaps.
    #[default]
    Lattice,
    /// Uniformly random centres, overlaps allowed.
    Random,
}

crate::names::named!(Layout { Lattice => "lattice", Random => "random" });

/// Everything that determines a generated sphere set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SceneSpec {
    /// Which scene.
    pub scene: Scene,
    /// Number of spheres.
    pub n: usize,
    /// Seed of the random generator.
    pub seed: u64,
    /// Placement of the centres.
    pub layout: Layout,
}

crate::names::named!(Scene {
    Freefall => "freefall",
    Slab => "slab",
    Poly1_2 => "poly1.2",
    Poly12 => "poly12",
    Poly120 => "poly120",
    Polylog => "polylog",
    Pour => "pour",
});

impl Scene {
    /// Range of the uniformly distributed radii \[m\].
    pub fn radius_range(self) -> (f32, f32) {
        match self {
            Scene::Freefall | Scene::Slab | Scene::Poly1_2 => (0.0005, 0.0006),
            Scene::Poly12 => (0.0005, 0.006),
            Scene::Pour => (0.003, 0.006),
            Scene::Poly120 | Scene::Polylog => (0.0005, 0.06),
        }
    }

    /// Side of the cubic box the scene lives in \[m\] (`polylog`'s depends on n and the layout).
    pub fn box_side(self, n: usize, layout: Layout) -> f64 {
        match self {
            Scene::Freefall | Scene::Slab => 1.0,
            Scene::Poly1_2 | Scene::Poly12 | Scene::Poly120 => 16.0,
            Scene::Pour => POUR_BOX * pour_width(n),
            Scene::Polylog => match layout {
                Layout::Random => (n as f64 * self.mean_volume() / 0.6).cbrt(),
                // Twice the volume of the spheres' own layer cells (2.1·r)³; for up to a
                // thousand spheres, room for a cubic lattice of largest-sphere cells, so that
                // few spheres never run out of layers.
                Layout::Lattice => {
                    let cell = LAYER_SPACING.powi(3) * self.mean_volume() / (4.0 / 3.0 * PI);
                    let few = cube_root_ceil(n.min(1000)) as f64;
                    (2.0 * n as f64 * cell)
                        .cbrt()
                        .max(LAYER_SPACING * 1.01 * self.radius_range().1 as f64 * few)
                }
            },
        }
    }

    /// Whether radii are log-uniform (else uniform) over [`Self::radius_range`].
    fn log_uniform(self) -> bool {
        self == Scene::Polylog
    }

    /// Mean sphere volume of the radius distribution \[m³\].
    fn mean_volume(self) -> f64 {
        let (a, b) = self.radius_range();
        let (a, b) = (a as f64, b as f64);
        let mean_r3 = if self.log_uniform() {
            (b.powi(3) - a.powi(3)) / (3.0 * (b / a).ln())
        } else {
            (b.powi(4) - a.powi(4)) / (4.0 * (b - a))
        };
        4.0 / 3.0 * std::f64::consts::PI * mean_r3
    }

    /// One radius drawn from the scene's distribution.
    fn sample_radius(self, rng: &mut Pcg64) -> f32 {
        let (a, b) = self.radius_range();
        if self.log_uniform() {
            let t: f32 = rng.random_range(0.0..=1.0);
            (a * (b / a).powf(t)).clamp(a, b)
        } else {
            rng.random_range(a..=b)
        }
    }
}

/// Lattice spacing of a `polylog` or `pour` layer over its largest radius.
const LAYER_SPACING: f64 = 2.1;

/// Width of the `pour` column of `n` spheres \[m\]: [`POUR_WIDTH`] at [`POUR_SPHERES`], as
/// n^(1/3), and at least four cells of the largest spheres.
fn pour_width(n: usize) -> f64 {
    let r_max = Scene::Pour.radius_range().1 as f64;
    (POUR_WIDTH * (n as f64 / POUR_SPHERES).cbrt()).max(4.0 * LAYER_SPACING * r_max)
}

/// Generates the spheres of `spec`.
pub fn generate(spec: &SceneSpec) -> Result<SphereSet> {
    check_count(spec.n)?;
    if spec.layout == Layout::Lattice {
        match spec.scene {
            Scene::Polylog => return layered(spec, Scene::Polylog.box_side(spec.n, spec.layout)),
            Scene::Pour => return layered(spec, pour_width(spec.n)),
            _ => {}
        }
    }
    let r_max = spec.scene.radius_range().1;
    let lattice = Lattice::plan(spec.scene, spec.n, spec.layout)?;
    if spec.layout == Layout::Lattice && lattice.spacing < 2.0 * r_max as f64 {
        let fit = lattice.capacity_at_spacing(2.0 * r_max as f64);
        return Err(Error::TooLarge {
            what: format!("spheres in a non-overlapping {} lattice", spec.scene.name()),
            got: spec.n as u64,
            limit: fit,
        });
    }
    let mut rng = Pcg64::seed_from_u64(spec.seed);
    let mut centers = try_vec(spec.n, || spheres_of(spec))?;
    let mut radii = try_vec(spec.n, || spheres_of(spec))?;
    for k in 0..spec.n {
        let r = spec.scene.sample_radius(&mut rng);
        // Per axis x, then y, then z: the order the seed's draws are taken in.
        let c = match spec.layout {
            Layout::Lattice => {
                let room = lattice.spacing / 2.0 - r as f64;
                lattice.cell(k) + DVec3::from_array(from_fn(|_| rng.random_range(-room..=room)))
            }
            Layout::Random => {
                let (lo, hi) = (lattice.lo + r as f64, lattice.hi() - r as f64);
                DVec3::from_array(from_fn(|a| rng.random_range(lo[a]..=hi[a])))
            }
        };
        centers.push(c.as_vec3().to_array());
        radii.push(r);
    }
    SphereSet::new(centers, radii)
}

/// What the generated arrays hold, for an out-of-memory error.
fn spheres_of(spec: &SceneSpec) -> String {
    format!("{} spheres of scene {}", spec.n, spec.scene.name())
}

/// The lattice layout of `polylog` and `pour`: radii sorted, cut into layers that each fill a
/// square lattice of spacing 2.1·(their largest radius) across `width` (`polylog`: the box from
/// its corner; `pour`: a column centred on the floor), stacked from the floor in a seeded random
/// order, every sphere jittered inside its own cell. No two spheres overlap: within a layer cells
/// are wider than the diameters, and layers are as far apart as their largest radii need.
fn layered(spec: &SceneSpec, width: f64) -> Result<SphereSet> {
    let side = spec.scene.box_side(spec.n, Layout::Lattice);
    let mut rng = Pcg64::seed_from_u64(spec.seed);
    let mut radii: Vec<f32> = try_vec(spec.n, || spheres_of(spec))?;
    radii.extend((0..spec.n).map(|_| spec.scene.sample_radius(&mut rng)));
    radii.sort_unstable_by(|a, b| b.total_cmp(a));
    // Layers of like-sized spheres: each takes as many as its lattice holds.
    let mut layers: Vec<std::ops::Range<usize>> = Vec::new();
    let mut start = 0;
    while start < radii.len() {
        let spacing = LAYER_SPACING * radii[start] as f64;
        let per_row = ((width / spacing) as usize).max(1);
        let end = (start + per_row * per_row).min(radii.len());
        layers.push(start..end);
        start = end;
    }
    // Shuffle the layers (Fisher–Yates), so sizes mix as the pile pours.
    for k in (1..layers.len()).rev() {
        let j = rng.random_range(0..=k);
        layers.swap(k, j);
    }
    let mut centers = try_vec(spec.n, || spheres_of(spec))?;
    let mut out_radii = try_vec(spec.n, || spheres_of(spec))?;
    let mut z = 0.0f64;
    let mut below = 0.0f64; // largest radius of the layer below (none under the first)
    for layer in &layers {
        let top = radii[layer.start] as f64;
        let spacing = LAYER_SPACING * top;
        z += below + top * 1.05;
        if z + top > side {
            return Err(Error::TooLarge {
                what: format!(
                    "spheres in the {} layers (the box is full)",
                    spec.scene.name()
                ),
                got: spec.n as u64,
                limit: centers.len() as u64,
            });
        }
        let per_row = ((width / spacing) as usize).max(1);
        // `pour` centres each layer on the floor; `polylog`'s fill the box from its corner.
        let edge = match spec.scene {
            Scene::Pour => (side - per_row as f64 * spacing) / 2.0,
            _ => 0.0,
        };
        for (k, &r) in radii[layer.clone()].iter().enumerate() {
            let room = (spacing / 2.0 - r as f64).max(0.0);
            let (ix, iy) = (k % per_row, k / per_row);
            let c = DVec3::new(
                edge + (ix as f64 + 0.5) * spacing + rng.random_range(-room..=room),
                edge + (iy as f64 + 0.5) * spacing + rng.random_range(-room..=room),
                z,
            );
            centers.push(c.as_vec3().to_array());
            out_radii.push(r);
        }
        below = top;
    }
    SphereSet::new(centers, out_radii)
}

/// The smallest m with m³ ≥ n (at least 1).
fn cube_root_ceil(n: usize) -> usize {
    let mut m = (n as f64).cbrt().round().max(1.0) as usize;
    while m * m * m < n {
        m += 1;
    }
    m
}

/// A box of lattice cells that the spheres fill in x, then y, then z order.
struct Lattice {
    lo: DVec3,
    spacing: f64,
    counts: [usize; 3],
    side: f64,
}

impl Lattice {
    fn plan(scene: Scene, n: usize, layout: Layout) -> Result<Self> {
        let side = scene.box_side(n, layout);
        if scene == Scene::Slab {
            let spacing = 2.2 * scene.radius_range().1 as f64;
            // At most 0.8 wide, narrower for fewer spheres so there are always about 2.7
            // layers (a million spheres fill the 0.8 × 0.8 square).
            let per_row = ((0.8 * side / spacing) as usize)
                .min((n as f64 / 2.7).sqrt().ceil() as usize)
                .max(1);
            let width = per_row as f64 * spacing;
            let layers = n.div_ceil(per_row * per_row).max(1);
            let edge = (side - width) / 2.0;
            let lo = DVec3::new(edge, edge, SLAB_BASE * side);
            let fit_layers = ((side - lo.z) / spacing) as usize;
            if layers > fit_layers {
                return Err(Error::TooLarge {
                    what: "spheres in the slab scene".into(),
                    got: n as u64,
                    limit: (fit_layers * per_row * per_row) as u64,
                });
            }
            return Ok(Self {
                lo,
                spacing,
                counts: [per_row, per_row, layers],
                side: width,
            });
        }
        let m = cube_root_ceil(n);
        Ok(Self {
            lo: DVec3::ZERO,
            spacing: side / m as f64,
            counts: [m, m, m],
            side,
        })
    }

    /// Centre of the cell of sphere `k`.
    fn cell(&self, k: usize) -> DVec3 {
        let [nx, ny, _] = self.counts;
        let index = [k % nx, (k / nx) % ny, k / (nx * ny)].map(|i| i as f64);
        self.lo + (DVec3::from(index) + 0.5) * self.spacing
    }

    /// Upper corner of the filled box.
    fn hi(&self) -> DVec3 {
        self.lo + DVec3::from(self.counts.map(|c| c as f64)) * self.spacing
    }

    /// How many spheres a cubic lattice of this side holds at `spacing`.
    fn capacity_at_spacing(&self, spacing: f64) -> u64 {
        ((self.side / spacing) as u64).pow(3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oracle::brute_force_pairs;

    fn spec(scene: Scene, n: usize, layout: Layout) -> SceneSpec {
        SceneSpec {
            scene,
            n,
            seed: 7,
            layout,
        }
    }

    #[test]
    fn no_scene_is_too_coarse_for_f32() {
        use crate::names::Named;
        for &scene in Scene::ALL {
            for layout in [Layout::Lattice, Layout::Random] {
                let s = generate(&spec(scene, 20_000, layout)).unwrap();
                let warning = crate::spheres::coarse_coordinates(s.centers(), s.radii());
                assert_eq!(warning, None, "{scene:?} {layout:?}");
            }
        }
    }

    #[test]
    fn lattice_scenes_never_overlap_and_stay_in_their_box() {
        for scene in [
            Scene::Freefall,
            Scene::Slab,
            Scene::Poly12,
            Scene::Poly120,
            Scene::Polylog,
            Scene::Pour,
        ] {
            let s = generate(&spec(scene, 3000, Layout::Lattice)).unwrap();
            assert_eq!(s.len(), 3000);
            assert!(brute_force_pairs(&s).is_empty(), "{scene:?} overlaps");
            let (r_min, r_max) = scene.radius_range();
            assert!(s.min_radius() >= r_min && s.max_radius() <= r_max);
            let side = scene.box_side(3000, Layout::Lattice) as f32;
            for (c, r) in s.centers().iter().zip(s.radii()) {
                assert!(
                    c.iter().all(|&x| x - r >= 0.0 && x + r <= side),
                    "{scene:?}"
                );
            }
        }
    }

    #[test]
    fn the_polylog_pour_starts_dense_and_mixed() {
        let s = generate(&spec(Scene::Polylog, 20_000, Layout::Lattice)).unwrap();
        let side = Scene::Polylog.box_side(20_000, Layout::Lattice);
        let top = s
            .centers()
            .iter()
            .zip(s.radii())
            .map(|(c, r)| c[2] + r)
            .fold(0.0, f32::max);
        let solid: f64 = s
            .radii()
            .iter()
            .map(|&r| 4.0 / 3.0 * PI * (r as f64).powi(3))
            .sum();
        let fraction = solid / (side * side * top as f64);
        assert!(
            fraction > 0.2,
            "solid fraction of the start column {fraction}"
        );
        assert!(
            (top as f64) < 0.8 * side,
            "the column must leave room above it"
        );
        // Layers in random order: the largest sphere is not always at the bottom.
        let heaviest = s
            .radii()
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap()
            .0;
        assert!(s.centers()[heaviest][2] > 2.0 * s.max_radius());
    }

    #[test]
    fn the_pour_column_stands_on_the_middle_of_the_floor() {
        let s = generate(&spec(Scene::Pour, 4000, Layout::Lattice)).unwrap();
        let side = Scene::Pour.box_side(4000, Layout::Lattice);
        assert!((side - 0.8).abs() < 1e-9, "{side}");
        let (lo, hi) = s.bounds().unwrap();
        for a in 0..2 {
            let (from, to) = (lo[a] as f64, hi[a] as f64);
            assert!(to - from <= POUR_WIDTH, "axis {a}: {from}..{to}");
            assert!(
                ((from + to) / 2.0 - side / 2.0).abs() < 0.01,
                "axis {a} centred"
            );
        }
        // On the floor, and about half as tall as wide.
        let bottom = (0..s.len())
            .map(|k| s.centers()[k][2] - s.radii()[k])
            .fold(f32::INFINITY, f32::min);
        assert!((0.0..0.001).contains(&bottom), "{bottom}");
        assert!(
            (0.3..0.7).contains(&((hi[2] as f64) / POUR_WIDTH)),
            "{hi:?}"
        );
    }

    #[test]
    fn same_seed_same_spheres() {
        let a = generate(&spec(Scene::Poly120, 500, Layout::Random)).unwrap();
        let b = generate(&spec(Scene::Poly120, 500, Layout::Random)).unwrap();
        let c = generate(&SceneSpec {
            seed: 8,
            ..spec(Scene::Poly120, 500, Layout::Random)
        });
        assert_eq!(a, b);
        assert_ne!(a, c.unwrap());
    }

    #[test]
    fn too_many_spheres_for_a_lattice_is_an_error() {
        let e = generate(&spec(Scene::Poly120, 2_400_000, Layout::Lattice)).unwrap_err();
        assert!(
            matches!(e, Error::TooLarge { limit, .. } if limit == 133u64.pow(3)),
            "{e}"
        );
    }
}
