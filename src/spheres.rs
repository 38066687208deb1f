//! Validated sphere sets and the pairs reported for them.

use crate::error::{Error, Result, try_vec};
use rayon::prelude::*;

/// Largest magnitude accepted for a coordinate or a radius.
///
/// Squared distances are computed in `f32`; with every input below this bound they stay finite
/// (3·(2·10¹⁸)² ≈ 1.2·10³⁷ < `f32::MAX`), so no comparison ever sees an infinity.
pub const MAX_MAGNITUDE: f32 = 1e18;

/// Smallest radius accepted: 10⁻¹² (a picometre in SI units).
///
/// The rule ([`crate::proxy::within`]) compares plain `f32` squares. From this radius up every
/// threshold's square is a normal number (at least 4·10⁻²⁴), so a square that underflows, or
/// that a GPU flushes to zero, counts for less than 2^-70 of it and changes no decision. Smaller
/// radii (10⁻³⁰, say) would put the squares of whole gaps below `f32`'s range and report spheres
/// 10⁵ radii apart as touching.
pub const MIN_RADIUS: f32 = 1e-12;

/// Largest number of spheres in one set: indices are `u32` on every backend.
pub const MAX_SPHERES: usize = u32::MAX as usize;

/// Spheres one rayon task checks at least (fewer tasks would cost more than the checks).
const CHECKS_PER_TASK: usize = 4096;

/// A set of spheres whose every centre and radius has been checked.
///
/// Centres are finite with |x| ≤ [`MAX_MAGNITUDE`]; radii are finite, in
/// [[`MIN_RADIUS`], [`MAX_MAGNITUDE`]].
/// Units are whatever the caller uses (SI metres in the scenes).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SphereSet {
    centers: Vec<[f32; 3]>,
    radii: Vec<f32>,
    /// The radii's range and the centres' bounds, found in the checking pass.
    found: Found,
}

/// The bounds of a set of centres, lowest then highest corner.
pub(crate) type Bounds = ([f32; 3], [f32; 3]);

/// What one pass over (part of) a set finds: the first bad sphere, if any, the centres'
/// bounds and the radii's range. Parts surveyed apart (centres checked piece by piece while
/// they are copied elsewhere) are merged in order.
#[derive(Debug, Clone)]
pub(crate) struct Survey {
    bad: Option<(usize, String)>,
    lo: [f32; 3],
    hi: [f32; 3],
    radii: (f32, f32),
}

impl Survey {
    pub(crate) fn empty() -> Self {
        Survey {
            bad: None,
            lo: [f32::INFINITY; 3],
            hi: [f32::NEG_INFINITY; 3],
            radii: (f32::INFINITY, 0.0),
        }
    }

    /// Adds sphere `index` (centre `c`, radius `r`; `None`: radii not surveyed).
    fn add(mut self, index: usize, c: &[f32; 3], r: Option<f32>) -> Self {
        if self.bad.is_some() {
            return self;
        }
        let checked = match r {
            Some(r) => check_sphere(c, r),
            None => check_center(c),
        };
        if let Err(reason) = checked {
            self.bad = Some((index, reason));
            return self;
        }
        self.lo = std::array::from_fn(|a| self.lo[a].min(c[a]));
        self.hi = std::array::from_fn(|a| self.hi[a].max(c[a]));
        if let Some(r) = r {
            self.radii = (self.radii.0.min(r), self.radii.1.max(r));
        }
        self
    }

    /// The centres `centers` alone (radii not surveyed), the first numbered `first`.
    pub(crate) fn of_centers(first: usize, centers: &[[f32; 3]]) -> Self {
        Survey::of_part(first, centers, None)
    }

    /// The spheres of `centers` and `radii` (where given, as many), the first numbered
    /// `first`: one pass without branches for the common case (every coordinate within
    /// ±[`MAX_MAGNITUDE`] and every radius within [[`MIN_RADIUS`], [`MAX_MAGNITUDE`]], which no
    /// NaN is), and sphere by sphere again for the first bad one where it fails.
    fn of_part(first: usize, centers: &[[f32; 3]], radii: Option<&[f32]>) -> Self {
        let (within_centres, lo, hi) = centre_extent(centers);
        let (within_radii, range) = radius_extent(radii.unwrap_or_default());
        if within_centres && within_radii {
            return Survey {
                bad: None,
                lo,
                hi,
                radii: range,
            };
        }
        centers
            .iter()
            .enumerate()
            .fold(Survey::empty(), |acc, (i, c)| {
                acc.add(first + i, c, radii.map(|r| r[i]))
            })
    }

