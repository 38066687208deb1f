// The granular GPU step's state beyond the paper's (docs/method.md, "Contact history"): angular
// velocities, torque accumulators (dem_torque_*.wgsl), the contact history, the owner's walk of
// its contacts and the integration kernel. Needs dem_params.wgsl and dem_contact.wgsl, a
// dem_force_*.wgsl and a dem_torque_*.wgsl; the including shader defines
//   fn stable_id(p: u32) -> u32    the input index of the sphere at state index p
//
// Angular velocities and torques are in state order, as pos and vel (the engine permutes ω with
// them wherever it re-sorts the state), so every kernel reads them where it reads pos and vel.
//
// History: K = granular.slots slots per sphere, indexed by stable id (a re-sort never moves
// them), in two sets of buffers that swap roles every step (old: read, new: written). Slot s of
// the sphere of stable id a holds its partner at element a·K + s of the partners (scanned, 4
// bytes a slot) and its springs, six contiguous floats loaded only for the slot found, in one of
// the spring bindings: part a / P of them at element (a mod P)·K + s, P =
// granular.spheres_per_part (every sphere in part 0 where the springs fit one binding; the
// bindings past the parts in use hold a spare buffer and are never read).
// A pair is resolved once, by its owner (the sphere whose thread finds it); the owner looks the
// pair up in its own old slots, then in the partner's (whose springs are the negatives: the
// owner of a pair changes when the order or the proxy rule's case changes, and an uploaded
// history holds both sides), and writes it to its own new slots. Only the owner writes its
// slots: no atomics. Every contact is counted, also those that do not fit, and history_need
// keeps the most any sphere needed: the host grows K and redoes the steps when it exceeds K.

// Partner ids from here on name the walls (src/particles/history.rs).
const FIRST_WALL: u32 = 0xfffffffau;

// by state index
@group(0) @binding(18) var<storage, read_write> omega: array<vec4<f32>>;   // ωx, ωy, ωz, 0
// by stable id: contacts held, and per slot the partner's stable id, or FIRST_WALL + wall
@group(0) @binding(20) var<storage, read> partners_old: array<u32>;
@group(0) @binding(21) var<storage, read> held_old: array<u32>;
@group(0) @binding(22) var<storage, read_write> partners_new: array<u32>;
@group(0) @binding(23) var<storage, read_write> held_new: array<u32>;
// The most contacts with history any sphere had since the host cleared it.
@group(0) @binding(24) var<storage, read_write> history_need: atomic<u32>;
// per slot: the tangential spring ξ [m] x, y, z, then the rolling spring torque [N·m] x, y, z
@group(0) @binding(26) var<storage, read> springs_old0: array<array<f32, 6>>;
@group(0) @binding(27) var<storage, read> springs_old1: array<array<f32, 6>>;
@group(0) @binding(28) var<storage, read> springs_old2: array<array<f32, 6>>;
@group(0) @binding(29) var<storage, read> springs_old3: array<array<f32, 6>>;
@group(0) @binding(30) var<storage, read> springs_old4: array<array<f32, 6>>;
@group(0) @binding(31) var<storage, read> springs_old5: array<array<f32, 6>>;
@group(0) @binding(32) var<storage, read_write> springs_new0: array<array<f32, 6>>;
@group(0) @binding(33) var<storage, read_write> springs_new1: array<array<f32, 6>>;
@group(0) @binding(34) var<storage, read_write> springs_new2: array<array<f32, 6>>;
@group(0) @binding(35) var<storage, read_write> springs_new3: array<array<f32, 6>>;
@group(0) @binding(36) var<storage, read_write> springs_new4: array<array<f32, 6>>;
@group(0) @binding(37) var<storage, read_write> springs_new5: array<array<f32, 6>>;

// Where a slot's springs are: the spring binding and the element in it.
struct SpringsAt {
    part: u32,
    slot: u32,
}

