// The contact law of the granular GPU step (docs/method.md, "Contact laws", "Friction, rotation
// and rolling resistance"): linear (one stiffness or per pair) or Hertz normal force, tangential
// force with Coulomb cap, torque, rolling resistance (EPSD or constant torque), each contact's
// coefficients from the material table (`law_of`). Keep in sync with
// src/dem/model/contact.rs, line for line: the same formulas in the same order, in f32. Needs
// dem_params.wgsl prepended and a tangential model: dem_tangential_mindlin.wgsl (Mindlin's
// spring) or dem_tangential_md.wgsl (Mindlin–Deresiewicz), which define the springs a contact
// keeps (`Springs`, `no_springs`), the history entry that holds them (`Entry`, `springs_from`,
// `entry_of`) and the tangential force (`tangential_force`). Unlike the cpu step, which computes a pair from both sides, the GPU
// steps compute it once, from its owner's side, and give the partner the negated force and its
// own torque (what the cpu computes from the partner's side: its operations see exactly negated
// inputs).

// Row a (a sphere of material a), column b (a sphere or wall of material b; column
// dem.columns - 1: a rigid wall) at a · dem.columns + b: MaterialTable::laws.
@group(0) @binding(20) var<storage, read> material_laws: array<PairLaw>;

// The law of a sphere of material a against column b of the table (MaterialTable::law).
fn law_of(a: u32, b: u32) -> PairLaw {
    return material_laws[a * dem.columns + b];
}

// True where the scene has one material (set when the pipeline is made, DemModule::constants):
// the compiler then drops every sphere's material (0) and its lookups, and every pair's law is
// the uniform's copy of the table's first row.
override ONE_MATERIAL: bool = false;

// The law of two spheres of materials a and b.
fn sphere_law(a: u32, b: u32) -> PairLaw {
    if ONE_MATERIAL {
        return dem.sphere_law;
    }
    return law_of(a, b);
}

const LAW_LINEAR: u32 = 0u;
const LAW_PER_PAIR: u32 = 1u;
const LAW_HERTZ: u32 = 2u;
const ROLLING_EPSD: u32 = 0u;
const ROLLING_CONSTANT_TORQUE: u32 = 1u;

// 2·√(5/6): Tsuji's damping coefficient over ζ·√(S·m*).
const TSUJI: f32 = 1.8257419;

// A sphere as its contacts see it.
struct Body {
    c: vec3<f32>,
    v: vec3<f32>,
    w: vec3<f32>,   // angular velocity
    r: f32,
    m: f32,
    material: u32,  // its row of the material table
}

// The normal force's magnitude (≥ 0: a dry contact pushes or does nothing, it never pulls),
// its elastic part (no damping) and the normal stiffness.
struct Normal {
    push: f32,
    elastic: f32,
    stiffness: f32,
}

// A touching contact from its owner i's side, as friction needs it.
struct Touch {
    n: vec3<f32>,       // unit normal from i towards its partner
    overlap: f32,
    normal: Normal,
    m_eff: f32,
    r_eff: f32,
    i_eff: f32,         // I_i·I_j/(I_i + I_j), effective(I_i, I_j) (I_i on a wall)
    lever: f32,         // distance from i's centre to the contact point
    v_rel: vec3<f32>,   // velocity of i's surface relative to the partner's at the contact point
    w_rel: vec3<f32>,   // ω_i − ω_j (ω_i on a wall)
}

// What the tangential force of a contact needs besides its springs.
struct Load {
    k_t: f32,       // Mindlin's full tangential stiffness
    c_t: f32,       // tangential damping coefficient
    mu: f32,        // sliding friction coefficient
    elastic: f32,   // elastic normal force N
    pressing: f32,  // the normal force that caps the tangential one (push, ≥ 0)
}

// The tangential force on i and the springs it keeps (their rolling torque zero).
struct Tangential {
    force: vec3<f32>,
    springs: Springs,
}