    /// Both parts' findings, `self` the earlier: its bad sphere first.
    pub(crate) fn merge(self, later: Survey) -> Self {
        Survey {
            bad: self.bad.or(later.bad),
            lo: std::array::from_fn(|a| self.lo[a].min(later.lo[a])),
            hi: std::array::from_fn(|a| self.hi[a].max(later.hi[a])),
            radii: (
                self.radii.0.min(later.radii.0),
                self.radii.1.max(later.radii.1),
            ),
        }
    }

    /// The first bad sphere as an error, else the bounds of `n` centres.
    pub(crate) fn into_bounds(self, n: usize) -> Result<Option<Bounds>> {
        match self.bad {
            Some((index, reason)) => Err(Error::InvalidSphere { index, reason }),
            None => Ok((n > 0).then_some((self.lo, self.hi))),
        }
    }
}

/// Coordinates the fast survey takes at once: four centres, in lanes the compiler keeps in
/// vector registers.
const CENTRE_LANES: usize = 12;

/// The smaller of `a` and `b` as one vector instruction computes it (`b` where either is NaN):
/// the fast survey's min, exact wherever its `within` flag holds (no NaN met).
#[inline(always)]
fn lane_min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// The larger of `a` and `b` (`b` where either is NaN), as [`lane_min`].
#[inline(always)]
fn lane_max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// Whether every coordinate of `centers` is within ±[`MAX_MAGNITUDE`] (false for a NaN), and,
/// where it is, their bounds: one pass without branches over the coordinates as a flat run,
/// four centres at a time in [`CENTRE_LANES`] lanes.
fn centre_extent(centers: &[[f32; 3]]) -> (bool, [f32; 3], [f32; 3]) {
    let flat = centers.as_flattened();
    let (blocks, rest) = flat.as_chunks::<CENTRE_LANES>();
    let mut lo = [f32::INFINITY; CENTRE_LANES];
    let mut hi = [f32::NEG_INFINITY; CENTRE_LANES];
    let mut within = [true; CENTRE_LANES];
    for block in blocks {
        for k in 0..CENTRE_LANES {
            let x = block[k];
            within[k] &= x.abs() <= MAX_MAGNITUDE;
            lo[k] = lane_min(x, lo[k]);
            hi[k] = lane_max(x, hi[k]);
        }
    }
    for (k, &x) in rest.iter().enumerate() {
        within[k] &= x.abs() <= MAX_MAGNITUDE;
        lo[k] = lane_min(x, lo[k]);
        hi[k] = lane_max(x, hi[k]);
    }
    let axis = |lanes: &[f32; CENTRE_LANES], a: usize, pick: fn(f32, f32) -> f32| {
        lanes
            .iter()
            .skip(a)
            .step_by(3)
            .fold(lanes[a], |m, &x| pick(x, m))
    };
    (
        within.iter().all(|&w| w),
        std::array::from_fn(|a| axis(&lo, a, lane_min)),
        std::array::from_fn(|a| axis(&hi, a, lane_max)),
    )
}

/// Whether every radius is within [[`MIN_RADIUS`], [`MAX_MAGNITUDE`]] (false for a NaN), and,
/// where they are, their range (smallest, largest; `(∞, 0)` for none), as [`centre_extent`].
fn radius_extent(radii: &[f32]) -> (bool, (f32, f32)) {
    const LANES: usize = 8;
    let (blocks, rest) = radii.as_chunks::<LANES>();
    let mut lo = [f32::INFINITY; LANES];
    let mut hi = [0.0f32; LANES];
    let mut within = [true; LANES];
    let mut take = |k: usize, r: f32| {
        within[k] &= (MIN_RADIUS..=MAX_MAGNITUDE).contains(&r);
        lo[k] = lane_min(r, lo[k]);
        hi[k] = lane_max(r, hi[k]);
    };
    for block in blocks {
        for (k, &r) in block.iter().enumerate() {
            take(k, r);
        }
    }
    for (k, &r) in rest.iter().enumerate() {
        take(k, r);
    }
    (
        within.iter().all(|&w| w),
        (
            lo.iter().fold(f32::INFINITY, |m, &x| lane_min(x, m)),
            hi.iter().fold(0.0, |m, &x| lane_max(x, m)),
        ),
    )
}

