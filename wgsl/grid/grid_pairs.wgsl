// Detection stage of the wgpu-compute backend (sorted proxy grid, single- or multi-level; see
// grid_params.wgsl and grid_stencil.wgsl). Each sphere walks its stencil (grid_walk.wgsl), which
// visits each pair once, so the narrow phase (collides, proxy.wgsl) alone decides. Needs
// grid_params.wgsl and grid_stencil.wgsl prepended, grid_walk.wgsl, proxy.wgsl and
// pair_output.wgsl appended.

@group(0) @binding(0) var<uniform> params: GridParams;
@group(0) @binding(1) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> ids: array<u32>;
@group(0) @binding(6) var<storage, read> cell_start: array<u32>;

struct Walker {
    p: u32,
    s: vec4<f32>,
    id: u32,      // input index of sphere p
    tested: u32,  // candidates tested
}

fn walk_sphere(q: u32) -> vec4<f32> {
    return spheres[q];
}

fn walker_cell(w: ptr<function, Walker>, level: u32) -> vec3<u32> {
    return cell_coords((*w).s.xyz, level);
}

fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    let s = (*w).s;
    if collides(s.xyz, s.w, t.xyz, t.w) {
        emit_pair((*w).id, q, params.capacity);
    }
}

fn walked(w: ptr<function, Walker>, n: u32) {
    (*w).tested += n;
}

@compute @workgroup_size(256)
fn find_pairs(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * params.row;
    var w = Walker(p, vec4(0.0), 0u, 0u);
    if p < params.n {
        w.s = spheres[p];
        w.id = ids[p];
        stencil_walk(&w);
    }
    finish_pairs(w.tested, lid, params.capacity);
}
