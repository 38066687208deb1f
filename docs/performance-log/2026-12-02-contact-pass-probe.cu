// The probe of performance-log/2026-12-02-h200.md (not part of mochi): the dense slab's contact
// pass (the half-stencil walk of a dense cell table, the per-pair linear law, the partner's share
// added with float atomics) written in CUDA, in the variants the log names, timed on a bed read
// from a binary file (int32 n, then n rows of float32 x, y, z, r, vx, vy, vz: a frame's first
// seven columns). Build: nvcc -O3 -arch=sm_90 -std=c++17 [-use_fast_math] -o probe this file.
// Run: probe BED (the variants of session 21); probe BED queued (session 23: the tree's form
// beside the queued law and the form with more loads in flight, forces checked against the
// tree's); probe BED once (those kernels launched once each, for Nsight Compute); probe BED order
// (session 24: the tree's form with its threads taking the spheres tile by tile).
#include <initializer_list>
#include <string>
#include "2026-12-02-probe-common.cuh"
#include <cub/block/block_scan.cuh>
#include <thrust/device_vector.h>
#include <thrust/sort.h>
#include <thrust/scan.h>
#include <thrust/sequence.h>
#include <thrust/binary_search.h>
#include <thrust/gather.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/extrema.h>
struct Win { int first, width, ny, count, dx, dy; int3 lo; };
__device__ __forceinline__ Win window(float4 s, const P& p) {
  float reach = (s.w + p.rmax + p.slack) * p.inv + 1.f/256.f;
  float ux = (s.x - p.lo.x)*p.inv, uy = (s.y - p.lo.y)*p.inv, uz = (s.z - p.lo.z)*p.inv;
  int lx = (int)fminf(fmaxf(floorf(ux - reach), 0.f), p.nx-3) + 1, hx = (int)fminf(fmaxf(floorf(ux + reach), 0.f), p.nx-3) + 1;
  int ly = (int)fminf(fmaxf(floorf(uy - reach), 0.f), p.ny-3) + 1, hy = (int)fminf(fmaxf(floorf(uy + reach), 0.f), p.ny-3) + 1;
  int lz = (int)fminf(fmaxf(floorf(uz - reach), 0.f), p.nz-3) + 1, hz = (int)fminf(fmaxf(floorf(uz + reach), 0.f), p.nz-3) + 1;
  Win w; w.lo = make_int3(lx, ly, lz); w.width = hx-lx+1; w.ny = hy-ly+1; w.count = w.ny*(hz-lz+1);
  w.dx = p.nx; w.dy = p.ny; w.first = lx + p.nx*(ly + p.ny*lz); return w;
}
// The tree's per-pair law as wgsl/dem/dem_physics.wgsl writes it: the effective mass without the
// product (two divisions), the damping's √(k·m*) as √k·√m* (two square roots), the normal as
// three divisions by the distance.
__device__ __forceinline__ float effective(float a, float b) { float lo = fminf(a, b), hi = fmaxf(a, b); return lo / (1.f + lo / hi); }
__device__ __forceinline__ float4 law_tree(float4 s, float4 v, float4 t, float4 u, const P& p) {
  float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z;
  float d2 = dx*dx + dy*dy + dz*dz; float reach = s.w + t.w;
  if (d2 > reach*reach || d2 == 0.f) return make_float4(0,0,0,0);
  float dist = sqrtf(d2); float nx = dx/dist, ny = dy/dist, nz = dz/dist;
  float ov = reach - dist;
  float vn = (u.x-v.x)*nx + (u.y-v.y)*ny + (u.z-v.z)*nz;
  float me = effective(v.w, u.w); float k = me*p.rate; float c = 2.f*p.zeta*(sqrtf(k)*sqrtf(me));
  float push = fmaxf(k*ov - c*vn, 0.f);
  return make_float4(-push*nx, -push*ny, -push*nz, 1.f);
}
// The same law trimmed: the damping 2ζ·m*·√rate (√rate once for all, as k = m*·rate), the normal
// as the offset times one reciprocal of the distance.
__device__ __forceinline__ float4 law_trimmed(float4 s, float4 v, float4 t, float4 u, const P& p) {
  float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z;
  float d2 = dx*dx + dy*dy + dz*dz; float reach = s.w + t.w;
  if (d2 > reach*reach || d2 == 0.f) return make_float4(0,0,0,0);
  float dist = sqrtf(d2); float inv = 1.f/dist; float nx = dx*inv, ny = dy*inv, nz = dz*inv;
  float ov = reach - dist;
  float vn = (u.x-v.x)*nx + (u.y-v.y)*ny + (u.z-v.z)*nz;
  float me = effective(v.w, u.w); float k = me*p.rate; float c = (2.f*p.zeta*sqrtf(p.rate))*me;
  float push = fmaxf(k*ov - c*vn, 0.f);
  return make_float4(-push*nx, -push*ny, -push*nz, 1.f);
}
// Variant A: resolve each candidate as the walk meets it (LAW 0: the probe's law; 1: the tree's;
// 2: the tree's trimmed).
// `order`: the sphere each thread takes (nullptr: thread i takes sphere i, as the tree does).
template <bool RESOLVE, bool PARTNER, int LAW = 0>
__global__ void __launch_bounds__(256) resolve_inline(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, P p, const unsigned* __restrict__ order) {
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (order && i < p.n) i = (int)__ldg(&order[i]);
  unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = __ldg(&vel[i]);
    Win w = window(s, p); int3 c = cellc(make_float3(s.x, s.y, s.z), p);
    int y = c.y - w.lo.y, z = c.z - w.lo.z; int k = y + w.ny*z;
    int row = w.first + w.dx*(y + w.dy*z); int next_plane = w.dx*(w.dy - w.ny + 1);
    float fx = 0, fy = 0, fz = 0; float walked = 0;
    for (; k < w.count; k++) {
      unsigned a = __ldg(&cs[row]), b = __ldg(&cs[row + w.width]);
      if (a < (unsigned)i + 1) a = i + 1;
      for (unsigned q = a; q < b; q++) {
        float4 t = __ldg(&pos[q]);
        if (RESOLVE) {
          float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
          if (dx*dx+dy*dy+dz*dz > reach*reach) continue;
          float4 u = __ldg(&vel[q]);
          float4 f = LAW == 1 ? law_tree(s, v, t, u, p) : LAW == 2 ? law_trimmed(s, v, t, u, p) : law(s, v, t, u, p);
          if (f.w != 0.f) {
            if (PARTNER) { atomicAdd(&force[3*q], -f.x); atomicAdd(&force[3*q+1], -f.y); atomicAdd(&force[3*q+2], -f.z); }
            fx += f.x; fy += f.y; fz += f.z; mine++;
          }
        } else {
          float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
          walked += (dx*dx+dy*dy+dz*dz <= reach*reach) ? 1.f : 0.f;
        }
      }
      y++; if (y == w.ny) { y = 0; row += next_plane; } else row += w.dx;
    }
    if (!RESOLVE) mine = (unsigned)walked;
    if (mine) { atomicAdd(&force[3*i], fx); atomicAdd(&force[3*i+1], fy); atomicAdd(&force[3*i+2], fz); }
  }
  // warp-aggregated count
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// Variant B: as the WGSL pass: list up to ROOM candidates within reach in shared memory, resolve them, walk again for more.
#define ROOM 8
__global__ void __launch_bounds__(256) resolve_listed(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, P p) {
  __shared__ unsigned near[ROOM*256];
  int i = blockIdx.x * blockDim.x + threadIdx.x; unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = __ldg(&vel[i]);
    float fx = 0, fy = 0, fz = 0;
    unsigned skip = 0; unsigned base = threadIdx.x*ROOM;
    for (;;) {
      unsigned found = 0, listed = 0;
      Win w = window(s, p); int3 c = cellc(make_float3(s.x, s.y, s.z), p);
      int y = c.y - w.lo.y, z = c.z - w.lo.z; int k = y + w.ny*z;
      int row = w.first + w.dx*(y + w.dy*z); int next_plane = w.dx*(w.dy - w.ny + 1);
      for (; k < w.count; k++) {
        unsigned a = __ldg(&cs[row]), b = __ldg(&cs[row + w.width]);
        if (a < (unsigned)i + 1) a = i + 1;
        for (unsigned q = a; q < b; q++) {
          float4 t = __ldg(&pos[q]);
          float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
          if (dx*dx+dy*dy+dz*dz > reach*reach) continue;
          unsigned f = found++;
          if (f >= skip && listed < ROOM) near[base + listed++] = q;
        }
        y++; if (y == w.ny) { y = 0; row += next_plane; } else row += w.dx;
      }
      for (unsigned kk = 0; kk < listed; kk++) {
        unsigned q = near[base + kk]; float4 t = __ldg(&pos[q]); float4 u = __ldg(&vel[q]);
        float4 f = law(s, v, t, u, p);
        if (f.w != 0.f) { atomicAdd(&force[3*q], -f.x); atomicAdd(&force[3*q+1], -f.y); atomicAdd(&force[3*q+2], -f.z); fx += f.x; fy += f.y; fz += f.z; mine++; }
      }
      if (found <= skip + ROOM) break; skip += ROOM;
    }
    if (mine) { atomicAdd(&force[3*i], fx); atomicAdd(&force[3*i+1], fy); atomicAdd(&force[3*i+2], fz); }
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// Variant C: every sphere walks its whole window and sums its own force alone (each pair's law
// twice, no atomics, one plain store).
__global__ void __launch_bounds__(256) resolve_full(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, P p) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = __ldg(&vel[i]);
    Win w = window(s, p);
    float fx = 0, fy = 0, fz = 0; int y = 0; int row = w.first; int next_plane = w.dx*(w.dy - w.ny + 1);
    for (int k = 0; k < w.count; k++) {
      unsigned a = __ldg(&cs[row]), b = __ldg(&cs[row + w.width]);
      for (unsigned q = a; q < b; q++) {
        float4 t = __ldg(&pos[q]);
        float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
        if (dx*dx+dy*dy+dz*dz > reach*reach || q == (unsigned)i) continue;
        float4 u = __ldg(&vel[q]);
        float4 f = law(s, v, t, u, p);
        if (f.w != 0.f) { fx += f.x; fy += f.y; fz += f.z; mine++; }
      }
      y++; if (y == w.ny) { y = 0; row += next_plane; } else row += w.dx;
    }
    force[3*i] = fx; force[3*i+1] = fy; force[3*i+2] = fz;
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// Variant D: as the inline resolve, each force added with one vector atomic (Hopper's
// red.global.add.v4.f32) to a float4 a sphere.
__global__ void __launch_bounds__(256) resolve_v4(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float4* force, unsigned* contacts, P p) {
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = __ldg(&vel[i]);
    Win w = window(s, p); int3 c = cellc(make_float3(s.x, s.y, s.z), p);
    int y = c.y - w.lo.y, z = c.z - w.lo.z; int k = y + w.ny*z;
    int row = w.first + w.dx*(y + w.dy*z); int next_plane = w.dx*(w.dy - w.ny + 1);
    float4 tot = make_float4(0, 0, 0, 0);
    for (; k < w.count; k++) {
      unsigned a = __ldg(&cs[row]), b = __ldg(&cs[row + w.width]);
      if (a < (unsigned)i + 1) a = i + 1;
      for (unsigned q = a; q < b; q++) {
        float4 t = __ldg(&pos[q]);
        float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
        if (dx*dx+dy*dy+dz*dz > reach*reach) continue;
        float4 u = __ldg(&vel[q]);
        float4 f = law(s, v, t, u, p);
        if (f.w != 0.f) {
          atomicAdd(&force[q], make_float4(-f.x, -f.y, -f.z, 0.f));
          tot.x += f.x; tot.y += f.y; tot.z += f.z; mine++;
        }
      }
      y++; if (y == w.ny) { y = 0; row += next_plane; } else row += w.dx;
    }
    if (mine) atomicAdd(&force[i], tot);
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// Variant F: the law for a warp's 32 contacts at once. Every lane steps its own walk one
// candidate an iteration (the rows flattened, so the warp stays converged); the lanes within
// reach append (partner, own lane) to the warp's queue in shared memory, and each time 32 are
// queued every lane resolves one of them. The own share goes to the owner's slot in shared
// memory (OWN_SHARED) or with global atomics as the partner's.
template <bool OWN_SHARED>
__global__ void __launch_bounds__(256) resolve_queued(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, P p) {
  __shared__ unsigned queued[8][64];
  __shared__ float own[8][32][3];
  const unsigned FULL = 0xffffffffu;
  int lane = threadIdx.x & 31, wp = threadIdx.x >> 5;
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  bool alive = i < p.n;
  own[wp][lane][0] = 0.f; own[wp][lane][1] = 0.f; own[wp][lane][2] = 0.f;
  float4 s = make_float4(0, 0, 0, 0), v = s;
  int k = 0, count = 0, y = 0, row = 0, width = 0, ny = 1, dx = 0, next_plane = 0;
  if (alive) {
    s = __ldg(&pos[i]); v = __ldg(&vel[i]);
    Win w = window(s, p); int3 c = cellc(make_float3(s.x, s.y, s.z), p);
    y = c.y - w.lo.y; int z = c.z - w.lo.z; k = y + w.ny*z; count = w.count; ny = w.ny;
    row = w.first + w.dx*(y + w.dy*z); next_plane = w.dx*(w.dy - w.ny + 1); width = w.width; dx = w.dx;
  }
  unsigned q = 0, b = 0, mine = 0; int queue = 0;
  auto resolve = [&](unsigned entry, bool take) {
    unsigned j = entry >> 5; int o = entry & 31;
    float4 so, vo;
    so.x = __shfl_sync(FULL, s.x, o); so.y = __shfl_sync(FULL, s.y, o); so.z = __shfl_sync(FULL, s.z, o); so.w = __shfl_sync(FULL, s.w, o);
    vo.x = __shfl_sync(FULL, v.x, o); vo.y = __shfl_sync(FULL, v.y, o); vo.z = __shfl_sync(FULL, v.z, o); vo.w = __shfl_sync(FULL, v.w, o);
    if (!take) return;
    float4 t = __ldg(&pos[j]); float4 u = __ldg(&vel[j]);
    float4 f = law(so, vo, t, u, p);
    if (f.w != 0.f) {
      atomicAdd(&force[3*j], -f.x); atomicAdd(&force[3*j+1], -f.y); atomicAdd(&force[3*j+2], -f.z);
      if (OWN_SHARED) { atomicAdd(&own[wp][o][0], f.x); atomicAdd(&own[wp][o][1], f.y); atomicAdd(&own[wp][o][2], f.z); }
      else { unsigned io = i - lane + o; atomicAdd(&force[3*io], f.x); atomicAdd(&force[3*io+1], f.y); atomicAdd(&force[3*io+2], f.z); }
      mine++;
    }
  };
  for (;;) {
    while (q >= b && k < count) {
      unsigned a = __ldg(&cs[row]); b = __ldg(&cs[row + width]);
      q = a < (unsigned)i + 1 ? (unsigned)i + 1 : a;
      k++; y++; if (y == ny) { y = 0; row += next_plane; } else row += dx;
    }
    bool more = alive && q < b;
    if (!__any_sync(FULL, more)) break;
    bool hit = false;
    if (more) {
      float4 t = __ldg(&pos[q]);
      float ex = t.x - s.x, ey = t.y - s.y, ez = t.z - s.z; float reach = s.w + t.w;
      hit = ex*ex + ey*ey + ez*ez <= reach*reach;
    }
    unsigned ballot = __ballot_sync(FULL, hit);
    if (hit) queued[wp][queue + __popc(ballot & ((1u << lane) - 1u))] = (q << 5) | lane;
    if (more) q++;
    queue += __popc(ballot);
    if (queue >= 32) {
      __syncwarp();
      queue -= 32;
      resolve(queued[wp][queue + lane], true);
      __syncwarp();
    }
  }
  __syncwarp();
  unsigned last = lane < queue ? queued[wp][lane] : 0u;
  resolve(last, lane < queue);
  __syncwarp();
  if (OWN_SHARED && alive) {
    float fx = own[wp][lane][0], fy = own[wp][lane][1], fz = own[wp][lane][2];
    if (fx != 0.f || fy != 0.f || fz != 0.f) { atomicAdd(&force[3*i], fx); atomicAdd(&force[3*i+1], fy); atomicAdd(&force[3*i+2], fz); }
  }
  unsigned tot = __reduce_add_sync(FULL, mine);
  if (lane == 0 && tot) atomicAdd(contacts, tot);
}
// Variant G: the tree's form with more loads in flight: the next row's bounds read before the
// current row's candidates, and U candidates of a row read together before any is tested (and
// the velocities of those within reach read together before any law); MINB > 1 asks the
// compiler for registers enough to keep MINB blocks on an SM.
template <int U, int MINB>
__global__ void __launch_bounds__(256, MINB) resolve_rows(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, P p) {
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = __ldg(&vel[i]);
    Win w = window(s, p); int3 c = cellc(make_float3(s.x, s.y, s.z), p);
    int y = c.y - w.lo.y, z = c.z - w.lo.z; int k = y + w.ny*z;
    int row = w.first + w.dx*(y + w.dy*z); int next_plane = w.dx*(w.dy - w.ny + 1);
    float fx = 0, fy = 0, fz = 0;
    unsigned a = 0, b = 0;
    if (k < w.count) { a = __ldg(&cs[row]); b = __ldg(&cs[row + w.width]); }
    while (k < w.count) {
      unsigned qa = a < (unsigned)i + 1 ? (unsigned)i + 1 : a, qb = b;
      k++; y++; if (y == w.ny) { y = 0; row += next_plane; } else row += w.dx;
      if (k < w.count) { a = __ldg(&cs[row]); b = __ldg(&cs[row + w.width]); }
      for (unsigned q = qa; q < qb; q += U) {
        float4 t[U], u[U]; bool hit[U];
#pragma unroll
        for (int e = 0; e < U; e++) t[e] = q + e < qb ? __ldg(&pos[q + e]) : make_float4(1e30f, 1e30f, 1e30f, 0.f);
#pragma unroll
        for (int e = 0; e < U; e++) {
          float dx = t[e].x - s.x, dy = t[e].y - s.y, dz = t[e].z - s.z; float reach = s.w + t[e].w;
          hit[e] = dx*dx + dy*dy + dz*dz <= reach*reach;
          if (hit[e]) u[e] = __ldg(&vel[q + e]);
        }
#pragma unroll
        for (int e = 0; e < U; e++) {
          if (!hit[e]) continue;
          float4 f = law(s, v, t[e], u[e], p);
          if (f.w != 0.f) {
            unsigned j = q + e;
            atomicAdd(&force[3*j], -f.x); atomicAdd(&force[3*j+1], -f.y); atomicAdd(&force[3*j+2], -f.z);
            fx += f.x; fy += f.y; fz += f.z; mine++;
          }
        }
      }
    }
    if (mine) { atomicAdd(&force[3*i], fx); atomicAdd(&force[3*i+1], fy); atomicAdd(&force[3*i+2], fz); }
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// Variant H: the listed form with the laws shared out over the block. Each thread walks and lists
// up to ROOM candidates within reach (as variant B); the block then numbers the listed entries
// (a scan of the counts) and resolves them 256 at a time, every thread one entry: its owner by a
// binary search of the counts' prefix, the partner's share by atomics, the entry's force to
// shared memory, which each owner then sums over its own entries of the round (no atomics for
// the own share). Threads with more than ROOM walk again while any thread of the block does.
__global__ void __launch_bounds__(256) resolve_block_laws(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float* force, unsigned* contacts, P p) {
  typedef cub::BlockScan<unsigned, 256> Scan;
  __shared__ typename Scan::TempStorage scan_room;
  __shared__ unsigned near[ROOM*256];
  __shared__ unsigned first[257];
  __shared__ float4 share[256], own_pos[256], own_vel[256];
  int lid = threadIdx.x, i = blockIdx.x * blockDim.x + lid;
  bool alive = i < p.n;
  float4 s = make_float4(0, 0, 0, 0), v = s;
  if (alive) { s = __ldg(&pos[i]); v = __ldg(&vel[i]); }
  own_pos[lid] = s; own_vel[lid] = v;
  float fx = 0, fy = 0, fz = 0; unsigned mine = 0, skip = 0; bool walking = alive;
  for (;;) {
    unsigned found = 0, listed = 0;
    if (walking) {
      Win w = window(s, p); int3 c = cellc(make_float3(s.x, s.y, s.z), p);
      int y = c.y - w.lo.y, z = c.z - w.lo.z; int k = y + w.ny*z;
      int row = w.first + w.dx*(y + w.dy*z); int next_plane = w.dx*(w.dy - w.ny + 1);
      for (; k < w.count; k++) {
        unsigned a = __ldg(&cs[row]), b = __ldg(&cs[row + w.width]);
        if (a < (unsigned)i + 1) a = i + 1;
        for (unsigned q = a; q < b; q++) {
          float4 t = __ldg(&pos[q]);
          float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
          if (dx*dx+dy*dy+dz*dz > reach*reach) continue;
          unsigned f = found++;
          if (f >= skip && listed < ROOM) near[lid*ROOM + listed++] = q;
        }
        y++; if (y == w.ny) { y = 0; row += next_plane; } else row += w.dx;
      }
    }
    unsigned at, total;
    Scan(scan_room).ExclusiveSum(listed, at, total);
    first[lid] = at;
    if (lid == 0) first[256] = total;
    __syncthreads();
    for (unsigned r0 = 0; r0 < total; r0 += 256) {
      unsigned e = r0 + lid;
      float4 f = make_float4(0, 0, 0, 0);
      if (e < total) {
        int lo = 0, hi = 255;
        while (lo < hi) { int mid = (lo + hi + 1) >> 1; if (first[mid] <= e) lo = mid; else hi = mid - 1; }
        unsigned q = near[lo*ROOM + (e - first[lo])];
        float4 t = __ldg(&pos[q]), u = __ldg(&vel[q]);
        f = law(own_pos[lo], own_vel[lo], t, u, p);
        if (f.w != 0.f) { atomicAdd(&force[3*q], -f.x); atomicAdd(&force[3*q+1], -f.y); atomicAdd(&force[3*q+2], -f.z); mine++; }
      }
      share[lid] = f;
      __syncthreads();
      unsigned a = max(at, r0), b = min(at + listed, r0 + 256);
      for (unsigned k = a; k < b; k++) { float4 g = share[k - r0]; fx += g.x; fy += g.y; fz += g.z; }
      __syncthreads();
    }
    walking = walking && found > skip + ROOM;
    if (!__syncthreads_or(walking)) break;
    skip += ROOM;
  }
  if (fx != 0.f || fy != 0.f || fz != 0.f) { atomicAdd(&force[3*i], fx); atomicAdd(&force[3*i+1], fy); atomicAdd(&force[3*i+2], fz); }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((lid & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// Variant E: the partner's share into an inbox (one returning atomic for a slot, one 16-byte
// store), the own sum stored plainly; `inbox_sum` adds each sphere's inbox and clears its count.
#define SLOTS 16
template <int MODE> // 0: inbox; 1: own plain store, partner atomics into a second buffer
__global__ void __launch_bounds__(256) resolve_inbox(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ cs, float4* own, unsigned* count, float4* inbox, float* partner, unsigned* contacts, P p) {
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = __ldg(&vel[i]);
    Win w = window(s, p); int3 c = cellc(make_float3(s.x, s.y, s.z), p);
    int y = c.y - w.lo.y, z = c.z - w.lo.z; int k = y + w.ny*z;
    int row = w.first + w.dx*(y + w.dy*z); int next_plane = w.dx*(w.dy - w.ny + 1);
    float4 tot = make_float4(0, 0, 0, 0);
    for (; k < w.count; k++) {
      unsigned a = __ldg(&cs[row]), b = __ldg(&cs[row + w.width]);
      if (a < (unsigned)i + 1) a = i + 1;
      for (unsigned q = a; q < b; q++) {
        float4 t = __ldg(&pos[q]);
        float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w;
        if (dx*dx+dy*dy+dz*dz > reach*reach) continue;
        float4 u = __ldg(&vel[q]);
        float4 f = law(s, v, t, u, p);
        if (f.w != 0.f) {
          if (MODE == 0) {
            unsigned at = atomicAdd(&count[q], 1u);
            if (at < SLOTS) inbox[(size_t)q*SLOTS + at] = make_float4(-f.x, -f.y, -f.z, 0.f);
          } else {
            atomicAdd(&partner[3*q], -f.x); atomicAdd(&partner[3*q+1], -f.y); atomicAdd(&partner[3*q+2], -f.z);
          }
          tot.x += f.x; tot.y += f.y; tot.z += f.z; mine++;
        }
      }
      y++; if (y == w.ny) { y = 0; row += next_plane; } else row += w.dx;
    }
    own[i] = tot;
  }
  unsigned tt = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tt) atomicAdd(contacts, tt);
}
__global__ void inbox_sum(float4* own, unsigned* count, const float4* inbox, int n) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; if (i >= n) return;
  unsigned c = min(count[i], (unsigned)SLOTS); float4 f = own[i];
  for (unsigned k = 0; k < c; k++) { float4 g = inbox[(size_t)i*SLOTS + k]; f.x += g.x; f.y += g.y; f.z += g.z; }
  own[i] = f; count[i] = 0;
}
__global__ void partner_sum(float4* own, float* partner, int n) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; if (i >= n) return;
  float4 f = own[i]; f.x += partner[3*i]; f.y += partner[3*i+1]; f.z += partner[3*i+2];
  own[i] = f; partner[3*i] = 0; partner[3*i+1] = 0; partner[3*i+2] = 0;
}
// Lists: at a re-binning, every pair within r_i + r_j + 2 skin (each sphere may move a skin
// before the next), half (the walk's), as a CSR by first sphere: counted, scanned, written.
template <bool WRITE>
__global__ void __launch_bounds__(256) list_pairs(const float4* __restrict__ pos, const unsigned* __restrict__ cs, unsigned* counts, const unsigned* offsets, unsigned* pi, unsigned* pj, P p, float extra) {
  int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= p.n) return;
  float4 s = __ldg(&pos[i]);
  Win w = window(s, p); int3 c = cellc(make_float3(s.x, s.y, s.z), p);
  int y = c.y - w.lo.y, z = c.z - w.lo.z; int k = y + w.ny*z;
  int row = w.first + w.dx*(y + w.dy*z); int next_plane = w.dx*(w.dy - w.ny + 1);
  unsigned m = 0; unsigned at = WRITE ? offsets[i] : 0;
  for (; k < w.count; k++) {
    unsigned a = __ldg(&cs[row]), b = __ldg(&cs[row + w.width]);
    if (a < (unsigned)i + 1) a = i + 1;
    for (unsigned q = a; q < b; q++) {
      float4 t = __ldg(&pos[q]);
      float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z; float reach = s.w + t.w + extra;
      if (dx*dx+dy*dy+dz*dz > reach*reach) continue;
      if (WRITE) { pi[at + m] = i; pj[at + m] = q; }
      m++;
    }
    y++; if (y == w.ny) { y = 0; row += next_plane; } else row += w.dx;
  }
  if (!WRITE) counts[i] = m;
}
// One thread a listed pair. SEG: the first sphere's share summed over its run of pairs in the
// warp (they are consecutive) and added once; else added with atomics as the partner's.
template <bool SEG>
__global__ void __launch_bounds__(256) pair_forces(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ pi, const unsigned* __restrict__ pj, unsigned npairs, float* force, unsigned* contacts, P p) {
  unsigned t = blockIdx.x * blockDim.x + threadIdx.x;
  int lane = threadIdx.x & 31;
  int key = -1; float fx = 0, fy = 0, fz = 0; unsigned mine = 0;
  if (t < npairs) {
    unsigned i = __ldg(&pi[t]), j = __ldg(&pj[t]); key = (int)i;
    float4 s = __ldg(&pos[i]), tt = __ldg(&pos[j]);
    float dx = tt.x - s.x, dy = tt.y - s.y, dz = tt.z - s.z; float reach = s.w + tt.w;
    if (dx*dx+dy*dy+dz*dz <= reach*reach) {
      float4 v = __ldg(&vel[i]), u = __ldg(&vel[j]);
      float4 f = law(s, v, tt, u, p);
      if (f.w != 0.f) {
        atomicAdd(&force[3*j], -f.x); atomicAdd(&force[3*j+1], -f.y); atomicAdd(&force[3*j+2], -f.z);
        fx = f.x; fy = f.y; fz = f.z; mine = 1;
        if (!SEG) { atomicAdd(&force[3*i], fx); atomicAdd(&force[3*i+1], fy); atomicAdd(&force[3*i+2], fz); }
      }
    }
  }
  if (SEG) {
    for (int off = 1; off < 32; off <<= 1) {
      float ox = __shfl_up_sync(0xffffffff, fx, off), oy = __shfl_up_sync(0xffffffff, fy, off), oz = __shfl_up_sync(0xffffffff, fz, off);
      int ko = __shfl_up_sync(0xffffffff, key, off);
      if (lane >= off && ko == key) { fx += ox; fy += oy; fz += oz; }
    }
    int kn = __shfl_down_sync(0xffffffff, key, 1);
    if (key >= 0 && (lane == 31 || kn != key) && (fx != 0.f || fy != 0.f || fz != 0.f)) {
      atomicAdd(&force[3*key], fx); atomicAdd(&force[3*key+1], fy); atomicAdd(&force[3*key+2], fz);
    }
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if (lane == 0 && tot) atomicAdd(contacts, tot);
}
// One thread a sphere over its listed pairs (the lists of 2026-11-28, as a CSR).
__global__ void __launch_bounds__(256) list_forces(const float4* __restrict__ pos, const float4* __restrict__ vel, const unsigned* __restrict__ offsets, const unsigned* __restrict__ pj, float* force, unsigned* contacts, P p) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; unsigned mine = 0;
  if (i < p.n) {
    float4 s = __ldg(&pos[i]); float4 v = __ldg(&vel[i]); float fx = 0, fy = 0, fz = 0;
    unsigned a = offsets[i], b = offsets[i + 1];
    for (unsigned k = a; k < b; k++) {
      unsigned j = __ldg(&pj[k]); float4 tt = __ldg(&pos[j]);
      float dx = tt.x - s.x, dy = tt.y - s.y, dz = tt.z - s.z; float reach = s.w + tt.w;
      if (dx*dx+dy*dy+dz*dz > reach*reach) continue;
      float4 u = __ldg(&vel[j]); float4 f = law(s, v, tt, u, p);
      if (f.w != 0.f) { atomicAdd(&force[3*j], -f.x); atomicAdd(&force[3*j+1], -f.y); atomicAdd(&force[3*j+2], -f.z); fx += f.x; fy += f.y; fz += f.z; mine++; }
    }
    if (mine) { atomicAdd(&force[3*i], fx); atomicAdd(&force[3*i+1], fy); atomicAdd(&force[3*i+2], fz); }
  }
  unsigned tot = __reduce_add_sync(0xffffffff, mine);
  if ((threadIdx.x & 31) == 0 && tot) atomicAdd(contacts, tot);
}
// Integration as the update: pos, vel, force read; pos, vel written; force cleared.
__global__ void integrate(float4* pos, float4* vel, float* force, int n, float dt) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; if (i >= n) return;
  float4 s = pos[i], v = vel[i]; float m = v.w;
  float ax = force[3*i]/m, ay = force[3*i+1]/m, az = force[3*i+2]/m - 9.81f;
  v.x += ax*dt; v.y += ay*dt; v.z += az*dt; s.x += v.x*dt; s.y += v.y*dt; s.z += v.z*dt;
  vel[i] = v; pos[i] = s; force[3*i] = 0; force[3*i+1] = 0; force[3*i+2] = 0;
}