/// The bounds of `centers` (`None` for none), found on the rayon pool; the first centre that is
/// not finite or beyond [`MAX_MAGNITUDE`] as an error.
pub(crate) fn center_bounds(centers: &[[f32; 3]]) -> Result<Option<Bounds>> {
    survey(centers, None).into_bounds(centers.len())
}

/// Surveys `centers` (and `radii`, where given) in one pass on the rayon pool; the bad sphere
/// reported is the first in order, as a loop would find it.
fn survey(centers: &[[f32; 3]], radii: Option<&[f32]>) -> Survey {
    let pieces = centers.par_chunks(CHECKS_PER_TASK).enumerate();
    let first = |k: usize| k * CHECKS_PER_TASK;
    match radii {
        None => pieces
            .map(|(k, piece)| Survey::of_part(first(k), piece, None))
            .reduce(Survey::empty, Survey::merge),
        Some(radii) => pieces
            .zip(radii.par_chunks(CHECKS_PER_TASK))
            .map(|((k, piece), r)| Survey::of_part(first(k), piece, Some(r)))
            .reduce(Survey::empty, Survey::merge),
    }
}

/// What checking a set of spheres finds: the radii's range (0, 0 for none) and the centres'
/// bounds (`None` for none).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Found {
    min_radius: f32,
    max_radius: f32,
    bounds: Option<Bounds>,
}

impl Found {
    /// Checks `centers` and `radii` (as many, at most [`MAX_SPHERES`]) on the rayon pool.
    fn check(centers: &[[f32; 3]], radii: &[f32]) -> Result<Self> {
        if centers.len() != radii.len() {
            return Err(Error::Usage(format!(
                "{} centres but {} radii",
                centers.len(),
                radii.len()
            )));
        }
        check_count(centers.len())?;
        let found = survey(centers, Some(radii));
        let (min_radius, max_radius) = found.radii;
        Ok(Found {
            min_radius: if radii.is_empty() { 0.0 } else { min_radius },
            max_radius,
            bounds: found.into_bounds(centers.len())?,
        })
    }
}

/// Spheres checked where they lie: borrowed centres and radii with what checking them found,
/// as a [`SphereSet`] holds them. What a backend builds over; a caller whose spheres are in
/// its own memory (a NumPy array, a mapped file) checks them there and copies them once, into
/// the backend.
#[derive(Debug, Clone, Copy)]
pub struct Spheres<'a> {
    centers: &'a [[f32; 3]],
    radii: &'a [f32],
    found: Found,
}

impl<'a> Spheres<'a> {
    /// Checks `centers` and `radii` (same length) as [`SphereSet::new`] does.
    pub fn check(centers: &'a [[f32; 3]], radii: &'a [f32]) -> Result<Self> {
        let found = Found::check(centers, radii)?;
        Ok(Spheres {
            centers,
            radii,
            found,
        })
    }

    /// A set of its own: the spheres copied (no second check).
    pub fn to_set(&self) -> Result<SphereSet> {
        self.to_set_in(Default::default())
    }

    /// [`Self::to_set`] into the allocations `room` (those of [`SphereSet::into_parts`], say,
    /// grown fallibly where too small): a caller that copies sets again and again takes no
    /// fresh memory.
    pub fn to_set_in(&self, room: (Vec<[f32; 3]>, Vec<f32>)) -> Result<SphereSet> {
        let (mut centers, mut radii) = room;
        let n = self.len();
        let out_of_memory = || Error::OutOfMemory {
            what: format!("{n} spheres"),
            bytes: (n as u64).saturating_mul(16),
        };
        centers.clear();
        radii.clear();
        centers.try_reserve_exact(n).map_err(|_| out_of_memory())?;
        radii.try_reserve_exact(n).map_err(|_| out_of_memory())?;
        centers.par_extend(self.centers.par_iter().copied());
        radii.par_extend(self.radii.par_iter().copied());
        Ok(SphereSet {
            centers,
            radii,
            found: self.found,
        })
    }

