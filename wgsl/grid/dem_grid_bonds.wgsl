// Which candidates within reach a cohesive walk lists (wgpu-compute's granular step where
// contacts hold past touching: FILTERS_BONDS). A candidate apart from the walker's sphere is a
// contact only where the pair held one at the last step; every other apart candidate is skipped
// by the walk, before its slot, its lookup in both spheres' old history and its law, which would
// all find nothing. A pair that held a contact at the last step either touched then, and is now
// apart by at most what its two spheres moved in one step (the walker's `slack`: twice the
// step's length at the largest speed, and rounding), or was held across a gap, which the step
// that held it marked in both spheres' bits (`held_apart`).
//
// `bonds`: each sphere's marks, a 16-bit hash set of its partners' stable ids, in the word of its
// stable id modulo a power of two (spheres sharing a word share their marks: more is listed,
// nothing lost); a word's half of the clock's parity is the last step's marks, which a step
// reads, the other half the step's own, which it writes (and the integration of the next step
// clears). After the words: the largest speed the integration gave, by the clock's parity, and
// whether this batch's marks and speed are whole (the host zeroes the buffer at every batch's
// start: a batch's first step lists every candidate within reach, and makes them whole).
// Needs dem_grid_granular.wgsl's walk and dem_granular.wgsl's walker.

override FILTERS_BONDS: bool = false;

@group(0) @binding(39) var<storage, read_write> bonds: array<atomic<u32>>;

// Words after the marks: the largest speed (f32 bits) of the clock's parity 0 and 1, and the
// batch's marks and speed being whole (1).
const WHOLE_WORD: u32 = 2u;
const HEADER_WORDS: u32 = 4u;

// The shift of the half of the marks' words this step writes, as the walker saw the clock
// (`see_bonds`): the marking needs no load of its own.
var<private> written_shift: u32;

// The word of the marks of the sphere of stable id `id`.
fn marks_word(id: u32) -> u32 {
    return id & (arrayLength(&bonds) - HEADER_WORDS - 1u);
}

// The k-th word after the marks.
fn header_word(k: u32) -> u32 {
    return arrayLength(&bonds) - HEADER_WORDS + k;
}

// The bit of stable id `id` in a sphere's 16 marks.
fn mark_bit(id: u32) -> u32 {
    return 1u << ((id * 0x9e3779b1u) >> 28u);
}

// The shift of the half of a word that a step of clock `c` writes (the other half it reads).
fn written_half(c: u32) -> u32 {
    return 16u * ((c + 1u) & 1u);
}

// Every thread of a contact pass, first: the half of the marks it writes (a thread may resolve
// other walkers' contacts).
fn see_clock() {
    if FILTERS_BONDS {
        written_shift = written_half(atomicLoad(&clock));
    }
}

// The walker's view of the last step: its sphere's marks and the slack within which an apart
// candidate may have touched then (negative: the marks are not whole, every candidate is
// listed); `a` is the walker's stable id.
fn see_bonds(w: ptr<function, Walker>, a: u32) {
    (*w).slack = -1.0;
    if !FILTERS_BONDS {
        return;
    }
    let c = atomicLoad(&clock);
    if (*w).p == 0u {
        // The integration of this step takes the next step's largest speed here.
        atomicStore(&bonds[header_word((c + 1u) & 1u)], 0u);
    }
    if atomicLoad(&bonds[header_word(WHOLE_WORD)]) == 0u {
        return;
    }
    // No speed past the largest finite one (an infinite or NaN speed lists every candidate).
    let fastest = atomicLoad(&bonds[header_word(c & 1u)]);
    if fastest >= 0x7f800000u {
        return;
    }
    (*w).marks = (atomicLoad(&bonds[marks_word(a)]) >> (16u - written_half(c))) & 0xffffu;
    let speed = bitcast<f32>(fastest);
    let s = (*w).s;
    let far = max(max(abs(s.x), abs(s.y)), abs(s.z));
    // Each centre moved by dt·v and its rounding (a few units in the last place of the larger
    // coordinate); the pair's distance has rounding of its own (the factor in `unbonded`).
    (*w).slack = 2.0 * dem.dt * speed * (1.0 + 1.0 / 1024.0) + far / 65536.0;
}

// Whether candidate q (sorted place; t its centre and radius, within reach) is apart from the
// walker's sphere and held no contact with it at the last step: then the walk skips it.
fn unbonded(w: ptr<function, Walker>, q: u32, t: vec4<f32>) -> bool {
    if !FILTERS_BONDS || (*w).slack < 0.0 {
        return false;
    }
    let d = t.xyz - (*w).s.xyz;
    let touch = (*w).s.w + t.w;
    let beyond = touch * (1.0 + 1.0 / 65536.0) + (*w).slack;
    if d.x * d.x + d.y * d.y + d.z * d.z <= beyond * beyond {
        return false;
    }
    return (*w).marks == 0u || ((*w).marks & mark_bit(stable_id(home[q]))) == 0u;
}

// Marks, for the next step, the walker's contact with sphere b (stable id; t its centre and
// radius) that holds this step, where they are apart (dem_granular.wgsl's hook).
fn held_apart(w: ptr<function, Walker>, b: u32, t: vec4<f32>) {
    if !FILTERS_BONDS {
        return;
    }
    let a = (*w).a;
    let s = (*w).s;
    let d = t.xyz - s.xyz;
    let touch = s.w + t.w;
    if d.x * d.x + d.y * d.y + d.z * d.z <= touch * touch {
        return;
    }
    atomicOr(&bonds[marks_word(a)], mark_bit(b) << written_shift);
    atomicOr(&bonds[marks_word(b)], mark_bit(a) << written_shift);
}

// After sphere p (state index) moved by dt·v (dem_granular.wgsl's hook): its speed into the
// next step's largest, its marks of the last step cleared (the next step writes there), the
// marks and speed whole.
fn moved_by(p: u32, v: vec3<f32>) {
    if !FILTERS_BONDS {
        return;
    }
    let c = atomicLoad(&clock);
    let top = header_word((c + 1u) & 1u);
    let speed = bitcast<u32>(length(v));
    if speed > atomicLoad(&bonds[top]) {
        atomicMax(&bonds[top], speed);
    }
    let at = marks_word(stable_id(p));
    let kept = 0xffffu << written_half(c);
    let word = atomicLoad(&bonds[at]);
    if (word & ~kept) != 0u {
        atomicAnd(&bonds[at], kept);
    }
    if p == 0u {
        atomicStore(&bonds[header_word(WHOLE_WORD)], 1u);
    }
}
