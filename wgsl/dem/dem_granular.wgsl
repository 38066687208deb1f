// The granular GPU step's state beyond the paper's (docs/method.md, "Contact history"): angular
// velocities, torque accumulators (dem_torque_*.wgsl), the contact history, the owner's walk of
// its contacts and the integration kernel. Needs dem_params.wgsl and dem_contact.wgsl, a
// dem_force_*.wgsl and a dem_torque_*.wgsl; the including shader defines
//   fn stable_id(p: u32) -> u32    the input index of the sphere at state index p
//   fn row_before(p: u32) -> u32   the state index the sphere at state index p had in the
//                                  previous step (its row of the old history)
//
// Angular velocities and torques are in state order, as pos and vel (the engine permutes ω with
// them wherever it re-sorts the state), so every kernel reads them where it reads pos and vel.
// Each sphere's material travels in its ω's fourth component, a whole f32 number (`material_of`):
// read with ω at no cost, and moved wherever ω moves.
//
// History: K = dem.slots slots per sphere in rows in state order, in two sets of buffers
// that swap roles every step (old: read, new: written): a step writes the new row of the sphere
// at state index p at row p, and reads its old row at row_before(p), the row the previous step
// wrote. The state barely moves from one re-sort to the next, so neighbouring threads read and
// write neighbouring rows. A slot is one 32-byte entry (one memory sector, written whole: a
// partly written sector costs the memory a read of the rest) holding the partner's stable id and
// the six springs. Slot s of row r is in one of the entry bindings: part r / P of them, at
// element (r mod P)·K + s, P = dem.spheres_per_part (every row in part 0 where the
// entries fit one binding; the bindings past the parts in use hold a spare buffer and are
// never read).
// A pair is resolved once, by its owner (the sphere whose thread finds it, or, where the grid's
// walk lists only touching spheres, the one whose old row holds a pair now apart); the owner
// looks the pair up in its own old slots, then in the partner's (whose springs are the
// negatives: the owner of a pair changes when the order or the proxy rule's case changes), and
// writes it to its own new slots. Only the owner writes its
// slots: no atomics. Every contact is counted, also those that do not fit, and a sphere that
// needs more than K raises history_need to its count: the host then grows K and redoes the
// steps.

// Partner ids from here on name the walls (src/particles/history.rs).
const FIRST_WALL: u32 = 0xfffffffau;
// The partner of a slot that holds no contact: a candidate the walk listed (and gave a slot)
// that does not touch (NO_PARTNER in src/particles/history.rs; no lookup matches it).
const NO_PARTNER: u32 = 0xfffefff9u;

// by state index
@group(0) @binding(18) var<storage, read_write> omega: array<vec4<f32>>;   // ωx, ωy, ωz, material
// Read-only views of vel (11) and omega (18) for the kernels that resolve contacts, which only
// read them: no kernel reads one buffer through both.
@group(0) @binding(11) var<storage, read> vel_ro: array<vec4<f32>>;
@group(0) @binding(18) var<storage, read> omega_ro: array<vec4<f32>>;
// by history row: contacts held
@group(0) @binding(21) var<storage, read> held_old: array<u32>;
@group(0) @binding(23) var<storage, read_write> held_new: array<u32>;
// The most contacts with history any sphere had since the host cleared it.
@group(0) @binding(24) var<storage, read_write> history_need: atomic<u32>;
// per slot, an Entry of the tangential model (dem_tangential_*.wgsl): the partner's stable id (or
// FIRST_WALL + wall) in its first word's w, the springs as bits
@group(0) @binding(50) var<storage, read> entries_old0: array<Entry>;
@group(0) @binding(51) var<storage, read> entries_old1: array<Entry>;
@group(0) @binding(52) var<storage, read> entries_old2: array<Entry>;
@group(0) @binding(53) var<storage, read> entries_old3: array<Entry>;
@group(0) @binding(54) var<storage, read> entries_old4: array<Entry>;
@group(0) @binding(55) var<storage, read> entries_old5: array<Entry>;
@group(0) @binding(56) var<storage, read> entries_old6: array<Entry>;
@group(0) @binding(57) var<storage, read> entries_old7: array<Entry>;
@group(0) @binding(58) var<storage, read_write> entries_new0: array<Entry>;
@group(0) @binding(59) var<storage, read_write> entries_new1: array<Entry>;
@group(0) @binding(60) var<storage, read_write> entries_new2: array<Entry>;
@group(0) @binding(61) var<storage, read_write> entries_new3: array<Entry>;
@group(0) @binding(62) var<storage, read_write> entries_new4: array<Entry>;
@group(0) @binding(63) var<storage, read_write> entries_new5: array<Entry>;
@group(0) @binding(64) var<storage, read_write> entries_new6: array<Entry>;
@group(0) @binding(65) var<storage, read_write> entries_new7: array<Entry>;

