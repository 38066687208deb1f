//! The pinhole camera: where it stands, what it looks at, and the rays of each pixel.

use crate::error::{Error, Result};
use glam::{DVec3, Vec3};

/// World "up" of every default view: +z (gravity points along -z in the built-in scenes).
const UP: DVec3 = DVec3::Z;

/// The default viewing direction, from the target towards the eye: a 3/4 view from the front
/// left, 33° above the horizon.
const VIEW_FROM: DVec3 = DVec3::new(-0.55, -1.0, 0.75);

/// A region less tall than this share of its horizontal extent (a heap, a layer) is seen from
/// [`LOW_ELEVATION_DEG`] above the horizon rather than along [`VIEW_FROM`]: from 33°, a heap
/// whose slopes are gentler than that shows as a disc; from low, its outline shows its height
/// and its slopes.
const FLAT_SHARE: f64 = 0.5;

/// The elevation of the view of a flat region \[degrees\] (the azimuth is [`VIEW_FROM`]'s).
const LOW_ELEVATION_DEG: f64 = 12.0;

/// Space left around the framed region: its projection spans at most `1 / FIT_MARGIN` of the
/// picture's width or height.
const FIT_MARGIN: f64 = 1.06;

/// Largest image side in pixels.
pub const MAX_SIDE: u32 = 8192;

/// A perspective camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position \[m\].
    pub eye: [f64; 3],
    /// The point at the centre of the picture \[m\].
    pub look_at: [f64; 3],
    /// Vertical field of view \[degrees\], in (0, 180) (default: 40).
    pub fov_deg: f64,
}

/// Default vertical field of view \[degrees\].
pub const DEFAULT_FOV_DEG: f64 = 40.0;

/// [`Error::InvalidConfig`] of the camera.
fn camera_error(reason: String) -> Error {
    Error::InvalidConfig {
        what: "camera".into(),
        reason,
    }
}

impl Camera {
    /// The default view of the box `lo..hi`: from the front left, 33° above the horizon, or
    /// 12° where the box is less than half as tall as it is wide (a heap, a layer); the box's projection is centred and fills the picture of aspect
    /// `width / height` but for a margin (every corner inside).
    pub fn framing(lo: [f64; 3], hi: [f64; 3], aspect: f64, fov_deg: f64) -> Camera {
        let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
        let forward = -unit(view_from(lo, hi));
        let right = unit(forward.cross(UP));
        let up = right.cross(forward);
        let tan_v = (0.5 * fov_deg.to_radians()).tan() / FIT_MARGIN;
        let tan_h = tan_v * aspect;
        let corners: [DVec3; 8] = std::array::from_fn(|k| {
            DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        });
        // The eye never enters the box's bounding sphere: every corner lies ahead of it.
        let radius = 0.5 * (hi - lo).length().max(f64::MIN_POSITIVE);
        let mut target = 0.5 * (lo + hi);
        let mut distance = radius;
        // Each round: the nearest distance at which every corner fits (around `target`), then
        // `target` moved across the view so that the corners' projection is centred. A few
        // rounds settle it to well under a pixel.
        for _ in 0..6 {
            distance = corners.iter().fold(1.02 * radius, |d, &p| {
                let rel = p - target;
                let depth = rel.dot(forward);
                let across = rel.dot(right).abs() / tan_h - depth;
                let along = rel.dot(up).abs() / tan_v - depth;
                d.max(across).max(along)
            });
            let eye = target - distance * forward;
            let (mut x, mut y) = (
                (f64::INFINITY, f64::NEG_INFINITY),
                (f64::INFINITY, f64::NEG_INFINITY),
            );
            for &p in &corners {
                let rel = p - eye;
                let depth = rel.dot(forward);
                let (px, py) = (rel.dot(right) / depth, rel.dot(up) / depth);
                x = (x.0.min(px), x.1.max(px));
                y = (y.0.min(py), y.1.max(py));
            }
            target += distance * (0.5 * (x.0 + x.1) * right + 0.5 * (y.0 + y.1) * up);
        }
        Camera {
            eye: (target - distance * forward).to_array(),
            look_at: target.to_array(),
            fov_deg,
        }
    }