// The key of sphere i's tile of tx × ty × tz cells (tiles x fastest): threads taking the
// spheres tile by tile walk neighbouring windows at once in every direction, not along x alone.
__global__ void tile_keys(const float4* pos, unsigned* key, P p, int tx, int ty, int tz) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; if (i >= p.n) return;
  float4 s = pos[i]; int3 c = cellc(make_float3(s.x, s.y, s.z), p);
  int ntx = p.nx / tx + 1, nty = p.ny / ty + 1;
  key[i] = c.x / tx + ntx * (c.y / ty + nty * (c.z / tz));
}

int main(int argc, char** argv) {
  Bed bed; if (argc < 2 || !load_bed(argv[1], bed)) { printf("usage: probe BED\n"); return 1; }
  const int n = bed.n; const std::vector<float4>& hp = bed.pos; const std::vector<float4>& hv = bed.vel;
  const float rmax = bed.rmax; const float3 lo = bed.lo, hi = bed.hi;
  P p; p.lo = lo; float cell = 2.f*rmax*1.001f; p.inv = 1.f/cell; p.nx = (int)((hi.x-lo.x)*p.inv)+3; p.ny = (int)((hi.y-lo.y)*p.inv)+3; p.nz = (int)((hi.z-lo.z)*p.inv)+3;
  p.rmax = rmax*1.001f; p.slack = 0; p.n = n; p.zeta = 0.3f; float dt = 1e-4f; p.rate = (3.14159265f/(10*dt))*(3.14159265f/(10*dt));
  size_t cells = (size_t)p.nx*p.ny*p.nz; printf("n %d rmax %g grid %d x %d x %d (%zu cells)\n", n, rmax, p.nx, p.ny, p.nz, cells);
  thrust::device_vector<float4> dpos(hp.begin(), hp.end()), dvel(hv.begin(), hv.end()), spos(n), svel(n);
  thrust::device_vector<unsigned> key(n), idx(n), cs(cells + 1);
  keys_k<<<(n+255)/256, 256>>>(thrust::raw_pointer_cast(dpos.data()), thrust::raw_pointer_cast(key.data()), p);
  thrust::sequence(idx.begin(), idx.end()); thrust::sort_by_key(key.begin(), key.end(), idx.begin());
  thrust::gather(idx.begin(), idx.end(), dpos.begin(), spos.begin()); thrust::gather(idx.begin(), idx.end(), dvel.begin(), svel.begin());
  thrust::lower_bound(key.begin(), key.end(), thrust::counting_iterator<unsigned>(0), thrust::counting_iterator<unsigned>(cells + 1), cs.begin());
  thrust::device_vector<float> force(3*(size_t)n); thrust::device_vector<unsigned> cnt(1);
  float4* P_ = thrust::raw_pointer_cast(spos.data()); float4* V_ = thrust::raw_pointer_cast(svel.data());
  unsigned* C_ = thrust::raw_pointer_cast(cs.data()); float* F_ = thrust::raw_pointer_cast(force.data()); unsigned* K_ = thrust::raw_pointer_cast(cnt.data());
  thrust::device_vector<float4> force4(n); float4* F4 = thrust::raw_pointer_cast(force4.data());
  thrust::device_vector<float4> own4(n), inbox4((size_t)n*SLOTS); thrust::device_vector<unsigned> cnt4(n); thrust::device_vector<float> part(3*(size_t)n);
  float4* OWN = thrust::raw_pointer_cast(own4.data()); float4* INB = thrust::raw_pointer_cast(inbox4.data()); unsigned* CNT = thrust::raw_pointer_cast(cnt4.data()); float* PART = thrust::raw_pointer_cast(part.data());
  cudaEvent_t e0, e1; cudaEventCreate(&e0); cudaEventCreate(&e1);
  int blocks = (n+255)/256; const int R = 200;
  auto bench = [&](const char* name, auto launch) {
    for (int w = 0; w < 10; w++) launch();
    cudaMemset(K_, 0, 4); launch(); unsigned c; cudaMemcpy(&c, K_, 4, cudaMemcpyDeviceToHost);
    CK(cudaDeviceSynchronize()); cudaEventRecord(e0);
    for (int r = 0; r < R; r++) launch();
    cudaEventRecord(e1); CK(cudaEventSynchronize(e1)); float ms; cudaEventElapsedTime(&ms, e0, e1);
    printf("%-40s %8.2f us  (count %u)\n", name, 1000.f*ms/R, c);
  };
  const std::string mode = argc > 2 ? argv[2] : "";
  // Session 24 (`order`): the tree's form with its threads taking the sorted spheres tile by
  // tile instead of in the cells' order, the state left where it is; forces checked against the
  // tree's order.
  if (mode == "order") {
    auto forces = [&](auto launch) {
      cudaMemset(F_, 0, 12*(size_t)n); launch(); CK(cudaDeviceSynchronize());
      std::vector<float> h(3*(size_t)n); cudaMemcpy(h.data(), F_, 12*(size_t)n, cudaMemcpyDeviceToHost); return h;
    };
    const int tiles[][3] = {{4, 4, 64}, {8, 8, 64}, {16, 16, 64}, {32, 8, 64}, {8, 8, 2}, {16, 4, 64}, {64, 4, 64}};
    std::vector<thrust::device_vector<unsigned>> orders;
    for (auto& t : tiles) {
      thrust::device_vector<unsigned> tk(n), ord(n);
      tile_keys<<<blocks,256>>>(P_, thrust::raw_pointer_cast(tk.data()), p, t[0], t[1], t[2]);
      thrust::sequence(ord.begin(), ord.end()); thrust::stable_sort_by_key(tk.begin(), tk.end(), ord.begin());
      orders.push_back(ord);
    }
    for (float slack : {0.f, 0.2f}) {
      p.slack = slack*cell; printf("-- slack %.1f cell\n", slack);
      auto tree = [&]{ resolve_inline<true,true><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); };
      std::vector<float> ref = forces(tree);
      bench("walk only, cells' order", [&]{ resolve_inline<false,false><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); });
      bench("the tree's form, cells' order", tree);
      for (size_t k = 0; k < orders.size(); k++) {
        const unsigned* O = thrust::raw_pointer_cast(orders[k].data());
        auto ordered = [&]{ resolve_inline<true,true><<<blocks,256>>>(P_, V_, C_, F_, K_, p, O); };
        std::vector<float> h = forces(ordered);
        double d2 = 0, r2 = 0; for (size_t e = 0; e < h.size(); e++) { d2 += double(h[e]-ref[e])*(h[e]-ref[e]); r2 += double(ref[e])*ref[e]; }
        char name[96]; snprintf(name, sizeof name, "tiles %dx%dx%d: walk only", tiles[k][0], tiles[k][1], tiles[k][2]);
        bench(name, [&]{ resolve_inline<false,false><<<blocks,256>>>(P_, V_, C_, F_, K_, p, O); });
        snprintf(name, sizeof name, "tiles %dx%dx%d: the tree's form", tiles[k][0], tiles[k][1], tiles[k][2]);
        bench(name, ordered);
        printf("   forces against the cells' order, RMS relative %.2e\n", std::sqrt(d2/r2));
      }
    }
    return 0;
  }
  // The queued form beside the tree's (`queued`), its forces checked against the tree's; `once`:
  // each of those kernels launched once (for Nsight Compute).
  if (mode == "queued" || mode == "once") {
    auto forces = [&](auto launch) {
      cudaMemset(F_, 0, 12*(size_t)n); launch(); CK(cudaDeviceSynchronize());
      std::vector<float> h(3*(size_t)n); cudaMemcpy(h.data(), F_, 12*(size_t)n, cudaMemcpyDeviceToHost); return h;
    };
    for (float slack : {0.f, 0.2f}) {
      p.slack = slack*cell;
      auto walk = [&]{ resolve_inline<false,false><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); };
      auto nopartner = [&]{ resolve_inline<true,false><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); };
      auto tree = [&]{ resolve_inline<true,true><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); };
      auto qshared = [&]{ resolve_queued<true><<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      auto qglobal = [&]{ resolve_queued<false><<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      auto rows1 = [&]{ resolve_rows<1,1><<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      auto rows2 = [&]{ resolve_rows<2,1><<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      auto rows4 = [&]{ resolve_rows<4,1><<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      auto rows1o = [&]{ resolve_rows<1,8><<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      auto rows2o = [&]{ resolve_rows<2,8><<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      auto tree_law = [&]{ resolve_inline<true,true,1><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); };
      auto trimmed_law = [&]{ resolve_inline<true,true,2><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); };
      auto listed = [&]{ resolve_listed<<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      auto blocklaws = [&]{ resolve_block_laws<<<blocks,256>>>(P_, V_, C_, F_, K_, p); };
      if (mode == "once") { if (slack > 0.f) { walk(); nopartner(); tree(); qshared(); qglobal(); rows1(); rows2(); rows4(); rows1o(); rows2o(); listed(); blocklaws(); tree_law(); trimmed_law(); CK(cudaDeviceSynchronize()); } continue; }
      printf("-- slack %.1f cell\n", slack);
      std::vector<float> ref = forces(tree);
      auto against_tree = [&](const char* name, const std::vector<float>& h) {
        double d2 = 0, r2 = 0; for (size_t e = 0; e < h.size(); e++) { d2 += double(h[e]-ref[e])*(h[e]-ref[e]); r2 += double(ref[e])*ref[e]; }
        printf("%s: forces against the tree's, RMS relative %.2e\n", name, std::sqrt(d2/r2));
      };
      against_tree("queued, own in shared", forces(qshared));
      against_tree("queued, own global", forces(qglobal));
      against_tree("rows, 1 at a time", forces(rows1));
      against_tree("rows, 4 at a time", forces(rows4));
      against_tree("rows, 2 at a time, 8 blocks", forces(rows2o));
      against_tree("listed, laws shared over the block", forces(blocklaws));
      std::vector<float> tree_forces = forces(tree_law);
      ref = tree_forces;
      against_tree("the tree's law trimmed, against the tree's law", forces(trimmed_law));
      bench("walk only", walk);
      bench("inline resolve, no partner atomics", nopartner);
      bench("inline resolve (the tree's form)", tree);
      bench("queued, own share in shared memory", qshared);
      bench("queued, own share by global atomics", qglobal);
      bench("next row's bounds early, 1 candidate", rows1);
      bench("next row's bounds early, 2 candidates", rows2);
      bench("next row's bounds early, 4 candidates", rows4);
      bench("the same, 1 candidate, 8 blocks an SM", rows1o);
      bench("the same, 2 candidates, 8 blocks an SM", rows2o);
      bench("listed (as the WGSL pass)", listed);
      bench("listed, laws shared over the block", blocklaws);
      bench("inline, the tree's law", tree_law);
      bench("inline, the tree's law trimmed", trimmed_law);
    }
    return 0;
  }
  for (float slack : {0.f, 0.1f, 0.2f}) {
    p.slack = slack*cell; printf("-- slack %.1f cell\n", slack);
    bench("walk only", [&]{ resolve_inline<false,false><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); });
    bench("inline resolve, no partner atomics", [&]{ resolve_inline<true,false><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); });
    bench("inline resolve", [&]{ resolve_inline<true,true><<<blocks,256>>>(P_, V_, C_, F_, K_, p, nullptr); });
    bench("inline resolve, float4 atomics", [&]{ resolve_v4<<<blocks,256>>>(P_, V_, C_, (float4*)F4, K_, p); });
    bench("inbox: resolve", [&]{ resolve_inbox<0><<<blocks,256>>>(P_, V_, C_, OWN, CNT, INB, PART, K_, p); cudaMemsetAsync(CNT, 0, 4*(size_t)n); });
    bench("inbox: resolve + sum", [&]{ resolve_inbox<0><<<blocks,256>>>(P_, V_, C_, OWN, CNT, INB, PART, K_, p); inbox_sum<<<blocks,256>>>(OWN, CNT, INB, n); });
    bench("own store + partner atomics", [&]{ resolve_inbox<1><<<blocks,256>>>(P_, V_, C_, OWN, CNT, INB, PART, K_, p); });
    bench("own store + partner atomics + sum", [&]{ resolve_inbox<1><<<blocks,256>>>(P_, V_, C_, OWN, CNT, INB, PART, K_, p); partner_sum<<<blocks,256>>>(OWN, PART, n); });
    bench("full window, no atomics (count 2x)", [&]{ resolve_full<<<blocks,256>>>(P_, V_, C_, F_, K_, p); });
    bench("listed (as the WGSL pass)", [&]{ resolve_listed<<<blocks,256>>>(P_, V_, C_, F_, K_, p); });
  }
  for (float skin : {0.1f, 0.2f}) {
    float extra = 2.f*skin*cell; p.slack = 0;
    thrust::device_vector<unsigned> counts(n + 1, 0), offsets(n + 1);
    unsigned* CN = thrust::raw_pointer_cast(counts.data()); unsigned* OF = thrust::raw_pointer_cast(offsets.data());
    list_pairs<false><<<blocks,256>>>(P_, C_, CN, OF, nullptr, nullptr, p, extra);
    thrust::exclusive_scan(counts.begin(), counts.end(), offsets.begin());
    unsigned npairs = offsets[n];
    thrust::device_vector<unsigned> pi(npairs), pj(npairs);
    unsigned* PI = thrust::raw_pointer_cast(pi.data()); unsigned* PJ = thrust::raw_pointer_cast(pj.data());
    printf("-- lists within reach + 2 x %.1f cell: %u pairs\n", skin, npairs);
    bench("lists: count pass", [&]{ list_pairs<false><<<blocks,256>>>(P_, C_, CN, OF, PI, PJ, p, extra); });
    bench("lists: write pass", [&]{ list_pairs<true><<<blocks,256>>>(P_, C_, CN, OF, PI, PJ, p, extra); });
    int pblocks = (npairs + 255)/256;
    bench("pairs: thread a pair, atomics both", [&]{ pair_forces<false><<<pblocks,256>>>(P_, V_, PI, PJ, npairs, F_, K_, p); });
    bench("pairs: thread a pair, warp-summed first", [&]{ pair_forces<true><<<pblocks,256>>>(P_, V_, PI, PJ, npairs, F_, K_, p); });
    bench("lists: thread a sphere over its list", [&]{ list_forces<<<blocks,256>>>(P_, V_, OF, PJ, F_, K_, p); });
  }
  bench("memset force", [&]{ cudaMemsetAsync(F_, 0, 12*(size_t)n); });
  thrust::device_vector<float4> p2 = spos, v2 = svel;
  float4* P2 = thrust::raw_pointer_cast(p2.data()); float4* V2 = thrust::raw_pointer_cast(v2.data());
  bench("integrate (pos, vel, force)", [&]{ integrate<<<blocks,256>>>(P2, V2, F_, n, 1e-9f); });
  return 0;
}
