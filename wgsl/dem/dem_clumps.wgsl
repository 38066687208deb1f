// Clumps in the granular GPU step (docs/method.md, "Clumps"): rigid bodies whose component
// spheres are the run's first spheres (stable ids from 0, clump by clump).
// The contact pass never pairs two components of one clump (`one_clump`) and notes where each
// component's state row is (`note_row`); `advance_clumps`, one thread a clump, after the contact
// pass and the walls, sums its components' forces and torques (each force acting at its
// component's centre adds its arm's moment), kicks the momenta, moves the centre, turns the body
// and places its components; the integration of a run with clumps (`integrate_clumped`, and
// the dense grid's `integrate_and_count_clumped`) then leaves the components where they are. The step is the cpu's, src/clump/rigid.rs (`RigidBody::advance`), in f32: the
// centre as a rounded value and its residual (as a sphere's, dem_params.wgsl), the free rotation
// by the symmetric splitting of Dullweber, Leimkuhler & McLachlan (J. Chem. Phys. 107 (1997)
// 5840). Everything here runs only with CLUMPED (a run with clumps): without, the contact
// pass binds clump_of and clump_rows to one unread row each, and every call site tests CLUMPED
// before it computes the stable ids it passes (arguments are evaluated before a call: a dead
// call's would still be read). Appended to the granular step's physics; needs
// dem_params.wgsl, dem_granular.wgsl and the force and torque accumulators.

// True where the run has clumps (DemModule::constants; a constant of the pipelines, which a
// flow event that inserts clumps does not change).
override CLUMPED: bool = false;

// One clump's rigid-body state; twin of ClumpBodyRow in src/engines/common/clumps.rs.
struct ClumpBody {
    centre: vec3<f32>,       // the centre of mass, rounded [m]
    first: u32,              // the stable id of its first component
    residual: vec3<f32>,     // the centre's rounding error (centre + residual is the centre)
    shape: u32,              // its row of clump_shapes
    orientation: vec4<f32>,  // x, y, z, w: the rotation from its principal frame to the world
    velocity: vec3<f32>,     // of the centre [m/s]
    _pad0: u32,
    momentum: vec3<f32>,     // angular momentum about the centre, world frame [kg·m²/s]
    _pad1: u32,
}

// A kind of clump: its mass, principal moments and components; twin of ClumpShapeRow in
// src/engines/common/clumps.rs.
struct ClumpShape {
    moments: vec3<f32>,  // about the principal axes [kg·m²]
    mass: f32,           // [kg]
    first_part: u32,     // its first component's row of clump_parts
    parts: u32,          // its components
    _pad0: u32,
    _pad1: u32,
}

// by component (stable id): its clump
@group(0) @binding(80) var<storage, read> clump_of: array<u32>;
// by component (stable id): its state row this step (written by the contact pass)
@group(0) @binding(81) var<storage, read_write> clump_rows: array<u32>;
// by clump
@group(0) @binding(82) var<storage, read_write> clump_bodies: array<ClumpBody>;
@group(0) @binding(83) var<storage, read> clump_shapes: array<ClumpShape>;
// the components of each shape: centre in the principal frame, radius
@group(0) @binding(84) var<storage, read> clump_parts: array<vec4<f32>>;

// clump_of's entry past the components (its rows are padded to whole 16 bytes with it).
const NO_CLUMP: u32 = 0xffffffffu;

// Whether the sphere of stable id a is a clump's component.
fn is_component(a: u32) -> bool {
    return CLUMPED && a < arrayLength(&clump_of) && clump_of[a] != NO_CLUMP;
}

// Whether the spheres of stable ids a and b are components of one clump: never a pair.
fn one_clump(a: u32, b: u32) -> bool {
    return is_component(a) && is_component(b) && clump_of[a] == clump_of[b];
}

// Notes that the sphere of stable id a is at state row p this step (where it is a component).
fn note_row(a: u32, p: u32) {
    if is_component(a) {
        clump_rows[a] = p;
    }
}

// v turned by the unit quaternion q (x, y, z, w).
fn clump_turned(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let t = 2.0 * cross(q.xyz, v);
    return v + q.w * t + cross(q.xyz, t);
}

// v turned by the inverse of the unit quaternion q.
fn clump_unturned(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    return clump_turned(vec4(-q.xyz, q.w), v);
}

