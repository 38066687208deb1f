// OptiX programs of the granular DEM step (docs/method.md, "The optix granular step"): as
// dem.cu, one point ray per sphere whose intersection program applies the proxy-sphere rule and
// resolves each kept contact at once, here with contact.cuh's law (Hertz–Mindlin or linear,
// friction with history, rolling resistance). The ray's sphere owns the pair: it reads the
// pair's springs from the old history (its own slots, else the partner's negated), writes the
// updated ones to its own new slots (counted in the payload: no atomics), sums its own force
// and torque in the payload and adds the partner's with atomics. Needs device.cuh, physics.cuh,
// contact.cuh and history.cuh prepended. Keep GranularLaunch in sync with
// src/engines/optix/launches.rs.

struct GranularLaunch {
    const float4* pos;               // x, y, z, r (the state's order)
    const float4* vel;               // vx, vy, vz, mass
    const float4* ang;               // wx, wy, wz, material (its bits)
    const unsigned int* ids;         // stable id (input index) of each sphere
    float* force;                    // 3 floats per sphere, summed with atomics
    float* torque;                   // 3 floats per sphere, summed with atomics
    unsigned int* contacts;          // touching pairs, spread over 256 counters
    unsigned long long* candidates;  // boxes visited, spread over 256 counters
    const unsigned int* old_count;   // the last step's history, by stable id
    const MochiHistoryEntry* old_entries;
    unsigned int* new_count;         // this step's: contacts each ray holds (may exceed slots)
    MochiHistoryEntry* new_entries;  // g.dem.slots per stable id
    const MochiLoadEntry* old_loads;  // beside old_entries (MOCHI_LOAD_HISTORY; else unused)
    MochiLoadEntry* new_loads;        // beside new_entries (MOCHI_LOAD_HISTORY; else unused)
    unsigned long long handle;       // the acceleration structure
    const unsigned int* clump_of;    // by stable id below `components`: its clump
    unsigned int n;
    unsigned int mode;       // MOCHI_MODE_MOCHI or MOCHI_MODE_NNS
    unsigned int components; // the clumps' component spheres: the first stable ids
    unsigned int _pad[1];    // g starts a 16-byte line (its sphere_law's alignment)
    MochiLaw g;              // with the history's slots (g.dem.slots)
};

extern "C" __constant__ GranularLaunch params;

// Payload words: boxes visited, this sphere's force (x, y, z as float bits), its torque (x, y,
// z), touching spheres, contacts held (written or not).
#define MOCHI_GRANULAR_PAYLOADS 9u

static __forceinline__ __device__ MochiBody mochi_body(unsigned int k) {
    float4 s = params.pos[k];
    float4 v = params.vel[k];
    float4 w = params.ang[k];
    MochiBody b;
    b.c = mochi_v3(s.x, s.y, s.z);
    b.v = mochi_v3(v.x, v.y, v.z);
    b.w = mochi_v3(w.x, w.y, w.z);
    b.r = s.w;
    b.m = v.w;
    b.material = __float_as_uint(w.w);
    return b;
}

static __forceinline__ __device__ void mochi_add_payload(unsigned int k, float x) {
    mochi_set_payload(k, __float_as_uint(__uint_as_float(mochi_get_payload(k)) + x));
}

extern "C" __global__ void __raygen__granular() {
    unsigned int i = mochi_launch_index();
    if (i >= params.n) {
        return;
    }
    float4 s = params.pos[i];
    unsigned int payload[MOCHI_GRANULAR_PAYLOADS] = {0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u};
    mochi_trace_point(params.handle, s.x, s.y, s.z, MOCHI_GRANULAR_PAYLOADS, payload);
    atomicAdd(&params.candidates[i & 255u], (unsigned long long)payload[0]);
    if (payload[7] != 0u) {
        atomicAdd(&params.force[3 * i], __uint_as_float(payload[1]));
        atomicAdd(&params.force[3 * i + 1], __uint_as_float(payload[2]));
        atomicAdd(&params.force[3 * i + 2], __uint_as_float(payload[3]));
        if (params.g.dem.turns) {
            atomicAdd(&params.torque[3 * i], __uint_as_float(payload[4]));
            atomicAdd(&params.torque[3 * i + 1], __uint_as_float(payload[5]));
            atomicAdd(&params.torque[3 * i + 2], __uint_as_float(payload[6]));
        }
        atomicAdd(&params.contacts[i & 255u], payload[7]);
    }
    if (mochi_keeps(params.g)) {
        // The walls' entries follow (granular_integrate), which also checks the count.
        params.new_count[params.ids[i]] = payload[8];
    }
}

extern "C" __global__ void __intersection__granular() {
    unsigned int i = mochi_launch_index();
    unsigned int j = mochi_primitive_index();
    mochi_set_payload(0u, mochi_get_payload(0u) + 1u);
    const MochiLaw& g = params.g;
    // The proxy rule on the spheres grown by half the reach past touching at which contacts
    // may hold (0 but where they adhere): it finds every pair within that reach.
    float grow = 0.5f * g.dem.reach;
    float4 s_i = params.pos[i];
    float4 s_j = params.pos[j];
    s_i.w += grow;
    s_j.w += grow;
    if (!mochi_keep(params.mode, i, s_i, j, s_j)) {
        return;
    }
    MochiBody a = mochi_body(i);
    MochiBody b = mochi_body(j);
    unsigned int id_i = params.ids[i];
    unsigned int id_j = params.ids[j];
    // Two components of one clump are never a pair (clumps.cuh).
    if (id_j < params.components && id_i < params.components &&
        params.clump_of[id_i] == params.clump_of[id_j]) {
        return;
    }
    MochiSprings old = mochi_no_springs();
    bool bonded = false;
    if (mochi_keeps(g)) {
        MochiSlots h = {params.old_count, params.old_entries, g.dem.slots, params.old_loads};
        bonded = mochi_old_contact(h, id_i, id_j, old);
    }
    MochiPairContact c;
    if (!mochi_pair_contact(g, a, b, old, bonded, c)) {
        return;
    }
    atomicAdd(&params.force[3 * j], -c.force.x);
    atomicAdd(&params.force[3 * j + 1], -c.force.y);
    atomicAdd(&params.force[3 * j + 2], -c.force.z);
    mochi_add_payload(1u, c.force.x);
    mochi_add_payload(2u, c.force.y);
    mochi_add_payload(3u, c.force.z);
    if (g.dem.turns) {
        float3 t = mochi_partner_torque(b.r, c);
        atomicAdd(&params.torque[3 * j], t.x);
        atomicAdd(&params.torque[3 * j + 1], t.y);
        atomicAdd(&params.torque[3 * j + 2], t.z);
        mochi_add_payload(4u, c.torque.x);
        mochi_add_payload(5u, c.torque.y);
        mochi_add_payload(6u, c.torque.z);
    }
    mochi_set_payload(7u, mochi_get_payload(7u) + 1u);
    if (mochi_keeps(g)) {
        unsigned int k = mochi_get_payload(8u);
        if (k < g.dem.slots) {
            mochi_keep_entry(params.new_entries, params.new_loads,
                             (unsigned long long)id_i * g.dem.slots + k, id_j, c.springs);
        }
        mochi_set_payload(8u, k + 1u);
    }
}
