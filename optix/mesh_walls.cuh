// Mesh walls of the optix granular step: the CUDA twin of wgsl/dem/dem_mesh_walls.wgsl (read its
// doc: rest geometry, one grid cell's triangles per sphere, the nearest MOCHI_MESH_NEAR within
// the radius, one contact per surface seen at a face, an edge or a vertex alike) and of the cpu
// step's src/dem/walls. Resolved by each sphere's thread of granular_integrate after the box
// walls, its contacts appended to its history under partner MOCHI_FIRST_MESH_WALL + wall (the
// k-th contact of a wall, nearest first, in the k-th old entry of that id). Needs contact.cuh
// and history.cuh prepended. Keep MochiMeshWall in sync with MeshWallRow and MochiMeshParams
// with MeshParams (src/engines/gpu_walls.rs).

// Partner ids of mesh walls' contacts (FIRST_MESH_WALL in src/particles/history.rs).
#define MOCHI_FIRST_MESH_WALL 0xFFFEFFFAu
// Candidates within a sphere's radius kept per wall, nearest first (MESH_NEAR).
#define MOCHI_MESH_NEAR 16u
// Candidates this fraction of the radius behind a kept contact's tangent plane count as on it.
#define MOCHI_ON_PLANE 1e-4f

struct MochiMeshParams {
    unsigned int walls;       // mesh walls
    unsigned int box_walls;   // 1: the six walls of the box hold the spheres in
    unsigned int loads_step;  // the step whose loads on the walls are summed
    unsigned int load_lanes;  // partial sums of each load (sphere p adds to lane p mod lanes)
    float own_lo[3];          // the loads sum the spheres whose centre c has own_lo <= c <
    float own_hi[3];          // own_hi (infinite: every sphere; a rank's step: its box)
};

// Whether centre c lies in the box whose spheres' loads on the walls are summed.
static __device__ bool mochi_loads_own(const MochiMeshParams& m, float3 c) {
    return c.x >= m.own_lo[0] && c.y >= m.own_lo[1] && c.z >= m.own_lo[2] &&
           c.x < m.own_hi[0] && c.y < m.own_hi[1] && c.z < m.own_hi[2];
}

struct MochiMeshWall {
    float lo[3];              // the rest-geometry grid's lower corner [m]
    float cell;               // its cell side [m]
    unsigned int dims[3];     // its cells per axis
    unsigned int first_cell;  // its first cell's index in the grid
    float velocity[3];        // of the translation [m/s], from `start` on
    float omega;              // angular speed about `axis` [rad/s], from `start` on
    float axis[3];            // unit
    float start;              // when the motion starts [s]
    float centre[3];          // a point of the axis at `start` [m]; loads' torques are about it
    unsigned int column;      // its column in the material table (its material's, or rigid)
    float own_friction;       // its own μ with the spheres, or negative: each pair's
    unsigned int _pad[3];     // to the size of the Rust row (a multiple of 16 bytes)
};

// The mesh walls as granular_integrate reads them.
struct MochiMeshes {
    MochiMeshParams params;
    const MochiMeshWall* walls;
    // Cell k's triangles are grid[grid[k]] .. grid[grid[k + 1] - 1] (the cells' offsets, then
    // the triangle indices).
    const unsigned int* grid;
    // per triangle: corners a, b, c and the unit normal, rest geometry
    const float4* tris;
    // per lane and wall 8 floats: force on it x, y, z, 0, torque x, y, z, 0; then the most
    // candidates a sphere had (as an unsigned int)
    float* loads;
};

// Where a wall is at one time and how its points move.
struct MochiPose {
    float4 q;  // rotation from the rest geometry (x, y, z, w)
    float3 offset;
    float3 centre;
    float3 velocity;
    float3 spin;
};

static __forceinline__ __device__ float3 mochi_rotate(float4 q, float3 v) {
    float3 u = mochi_v3(q.x, q.y, q.z);
    float3 inner = mochi_add(mochi_cross(u, v), mochi_scale(q.w, v));
    return mochi_add(v, mochi_scale(2.0f, mochi_cross(u, inner)));
}

static __forceinline__ __device__ float3 mochi_row3(const float* x) {
    return mochi_v3(x[0], x[1], x[2]);
}

static __forceinline__ __device__ MochiPose mochi_pose_at(const MochiMeshWall& m, float t) {
    bool running = t > m.start;
    float tau = running ? t - m.start : 0.0f;
    float half = 0.5f * m.omega * tau;
    float3 axis = mochi_row3(m.axis);
    float s = sinf(half);
    MochiPose pose;
    pose.q = make_float4(axis.x * s, axis.y * s, axis.z * s, cosf(half));
    float3 centre0 = mochi_row3(m.centre);
    float3 velocity = mochi_row3(m.velocity);
    pose.centre = mochi_add(centre0, mochi_scale(tau, velocity));
    pose.offset = mochi_sub(pose.centre, mochi_rotate(pose.q, centre0));
    pose.velocity = running ? velocity : mochi_zero3();
    pose.spin = running ? mochi_scale(m.omega, axis) : mochi_zero3();
    return pose;
}

