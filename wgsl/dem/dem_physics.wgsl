// The paper's DEM law (linear spring-dashpot, no friction) shared by the GPU steps: the contact
// and wall forces, which dem_integrate.wgsl's kernel follows, of one stiffness or of a stiffness
// per pair (`stiffness = "per-pair"` without friction or rolling resistance: k = m*·rate, m* the
// contact's effective mass, m_i on a wall, rate the one material's). Keep the formulas in sync
// with the Linear and LinearPerPair arms of normal_force in src/dem/model/contact.rs
// (pair_contact, wall_contacts without friction): the same operations in the same order. Needs
// dem_params.wgsl prepended and a dem_force_*.wgsl (add_force, load_force).

// True where the stiffness is per pair (set when the pipeline is made, DemModule::open): the
// compiler then keeps one of the two stiffnesses.
override PER_PAIR: bool = false;

// The stiffness of a contact of effective mass m_eff (m on a wall).
fn stiffness_of(m_eff: f32) -> f32 {
    if PER_PAIR {
        return m_eff * dem.sphere_law.rate;
    }
    return dem.stiffness;
}

// Force on sphere i from sphere j (xyz) and 1 in w when they touch; zero otherwise.
fn contact_force(c_i: vec3<f32>, v_i: vec3<f32>, r_i: f32, m_i: f32,
                 c_j: vec3<f32>, v_j: vec3<f32>, r_j: f32, m_j: f32) -> vec4<f32> {
    let d = c_j - c_i;
    let d2 = d.x * d.x + d.y * d.y + d.z * d.z;
    let reach = r_i + r_j;
    if d2 > reach * reach || d2 == 0.0 {
        return vec4(0.0);
    }
    let dist = sqrt(d2);
    let n = d / dist;
    let overlap = reach - dist;
    let dv = v_j - v_i;
    let vn = dv.x * n.x + dv.y * n.y + dv.z * n.z;
    let m_eff = effective(m_i, m_j);
    let k = stiffness_of(m_eff);
    let c = 2.0 * dem.damping_ratio * root_product(k, m_eff);
    let push = max(k * overlap - c * vn, 0.0);
    return vec4(-push * n, 1.0);
}

// Force of the box walls on a sphere at c with velocity v, radius r and mass m.
fn wall_force(c: vec3<f32>, v: vec3<f32>, r: f32, m: f32) -> vec3<f32> {
    let k = stiffness_of(m);
    let damping = 2.0 * dem.damping_ratio * root_product(k, m);
    var f = vec3(0.0);
    for (var a = 0; a < 3; a += 1) {
        let below = r - (c[a] - dem.box_lo[a]);
        if below > 0.0 {
            f[a] += max(k * below - damping * v[a], 0.0);
        }
        let above = r - (dem.box_hi[a] - c[a]);
        if above > 0.0 {
            f[a] -= max(k * above + damping * v[a], 0.0);
        }
    }
    return f;
}