// Where slot s of the sphere of stable id a keeps its springs.
fn springs_at(a: u32, s: u32) -> SpringsAt {
    let part = a / granular.spheres_per_part;
    return SpringsAt(part, (a - part * granular.spheres_per_part) * granular.slots + s);
}

// Sphere p resolving its contacts. Its stable id, old count and the place of its springs are
// found only where contacts keep history (granular.slots > 0), the only use of them.
struct Walker {
    p: u32,              // state index
    s: vec4<f32>,        // centre, radius
    a: u32,              // stable id
    kept: u32,           // its contacts in the old history
    own: SpringsAt,      // where the springs of its slot 0 are
    me: Body,
    force: vec3<f32>,
    torque: vec3<f32>,
    touching: u32,       // touching spheres it resolved
    held: u32,           // contacts with history (spheres it owns and walls)
}

fn walker(p: u32) -> Walker {
    var a = 0u;
    var kept = 0u;
    var own = SpringsAt(0u, 0u);
    if granular.slots > 0u {
        a = stable_id(p);
        kept = held_old[a];
        own = springs_at(a, 0u);
    }
    let s = pos[p];
    let v = vel[p];
    let me = Body(s.xyz, v.xyz, omega[p].xyz, s.w, v.w);
    return Walker(p, s, a, kept, own, me, vec3(0.0), vec3(0.0), 0u, 0u);
}

// The old springs at `at` times `sign`.
fn springs_of(at: SpringsAt, sign: f32) -> Springs {
    var x: array<f32, 6>;
    switch at.part {
        case 1u: { x = springs_old1[at.slot]; }
        case 2u: { x = springs_old2[at.slot]; }
        case 3u: { x = springs_old3[at.slot]; }
        case 4u: { x = springs_old4[at.slot]; }
        case 5u: { x = springs_old5[at.slot]; }
        case 0u, default: { x = springs_old0[at.slot]; }
    }
    return Springs(sign * vec3(x[0], x[1], x[2]), sign * vec3(x[3], x[4], x[5]));
}

// Writes `s` as the new springs at `at`.
fn store_springs(at: SpringsAt, s: Springs) {
    let t = s.tangential;
    let r = s.rolling;
    let x = array(t.x, t.y, t.z, r.x, r.y, r.z);
    switch at.part {
        case 1u: { springs_new1[at.slot] = x; }
        case 2u: { springs_new2[at.slot] = x; }
        case 3u: { springs_new3[at.slot] = x; }
        case 4u: { springs_new4[at.slot] = x; }
        case 5u: { springs_new5[at.slot] = x; }
        case 0u, default: { springs_new0[at.slot] = x; }
    }
}

// The springs the walker (stable id a, `kept` old contacts, springs of slot 0 at `own`) kept
// of its contact with `partner` (a sphere's stable id or a wall), from its old slots, else
// from the partner's (negated); zero for a new contact.
fn old_springs(a: u32, kept: u32, own: SpringsAt, partner: u32) -> Springs {
    let k = granular.slots;
    for (var s = 0u; s < kept; s += 1u) {
        if partners_old[a * k + s] == partner {
            return springs_of(SpringsAt(own.part, own.slot + s), 1.0);
        }
    }
    if partner < FIRST_WALL {
        for (var s = 0u; s < held_old[partner]; s += 1u) {
            if partners_old[partner * k + s] == a {
                return springs_of(springs_at(partner, s), -1.0);
            }
        }
    }
    return Springs(vec3(0.0), vec3(0.0));
}

// Keeps the contact with `partner` in the walker's next slot, where there is one; counts it.
fn keep_springs(w: ptr<function, Walker>, partner: u32, s: Springs) {
    let k = granular.slots;
    if (*w).held < k {
        partners_new[(*w).a * k + (*w).held] = partner;
        store_springs(SpringsAt((*w).own.part, (*w).own.slot + (*w).held), s);
    }
    (*w).held += 1u;
}

