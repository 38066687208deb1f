// The integration kernel of the frictionless GPU steps: walls, gravity and one semi-implicit
// Euler step. Follows the law's file (dem_physics.wgsl: its wall_force) and needs a dem_force_*.wgsl (load_force, clear_force).

// Walls, gravity and one semi-implicit Euler step, in place.
@compute @workgroup_size(256)
fn integrate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x + gid.y * dem.row;
    if p >= dem.n {
        return;
    }
    integrate_sphere(p);
}

// Integrates sphere p (state index) and zeroes its force accumulators for the next step (where
// a contact added to them: most of a loose scene's stay zero, unwritten); returns its new centre
// and radius.
fn integrate_sphere(p: u32) -> vec4<f32> {
    let s = pos[p];
    let v = vel[p];
    let contacts = load_force(p);
    if any(contacts != vec3(0.0)) {
        clear_force(p);
    }
    var f = contacts + wall_force(s.xyz, v.xyz, s.w, v.w);
    if dem.loaded != 0u {
        f += external_load(stable_id(p), 0u);
    }
    let g = gravity_at(atomicLoad(&clock) - 1u);
    let m = v.w;
    let v_new = v.xyz + dem.dt * (f / m + g);
    vel[p] = vec4(v_new, m);
    let moved = vec4(advance_position(p, s.xyz, dem.dt * v_new), s.w);
    pos[p] = moved;
    return moved;
}