    /// Number of spheres.
    pub fn len(&self) -> usize {
        self.radii.len()
    }

    /// True when there is no sphere.
    pub fn is_empty(&self) -> bool {
        self.radii.is_empty()
    }

    /// Centres, in input order.
    pub fn centers(&self) -> &'a [[f32; 3]] {
        self.centers
    }

    /// Radii, in input order.
    pub fn radii(&self) -> &'a [f32] {
        self.radii
    }

    /// Largest radius (0 for no spheres).
    pub fn max_radius(&self) -> f32 {
        self.found.max_radius
    }

    /// Smallest radius (0 for no spheres).
    pub fn min_radius(&self) -> f32 {
        self.found.min_radius
    }

    /// Component-wise bounds `(lo, hi)` of the centres; `None` for no spheres.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        self.found.bounds
    }

    /// Rows `[x, y, z, r]`, in input order.
    pub fn xyzr(&self) -> impl ExactSizeIterator<Item = [f32; 4]> + use<'a> {
        self.centers
            .iter()
            .zip(self.radii)
            .map(|(c, &r)| [c[0], c[1], c[2], r])
    }
}

impl<'a> From<&'a SphereSet> for Spheres<'a> {
    fn from(set: &'a SphereSet) -> Self {
        set.view()
    }
}

impl SphereSet {
    /// Checks and wraps centres and radii (same length).
    pub fn new(centers: Vec<[f32; 3]>, radii: Vec<f32>) -> Result<Self> {
        let found = Found::check(&centers, &radii)?;
        Ok(Self {
            centers,
            radii,
            found,
        })
    }

    /// The set as [`Spheres`], for a backend to build over.
    pub fn view(&self) -> Spheres<'_> {
        Spheres {
            centers: &self.centers,
            radii: &self.radii,
            found: self.found,
        }
    }

    /// Builds a set from rows `[x, y, z, r]`.
    pub fn from_xyzr(rows: &[[f32; 4]]) -> Result<Self> {
        check_count(rows.len())?;
        let what = || format!("{} spheres", rows.len());
        let mut centers = try_vec(rows.len(), what)?;
        let mut radii = try_vec(rows.len(), what)?;
        centers.extend(rows.iter().map(|s| [s[0], s[1], s[2]]));
        radii.extend(rows.iter().map(|s| s[3]));
        Self::new(centers, radii)
    }

    /// Number of spheres.
    pub fn len(&self) -> usize {
        self.radii.len()
    }

    /// True when the set holds no sphere.
    pub fn is_empty(&self) -> bool {
        self.radii.is_empty()
    }

    /// Centres, in input order.
    pub fn centers(&self) -> &[[f32; 3]] {
        &self.centers
    }

    /// Radii, in input order.
    pub fn radii(&self) -> &[f32] {
        &self.radii
    }

    /// Largest radius (0 for an empty set).
    pub fn max_radius(&self) -> f32 {
        self.found.max_radius
    }

    /// Smallest radius (0 for an empty set).
    pub fn min_radius(&self) -> f32 {
        self.found.min_radius
    }

    /// Component-wise bounds `(lo, hi)` of the centres; `None` for an empty set (found when
    /// the centres were checked).
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        self.found.bounds
    }

    /// Moves the spheres: replaces every centre, keeping the radii (refused centres leave the
    /// set as it was).
    pub fn set_centers(&mut self, centers: Vec<[f32; 3]>) -> Result<()> {
        if centers.len() != self.len() {
            return Err(Error::Usage(format!(
                "{} new centres for {} spheres",
                centers.len(),
                self.len()
            )));
        }
        self.found.bounds = survey(&centers, None).into_bounds(centers.len())?;
        self.centers = centers;
        Ok(())
    }

    /// [`Self::set_centers`] from borrowed centres, copied into the set's own (no allocation:
    /// a caller moving the spheres every step touches no fresh memory).
    pub fn copy_centers_from(&mut self, centers: &[[f32; 3]]) -> Result<()> {
        if centers.len() != self.len() {
            return Err(Error::Usage(format!(
                "{} new centres for {} spheres",
                centers.len(),
                self.len()
            )));
        }
        self.found.bounds = survey(centers, None).into_bounds(centers.len())?;
        self.centers
            .par_iter_mut()
            .with_min_len(CHECKS_PER_TASK)
            .zip(centers)
            .for_each(|(to, from)| *to = *from);
        Ok(())
    }

    /// The centres and radii, for their allocations to be filled again.
    pub fn into_parts(self) -> (Vec<[f32; 3]>, Vec<f32>) {
        (self.centers, self.radii)
    }

    /// Rows `[x, y, z, r]`, in input order.
    pub fn xyzr(&self) -> impl ExactSizeIterator<Item = [f32; 4]> + '_ {
        self.view().xyzr()
    }
}

