// Rows of a step's buffers moved to other places (src/engines/wgpu/state.rs, `RowMover`): each
// pair (from, to) copies the `words` words of row `from` over those of row `to`, one thread a
// word. No row is both a source and a target, so the copies of one pass never race.

// Twin of MoveParams in src/engines/wgpu/state.rs (tests/bindings.rs compares the layouts).
struct MoveParams {
    moves: u32, // pairs
    words: u32, // words a row
    row: u32,   // invocations per dispatch row
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: MoveParams;
@group(0) @binding(1) var<storage, read> pairs: array<vec2<u32>>;
// `move_within`: the rows of one buffer.
@group(0) @binding(2) var<storage, read_write> rows: array<u32>;
// `move_across`: from the rows of one buffer to those of another.
@group(0) @binding(3) var<storage, read> from_rows: array<u32>;
@group(0) @binding(4) var<storage, read_write> to_rows: array<u32>;

// The word a thread moves: where it is and where it goes (`valid` false past the last).
struct Word {
    at: u32,
    goes: u32,
    valid: bool,
}

fn word_of(gid: vec3<u32>) -> Word {
    let t = gid.x + gid.y * params.row;
    if t >= params.moves * params.words {
        return Word(0u, 0u, false);
    }
    let p = pairs[t / params.words];
    let w = t % params.words;
    return Word(p.x * params.words + w, p.y * params.words + w, true);
}

@compute @workgroup_size(256)
fn move_within(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = word_of(gid);
    if m.valid {
        rows[m.goes] = rows[m.at];
    }
}

@compute @workgroup_size(256)
fn move_across(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = word_of(gid);
    if m.valid {
        to_rows[m.goes] = from_rows[m.at];
    }
}
