// The slots a granular batch begins from, kept for a redo (src/engines/wgpu/held_saver.rs,
// `HeldSaver`): of one part of the old history, each sphere's held slots copied to the saved
// part, one thread a slot. A row's held slots are its first `held` (dem_granular.wgsl); the
// slots past them are left as they were, and a redo reads only the held ones.

// Twin of SaveParams in src/engines/wgpu/held_saver.rs (tests/bindings.rs compares the layouts).
struct SaveParams {
    first: u32,   // the part's first row
    rows: u32,    // rows of the part to save
    slots: u32,   // slots a row
    vectors: u32, // 16-byte vectors a slot
    row: u32,     // invocations per dispatch row
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: SaveParams;
// by history row: contacts held
@group(0) @binding(1) var<storage, read> held: array<u32>;
@group(0) @binding(2) var<storage, read> from_slots: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> to_slots: array<vec4<u32>>;

@compute @workgroup_size(256)
fn save_held(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * params.row;
    if s >= params.rows * params.slots || s % params.slots >= held[params.first + s / params.slots] {
        return;
    }
    for (var k = 0u; k < params.vectors; k += 1u) {
        let at = s * params.vectors + k;
        to_slots[at] = from_slots[at];
    }
}
