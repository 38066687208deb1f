// The second probe of performance-log/2026-12-02-h200.md (session 22; not part of mochi): the
// dense slab's contact pass with each CUDA block a tile of TX x TY x TZ cells, whose spheres and
// a halo of one cell are staged in shared memory first (the cells then of the largest diameter
// plus twice the slack, so that a widened window never leaves the halo). MODE 0: each pair once
// (the half-stencil walk), the partner's share by shared-memory atomics, the tile's sums then
// added to the forces with global atomics; 1: every sphere walks its whole window and stores its
// own force (each law twice, no atomics); 2: as 1 with the positions alone staged (velocities
// read from global memory). Beside them: the tree's form (the global walk, the partner's share
// by global atomics), its whole-window twin, and the whole-window pass with the integration
// fused in against the tree's form followed by an integration; every variant's forces are
// compared with the first's. With `cells` after the bed, the tree's form on cells finer than
// the diameter instead; with `compact`, the tree's form with its candidates read first from a
// compact copy of 8 bytes a sphere (centre and radius as 16-bit units of the bed's extent: a
// conservative test there, the exact one on the float4 centres of the few that pass). Bed:
// int32 n, then n rows of float32 x, y, z, r, vx, vy, vz (a frame's first seven columns).
// Build: nvcc -O3 -arch=sm_90 -std=c++17 -use_fast_math.
#include <initializer_list>
#include "2026-12-02-probe-common.cuh"
#include <string>
#include <thrust/device_vector.h>
#include <thrust/sort.h>
#include <thrust/sequence.h>
#include <thrust/binary_search.h>
#include <thrust/gather.h>
#include <thrust/iterator/counting_iterator.h>
struct Win { int3 lo, hi; };
__device__ __forceinline__ Win window(float4 s, const P& p) {
  float reach = (s.w + p.rmax + p.slack) * p.inv + 1.f/256.f;
  float ux = (s.x - p.lo.x)*p.inv, uy = (s.y - p.lo.y)*p.inv, uz = (s.z - p.lo.z)*p.inv;
  Win w;
  w.lo.x = (int)fminf(fmaxf(floorf(ux - reach), 0.f), p.nx-3) + 1; w.hi.x = (int)fminf(fmaxf(floorf(ux + reach), 0.f), p.nx-3) + 1;
  w.lo.y = (int)fminf(fmaxf(floorf(uy - reach), 0.f), p.ny-3) + 1; w.hi.y = (int)fminf(fmaxf(floorf(uy + reach), 0.f), p.ny-3) + 1;
  w.lo.z = (int)fminf(fmaxf(floorf(uz - reach), 0.f), p.nz-3) + 1; w.hi.z = (int)fminf(fmaxf(floorf(uz + reach), 0.f), p.nz-3) + 1;
  return w;
}
// Tiles of TX x TY x TZ cells, a halo of one; CAP spheres staged at most (else the tile's own
// spheres walk global memory).
template <int TX, int TY, int TZ, int CAP, int MODE>  // MODE 0: half + shared atomics; 1: full, no atomics; 2: full, positions only staged (vel from global)
__global__ void __launch_bounds__(256) resolve_tiled(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, unsigned* overflow, P p, int tnx, int tny) {
  constexpr int RX = TX + 2, RY = TY + 2, RZ = TZ + 2, R = RY * RZ, LX = RX + 1;
  __shared__ float4 spos[CAP];
  __shared__ float4 svel[MODE == 2 ? 1 : CAP];
  __shared__ float sacc[MODE == 0 ? 3 * CAP : 1];
  __shared__ unsigned row_len[R], row_off[R + 1], row_a[R], lstart[R * LX];
  int b = blockIdx.x; int tx = b % tnx, ty = (b / tnx) % tny, tz = b / (tnx * tny);
  int cx0 = 1 + tx * TX, cy0 = 1 + ty * TY, cz0 = 1 + tz * TZ;
  int xa = cx0 - 1;  // local x 0 is global xa; the grid has a margin cell on each side
  int xb = min(cx0 + TX, p.nx - 1);
  for (int r = threadIdx.x; r < R; r += blockDim.x) {
    int gy = cy0 - 1 + r % RY, gz = cz0 - 1 + r / RY; unsigned a = 0, e = 0;
    if (gy < p.ny && gz < p.nz) { int base = p.nx * (gy + p.ny * gz); a = __ldg(&cs[base + xa]); e = __ldg(&cs[base + xb + 1]); }
    row_a[r] = a; row_len[r] = e - a;
  }
  __syncthreads();
  if (threadIdx.x < 32) {  // exclusive scan of R row lengths by one warp
    unsigned carry = 0;
    for (int c = 0; c < R; c += 32) {
      int r = c + threadIdx.x; unsigned v = r < R ? row_len[r] : 0, x = v;
      for (int o = 1; o < 32; o <<= 1) { unsigned y = __shfl_up_sync(0xffffffff, x, o); if (threadIdx.x >= o) x += y; }
      if (r < R) row_off[r] = carry + x - v;
      carry += __shfl_sync(0xffffffff, x, 31);
    }
    if (threadIdx.x == 0) row_off[R] = carry;
  }
  if (MODE == 0) for (int k = threadIdx.x; k < 3 * CAP; k += blockDim.x) sacc[k] = 0.f;
  __syncthreads();
  unsigned total = row_off[R];
  if (total > CAP) { if (threadIdx.x == 0) atomicAdd(overflow, 1u); return; }
  for (int k = threadIdx.x; k < R * LX; k += blockDim.x) {
    int r = k / LX, lx = k % LX; int gy = cy0 - 1 + r % RY, gz = cz0 - 1 + r / RY; unsigned v = row_off[r];
    if (gy < p.ny && gz < p.nz) { int x = min(xa + lx, xb + 1); v += __ldg(&cs[p.nx * (gy + p.ny * gz) + x]) - row_a[r]; }
    lstart[k] = v;
  }
  for (unsigned s = threadIdx.x; s < total; s += blockDim.x) {
    int lo = 0, hi = R;
    while (hi - lo > 1) { int m = (lo + hi) >> 1; if (row_off[m] <= s) lo = m; else hi = m; }
    unsigned g = row_a[lo] + (s - row_off[lo]);
    spos[s] = __ldg(&pos[g]); if (MODE != 2) svel[s] = __ldg(&vel[g]);
  }
  __syncthreads();
  // own spheres: rows ly 1..TY, lz 1..TZ, cells lx 1..TX: local [lstart(r,1), lstart(r,TX+1)); spread over all threads
  constexpr int OWN = TY * TZ;
  __shared__ unsigned own_off[OWN + 1];
  if (threadIdx.x < 32) {
    unsigned carry = 0;
    for (int c = 0; c < OWN; c += 32) {
      int rr = c + threadIdx.x; unsigned v = 0;
      if (rr < OWN) { int r0 = (1 + rr % TY) + RY * (1 + rr / TY); v = lstart[r0 * LX + TX + 1] - lstart[r0 * LX + 1]; }
      unsigned x = v;
      for (int o = 1; o < 32; o <<= 1) { unsigned y = __shfl_up_sync(0xffffffff, x, o); if (threadIdx.x >= o) x += y; }
      if (rr < OWN) own_off[rr] = carry + x - v;
      carry += __shfl_sync(0xffffffff, x, 31);
    }
    if (threadIdx.x == 0) own_off[OWN] = carry;
  }
  __syncthreads();
  unsigned mine = 0; unsigned owns = own_off[OWN];
  for (unsigned o = threadIdx.x; o < owns; o += blockDim.x) {
    int lo_ = 0, hi_ = OWN;
    while (hi_ - lo_ > 1) { int m = (lo_ + hi_) >> 1; if (own_off[m] <= o) lo_ = m; else hi_ = m; }
    int rr = lo_; int ly = 1 + rr % TY, lz = 1 + rr / TY, r0 = ly + RY * lz;
    unsigned l = lstart[r0 * LX + 1] + (o - own_off[rr]);
    {
      unsigned g = row_a[r0] + (l - row_off[r0]);
      float4 s = spos[l]; float4 v = MODE == 2 ? __ldg(&vel[g]) : svel[l];
      Win w = window(s, p);
      w.lo.x = max(w.lo.x, xa); w.hi.x = min(w.hi.x, xb);
      w.lo.y = max(w.lo.y, cy0 - 1); w.hi.y = min(w.hi.y, cy0 + TY); w.lo.z = max(w.lo.z, cz0 - 1); w.hi.z = min(w.hi.z, cz0 + TZ);
      float fx = 0, fy = 0, fz = 0;
      int zs = MODE == 0 ? cz0 - 1 + lz : w.lo.z;
      for (int z = zs; z <= w.hi.z; z++) for (int y = ((MODE == 0 && z == cz0 - 1 + lz) ? cy0 - 1 + ly : w.lo.y); y <= w.hi.y; y++) {
        int r = (y - (cy0 - 1)) + RY * (z - (cz0 - 1));
        unsigned la = lstart[r * LX + w.lo.x - xa], le = lstart[r * LX + w.hi.x + 1 - xa];
        if (MODE == 0 && r == r0 && la < l + 1) la = l + 1;
        for (unsigned q = la; q < le; q++) {
          float4 t = spos[q];
          float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
          if (dx*dx+dy*dy+dz*dz > reach*reach || q == l) continue;
          float4 u;
          if (MODE == 2) u = __ldg(&vel[row_a[r] + (q - row_off[r])]); else u = svel[q];
          float4 f = law(s, v, t, u, p);
          if (f.w != 0.f) {
            if (MODE == 0) { atomicAdd(&sacc[3*q], -f.x); atomicAdd(&sacc[3*q+1], -f.y); atomicAdd(&sacc[3*q+2], -f.z); }
            fx += f.x; fy += f.y; fz += f.z; mine++;
          }
        }
      }
      if (MODE == 0) { atomicAdd(&sacc[3*l], fx); atomicAdd(&sacc[3*l+1], fy); atomicAdd(&sacc[3*l+2], fz); }
      else { force[3*g] = fx; force[3*g+1] = fy; force[3*g+2] = fz; }
    }
  }
  if (MODE == 0) {
    __syncthreads();
    for (unsigned s = threadIdx.x; s < total; s += blockDim.x) {
      float ax = sacc[3*s], ay = sacc[3*s+1], az = sacc[3*s+2];
      if (ax != 0.f || ay != 0.f || az != 0.f) {
        int lo = 0, hi = R;
        while (hi - lo > 1) { int m = (lo + hi) >> 1; if (row_off[m] <= s) lo = m; else hi = m; }
        unsigned g = row_a[lo] + (s - row_off[lo]);
        atomicAdd(&force[3*g], ax); atomicAdd(&force[3*g+1], ay); atomicAdd(&force[3*g+2], az);
      }
    }
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// Sphere i's own force from every contact in its whole window (each pair's law evaluated by both
// its spheres), and the contacts counted into `mine`.
__device__ __forceinline__ float3 whole_window_force(int i, float4 s, float4 v, const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, const P& p, unsigned& mine) {
  Win w = window(s, p);
  float fx = 0, fy = 0, fz = 0;
  for (int z = w.lo.z; z <= w.hi.z; z++) for (int y = w.lo.y; y <= w.hi.y; y++) {
    int row = p.nx * (y + p.ny * z);
    unsigned a = __ldg(&cs[row + w.lo.x]), b = __ldg(&cs[row + w.hi.x + 1]);
    for (unsigned q = a; q < b; q++) {
      float4 t = __ldg(&pos[q]);
      float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
      if (dx*dx+dy*dy+dz*dz > reach*reach || q == (unsigned)i) continue;
      float4 u = __ldg(&vel[q]); float4 f = law(s, v, t, u, p);
      if (f.w != 0.f) { fx += f.x; fy += f.y; fz += f.z; mine++; }
    }
  }
  return make_float3(fx, fy, fz);
}
// Global, every sphere its whole window, own force stored (no atomics).
__global__ void __launch_bounds__(256) resolve_global_full(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, P p) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; unsigned mine = 0;
  if (i < p.n) {
    float3 f = whole_window_force(i, __ldg(&pos[i]), __ldg(&vel[i]), pos, vel, cs, p, mine);
    force[3*i] = f.x; force[3*i+1] = f.y; force[3*i+2] = f.z;
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}

// The whole-window pass with the integration fused in: each sphere's whole force, then one
// semi-implicit Euler step written to a second state (the first is read by the other threads).
__global__ void __launch_bounds__(256) resolve_fused(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float4* pos2, float4* vel2, unsigned* contacts, P p, float dt) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = __ldg(&vel[i]);
    float3 f = whole_window_force(i, s, v, pos, vel, cs, p, mine);
    float fx = f.x, fy = f.y, fz = f.z;
    float m = v.w;
    v.x += dt*fx/m; v.y += dt*fy/m; v.z += dt*(fz/m - 9.81f);
    s.x += dt*v.x; s.y += dt*v.y; s.z += dt*v.z;
    vel2[i] = v; pos2[i] = s;
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// The tree's update after the pass: forces read and cleared, the state read and written in place.
__global__ void integrate(float4* pos, float4* vel, float* force, int n, float dt) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; if (i >= n) return;
  float4 s = pos[i], v = vel[i]; float m = v.w;
  v.x += dt*force[3*i]/m; v.y += dt*force[3*i+1]/m; v.z += dt*(force[3*i+2]/m - 9.81f);
  s.x += dt*v.x; s.y += dt*v.y; s.z += dt*v.z;
  vel[i] = v; pos[i] = s; force[3*i] = 0; force[3*i+1] = 0; force[3*i+2] = 0;
}

// Compact centres: each coordinate and the radius as 16-bit units of `unit` metres from `lo`.
struct Q { float3 lo; float inv_unit; };
__global__ void compact_k(const float4* pos, ushort4* cpos, Q q, int n) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; if (i >= n) return;
  float4 s = pos[i];
  cpos[i] = make_ushort4((unsigned short)__float2uint_rn((s.x - q.lo.x) * q.inv_unit), (unsigned short)__float2uint_rn((s.y - q.lo.y) * q.inv_unit),
                         (unsigned short)__float2uint_rn((s.z - q.lo.z) * q.inv_unit), (unsigned short)__float2uint_ru(s.w * q.inv_unit));
}
// MODE 0: walk only (count pairs within reach); 1: the whole pass. COMPACT: candidates tested
// first on the compact centres (reach + 2 units: rounding of both centres), then exactly.
template <int MODE, bool COMPACT>
__global__ void __launch_bounds__(256) pass_k(const float4* __restrict__ pos, const ushort4* __restrict__ cpos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, P p) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = MODE ? __ldg(&vel[i]) : make_float4(0, 0, 0, 0);
    ushort4 c = COMPACT ? __ldg(&cpos[i]) : make_ushort4(0, 0, 0, 0);
    Win w = window(s, p); int3 cc = cellc(make_float3(s.x, s.y, s.z), p);
    float fx = 0, fy = 0, fz = 0;
    for (int z = cc.z; z <= w.hi.z; z++) for (int y = (z == cc.z ? cc.y : w.lo.y); y <= w.hi.y; y++) {
      int row = p.nx * (y + p.ny * z);
      unsigned a = __ldg(&cs[row + w.lo.x]), b = __ldg(&cs[row + w.hi.x + 1]);
      if (a < (unsigned)i + 1) a = i + 1;
      for (unsigned q = a; q < b; q++) {
        if (COMPACT) {
          ushort4 t = __ldg(&cpos[q]);
          int dx = (int)t.x - (int)c.x, dy = (int)t.y - (int)c.y, dz = (int)t.z - (int)c.z; int reach = (int)t.w + (int)c.w + 2;
          if (dx*dx + dy*dy + dz*dz > reach*reach) continue;
        }
        float4 t = __ldg(&pos[q]);
        float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
        if (dx*dx+dy*dy+dz*dz > reach*reach) continue;
        if (MODE == 0) { mine++; continue; }
        float4 u = __ldg(&vel[q]); float4 f = law(s, v, t, u, p);
        if (f.w != 0.f) { atomicAdd(&force[3*q], -f.x); atomicAdd(&force[3*q+1], -f.y); atomicAdd(&force[3*q+2], -f.z); fx += f.x; fy += f.y; fz += f.z; mine++; }
      }
    }
    if (MODE && mine) { atomicAdd(&force[3*i], fx); atomicAdd(&force[3*i+1], fy); atomicAdd(&force[3*i+2], fz); }
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}

