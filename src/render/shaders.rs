//! The GPU render paths' WGSL modules: each one's composed source, entry point, bindings and
//! uniform, named once for the bind-group code and checked against the WGSL by
//! `tests/bindings.rs`.

use super::bvh;
use crate::gpu::shader::{Binding, SharedStruct, Vec3f, WgslModule, shared_struct, wgsl};

/// Ray queries over a BLAS of the spheres' boxes (`wgsl/render/render_rq.wgsl`).
pub(crate) const RQ_SOURCE: &str = wgsl!("render/render_rq.wgsl", "render/render_common.wgsl");
/// Our own BVH traversed in WGSL (`wgsl/render/render_bvh.wgsl`).
pub(crate) const BVH_SOURCE: &str = wgsl!("render/render_bvh.wgsl", "render/render_common.wgsl");
/// The one entry point of both modules.
pub(crate) const ENTRY_POINT: &str = "render";

pub(crate) const VIEW: Binding = Binding::uniform(0, "view");
pub(crate) const SPHERES: Binding = Binding::read(1, "spheres");
pub(crate) const COLOURS: Binding = Binding::read(2, "colours");
pub(crate) const PIXELS: Binding = Binding::read_write(3, "pixels");
/// The spheres' tree (searched by the BVH module; bound in both).
pub(crate) const NODES: Binding = Binding::read(4, "nodes");
/// Only in the ray-query module.
pub(crate) const TLAS: Binding = Binding::acceleration_structure(5, "tlas");
/// The walls' tree and triangles (three corners each).
pub(crate) const WALL_NODES: Binding = Binding::read(6, "wall_nodes");
pub(crate) const WALLS: Binding = Binding::read(7, "walls");

/// The camera, picture and floor; WGSL twin: `View` in `wgsl/render/render_common.wgsl`.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct View {
    pub eye: Vec3f,
    /// Picture width \[pixels\].
    pub width: u32,
    pub corner: Vec3f,
    /// Picture height \[pixels\].
    pub height: u32,
    pub right: Vec3f,
    /// Rays per pixel side (samples² per pixel).
    pub samples: u32,
    pub down: Vec3f,
    /// 1: cast shadow rays.
    pub shadows: u32,
    pub light: Vec3f,
    /// Number of spheres.
    pub n: u32,
    pub floor_lo: Vec3f,
    /// 1: draw the floor `z = floor_lo.z` over `floor_lo.xy .. floor_hi.xy`.
    pub floor_on: u32,
    pub floor_hi: Vec3f,
    /// Number of wall triangles.
    pub walls: u32,
}

fn view() -> SharedStruct {
    shared_struct!(
        "View",
        View {
            eye,
            width,
            corner,
            height,
            right,
            samples,
            down,
            shadows,
            light,
            n,
            floor_lo,
            floor_on,
            floor_hi,
            walls,
        }
    )
}

/// Every WGSL module of the render paths, exactly as the device gets it.
pub fn modules() -> Vec<WgslModule> {
    const COMMON: [Binding; 7] = [VIEW, SPHERES, COLOURS, PIXELS, NODES, WALL_NODES, WALLS];
    vec![
        WgslModule::new(
            "render_rq",
            RQ_SOURCE,
            &[ENTRY_POINT],
            &[&COMMON[..], &[TLAS]].concat(),
            vec![view(), bvh::node()],
        ),
        WgslModule::new(
            "render_bvh",
            BVH_SOURCE,
            &[ENTRY_POINT],
            &COMMON,
            vec![view(), bvh::node()],
        ),
    ]
}