// The sphere of state row `o` (its ω and material, omega[p]) with centre and radius s and
// velocity and mass v.
fn body_of(s: vec4<f32>, v: vec4<f32>, o: vec4<f32>) -> Body {
    var material = 0u;
    if !ONE_MATERIAL {
        material = u32(o.w);
    }
    return Body(s.xyz, v.xyz, o.xyz, s.w, v.w, material);
}

// Where a slot is: the entry binding and the element in it.
struct SlotAt {
    part: u32,
    slot: u32,
}

// Where slot s of history row r is.
fn slot_at(r: u32, s: u32) -> SlotAt {
    let part = r / dem.spheres_per_part;
    return SlotAt(part, (r - part * dem.spheres_per_part) * dem.slots + s);
}

// Sphere p resolving its contacts. Its stable id, old row, old count and the places of its
// slots are found only where contacts keep history (dem.slots > 0), the only use of them.
struct Walker {
    p: u32,              // its place in the walk (the stencil walk's sorted place)
    h: u32,              // its state index, its row of the new history
    s: vec4<f32>,        // centre, radius
    a: u32,              // stable id
    row_old: u32,        // its row of the old history
    kept: u32,           // its contacts in the old history
    own_old: SlotAt,     // where its old slot 0 is
    own_new: SlotAt,     // where its new slot 0 goes
    me: Body,
    force: vec3<f32>,
    torque: vec3<f32>,
    touching: u32,       // touching spheres it resolved
    held: u32,           // contacts with history (spheres it owns and walls)
    waiting: u32,        // candidates within reach met (dem_grid_granular.wgsl)
    list_from: u32,      // the first of them its list holds (dem_grid_granular.wgsl)
}

// The walker of the sphere at place p of the walk, state index h, centre and radius s.
fn walker(p: u32, h: u32, s: vec4<f32>) -> Walker {
    var a = 0u;
    var row_old = 0u;
    var kept = 0u;
    var own_old = SlotAt(0u, 0u);
    var own_new = SlotAt(0u, 0u);
    if dem.slots > 0u {
        a = stable_id(h);
        row_old = row_before(h);
        kept = held_old[row_old];
        own_old = slot_at(row_old, 0u);
        own_new = slot_at(h, 0u);
    }
    let me = body_of(s, vel_ro[h], omega_ro[h]);
    return Walker(p, h, s, a, row_old, kept, own_old, own_new, me, vec3(0.0), vec3(0.0), 0u, 0u, 0u, 0u);
}

// The old entry at `at`.
fn old_entry(at: SlotAt) -> Entry {
    if at.part == 0u {
        return entries_old0[at.slot];
    }
    switch at.part {
        case 1u: { return entries_old1[at.slot]; }
        case 2u: { return entries_old2[at.slot]; }
        case 3u: { return entries_old3[at.slot]; }
        case 4u: { return entries_old4[at.slot]; }
        case 5u: { return entries_old5[at.slot]; }
        case 6u: { return entries_old6[at.slot]; }
        case 7u: { return entries_old7[at.slot]; }
        default: { return entries_old0[at.slot]; }
    }
}

// The partner of the old entry at `at`.
fn old_partner(at: SlotAt) -> u32 {
    return old_entry(at)[0].w;
}

// The springs of the old entry at `at` times `sign`.
fn springs_of(at: SlotAt, sign: f32) -> Springs {
    return springs_from(old_entry(at), sign);
}

// Writes the new entry at `at`: `partner` and its springs `s`.
fn store_entry(at: SlotAt, partner: u32, s: Springs) {
    let e = entry_of(partner, s);
    if at.part == 0u {
        entries_new0[at.slot] = e;
        return;
    }
    switch at.part {
        case 1u: { entries_new1[at.slot] = e; }
        case 2u: { entries_new2[at.slot] = e; }
        case 3u: { entries_new3[at.slot] = e; }
        case 4u: { entries_new4[at.slot] = e; }
        case 5u: { entries_new5[at.slot] = e; }
        case 6u: { entries_new6[at.slot] = e; }
        case 7u: { entries_new7[at.slot] = e; }
        default: { entries_new0[at.slot] = e; }
    }
}

