// A flow event on the device (src/engines/wgpu/flow.rs): one pass over the state lists the
// spheres that leave (centre in an outflow box or below the floor) and the others whose centres
// lie in a box around an inflow, so that the event reads back these alone, in one read.

// Twin of FlowParams in src/engines/wgpu/flow.rs (tests/bindings.rs compares the layouts).
struct FlowParams {
    n: u32,          // spheres in the state
    row: u32,        // invocations per dispatch row
    near_boxes: u32, // boxes around the inflows: boxes[2k] and boxes[2k + 1] are lo and hi
    out_boxes: u32,  // outflow boxes, after those
    floor_on: u32,   // 1: centres below `floor` leave
    floor: f32,
    room: u32,       // entries of the near list
    leaving_room: u32, // entries of the leaving list
    materials: u32,  // 1: spin holds each sphere's material (the granular step's ω), else all 0
}

@group(0) @binding(0) var<uniform> params: FlowParams;
@group(0) @binding(1) var<storage, read> pos: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> boxes: array<vec4<f32>>;
// Words 0 and 1: spheres that leave, spheres near an inflow (each listed up to its room);
// from word 4, `room` near entries of four words (x, y, z, r as bits); after them,
// `leaving_room` leaving entries of three words (state index, radius as bits, material).
@group(0) @binding(3) var<storage, read_write> found: array<atomic<u32>>;
// by state index: ωx, ωy, ωz and the material as a whole f32 number (dem_granular.wgsl)
@group(0) @binding(4) var<storage, read> spin: array<vec4<f32>>;

const HEADER: u32 = 4u;

fn inside(c: vec3<f32>, k: u32) -> bool {
    return all(c >= boxes[2u * k].xyz) && all(c <= boxes[2u * k + 1u].xyz);
}

@compute @workgroup_size(256)
fn flow_scan(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.row;
    if i >= params.n {
        return;
    }
    let p = pos[i];
    var leaves = params.floor_on != 0u && p.z < params.floor;
    for (var k = 0u; k < params.out_boxes; k += 1u) {
        leaves = leaves || inside(p.xyz, params.near_boxes + k);
    }
    if leaves {
        let at = atomicAdd(&found[0], 1u);
        if at < params.leaving_room {
            let w = HEADER + 4u * params.room + 3u * at;
            var material = 0u;
            if params.materials != 0u {
                material = u32(spin[i].w);
            }
            atomicStore(&found[w], i);
            atomicStore(&found[w + 1u], bitcast<u32>(p.w));
            atomicStore(&found[w + 2u], material);
        }
        return;
    }
    for (var k = 0u; k < params.near_boxes; k += 1u) {
        if inside(p.xyz, k) {
            let at = atomicAdd(&found[1], 1u);
            if at < params.room {
                let w = HEADER + 4u * at;
                atomicStore(&found[w], bitcast<u32>(p.x));
                atomicStore(&found[w + 1u], bitcast<u32>(p.y));
                atomicStore(&found[w + 2u], bitcast<u32>(p.z));
                atomicStore(&found[w + 3u], bitcast<u32>(p.w));
            }
            break;
        }
    }
}