    /// Checks that the camera can form a picture.
    pub fn validate(&self) -> Result<()> {
        // The field of view first: the default eye stands at a distance derived from it.
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            return Err(camera_error(format!(
                "field of view {}° is not in (0, 180)",
                self.fov_deg
            )));
        }
        let finite = self.eye.iter().chain(&self.look_at).all(|x| x.is_finite());
        if !finite {
            return Err(camera_error("eye and look-at must be finite".into()));
        }
        if DVec3::from(self.look_at).distance(DVec3::from(self.eye)) == 0.0 {
            return Err(camera_error("eye and look-at coincide".into()));
        }
        Ok(())
    }

    /// The pixel grid of a `width`×`height` picture: ray `(x, y)` (pixel units, y down) has the
    /// direction `corner + x·right + y·down` from the eye.
    pub(crate) fn grid(&self, width: u32, height: u32) -> Grid {
        let eye = DVec3::from(self.eye);
        let forward = unit(DVec3::from(self.look_at) - eye);
        // Looking straight up or down: take +y as the picture's up instead.
        let up = if forward.cross(UP).abs().max_element() < 1e-9 {
            DVec3::Y
        } else {
            UP
        };
        let right = unit(forward.cross(up));
        let true_up = right.cross(forward);
        let pixel = 2.0 * (0.5 * self.fov_deg.to_radians()).tan() / height as f64;
        let (w, h) = (width as f64, height as f64);
        let corner = forward - 0.5 * w * pixel * right + 0.5 * h * pixel * true_up;
        Grid {
            eye: eye.as_vec3(),
            corner: corner.as_vec3(),
            right: (right * pixel).as_vec3(),
            down: (-true_up * pixel).as_vec3(),
            // Key light from the upper left, slightly behind the viewer.
            light: unit(0.8 * up - 0.5 * right - 0.4 * forward).as_vec3(),
        }
    }
}

/// The direction the default view of the box `lo..hi` looks from (towards the eye, not of
/// unit length): [`VIEW_FROM`], or as low as [`LOW_ELEVATION_DEG`] above the horizon for a
/// box less tall than half its larger horizontal side.
fn view_from(lo: DVec3, hi: DVec3) -> DVec3 {
    let size = hi - lo;
    if size.z < FLAT_SHARE * size.x.max(size.y) {
        let level = unit(DVec3::new(VIEW_FROM.x, VIEW_FROM.y, 0.0));
        let up = LOW_ELEVATION_DEG.to_radians();
        level * up.cos() + UP * up.sin()
    } else {
        VIEW_FROM
    }
}

/// `v` scaled to unit length by dividing each component by the length (not multiplying by its
/// reciprocal, as `DVec3::normalize` does: the rays stay bit for bit what they were).
fn unit(v: DVec3) -> DVec3 {
    v / v.length()
}

/// A camera's pixel grid in `f32`, as the shaders get it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Grid {
    pub eye: Vec3,
    pub corner: Vec3,
    pub right: Vec3,
    pub down: Vec3,
    /// Unit vector towards the (directional) light.
    pub light: Vec3,
}

/// Parses `WxH` (e.g. `960x720`) into an image size, each side in 1..=[`MAX_SIDE`].
pub fn parse_size(text: &str) -> Result<(u32, u32)> {
    let bad = || Error::InvalidConfig {
        what: format!("size {text:?}"),
        reason: "expected WxH such as 960x720".into(),
    };
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    check_size(w, h)?;
    Ok((w, h))
}

/// Checks an image size: each side in 1..=[`MAX_SIDE`].
pub fn check_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
        return Err(Error::InvalidConfig {
            what: format!("image size {width}x{height}"),
            reason: format!("each side must be in 1..={MAX_SIDE}"),
        });
    }
    Ok(())
}

