// The resolve kernel of the wgpu-compute DEM step with the paper's law (dem_physics.wgsl's
// contact_force): part of the module dem_grid.wgsl describes.

// Candidates within reach a walk lists before resolving them (the walk's loop then holds no
// contact law).
const ROOM: u32 = 8u;
const RESOLVE_GROUP: u32 = 256u; // threads of a resolve workgroup
var<workgroup> near_slots: array<u32, ROOM * RESOLVE_GROUP>;

struct Walker {
    p: u32,            // sorted place of the walker's sphere
    h: u32,            // its state row
    s: vec4<f32>,
    base: u32,         // its first slot in near_slots
    listed: u32,       // candidates within reach listed this walk
    found: u32,        // candidates within reach met this walk
    skip: u32,         // those met before are resolved already (by an earlier walk)
}

// The paper's state is pos and vel alone.
fn carry(i: u32, p: u32) {}

fn walk_sphere(q: u32) -> vec4<f32> {
    return walk_pos[q];
}

// Lists the sphere at sorted place q where it is within reach of the walker's.
fn visit(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    let s = (*w).s;
    let d = t.xyz - s.xyz;
    let reach = s.w + t.w;
    if d.x * d.x + d.y * d.y + d.z * d.z > reach * reach {
        return;
    }
    let f = (*w).found;
    (*w).found = f + 1u;
    if f >= (*w).skip && (*w).listed < ROOM {
        near_slots[(*w).base + (*w).listed] = q;
        (*w).listed += 1u;
    }
}

// A run's end: nothing to sum (the listed contacts are resolved after the walk).
fn walked(w: ptr<function, Walker>, n: u32) {}

var<workgroup> group_contacts: atomic<u32>;

// Detection and contact resolution in one pass: every pair is found once (grid_walk.wgsl's
// stencil walk, as in grid_pairs.wgsl) by the thread of one of its spheres, which adds equal and
// opposite forces: it lists up to ROOM candidates within reach, resolves them, and walks again for
// the next ROOM while there are more.
@compute @workgroup_size(RESOLVE_GROUP)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = index(gid);
    var total = vec4(0.0);
    if p < params.n {
        let h = home[p];
        let s = walk_pos[p];
        var skip = 0u;
        loop {
            var w = Walker(p, h, s, lid * ROOM, 0u, 0u, skip);
            stencil_walk(&w);
            if w.listed > 0u {
                let v = vel[h];
                for (var k = 0u; k < w.listed; k += 1u) {
                    let q = near_slots[w.base + k];
                    let t = walk_pos[q];
                    let row = home[q];
                    let u = vel[row];
                    let f = contact_force(s.xyz, v.xyz, s.w, v.w, t.xyz, u.xyz, t.w, u.w);
                    if f.w != 0.0 {
                        add_force(row, -f.xyz);
                        total += f;
                    }
                }
            }
            if w.found <= skip + ROOM {
                break;
            }
            skip += ROOM;
        }
        if total.w != 0.0 {
            add_force(h, total.xyz);
        }
    }
    atomicAdd(&group_contacts, u32(total.w));
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&counters[0], atomicLoad(&group_contacts));
    }
}
