// Mindlin's no-slip spring as the granular GPU step's tangential model (docs/method.md, "Friction,
// rotation and rolling resistance"): the springs a contact keeps, the history entry that holds
// them and the tangential force. Keep in sync with the `TangentialModel::Mindlin` arm of
// `friction` in src/dem/model/contact.rs, line for line. Composed with dem_contact.wgsl (the
// alternative: dem_tangential_md.wgsl).

// What a contact carries from one step to the next, as the sphere holding it sees it.
struct Springs {
    tangential: vec3<f32>,  // ξ [m]
    rolling: vec3<f32>,     // EPSD rolling torque [N·m]
}

// A slot of the history as bits: ξ x, y, z and the partner's stable id (or a wall), then the
// rolling spring torque x, y, z and 0 (32 bytes, one memory sector).
alias Entry = array<vec4<u32>, 2>;

fn no_springs() -> Springs {
    return Springs(vec3(0.0), vec3(0.0));
}

// The springs of entry e times `sign` (−1: the partner's, as the holder sees them).
fn springs_from(e: Entry, sign: f32) -> Springs {
    return Springs(sign * bitcast<vec3<f32>>(e[0].xyz), sign * bitcast<vec3<f32>>(e[1].xyz));
}

// The entry holding `partner` and its springs `s`.
fn entry_of(partner: u32, s: Springs) -> Entry {
    return Entry(
        vec4(bitcast<vec3<u32>>(s.tangential), partner),
        vec4(bitcast<vec3<u32>>(s.rolling), 0u),
    );
}

// Mindlin's spring: ξ turned into the tangent plane grows by v_t·dt, F_t = −k_t·ξ − c_t·v_t up
// to Coulomb's cap, where ξ = −F_t/k_t. The tangential force on i; the spring into `springs`.
fn tangential_force(
    load: Load,
    n: vec3<f32>,
    v_t: vec3<f32>,
    old: Springs,
) -> Tangential {
    var xi = into_plane(old.tangential, n) + v_t * dem.dt;
    var f_t = -load.k_t * xi - load.c_t * v_t;
    let cap = load.mu * load.pressing;
    let len = length_of(f_t);
    if len > cap {
        f_t *= cap / len;
        xi = -f_t / load.k_t;
    }
    var springs = no_springs();
    springs.tangential = xi;
    return Tangential(f_t, springs);
}
