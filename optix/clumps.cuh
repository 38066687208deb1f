// Clumps in the optix granular step (twin of wgsl/dem/dem_clumps.wgsl; docs/method.md,
// "Clumps"): rigid bodies whose component spheres are the run's first spheres (stable ids below
// `components`, clump by clump). granular.cu never pairs two components of one clump;
// granular_integrate resolves a component's walls, adds their force and torque to its
// accumulators, notes its state row and leaves it; advance_clumps, one thread a clump, then sums
// its components' forces and torques (each force acting at its component's centre adds its
// arm's moment), kicks the momenta, moves the centre, turns the body and places its
// components. The step is the cpu's, src/clump/rigid.rs (`RigidBody::advance`), in f32: the
// centre as a rounded value and its residual (as a sphere's, mochi_advance), the free rotation
// by the symmetric splitting of Dullweber, Leimkuhler & McLachlan (J. Chem. Phys. 107 (1997)
// 5840). Needs physics.cuh, contact.cuh and mesh_walls.cuh (mochi_rotate) prepended; part of
// the granular kernels' unit.

// One clump's state; twin of ClumpBodyRow in src/engines/common/clumps.rs.
struct MochiClumpBody {
    float3 centre;        // the centre of mass, rounded [m]
    unsigned int first;   // the stable id of its first component
    float3 residual;      // the centre's rounding error
    unsigned int shape;   // its row of the shapes
    float4 orientation;   // x, y, z, w: from its principal frame to the world
    float3 velocity;      // of the centre [m/s]
    unsigned int _pad0;
    float3 momentum;      // angular momentum about the centre, world frame [kg·m²/s]
    unsigned int _pad1;
};

// A kind of clump; twin of ClumpShapeRow in src/engines/common/clumps.rs.
struct MochiClumpShape {
    float3 moments;           // principal moments [kg·m²]
    float mass;               // [kg]
    unsigned int first_part;  // its first component's row of the parts
    unsigned int parts;       // its components
    unsigned int _pad0;
    unsigned int _pad1;
};

// v turned by the inverse of the unit quaternion q.
static __forceinline__ __device__ float3 mochi_unrotate(float4 q, float3 v) {
    return mochi_rotate(make_float4(-q.x, -q.y, -q.z, q.w), v);
}

// The flow of the kinetic energy's part L_k²/(2I_k) for h: q turned about its body axis `axis`
// by L_k·h/I_k (RigidBody::turn_about).
static __forceinline__ __device__ float4 mochi_turn_about(float4 q, float3 momentum,
                                                         float3 moments, unsigned int axis,
                                                         float h) {
    float3 body = mochi_unrotate(q, momentum);
    float l = axis == 0u ? body.x : (axis == 1u ? body.y : body.z);
    float moment = axis == 0u ? moments.x : (axis == 1u ? moments.y : moments.z);
    float half = 0.5f * l * h / moment;
    float s = sinf(half);
    float c = cosf(half);
    float3 e = mochi_v3(axis == 0u ? s : 0.0f, axis == 1u ? s : 0.0f, axis == 2u ? s : 0.0f);
    float3 u = mochi_v3(q.x, q.y, q.z);
    float3 v = mochi_add(mochi_add(mochi_scale(q.w, e), mochi_scale(c, u)), mochi_cross(u, e));
    return make_float4(v.x, v.y, v.z, q.w * c - (u.x * e.x + u.y * e.y + u.z * e.z));
}

