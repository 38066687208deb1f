// A rank's exchange of ghosts on the device (src/engines/wgpu/halo.rs), so that a round reads
// back and writes the layer near its box's faces, not the whole rank. `halo_gather` lists the
// rows of the rank's own spheres whose centres lie outside `inner` (its box shrunk by the halo:
// those a neighbour holds as ghosts, or that left the box) with their states, and the rows of
// its ghosts, and finds its own spheres' largest speed; `halo_scatter` writes the states the
// owners sent into their ghosts' rows.

// Twin of HaloParams in src/engines/wgpu/halo.rs (tests/bindings.rs compares the layouts).
struct HaloParams {
    n: u32,          // rows in the state
    row: u32,        // invocations per dispatch row
    near_room: u32,  // entries of `near`
    ghost_room: u32, // entries of `ghosts`
    inner_lo: vec3<f32>,
    spins: u32,      // 1: `omega` holds the spins (the granular step), else none is bound
    inner_hi: vec3<f32>,
    count: u32,      // entries of `incoming` (the scatter)
}

@group(0) @binding(0) var<uniform> params: HaloParams;
// The step's state by row: x, y, z, r; the residuals x, y, z, 0; vx, vy, vz, m; ωx, ωy, ωz and
// the material as a whole f32 number (dem_granular.wgsl).
@group(0) @binding(1) var<storage, read_write> pos: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> lo: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> vel: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> omega: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> ids: array<u32>;
// By stable id: 1 where the sphere is the rank's own, 0 for a ghost.
@group(0) @binding(6) var<storage, read> own: array<u32>;
// The near own spheres listed, the ghosts listed, the largest own speed (as bits: speeds are
// not negative, so their bits order as they do).
@group(0) @binding(7) var<storage, read_write> counts: array<atomic<u32>, 4>;
// Four words a near own sphere, as bits: pos; lo with the row; vel with the stable id; omega.
@group(0) @binding(8) var<storage, read_write> near: array<vec4<u32>>;
// Two words a ghost: its row, its stable id.
@group(0) @binding(9) var<storage, read_write> ghosts: array<vec2<u32>>;
// Four words a state to write, as bits: pos (the row in w), lo, vel, omega (w unused: the
// row keeps its radius, mass and material).
@group(0) @binding(10) var<storage, read> incoming: array<vec4<u32>>;

var<workgroup> fastest: atomic<u32>;

fn gather_row(r: u32) {
    let k = ids[r];
    if own[k] == 0u {
        let at = atomicAdd(&counts[1], 1u);
        if at < params.ghost_room {
            ghosts[at] = vec2<u32>(r, k);
        }
        return;
    }
    let v = vel[r];
    atomicMax(&fastest, bitcast<u32>(length(v.xyz)));
    let p = pos[r];
    let l = lo[r];
    let c = p.xyz + l.xyz;
    if all(c >= params.inner_lo) && all(c < params.inner_hi) {
        return;
    }
    let at = atomicAdd(&counts[0], 1u);
    if at < params.near_room {
        var w = vec4<f32>(0.0);
        if params.spins != 0u {
            w = omega[r];
        }
        near[4u * at] = bitcast<vec4<u32>>(p);
        near[4u * at + 1u] = vec4<u32>(bitcast<vec3<u32>>(l.xyz), r);
        near[4u * at + 2u] = vec4<u32>(bitcast<vec3<u32>>(v.xyz), k);
        near[4u * at + 3u] = bitcast<vec4<u32>>(w);
    }
}

@compute @workgroup_size(256)
fn halo_gather(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    if li == 0u {
        atomicStore(&fastest, 0u);
    }
    workgroupBarrier();
    let r = gid.x + gid.y * params.row;
    if r < params.n {
        gather_row(r);
    }
    workgroupBarrier();
    if li == 0u {
        atomicMax(&counts[2], atomicLoad(&fastest));
    }
}

@compute @workgroup_size(256)
fn halo_scatter(@builtin(global_invocation_id) gid: vec3<u32>) {
    let e = gid.x + gid.y * params.row;
    if e >= params.count {
        return;
    }
    let s = incoming[4u * e];
    let r = s.w;
    pos[r] = vec4<f32>(bitcast<vec3<f32>>(s.xyz), pos[r].w);
    lo[r] = vec4<f32>(bitcast<vec3<f32>>(incoming[4u * e + 1u].xyz), 0.0);
    vel[r] = vec4<f32>(bitcast<vec3<f32>>(incoming[4u * e + 2u].xyz), vel[r].w);
    if params.spins != 0u {
        omega[r] = vec4<f32>(bitcast<vec3<f32>>(incoming[4u * e + 3u].xyz), omega[r].w);
    }
}
