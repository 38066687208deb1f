// The granular contact law of the optix step: the CUDA twin of src/dem/model/contact.rs (read
// its doc for the physics), in f32 with the same operations in the same order (NVRTC compiles
// without fused multiply-adds, and glam's Vec3 computes component by component: dot products
// as (x·x + y·y) + z·z, cross products as glam writes them). Keep the two in sync. Needs
// physics.cuh (DemParams) prepended; keep GranularParams in sync with src/engines/optix/device.rs.

#define MOCHI_LAW_LINEAR 0u
#define MOCHI_LAW_LINEAR_PER_PAIR 1u
#define MOCHI_LAW_HERTZ 2u

#define MOCHI_ROLLING_EPSD 0u
#define MOCHI_ROLLING_CONSTANT_TORQUE 1u

// 2·√(5/6): Tsuji's damping coefficient over ζ·√(S·m*) (contact.rs TSUJI).
#define MOCHI_TSUJI 1.8257419f

// The step's parameters with the contact law's (StepParams: law, moduli, friction).
struct GranularParams {
    DemParams dem;               // box, gravity, dt, stiffness (MOCHI_LAW_LINEAR), damping ratio
    unsigned int law;            // MOCHI_LAW_*
    float rate;                  // k/m* of MOCHI_LAW_LINEAR_PER_PAIR [1/s²]
    float pair_e_star;           // E* of two spheres (Hertz) [Pa]
    float pair_g_star;           // G* of two spheres [Pa]
    float wall_e_star;           // E* of a sphere on a wall [Pa]
    float wall_g_star;           // G* of a sphere on a wall [Pa]
    float sliding;               // μ between spheres
    float wall_sliding;          // μ with the walls
    float rolling;               // μ_r
    unsigned int rolling_model;  // MOCHI_ROLLING_*
    unsigned int turns;          // 1: contacts exert torques (Friction::turns)
    unsigned int keeps;          // 1: contacts carry springs (Friction::has_history)
};

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
    float3 c;  // centre [m]
    float3 v;  // velocity [m/s]
    float3 w;  // angular velocity [rad/s]
    float r;   // radius [m]
    float m;   // mass [kg]
};

// Moment of inertia of a solid sphere, 2/5·m·r² (contact.rs moment_of_inertia).
static __forceinline__ __device__ float mochi_inertia(float m, float r) {
    return 0.4f * m * r * r;
}

// What a contact carries from one step to the next, as the sphere holding it sees it.
struct MochiSprings {
    float3 tangential;  // ξ [m]
    float3 rolling;     // EPSD rolling spring torque [N·m]
};

static __forceinline__ __device__ MochiSprings mochi_no_springs() {
    MochiSprings s;
    s.tangential = mochi_zero3();
    s.rolling = mochi_zero3();
    return s;
}

// The springs as the partner sees them: the exact negatives.
static __forceinline__ __device__ MochiSprings mochi_negated(MochiSprings s) {
    s.tangential = mochi_neg(s.tangential);
    s.rolling = mochi_neg(s.rolling);
    return s;
}

// The normal force's magnitude (≥ 0: a dry contact pushes or does nothing, it never pulls)
// and the normal stiffness.
struct MochiNormal {
    float push;
    float stiffness;
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
    bool on_wall;
};

