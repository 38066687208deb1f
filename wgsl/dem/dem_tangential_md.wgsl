// Mindlin and Deresiewicz's load-history dependent stiffness as the granular GPU step's
// tangential model (docs/method.md, "Friction, rotation and rolling resistance"; Thornton & Yin,
// Powder Technol. 65 (1991), as Thornton, Cummins & Cleary, Powder Technol. 210 (2011) restate
// it): the springs a contact keeps, the history entry that holds them and the tangential force.
// Keep in sync with `load_history` in src/dem/model/contact.rs, line for line (its cube_root is
// dem_contact.wgsl's).
// Composed with dem_contact.wgsl (the alternative: dem_tangential_mindlin.wgsl).

// What a contact carries from one step to the next, as the sphere holding it sees it (the
// partner: the vectors negated, the same normal force).
struct Springs {
    tangential: vec3<f32>,  // the elastic tangential force on the sphere [N]
    rolling: vec3<f32>,     // EPSD rolling torque [N·m]
    reversal: vec3<f32>,    // that force at the last reversal [N] (zero: the virgin curve)
    normal: f32,            // the elastic normal force of the last step [N]
}

// A slot of the history as bits: the tangential force x, y, z and the partner's stable id (or a
// wall), the rolling spring torque x, y, z and the normal force, the reversal force x, y, z and
// 0, and 16 bytes unused (64 bytes, two whole memory sectors).
alias Entry = array<vec4<u32>, 4>;

fn no_springs() -> Springs {
    return Springs(vec3(0.0), vec3(0.0), vec3(0.0), 0.0);
}

// The springs of entry e with their vectors times `sign` (−1: the partner's, as the holder sees
// them).
fn springs_from(e: Entry, sign: f32) -> Springs {
    return Springs(
        sign * bitcast<vec3<f32>>(e[0].xyz),
        sign * bitcast<vec3<f32>>(e[1].xyz),
        sign * bitcast<vec3<f32>>(e[2].xyz),
        bitcast<f32>(e[1].w),
    );
}

// The entry holding `partner` and its springs `s`.
fn entry_of(partner: u32, s: Springs) -> Entry {
    return Entry(
        vec4(bitcast<vec3<u32>>(s.tangential), partner),
        vec4(bitcast<vec3<u32>>(s.rolling), bitcast<u32>(s.normal)),
        vec4(bitcast<vec3<u32>>(s.reversal), 0u),
        vec4(0u),
    );
}

// The Mindlin–Deresiewicz tangential force on i (see `load_history` in contact.rs) and the springs
// it keeps.
fn tangential_force(
    load: Load,
    n: vec3<f32>,
    v_t: vec3<f32>,
    old: Springs,
) -> Tangential {
    let mu = load.mu;
    var f = into_plane(old.tangential, n);
    var r = into_plane(old.reversal, n);
    let dn = load.elastic - old.normal;
    let d = v_t * dem.dt;
    // A reversal: the displacement drives the force back towards the last reversal point.
    let back = f - r;
    if length_of(back) > 0.0 && dot3(back, d) > 0.0 {
        r = f;
    }
    // The reversal point follows the normal force; where it shrinks to nothing the virgin
    // curve holds.
    if any(r != vec3<f32>(0.0)) {
        let size = length_of(r);
        let grown = size + mu * dn;
        if grown > 0.0 {
            r = r * (grown / size);
        } else {
            r = vec3<f32>(0.0);
        }
    }
    var c: f32 = 1.0;
    if any(r != vec3<f32>(0.0)) {
        c = 2.0;
    }
    let scale = c * mu * load.elastic;
    let away = f - r;
    let gone = length_of(away);
    let slid = gone + c * mu * dn;
    var theta: f32 = 0.0;
    if scale > 0.0 {
        theta = cube_root(1.0 - slid / scale);
    }
    let step = length_of(d);
    if mu * dn > load.k_t * step {
        theta = 1.0;
    }
    var e = vec3<f32>(0.0);
    if gone > 0.0 {
        e = away / gone;
    } else if step > 0.0 {
        e = d / -step;
    }
    f = f - d * (load.k_t * theta) + e * (mu * dn * (1.0 - theta));
    // Past the mirror point of the last reversal: back on the virgin curve.
    if any(r != vec3<f32>(0.0)) && dot3(f, r) < 0.0 && length_of(f) >= length_of(r) {
        r = vec3<f32>(0.0);
    }
    // Never more than μN: full slip, and the virgin curve from there.
    let most = mu * load.elastic;
    let len = length_of(f);
    if len > most {
        f *= most / len;
        r = vec3<f32>(0.0);
    }
    var f_t = f - load.c_t * v_t;
    let cap = mu * load.pressing;
    let len_t = length_of(f_t);
    if len_t > cap {
        f_t *= cap / len_t;
        f = f_t;
        r = vec3<f32>(0.0);
    }
    return Tangential(f_t, Springs(f, vec3<f32>(0.0), r, load.elastic));
}
