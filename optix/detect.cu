// OptiX programs of collision detection: one point ray per sphere from its centre; the
// intersection program sees every proxy box the point lies in, applies the proxy-sphere rule
// and writes the kept pairs. It never reports a hit, so traversal visits every such box.
// Needs device.cuh prepended. Keep DetectParams in sync with src/engines/optix/launches.rs.

struct DetectParams {
    const float4* spheres;           // x, y, z, r in sorted order
    const unsigned int* ids;         // input index of each sorted sphere
    uint2* pairs;                    // kept pairs (input indices, smaller first)
    unsigned int* pair_count;        // pairs found (may exceed capacity)
    unsigned long long* candidates;  // boxes visited, spread over 256 counters
    unsigned long long handle;       // the acceleration structure
    unsigned int n;
    unsigned int capacity;
    unsigned int mode;               // MOCHI_MODE_MOCHI or MOCHI_MODE_NNS
    unsigned int _pad;
};

extern "C" __constant__ DetectParams params;

extern "C" __global__ void __raygen__detect() {
    unsigned int i = mochi_launch_index();
    if (i >= params.n) {
        return;
    }
    float4 s = params.spheres[i];
    unsigned int payload[MOCHI_MAX_PAYLOADS] = {0u, 0u, 0u, 0u, 0u};
    mochi_trace_point(params.handle, s.x, s.y, s.z, 1u, payload);
    atomicAdd(&params.candidates[i & 255u], (unsigned long long)payload[0]);
}

extern "C" __global__ void __intersection__detect() {
    unsigned int i = mochi_launch_index();
    unsigned int j = mochi_primitive_index();
    mochi_set_payload(0u, mochi_get_payload(0u) + 1u);
    if (mochi_keep(params.mode, i, params.spheres[i], j, params.spheres[j])) {
        unsigned int k = atomicAdd(params.pair_count, 1u);
        if (k < params.capacity) {
            unsigned int p = params.ids[i];
            unsigned int q = params.ids[j];
            params.pairs[k] = make_uint2(min(p, q), max(p, q));
        }
    }
}
