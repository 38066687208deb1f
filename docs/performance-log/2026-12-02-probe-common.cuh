// What the contact-pass probes of performance-log/2026-12-02-h200.md share (not part of mochi):
// the grid's parameters and cells (x fastest, a margin cell on each side), the per-pair linear
// law with damping of wgsl/dem/dem_physics.wgsl, and the bed they read.
#pragma once
#include <cstdio>
#include <cstdlib>
#include <vector>
#include <cmath>
#define CK(x) do { cudaError_t e = (x); if (e != cudaSuccess) { printf("%s: %s\n", #x, cudaGetErrorString(e)); exit(1);} } while (0)

struct P { float3 lo; float inv; int nx, ny, nz; float rmax; float slack; float rate; float zeta; int n; };

__device__ __forceinline__ int3 cellc(float3 c, const P& p) {
  float ux = fmaxf((c.x - p.lo.x) * p.inv, 0.f), uy = fmaxf((c.y - p.lo.y) * p.inv, 0.f), uz = fmaxf((c.z - p.lo.z) * p.inv, 0.f);
  return make_int3(min((int)ux, p.nx - 3) + 1, min((int)uy, p.ny - 3) + 1, min((int)uz, p.nz - 3) + 1);
}
__global__ void keys_k(const float4* pos, unsigned* key, P p) {
  int i = blockIdx.x * blockDim.x + threadIdx.x; if (i >= p.n) return;
  float4 s = pos[i]; int3 c = cellc(make_float3(s.x, s.y, s.z), p);
  key[i] = c.x + p.nx * (c.y + p.ny * c.z);
}
__device__ __forceinline__ float4 law(float4 s, float4 v, float4 t, float4 u, const P& p) {
  float dx = t.x - s.x, dy = t.y - s.y, dz = t.z - s.z;
  float d2 = dx*dx + dy*dy + dz*dz; float reach = s.w + t.w;
  if (d2 > reach*reach || d2 == 0.f) return make_float4(0,0,0,0);
  float dist = sqrtf(d2); float nx = dx/dist, ny = dy/dist, nz = dz/dist;
  float ov = reach - dist;
  float vn = (u.x-v.x)*nx + (u.y-v.y)*ny + (u.z-v.z)*nz;
  float me = v.w*u.w/(v.w+u.w); float k = me*p.rate; float c = 2.f*p.zeta*sqrtf(k*me);
  float push = fmaxf(k*ov - c*vn, 0.f);
  return make_float4(-push*nx, -push*ny, -push*nz, 1.f);
}
// The bed: n spheres of centres and radii `pos` and velocities and masses (density 2,500
// kg/m³) `vel`, the largest radius and the centres' bounds; read from `path` (int32 n, then n
// rows of float32 x, y, z, r, vx, vy, vz: a frame's first seven columns).
struct Bed { int n = 0; std::vector<float4> pos, vel; float rmax = 0; float3 lo, hi; };
inline bool load_bed(const char* path, Bed& b) {
  FILE* f = fopen(path, "rb"); if (!f || fread(&b.n, 4, 1, f) != 1) return false;
  std::vector<float> h(7*(size_t)b.n); if (fread(h.data(), 4, h.size(), f) != h.size()) return false; fclose(f);
  b.pos.resize(b.n); b.vel.resize(b.n); b.lo = make_float3(1e30,1e30,1e30); b.hi = make_float3(-1e30,-1e30,-1e30);
  const float dens = 2500.f;
  for (int i = 0; i < b.n; i++) { float* r = &h[7*(size_t)i]; b.pos[i] = make_float4(r[0], r[1], r[2], r[3]); b.vel[i] = make_float4(r[4], r[5], r[6], dens*4.f/3.f*3.14159265f*r[3]*r[3]*r[3]);
    b.rmax = fmaxf(b.rmax, r[3]); b.lo.x = fminf(b.lo.x, r[0]); b.lo.y = fminf(b.lo.y, r[1]); b.lo.z = fminf(b.lo.z, r[2]); b.hi.x = fmaxf(b.hi.x, r[0]); b.hi.y = fmaxf(b.hi.y, r[1]); b.hi.z = fmaxf(b.hi.z, r[2]); }
  return true;
}
