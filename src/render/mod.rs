//! Pictures of spheres: ray traced, headless, on the GPU or the CPU.
//!
//! A [`Scene`] holds the spheres with a colour each (by radius, speed, height or material,
//! [`ColorBy`], through the viridis map; [`ColorChoice::Auto`] picks one for a frame) and any
//! mesh walls' triangles ([`Scene::with_walls`]: a translucent skin, the nearest wall laid over
//! what lies behind it); a [`Picture`] says what to draw (size, [`Camera`] — by default
//! [`Camera::framing`] the region to show, from low for a heap —, samples per pixel, shadows);
//! a [`Renderer`] draws it into an [`Image`], which gets a colour [`Legend`] and a caption in
//! DejaVu Sans (embedded, anti-aliased) and is written as PNG (or collected into an animated
//! [`Gif`]).
//!
//! Three render paths give the same picture up to rounding. Each runs on the hardware of one
//! detection backend, whose name it takes, and is picked through the same registry
//! ([`RenderChoice::backend`]; [`RenderChoice::Auto`] says which it took and why it passed over
//! the others):
//!
//! | path | how |
//! | --- | --- |
//! | `wgpu-rq` | a BLAS of the spheres' boxes; a WGSL ray query per ray tests each candidate sphere and commits the nearest with `rayQueryGenerateIntersection` |
//! | `wgpu-compute` | our own BVH (Morton-ordered LBVH built on the CPU), traversed nearest child first in WGSL; any adapter (the NVIDIA H100 has no ray queries) |
//! | `cpu` | the same BVH and shading in Rust, one row per rayon task |
//!
//! Each pixel averages `samples`² camera rays; a hit is shaded with ambient, a soft headlight,
//! Lambert and Blinn–Phong terms of one directional light, and optionally a shadow ray towards
//! it. An optional floor (the simulation box's) is a grey checker that receives the spheres'
//! shadows. Misses show a light vertical gradient. The shaders are `wgsl/render_*.wgsl`; their CPU
//! twin is `shade.rs` and `bvh.rs` in this module.
//!
//! ```
//! use mochi::render::{Camera, ColorBy, Picture, RenderChoice, Renderer, Scene, SphereValues};
//! let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
//! let radii = [0.5, 0.3];
//! let spheres = SphereValues { positions: &positions, radii: &radii, ..Default::default() };
//! let values = ColorBy::Radius.values(&spheres);
//! let scene = Scene::new(&positions, &radii, &values, (0.3, 0.5))?;
//! let (lo, hi) = scene.bounds().expect("not empty");
//! let picture = Picture::new(64, 48, Camera::framing(lo, hi, 64.0 / 48.0, 40.0));
//! let (mut renderer, _why) = Renderer::open(RenderChoice::Cpu)?;
//! let image = renderer.render(&scene, &picture)?;
//! assert_eq!(image.pixels.len(), 64 * 48);
//! # Ok::<(), mochi::Error>(())
//! ```

mod bvh;
mod camera;
mod colour;
mod cpu;
mod font;
mod gpu;
mod image;
mod legend;
mod scene;
mod shade;
mod shaders;

pub use camera::{Camera, DEFAULT_FOV_DEG, MAX_SIDE, check_size, parse_point, parse_size};
pub use colour::{ColorBy, ColorChoice, SphereValues, unit, value_range, viridis};
pub use image::{Gif, Image, read_png};
pub use legend::Legend;
pub use scene::Scene;
pub use shaders::modules as shaders;

use crate::engines::{BackendKind, open_auto};
use crate::error::{Error, Result};

/// Most rays per pixel side.
pub const MAX_SAMPLES: u32 = 4;

