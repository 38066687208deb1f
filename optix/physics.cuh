// The DEM physics of the optix backend's step: parameters, contact and wall forces, gravity.
// LawParams is checked against its Rust twin by the layout asserts of
// src/engines/optix/launches.rs; the formulas follow src/dem/model/contact.rs, line for line.

// The law of one ordered pair of materials (PairLaw in src/dem/model/materials.rs, 32 bytes,
// uploaded as it is; 16-byte aligned on the device, where the table starts 256-byte aligned).
struct alignas(16) MochiPairLaw {
    float rate;           // k/m* of MOCHI_LAW_LINEAR_PER_PAIR [1/s²]
    float e_star;         // E* of Hertz–Mindlin [Pa]
    float g_star;         // G* of Hertz–Mindlin [Pa]
    float damping_ratio;  // ζ giving the pair's restitution
    float sliding;        // μ
    float rolling;        // μ_r
    float adhesion;       // Γ of JKR [J/m²] (0: the pair does not adhere)
    float _pad1;
};

// The liquid bridge of one ordered pair of materials (PairBridge in src/dem/model/materials.rs).
struct MochiPairBridge {
    float tension;  // γ·cos θ of the pair [N/m]
    float rupture;  // the gap at which the bridge ruptures [m]
    float _pad0;
    float _pad1;
};

// One entry of the material table: a pair's law and its bridge (TableLaw in
// src/dem/model/materials.rs).
struct alignas(16) MochiTableLaw {
    MochiPairLaw law;
    MochiPairBridge bridge;
};

// The cohesion laws that are the step's, not a pair's (CohesionParams in src/dem/model/law.rs;
// in MochiLaw, contact.cuh: LawParams keeps the size it has without them).
struct MochiCohesion {
    float bridge_volume;   // V of a liquid bridge [m³] (0: no bridges)
    float bridge_tension;  // γ·cos θ of two spheres of the first material [N/m] (the wgpu steps'
                           // with one material; these programs read each pair's in the table)
    float bridge_rupture;  // the gap at which their bridge ruptures [m]
    float density;         // cohesion energy density of LIGGGHTS' simplified JKR [J/m³] (0: none)
    float bridge_viscosity; // the bridges' liquid viscosity η [Pa·s] (0: no lubrication force)
};

// The step's parameters: the box, gravity, the time step and the contact law (LawParams in
// src/dem/model/law.rs, passed by value as it is).
struct LawParams {
    float box_lo[3];
    unsigned int n;
    float box_hi[3];
    unsigned int row;  // unused here (wgpu dispatch rows)
    float gravity[3];  // at t = 0
    float dt;
    float stiffness;      // of MOCHI_LAW_LINEAR
    float damping_ratio;  // the first material's (the paper's law)
    float gravity_spin;   // rad/s about the y axis
    unsigned int law;     // MOCHI_LAW_* (contact.cuh)
    unsigned int rolling_model;  // MOCHI_ROLLING_*
    unsigned int turns;          // 1: contacts exert torques (Friction::turns)
    unsigned int slots;          // history slots per sphere (0: contacts keep no springs)
    unsigned int spheres_per_part;  // unused here (wgpu entry bindings)
    unsigned int columns;        // laws in a row of the material table: the materials and a rigid wall
    unsigned int box_column;     // the box walls' column (their material, or a rigid wall)
    float reach;                 // how far past touching a contact may hold [m] (0: none adheres)
    unsigned int loaded;         // 1: some sphere has an external load (read by the integrations)
    MochiPairLaw sphere_law;     // the table's row 0, column 0
};

// The effective value a·b/(a + b) of two positive values (m*, R*, I*) without their product,
// which underflows f32 for small spheres: lo/(1 + lo/hi), symmetric in a and b (contact.rs
// effective).
static __forceinline__ __device__ float mochi_effective(float a, float b) {
    float lo = fminf(a, b);
    float hi = fmaxf(a, b);
    return lo / (1.0f + lo / hi);
}

