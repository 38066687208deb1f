//! Colour by a per-sphere value: the quantity ([`ColorBy`]), its range, and the viridis colour
//! map (perceptually uniform, readable in grey and by most colour-blind viewers).

use super::shade::pack;

/// What a sphere's colour shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ColorBy {
    /// The radius, in m.
    #[default]
    Radius,
    /// The speed |v|, in m/s.
    Speed,
    /// The material's index (0 for every sphere of a run of one material).
    Material,
}

impl ColorBy {
    /// The legend's label, with the unit.
    pub fn label(self) -> &'static str {
        match self {
            ColorBy::Radius => "radius [m]",
            ColorBy::Speed => "speed [m/s]",
            ColorBy::Material => "material",
        }
    }

    /// The value of each sphere: its radius, its speed (`velocities` may be empty for spheres
    /// at rest) or its material (`materials` may be empty for one material).
    pub fn values(self, radii: &[f32], velocities: &[[f32; 3]], materials: &[u8]) -> Vec<f32> {
        match self {
            ColorBy::Radius => radii.to_vec(),
            ColorBy::Material if materials.is_empty() => vec![0.0; radii.len()],
            ColorBy::Material => materials.iter().map(|&m| f32::from(m)).collect(),
            ColorBy::Speed if velocities.is_empty() => vec![0.0; radii.len()],
            ColorBy::Speed => velocities
                .iter()
                .map(|&v| glam::Vec3::from(v).length())
                .collect(),
        }
    }
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
    fn ranges_skip_non_finite_values() {
        assert_eq!(value_range(&[2.0, f32::NAN, -1.0]), (-1.0, 2.0));
        assert_eq!(value_range(&[]), (0.0, 0.0));
        assert_eq!(unit(5.0, (1.0, 1.0)), 0.5);
    }
}
