//! Colour by a per-sphere value: the quantity ([`ColorBy`], or the one `auto` picks for a frame,
//! [`ColorChoice`]), its range, and the viridis colour map (perceptually uniform, readable in
//! grey and by most colour-blind viewers).

use super::shade::pack;

/// What a sphere's colour shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColorBy {
    /// The radius, in m.
    Radius,
    /// The speed |v|, in m/s.
    Speed,
    /// The height of the centre, z, in m.
    Height,
    /// The material's index (0 for every sphere of a run of one material).
    Material,
    /// The contacts a sphere holds (the frame's `contacts`, of a run with contact history:
    /// bonds show where cohesion holds spheres together; 0 for a frame without them).
    Contacts,
}

/// The values of a frame's spheres a colouring reads (each one per sphere, or empty where the
/// frame has none).
#[derive(Debug, Clone, Copy, Default)]
pub struct SphereValues<'a> {
    /// Centres \[m\].
    pub positions: &'a [[f32; 3]],
    /// Radii \[m\].
    pub radii: &'a [f32],
    /// Velocities \[m/s\] (empty: at rest).
    pub velocities: &'a [[f32; 3]],
    /// Materials (empty: one material).
    pub materials: &'a [u8],
    /// Contacts held (empty: none known).
    pub contacts: &'a [u32],
}

impl ColorBy {
    /// Every quantity.
    pub const ALL: [ColorBy; 5] = [
        ColorBy::Radius,
        ColorBy::Speed,
        ColorBy::Height,
        ColorBy::Material,
        ColorBy::Contacts,
    ];

    /// The legend's label, with the unit.
    pub fn label(self) -> &'static str {
        match self {
            ColorBy::Radius => "radius [m]",
            ColorBy::Speed => "speed [m/s]",
            ColorBy::Height => "height [m]",
            ColorBy::Material => "material",
            ColorBy::Contacts => "contacts",
        }
    }

    /// The value of each sphere of `s`: its radius, its speed, the height of its centre, its
    /// material or its contacts (0 where `s` has none of those).
    pub fn values(self, s: &SphereValues<'_>) -> Vec<f32> {
        let n = s.radii.len();
        match self {
            ColorBy::Radius => s.radii.to_vec(),
            ColorBy::Height => s.positions.iter().map(|p| p[2]).collect(),
            ColorBy::Material if s.materials.is_empty() => vec![0.0; n],
            ColorBy::Material => s.materials.iter().map(|&m| f32::from(m)).collect(),
            ColorBy::Contacts if s.contacts.is_empty() => vec![0.0; n],
            ColorBy::Contacts => s.contacts.iter().map(|&c| c as f32).collect(),
            ColorBy::Speed if s.velocities.is_empty() => vec![0.0; n],
            ColorBy::Speed => s
                .velocities
                .iter()
                .map(|&v| glam::Vec3::from(v).length())
                .collect(),
        }
    }
}

impl ColorBy {
    /// The range of the colour map for `values` of this quantity: their own (see
    /// [`value_range`]), but for speeds from 0 to the 95th percentile: at rest is always the
    /// map's bottom, and the few fastest (a stream, a sphere in flight) take its top rather
    /// than leaving every slower one in its bottom colours.
    pub fn range(self, values: &[f32]) -> (f32, f32) {
        let (lo, hi) = value_range(values);
        if self != ColorBy::Speed {
            return (lo, hi);
        }
        let mut finite: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
        let Some(last) = finite.len().checked_sub(1) else {
            return (0.0, 0.0);
        };
        let at = (SPEED_TOP * last as f32).round() as usize;
        let top = *finite.select_nth_unstable_by(at, f32::total_cmp).1;
        // Where nineteen in twenty are at rest, the fastest set the top.
        (0.0, if top > 0.0 { top } else { hi.max(0.0) })
    }
}

/// The quantile of the speeds that the top of their colour map stands for.
const SPEED_TOP: f32 = 0.95;

/// What to colour the spheres by: one quantity, or `auto`, the one that tells most about a
/// frame ([`ColorChoice::resolve`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ColorChoice {
    /// The speed where walls move (a hopper's gate, a drum: the flow they drive) or the
    /// spheres do (a tenth of them faster than half the speed of a fall through their mean
    /// radius under 9.81 m/s²), else the radius where the radii differ more than 3:1, else the
    /// height.
    #[default]
    Auto,
    /// The radius, in m.
    Radius,
    /// The speed |v|, in m/s.
    Speed,
    /// The height of the centre, z, in m.
    Height,
    /// The material's index (0 for every sphere of a run of one material).
    Material,
    /// The contacts a sphere holds (frames of a run with contact history: bonds show).
    Contacts,
}