// Resolves the walker's sphere against sphere q (state index; t = its centre and radius): adds
// q's force and torque there and the walker's to the walker.
fn meet(w: ptr<function, Walker>, q: u32, t: vec4<f32>) {
    // Cheap rejection first: most candidates do not touch (and need nothing else of q).
    let d = t.xyz - (*w).s.xyz;
    let reach = (*w).s.w + t.w;
    if d.x * d.x + d.y * d.y + d.z * d.z > reach * reach {
        return;
    }
    let u = vel[q];
    let other = Body(t.xyz, u.xyz, omega[q].xyz, t.w, u.w);
    var old = Springs(vec3(0.0), vec3(0.0));
    var b = 0u;   // q's stable id, where contacts keep history
    if granular.slots > 0u {
        b = stable_id(q);
        old = old_springs((*w).a, (*w).kept, (*w).own, b);
    }
    let c = pair_contact((*w).me, other, old);
    if !c.touching {
        return;
    }
    add_force(q, -c.force);
    (*w).force += c.force;
    (*w).touching += 1u;
    if granular.turns != 0u {
        add_torque(q, c.torque_j);
        (*w).torque += c.torque_i;
    }
    if granular.slots > 0u {
        keep_springs(w, b, c.springs);
    }
}

// The walls touching the walker's sphere (each axis low wall first, as the cpu step), then its
// force and torque into the accumulators and its history count.
fn finish(w: ptr<function, Walker>) {
    let b = (*w).me;
    var normal = vec3(0.0);
    var tangential = vec3(0.0);
    var torque = vec3(0.0);
    for (var axis = 0u; axis < 3u; axis += 1u) {
        var f = 0.0;
        let below = b.r - (b.c[axis] - dem.box_lo[axis]);
        let above = b.r - (dem.box_hi[axis] - b.c[axis]);
        for (var side = 0u; side < 2u; side += 1u) {
            let overlap = select(below, above, side == 1u);
            if overlap <= 0.0 {
                continue;
            }
            let wall = 2u * axis + side;
            var old = Springs(vec3(0.0), vec3(0.0));
            if granular.slots > 0u {
                old = old_springs((*w).a, (*w).kept, (*w).own, FIRST_WALL + wall);
            }
            let vn = select(b.v[axis], -b.v[axis], side == 1u);
            let c = wall_contact(b, wall, overlap, vn, old);
            f += select(c.push, -c.push, side == 1u);
            tangential += c.tangential;
            torque += c.torque;
            if granular.slots > 0u {
                keep_springs(w, FIRST_WALL + wall, c.springs);
            }
        }
        normal[axis] = f;
    }
    (*w).force += normal;
    (*w).force += tangential;
    (*w).torque += torque;
    add_force((*w).p, (*w).force);
    if granular.turns != 0u {
        add_torque((*w).p, (*w).torque);
    }
    if granular.slots > 0u {
        held_new[(*w).a] = min((*w).held, granular.slots);
        atomicMax(&history_need, (*w).held);
    }
}

// Gravity and one semi-implicit Euler step of positions and angular velocities, in place (the
// walls' forces are in the accumulators already); zeroes the torque accumulators.
@compute @workgroup_size(256)
fn integrate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * dem.row;
    if p >= dem.n {
        return;
    }
    let s = pos[p];
    let v = vel[p];
    let f = load_force(p);
    let g = gravity_at(atomicLoad(&clock) - 1u);
    let m = v.w;
    let v_new = v.xyz + dem.dt * (f / m + g);
    vel[p] = vec4(v_new, m);
    pos[p] = vec4(s.xyz + dem.dt * v_new, s.w);
    if granular.turns != 0u {
        let inertia = moment_of_inertia(m, s.w);
        omega[p] = vec4(omega[p].xyz + dem.dt * (load_torque(p) / inertia), 0.0);
        clear_torque(p);
    }
}
