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

// The cohesion laws that are the step's, not a pair's; twin of CohesionParams in
// src/dem/model/law.rs (apart from LawParams, which a dry step keeps as small as it was).
struct CohesionParams {
    bridge_volume: f32,   // V of a liquid bridge [m³] (0: no bridges)
    bridge_tension: f32,  // γ·cos θ of two spheres of the first material [N/m] (bridge_of)
    bridge_rupture: f32,  // the gap at which their bridge ruptures [m]
    density: f32,         // cohesion energy density of LIGGGHTS' simplified JKR [J/m³] (0: none)
    bridge_viscosity: f32,// the bridges' liquid viscosity η [Pa·s] (0: no lubrication force)
}

@group(0) @binding(37) var<uniform> cohesion: CohesionParams;

// The liquid bridge of one ordered pair of materials; twin of PairBridge in
// src/dem/model/materials.rs.
struct PairBridge {
    tension: f32,   // γ·cos θ of the pair [N/m]
    rupture: f32,   // the gap at which the bridge ruptures [m]
    _pad0: f32,
    _pad1: f32,
}

// One entry of the material table; twin of TableLaw in src/dem/model/materials.rs.
struct TableLaw {
    law: PairLaw,
    bridge: PairBridge,
}

// Row a (a sphere of material a), column b (a sphere or wall of material b; column
// dem.columns - 1: a rigid wall) at a · dem.columns + b: MaterialTable::device_laws.
@group(0) @binding(20) var<storage, read> material_laws: array<TableLaw>;