// The flow of the kinetic energy's part L_k²/(2I_k) for h: q turned about its body axis `axis`
// by L_k·h/I_k (RigidBody::turn_about).
fn clump_turn_about(q: vec4<f32>, momentum: vec3<f32>, moments: vec3<f32>, axis: u32, h: f32) -> vec4<f32> {
    let body = clump_unturned(q, momentum);
    let half = 0.5 * body[axis] * h / moments[axis];
    var e = vec3(0.0);
    e[axis] = sin(half);
    let c = cos(half);
    return vec4(q.w * e + c * q.xyz + cross(q.xyz, e), q.w * c - dot(q.xyz, e));
}

// A value as a rounded vector and its rounding error.
struct Rounded {
    value: vec3<f32>,
    error: vec3<f32>,
}

// c + t, rounded, and its rounding error, exactly (`sum_error`, as advance_position).
fn rounded_sum(c: vec3<f32>, t: vec3<f32>) -> Rounded {
    let s = c + t;
    return Rounded(s, vec3(sum_error(c.x, t.x, s.x), sum_error(c.y, t.y, s.y), sum_error(c.z, t.z, s.z)));
}

// One step of clump k, then its components placed at its new pose and given its motion.
@compute @workgroup_size(256)
fn advance_clumps(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = gid.x + gid.y * groups.x * 256u;
    if k >= arrayLength(&clump_bodies) {
        return;
    }
    var b = clump_bodies[k];
    let shape = clump_shapes[b.shape];
    var force = shape.mass * gravity_at(atomicLoad(&clock) - 1u);
    var torque = vec3(0.0);
    for (var j = 0u; j < shape.parts; j += 1u) {
        let a = b.first + j;
        let p = clump_rows[a];
        var f = load_force(p);
        if any(f != vec3(0.0)) {
            clear_force(p);
        }
        var t = vec3(0.0);
        if dem.turns != 0u {
            t = load_torque(p);
            if any(t != vec3(0.0)) {
                clear_torque(p);
            }
        }
        if dem.loaded != 0u {
            f += external_load(a, 0u);
            t += external_load(a, 1u);
        }
        let arm = clump_turned(b.orientation, clump_parts[shape.first_part + j].xyz);
        force += f;
        torque += cross(arm, f) + t;
    }
    b.velocity += force / shape.mass * dem.dt;
    b.momentum += torque * dem.dt;
    let moved = rounded_sum(b.centre, b.velocity * dem.dt + b.residual);
    b.centre = moved.value;
    b.residual = moved.error;
    var q = b.orientation;
    q = clump_turn_about(q, b.momentum, shape.moments, 0u, 0.5 * dem.dt);
    q = clump_turn_about(q, b.momentum, shape.moments, 1u, 0.5 * dem.dt);
    q = clump_turn_about(q, b.momentum, shape.moments, 2u, dem.dt);
    q = clump_turn_about(q, b.momentum, shape.moments, 1u, 0.5 * dem.dt);
    q = clump_turn_about(q, b.momentum, shape.moments, 0u, 0.5 * dem.dt);
    q = normalize(q);
    b.orientation = q;
    clump_bodies[k] = b;
    let w = clump_turned(q, clump_unturned(q, b.momentum) / shape.moments);
    for (var j = 0u; j < shape.parts; j += 1u) {
        let part = clump_parts[shape.first_part + j];
        let arm = clump_turned(q, part.xyz);
        let p = clump_rows[b.first + j];
        let at = rounded_sum(b.centre, arm + b.residual);
        pos[p] = vec4(at.value, part.w);
        pos_lo[p] = vec4(at.error, 0.0);
        vel[p] = vec4(b.velocity + cross(w, arm), shape.mass);
        omega[p] = vec4(w, omega[p].w);
    }
}

// The integration of sphere p of a run with clumps: a component stays where its clump's step
// put it; returns its centre and radius.
fn integrate_or_keep(p: u32) -> vec4<f32> {
    if is_component(stable_id(p)) {
        return pos[p];
    }
    return integrate_sphere(p);
}

// The integration kernel of a run with clumps (a run without them runs dem_granular.wgsl's
// `integrate` as it was: it pays nothing for them).
@compute @workgroup_size(256)
fn integrate_clumped(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * dem.row;
    if p >= dem.n {
        return;
    }
    integrate_or_keep(p);
}
