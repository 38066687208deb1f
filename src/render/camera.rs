//! The pinhole camera: where it stands, what it looks at, and the rays of each pixel.

use crate::error::{Error, Result};
use glam::{DVec3, Vec3};

/// World "up" of every default view: +z (gravity points along -z in the built-in scenes).
const UP: DVec3 = DVec3::Z;

/// The default viewing direction, from the target towards the eye: a 3/4 view from the front
/// left, above.
const VIEW_FROM: DVec3 = DVec3::new(-0.55, -1.0, 0.75);

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
    /// The default 3/4 view of the box `lo..hi`, from the front left and above, far enough that
    /// the box's bounding sphere fits the picture of aspect `width / height`.
    pub fn framing(lo: [f64; 3], hi: [f64; 3], aspect: f64, fov_deg: f64) -> Camera {
        let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
        let center = 0.5 * (lo + hi);
        let radius = 0.5 * (hi - lo).length().max(f64::MIN_POSITIVE);
        let half_v = 0.5 * fov_deg.to_radians();
        let half_h = (half_v.tan() * aspect.min(1.0)).atan();
        let distance = 1.02 * radius / half_v.min(half_h).sin();
        let dir = unit(VIEW_FROM);
        Camera {
            eye: (center + distance * dir).to_array(),
            look_at: center.to_array(),
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

    #[test]
    fn the_framing_sees_the_whole_box() {
        let cam = Camera::framing([0.0; 3], [1.0; 3], 4.0 / 3.0, 40.0);
        let d = DVec3::from(cam.eye).distance(DVec3::from(cam.look_at));
        assert!(d > 0.5 * 3f64.sqrt() / 20f64.to_radians().sin());
        assert_eq!(cam.look_at, [0.5; 3]);
    }
}