// The law of a sphere of material a against column b of the table (MaterialTable::law).
fn law_of(a: u32, b: u32) -> PairLaw {
    return material_laws[a * dem.columns + b].law;
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

// The liquid bridge of a sphere of material a against column b of the table
// (MaterialTable::bridge); with one material every pair's is the cohesion uniform's.
fn bridge_of(a: u32, b: u32) -> PairBridge {
    if ONE_MATERIAL {
        return PairBridge(cohesion.bridge_tension, cohesion.bridge_rupture, 0.0, 0.0);
    }
    return material_laws[a * dem.columns + b].bridge;
}

const LAW_LINEAR: u32 = 0u;
const LAW_PER_PAIR: u32 = 1u;
const LAW_HERTZ: u32 = 2u;
const ROLLING_EPSD: u32 = 0u;
const ROLLING_CONSTANT_TORQUE: u32 = 1u;

// 2·√(5/6): Tsuji's damping coefficient over ζ·√(S·m*).
const TSUJI: f32 = 1.8257419;
// π in f32 (typed: products with it are rounded to f32 as the Rust law's are).
const PI: f32 = 3.1415927;
// Most Newton steps of jkr_radius (JKR_ITERATIONS in src/dem/model/contact.rs).
const JKR_ITERATIONS: u32 = 12u;

// True where some contact adheres (JKR, liquid bridges, simplified JKR; set when the pipeline
// is made, DemModule::constants): without it the compiler drops the cohesion laws, and a
// contact is one that touches.
override COHESIVE: bool = false;

// A sphere as its contacts see it.
struct Body {
    c: vec3<f32>,
    v: vec3<f32>,
    w: vec3<f32>,   // angular velocity
    r: f32,
    m: f32,
    material: u32,  // its row of the material table
}

// The normal force's magnitude (≥ 0 for a dry contact: it pushes or does nothing; a JKR neck
// pulls), its elastic part (no damping) and the normal stiffness; the load that caps friction
// and rolling (the push, or with JKR the push plus twice the pull-off force, plus a bridge's
// pull) and JKR's contact radius (0 for the other laws).
struct Normal {
    push: f32,
    elastic: f32,
    stiffness: f32,
    load: f32,
    radius: f32,
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
    pressing: f32,  // the normal force that caps the tangential one (the load, ≥ 0)
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

// ∛x of a normal x > 0: a start from the bits, then three Newton steps (0 for x ≤ 0). Keep in
// sync with `cube_root` in src/dem/model/contact.rs.
fn cube_root(x: f32) -> f32 {
    if x <= 0.0 {
        return 0.0;
    }
    var y = bitcast<f32>(bitcast<u32>(x) / 3u + 0x2a5137a0u);
    y = (y + y + x / (y * y)) / 3.0;
    y = (y + y + x / (y * y)) / 3.0;
    y = (y + y + x / (y * y)) / 3.0;
    return y;
}

// The pull-off force of a JKR contact, 1.5·π·Γ·R* (contact.rs jkr_pull_off).
fn jkr_pull_off(r_eff: f32, adhesion: f32) -> f32 {
    return 1.5 * PI * adhesion * r_eff;
}

// The (negative) overlap at which a JKR neck breaks (contact.rs jkr_break).
fn jkr_break(r_eff: f32, e_star: f32, adhesion: f32) -> f32 {
    let g = PI * adhesion / e_star;
    return -0.75 * cube_root(g * g * r_eff);
}

// JKR's contact radius at `overlap` by Newton's method on x = √a (contact.rs jkr_radius).
fn jkr_radius(overlap: f32, r_eff: f32, e_star: f32, adhesion: f32) -> f32 {
    let c = sqrt(2.0 * PI * adhesion / e_star);
    var x = max(sqrt(sqrt(2.0 * r_eff * max(overlap, 0.0))), cube_root(2.0 * c * r_eff));
    for (var k = 0u; k < JKR_ITERATIONS; k += 1u) {
        let x3 = x * x * x;
        let slope = 4.0 * x3 / r_eff - c;
        if slope <= 0.0 {
            break;
        }
        let next = x - (x3 * x / r_eff - c * x - overlap) / slope;
        // Converged: every later step would repeat this one.
        if next == x {
            break;
        }
        x = next;
    }
    return x * x;
}

// Whether a contact of `law` and bridge `wet` that held at the last step and now overlaps by
// `overlap` ≤ 0 still holds: a JKR neck not yet broken, a liquid bridge not yet ruptured
// (contact.rs holds).
fn holds(law: PairLaw, wet: PairBridge, r_eff: f32, overlap: f32) -> bool {
    return (law.adhesion > 0.0 && overlap > jkr_break(r_eff, law.e_star, law.adhesion))
        || (cohesion.bridge_volume > 0.0 && -overlap < wet.rupture);
}

// The pull of a liquid bridge wetting the pair as `wet` says between bodies of effective
// radius r_eff overlapping by `overlap` (a gap where negative); 0 without bridges (contact.rs
// bridge_pull).
fn bridge_pull(wet: PairBridge, r_eff: f32, overlap: f32) -> f32 {
    let volume = cohesion.bridge_volume;
    if volume == 0.0 {
        return 0.0;
    }
    let r = 2.0 * r_eff;
    let s = 0.5 * max(-overlap, 0.0) * sqrt(r / volume);
    return 2.0 * PI * r * wet.tension / (1.0 + 2.1 * s + 10.0 * s * s);
}

// The smallest gap a bridge's lubrication force takes, a fraction of R* (contact.rs BRIDGE_MIN_GAP).
const BRIDGE_MIN_GAP: f32 = 0.01;

// Set where the bridges' liquid has a viscosity (its lubrication force compiled in: the other
// cohesive steps keep their registers).
override VISCOUS: bool = false;

// The lubrication force of a liquid bridge between bodies of effective radius r_eff overlapping
// by `overlap` whose gap grows at `vn`: 6π·η·R*²·v_n/s, pulling them together where positive; 0
// without a viscosity (contact.rs bridge_drag).
fn bridge_drag(r_eff: f32, overlap: f32, vn: f32) -> f32 {
    let eta = cohesion.bridge_viscosity;
    if !VISCOUS || eta == 0.0 {
        return 0.0;
    }
    let gap = max(-overlap, BRIDGE_MIN_GAP * r_eff);
    return 6.0 * PI * eta * r_eff * (r_eff / gap) * vn;
}

// `along` with a bridge's `drag` added, where there is one (contact.rs dragged).
fn dragged(along: f32, drag: f32) -> f32 {
    if drag != 0.0 {
        return along + drag;
    }
    return along;
}

// The pull of a bridge and of the simplified JKR on a sphere of radius r against a surface it
// overlaps by `overlap` (the area where they meet a circle in the surface's plane).
fn surface_pull(wet: PairBridge, r: f32, overlap: f32) -> f32 {
    var pull = bridge_pull(wet, r, overlap);
    if cohesion.density > 0.0 && overlap > 0.0 {
        pull += cohesion.density * PI * overlap * (2.0 * r - overlap);
    }
    return pull;
}

// The normal force of a contact of law `law` with overlap `overlap` (> 0, or ≤ 0 on a JKR neck)
// and normal relative velocity `vn`.
fn normal_force(law: PairLaw, overlap: f32, vn: f32, m_eff: f32, r_eff: f32) -> Normal {
    if dem.law == LAW_LINEAR {
        let c = 2.0 * law.damping_ratio * root_product(dem.stiffness, m_eff);
        let elastic = dem.stiffness * overlap;
        let push = max(elastic - c * vn, 0.0);
        return Normal(push, elastic, dem.stiffness, push, 0.0);
    }
    if dem.law == LAW_PER_PAIR {
        let k = m_eff * law.rate;
        let c = 2.0 * law.damping_ratio * root_product(k, m_eff);
        let elastic = k * overlap;
        let push = max(elastic - c * vn, 0.0);
        return Normal(push, elastic, k, push, 0.0);
    }
    if COHESIVE && law.adhesion > 0.0 {
        // JKR: the contact radius of the overlap, its force (a pull on the neck and at small
        // overlaps) and Tsuji's damping with the stiffness 2E*a; no clamp, the neck pulls.
        let a = jkr_radius(overlap, r_eff, law.e_star, law.adhesion);
        let s_n = 2.0 * law.e_star * a;
        let c = TSUJI * law.damping_ratio * root_product(s_n, m_eff);
        let elastic = 2.0 / 3.0 * s_n * a * a / r_eff
            - sqrt(8.0 * PI * law.adhesion * law.e_star * a * a * a);
        let push = elastic - c * vn;
        let load = max(push + 2.0 * jkr_pull_off(r_eff, law.adhesion), 0.0);
        return Normal(push, elastic, s_n, load, a);
    }
    let s_n = 2.0 * law.e_star * sqrt(r_eff * overlap);
    let c = TSUJI * law.damping_ratio * root_product(s_n, m_eff);
    let elastic = 2.0 / 3.0 * s_n * overlap;
    let push = max(elastic - c * vn, 0.0);
    return Normal(push, elastic, s_n, push, 0.0);
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
    let pressing = t.normal.load;
    let elastic = t.normal.elastic;
    var out = Friction(vec3(0.0), vec3(0.0), no_springs());
    if mu > 0.0 {
        var k_t: f32;
        var c_t: f32;
        if dem.law == LAW_HERTZ {
            var a = t.normal.radius;
            if !(COHESIVE && law.adhesion > 0.0) {
                a = sqrt(t.r_eff * t.overlap);
            }
            k_t = 8.0 * law.g_star * a;
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

// The contact of sphere i with sphere j from i's side, given the springs i kept of it (`old`);
// `bonded`: whether they were in contact at the last step, where a cohesive pair may hold
// beyond touching (contact.rs pair_contact).
fn pair_contact(i: Body, j: Body, old: Springs, bonded: bool) -> Contact {
    var out = Contact(false, vec3(0.0), vec3(0.0), vec3(0.0), no_springs());
    let d = j.c - i.c;
    let d2 = d.x * d.x + d.y * d.y + d.z * d.z;
    let reach = i.r + j.r;
    let apart = d2 > reach * reach;
    if (apart && !(COHESIVE && bonded)) || d2 == 0.0 {
        return out;
    }
    let dist = sqrt(d2);
    let n = d / dist;
    // GPU square roots may round up by an ulp or two (they are not correctly rounded): a pair
    // just touching could get a negative overlap, whose Hertz √(R·δ) is NaN.
    var overlap = reach - dist;
    if !apart {
        overlap = max(overlap, 0.0);
    }
    let vn = dot3(j.v - i.v, n);
    let m_eff = effective(i.m, j.m);
    let r_eff = effective(i.r, j.r);
    let law = sphere_law(i.material, j.material);
    var pull = 0.0;
    var drag = 0.0;
    if COHESIVE {
        let wet = bridge_of(i.material, j.material);
        if apart && !holds(law, wet, r_eff, overlap) {
            return out;
        }
        pull = bridge_pull(wet, r_eff, overlap);
        drag = bridge_drag(r_eff, overlap, vn);
        if cohesion.density > 0.0 && !apart {
            // The area of the circle where the two spheres' surfaces meet (symmetric in i, j).
            let spread = abs(i.r - j.r);
            let area =
                PI / 4.0 * ((reach - dist) * (reach + dist) * (dist - spread) * (dist + spread)) / d2;
            pull += cohesion.density * max(area, 0.0);
        }
        if apart && law.adhesion == 0.0 {
            // A liquid bridge across a gap: its pull alone, and its drag.
            out.touching = true;
            out.force = dragged(pull, drag) * n;
            return out;
        }
    }
    var normal = normal_force(law, overlap, vn, m_eff, r_eff);
    out.touching = true;
    out.force = -normal.push * n;
    if COHESIVE {
        var along = -normal.push;
        if pull > 0.0 {
            // The pull presses the contact as a load does.
            normal.load += pull;
            along = pull - normal.push;
        }
        out.force = dragged(along, drag) * n;
    }
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
// overlap `overlap` (> 0, or ≤ 0 for a cohesive contact that holds), its point there moving at
// `velocity`, of law `law` and bridge `wet` (b's material's row, the surface's column) and
// sliding friction `mu`; friction only where spheres turn (contact.rs surface_contact).
fn surface_contact(
    b: Body,
    n: vec3<f32>,
    overlap: f32,
    velocity: vec3<f32>,
    law: PairLaw,
    wet: PairBridge,
    mu: f32,
    old: Springs,
) -> SurfaceContact {
    var out = SurfaceContact(vec3(0.0), vec3(0.0), no_springs());
    // v_n as for a pair: the partner's (the surface's) velocity minus b's, along n.
    let vn = dot3(velocity - b.v, n);
    var pull = 0.0;
    var drag = 0.0;
    if COHESIVE {
        pull = surface_pull(wet, b.r, overlap);
        drag = bridge_drag(b.r, overlap, vn);
        if overlap <= 0.0 && law.adhesion == 0.0 {
            // A liquid bridge across a gap: its pull alone, and its drag.
            out.force = dragged(pull, drag) * n;
            return out;
        }
    }
    var nf = normal_force(law, overlap, vn, b.m, b.r);
    out.force = -nf.push * n;
    if COHESIVE {
        var along = -nf.push;
        if pull > 0.0 {
            nf.load += pull;
            along = pull - nf.push;
        }
        out.force = dragged(along, drag) * n;
    }
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
