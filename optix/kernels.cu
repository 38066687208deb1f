// Plain CUDA kernels of the optix backend. Needs device.cuh prepended.

// Gathers the spheres into sorted order (`order[p]` is the input index of sorted position p) and
// writes each one's proxy box (x, y, z min, then max): half-width 2·r in mochi mode, 2·r_max in
// nns mode, padded by `pad_rel` of the largest coordinate involved so the box test never
// rejects a point the rule accepts. Keep in sync with wgsl/rq_build.wgsl.
extern "C" __global__ void proxy_boxes(const float4* spheres_in, const unsigned int* order,
                                       float4* spheres, float* boxes, unsigned int n,
                                       unsigned int mode, float r_max, float pad_rel) {
    unsigned int p = blockIdx.x * blockDim.x + threadIdx.x;
    if (p >= n) {
        return;
    }
    float4 s = spheres_in[order[p]];
    spheres[p] = s;
    float h = mode == MOCHI_MODE_NNS ? 2.0f * r_max : 2.0f * s.w;
    float pad = (fmaxf(fmaxf(fabsf(s.x), fabsf(s.y)), fabsf(s.z)) + h) * pad_rel;
    float w = h + pad;
    boxes[6 * p + 0] = s.x - w;
    boxes[6 * p + 1] = s.y - w;
    boxes[6 * p + 2] = s.z - w;
    boxes[6 * p + 3] = s.x + w;
    boxes[6 * p + 4] = s.y + w;
    boxes[6 * p + 5] = s.z + w;
}
