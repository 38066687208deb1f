// Plain CUDA kernels of the optix backend. Needs device.cuh and physics.cuh prepended.

// Half-width of the proxy box of a sphere of radius r (ProxyMode::box_half_width).
static __forceinline__ __device__ float mochi_box_half_width(unsigned int mode, float r,
                                                             float r_max) {
    return mode == MOCHI_MODE_NNS ? 2.0f * r_max : 2.0f * r;
}

// Writes the proxy box of sphere s as 6 floats (min x, y, z, then max), padded by `pad_rel` of
// the largest coordinate involved so the box test never rejects a point the rule accepts.
static __forceinline__ __device__ void mochi_write_box(float* box, float4 s, unsigned int mode,
                                                       float r_max, float pad_rel) {
    float h = mochi_box_half_width(mode, s.w, r_max);
    float pad = (fmaxf(fmaxf(fabsf(s.x), fabsf(s.y)), fabsf(s.z)) + h) * pad_rel;
    float w = h + pad;
    box[0] = s.x - w;
    box[1] = s.y - w;
    box[2] = s.z - w;
    box[3] = s.x + w;
    box[4] = s.y + w;
    box[5] = s.z + w;
}

// Gathers the spheres into sorted order (`order[p]` is the input index of sorted position p) and
// writes each one's proxy box (mochi_write_box). Keep in sync with wgsl/rq/rq_build.wgsl.
extern "C" __global__ void proxy_boxes(const float4* spheres_in, const unsigned int* order,
                                       float4* spheres, float* boxes, unsigned int n,
                                       unsigned int mode, float r_max, float pad_rel) {
    unsigned int p = blockIdx.x * blockDim.x + threadIdx.x;
    if (p >= n) {
        return;
    }
    float4 s = spheres_in[order[p]];
    spheres[p] = s;
    mochi_write_box(boxes + 6 * p, s, mode, r_max, pad_rel);
}

// ---- The DEM step (src/engines/optix/dem.rs) ----------------------------------------------------------

// The proxy box of every sphere of the state, in place, its radius grown by `grow` (half the
// reach past touching at which contacts may hold; 0 but where they adhere).
extern "C" __global__ void dem_boxes(const float4* pos, float* boxes, unsigned int n,
                                     unsigned int mode, float r_max, float pad_rel, float grow) {
    unsigned int p = blockIdx.x * blockDim.x + threadIdx.x;
    if (p >= n) {
        return;
    }
    float4 s = pos[p];
    s.w += grow;
    mochi_write_box(boxes + 6 * p, s, mode, r_max + grow, pad_rel);
}

// Walls, gravity at step `step`, the external force where dem.loaded is 1 (`external`, by
// input index `ids[p]`: force at row 2i) and one semi-implicit Euler step, in place (the centres
// with their residuals `lo`); clears the force accumulator for the next step. Keep in sync with
// `integrate_sphere` in wgsl/dem/dem_integrate.wgsl.
extern "C" __global__ void dem_integrate(float4* pos, float4* lo, float4* vel, float* force,
                                         const unsigned int* ids, const float4* external,
                                         LawParams dem, unsigned int step) {
    unsigned int p = blockIdx.x * blockDim.x + threadIdx.x;
    if (p >= dem.n) {
        return;
    }
    float4 s = pos[p];
    float4 v = vel[p];
    float3 w = mochi_wall_force(dem, s, v);
    float3 g = mochi_gravity_at(dem, step);
    float m = v.w;
    float fx = force[3 * p] + w.x;
    float fy = force[3 * p + 1] + w.y;
    float fz = force[3 * p + 2] + w.z;
    if (dem.loaded) {
        float4 e = external[2u * ids[p]];
        fx += e.x;
        fy += e.y;
        fz += e.z;
    }
    force[3 * p] = 0.0f;
    force[3 * p + 1] = 0.0f;
    force[3 * p + 2] = 0.0f;
    float vx = v.x + dem.dt * (fx / m + g.x);
    float vy = v.y + dem.dt * (fy / m + g.y);
    float vz = v.z + dem.dt * (fz / m + g.z);
    vel[p] = make_float4(vx, vy, vz, m);
    float4 l = lo[p];
    mochi_move(s, l, dem.dt, vx, vy, vz);
    pos[p] = s;
    lo[p] = l;
}

// Reorders the state: sorted position p takes the sphere at position `order[p]` of the input.
extern "C" __global__ void dem_permute(const float4* pos_in, const float4* lo_in,
                                       const float4* vel_in, const unsigned int* ids_in,
                                       const unsigned int* order, float4* pos, float4* lo,
                                       float4* vel, unsigned int* ids, unsigned int n) {
    unsigned int p = blockIdx.x * blockDim.x + threadIdx.x;
    if (p >= n) {
        return;
    }
    unsigned int k = order[p];
    pos[p] = pos_in[k];
    lo[p] = lo_in[k];
    vel[p] = vel_in[k];
    ids[p] = ids_in[k];
}