// One step of each of `count` clumps (`rows`: each component's state row this step, by stable
// id; `external`: loads by stable id where g.dem.loaded), then its components placed at its new
// pose and given its motion; clears their accumulators.
extern "C" __global__ void advance_clumps(MochiClumpBody* bodies, const MochiClumpShape* shapes,
                                          const float4* parts, const unsigned int* rows,
                                          float4* pos, float4* lo, float4* vel, float4* ang,
                                          float* force, float* torque, const float4* external,
                                          MochiLaw g, unsigned int step, unsigned int count) {
    unsigned int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= count) {
        return;
    }
    MochiClumpBody b = bodies[k];
    const MochiClumpShape shape = shapes[b.shape];
    const float dt = g.dem.dt;
    float3 f_sum = mochi_scale(shape.mass, mochi_gravity_at(g.dem, step));
    float3 t_sum = mochi_zero3();
    for (unsigned int j = 0u; j < shape.parts; ++j) {
        unsigned int a = b.first + j;
        unsigned int p = rows[a];
        float3 f = mochi_v3(force[3 * p], force[3 * p + 1], force[3 * p + 2]);
        force[3 * p] = 0.0f;
        force[3 * p + 1] = 0.0f;
        force[3 * p + 2] = 0.0f;
        float3 t = mochi_zero3();
        if (g.dem.turns) {
            t = mochi_v3(torque[3 * p], torque[3 * p + 1], torque[3 * p + 2]);
            torque[3 * p] = 0.0f;
            torque[3 * p + 1] = 0.0f;
            torque[3 * p + 2] = 0.0f;
        }
        if (g.dem.loaded) {
            float4 e = external[2u * a];
            f = mochi_add(f, mochi_v3(e.x, e.y, e.z));
            float4 e_t = external[2u * a + 1u];
            t = mochi_add(t, mochi_v3(e_t.x, e_t.y, e_t.z));
        }
        float4 part = parts[shape.first_part + j];
        float3 arm = mochi_rotate(b.orientation, mochi_v3(part.x, part.y, part.z));
        f_sum = mochi_add(f_sum, f);
        t_sum = mochi_add(t_sum, mochi_add(mochi_cross(arm, f), t));
    }
    b.velocity = mochi_add(b.velocity, mochi_scale(dt, mochi_div(f_sum, shape.mass)));
    b.momentum = mochi_add(b.momentum, mochi_scale(dt, t_sum));
    mochi_advance(b.centre.x, b.residual.x, dt * b.velocity.x);
    mochi_advance(b.centre.y, b.residual.y, dt * b.velocity.y);
    mochi_advance(b.centre.z, b.residual.z, dt * b.velocity.z);
    float4 q = b.orientation;
    q = mochi_turn_about(q, b.momentum, shape.moments, 0u, 0.5f * dt);
    q = mochi_turn_about(q, b.momentum, shape.moments, 1u, 0.5f * dt);
    q = mochi_turn_about(q, b.momentum, shape.moments, 2u, dt);
    q = mochi_turn_about(q, b.momentum, shape.moments, 1u, 0.5f * dt);
    q = mochi_turn_about(q, b.momentum, shape.moments, 0u, 0.5f * dt);
    float norm = sqrtf(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    q = make_float4(q.x / norm, q.y / norm, q.z / norm, q.w / norm);
    b.orientation = q;
    bodies[k] = b;
    float3 in_body = mochi_unrotate(q, b.momentum);
    float3 w = mochi_rotate(q, mochi_v3(in_body.x / shape.moments.x, in_body.y / shape.moments.y,
                                        in_body.z / shape.moments.z));
    for (unsigned int j = 0u; j < shape.parts; ++j) {
        float4 part = parts[shape.first_part + j];
        float3 arm = mochi_rotate(q, mochi_v3(part.x, part.y, part.z));
        unsigned int p = rows[b.first + j];
        float4 at = make_float4(b.centre.x, b.centre.y, b.centre.z, part.w);
        float4 rest = make_float4(b.residual.x, b.residual.y, b.residual.z, 0.0f);
        mochi_advance(at.x, rest.x, arm.x);
        mochi_advance(at.y, rest.y, arm.y);
        mochi_advance(at.z, rest.z, arm.z);
        pos[p] = at;
        lo[p] = rest;
        float3 v = mochi_add(b.velocity, mochi_cross(w, arm));
        vel[p] = make_float4(v.x, v.y, v.z, shape.mass);
        ang[p] = make_float4(w.x, w.y, w.z, ang[p].w);
    }
}
