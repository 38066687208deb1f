// The granular contact law of the optix step: the CUDA twin of src/dem/model/contact.rs (read
// its doc for the physics), in f32 with the same operations in the same order (NVRTC compiles
// without fused multiply-adds, and glam's Vec3 computes component by component: dot products
// as (x·x + y·y) + z·z, cross products as glam writes them). Keep the two in sync. Needs
// physics.cuh (LawParams, MochiPairLaw) prepended; keep MochiLaw in sync with DeviceLaw in
// src/engines/optix/launches.rs.
// The tangential model is chosen when the programs are compiled: Mindlin's spring, or with
// MOCHI_LOAD_HISTORY defined the Mindlin–Deresiewicz law (contact.rs load_history), whose springs
// carry the load history too (the units GranularLoaded and GranularKernelsLoaded of
// src/engines/optix/programs.rs), so the spring's programs are the same as without the model.
// Each contact reads its coefficients from the material table (MochiPairLaw, MaterialTable's
// laws as uploaded): a sphere pair the row of i's material and the column of j's, a wall the
// column of its material or of a rigid wall (src/dem/model/materials.rs).

#define MOCHI_LAW_LINEAR 0u
#define MOCHI_LAW_LINEAR_PER_PAIR 1u
#define MOCHI_LAW_HERTZ 2u

#define MOCHI_ROLLING_EPSD 0u
#define MOCHI_ROLLING_CONSTANT_TORQUE 1u

// 2·√(5/6): Tsuji's damping coefficient over ζ·√(S·m*) (contact.rs TSUJI).
#define MOCHI_TSUJI 1.8257419f
// π in f32 (contact.rs PI).
#define MOCHI_PI 3.14159265f
// Most Newton steps of mochi_jkr_radius (contact.rs JKR_ITERATIONS).
#define MOCHI_JKR_ITERATIONS 12

// True in the units whose contacts adhere (JKR, liquid bridges, simplified JKR: the cohesive
// units of src/engines/optix/programs.rs define it so): elsewhere the compiler drops the
// cohesion laws, and a contact is one that touches.
#ifndef MOCHI_COHESIVE
#define MOCHI_COHESIVE false
#endif

// The law as the granular programs and kernels read it: the step's parameters and the material
// table (DeviceLaw in src/engines/optix/launches.rs).
struct MochiLaw {
    LawParams dem;             // box, gravity, dt, the law and its models, the history's slots
    const MochiTableLaw* laws; // the material table (MaterialTable::device_laws), row by row
    MochiCohesion cohesion;    // the liquid bridges and the simplified JKR (zeros: none)
};

// Whether contacts carry springs from one step to the next (a contact history).
static __forceinline__ __device__ bool mochi_keeps(const MochiLaw& g) {
    return g.dem.slots != 0u;
}

// The law of a sphere of material a against a sphere or wall of column b (MaterialTable::law).
static __forceinline__ __device__ MochiPairLaw mochi_law(const MochiLaw& g, unsigned int a,
                                                         unsigned int b) {
    return g.laws[a * g.dem.columns + b].law;
}

// The liquid bridge of a sphere of material a against column b (MaterialTable::bridge).
static __forceinline__ __device__ MochiPairBridge mochi_bridge(const MochiLaw& g, unsigned int a,
                                                               unsigned int b) {
    return g.laws[a * g.dem.columns + b].bridge;
}

// ---- glam's Vec3 operations, component by component -------------------------------------------