/// Refuses more than [`MAX_SPHERES`] spheres.
pub fn check_count(n: usize) -> Result<()> {
    match n <= MAX_SPHERES {
        true => Ok(()),
        false => Err(Error::TooLarge {
            what: "number of spheres".into(),
            got: n as u64,
            limit: MAX_SPHERES as u64,
        }),
    }
}

fn check_center(c: &[f32; 3]) -> Result<(), String> {
    for (axis, &x) in ["x", "y", "z"].iter().zip(c) {
        if !x.is_finite() {
            return Err(format!("{axis} is {x}, not a finite number"));
        }
        if x.abs() > MAX_MAGNITUDE {
            return Err(format!(
                "{axis} = {} exceeds ±{MAX_MAGNITUDE:e}",
                crate::numbers::shown(x)
            ));
        }
    }
    Ok(())
}

/// Checks one sphere; the message names the problem (not the sphere).
pub(crate) fn check_sphere(c: &[f32; 3], r: f32) -> Result<(), String> {
    check_center(c)?;
    if !r.is_finite() {
        return Err(format!("radius is {r}, not a finite number"));
    }
    if r <= 0.0 {
        return Err(format!("radius must be > 0 (got {r})"));
    }
    if r < MIN_RADIUS {
        return Err(format!(
            "radius {r:e} is below the smallest radius, {MIN_RADIUS:e}"
        ));
    }
    if r > MAX_MAGNITUDE {
        return Err(format!(
            "radius {} exceeds {MAX_MAGNITUDE:e}",
            crate::numbers::shown(r)
        ));
    }
    Ok(())
}

/// Coarsest `f32` spacing of a centre coordinate, as a fraction of its sphere's radius, that
/// [`coarse_coordinates`] accepts without a warning: 2^-6.
///
/// Centres are held in `f32`; near |x| the representable values lie ulp(x) apart (2^-23·|x| or
/// so), so a centre read from a finer file moves by up to half that, and every distance the rule
/// computes carries errors of that size. Above this bound a pair within a few hundredths of a
/// radius of touching may be decided either way (and a DEM contact's overlap, typically about a
/// hundredth of a radius, is lost in rounding); the exactness guarantees hold for the `f32`
/// values, not for the file's digits. The built-in scenes stay far below it (the 16-unit cube of
/// `poly120` with radii from 0.0005 at 2^-8 of a radius).
pub const MAX_SPACING_PER_RADIUS: f32 = 1.0 / 64.0;