// The walker's old slot of its contact with `partner` (a sphere's stable id or a wall), or
// `kept` where it holds none. A row holds a partner once, so where the search starts changes
// nothing but its length: it starts at the slot the contact gets in the new row (`held`), where
// it was in the old one if the walk met the same contacts before it, and wraps around.
fn own_old_slot(w: ptr<function, Walker>, partner: u32) -> u32 {
    let at = (*w).own_old;
    let kept = (*w).kept;
    var s = (*w).held;
    for (var k = 0u; k < kept; k += 1u) {
        if s >= kept {
            s = 0u;
        }
        if old_partner(SlotAt(at.part, at.slot + s)) == partner {
            return s;
        }
        s += 1u;
    }
    return kept;
}

// The springs in the walker's old slot s.
fn own_old_springs(w: ptr<function, Walker>, s: u32) -> Springs {
    return springs_of(SlotAt((*w).own_old.part, (*w).own_old.slot + s), 1.0);
}

// What a sphere kept of a contact at the last step: its springs, and whether there was one.
struct Recalled {
    springs: Springs,
    held: bool,
}

// The walker's contact with sphere q (state index, stable id b) at the last step: from its own
// old slots, else from q's (negated); none for a new contact.
fn old_contact(w: ptr<function, Walker>, q: u32, b: u32) -> Recalled {
    let own = own_old_slot(w, b);
    if own < (*w).kept {
        return Recalled(own_old_springs(w, own), true);
    }
    let row = row_before(q);
    let at = slot_at(row, 0u);
    for (var s = 0u; s < held_old[row]; s += 1u) {
        let theirs = SlotAt(at.part, at.slot + s);
        if old_partner(theirs) == (*w).a {
            return Recalled(springs_of(theirs, -1.0), true);
        }
    }
    return Recalled(no_springs(), false);
}

// The walker's contact with a wall (FIRST_WALL + wall) at the last step.
fn old_wall_contact(w: ptr<function, Walker>, wall: u32) -> Recalled {
    let own = own_old_slot(w, FIRST_WALL + wall);
    if own < (*w).kept {
        return Recalled(own_old_springs(w, own), true);
    }
    return Recalled(no_springs(), false);
}

// Keeps the contact with `partner` in the walker's next slot, where there is one; counts it.
fn keep_springs(w: ptr<function, Walker>, partner: u32, s: Springs) {
    if (*w).held < dem.slots {
        store_entry(SlotAt((*w).own_new.part, (*w).own_new.slot + (*w).held), partner, s);
    }
    (*w).held += 1u;
}

// Whether sphere t (centre, radius) may touch sphere s, or hold to it (within dem.reach of
// touching, where contacts adhere): the cheap test that rejects most candidates of a walk (they
// need nothing else of their sphere).
fn reaches(s: vec4<f32>, t: vec4<f32>) -> bool {
    let d = t.xyz - s.xyz;
    var reach = s.w + t.w;
    if COHESIVE {
        reach += dem.reach;
    }
    return d.x * d.x + d.y * d.y + d.z * d.z <= reach * reach;
}

// Candidate q (state index; t = its centre and radius) of the walk, resolved where it reaches
// the walker's sphere.
fn meet(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    if reaches((*w).s, t) {
        take(w, contact_with(w, q, t));
    }
}

// Resolves the walker's sphere against sphere q (state index; t = its centre and radius, within
// reach): adds q's force and torque there and keeps the springs in the walker's next slot (a pair
// within reach takes one also where it is no contact: its centres coincide, or it is within
// reach but apart and not held; the slot then names NO_PARTNER). Returns the contact, for the
// walker to take (`take`).
fn contact_with(w: ptr<function, Walker>, q: u32, t: vec4<f32>) -> Contact {
    let other = body_of(t, vel_ro[q], omega_ro[q]);
    var old = Recalled(no_springs(), false);
    var b = 0u;   // q's stable id, where contacts keep history
    if dem.slots > 0u {
        b = stable_id(q);
        old = old_contact(w, q, b);
    }
    let c = pair_contact((*w).me, other, old.springs, old.held);
    if c.touching {
        add_force(q, -c.force);
        if dem.turns != 0u {
            add_torque(q, c.torque_j);
        }
    }
    if dem.slots > 0u {
        keep_springs(w, select(NO_PARTNER, b, c.touching), c.springs);
    }
    return c;
}

