// Device-side declarations shared by mochi's OptiX programs: the few OptiX intrinsics they call
// (written from the documented ABI of the `_optix_*` calls, not from NVIDIA's headers) and the
// proxy-sphere rule of docs/method.md. NVRTC compiles this file prepended to each program file.

// ---- OptiX intrinsics -------------------------------------------------------------------

static __forceinline__ __device__ unsigned int mochi_launch_index() {
    unsigned int u;
    asm("call (%0), _optix_get_launch_index_x, ();" : "=r"(u) :);
    return u;
}

static __forceinline__ __device__ unsigned int mochi_primitive_index() {
    unsigned int u;
    asm("call (%0), _optix_read_primitive_idx, ();" : "=r"(u) :);
    return u;
}

// Payload word k (0..MOCHI_MAX_PAYLOADS) of the ray being traced.
static __forceinline__ __device__ unsigned int mochi_get_payload(unsigned int k) {
    unsigned int u;
    asm volatile("call (%0), _optix_get_payload, (%1);" : "=r"(u) : "r"(k));
    return u;
}

static __forceinline__ __device__ void mochi_set_payload(unsigned int k, unsigned int p) {
    asm volatile("call _optix_set_payload, (%0, %1);" : : "r"(k), "r"(p));
}

// Payload words of the detection and frictionless DEM programs (the pipelines declare their own
// count; the granular step's programs use more).
#define MOCHI_MAX_PAYLOADS 5

// Word k of the payload array `p` as the trace call passes it: 0 past its end.
template <unsigned int N>
static __forceinline__ __device__ unsigned int mochi_payload_word(const unsigned int (&p)[N],
                                                                  unsigned int k) {
    return k < N ? p[k < N ? k : 0u] : 0u;
}

// Traces a point ray (zero length, any direction) from `o` with `count` payload words `p`
// (count <= N <= 32), any-hit programs disabled; `p` holds the words as the programs left them.
template <unsigned int N>
static __forceinline__ __device__ void mochi_trace_point(unsigned long long handle, float ox,
                                                         float oy, float oz, unsigned int count,
                                                         unsigned int (&p)[N]) {
    static_assert(N <= 32u, "OptiX passes at most 32 payload words");
    const unsigned int flags = 1u;  // OPTIX_RAY_FLAG_DISABLE_ANYHIT
    unsigned int r[32];
    asm volatile(
        "call"
        "(%0,%1,%2,%3,%4,%5,%6,%7,%8,%9,%10,%11,%12,%13,%14,%15,%16,%17,%18,%19,%20,%21,%22,%23,"
        "%24,%25,%26,%27,%28,%29,%30,%31),"
        "_optix_trace_typed_32,"
        "(%32,%33,%34,%35,%36,%37,%38,%39,%40,%41,%42,%43,%44,%45,%46,%47,%48,%49,%50,%51,%52,"
        "%53,%54,%55,%56,%57,%58,%59,%60,%61,%62,%63,%64,%65,%66,%67,%68,%69,%70,%71,%72,%73,"
        "%74,%75,%76,%77,%78,%79,%80);"
        : "=r"(r[0]), "=r"(r[1]), "=r"(r[2]), "=r"(r[3]), "=r"(r[4]), "=r"(r[5]), "=r"(r[6]),
          "=r"(r[7]), "=r"(r[8]), "=r"(r[9]), "=r"(r[10]), "=r"(r[11]), "=r"(r[12]), "=r"(r[13]),
          "=r"(r[14]), "=r"(r[15]), "=r"(r[16]), "=r"(r[17]), "=r"(r[18]), "=r"(r[19]),
          "=r"(r[20]), "=r"(r[21]), "=r"(r[22]), "=r"(r[23]), "=r"(r[24]), "=r"(r[25]),
          "=r"(r[26]), "=r"(r[27]), "=r"(r[28]), "=r"(r[29]), "=r"(r[30]), "=r"(r[31])
        : "r"(0u), "l"(handle), "f"(ox), "f"(oy), "f"(oz), "f"(0.0f), "f"(0.0f), "f"(1.0f),
          "f"(0.0f), "f"(0.0f), "f"(0.0f), "r"(0xffu), "r"(flags), "r"(0u), "r"(1u), "r"(0u),
          "r"(count), "r"(mochi_payload_word(p, 0u)), "r"(mochi_payload_word(p, 1u)),
          "r"(mochi_payload_word(p, 2u)), "r"(mochi_payload_word(p, 3u)),
          "r"(mochi_payload_word(p, 4u)), "r"(mochi_payload_word(p, 5u)),
          "r"(mochi_payload_word(p, 6u)), "r"(mochi_payload_word(p, 7u)),
          "r"(mochi_payload_word(p, 8u)), "r"(mochi_payload_word(p, 9u)),
          "r"(mochi_payload_word(p, 10u)), "r"(mochi_payload_word(p, 11u)),
          "r"(mochi_payload_word(p, 12u)), "r"(mochi_payload_word(p, 13u)),
          "r"(mochi_payload_word(p, 14u)), "r"(mochi_payload_word(p, 15u)),
          "r"(mochi_payload_word(p, 16u)), "r"(mochi_payload_word(p, 17u)),
          "r"(mochi_payload_word(p, 18u)), "r"(mochi_payload_word(p, 19u)),
          "r"(mochi_payload_word(p, 20u)), "r"(mochi_payload_word(p, 21u)),
          "r"(mochi_payload_word(p, 22u)), "r"(mochi_payload_word(p, 23u)),
          "r"(mochi_payload_word(p, 24u)), "r"(mochi_payload_word(p, 25u)),
          "r"(mochi_payload_word(p, 26u)), "r"(mochi_payload_word(p, 27u)),
          "r"(mochi_payload_word(p, 28u)), "r"(mochi_payload_word(p, 29u)),
          "r"(mochi_payload_word(p, 30u)), "r"(mochi_payload_word(p, 31u)));
    for (unsigned int k = 0; k < N; ++k) {
        p[k] = r[k];
    }
}

// ---- The proxy-sphere rule (docs/method.md rules 1-3). Keep in sync with src/proxy.rs. -----------
// Rounded exactly as the Rust code: no fused multiply-adds (the __f*_rn intrinsics).

#define MOCHI_MODE_MOCHI 0u
#define MOCHI_MODE_NNS 1u

// |d| <= t in plain squares (src/proxy.rs `within`: the accepted radii keep every threshold's
// square normal).
static __forceinline__ __device__ bool mochi_within(float dx, float dy, float dz, float t) {
    return __fadd_rn(__fadd_rn(__fmul_rn(dx, dx), __fmul_rn(dy, dy)), __fmul_rn(dz, dz)) <=
           __fmul_rn(t, t);
}

// Whether the ray of sphere i keeps its candidate j (spheres as x, y, z, r).
static __forceinline__ __device__ bool mochi_keep(
    unsigned int mode, unsigned int i, float4 a, unsigned int j, float4 b) {
    if (i == j) {
        return false;
    }
    float dx = __fsub_rn(a.x, b.x);
    float dy = __fsub_rn(a.y, b.y);
    float dz = __fsub_rn(a.z, b.z);
    bool collides = mochi_within(dx, dy, dz, __fadd_rn(a.w, b.w));
    if (mode == MOCHI_MODE_NNS) {
        return j > i && collides;
    }
    return collides && mochi_within(dx, dy, dz, 2.0f * b.w) &&
           (j > i || !mochi_within(dx, dy, dz, 2.0f * a.w));
}