// √(a·b) without the product, which underflows (or overflows) f32: √a·√b (contact.rs
// root_product).
static __forceinline__ __device__ float mochi_root_product(float a, float b) {
    return sqrtf(a) * sqrtf(b);
}

// Force on sphere i from sphere j (x, y, z, r and vx, vy, vz, mass each) in xyz, and 1 in w
// when they touch; zero otherwise.
static __forceinline__ __device__ float4 mochi_contact_force(const LawParams& dem, float4 c_i,
                                                             float4 v_i, float4 c_j, float4 v_j) {
    float dx = c_j.x - c_i.x;
    float dy = c_j.y - c_i.y;
    float dz = c_j.z - c_i.z;
    float d2 = dx * dx + dy * dy + dz * dz;
    float reach = c_i.w + c_j.w;
    if (d2 > reach * reach || d2 == 0.0f) {
        return make_float4(0.0f, 0.0f, 0.0f, 0.0f);
    }
    float dist = sqrtf(d2);
    float nx = dx / dist;
    float ny = dy / dist;
    float nz = dz / dist;
    float overlap = reach - dist;
    float vn = (v_j.x - v_i.x) * nx + (v_j.y - v_i.y) * ny + (v_j.z - v_i.z) * nz;
    float m_eff = mochi_effective(v_i.w, v_j.w);
    float c = 2.0f * dem.damping_ratio * mochi_root_product(dem.stiffness, m_eff);
    float push = fmaxf(dem.stiffness * overlap - c * vn, 0.0f);
    return make_float4(-push * nx, -push * ny, -push * nz, 1.0f);
}

// Force of the box walls on sphere s (x, y, z, r) with velocity and mass v.
static __forceinline__ __device__ float3 mochi_wall_force(const LawParams& dem, float4 s,
                                                          float4 v) {
    float damping = 2.0f * dem.damping_ratio * mochi_root_product(dem.stiffness, v.w);
    float c[3] = {s.x, s.y, s.z};
    float u[3] = {v.x, v.y, v.z};
    float f[3] = {0.0f, 0.0f, 0.0f};
    for (int a = 0; a < 3; ++a) {
        float below = s.w - (c[a] - dem.box_lo[a]);
        if (below > 0.0f) {
            f[a] += fmaxf(dem.stiffness * below - damping * u[a], 0.0f);
        }
        float above = s.w - (dem.box_hi[a] - c[a]);
        if (above > 0.0f) {
            f[a] -= fmaxf(dem.stiffness * above + damping * u[a], 0.0f);
        }
    }
    return make_float3(f[0], f[1], f[2]);
}

// Moves the coordinate hi + lo (a normalised pair: hi is the sum rounded to f32) by d: the
// displacement and the residual are added first, then to hi without error (TwoSum), whose
// rounding error is the new residual. Keep in sync with `advance` in src/particles/position.rs
// (and advance_position in wgsl/dem/dem_params.wgsl): the same additions in the same order; NVRTC
// compiles without fused multiply-adds and never reassociates them.
static __forceinline__ __device__ void mochi_advance(float& hi, float& lo, float d) {
    float t = d + lo;
    float s = hi + t;
    float tt = s - hi;
    lo = (hi - (s - tt)) + (t - tt);
    hi = s;
}

// Moves the centre s.xyz, with its residuals lo.xyz, by dt·v (the step's displacement).
static __forceinline__ __device__ void mochi_move(float4& s, float4& lo, float dt, float vx,
                                                  float vy, float vz) {
    mochi_advance(s.x, lo.x, dt * vx);
    mochi_advance(s.y, lo.y, dt * vy);
    mochi_advance(s.z, lo.z, dt * vz);
}

// Gravity at step `step`, turned about the y axis by gravity_spin · t.
static __forceinline__ __device__ float3 mochi_gravity_at(const LawParams& dem,
                                                          unsigned int step) {
    float angle = dem.gravity_spin * ((float)step * dem.dt);
    float s = sinf(angle);
    float c = cosf(angle);
    const float* g = dem.gravity;
    return make_float3(g[0] * c + g[2] * s, g[1], g[2] * c - g[0] * s);
}
