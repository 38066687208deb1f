// Contacts held across a gap, found from the history (wgpu-compute's granular step where
// contacts hold at least 0.5 % of the smallest radius past touching and keep history:
// APART_FROM_HISTORY, the host's `APART_REACH`). A pair apart is a contact only where the last
// step held one, and then one of its spheres' old history rows names the other; so the walk
// lists only the candidates that touch its sphere (its cells and windows a dry walk's), and
// after it each walker resolves the contacts of its own old row whose spheres are now apart. The two tests are one comparison and its negation, on the same words (the
// walk's sorted centres; a difference negated rounds alike), so each pair that touches is the
// walk's and each pair apart the history's. A pair is in one of its spheres' old rows only (its
// owner's: a step writes only the owner's row, and a history the host lays out keeps one side,
// src/engines/wgpu/granular.rs `owned`), so it is resolved once.
// `name_places` writes, before the contact pass, each stable id's sorted place.
// Needs dem_grid_granular.wgsl's walk and dem_granular.wgsl's walker.

override APART_FROM_HISTORY: bool = false;

// by stable id: the sorted place of the sphere with that id in this step (an id no sphere has
// holds a place of an earlier step, which `resolve_apart` tells apart)
@group(0) @binding(39) var<storage, read_write> place_of_id: array<u32>;

// Each sorted place under its sphere's stable id, for the contact pass after it.
@compute @workgroup_size(256)
fn name_places(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = index(gid);
    if p >= params.n {
        return;
    }
    place_of_id[stable_id(home_ro[p])] = p;
}

// Whether spheres s and t (centre, radius) touch: a pair the walk lists.
fn touches(s: vec4<f32>, t: vec4<f32>) -> bool {
    let d = t.xyz - s.xyz;
    let touch = s.w + t.w;
    return d.x * d.x + d.y * d.y + d.z * d.z <= touch * touch;
}

// Whether candidate t (centre, radius) of a walk from sphere s is listed: where contacts are
// found from the history apart, one that touches; else one within reach.
fn walk_lists(s: vec4<f32>, t: vec4<f32>) -> bool {
    if APART_FROM_HISTORY {
        return touches(s, t);
    }
    return reaches(s, t);
}

// The walker's contacts of the last step, from its own old row, whose spheres are now apart
// (after its walk, which met those that touch).
fn resolve_apart(w: ptr<function, Walker>) {
    if !APART_FROM_HISTORY {
        return;
    }
    let at = (*w).own_old;
    for (var s = 0u; s < (*w).kept; s += 1u) {
        let b = old_partner(SlotAt(at.part, at.slot + s));
        // Walls (ids past NO_PARTNER) are `finish`'s and the mesh walls' kernel's; NO_PARTNER
        // names no contact.
        if b >= NO_PARTNER || b >= arrayLength(&place_of_id) {
            continue;
        }
        // The place named by an id whose sphere left holds another sphere (or none): no
        // contact, skipped here where it touches, below where not.
        let q = place_of_id[b];
        if q >= params.n {
            continue;
        }
        let t = walk_pos_ro[q];
        if touches((*w).s, t) || stable_id(home_ro[q]) != b {
            continue;
        }
        take(w, contact_with(w, home_ro[q], t));
    }
}
