// OptiX programs of the DEM step (docs/method.md, "The DEM step"): one point ray per sphere from
// its centre; the intersection program applies the proxy-sphere rule to every box the point lies
// in and resolves each kept contact at once: the partner's share of the force goes to it with
// atomics, this sphere's share is summed in the payload and added once by the raygen program.
// It never reports a hit, so traversal visits every such box. Needs device.cuh and physics.cuh
// prepended. Keep DemLaunch in sync with src/engines/optix/launches.rs.

struct DemLaunch {
    float4* pos;                     // x, y, z, r (the state's order)
    const float4* vel;               // vx, vy, vz, mass
    float* force;                    // 3 floats per sphere, summed with atomics
    unsigned int* contacts;          // touching pairs, spread over 256 counters
    unsigned long long* candidates;  // boxes visited, spread over 256 counters
    unsigned long long handle;       // the acceleration structure
    unsigned int n;
    unsigned int mode;               // MOCHI_MODE_MOCHI or MOCHI_MODE_NNS
    unsigned int _pad[2];
    LawParams dem;
};

extern "C" __constant__ DemLaunch params;

extern "C" __global__ void __raygen__dem() {
    unsigned int i = mochi_launch_index();
    if (i >= params.n) {
        return;
    }
    float4 s = params.pos[i];
    // Payload: boxes visited, this sphere's force (x, y, z as float bits), contacts.
    unsigned int payload[MOCHI_MAX_PAYLOADS] = {0u, 0u, 0u, 0u, 0u};
    mochi_trace_point(params.handle, s.x, s.y, s.z, 5u, payload);
    atomicAdd(&params.candidates[i & 255u], (unsigned long long)payload[0]);
    if (payload[4] != 0u) {
        atomicAdd(&params.force[3 * i], __uint_as_float(payload[1]));
        atomicAdd(&params.force[3 * i + 1], __uint_as_float(payload[2]));
        atomicAdd(&params.force[3 * i + 2], __uint_as_float(payload[3]));
        atomicAdd(&params.contacts[i & 255u], payload[4]);
    }
}

extern "C" __global__ void __intersection__dem() {
    unsigned int i = mochi_launch_index();
    unsigned int j = mochi_primitive_index();
    mochi_set_payload(0u, mochi_get_payload(0u) + 1u);
    float4 s = params.pos[i];
    float4 t = params.pos[j];
    if (!mochi_keep(params.mode, i, s, j, t)) {
        return;
    }
    float4 f = mochi_contact_force(params.dem, s, params.vel[i], t, params.vel[j]);
    if (f.w == 0.0f) {
        return;
    }
    atomicAdd(&params.force[3 * j], -f.x);
    atomicAdd(&params.force[3 * j + 1], -f.y);
    atomicAdd(&params.force[3 * j + 2], -f.z);
    mochi_set_payload(1u, __float_as_uint(__uint_as_float(mochi_get_payload(1u)) + f.x));
    mochi_set_payload(2u, __float_as_uint(__uint_as_float(mochi_get_payload(2u)) + f.y));
    mochi_set_payload(3u, __float_as_uint(__uint_as_float(mochi_get_payload(3u)) + f.z));
    mochi_set_payload(4u, mochi_get_payload(4u) + 1u);
}