static __forceinline__ __device__ float3 mochi_v3(float x, float y, float z) {
    return make_float3(x, y, z);
}
static __forceinline__ __device__ float3 mochi_add(float3 a, float3 b) {
    return make_float3(a.x + b.x, a.y + b.y, a.z + b.z);
}
static __forceinline__ __device__ float3 mochi_sub(float3 a, float3 b) {
    return make_float3(a.x - b.x, a.y - b.y, a.z - b.z);
}
static __forceinline__ __device__ float3 mochi_neg(float3 a) {
    return make_float3(-a.x, -a.y, -a.z);
}
// s·a (a·s rounds the same).
static __forceinline__ __device__ float3 mochi_scale(float s, float3 a) {
    return make_float3(s * a.x, s * a.y, s * a.z);
}
static __forceinline__ __device__ float3 mochi_div(float3 a, float s) {
    return make_float3(a.x / s, a.y / s, a.z / s);
}
static __forceinline__ __device__ float mochi_dot(float3 a, float3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
static __forceinline__ __device__ float3 mochi_cross(float3 a, float3 b) {
    return make_float3(a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y);
}
static __forceinline__ __device__ float3 mochi_zero3() {
    return make_float3(0.0f, 0.0f, 0.0f);
}
// The length of v without squaring anything below its largest component s: s·|v/s| (|v|²
// underflows f32 for the forces and torques of small spheres); 0 for the zero vector
// (contact.rs length).
static __forceinline__ __device__ float mochi_length(float3 v) {
    float s = fmaxf(fmaxf(fabsf(v.x), fabsf(v.y)), fabsf(v.z));
    if (s > 0.0f) {
        float3 u = mochi_div(v, s);
        return s * sqrtf(mochi_dot(u, u));
    }
    return 0.0f;
}

// ---- The contact (contact.rs) ------------------------------------------------------------------

// A sphere as its contacts see it (contact.rs Body).
struct MochiBody {
    float3 c;               // centre [m]
    float3 v;               // velocity [m/s]
    float3 w;               // angular velocity [rad/s]
    float r;                // radius [m]
    float m;                // mass [kg]
    unsigned int material;  // its row in the material table
};

// Moment of inertia of a solid sphere, 2/5·m·r² (contact.rs moment_of_inertia).
static __forceinline__ __device__ float mochi_inertia(float m, float r) {
    return 0.4f * m * r * r;
}

// What a contact carries from one step to the next, as the sphere holding it sees it.
struct MochiSprings {
    float3 tangential;  // ξ [m]; Mindlin–Deresiewicz: the elastic tangential force [N]
    float3 rolling;     // EPSD rolling spring torque [N·m]
#ifdef MOCHI_LOAD_HISTORY
    float3 reversal;  // the elastic tangential force at the last reversal [N] (0: virgin curve)
    float normal;     // the elastic normal force of the last step [N]
#endif
};

static __forceinline__ __device__ MochiSprings mochi_no_springs() {
    MochiSprings s;
    s.tangential = mochi_zero3();
    s.rolling = mochi_zero3();
#ifdef MOCHI_LOAD_HISTORY
    s.reversal = mochi_zero3();
    s.normal = 0.0f;
#endif
    return s;
}

// The springs as the partner sees them: the exact negatives (the same normal force).
static __forceinline__ __device__ MochiSprings mochi_negated(MochiSprings s) {
    s.tangential = mochi_neg(s.tangential);
    s.rolling = mochi_neg(s.rolling);
#ifdef MOCHI_LOAD_HISTORY
    s.reversal = mochi_neg(s.reversal);
#endif
    return s;
}

// The normal force's magnitude (≥ 0 for a dry contact: it pushes or does nothing; a JKR neck
// pulls), its elastic part (no damping) and the normal stiffness; the load that caps friction
// and rolling (the push, or with JKR the push plus twice the pull-off force, plus a bridge's
// pull) and JKR's contact radius (0 for the other laws). contact.rs Normal.
struct MochiNormal {
    float push;
    float elastic;
    float stiffness;
    float load;
    float radius;
};

// A touching contact from sphere i's side, as friction needs it (contact.rs Touch).
struct MochiTouch {
    float3 n;  // unit normal from i towards its partner
    float overlap;
    MochiNormal normal;
    float m_eff;
    float r_eff;
    float i_eff;   // I_i·I_j/(I_i + I_j), mochi_effective(I_i, I_j) (I_i on a wall)
    float lever;   // from i's centre to the contact point
    float3 v_rel;  // velocity of i's surface relative to the partner's at the contact point
    float3 w_rel;  // ω_i − ω_j (ω_i on a wall)
};

// ∛x of a normal x > 0 by the same operations on every backend: a start from the bits, then
// three Newton steps (contact.rs cube_root); 0 for x ≤ 0.
static __forceinline__ __device__ float mochi_cube_root(float x) {
    if (x <= 0.0f) {
        return 0.0f;
    }
    float y = __uint_as_float(__float_as_uint(x) / 3u + 0x2a5137a0u);
    for (int k = 0; k < 3; ++k) {
        y = (y + y + x / (y * y)) / 3.0f;
    }
    return y;
}

// The pull-off force of a JKR contact, 1.5·π·Γ·R* (contact.rs jkr_pull_off).
static __forceinline__ __device__ float mochi_jkr_pull_off(float r_eff, float adhesion) {
    return 1.5f * MOCHI_PI * adhesion * r_eff;
}

// The (negative) overlap at which a JKR neck breaks (contact.rs jkr_break).
static __forceinline__ __device__ float mochi_jkr_break(float r_eff, float e_star,
                                                        float adhesion) {
    float g = MOCHI_PI * adhesion / e_star;
    return -0.75f * mochi_cube_root(g * g * r_eff);
}

// JKR's contact radius at `overlap` by Newton's method on x = √a (contact.rs jkr_radius).
static __forceinline__ __device__ float mochi_jkr_radius(float overlap, float r_eff,
                                                         float e_star, float adhesion) {
    float c = sqrtf(2.0f * MOCHI_PI * adhesion / e_star);
    float x = fmaxf(sqrtf(sqrtf(2.0f * r_eff * fmaxf(overlap, 0.0f))),
                    mochi_cube_root(2.0f * c * r_eff));
    for (int k = 0; k < MOCHI_JKR_ITERATIONS; ++k) {
        float x3 = x * x * x;
        float slope = 4.0f * x3 / r_eff - c;
        if (slope <= 0.0f) {
            break;
        }
        float next = x - (x3 * x / r_eff - c * x - overlap) / slope;
        // Converged: every later step would repeat this one.
        if (next == x) {
            break;
        }
        x = next;
    }
    return x * x;
}

// Whether a contact of `law` and bridge `wet` that held at the last step and now overlaps by
// `overlap` ≤ 0 still holds: a JKR neck not yet broken, a liquid bridge not yet ruptured
// (contact.rs holds).
static __forceinline__ __device__ bool mochi_holds(const MochiLaw& g, const MochiPairLaw& law,
                                                   const MochiPairBridge& wet, float r_eff,
                                                   float overlap) {
    return (law.adhesion > 0.0f && overlap > mochi_jkr_break(r_eff, law.e_star, law.adhesion)) ||
           (g.cohesion.bridge_volume > 0.0f && -overlap < wet.rupture);
}

// The smallest gap a bridge's lubrication force takes, a fraction of R* (contact.rs).
#define MOCHI_BRIDGE_MIN_GAP 0.01f

// The lubrication force of a liquid bridge between bodies of effective radius r_eff overlapping
// by `overlap` whose gap grows at `vn`: 6π·η·R*²·v_n/s, pulling them together where positive; 0
// without a viscosity (contact.rs bridge_drag).
static __forceinline__ __device__ float mochi_bridge_drag(const MochiLaw& g, float r_eff,
                                                          float overlap, float vn) {
    float eta = g.cohesion.bridge_viscosity;
    if (eta == 0.0f) {
        return 0.0f;
    }
    float gap = fmaxf(-overlap, MOCHI_BRIDGE_MIN_GAP * r_eff);
    return 6.0f * MOCHI_PI * eta * r_eff * (r_eff / gap) * vn;
}

// The pull of a liquid bridge wetting the pair as `wet` says between bodies of effective radius
// r_eff overlapping by `overlap` (a gap where negative); 0 without bridges (contact.rs
// bridge_pull).
static __forceinline__ __device__ float mochi_bridge_pull(const MochiLaw& g,
                                                          const MochiPairBridge& wet, float r_eff,
                                                          float overlap) {
    float volume = g.cohesion.bridge_volume;
    if (volume == 0.0f) {
        return 0.0f;
    }
    float r = 2.0f * r_eff;
    float s = 0.5f * fmaxf(-overlap, 0.0f) * sqrtf(r / volume);
    return 2.0f * MOCHI_PI * r * wet.tension / (1.0f + 2.1f * s + 10.0f * s * s);
}

// The pull of a bridge and of the simplified JKR on a sphere of radius r against a surface it
// overlaps by `overlap` (the area where they meet a circle in the surface's plane).
static __forceinline__ __device__ float mochi_surface_pull(const MochiLaw& g,
                                                           const MochiPairBridge& wet, float r,
                                                           float overlap) {
    float pull = mochi_bridge_pull(g, wet, r, overlap);
    if (g.cohesion.density > 0.0f && overlap > 0.0f) {
        pull += g.cohesion.density * MOCHI_PI * overlap * (2.0f * r - overlap);
    }
    return pull;
}

// The normal force of a contact of law `law` with overlap `overlap` (> 0, or ≤ 0 on a JKR neck)
// and normal relative velocity vn (contact.rs normal_force).
static __forceinline__ __device__ MochiNormal mochi_normal_force(const MochiLaw& g,
                                                                 const MochiPairLaw& law,
                                                                 float overlap, float vn,
                                                                 float m_eff, float r_eff) {
    MochiNormal out;
    out.radius = 0.0f;
    if (g.dem.law == MOCHI_LAW_HERTZ && MOCHI_COHESIVE && law.adhesion > 0.0f) {
        // JKR: the contact radius of the overlap, its force (a pull on the neck and at small
        // overlaps) and Tsuji's damping with the stiffness 2E*a; no clamp, the neck pulls.
        float a = mochi_jkr_radius(overlap, r_eff, law.e_star, law.adhesion);
        float s_n = 2.0f * law.e_star * a;
        float c = MOCHI_TSUJI * law.damping_ratio * mochi_root_product(s_n, m_eff);
        out.elastic = 2.0f / 3.0f * s_n * a * a / r_eff -
                      sqrtf(8.0f * MOCHI_PI * law.adhesion * law.e_star * a * a * a);
        out.push = out.elastic - c * vn;
        out.stiffness = s_n;
        out.load = fmaxf(out.push + 2.0f * mochi_jkr_pull_off(r_eff, law.adhesion), 0.0f);
        out.radius = a;
        return out;
    }
    if (g.dem.law == MOCHI_LAW_HERTZ) {
        float s_n = 2.0f * law.e_star * sqrtf(r_eff * overlap);
        float c = MOCHI_TSUJI * law.damping_ratio * mochi_root_product(s_n, m_eff);
        out.elastic = 2.0f / 3.0f * s_n * overlap;
        out.push = fmaxf(out.elastic - c * vn, 0.0f);
        out.stiffness = s_n;
    } else {
        float k = g.dem.law == MOCHI_LAW_LINEAR ? g.dem.stiffness : m_eff * law.rate;
        float c = 2.0f * law.damping_ratio * mochi_root_product(k, m_eff);
        out.elastic = k * overlap;
        out.push = fmaxf(out.elastic - c * vn, 0.0f);
        out.stiffness = k;
    }
    out.load = out.push;
    return out;
}

// `along` with a bridge's `drag` added, where there is one (contact.rs dragged).
static __forceinline__ __device__ float mochi_dragged(float along, float drag) {
    return drag != 0.0f ? along + drag : along;
}

// The normal force of a contact that also pulls by `pull` ≥ 0 (a bridge, the simplified JKR)
// and a bridge's `drag` along n from i towards its partner: the force on i, the load grown by
// the pull.
static __forceinline__ __device__ float3 mochi_pulled(MochiNormal& normal, float pull, float drag,
                                                      float3 n) {
    float along = -normal.push;
    if (pull > 0.0f) {
        normal.load += pull;
        along = pull - normal.push;
    }
    return mochi_scale(mochi_dragged(along, drag), n);
}

// `x` turned into the plane normal to `n`: its normal part removed, its length kept.
static __forceinline__ __device__ float3 mochi_into_plane(float3 x, float3 n) {
    float3 t = mochi_sub(x, mochi_scale(mochi_dot(x, n), n));
    float len = mochi_length(t);
    if (len > 0.0f) {
        return mochi_scale(mochi_length(x) / len, t);
    }
    return t;
}

#ifdef MOCHI_LOAD_HISTORY
// The Mindlin–Deresiewicz tangential force on i with full stiffness k_t, damping c_t, sliding
// coefficient mu, elastic normal force `elastic` and Coulomb's cap mu·pressing; its springs
// into `springs` (contact.rs load_history: Thornton & Yin's incremental form in vectors).
static __forceinline__ __device__ float3 mochi_load_history(const MochiLaw& g, float k_t,
                                                           float c_t, float mu, float elastic,
                                                           float pressing, float3 n, float3 v_t,
                                                           const MochiSprings& old,
                                                           MochiSprings& springs) {
    float3 f = mochi_into_plane(old.tangential, n);
    float3 r = mochi_into_plane(old.reversal, n);
    float dn = elastic - old.normal;
    float3 d = mochi_scale(g.dem.dt, v_t);
    // A reversal: the displacement drives the force back towards the last reversal point.
    float3 back = mochi_sub(f, r);
    if (mochi_length(back) > 0.0f && mochi_dot(back, d) > 0.0f) {
        r = f;
    }
    // The reversal point follows the normal force; where it shrinks to nothing the virgin
    // curve holds.
    bool reversed = r.x != 0.0f || r.y != 0.0f || r.z != 0.0f;
    if (reversed) {
        float size = mochi_length(r);
        float grown = size + mu * dn;
        r = grown > 0.0f ? mochi_scale(grown / size, r) : mochi_zero3();
    }
    float c = (r.x != 0.0f || r.y != 0.0f || r.z != 0.0f) ? 2.0f : 1.0f;
    float scale = c * mu * elastic;
    float3 away = mochi_sub(f, r);
    float gone = mochi_length(away);
    float theta = 0.0f;
    if (scale > 0.0f) {
        theta = mochi_cube_root(1.0f - (gone + c * mu * dn) / scale);
    }
    float step = mochi_length(d);
    if (mu * dn > k_t * step) {
        theta = 1.0f;
    }
    float3 e = mochi_zero3();
    if (gone > 0.0f) {
        e = mochi_div(away, gone);
    } else if (step > 0.0f) {
        e = mochi_div(d, -step);
    }
    f = mochi_add(mochi_sub(f, mochi_scale(k_t * theta, d)),
                  mochi_scale(mu * dn * (1.0f - theta), e));
    // Past the mirror point of the last reversal: back on the virgin curve.
    if ((r.x != 0.0f || r.y != 0.0f || r.z != 0.0f) && mochi_dot(f, r) < 0.0f &&
        mochi_length(f) >= mochi_length(r)) {
        r = mochi_zero3();
    }
    // Never more than μN: full slip, and the virgin curve from there.
    float most = mu * elastic;
    float len = mochi_length(f);
    if (len > most) {
        f = mochi_scale(most / len, f);
        r = mochi_zero3();
    }
    float3 f_t = mochi_sub(f, mochi_scale(c_t, v_t));
    float cap = mu * pressing;
    float len_t = mochi_length(f_t);
    if (len_t > cap) {
        f_t = mochi_scale(cap / len_t, f_t);
        f = f_t;
        r = mochi_zero3();
    }
    springs.tangential = f;
    springs.reversal = r;
    springs.normal = elastic;
    return f_t;
}
#endif

// Tangential force, torque on i (from it and from rolling resistance), the rolling torque
// alone, and the springs to keep (contact.rs friction).
struct MochiFriction {
    float3 force;
    float3 torque;
    float3 rolling;
    MochiSprings springs;
};

// Of a contact of law `law` with sliding coefficient mu.
static __forceinline__ __device__ MochiFriction mochi_friction(const MochiLaw& g,
                                                               const MochiPairLaw& law,
                                                               const MochiTouch& t, float mu,
                                                               MochiSprings old) {
    float3 n = t.n;
    float pressing = t.normal.load;
    MochiFriction out;
    out.force = mochi_zero3();
    out.torque = mochi_zero3();
    out.rolling = mochi_zero3();
    out.springs = mochi_no_springs();
    if (mu > 0.0f) {
        float k_t;
        float c_t;
        if (g.dem.law == MOCHI_LAW_HERTZ) {
            float a = MOCHI_COHESIVE && law.adhesion > 0.0f ? t.normal.radius
                                                              : sqrtf(t.r_eff * t.overlap);
            float s_t = 8.0f * law.g_star * a;
            k_t = s_t;
            c_t = MOCHI_TSUJI * law.damping_ratio * mochi_root_product(s_t, t.m_eff);
        } else {
            k_t = 2.0f / 7.0f * t.normal.stiffness;
            c_t = 2.0f * law.damping_ratio * mochi_root_product(k_t, t.m_eff);
        }
        float3 v_t = mochi_sub(t.v_rel, mochi_scale(mochi_dot(t.v_rel, n), n));
#ifdef MOCHI_LOAD_HISTORY
        float3 f_t = mochi_load_history(g, k_t, c_t, mu, t.normal.elastic, pressing, n, v_t, old,
                                        out.springs);
#else
        float3 xi = mochi_add(mochi_into_plane(old.tangential, n), mochi_scale(g.dem.dt, v_t));
        float3 f_t = mochi_sub(mochi_scale(-k_t, xi), mochi_scale(c_t, v_t));
        float cap = mu * pressing;
        float len = mochi_length(f_t);
        if (len > cap) {
            f_t = mochi_scale(cap / len, f_t);
            xi = mochi_div(mochi_neg(f_t), k_t);
        }
        out.springs.tangential = xi;
#endif
        out.force = f_t;
        out.torque = mochi_cross(mochi_scale(t.lever, n), f_t);
    }
    float mu_r = law.rolling;
    if (mu_r > 0.0f) {
        float3 w_roll = mochi_sub(t.w_rel, mochi_scale(mochi_dot(t.w_rel, n), n));
        float cap = mu_r * t.r_eff * pressing;
        float3 rolling;
        if (g.dem.rolling_model == MOCHI_ROLLING_EPSD) {
            float k_r = 2.25f * t.normal.stiffness * mu_r * mu_r * t.r_eff * t.r_eff;
            float3 m = mochi_sub(mochi_into_plane(old.rolling, n),
                                 mochi_scale(k_r * g.dem.dt, w_roll));
            float len = mochi_length(m);
            if (len > cap) {
                m = mochi_scale(cap / len, m);
            }
            out.springs.rolling = m;
            rolling = m;
        } else {
            float speed = mochi_length(w_roll);
            if (speed > 0.0f) {
                // Never more than stops the relative rolling within the step.
                float size = fminf(cap, t.i_eff * speed / g.dem.dt);
                rolling = mochi_scale(-size / speed, w_roll);
            } else {
                rolling = mochi_zero3();
            }
        }
        out.torque = mochi_add(out.torque, rolling);
        out.rolling = rolling;
    }
    return out;
}

// What one sphere pair does, from i's side: the force and torque on i, the springs i keeps,
// and what the partner's torque is made of (the tangential force and the rolling torque, where
// the pair's μ and μ_r give them).
struct MochiPairContact {
    float3 n;                // unit normal from i towards j
    float sliding;           // the pair's μ
    float rolling_friction;  // the pair's μ_r
    float3 force;
    float3 torque;
    float3 tangential;
    float3 rolling;
    MochiSprings springs;
};

// The contact of sphere i with sphere j given the springs i kept of it (`old`); false when they
// do not touch (or their centres coincide). `bonded`: whether they were in contact at the last
// step, where a cohesive pair may hold past touching. contact.rs pair_contact.
static __forceinline__ __device__ bool mochi_pair_contact(const MochiLaw& g,
                                                          const MochiBody& i, const MochiBody& j,
                                                          MochiSprings old, bool bonded,
                                                          MochiPairContact& out) {
    float3 d = mochi_sub(j.c, i.c);
    float d2 = mochi_dot(d, d);
    float reach = i.r + j.r;
    bool apart = d2 > reach * reach;
    if ((apart && !(MOCHI_COHESIVE && bonded)) || d2 == 0.0f) {
        return false;
    }
    float dist = sqrtf(d2);
    float3 n = mochi_div(d, dist);
    float overlap = reach - dist;
    float vn = mochi_dot(mochi_sub(j.v, i.v), n);
    float m_eff = mochi_effective(i.m, j.m);
    float r_eff = mochi_effective(i.r, j.r);
    MochiPairLaw law = mochi_law(g, i.material, j.material);
    out.n = n;
    out.sliding = law.sliding;
    out.rolling_friction = law.rolling;
    out.torque = mochi_zero3();
    out.tangential = mochi_zero3();
    out.rolling = mochi_zero3();
    out.springs = mochi_no_springs();
    float pull = 0.0f;
    float drag = 0.0f;
    if (MOCHI_COHESIVE) {
        MochiPairBridge wet = mochi_bridge(g, i.material, j.material);
        if (apart && !mochi_holds(g, law, wet, r_eff, overlap)) {
            return false;
        }
        pull = mochi_bridge_pull(g, wet, r_eff, overlap);
        drag = mochi_bridge_drag(g, r_eff, overlap, vn);
        if (g.cohesion.density > 0.0f && !apart) {
            // The area of the circle where the two spheres' surfaces meet (symmetric in i, j).
            float spread = fabsf(i.r - j.r);
            float area = MOCHI_PI / 4.0f *
                         ((reach - dist) * (reach + dist) * (dist - spread) * (dist + spread)) / d2;
            pull += g.cohesion.density * fmaxf(area, 0.0f);
        }
        if (apart && law.adhesion == 0.0f) {
            // A liquid bridge across a gap: its pull alone, and its drag (no friction: the
            // partner's torque is zero).
            out.sliding = 0.0f;
            out.rolling_friction = 0.0f;
            out.force = mochi_scale(mochi_dragged(pull, drag), n);
            return true;
        }
    }
    MochiNormal normal = mochi_normal_force(g, law, overlap, vn, m_eff, r_eff);
    float3 force = mochi_pulled(normal, pull, drag, n);
    if (!g.dem.turns) {
        out.force = force;
        return true;
    }
    MochiTouch touch;
    touch.n = n;
    touch.overlap = overlap;
    touch.normal = normal;
    touch.m_eff = m_eff;
    touch.r_eff = r_eff;
    touch.i_eff = mochi_effective(mochi_inertia(i.m, i.r), mochi_inertia(j.m, j.r));
    touch.lever = i.r;
    touch.v_rel = mochi_sub(mochi_add(i.v, mochi_cross(i.w, mochi_scale(i.r, n))),
                            mochi_sub(j.v, mochi_cross(j.w, mochi_scale(j.r, n))));
    touch.w_rel = mochi_sub(i.w, j.w);
    MochiFriction f = mochi_friction(g, law, touch, law.sliding, old);
    out.force = mochi_add(force, f.force);
    out.torque = f.torque;
    out.tangential = f.force;
    out.rolling = f.rolling;
    out.springs = f.springs;
    return true;
}

// The torque on the partner j (radius r_j) of contact `c`, as j's own side computes it (its
// law is i's: the table is symmetric): its normal and tangential force are the exact negatives
// of i's, so (r_j·(−n)) × (−F_t) = (r_j·n) × F_t bit for bit, and its rolling torque is
// −rolling.
static __forceinline__ __device__ float3 mochi_partner_torque(float r_j,
                                                              const MochiPairContact& c) {
    float3 torque = mochi_zero3();
    if (c.sliding > 0.0f) {
        torque = mochi_cross(mochi_scale(r_j, c.n), c.tangential);
    }
    if (c.rolling_friction > 0.0f) {
        torque = mochi_add(torque, mochi_neg(c.rolling));
    }
    return torque;
}

// What the six walls of the box do to one sphere (contact.rs WallContacts).
// Sphere b's touch of a wall whose surface moves at `velocity` where it touches (normal n from
// b's centre; a box wall's stands still: x − 0 is x, bit for bit as the cpu step's).
static __forceinline__ __device__ MochiTouch mochi_wall_touch(const MochiBody& b, float3 n,
                                                              float overlap, MochiNormal nf,
                                                              float3 velocity) {
    MochiTouch touch;
    touch.n = n;
    touch.overlap = overlap;
    touch.normal = nf;
    touch.m_eff = b.m;
    touch.r_eff = b.r;
    touch.i_eff = mochi_inertia(b.m, b.r);
    touch.lever = b.r;
    touch.v_rel = mochi_sub(mochi_add(b.v, mochi_cross(b.w, mochi_scale(b.r, n))), velocity);
    touch.w_rel = b.w;
    return touch;
}

struct MochiWalls {
    float3 normal;      // normal forces, summed per axis low wall first
    float3 tangential;  // tangential forces
    float3 torque;      // about the centre
};

// The walls touching sphere b (or held by it past touching, where contacts adhere):
// `old(w, springs)` tells whether it touched wall w (0..6: low and high walls of x, y and z,
// 2·axis + side) at the last step, with the springs it kept of it into `springs`, and
// `keep(w, springs)` receives those to keep, for each wall in contact in order, where contacts
// carry springs. contact.rs wall_contacts.
template <class Old, class Keep>
static __forceinline__ __device__ MochiWalls mochi_wall_contacts(const MochiLaw& g,
                                                                 const MochiBody& b, Old old,
                                                                 Keep keep) {
    float c[3] = {b.c.x, b.c.y, b.c.z};
    float v[3] = {b.v.x, b.v.y, b.v.z};
    float normal[3] = {0.0f, 0.0f, 0.0f};
    MochiPairLaw law = mochi_law(g, b.material, g.dem.box_column);
    MochiPairBridge wet = mochi_bridge(g, b.material, g.dem.box_column);
    MochiWalls out;
    out.tangential = mochi_zero3();
    out.torque = mochi_zero3();
    for (unsigned int a = 0; a < 3; ++a) {
        float f = 0.0f;
        // Low wall (normal −e_a from the centre, v_n = v_a), then high wall (+e_a, v_n = −v_a).
        float below = b.r - (c[a] - g.dem.box_lo[a]);
        float above = b.r - (g.dem.box_hi[a] - c[a]);
        for (unsigned int side = 0; side < 2; ++side) {
            float overlap = side == 0 ? below : above;
            float vn = side == 0 ? v[a] : -v[a];
            unsigned int wall = 2 * a + side;
            MochiSprings kept = mochi_no_springs();
            bool touched = false;
            // Within reach of the wall, a cohesive contact may hold: only then is it looked up.
            if (overlap > 0.0f || (MOCHI_COHESIVE && -overlap < g.dem.reach)) {
                touched = old(wall, kept);
            }
            bool held = MOCHI_COHESIVE && touched && mochi_holds(g, law, wet, b.r, overlap);
            if (overlap <= 0.0f && !held) {
                continue;
            }
            float pull = 0.0f;
            float drag = 0.0f;
            bool bridged = false;
            if (MOCHI_COHESIVE) {
                pull = mochi_surface_pull(g, wet, b.r, overlap);
                drag = mochi_bridge_drag(g, b.r, overlap, vn);
                bridged = overlap <= 0.0f && law.adhesion == 0.0f;
            }
            MochiNormal nf;
            if (bridged) {
                // A liquid bridge across a gap: its pull alone, no friction.
                nf.push = 0.0f;
                nf.elastic = 0.0f;
                nf.stiffness = 0.0f;
                nf.load = 0.0f;
                nf.radius = 0.0f;
            } else {
                nf = mochi_normal_force(g, law, overlap, vn, b.m, b.r);
            }
            // The push away from the wall, less a bridge's pull and drag.
            float push = nf.push;
            if (pull > 0.0f) {
                nf.load += pull;
                push = nf.push - pull;
            }
            if (drag != 0.0f) {
                push = push - drag;
            }
            if (side == 0) {
                f += push;
            } else {
                f -= push;
            }
            if (g.dem.turns && !bridged) {
                // ±e_a, the low wall's with negative zeros as glam's −Vec3::AXES[a].
                float s = side == 0 ? -1.0f : 1.0f;
                float z = side == 0 ? -0.0f : 0.0f;
                float3 n = mochi_v3(a == 0 ? s : z, a == 1 ? s : z, a == 2 ? s : z);
                MochiTouch touch = mochi_wall_touch(b, n, overlap, nf, mochi_zero3());
                MochiFriction fr = mochi_friction(g, law, touch, law.sliding, kept);
                out.tangential = mochi_add(out.tangential, fr.force);
                out.torque = mochi_add(out.torque, fr.torque);
                if (mochi_keeps(g)) {
                    keep(wall, fr.springs);
                }
            } else if (mochi_keeps(g)) {
                // An adhering contact is remembered without springs.
                keep(wall, mochi_no_springs());
            }
        }
        normal[a] = f;
    }
    out.normal = mochi_v3(normal[0], normal[1], normal[2]);
    return out;
}

// The contact of sphere b with a surface (a mesh wall) of column `column` in the material
// table, moving at `velocity` where it touches, normal n from the centre, overlap > 0: its
// force and torque and the springs to keep (contact.rs surface_contact). `given` is the wall's
// own μ, or negative where it has none (then the pair's).
struct MochiSurface {
    float3 force;
    float3 torque;
    MochiSprings springs;
};

static __device__ MochiSurface mochi_surface_contact(const MochiLaw& g, const MochiBody& b,
                                                     float3 n, float overlap, float3 velocity,
                                                     unsigned int column, float given,
                                                     MochiSprings old) {
    MochiPairLaw law = mochi_law(g, b.material, column);
    float mu = given < 0.0f ? law.sliding : given;
    MochiSurface out;
    out.torque = mochi_zero3();
    out.springs = mochi_no_springs();
    // v_n as for a pair: the partner's (the surface's) velocity minus b's, along n.
    float vn = mochi_dot(mochi_sub(velocity, b.v), n);
    float pull = 0.0f;
    float drag = 0.0f;
    if (MOCHI_COHESIVE) {
        pull = mochi_surface_pull(g, mochi_bridge(g, b.material, column), b.r, overlap);
        drag = mochi_bridge_drag(g, b.r, overlap, vn);
        if (overlap <= 0.0f && law.adhesion == 0.0f) {
            // A liquid bridge across a gap: its pull alone, and its drag.
            out.force = mochi_scale(mochi_dragged(pull, drag), n);
            return out;
        }
    }
    MochiNormal nf = mochi_normal_force(g, law, overlap, vn, b.m, b.r);
    out.force = mochi_pulled(nf, pull, drag, n);
    if (!g.dem.turns) {
        return out;
    }
    MochiFriction f =
        mochi_friction(g, law, mochi_wall_touch(b, n, overlap, nf, velocity), mu, old);
    out.force = mochi_add(out.force, f.force);
    out.torque = f.torque;
    out.springs = f.springs;
    return out;
}