// Adds the walker's side of contact c to its sums (nothing where c does not touch).
fn take(w: ptr<function, Walker>, c: Contact) {
    (*w).force += c.force;
    (*w).torque += c.torque_i;
    (*w).touching += u32(c.touching);
}

// The box walls touching the walker's sphere (each axis low wall first, as the cpu step), then
// its force and torque into the accumulators and its history count (the mesh walls' kernel,
// dem_mesh_walls.wgsl, appends to both after this pass); a clump's component notes its row.
fn finish(w: ptr<function, Walker>) {
    let b = (*w).me;
    if mesh.box_walls != 0u {
        let law = law_of(b.material, dem.box_column);
        let wet = bridge_of(b.material, dem.box_column);
        for (var axis = 0u; axis < 3u; axis += 1u) {
            let below = b.r - (b.c[axis] - dem.box_lo[axis]);
            let above = b.r - (dem.box_hi[axis] - b.c[axis]);
            for (var side = 0u; side < 2u; side += 1u) {
                let overlap = select(below, above, side == 1u);
                // Within reach of the wall, a cohesive contact may hold: only then is it looked up.
                let near = overlap > 0.0 || (COHESIVE && -overlap < dem.reach);
                if !near {
                    continue;
                }
                let wall = 2u * axis + side;
                var old = Recalled(no_springs(), false);
                if dem.slots > 0u {
                    old = old_wall_contact(w, wall);
                }
                // A cohesive contact of the last step holds past touching while its law lets it.
                let held = COHESIVE && old.held && holds(law, wet, b.r, overlap);
                if overlap <= 0.0 && !held {
                    continue;
                }
                var n = vec3(0.0);
                n[axis] = select(-1.0, 1.0, side == 1u);
                let c = surface_contact(b, n, overlap, vec3(0.0), law, wet, law.sliding, old.springs);
                (*w).force += c.force;
                (*w).torque += c.torque;
                if dem.slots > 0u {
                    keep_springs(w, FIRST_WALL + wall, c.springs);
                }
            }
        }
    }
    // A sphere that touches nothing (most of those whose contacts others own) adds nothing.
    if any((*w).force != vec3(0.0)) {
        add_force((*w).h, (*w).force);
    }
    if dem.turns != 0u && any((*w).torque != vec3(0.0)) {
        add_torque((*w).h, (*w).torque);
    }
    if CLUMPED {
        note_row(stable_id((*w).h), (*w).h);
    }
    if dem.slots > 0u {
        held_new[(*w).h] = min((*w).held, dem.slots);
        if (*w).held > dem.slots {
            atomicMax(&history_need, (*w).held);
        }
    }
}

// Gravity and one semi-implicit Euler step of positions and angular velocities, in place (the
// walls' forces are in the accumulators already); zeroes the force and torque accumulators (those
// a contact or wall added to), so they are zero between steps.
@compute @workgroup_size(256)
fn integrate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * dem.row;
    if p >= dem.n {
        return;
    }
    integrate_sphere(p);
}

// Integrates sphere p (state index); returns its new centre and radius.
fn integrate_sphere(p: u32) -> vec4<f32> {
    let s = pos[p];
    let v = vel[p];
    var f = load_force(p);
    if any(f != vec3(0.0)) {
        clear_force(p);
    }
    if dem.loaded != 0u {
        f += external_load(stable_id(p), 0u);
    }
    let g = gravity_at(atomicLoad(&clock) - 1u);
    let m = v.w;
    let v_new = v.xyz + dem.dt * (f / m + g);
    vel[p] = vec4(v_new, m);
    let moved = vec4(advance_position(p, s.xyz, dem.dt * v_new), s.w);
    pos[p] = moved;
    if dem.turns != 0u {
        let inertia = moment_of_inertia(m, s.w);
        let torque = load_torque(p);
        if any(torque != vec3(0.0)) {
            clear_torque(p);
        }
        var t = torque;
        if dem.loaded != 0u {
            t += external_load(stable_id(p), 1u);
        }
        let o = omega[p];
        omega[p] = vec4(o.xyz + dem.dt * (t / inertia), o.w);
    }
    return moved;
}