int main(int argc, char** argv) {
  Bed bed; if (argc < 2 || !load_bed(argv[1], bed)) { printf("usage: probe BED\n"); return 1; }
  const int n = bed.n; const std::vector<float4>& hp = bed.pos; const std::vector<float4>& hv = bed.vel;
  const float rmax = bed.rmax; const float3 lo = bed.lo, hi = bed.hi;
  cudaEvent_t e0, e1; cudaEventCreate(&e0); cudaEventCreate(&e1);
  thrust::device_vector<float4> dpos(hp.begin(), hp.end()), dvel(hv.begin(), hv.end());
  thrust::device_vector<float> ref;
  // Configurations {slack, cell} in diameters (cell 0: the diameter plus twice the slack).
  // `probe BED` times the tiles; `probe BED cells` the tree's form on finer cells; `probe BED
  // compact` the tree's form with its candidates read from a compact copy first.
  const bool compact = argc > 2 && std::string(argv[2]) == "compact";
  const bool cells_only = argc > 2 && !compact;
  const std::vector<std::pair<float, float>> tiles_cfg = {{0.f, 1.f}, {0.2f, 1.f}, {0.2f, 0.f}};
  const std::vector<std::pair<float, float>> cells_cfg = {{0.f, 1.f}, {0.2f, 1.f}, {0.2f, 0.8f}, {0.2f, 0.667f}, {0.2f, 0.5f}, {0.2f, 0.4f}, {0.f, 0.5f}};
  const std::vector<std::pair<float, float>> compact_cfg = {{0.f, 1.f}, {0.2f, 1.f}};
  for (auto [slackc, cellf] : compact ? compact_cfg : cells_only ? cells_cfg : tiles_cfg) {
    P p; p.lo = lo; float base = 2.f*rmax*1.001f; float slack = slackc*base; bool big = cellf == 0.f;
    float cell = big ? base + 2.f*slack : base*cellf;
    p.inv = 1.f/cell; p.nx = (int)((hi.x-lo.x)*p.inv)+3; p.ny = (int)((hi.y-lo.y)*p.inv)+3; p.nz = (int)((hi.z-lo.z)*p.inv)+3;
    p.rmax = rmax*1.001f; p.slack = slack; p.n = n; p.zeta = 0.3f; float dt = 1e-4f; p.rate = (3.14159265f/(10*dt))*(3.14159265f/(10*dt));
    size_t cells = (size_t)p.nx*p.ny*p.nz;
    printf("== slack %.1f diameter, cells %s %.3f diameter: %g m, grid %d x %d x %d\n", slackc, big ? "2 slack +" : "", big ? 1.f : cellf, cell, p.nx, p.ny, p.nz);
    thrust::device_vector<float4> spos(n), svel(n); thrust::device_vector<unsigned> key(n), idx(n), cs(cells + 1);
    keys_k<<<(n+255)/256, 256>>>(thrust::raw_pointer_cast(dpos.data()), thrust::raw_pointer_cast(key.data()), p);
    thrust::sequence(idx.begin(), idx.end()); thrust::sort_by_key(key.begin(), key.end(), idx.begin());
    thrust::gather(idx.begin(), idx.end(), dpos.begin(), spos.begin()); thrust::gather(idx.begin(), idx.end(), dvel.begin(), svel.begin());
    thrust::lower_bound(key.begin(), key.end(), thrust::counting_iterator<unsigned>(0), thrust::counting_iterator<unsigned>(cells + 1), cs.begin());
    thrust::device_vector<float> force(3*(size_t)n); thrust::device_vector<unsigned> cnt(2);
    float4* P_ = thrust::raw_pointer_cast(spos.data()); float4* V_ = thrust::raw_pointer_cast(svel.data());
    unsigned* C_ = thrust::raw_pointer_cast(cs.data()); float* F_ = thrust::raw_pointer_cast(force.data()); unsigned* K_ = thrust::raw_pointer_cast(cnt.data());
    // reference forces by sphere id (idx) from the global pass
    std::vector<float> fref;
    auto check = [&](const char* name) {
      std::vector<float> fh(3*(size_t)n); thrust::copy(force.begin(), force.end(), fh.begin());
      if (fref.empty()) { fref = fh; return; }
      double num = 0, den = 0; for (size_t k = 0; k < fh.size(); k++) { double d = fh[k] - fref[k]; num += d*d; den += (double)fref[k]*fref[k]; }
      printf("   %-44s rel. force difference %.2e\n", name, sqrt(num/den));
    };
    auto bench = [&](const char* name, bool zero, auto launch, bool compare = true) {
      const int R = 200;
      for (int w = 0; w < 5; w++) launch();
      cudaMemset(K_, 0, 8); thrust::fill(force.begin(), force.end(), 0.f); launch(); unsigned c[2]; cudaMemcpy(c, K_, 8, cudaMemcpyDeviceToHost);
      CK(cudaDeviceSynchronize()); if (compare) check(name);
      cudaEventRecord(e0);
      for (int r = 0; r < R; r++) { if (zero) cudaMemsetAsync(F_, 0, 12*(size_t)n); launch(); }
      cudaEventRecord(e1); CK(cudaEventSynchronize(e1)); float ms; cudaEventElapsedTime(&ms, e0, e1);
      printf("%-44s %8.2f us  (contacts %u, tiles overflowed %u)\n", name, 1000.f*ms/R, c[0], c[1]);
    };
    int blocks = (n+255)/256;
    if (compact) {
      float extent = fmaxf(fmaxf(hi.x - lo.x, hi.y - lo.y), hi.z - lo.z) + 2.f*rmax;
      Q qz; qz.lo = make_float3(lo.x - rmax, lo.y - rmax, lo.z - rmax); qz.inv_unit = 65000.f / extent;
      printf("compact unit %g m\n", 1.f/qz.inv_unit);
      thrust::device_vector<ushort4> cpos(n); ushort4* C8 = thrust::raw_pointer_cast(cpos.data());
      bench("compact copy written (8 bytes a sphere)", false, [&]{ compact_k<<<blocks,256>>>(P_, C8, qz, n); }, false);
      bench("walk only, float4 centres", false, [&]{ pass_k<0,false><<<blocks,256>>>(P_, C8, V_, C_, F_, K_, p); }, false);
      bench("walk only, compact centres first", false, [&]{ pass_k<0,true><<<blocks,256>>>(P_, C8, V_, C_, F_, K_, p); }, false);
      bench("whole pass, float4 centres (+ clear)", true, [&]{ pass_k<1,false><<<blocks,256>>>(P_, C8, V_, C_, F_, K_, p); });
      bench("whole pass, compact centres first (+ clear)", true, [&]{ pass_k<1,true><<<blocks,256>>>(P_, C8, V_, C_, F_, K_, p); });
      continue;
    }
    bench("global walk + atomics (+ clear)", true, [&]{ pass_k<1,false><<<blocks,256>>>(P_, nullptr, V_, C_, F_, K_, p); });
    auto tiled = [&](auto kern, int TX, int TY, int TZ, int threads, const char* name, bool zero) {
      int tnx = (p.nx - 2 + TX - 1)/TX, tny = (p.ny - 2 + TY - 1)/TY, tnz = (p.nz - 2 + TZ - 1)/TZ;
      bench(name, zero, [&]{ kern<<<tnx*tny*tnz, threads>>>(P_, V_, C_, F_, K_, K_ + 1, p, tnx, tny); });
    };
    bench("global full window, no atomics", false, [&]{ resolve_global_full<<<blocks,256>>>(P_, V_, C_, F_, K_, p); });
    if (!cells_only) {
      // dt 1e-9 s: the state stays the bed's over the repeats (to 1e-9 of a radius).
      thrust::device_vector<float4> pos2 = spos, vel2 = svel, pos3 = spos, vel3 = svel, pos4 = spos, vel4 = svel;
      float4* P2 = thrust::raw_pointer_cast(pos2.data()); float4* V2 = thrust::raw_pointer_cast(vel2.data());
      float4* P3 = thrust::raw_pointer_cast(pos3.data()); float4* V3 = thrust::raw_pointer_cast(vel3.data());
      float4* P4 = thrust::raw_pointer_cast(pos4.data()); float4* V4 = thrust::raw_pointer_cast(vel4.data());
      bench("global walk + atomics, then integrate", false, [&]{ pass_k<1,false><<<blocks,256>>>(P3, nullptr, V3, C_, F_, K_, p); integrate<<<blocks,256>>>(P3, V3, F_, n, 1e-9f); }, false);
      bool flip = false;
      bench("whole windows + integration fused", false, [&]{ if (flip) resolve_fused<<<blocks,256>>>(P2, V2, C_, P4, V4, K_, p, 1e-9f); else resolve_fused<<<blocks,256>>>(P4, V4, C_, P2, V2, K_, p, 1e-9f); flip = !flip; }, false);
    }
    if (!cells_only && (big || slackc == 0.f)) {
      tiled(resolve_tiled<8,8,4,1024,0>, 8,8,4, 128, "tiles 8x8x4 half, shared atomics (+ clear)", true);
      tiled(resolve_tiled<16,8,4,960,0>, 16,8,4, 256, "tiles 16x8x4 half, shared atomics (+ clear)", true);
      tiled(resolve_tiled<8,8,4,1024,1>, 8,8,4, 128, "tiles 8x8x4 full, no atomics", false);
      tiled(resolve_tiled<16,8,4,1280,1>, 16,8,4, 256, "tiles 16x8x4 full, no atomics, 256 thr", false);
      tiled(resolve_tiled<16,8,4,1280,1>, 16,8,4, 128, "tiles 16x8x4 full, no atomics, 128 thr", false);
      tiled(resolve_tiled<32,8,4,2048,2>, 32,8,4, 256, "tiles 32x8x4 full, pos staged only", false);
      tiled(resolve_tiled<16,16,4,2048,2>, 16,16,4, 256, "tiles 16x16x4 full, pos staged only", false);
      tiled(resolve_tiled<16,8,4,1280,2>, 16,8,4, 256, "tiles 16x8x4 full, pos staged only", false);
    }
  }
  return 0;
}
