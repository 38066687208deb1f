// The proxy-sphere rule (docs/method.md, rules 1–3). Keep in sync with src/proxy.rs, line for line.
// Prepended to every shader that filters candidates.

const MODE_MOCHI: u32 = 0u;
const MODE_NNS: u32 = 1u;

// |d| <= t in plain squares (src/proxy.rs `within`: the accepted radii keep every threshold's
// square normal).
fn within(d: vec3<f32>, t: f32) -> bool {
    return d.x * d.x + d.y * d.y + d.z * d.z <= t * t;
}

fn collides(c_i: vec3<f32>, r_i: f32, c_j: vec3<f32>, r_j: f32) -> bool {
    return within(c_i - c_j, r_i + r_j);
}

fn keep(i: u32, c_i: vec3<f32>, r_i: f32, j: u32, c_j: vec3<f32>, r_j: f32) -> bool {
    if i == j {
        return false;
    }
    let d = c_i - c_j;
    return within(d, r_i + r_j) && within(d, 2.0 * r_j) && (j > i || !within(d, 2.0 * r_i));
}

fn keep_nns(i: u32, c_i: vec3<f32>, r_i: f32, j: u32, c_j: vec3<f32>, r_j: f32) -> bool {
    return j > i && collides(c_i, r_i, c_j, r_j);
}

fn keep_in(mode: u32, i: u32, c_i: vec3<f32>, r_i: f32, j: u32, c_j: vec3<f32>, r_j: f32) -> bool {
    if mode == MODE_NNS {
        return keep_nns(i, c_i, r_i, j, c_j, r_j);
    }
    return keep(i, c_i, r_i, j, c_j, r_j);
}

// Half-width of the box of a sphere of radius r_j (ProxyMode::box_half_width).
fn box_half_width(mode: u32, r_j: f32, r_max: f32) -> f32 {
    if mode == MODE_NNS {
        return 2.0 * r_max;
    }
    return 2.0 * r_j;
}