// What friction does: the tangential force on i, the rolling torque on i (the partner gets
// its negative) and the springs i keeps.
struct Friction {
    force: vec3<f32>,
    rolling: vec3<f32>,
    springs: Springs,
}

// What one contact does: the force on i (its partner gets the negative), the torques on i and
// on its partner j, the springs i keeps; `touching` false for no contact (all else zero).
struct Contact {
    touching: bool,
    force: vec3<f32>,
    torque_i: vec3<f32>,
    torque_j: vec3<f32>,
    springs: Springs,
}

fn moment_of_inertia(m: f32, r: f32) -> f32 {
    return 0.4 * m * r * r;
}

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// The length of v without squaring anything below its largest component s: s·|v/s| (|v|²
// underflows f32 for the forces and torques of small spheres); 0 for the zero vector. Keep in
// sync with `length` in src/dem/model/contact.rs.
fn length_of(v: vec3<f32>) -> f32 {
    let s = max(max(abs(v.x), abs(v.y)), abs(v.z));
    if s > 0.0 {
        let u = v / s;
        return s * sqrt(dot3(u, u));
    }
    return 0.0;
}

// The normal force of a contact of law `law` with overlap `overlap` > 0 and normal relative
// velocity `vn`.
fn normal_force(law: PairLaw, overlap: f32, vn: f32, m_eff: f32, r_eff: f32) -> Normal {
    if dem.law == LAW_LINEAR {
        let c = 2.0 * law.damping_ratio * root_product(dem.stiffness, m_eff);
        let elastic = dem.stiffness * overlap;
        return Normal(max(elastic - c * vn, 0.0), elastic, dem.stiffness);
    }
    if dem.law == LAW_PER_PAIR {
        let k = m_eff * law.rate;
        let c = 2.0 * law.damping_ratio * root_product(k, m_eff);
        let elastic = k * overlap;
        return Normal(max(elastic - c * vn, 0.0), elastic, k);
    }
    let s_n = 2.0 * law.e_star * sqrt(r_eff * overlap);
    let c = TSUJI * law.damping_ratio * root_product(s_n, m_eff);
    let elastic = 2.0 / 3.0 * s_n * overlap;
    return Normal(max(elastic - c * vn, 0.0), elastic, s_n);
}

// `x` turned into the plane normal to `n`: its normal part removed, its length kept.
fn into_plane(x: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let t = x - dot3(x, n) * n;
    let len = length_of(t);
    if len > 0.0 {
        return t * (length_of(x) / len);
    }
    return t;
}

// Tangential force of a contact of law `law` with sliding coefficient `mu`, rolling torque and
// the springs to keep.
fn friction(t: Touch, law: PairLaw, mu: f32, old: Springs) -> Friction {
    let n = t.n;
    let pressing = t.normal.push;
    let elastic = t.normal.elastic;
    var out = Friction(vec3(0.0), vec3(0.0), no_springs());
    if mu > 0.0 {
        var k_t: f32;
        var c_t: f32;
        if dem.law == LAW_HERTZ {
            k_t = 8.0 * law.g_star * sqrt(t.r_eff * t.overlap);
            c_t = TSUJI * law.damping_ratio * root_product(k_t, t.m_eff);
        } else {
            k_t = 2.0 / 7.0 * t.normal.stiffness;
            c_t = 2.0 * law.damping_ratio * root_product(k_t, t.m_eff);
        }
        let v_t = t.v_rel - dot3(t.v_rel, n) * n;
        let tangential = tangential_force(Load(k_t, c_t, mu, elastic, pressing), n, v_t, old);
        out.force = tangential.force;
        out.springs = tangential.springs;
    }
    let mu_r = law.rolling;
    if mu_r > 0.0 {
        let w_roll = t.w_rel - dot3(t.w_rel, n) * n;
        let cap = mu_r * t.r_eff * pressing;
        if dem.rolling_model == ROLLING_EPSD {
            let k_r = 2.25 * t.normal.stiffness * mu_r * mu_r * t.r_eff * t.r_eff;
            var m = into_plane(old.rolling, n) - k_r * dem.dt * w_roll;
            let len = length_of(m);
            if len > cap {
                m *= cap / len;
            }
            out.springs.rolling = m;
            out.rolling = m;
        } else {
            let speed = length_of(w_roll);
            if speed > 0.0 {
                // Never more than stops the relative rolling within the step.
                let size = min(cap, t.i_eff * speed / dem.dt);
                out.rolling = w_roll * (-size / speed);
            }
        }
    }
    return out;
}