/// Parses `x,y,z` into a point.
pub fn parse_point(text: &str) -> Result<[f64; 3]> {
    let bad = || Error::InvalidConfig {
        what: format!("point {text:?}"),
        reason: "expected x,y,z such as 0.5,-1,2".into(),
    };
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(bad)?;
    <[f64; 3]>::try_from(values).map_err(|_| bad())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_ray_points_at_the_target() {
        let cam = Camera {
            eye: [0.0, -5.0, 0.0],
            look_at: [0.0; 3],
            fov_deg: 40.0,
        };
        let g = cam.grid(4, 2);
        let d = g.corner + 2.0 * g.right + 1.0 * g.down;
        assert!(d.x.abs() < 1e-6 && d.z.abs() < 1e-6 && d.y > 0.99, "{d:?}");
    }

    #[test]
    fn sizes_and_points_parse_or_fail() {
        assert_eq!(parse_size("960x720").unwrap(), (960, 720));
        assert!(parse_size("0x5").is_err() && parse_size("abc").is_err());
        assert!(parse_size("9000x10").is_err());
        assert_eq!(parse_point("1,2.5,-3").unwrap(), [1.0, 2.5, -3.0]);
        assert!(parse_point("1,2").is_err() && parse_point("1,x,2").is_err());
    }

    #[test]
    fn a_field_of_view_out_of_range_is_named_as_such() {
        for fov in [0.0, 180.0, -5.0, f64::NAN] {
            let e = Camera::framing([0.0; 3], [1.0; 3], 4.0 / 3.0, fov)
                .validate()
                .unwrap_err()
                .to_string();
            assert!(e.contains("field of view"), "{fov}: {e}");
        }
    }

    /// Where `p` falls in the picture of `cam` (`width`×`height`), in pixels.
    fn project(cam: &Camera, width: u32, height: u32, p: DVec3) -> (f64, f64) {
        let g = cam.grid(width, height);
        let (corner, right, down) = (g.corner.as_dvec3(), g.right.as_dvec3(), g.down.as_dvec3());
        let d = p - DVec3::from(cam.eye);
        // d = s·(corner + x·right + y·down): solve the 3×3 system.
        let m = glam::DMat3::from_cols(right, down, corner);
        let xyz = m.inverse() * d;
        (xyz.x / xyz.z, xyz.y / xyz.z)
    }

    /// The elevation of the view \[degrees\].
    fn elevation(cam: &Camera) -> f64 {
        let d = DVec3::from(cam.eye) - DVec3::from(cam.look_at);
        (d.z / d.length()).asin().to_degrees()
    }

    #[test]
    fn the_framing_fits_the_box_into_the_picture_centred() {
        let (w, h) = (400, 300);
        for (lo, hi) in [
            ([0.0; 3], [1.0; 3]),
            ([-0.2, -0.1, 0.0], [0.2, 0.1, 0.05]),
            ([0.0, 0.0, -3.0], [0.5, 0.5, 1.0]),
        ] {
            let cam = Camera::framing(lo, hi, w as f64 / h as f64, 40.0);
            let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
            let (mut x, mut y) = ((f64::MAX, f64::MIN), (f64::MAX, f64::MIN));
            for k in 0..8 {
                let p = DVec3::select(glam::BVec3::new(k & 1 == 0, k & 2 == 0, k & 4 == 0), lo, hi);
                let (px, py) = project(&cam, w, h, p);
                x = (x.0.min(px), x.1.max(px));
                y = (y.0.min(py), y.1.max(py));
            }
            let msg = format!("{lo}..{hi}: x {x:?}, y {y:?}");
            assert!(
                x.0 >= 0.0 && x.1 <= w as f64 && y.0 >= 0.0 && y.1 <= h as f64,
                "{msg}"
            );
            // Centred, and filling the picture's width or height but for the margin.
            assert!(
                (x.0 + x.1 - w as f64).abs() < 1.0 && (y.0 + y.1 - h as f64).abs() < 1.0,
                "{msg}"
            );
            let fill = ((x.1 - x.0) / w as f64).max((y.1 - y.0) / h as f64);
            assert!(fill > 0.9, "{msg}: {fill}");
        }
    }

    #[test]
    fn a_flat_region_is_seen_from_low_and_a_tall_one_from_above() {
        let heap = Camera::framing([-0.2, -0.2, 0.0], [0.2, 0.2, 0.08], 4.0 / 3.0, 40.0);
        let column = Camera::framing([-0.1, -0.1, 0.0], [0.1, 0.1, 0.4], 4.0 / 3.0, 40.0);
        let cube = Camera::framing([0.0; 3], [1.0; 3], 4.0 / 3.0, 40.0);
        assert!(
            (elevation(&heap) - LOW_ELEVATION_DEG).abs() < 1e-9,
            "{}",
            elevation(&heap)
        );
        for cam in [column, cube] {
            assert!((elevation(&cam) - 33.3).abs() < 0.1, "{}", elevation(&cam));
        }
        // Both from the front left.
        for cam in [heap, cube] {
            let d = DVec3::from(cam.eye) - DVec3::from(cam.look_at);
            assert!(d.x < 0.0 && d.y < 0.0 && d.y < 1.5 * d.x, "{d}");
        }
    }
}