static __forceinline__ __device__ float3 mochi_corner(const MochiMeshes& w, unsigned int tri,
                                                      unsigned int k) {
    float4 c = w.tris[4u * tri + k];
    return mochi_v3(c.x, c.y, c.z);
}

// The triangle's point closest to p (corner, edge or face regions by the barycentric signs, as
// Triangle::closest_point).
static __device__ float3 mochi_closest_point(const MochiMeshes& w, unsigned int tri, float3 p) {
    float3 a = mochi_corner(w, tri, 0u);
    float3 b = mochi_corner(w, tri, 1u);
    float3 c = mochi_corner(w, tri, 2u);
    float3 ab = mochi_sub(b, a);
    float3 ac = mochi_sub(c, a);
    float3 ap = mochi_sub(p, a);
    float d1 = mochi_dot(ab, ap);
    float d2 = mochi_dot(ac, ap);
    if (d1 <= 0.0f && d2 <= 0.0f) {
        return a;
    }
    float3 bp = mochi_sub(p, b);
    float d3 = mochi_dot(ab, bp);
    float d4 = mochi_dot(ac, bp);
    if (d3 >= 0.0f && d4 <= d3) {
        return b;
    }
    float vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f) {
        return mochi_add(a, mochi_scale(d1 / (d1 - d3), ab));
    }
    float3 cp = mochi_sub(p, c);
    float d5 = mochi_dot(ab, cp);
    float d6 = mochi_dot(ac, cp);
    if (d6 >= 0.0f && d5 <= d6) {
        return c;
    }
    float vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f) {
        return mochi_add(a, mochi_scale(d2 / (d2 - d6), ac));
    }
    float va = d3 * d6 - d5 * d4;
    if (va <= 0.0f && d4 - d3 >= 0.0f && d5 - d6 >= 0.0f) {
        float t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return mochi_add(b, mochi_scale(t, mochi_sub(c, b)));
    }
    float3 n = mochi_corner(w, tri, 3u);
    return mochi_sub(p, mochi_scale(mochi_dot(ap, n), n));
}

#define MOCHI_NO_CELL 0xFFFFFFFFu
// No old history slot of a contact.
#define MOCHI_NO_SLOT 0xFFFFFFFFu

// The offset in the grid of the cell of wall m's grid that holds the rest point p, or
// MOCHI_NO_CELL outside the grid (a non-finite centre too).
static __forceinline__ __device__ unsigned int mochi_cell_holding(const MochiMeshWall& m,
                                                                  float3 p) {
    float at[3] = {(p.x - m.lo[0]) / m.cell, (p.y - m.lo[1]) / m.cell, (p.z - m.lo[2]) / m.cell};
    for (unsigned int a = 0; a < 3; ++a) {
        if (!(at[a] >= 0.0f && at[a] < (float)m.dims[a])) {
            return MOCHI_NO_CELL;
        }
    }
    unsigned int x = (unsigned int)at[0];
    unsigned int y = (unsigned int)at[1];
    unsigned int z = (unsigned int)at[2];
    return m.first_cell + x + m.dims[0] * (y + m.dims[1] * z);
}

// A sphere's candidates of one wall, nearest first.
struct MochiNear {
    float d2[MOCHI_MESH_NEAR];
    unsigned int tri[MOCHI_MESH_NEAR];
};

// Lists the triangles of `cell` within distance r of the rest point p into `near`, nearest
// first (equal distances in the order met); returns how many there were (more than
// MOCHI_MESH_NEAR: the farthest were dropped).
static __device__ unsigned int mochi_mesh_candidates(const MochiMeshes& w, unsigned int cell,
                                                     float3 p, float r, MochiNear& near) {
    unsigned int found = 0u;
    for (unsigned int k = w.grid[cell]; k < w.grid[cell + 1u]; ++k) {
        unsigned int tri = w.grid[k];
        float3 q = mochi_sub(mochi_closest_point(w, tri, p), p);
        float d2 = mochi_dot(q, q);
        if (d2 >= r * r || d2 <= 0.0f) {
            continue;
        }
        unsigned int held = min(found, MOCHI_MESH_NEAR);
        found += 1u;
        if (held == MOCHI_MESH_NEAR && d2 >= near.d2[MOCHI_MESH_NEAR - 1u]) {
            continue;
        }
        unsigned int j = held == MOCHI_MESH_NEAR ? MOCHI_MESH_NEAR - 1u : held;
        while (j > 0u && near.d2[j - 1u] > d2) {
            near.d2[j] = near.d2[j - 1u];
            near.tri[j] = near.tri[j - 1u];
            j -= 1u;
        }
        near.d2[j] = d2;
        near.tri[j] = tri;
    }
    return found;
}

