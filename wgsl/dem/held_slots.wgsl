// The slots each sphere holds of a part of a granular step's history (src/engines/wgpu/
// held_slots.rs, `HeldSlots`), one thread a slot; a row's held slots are its first `held`
// (dem_granular.wgsl). `save_held` copies them to the same places of the saved part that a
// batch's redo begins from (the slots past them are left as they were: a redo reads only the held
// ones); `pack_held` packs them, row after row, into a list the host reads back, and `pick_held`
// their partners alone (a slot's first vector's w), for the host to count each sphere's
// contacts without reading the springs.

// Twin of SlotParams in src/engines/wgpu/held_slots.rs (tests/bindings.rs compares the layouts).
struct SlotParams {
    first: u32,   // the part's first row
    rows: u32,    // rows of the part
    slots: u32,   // slots a row
    vectors: u32, // 16-byte vectors a slot
    row: u32,     // invocations per dispatch row
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: SlotParams;
// by history row: contacts held
@group(0) @binding(1) var<storage, read> held: array<u32>;
@group(0) @binding(2) var<storage, read> from_slots: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> to_slots: array<vec4<u32>>;
// `pack_held`, `pick_held`, by history row: the place of the row's first slot in its part's list
@group(0) @binding(4) var<storage, read> packed_at: array<u32>;
// `pick_held`: each held slot's partner, at its place in the list
@group(0) @binding(5) var<storage, read_write> partners: array<u32>;

// The slot of the part a thread takes, and its place in its row (`held` false: none held).
struct Slot {
    at: u32,
    k: u32,
    held: bool,
}

fn slot_of(gid: vec3<u32>) -> Slot {
    let s = gid.x + gid.y * params.row;
    if s >= params.rows * params.slots {
        return Slot(0u, 0u, false);
    }
    let k = s % params.slots;
    return Slot(s, k, k < held[params.first + s / params.slots]);
}

@compute @workgroup_size(256)
fn save_held(@builtin(global_invocation_id) gid: vec3<u32>) {
    let slot = slot_of(gid);
    if !slot.held {
        return;
    }
    for (var v = 0u; v < params.vectors; v += 1u) {
        let at = slot.at * params.vectors + v;
        to_slots[at] = from_slots[at];
    }
}

// The place in its part's list of the held slot `slot`.
fn packed_place(slot: Slot) -> u32 {
    return packed_at[params.first + slot.at / params.slots] + slot.k;
}

@compute @workgroup_size(256)
fn pack_held(@builtin(global_invocation_id) gid: vec3<u32>) {
    let slot = slot_of(gid);
    if !slot.held {
        return;
    }
    let to = packed_place(slot);
    for (var v = 0u; v < params.vectors; v += 1u) {
        to_slots[to * params.vectors + v] = from_slots[slot.at * params.vectors + v];
    }
}

@compute @workgroup_size(256)
fn pick_held(@builtin(global_invocation_id) gid: vec3<u32>) {
    let slot = slot_of(gid);
    if slot.held {
        partners[packed_place(slot)] = from_slots[slot.at * params.vectors].w;
    }
}
