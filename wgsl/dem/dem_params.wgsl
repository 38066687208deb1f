// What every GPU DEM step shares: its parameters, the state it steps and its clock, and gravity.
// Prepended to dem_physics.wgsl (the paper's law) or to dem_contact.wgsl and dem_granular.wgsl
// (the granular step).

// The step's parameters: the box, gravity, the time step and the contact law. Twin of LawParams
// in src/dem/model/law.rs (tests/bindings.rs compares the layouts).
struct LawParams {
    box_lo: vec3<f32>,
    n: u32,
    box_hi: vec3<f32>,
    row: u32,               // invocations per dispatch row of a 256-wide kernel
    gravity: vec3<f32>,     // at t = 0
    dt: f32,
    stiffness: f32,         // of LAW_LINEAR
    damping_ratio: f32,     // the first material's (the paper's law)
    gravity_spin: f32,      // rad/s about the y axis
    law: u32,               // LAW_* (dem_contact.wgsl)
    rolling_model: u32,     // ROLLING_*
    turns: u32,             // 1 where any contact exerts a torque
    slots: u32,             // history slots per sphere (0: contacts keep no springs)
    spheres_per_part: u32,  // history rows one entry binding holds (dem_granular.wgsl)
    columns: u32,           // laws in a row of the material table: the materials and a rigid wall
    box_column: u32,        // the table's column of the six box walls
    reach: f32,             // how far past touching a contact may hold [m] (0: none adheres)
    loaded: u32,            // 1: some sphere has an external load (read by the integrations)
    sphere_law: PairLaw,    // row 0, column 0 of the table: with one material, every pair's law
}

// The law of one ordered pair of materials; twin of PairLaw in src/dem/model/materials.rs.
struct PairLaw {
    rate: f32,            // k/m* of LAW_PER_PAIR [1/s²]
    e_star: f32,          // E* of LAW_HERTZ [Pa]
    g_star: f32,          // G* of LAW_HERTZ [Pa]
    damping_ratio: f32,   // ζ giving the pair's restitution
    sliding: f32,         // μ
    rolling: f32,         // μ_r
    adhesion: f32,        // Γ of JKR [J/m²] (0: the pair does not adhere)
    _pad1: f32,
}

@group(0) @binding(1) var<uniform> dem: LawParams;
@group(0) @binding(10) var<storage, read_write> pos: array<vec4<f32>>;   // x, y, z, r
@group(0) @binding(11) var<storage, read_write> vel: array<vec4<f32>>;   // vx, vy, vz, mass
// the residuals of the centres in pos: x, y, z, 0 (each coordinate of pos plus its residual is
// the position; bound only where the state moves: the integration and the passes that move it)
@group(0) @binding(34) var<storage, read_write> pos_lo: array<vec4<f32>>;
// steps begun since t = 0
@group(0) @binding(16) var<storage, read_write> clock: atomic<u32>;
// by stable id k (fn stable_id of the step's module): sphere k's external force at row 2k and its
// torque at row 2k + 1 (x, y, z, 0), read only where dem.loaded is 1 (bound to one empty pair of
// rows otherwise)
@group(0) @binding(36) var<storage, read> external_loads: array<vec4<f32>>;

// The external force (`row` 0) or torque (1) of the sphere of stable id `id`.
fn external_load(id: u32, row: u32) -> vec3<f32> {
    return external_loads[2u * id + row].xyz;
}

// The effective value a·b/(a + b) of two positive values (m*, R*, I*) without their product,
// which underflows f32 for small spheres: lo/(1 + lo/hi), symmetric in a and b. Keep in sync with
// `effective` in src/dem/model/contact.rs.
fn effective(a: f32, b: f32) -> f32 {
    let lo = min(a, b);
    let hi = max(a, b);
    return lo / (1.0 + lo / hi);
}

// √(a·b) without the product, which underflows (or overflows) f32: √a·√b. Keep in sync with
// `root_product` in src/dem/model/contact.rs.
fn root_product(a: f32, b: f32) -> f32 {
    return sqrt(a) * sqrt(b);
}

// Moves the position of sphere p, its centre c (pos[p].xyz) plus its residual pos_lo[p], by the
// displacement d; returns the new centre and writes the new residual. The displacement and the
// residual are added first, then to the centre: the new centre is the rounded sum, the new
// residual its rounding error, exactly (`sum_error`), so no displacement is lost however small.
// Keep in sync with `advance` in src/particles/position.rs: the same sums, the same bits.
fn advance_position(p: u32, c: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let t = d + pos_lo[p].xyz;
    let s = c + t;
    let lo = vec3(sum_error(c.x, t.x, s.x), sum_error(c.y, t.y, s.y), sum_error(c.z, t.z, s.z));
    pos_lo[p] = vec4(lo, 0.0);
    return s;
}

// The rounding error of the sum s = a + b of two finite f32, exactly: (a + b) − s, computed in
// integers from their bits. The float TwoSum of src/particles/position.rs gives the same value
// from six additions, but a shader compiler may simplify those away ((a + b) − a → b: Vulkan lets
// it reassociate additions that SPIR-V does not mark NoContraction, which WGSL cannot ask for,
// and Mesa's compiler does), where it must keep integer arithmetic. a, b and s are whole
// multiples of 2^k, k the lower of a's and b's last bits, and the error is one below 2^25 of
// them: the sum of their multiples modulo 2^32 is it. An error below 2^-126 (a sum of 1e-38 m
// and less) is dropped. Keep in sync with `sum_error_by_bits` in src/particles/position.rs.
fn sum_error(a: f32, b: f32, s: f32) -> f32 {
    if a == 0.0 || b == 0.0 {
        return 0.0; // the sum is exact
    }
    let k = min(last_bit(a), last_bit(b));
    if k < -126 {
        return 0.0;
    }
    let e = bitcast<i32>(multiple_of(a, k) + multiple_of(b, k) - multiple_of(s, k));
    return f32(e) * bitcast<f32>(u32(k + 127) << 23u);
}

// The exponent of the last bit of the significand of a finite f32.
fn last_bit(x: f32) -> i32 {
    let field = i32((bitcast<u32>(x) >> 23u) & 0xffu);
    return max(field, 1) - 150;
}

// x / 2^k modulo 2^32, as two's complement (x a whole multiple of 2^k).
fn multiple_of(x: f32, k: i32) -> u32 {
    let bits = bitcast<u32>(x);
    let field = (bits >> 23u) & 0xffu;
    let m = select(bits & 0x7fffffu, (bits & 0x7fffffu) | 0x800000u, field != 0u);
    let shift = last_bit(x) - k;
    var v = 0u;
    if shift >= 0 && shift < 32 {
        v = m << u32(shift);
    } else if shift < 0 && shift > -32 {
        v = m >> u32(-shift);
    }
    return select(v, 0u - v, (bits & 0x80000000u) != 0u);
}

// Gravity at step `step`, turned about the y axis by gravity_spin · t.
fn gravity_at(step: u32) -> vec3<f32> {
    let angle = dem.gravity_spin * (f32(step) * dem.dt);
    let s = sin(angle);
    let c = cos(angle);
    let g = dem.gravity;
    return vec3(g.x * c + g.z * s, g.y, g.z * c - g.x * s);
}
