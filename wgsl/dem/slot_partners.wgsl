// The partner of every history slot of one part of a step's entries, copied into one list (one
// word a slot) for the host to count each sphere's contacts without reading the springs back
// (src/engines/wgpu/granular.rs, `PartnerPicker`). One thread a slot.

// Twin of PickParams in src/engines/wgpu/granular.rs (tests/bindings.rs compares the layouts).
struct PickParams {
    slots: u32,  // slots of the part
    width: u32,  // words a slot
    first: u32,  // the list's place of the part's first slot
    row: u32,    // invocations per dispatch row
}

// A slot's partner is its first word's w (dem_granular.wgsl's entries).
const PARTNER_WORD: u32 = 3u;

@group(0) @binding(0) var<uniform> params: PickParams;
@group(0) @binding(1) var<storage, read> entries: array<u32>;
@group(0) @binding(2) var<storage, read_write> partners: array<u32>;

@compute @workgroup_size(256)
fn pick_partners(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * params.row;
    if s < params.slots {
        partners[params.first + s] = entries[s * params.width + PARTNER_WORD];
    }
}