// Sphere b's contacts with every mesh wall at time t: their force and torque added to `force`
// and `torque`; `old(partner, first, springs)` gives the slot at or after `first` of the
// sphere's old contact with `partner` and its springs (MOCHI_NO_SLOT: none),
// `keep(partner, springs)` receives the springs to keep in order; in step `summing` the
// reactions go to the walls' loads (lane `lane`). Where contacts adhere, a contact of the last
// step holds past touching while its law lets it (src/engines/cpu/walls.rs).
template <class Old, class Keep>
static __device__ void mochi_mesh_contacts(const MochiLaw& g, const MochiMeshes& w,
                                           const MochiBody& b, float t, bool summing,
                                           unsigned int lane, float3& force, float3& torque,
                                           Old old, Keep keep) {
    for (unsigned int wall = 0; wall < w.params.walls; ++wall) {
        const MochiMeshWall m = w.walls[wall];
        MochiPose pose = mochi_pose_at(m, t);
        float4 inverse = make_float4(-pose.q.x, -pose.q.y, -pose.q.z, pose.q.w);
        float3 p = mochi_rotate(inverse, mochi_sub(b.c, pose.offset));
        unsigned int cell = mochi_cell_holding(m, p);
        if (cell == MOCHI_NO_CELL || w.grid[cell] >= w.grid[cell + 1u]) {
            continue;
        }
        // Where contacts adhere, a contact of the last step may hold past touching, up to the
        // reach.
        float within = MOCHI_COHESIVE ? b.r + g.dem.reach : b.r;
        MochiNear near;
        unsigned int found = mochi_mesh_candidates(w, cell, p, within, near);
        if (found == 0u) {
            continue;
        }
        if (found > MOCHI_MESH_NEAR) {
            atomicMax(reinterpret_cast<unsigned int*>(
                          &w.loads[8u * w.params.walls * w.params.load_lanes]),
                      found);
        }
        unsigned int partner = MOCHI_FIRST_MESH_WALL + wall;
        float3 f_wall = mochi_zero3();
        float3 t_wall = mochi_zero3();
        float4 kept_plane[MOCHI_MESH_NEAR];
        unsigned int kept = 0u;
        unsigned int next_old = 0u;
        float slack = MOCHI_ON_PLANE * b.r;
        for (unsigned int k = 0; k < min(found, MOCHI_MESH_NEAR); ++k) {
            float3 q = mochi_closest_point(w, near.tri[k], p);
            float3 to = mochi_sub(q, p);
            bool covered = false;
            for (unsigned int j = 0; j < kept; ++j) {
                float3 n = mochi_v3(kept_plane[j].x, kept_plane[j].y, kept_plane[j].z);
                covered = covered || mochi_dot(to, n) >= kept_plane[j].w - slack;
            }
            if (covered) {
                continue;
            }
            float d = sqrtf(near.d2[k]);
            float3 n_rest = mochi_div(to, d);
            kept_plane[kept] = make_float4(n_rest.x, n_rest.y, n_rest.z, d);
            kept += 1u;
            float3 point = mochi_add(mochi_rotate(pose.q, q), pose.offset);
            float3 n = mochi_rotate(pose.q, n_rest);
            float3 surface_velocity = mochi_add(
                pose.velocity, mochi_cross(pose.spin, mochi_sub(point, pose.centre)));
            // The k-th contact with this wall takes the k-th old entry of it.
            MochiSprings springs = mochi_no_springs();
            unsigned int s = MOCHI_NO_SLOT;
            if (mochi_keeps(g)) {
                s = old(partner, next_old, springs);
            }
            bool touching = near.d2[k] < b.r * b.r;
            // d < r where touching, but the square root may round up.
            float overlap = touching ? fmaxf(b.r - d, 0.0f) : b.r - d;
            if (!touching &&
                !(MOCHI_COHESIVE && s != MOCHI_NO_SLOT &&
                  mochi_holds(g, mochi_law(g, b.material, m.column),
                              mochi_bridge(g, b.material, m.column), b.r, overlap))) {
                // Past touching, only a contact of the last step that still holds (its entry
                // is left for the next contact).
                continue;
            }
            if (s != MOCHI_NO_SLOT) {
                next_old = s + 1u;
            }
            MochiSurface c = mochi_surface_contact(g, b, n, overlap, surface_velocity, m.column,
                                                   m.own_friction, springs);
            f_wall = mochi_add(f_wall, c.force);
            t_wall = mochi_add(t_wall, c.torque);
            if (mochi_keeps(g)) {
                keep(partner, c.springs);
            }
        }
        force = mochi_add(force, f_wall);
        torque = mochi_add(torque, t_wall);
        if (summing) {
            // The wall takes the opposite force and the opposite angular impulse about its
            // centre.
            float3 about = mochi_neg(
                mochi_add(mochi_cross(mochi_sub(b.c, pose.centre), f_wall), t_wall));
            float* at = w.loads + 8u * (lane * w.params.walls + wall);
            atomicAdd(at, -f_wall.x);
            atomicAdd(at + 1, -f_wall.y);
            atomicAdd(at + 2, -f_wall.z);
            atomicAdd(at + 4, about.x);
            atomicAdd(at + 5, about.y);
            atomicAdd(at + 6, about.z);
        }
    }
}
