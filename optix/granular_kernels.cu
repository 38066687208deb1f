// Plain CUDA kernels of the optix granular step (src/engines/optix/granular.rs). Needs
// device.cuh, physics.cuh, contact.cuh and history.cuh prepended. The load histories
// (`old_loads`, `new_loads`) are read and written only with MOCHI_LOAD_HISTORY.

// Walls (with their springs), gravity at step `step` and one semi-implicit Euler step of
// positions (the centres with their residuals `lo`) and angular velocities, in place (src/engines/cpu/dem.rs: pairs, then the walls'
// normal and tangential forces; each sphere's material rides in its angular velocity row's w,
// as bits, and stays there); clears the force and torque accumulators for the next step.
// Appends the walls' springs to the sphere's new history after those its ray wrote, and where a
// sphere holds more contacts than its slots (g.dem.slots), raises `need` to its count (the host then grows
// the slots and redoes the steps). Where g.dem.loaded is 1, adds each sphere's external force
// and torque (`external`, by input index: force at row 2i, torque at 2i + 1) to its contacts'.
// The first `components` stable ids are clumps' components: their walls go into their
// accumulators and their rows into `clump_rows`, and they are left for advance_clumps.
extern "C" __global__ void granular_integrate(float4* pos, float4* lo, float4* vel,
                                              float4* ang, float* force, float* torque,
                                              const unsigned int* ids, const float4* external,
                                              const unsigned int* old_count,
                                              const MochiHistoryEntry* old_entries,
                                              unsigned int* new_count,
                                              MochiHistoryEntry* new_entries,
                                              const MochiLoadEntry* old_loads,
                                              MochiLoadEntry* new_loads, unsigned int* need,
                                              MochiLaw g,
                                              unsigned int step, MochiMeshParams mesh,
                                              const MochiMeshWall* mesh_walls,
                                              const unsigned int* mesh_grid,
                                              const float4* mesh_tris, float* mesh_loads,
                                              unsigned int* clump_rows,
                                              unsigned int components) {
    unsigned int p = blockIdx.x * blockDim.x + threadIdx.x;
    if (p >= g.dem.n) {
        return;
    }
    const unsigned int slots = g.dem.slots;
    float4 s = pos[p];
    float4 v = vel[p];
    float4 w = ang[p];
    MochiBody b;
    b.c = mochi_v3(s.x, s.y, s.z);
    b.v = mochi_v3(v.x, v.y, v.z);
    b.w = mochi_v3(w.x, w.y, w.z);
    b.r = s.w;
    b.m = v.w;
    b.material = __float_as_uint(w.w);
    unsigned int id = ids[p];
    unsigned int held = mochi_keeps(g) ? new_count[id] : 0u;
    unsigned long long row = (unsigned long long)id * slots;
    MochiSlots old_slots = {old_count, old_entries, slots, old_loads};
    MochiWalls walls;
    walls.normal = mochi_zero3();
    walls.tangential = mochi_zero3();
    walls.torque = mochi_zero3();
    if (mesh.box_walls) {
        walls = mochi_wall_contacts(
            g, b,
            [&](unsigned int wall, MochiSprings& springs) {
                // Only where contacts carry springs (old_slots are empty otherwise).
                return mochi_keeps(g) && mochi_find(old_slots, id, MOCHI_FIRST_WALL + wall, springs);
            },
            [&](unsigned int wall, MochiSprings springs) {
                if (held < slots) {
                    mochi_keep_entry(new_entries, new_loads, row + held, MOCHI_FIRST_WALL + wall,
                                     springs);
                }
                held += 1u;
            });
    }
    if (mesh.walls > 0u) {
        MochiMeshes meshes = {mesh, mesh_walls, mesh_grid, mesh_tris, mesh_loads};
        float3 mesh_force = mochi_zero3();
        float3 mesh_torque = mochi_zero3();
        mochi_mesh_contacts(
            g, meshes, b, (float)step * g.dem.dt,
            step == mesh.loads_step && mochi_loads_own(mesh, b.c), p % mesh.load_lanes,
            mesh_force, mesh_torque,
            [&](unsigned int partner, unsigned int first, MochiSprings& springs) {
                unsigned int s = mochi_find_from(old_slots, id, partner, first, springs);
                return s < old_count[id] ? s : MOCHI_NO_SLOT;
            },
            [&](unsigned int partner, MochiSprings springs) {
                if (held < slots) {
                    mochi_keep_entry(new_entries, new_loads, row + held, partner, springs);
                }
                held += 1u;
            });
        // The mesh walls' forces are whole (normal and tangential) and their torques, as the
        // box walls' tangential parts, only where contacts turn.
        walls.normal = mochi_add(walls.normal, mesh_force);
        walls.torque = mochi_add(walls.torque, mesh_torque);
    }
    if (mochi_keeps(g)) {
        new_count[id] = min(held, slots);
        if (held > slots) {
            atomicMax(need, held);
        }
    }
    if (id < components) {
        // A clump's component: its walls join its contacts for its clump's step
        // (advance_clumps, clumps.cuh), which places it.
        clump_rows[id] = p;
        float3 f = walls.normal;
        if (g.dem.turns) {
            f = mochi_add(f, walls.tangential);
            torque[3 * p] += walls.torque.x;
            torque[3 * p + 1] += walls.torque.y;
            torque[3 * p + 2] += walls.torque.z;
        }
        force[3 * p] += f.x;
        force[3 * p + 1] += f.y;
        force[3 * p + 2] += f.z;
        return;
    }
    float3 f = mochi_add(mochi_v3(force[3 * p], force[3 * p + 1], force[3 * p + 2]), walls.normal);
    force[3 * p] = 0.0f;
    force[3 * p + 1] = 0.0f;
    force[3 * p + 2] = 0.0f;
    float3 g_now = mochi_gravity_at(g.dem, step);
    float m = v.w;
    float dt = g.dem.dt;
    if (g.dem.turns) {
        f = mochi_add(f, walls.tangential);
        float3 t = mochi_add(mochi_v3(torque[3 * p], torque[3 * p + 1], torque[3 * p + 2]),
                             walls.torque);
        torque[3 * p] = 0.0f;
        torque[3 * p + 1] = 0.0f;
        torque[3 * p + 2] = 0.0f;
        if (g.dem.loaded) {
            float4 e = external[2u * id + 1u];
            t = mochi_add(t, mochi_v3(e.x, e.y, e.z));
        }
        float inertia = mochi_inertia(m, s.w);
        ang[p] = make_float4(w.x + dt * (t.x / inertia), w.y + dt * (t.y / inertia),
                             w.z + dt * (t.z / inertia), w.w);
    }
    if (g.dem.loaded) {
        float4 e = external[2u * id];
        f = mochi_add(f, mochi_v3(e.x, e.y, e.z));
    }
    float vx = v.x + dt * (f.x / m + g_now.x);
    float vy = v.y + dt * (f.y / m + g_now.y);
    float vz = v.z + dt * (f.z / m + g_now.z);
    vel[p] = make_float4(vx, vy, vz, m);
    float4 l = lo[p];
    mochi_move(s, l, dt, vx, vy, vz);
    pos[p] = s;
    lo[p] = l;
}

// Reorders rows of 4 floats: sorted position p takes row `order[p]` of the input (the angular
// velocities with the materials, beside dem_permute's state).
extern "C" __global__ void permute_rows(const float4* rows_in, const unsigned int* order,
                                        float4* rows, unsigned int n) {
    unsigned int p = blockIdx.x * blockDim.x + threadIdx.x;
    if (p >= n) {
        return;
    }
    rows[p] = rows_in[order[p]];
}