/// A warning (one line, naming the first such sphere and how many there are) when the `f32`
/// spacing of some centre coordinate exceeds [`MAX_SPACING_PER_RADIUS`] of its radius: the
/// input's coordinates are too large for `f32` to place spheres of its radii; `None` otherwise.
pub fn coarse_coordinates(centers: &[[f32; 3]], radii: &[f32]) -> Option<String> {
    let spacing = |x: f32| x.abs().next_up() - x.abs();
    let coarse = |(c, &r): (&[f32; 3], &f32)| {
        let axis = (0..3).max_by(|&a, &b| c[a].abs().total_cmp(&c[b].abs()))?;
        (spacing(c[axis]) > r * MAX_SPACING_PER_RADIUS).then_some((axis, c[axis], r))
    };
    let mut rows = centers.iter().zip(radii).enumerate();
    let (index, (axis, x, r)) = rows.find_map(|(k, row)| Some((k, coarse(row)?)))?;
    let more = rows.filter(|(_, row)| coarse(*row).is_some()).count();
    Some(format!(
        "sphere {index} (0-based): {} = {x:e} is held in 32-bit floats only to within {:e}, \
         more than 1/{} of its radius {r:e} ({more} more spheres like it): pairs that close \
         to touching may be decided either way",
        ["x", "y", "z"][axis],
        spacing(x),
        MAX_SPACING_PER_RADIUS.recip()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_spheres_with_their_index() {
        let ok = [0.0, 0.0, 0.0];
        let cases = [
            (
                vec![ok, [f32::NAN, 0.0, 0.0]],
                vec![1.0, 1.0],
                1,
                "not a finite",
            ),
            (vec![ok, ok], vec![1.0, f32::INFINITY], 1, "not a finite"),
            (vec![ok], vec![0.0], 0, "> 0"),
            (vec![ok], vec![-1.0], 0, "> 0"),
            (vec![[2e18, 0.0, 0.0]], vec![1.0], 0, "exceeds"),
            (vec![ok, ok], vec![1.0, 9e-31], 1, "smallest radius"),
        ];
        for (centers, radii, want_index, want_text) in cases {
            match SphereSet::new(centers, radii) {
                Err(Error::InvalidSphere { index, reason }) => {
                    assert_eq!(index, want_index);
                    assert!(reason.contains(want_text), "{reason}");
                }
                other => panic!("expected InvalidSphere, got {other:?}"),
            }
        }
    }

    #[test]
    fn coordinates_too_coarse_for_the_radii_are_named() {
        // 1e17 is held to within 2^33: far more than a radius of 1.
        let centers = [
            [0.0, 0.0, 0.0],
            [1e17, 0.0, 0.0],
            [0.0, -3e16, 0.0],
            [5.0; 3],
        ];
        let radii = [1.0, 1.0, 1.0, 1e-3];
        let warning = coarse_coordinates(&centers, &radii).expect("a warning");
        assert!(
            warning.starts_with("sphere 1 (0-based): x = 1e17"),
            "{warning}"
        );
        assert!(warning.contains("(1 more spheres"), "{warning}");
        assert!(warning.contains("8.589935e9"), "{warning}");
        // At the bound: 1024 has spacing 2^-13 = 2^-6 of a radius 2^-7, and is accepted.
        assert_eq!(
            coarse_coordinates(&[[1024.0, 0.0, -1.0]], &[0.0078125]),
            None
        );
        let warning = coarse_coordinates(&[[1.0, 0.0, -1024.0]], &[0.0078]).expect("a warning");
        assert!(
            warning.contains("more than 1/64 of its radius"),
            "{warning}"
        );
        assert!(warning.contains("z = -1.024e3"), "{warning}");
        assert_eq!(coarse_coordinates(&centers[..1], &radii[..1]), None);
    }

    #[test]
    fn bounds_and_radius_range_are_the_plain_ones_for_every_length() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        for n in (1..40).chain([4095, 4096, 4097, 100_003]) {
            let centers: Vec<[f32; 3]> = (0..n)
                .map(|_| std::array::from_fn(|_| rng.random_range(-5.0..5.0)))
                .collect();
            let radii: Vec<f32> = (0..n).map(|_| rng.random_range(1e-3..2.0)).collect();
            let lo = std::array::from_fn(|a| centers.iter().map(|c| c[a]).fold(f32::MAX, f32::min));
            let hi = std::array::from_fn(|a| centers.iter().map(|c| c[a]).fold(f32::MIN, f32::max));
            let (r_min, r_max) = radii
                .iter()
                .fold((f32::MAX, 0.0f32), |(a, b), &r| (a.min(r), b.max(r)));
            let set = SphereSet::new(centers, radii).unwrap();
            assert_eq!(set.bounds(), Some((lo, hi)), "{n} spheres");
            assert_eq!(
                (set.min_radius(), set.max_radius()),
                (r_min, r_max),
                "{n} spheres"
            );
        }
    }

    #[test]
    fn tracks_radius_range_and_moves() {
        let mut s = SphereSet::new(vec![[0.0; 3], [1.0; 3]], vec![0.5, 2.0]).unwrap();
        assert_eq!((s.min_radius(), s.max_radius()), (0.5, 2.0));
        assert_eq!(s.bounds(), Some(([0.0; 3], [1.0; 3])));
        assert!(s.set_centers(vec![[0.0; 3]]).is_err());
        let refused = s.set_centers(vec![[0.0; 3], [f32::NAN; 3]]).unwrap_err();
        assert!(refused.to_string().contains("sphere 1"), "{refused}");
        // A refused move leaves the set as it was.
        assert_eq!(s.centers(), [[0.0; 3], [1.0; 3]]);
        assert_eq!(s.bounds(), Some(([0.0; 3], [1.0; 3])));
        s.set_centers(vec![[3.0; 3], [-4.0, 4.0, 4.0]]).unwrap();
        assert_eq!(s.centers()[1], [-4.0, 4.0, 4.0]);
        assert_eq!(s.bounds(), Some(([-4.0, 3.0, 3.0], [3.0, 4.0, 4.0])));
        // Borrowed centres likewise: refused ones change nothing, accepted ones are copied.
        assert!(s.copy_centers_from(&[[0.0; 3]]).is_err());
        let refused = s.copy_centers_from(&[[1e30, 0.0, 0.0], [0.0; 3]]);
        assert!(refused.unwrap_err().to_string().contains("sphere 0"));
        assert_eq!(s.centers(), [[3.0; 3], [-4.0, 4.0, 4.0]]);
        assert_eq!(s.bounds(), Some(([-4.0, 3.0, 3.0], [3.0, 4.0, 4.0])));
        let many: Vec<[f32; 3]> = (0..10_000).map(|k| [k as f32, 0.0, -(k as f32)]).collect();
        let mut big = SphereSet::new(vec![[0.0; 3]; many.len()], vec![1.0; many.len()]).unwrap();
        big.copy_centers_from(&many).unwrap();
        assert_eq!(big.centers(), many);
        assert_eq!(
            big.bounds(),
            Some(([0.0, 0.0, -9999.0], [9999.0, 0.0, 0.0]))
        );
        assert_eq!(SphereSet::default().bounds(), None);
        assert_eq!(SphereSet::default().max_radius(), 0.0);
        let empty = SphereSet::new(Vec::new(), Vec::new()).unwrap();
        assert_eq!((empty.min_radius(), empty.max_radius()), (0.0, 0.0));
        assert!(SphereSet::new(vec![[0.0; 3]], vec![MIN_RADIUS]).is_ok());
    }

    #[test]
    fn borrowed_spheres_are_checked_as_a_set_and_copied_into_one_unchanged() {
        let centers = [[0.0; 3], [2.0, -1.0, 0.5], [1.0; 3]];
        let radii = [0.5, 0.25, 1.5];
        let set = SphereSet::new(centers.to_vec(), radii.to_vec()).unwrap();
        let view = Spheres::check(&centers, &radii).unwrap();
        assert_eq!(view.bounds(), set.bounds());
        assert_eq!((view.min_radius(), view.max_radius()), (0.25, 1.5));
        assert_eq!(
            view.xyzr().collect::<Vec<_>>(),
            set.xyzr().collect::<Vec<_>>()
        );
        assert_eq!(view.to_set().unwrap(), set);
        // Into larger and smaller allocations alike, which it keeps.
        let room = (vec![[9.0; 3]; 10], Vec::with_capacity(1));
        let copied = view.to_set_in(room).unwrap();
        assert_eq!(copied, set);
        assert!(copied.into_parts().0.capacity() >= 10);
        assert_eq!(set.view().to_set().unwrap(), set);
        // The set's refusals, word for word.
        let bad = [[0.0; 3], [0.0, f32::NAN, 0.0], [1.0; 3]];
        let refused = Spheres::check(&bad, &radii).unwrap_err().to_string();
        let by_set = SphereSet::new(bad.to_vec(), radii.to_vec()).unwrap_err();
        assert_eq!(refused, by_set.to_string());
        assert!(refused.contains("sphere 1"), "{refused}");
        let short = Spheres::check(&centers, &radii[1..]).unwrap_err();
        assert!(
            short.to_string().contains("3 centres but 2 radii"),
            "{short}"
        );
        let empty = Spheres::check(&[], &[]).unwrap();
        assert_eq!(
            (empty.len(), empty.bounds(), empty.max_radius()),
            (0, None, 0.0)
        );
    }
}
