// Render path wgpu-compute: `trace` walks our own BVH of the spheres (built on the CPU,
// src/render/bvh.rs; `walk` is in render_common.wgsl, which is appended to this file).

fn trace(o: vec3<f32>, d: vec3<f32>, t_max: f32, first: bool) -> Hit {
    return walk(SPHERE_TREE, o, d, t_max, first);
}
