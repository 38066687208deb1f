// Mesh walls in the granular GPU step (src/dem/walls, the cpu step's `engines/cpu/walls.rs`):
// each sphere's contacts with every mesh wall, resolved after the contact pass by two kernels of
// their own (dispatched only where there are mesh walls: the contact pass keeps its registers):
// `mesh_walls_near` lists the spheres whose cell of some wall's grid lists triangles, and
// `mesh_wall_contacts` resolves the listed ones, so that its warps run the contact law together
// where resolving every sphere in state order would leave most lanes of each warp idle. The
// contacts are appended to the sphere's history row and force, with history under partner
// FIRST_MESH_WALL + w (the k-th contact of a wall, nearest first, in the k-th old entry of that
// id), and the loads on each wall summed in the step the host asks for. Twin structs:
// `MeshParams`, `MeshWall` in src/engines/gpu_walls.rs.
//
// A wall's triangles live in their rest geometry, each listed in the cells of a uniform grid
// over their rest bounds (grown by the largest radius) that it comes within the largest radius
// of; a sphere's centre is taken into the rest geometry by the wall's pose at the step's time (a
// function of the time alone, as on the cpu), and the triangles of the cell holding it are its
// candidates. Of those within its radius, the nearest MESH_NEAR are kept, ordered by distance,
// and a candidate becomes a contact only where it lies in front of the tangent plane of every
// contact kept before it (src/dem/walls/touch.rs says why: one contact per surface seen, at a
// face, an edge or a vertex alike). A sphere with more candidates raises the count the host
// checks after the step and refuses.

struct MeshParams {
    walls: u32,         // mesh walls
    box_walls: u32,     // 1: the six walls of the box hold the spheres in
    loads_step: u32,    // the step whose loads on the walls are summed into mesh_loads
    load_lanes: u32,    // partial sums of each load (sphere p adds to lane p mod load_lanes)
    own_lo: vec3<f32>,  // the loads sum the spheres whose centre c has own_lo <= c < own_hi
    own_hi: vec3<f32>,  // (infinite: every sphere; a rank's step: its box, not its ghosts)
}

struct MeshWall {
    lo: vec3<f32>,      // the rest-geometry grid's lower corner [m]
    cell: f32,          // its cell side [m]
    dims: vec3<u32>,    // its cells per axis
    first_cell: u32,    // its first cell's index in mesh_grid
    velocity: vec3<f32>,// of the translation [m/s], from `start` on
    omega: f32,         // angular speed about `axis` [rad/s], from `start` on
    axis: vec3<f32>,    // unit
    start: f32,         // when the motion starts [s]
    centre: vec3<f32>,  // a point of the axis at `start` [m]; loads' torques are about it
    column: u32,        // the wall's column of the material table
    own_friction: f32,  // the wall's own μ, or < 0 (NO_FRICTION): the pair's
}

// Partner ids of mesh walls' contacts (src/particles/history.rs).
const FIRST_MESH_WALL: u32 = 0xfffefffau;
// Candidates within a sphere's radius kept per wall, nearest first.
const MESH_NEAR: u32 = 16u;
// Candidates this fraction of the radius behind a kept contact's tangent plane count as on it.
const ON_PLANE: f32 = 1e-4;

@group(0) @binding(70) var<uniform> mesh: MeshParams;
@group(0) @binding(71) var<storage, read> mesh_walls: array<MeshWall>;
// Cell k's triangles are mesh_grid[mesh_grid[k]] .. mesh_grid[mesh_grid[k + 1] - 1] (the
// cells' offsets, then the triangle indices).
@group(0) @binding(72) var<storage, read> mesh_grid: array<u32>;
// per triangle: corners a, b, c and the unit normal (b − a) × (c − a), rest geometry
@group(0) @binding(73) var<storage, read> mesh_tris: array<vec4<f32>>;
// per lane and wall 8 words as f32 bits: force on it x, y, z, 0, torque x, y, z, 0 (word
// (lane·walls + wall)·8 + k; the host adds the lanes: one sum per wall would have every
// sphere touching it retry its compare-and-swap against all the others); then the most
// candidates a sphere had (a u32)
@group(0) @binding(74) var<storage, read_write> mesh_loads: array<atomic<u32>>;
// The spheres near a mesh wall: words 0 and 1 count those of the steps of even and odd number
// (the host zeroes both ahead of a batch; each step's listing zeroes the next step's), then the
// state indices of the current step's.
@group(0) @binding(75) var<storage, read_write> mesh_near: array<atomic<u32>>;