// The normal force of a contact with overlap > 0 and normal relative velocity vn.
static __forceinline__ __device__ MochiNormal mochi_normal_force(const GranularParams& g,
                                                                 bool on_wall, float overlap,
                                                                 float vn, float m_eff,
                                                                 float r_eff) {
    MochiNormal out;
    if (g.law == MOCHI_LAW_HERTZ) {
        float e_star = on_wall ? g.wall_e_star : g.pair_e_star;
        float s_n = 2.0f * e_star * sqrtf(r_eff * overlap);
        float c = MOCHI_TSUJI * g.dem.damping_ratio * mochi_root_product(s_n, m_eff);
        out.push = fmaxf(2.0f / 3.0f * s_n * overlap - c * vn, 0.0f);
        out.stiffness = s_n;
    } else {
        float k = g.law == MOCHI_LAW_LINEAR ? g.dem.stiffness : m_eff * g.rate;
        float c = 2.0f * g.dem.damping_ratio * mochi_root_product(k, m_eff);
        out.push = fmaxf(k * overlap - c * vn, 0.0f);
        out.stiffness = k;
    }
    return out;
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

// Tangential force, torque on i (from it and from rolling resistance), the rolling torque
// alone, and the springs to keep (contact.rs friction).
struct MochiFriction {
    float3 force;
    float3 torque;
    float3 rolling;
    MochiSprings springs;
};

static __forceinline__ __device__ MochiFriction mochi_friction(const GranularParams& g,
                                                               const MochiTouch& t, float mu,
                                                               MochiSprings old) {
    float3 n = t.n;
    float pressing = t.normal.push;
    MochiFriction out;
    out.force = mochi_zero3();
    out.torque = mochi_zero3();
    out.rolling = mochi_zero3();
    out.springs = mochi_no_springs();
    if (mu > 0.0f) {
        float k_t;
        float c_t;
        if (g.law == MOCHI_LAW_HERTZ) {
            float g_star = t.on_wall ? g.wall_g_star : g.pair_g_star;
            float s_t = 8.0f * g_star * sqrtf(t.r_eff * t.overlap);
            k_t = s_t;
            c_t = MOCHI_TSUJI * g.dem.damping_ratio * mochi_root_product(s_t, t.m_eff);
        } else {
            k_t = 2.0f / 7.0f * t.normal.stiffness;
            c_t = 2.0f * g.dem.damping_ratio * mochi_root_product(k_t, t.m_eff);
        }
        float3 v_t = mochi_sub(t.v_rel, mochi_scale(mochi_dot(t.v_rel, n), n));
        float3 xi = mochi_add(mochi_into_plane(old.tangential, n), mochi_scale(g.dem.dt, v_t));
        float3 f_t = mochi_sub(mochi_scale(-k_t, xi), mochi_scale(c_t, v_t));
        float cap = mu * pressing;
        float len = mochi_length(f_t);
        if (len > cap) {
            f_t = mochi_scale(cap / len, f_t);
            xi = mochi_div(mochi_neg(f_t), k_t);
        }
        out.force = f_t;
        out.torque = mochi_cross(mochi_scale(t.lever, n), f_t);
        out.springs.tangential = xi;
    }
    float mu_r = g.rolling;
    if (mu_r > 0.0f) {
        float3 w_roll = mochi_sub(t.w_rel, mochi_scale(mochi_dot(t.w_rel, n), n));
        float cap = mu_r * t.r_eff * pressing;
        float3 rolling;
        if (g.rolling_model == MOCHI_ROLLING_EPSD) {
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
// and what the partner's torque is made of (the tangential force and the rolling torque).
struct MochiPairContact {
    float3 n;  // unit normal from i towards j
    float3 force;
    float3 torque;
    float3 tangential;
    float3 rolling;
    MochiSprings springs;
};

// The contact of sphere i with sphere j given the springs i kept of it (`old`); false when they
// do not touch (or their centres coincide). contact.rs pair_contact.
static __forceinline__ __device__ bool mochi_pair_contact(const GranularParams& g,
                                                          const MochiBody& i, const MochiBody& j,
                                                          MochiSprings old,
                                                          MochiPairContact& out) {
    float3 d = mochi_sub(j.c, i.c);
    float d2 = mochi_dot(d, d);
    float reach = i.r + j.r;
    if (d2 > reach * reach || d2 == 0.0f) {
        return false;
    }
    float dist = sqrtf(d2);
    float3 n = mochi_div(d, dist);
    float overlap = reach - dist;
    float vn = mochi_dot(mochi_sub(j.v, i.v), n);
    float m_eff = mochi_effective(i.m, j.m);
    float r_eff = mochi_effective(i.r, j.r);
    MochiNormal normal = mochi_normal_force(g, false, overlap, vn, m_eff, r_eff);
    float3 force = mochi_scale(-normal.push, n);
    out.n = n;
    if (!g.turns) {
        out.force = force;
        out.torque = mochi_zero3();
        out.tangential = mochi_zero3();
        out.rolling = mochi_zero3();
        out.springs = mochi_no_springs();
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
    touch.on_wall = false;
    MochiFriction f = mochi_friction(g, touch, g.sliding, old);
    out.force = mochi_add(force, f.force);
    out.torque = f.torque;
    out.tangential = f.force;
    out.rolling = f.rolling;
    out.springs = f.springs;
    return true;
}

// The torque on the partner j (radius r_j) of contact `c`, as j's own side computes it: its
// normal and tangential force are the exact negatives of i's, so (r_j·(−n)) × (−F_t) =
// (r_j·n) × F_t bit for bit, and its rolling torque is −rolling.
static __forceinline__ __device__ float3 mochi_partner_torque(const GranularParams& g, float r_j,
                                                              const MochiPairContact& c) {
    float3 torque = mochi_zero3();
    if (g.sliding > 0.0f) {
        torque = mochi_cross(mochi_scale(r_j, c.n), c.tangential);
    }
    if (g.rolling > 0.0f) {
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
    touch.on_wall = true;
    return touch;
}

struct MochiWalls {
    float3 normal;      // normal forces, summed per axis low wall first
    float3 tangential;  // tangential forces
    float3 torque;      // about the centre
};

// The walls touching sphere b: `old(w)` gives the springs it kept of wall w (0..6: low and
// high walls of x, y and z, 2·axis + side) and `keep(w, springs)` receives those to keep, for
// each touching wall in order, where contacts carry springs. contact.rs wall_contacts.
template <class Old, class Keep>
static __forceinline__ __device__ MochiWalls mochi_wall_contacts(const GranularParams& g,
                                                                 const MochiBody& b, Old old,
                                                                 Keep keep) {
    float c[3] = {b.c.x, b.c.y, b.c.z};
    float v[3] = {b.v.x, b.v.y, b.v.z};
    float normal[3] = {0.0f, 0.0f, 0.0f};
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
            if (overlap <= 0.0f) {
                continue;
            }
            MochiNormal nf = mochi_normal_force(g, true, overlap, vn, b.m, b.r);
            if (side == 0) {
                f += nf.push;
            } else {
                f -= nf.push;
            }
            if (g.turns) {
                // ±e_a, the low wall's with negative zeros as glam's −Vec3::AXES[a].
                float s = side == 0 ? -1.0f : 1.0f;
                float z = side == 0 ? -0.0f : 0.0f;
                float3 n = mochi_v3(a == 0 ? s : z, a == 1 ? s : z, a == 2 ? s : z);
                unsigned int wall = 2 * a + side;
                MochiTouch touch = mochi_wall_touch(b, n, overlap, nf, mochi_zero3());
                MochiFriction fr = mochi_friction(g, touch, g.wall_sliding, old(wall));
                out.tangential = mochi_add(out.tangential, fr.force);
                out.torque = mochi_add(out.torque, fr.torque);
                if (g.keeps) {
                    keep(wall, fr.springs);
                }
            }
        }
        normal[a] = f;
    }
    out.normal = mochi_v3(normal[0], normal[1], normal[2]);
    return out;
}