crate::names::named!(ColorChoice {
    Auto => "auto",
    Radius => "radius",
    Speed => "speed",
    Height => "height",
    Material => "material",
    Contacts => "contacts",
});

impl From<ColorBy> for ColorChoice {
    /// That quantity, chosen.
    fn from(color_by: ColorBy) -> Self {
        match color_by {
            ColorBy::Radius => ColorChoice::Radius,
            ColorBy::Speed => ColorChoice::Speed,
            ColorBy::Height => ColorChoice::Height,
            ColorBy::Material => ColorChoice::Material,
            ColorBy::Contacts => ColorChoice::Contacts,
        }
    }
}

/// `auto` colours by speed where a tenth of the spheres move faster than this share of
/// √(2·g·r̄), the speed of a fall through the mean radius r̄ (g = 9.81 m/s²): a collapse or a
/// flow, but not a heap whose last few spheres still roll away from its foot.
const MOVING_SHARE: f32 = 0.5;

/// `auto` colours by radius where the largest radius exceeds the smallest this many times
/// (and nothing moves): sizes that different are what tells the spheres apart.
const SIZES_APART: f32 = 3.0;

impl ColorChoice {
    /// The quantity: the one chosen, or for `auto` the one that tells most about spheres of
    /// `radii` moving at `velocities` (empty: at rest) among walls that move or not
    /// (`walls_move`): their speed where either moves (see [`ColorChoice::Auto`]), else their
    /// radius where it differs more than 3:1, else their height.
    pub fn resolve(self, radii: &[f32], velocities: &[[f32; 3]], walls_move: bool) -> ColorBy {
        match self {
            ColorChoice::Radius => ColorBy::Radius,
            ColorChoice::Speed => ColorBy::Speed,
            ColorChoice::Height => ColorBy::Height,
            ColorChoice::Material => ColorBy::Material,
            ColorChoice::Contacts => ColorBy::Contacts,
            ColorChoice::Auto if walls_move || moving(radii, velocities) => ColorBy::Speed,
            ColorChoice::Auto => {
                let (lo, hi) = value_range(radii);
                if hi > SIZES_APART * lo {
                    ColorBy::Radius
                } else {
                    ColorBy::Height
                }
            }
        }
    }
}

/// Whether a tenth of the spheres move faster than [`MOVING_SHARE`] of √(2·g·r̄).
fn moving(radii: &[f32], velocities: &[[f32; 3]]) -> bool {
    if velocities.is_empty() || radii.is_empty() {
        return false;
    }
    let mean = radii.iter().map(|&r| r as f64).sum::<f64>() / radii.len() as f64;
    let slow = MOVING_SHARE * (2.0 * 9.81 * mean as f32).sqrt();
    let fast = velocities
        .iter()
        .filter(|&&v| glam::Vec3::from(v).length() > slow)
        .count();
    10 * fast >= velocities.len()
}

/// The smallest and largest finite value, or `(0, 0)` when there is none.
pub fn value_range(values: &[f32]) -> (f32, f32) {
    let finite = values.iter().copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if lo <= hi { (lo, hi) } else { (0.0, 0.0) }
}

/// Viridis at nine evenly spaced stops (sRGB bytes), interpolated linearly in between.
const VIRIDIS: [[u8; 3]; 9] = [
    [0x44, 0x01, 0x54],
    [0x47, 0x2d, 0x7b],
    [0x3b, 0x52, 0x8b],
    [0x2c, 0x72, 0x8e],
    [0x21, 0x91, 0x8c],
    [0x28, 0xae, 0x80],
    [0x5e, 0xc9, 0x62],
    [0xad, 0xdc, 0x30],
    [0xfd, 0xe7, 0x25],
];

/// Viridis at `u` in [0, 1] (clamped; NaN is 0), as `[r, g, b]` in [0, 1].
pub fn viridis(u: f32) -> [f32; 3] {
    let u = if u.is_nan() { 0.0 } else { u.clamp(0.0, 1.0) };
    let x = u * (VIRIDIS.len() - 1) as f32;
    let k = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - k as f32;
    [0, 1, 2].map(|c| {
        let (a, b) = (VIRIDIS[k][c] as f32, VIRIDIS[k + 1][c] as f32);
        (a + (b - a) * f) / 255.0
    })
}