// The contact of sphere i with sphere j from i's side, given the springs i kept of it (`old`).
fn pair_contact(i: Body, j: Body, old: Springs) -> Contact {
    var out = Contact(false, vec3(0.0), vec3(0.0), vec3(0.0), no_springs());
    let d = j.c - i.c;
    let d2 = d.x * d.x + d.y * d.y + d.z * d.z;
    let reach = i.r + j.r;
    if d2 > reach * reach || d2 == 0.0 {
        return out;
    }
    let dist = sqrt(d2);
    let n = d / dist;
    // GPU square roots may round up by an ulp or two (they are not correctly rounded): a pair
    // just touching could get a negative overlap, whose Hertz √(R·δ) is NaN.
    let overlap = max(reach - dist, 0.0);
    let vn = dot3(j.v - i.v, n);
    let m_eff = effective(i.m, j.m);
    let r_eff = effective(i.r, j.r);
    let law = sphere_law(i.material, j.material);
    let normal = normal_force(law, overlap, vn, m_eff, r_eff);
    out.touching = true;
    out.force = -normal.push * n;
    if dem.turns == 0u {
        return out;
    }
    let touch = Touch(
        n,
        overlap,
        normal,
        m_eff,
        r_eff,
        effective(moment_of_inertia(i.m, i.r), moment_of_inertia(j.m, j.r)),
        i.r,
        (i.v + cross(i.w, i.r * n)) - (j.v - cross(j.w, j.r * n)),
        i.w - j.w,
    );
    let f = friction(touch, law, law.sliding, old);
    out.force += f.force;
    out.torque_i = cross(i.r * n, f.force) + f.rolling;
    // From j's side: lever r_j along −n, force −F_t, rolling torque −M.
    out.torque_j = cross(j.r * n, f.force) - f.rolling;
    out.springs = f.springs;
    return out;
}

// What a surface (a box wall, a mesh wall's point) does to the sphere touching it: the force
// and torque on the sphere and the springs it keeps.
struct SurfaceContact {
    force: vec3<f32>,
    torque: vec3<f32>,
    springs: Springs,
}

// The surface touching b along the unit normal n (from b's centre towards the surface) with
// overlap `overlap` > 0, its point there moving at `velocity`, of law `law` (b's material's row,
// the surface's column) and sliding friction `mu`; friction only where spheres turn.
fn surface_contact(
    b: Body,
    n: vec3<f32>,
    overlap: f32,
    velocity: vec3<f32>,
    law: PairLaw,
    mu: f32,
    old: Springs,
) -> SurfaceContact {
    // v_n as for a pair: the partner's (the surface's) velocity minus b's, along n.
    let nf = normal_force(law, overlap, dot3(velocity - b.v, n), b.m, b.r);
    var out = SurfaceContact(-nf.push * n, vec3(0.0), no_springs());
    if dem.turns == 0u {
        return out;
    }
    let touch = Touch(
        n,
        overlap,
        nf,
        b.m,
        b.r,
        moment_of_inertia(b.m, b.r),
        b.r,
        b.v + cross(b.w, b.r * n) - velocity,
        b.w,
    );
    let f = friction(touch, law, mu, old);
    out.force += f.force;
    out.torque = cross(b.r * n, f.force) + f.rolling;
    out.springs = f.springs;
    return out;
}