/// What to draw: the picture's size, the camera, the rays per pixel and whether to cast shadows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Picture {
    /// Width in pixels, 1..=[`MAX_SIDE`].
    pub width: u32,
    /// Height in pixels, 1..=[`MAX_SIDE`].
    pub height: u32,
    /// The camera.
    pub camera: Camera,
    /// Rays per pixel side, 1..=[`MAX_SAMPLES`] (`samples`² rays per pixel; default: 1).
    pub samples: u32,
    /// Cast a shadow ray from every lit point towards the light (default: false).
    pub shadows: bool,
    /// A floor to draw under the spheres, usually the simulation box's: the rectangle at
    /// `z = lo[2]` over `lo[0]..hi[0]` × `lo[1]..hi[1]` \[m\], a grey checker of 10×10 cells
    /// that receives shadows (default: none).
    pub floor: Option<([f64; 3], [f64; 3])>,
}

impl Picture {
    /// A picture of `width`×`height` pixels through `camera`, one ray per pixel, no shadows.
    pub fn new(width: u32, height: u32, camera: Camera) -> Picture {
        Picture {
            width,
            height,
            camera,
            samples: 1,
            shadows: false,
            floor: None,
        }
    }

    /// The floor in `f32`, as the shaders get it.
    fn floor(&self) -> Option<shade::Floor> {
        self.floor.map(|(lo, hi)| shade::Floor {
            lo: glam::DVec3::from(lo).as_vec3(),
            hi: glam::DVec3::from(hi).as_vec3(),
        })
    }

    /// Checks the size, the camera and the samples.
    pub fn validate(&self) -> Result<()> {
        check_size(self.width, self.height)?;
        self.camera.validate()?;
        if let Some((lo, hi)) = self.floor {
            let ok = (0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] <= hi[k])
                && lo[0] < hi[0]
                && lo[1] < hi[1];
            if !ok {
                return Err(Error::InvalidConfig {
                    what: format!("floor {lo:?}..{hi:?}"),
                    reason: "must be finite with lo < hi in x and y".into(),
                });
            }
        }
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return Err(Error::InvalidConfig {
                what: format!("samples {}", self.samples),
                reason: format!("rays per pixel side must be in 1..={MAX_SAMPLES}"),
            });
        }
        Ok(())
    }
}

/// Which render path to use. Each path needs the hardware of one detection backend and is
/// chosen through the registry like it ([`RenderChoice::backend`]): `auto` is the registry's one
/// rule over the backends that have a path, with their probes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RenderChoice {
    /// The fastest path that runs here: wgpu-rq, then wgpu-compute, then cpu, passing over
    /// software adapters (slower than the cpu path).
    #[default]
    Auto,
    /// Ray queries over a BLAS of the spheres' boxes.
    #[cfg_attr(feature = "clap", value(name = "wgpu-rq"))]
    WgpuRq,
    /// Our own BVH traversed in a WGSL compute shader.
    #[cfg_attr(feature = "clap", value(name = "wgpu-compute"))]
    WgpuCompute,
    /// The same BVH on the CPU (rayon).
    Cpu,
}

impl RenderChoice {
    /// The backend whose hardware the path needs, `None` for `auto`: ray queries need an
    /// adapter with ray queries (`wgpu-rq`), our own BVH only compute shaders
    /// (`wgpu-compute`), the cpu path nothing (`cpu`). `optix` has no render path.
    pub fn backend(self) -> Option<BackendKind> {
        match self {
            RenderChoice::Auto => None,
            RenderChoice::WgpuRq => Some(BackendKind::WgpuRq),
            RenderChoice::WgpuCompute => Some(BackendKind::WgpuCompute),
            RenderChoice::Cpu => Some(BackendKind::Cpu),
        }
    }
}

crate::names::named!(RenderChoice {
    Auto => "auto",
    WgpuRq => "wgpu-rq",
    WgpuCompute => "wgpu-compute",
    Cpu => "cpu",
});

/// The backends that have a render path, in the order `auto` prefers them.
fn render_backends() -> Vec<BackendKind> {
    use crate::names::Named;
    let paths: Vec<BackendKind> = RenderChoice::ALL
        .iter()
        .filter_map(|choice| choice.backend())
        .collect();
    BackendKind::ALL
        .into_iter()
        .filter(|kind| paths.contains(kind))
        .collect()
}

