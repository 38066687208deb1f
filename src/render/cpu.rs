//! The `cpu` render path: one task per row (rayon), each pixel traced through the trees of
//! [`super::bvh`] (spheres, and the walls' triangles) and shaded by [`super::shade::pixel`],
//! exactly as the shaders do.

use super::Picture;
use super::bvh::{trace, trace_spheres};
use super::scene::Scene;
use super::shade::{hit_triangle, pixel};
use rayon::prelude::*;

/// The pixels of `picture` of `scene`, row by row.
pub(crate) fn render(scene: &Scene, picture: &Picture) -> Vec<u32> {
    let grid = picture.camera.grid(picture.width, picture.height);
    let floor = picture.floor();
    let mut pixels = vec![0u32; picture.width as usize * picture.height as usize];
    pixels
        .par_chunks_mut(picture.width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                *out = pixel(
                    &grid,
                    (x as u32, y as u32),
                    (picture.samples, picture.height),
                    picture.shadows,
                    floor.as_ref(),
                    (&scene.spheres, &scene.colours, &scene.walls),
                    |o, d, t_max, first| {
                        trace_spheres(&scene.nodes, &scene.spheres, o, d, t_max, first)
                    },
                    |o, d, t_max| {
                        trace(&scene.wall_nodes, o, d, t_max, false, |k| {
                            hit_triangle(o, d, &scene.walls, k)
                        })
                    },
                );
            }
        });
    pixels
}