// Where a wall is at one time and how its points move.
struct Pose {
    q: vec4<f32>,       // rotation from the rest geometry (x, y, z, w)
    offset: vec3<f32>,  // x = q·x_rest + offset
    centre: vec3<f32>,
    velocity: vec3<f32>,
    spin: vec3<f32>,
}

fn rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    return v + 2.0 * cross(q.xyz, cross(q.xyz, v) + q.w * v);
}

fn pose_at(m: MeshWall, t: f32) -> Pose {
    let running = t > m.start;
    let tau = select(0.0, t - m.start, running);
    let half = 0.5 * m.omega * tau;
    let q = vec4(m.axis * sin(half), cos(half));
    let centre = m.centre + m.velocity * tau;
    let velocity = select(vec3(0.0), m.velocity, running);
    let spin = select(vec3(0.0), m.axis * m.omega, running);
    return Pose(q, centre - rotate(q, m.centre), centre, velocity, spin);
}

// The triangle's point closest to p (corner, edge or face regions by the barycentric signs, as
// `Triangle::closest_point`).
fn closest_point(tri: u32, p: vec3<f32>) -> vec3<f32> {
    let a = mesh_tris[4u * tri].xyz;
    let b = mesh_tris[4u * tri + 1u].xyz;
    let c = mesh_tris[4u * tri + 2u].xyz;
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot3(ab, ap);
    let d2 = dot3(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = dot3(ab, bp);
    let d4 = dot3(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = dot3(ab, cp);
    let d6 = dot3(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return b + (c - b) * w;
    }
    let n = mesh_tris[4u * tri + 3u].xyz;
    return p - n * dot3(ap, n);
}

// A sphere's candidates of one wall: distance² and triangle, nearest first; and its contacts
// kept so far: rest normal and distance.
var<private> near_d2: array<f32, MESH_NEAR>;
var<private> near_tri: array<u32, MESH_NEAR>;
var<private> kept_plane: array<vec4<f32>, MESH_NEAR>;

// The offset in mesh_grid of the cell of wall m's grid that holds the rest point p (its
// triangles run from mesh_grid[cell] to mesh_grid[cell + 1]), or NO_CELL outside the grid.
const NO_CELL: u32 = 0xffffffffu;

fn cell_holding(m: MeshWall, p: vec3<f32>) -> u32 {
    let at = (p - m.lo) / m.cell;
    // Written so that a non-finite centre (an unstable run, stopped by the host at the next
    // read) is in no cell.
    if !(all(at >= vec3(0.0)) && all(at < vec3<f32>(m.dims))) {
        return NO_CELL;
    }
    let c = vec3<u32>(at);
    return m.first_cell + c.x + m.dims.x * (c.y + m.dims.y * c.z);
}

// Whether the cell (of cell_holding) lists triangles.
fn lists_triangles(cell: u32) -> bool {
    return cell != NO_CELL && mesh_grid[cell] < mesh_grid[cell + 1u];
}

// Adds x to the f32 whose bits are mesh_loads[k].
fn add_load(k: u32, x: f32) {
    var old = atomicLoad(&mesh_loads[k]);
    loop {
        let swap = atomicCompareExchangeWeak(&mesh_loads[k], old, bitcast<u32>(bitcast<f32>(old) + x));
        if swap.exchanged {
            break;
        }
        old = swap.old_value;
    }
}

// Lists the triangles of `cell` within distance r of the rest point p (in it) into near_*,
// nearest first; returns how many there were (more than MESH_NEAR: the farthest were dropped).
// A cell lists each triangle that comes within the largest radius of it once.
fn mesh_candidates(cell: u32, p: vec3<f32>, r: f32) -> u32 {
    var found = 0u;
    for (var k = mesh_grid[cell]; k < mesh_grid[cell + 1u]; k += 1u) {
        let tri = mesh_grid[k];
        let q = closest_point(tri, p);
        let d2 = dot3(q - p, q - p);
        if d2 >= r * r || d2 <= 0.0 {
            continue;
        }
        let held = min(found, MESH_NEAR);
        found += 1u;
        if held == MESH_NEAR && d2 >= near_d2[MESH_NEAR - 1u] {
            continue;
        }
        // Insertion by distance, equal distances in the order met.
        var j = held;
        if j == MESH_NEAR {
            j = MESH_NEAR - 1u;
        }
        while j > 0u && near_d2[j - 1u] > d2 {
            near_d2[j] = near_d2[j - 1u];
            near_tri[j] = near_tri[j - 1u];
            j -= 1u;
        }
        near_d2[j] = d2;
        near_tri[j] = tri;
    }
    return found;
}

// The walker's old slot at or after slot `first` of its contact with `partner`, or `kept`.
fn own_old_slot_from(w: ptr<function, Walker>, partner: u32, first: u32) -> u32 {
    let at = (*w).own_old;
    var s = first;
    for (; s < (*w).kept; s += 1u) {
        if old_partner(SlotAt(at.part, at.slot + s)) == partner {
            break;
        }
    }
    return s;
}

// The walker's contacts with wall `wall` (m, at `pose`; p: its centre in the rest geometry):
// their force and torque added to the walker's, their springs kept; in step mesh.loads_step
// (`summing`) their reactions added to the wall's loads.
fn wall_contacts(w: ptr<function, Walker>, wall: u32, m: MeshWall, pose: Pose, cell: u32, p: vec3<f32>, summing: bool) {
    let b = (*w).me;
    // Where contacts adhere, a contact of the last step may hold past touching, up to the reach.
    var within = b.r;
    if COHESIVE {
        within += dem.reach;
    }
    let found = mesh_candidates(cell, p, within);
    if found == 0u {
        return;
    }
    if found > MESH_NEAR {
        atomicMax(&mesh_loads[8u * mesh.walls * mesh.load_lanes], found);
    }
    // The contacts kept so far: rest normal and distance.
    let partner = FIRST_MESH_WALL + wall;
    var force = vec3(0.0);
    var torque = vec3(0.0);
    var kept = 0u;
    var next_old = 0u;
    let slack = ON_PLANE * b.r;
    let law = law_of(b.material, m.column);
    let wet = bridge_of(b.material, m.column);
    let mu = select(law.sliding, m.own_friction, m.own_friction >= 0.0);
    for (var k = 0u; k < min(found, MESH_NEAR); k += 1u) {
        let q = closest_point(near_tri[k], p);
        let to = q - p;
        var covered = false;
        for (var j = 0u; j < kept; j += 1u) {
            covered = covered || dot3(to, kept_plane[j].xyz) >= kept_plane[j].w - slack;
        }
        if covered {
            continue;
        }
        let d = sqrt(near_d2[k]);
        let n_rest = to / d;
        kept_plane[kept] = vec4(n_rest, d);
        kept += 1u;
        let point = rotate(pose.q, q) + pose.offset;
        let n = rotate(pose.q, n_rest);
        let surface_velocity = pose.velocity + cross(pose.spin, point - pose.centre);
        // The k-th contact with this wall takes the k-th old entry of it.
        var s = (*w).kept;
        if dem.slots > 0u {
            s = own_old_slot_from(w, partner, next_old);
        }
        let touching = near_d2[k] < b.r * b.r;
        // d < r where touching, but the GPU's square root may round up (see pair_contact).
        var overlap = b.r - d;
        if touching {
            overlap = max(overlap, 0.0);
        } else if !(COHESIVE && s < (*w).kept && holds(law, wet, b.r, overlap)) {
            // Past touching, only a contact of the last step that still holds (its entry is
            // left for the next contact).
            continue;
        }
        var old = no_springs();
        if s < (*w).kept {
            old = own_old_springs(w, s);
            next_old = s + 1u;
        }
        let c = surface_contact(b, n, overlap, surface_velocity, law, wet, mu, old);
        force += c.force;
        torque += c.torque;
        if dem.slots > 0u {
            keep_springs(w, partner, c.springs);
        }
    }
    (*w).force += force;
    (*w).torque += torque;
    if summing {
        // The wall takes the opposite force and the opposite angular impulse about its
        // centre.
        let about = -(cross(b.c - pose.centre, force) + torque);
        let at = 8u * ((*w).h % mesh.load_lanes * mesh.walls + wall);
        for (var a = 0u; a < 3u; a += 1u) {
            add_load(at + a, -force[a]);
            add_load(at + 4u + a, about[a]);
        }
    }
}

// Where wall m is at time t, and the rest point of the world point c.
struct Seen {
    pose: Pose,
    p: vec3<f32>,
}

fn seen_from(m: MeshWall, t: f32, c: vec3<f32>) -> Seen {
    let pose = pose_at(m, t);
    let inverse = vec4(-pose.q.xyz, pose.q.w);
    return Seen(pose, rotate(inverse, c - pose.offset));
}

// Whether the cell of some mesh wall's grid holding the centre c at time t lists triangles:
// the spheres for which none does (most of them) have nothing to do.
fn near_mesh_walls(c: vec3<f32>, t: f32) -> bool {
    for (var wall = 0u; wall < mesh.walls; wall += 1u) {
        let m = mesh_walls[wall];
        if lists_triangles(cell_holding(m, seen_from(m, t, c).p)) {
            return true;
        }
    }
    return false;
}

// The walker's contacts with every mesh wall at time t (`wall_contacts`).
fn mesh_contacts(w: ptr<function, Walker>, t: f32, summing: bool) {
    let b = (*w).me;
    for (var wall = 0u; wall < mesh.walls; wall += 1u) {
        let m = mesh_walls[wall];
        let seen = seen_from(m, t, b.c);
        let cell = cell_holding(m, seen.p);
        if lists_triangles(cell) {
            wall_contacts(w, wall, m, seen.pose, cell, seen.p, summing);
        }
    }
}

// The listing's room of a workgroup: its spheres near a wall, and where they go in mesh_near.
var<workgroup> group_near: atomic<u32>;
var<workgroup> group_first: u32;

// Lists sphere p (state index) in mesh_near where the cell of some mesh wall's grid holding it
// lists triangles (`near_mesh_walls`), a workgroup's spheres in one block (one atomic per
// workgroup on the count).
@compute @workgroup_size(256)
fn mesh_walls_near(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let p = gid.x + gid.y * dem.row;
    let step = atomicLoad(&clock) - 1u;
    let parity = step & 1u;
    if lid == 0u {
        atomicStore(&group_near, 0u);
    }
    workgroupBarrier();
    var near = false;
    if p < dem.n {
        near = near_mesh_walls(pos[p].xyz, f32(step) * dem.dt);
    }
    var at = 0u;
    if near {
        at = atomicAdd(&group_near, 1u);
    }
    workgroupBarrier();
    if lid == 0u {
        group_first = atomicAdd(&mesh_near[parity], atomicLoad(&group_near));
    }
    if p == 0u {
        atomicStore(&mesh_near[1u - parity], 0u);
    }
    let first = workgroupUniformLoad(&group_first);
    if near {
        atomicStore(&mesh_near[2u + first + at], p);
    }
}

// The mesh-wall contacts of the listed sphere `gid` of this step (mesh_walls_near), after the
// contact pass wrote its row of the new history and added its other forces: the contacts
// appended to the row (the count raised past the slots as the contact pass does), their force
// and torque added to the sphere's accumulators.
@compute @workgroup_size(256)
fn mesh_wall_contacts(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x + gid.y * dem.row;
    let step = atomicLoad(&clock) - 1u;
    if k >= atomicLoad(&mesh_near[step & 1u]) {
        return;
    }
    let p = atomicLoad(&mesh_near[2u + k]);
    var w = walker(p, p, pos[p]);
    if dem.slots > 0u {
        // Past the slots the batch is redone anyway (history_need is raised already).
        w.held = held_new[p];
    }
    let c = w.me.c;
    let own = all(c >= mesh.own_lo) && all(c < mesh.own_hi);
    let summing = step == mesh.loads_step && own;
    mesh_contacts(&w, f32(step) * dem.dt, summing);
    add_force(p, w.force);
    if dem.turns != 0u {
        add_torque(p, w.torque);
    }
    if dem.slots > 0u {
        held_new[p] = min(w.held, dem.slots);
        if w.held > dem.slots {
            atomicMax(&history_need, w.held);
        }
    }
}