/// An open render path.
pub struct Renderer {
    path: Path,
}

enum Path {
    Gpu {
        renderer: Box<gpu::GpuRenderer>,
        backend: BackendKind,
    },
    Cpu,
}

impl Renderer {
    /// Opens the path `choice`, or says why it cannot run here. For `auto`, also returns which
    /// path it picked and why it passed over the faster ones.
    pub fn open(choice: RenderChoice) -> Result<(Renderer, Option<String>)> {
        match choice.backend() {
            Some(backend) => Ok((Self::open_on(backend)?, None)),
            None => {
                let (renderer, reason) = open_auto(&render_backends(), Self::open_on)?;
                Ok((renderer, Some(format!("render: {reason}"))))
            }
        }
    }

    /// Opens the render path of `backend` (see [`RenderChoice::backend`]).
    fn open_on(backend: BackendKind) -> Result<Renderer> {
        let ray_query = match backend {
            BackendKind::Cpu => return Ok(Renderer { path: Path::Cpu }),
            BackendKind::WgpuRq => true,
            BackendKind::WgpuCompute => false,
            BackendKind::Optix => {
                return Err(Error::BackendUnavailable {
                    backend: backend.name(),
                    reason: "it has no render path".into(),
                });
            }
        };
        let unavailable = |reason: String| Error::BackendUnavailable {
            backend: backend.name(),
            reason,
        };
        backend.probe().map_err(unavailable)?;
        let renderer = gpu::GpuRenderer::open(ray_query).map_err(|e| unavailable(e.to_string()))?;
        let path = Path::Gpu {
            renderer: Box::new(renderer),
            backend,
        };
        Ok(Renderer { path })
    }

    /// The path's name (`wgpu-rq`, `wgpu-compute` or `cpu`).
    pub fn name(&self) -> &'static str {
        match &self.path {
            Path::Gpu { backend, .. } => backend.name(),
            Path::Cpu => BackendKind::Cpu.name(),
        }
    }

    /// The path and where it runs, in one line.
    pub fn describe(&self) -> String {
        match &self.path {
            Path::Gpu { renderer, backend } => {
                format!("{} ({})", backend.name(), renderer.device())
            }
            Path::Cpu => format!("cpu ({} threads)", rayon::current_num_threads()),
        }
    }

    /// Draws `scene` as `picture` says. An empty scene is background only (drawn on the CPU
    /// whatever the path: there is nothing to trace).
    pub fn render(&mut self, scene: &Scene, picture: &Picture) -> Result<Image> {
        picture.validate()?;
        let pixels = match &self.path {
            Path::Gpu { renderer, .. } if !scene.is_empty() => renderer.render(scene, picture)?,
            _ => cpu::render(scene, picture),
        };
        Ok(Image {
            width: picture.width,
            height: picture.height,
            pixels,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::names::Named;

    #[test]
    fn each_render_path_is_named_and_chosen_as_its_backend() {
        assert_eq!(
            render_backends(),
            [
                BackendKind::WgpuRq,
                BackendKind::WgpuCompute,
                BackendKind::Cpu
            ]
        );
        for choice in RenderChoice::ALL {
            let named = choice.backend().map_or("auto", BackendKind::name);
            assert_eq!(named, choice.name());
        }
    }

    #[test]
    fn auto_says_which_path_it_picked_among_those_that_exist() {
        let (renderer, reason) = Renderer::open(RenderChoice::Auto).expect("cpu opens");
        let reason = reason.expect("auto says why");
        let picked = format!("render: auto picked {}", renderer.name());
        assert!(reason.starts_with(&picked), "{reason}");
        assert!(!reason.contains("optix"), "{reason}");
        let (_, named) = Renderer::open(RenderChoice::Cpu).expect("cpu opens");
        assert_eq!(named, None);
    }
}