/// Where `value` falls in `range`, in [0, 1]; the middle for an empty range.
pub fn unit(value: f32, (lo, hi): (f32, f32)) -> f32 {
    if hi > lo {
        ((value - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.5
    }
}

/// Each value's colour, packed as the shaders read it.
pub(crate) fn colours(values: &[f32], range: (f32, f32)) -> Vec<u32> {
    values
        .iter()
        .map(|&v| pack(viridis(unit(v, range))))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_map_runs_from_purple_to_yellow() {
        let lo = viridis(0.0);
        let hi = viridis(1.0);
        assert!(lo[2] > lo[1] && hi[0] > 0.9 && hi[1] > 0.85);
        assert_eq!(viridis(f32::NAN), lo);
        assert_eq!(viridis(2.0), hi);
    }

    #[test]
    fn auto_colours_by_speed_where_things_move_else_by_radius_or_height() {
        // 100 spheres of mean radius 5 mm: √(2·g·r̄) = 0.31 m/s, half of it 0.157 m/s.
        let radii: Vec<f32> = (0..100).map(|k| 0.004 + 0.001 * (k % 3) as f32).collect();
        let creeping = vec![[0.0, 0.15, 0.0]; 100];
        let mut ten_roll = creeping.clone();
        for v in &mut ten_roll[40..50] {
            *v = [0.0, 0.0, -0.16];
        }
        let mut nine_roll = ten_roll.clone();
        nine_roll[40] = [0.0; 3];
        let auto = |r: &[f32], v: &[[f32; 3]]| ColorChoice::Auto.resolve(r, v, false);
        assert_eq!(auto(&radii, &creeping), ColorBy::Height);
        assert_eq!(auto(&radii, &nine_roll), ColorBy::Height);
        assert_eq!(auto(&radii, &ten_roll), ColorBy::Speed);
        assert_eq!(auto(&radii, &[]), ColorBy::Height);
        // Walls that move make it speed, whatever the spheres do.
        assert_eq!(ColorChoice::Auto.resolve(&radii, &[], true), ColorBy::Speed);
        let mut mixed = radii.clone();
        mixed[0] = 0.0015;
        assert_eq!(auto(&mixed, &creeping), ColorBy::Radius);
        assert_eq!(auto(&mixed, &ten_roll), ColorBy::Speed);
        assert_eq!(auto(&[], &[]), ColorBy::Height);
        // A quantity named is kept.
        for color_by in ColorBy::ALL {
            let chosen = ColorChoice::from(color_by);
            assert_eq!(chosen.resolve(&radii, &ten_roll, true), color_by);
        }
    }

    #[test]
    fn speeds_are_coloured_from_zero_to_their_95th_percentile() {
        let mut speeds: Vec<f32> = (0..100).map(|k| k as f32 / 100.0).collect();
        speeds.push(f32::NAN);
        assert_eq!(ColorBy::Speed.range(&speeds), (0.0, 0.94));
        assert_eq!(ColorBy::Height.range(&speeds), (0.0, 0.99));
        // Nearly all at rest: the fastest set the top.
        let mut resting = vec![0.0; 100];
        resting[7] = 0.5;
        assert_eq!(ColorBy::Speed.range(&resting), (0.0, 0.5));
        assert_eq!(ColorBy::Speed.range(&[]), (0.0, 0.0));
    }

    #[test]
    fn height_is_the_centres_z() {
        let spheres = SphereValues {
            positions: &[[1.0, 2.0, 3.0], [0.0, 0.0, -1.0]],
            radii: &[1.0; 2],
            ..SphereValues::default()
        };
        assert_eq!(ColorBy::Height.values(&spheres), [3.0, -1.0]);
        // Contacts where the frame has them, else none.
        assert_eq!(ColorBy::Contacts.values(&spheres), [0.0, 0.0]);
        let held = SphereValues {
            contacts: &[3, 0],
            ..spheres
        };
        assert_eq!(ColorBy::Contacts.values(&held), [3.0, 0.0]);
    }

    #[test]
    fn ranges_skip_non_finite_values() {
        assert_eq!(value_range(&[2.0, f32::NAN, -1.0]), (-1.0, 2.0));
        assert_eq!(value_range(&[]), (0.0, 0.0));
        assert_eq!(unit(5.0, (1.0, 1.0)), 0.5);
    }
}
