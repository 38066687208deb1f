// The proxy-sphere rule (method.md rules 1–3). Keep in sync with src/proxy.rs, line for line.
// Prepended to every shader that filters candidates.

const MODE_MOCHI: u32 = 0u;
const MODE_NNS: u32 = 1u;

fn dist2(c_i: vec3<f32>, c_j: vec3<f32>) -> f32 {
    let dx = c_i.x - c_j.x;
    let dy = c_i.y - c_j.y;
    let dz = c_i.z - c_j.z;
    return dx * dx + dy * dy + dz * dz;
}

fn collides(d2: f32, r_i: f32, r_j: f32) -> bool {
    let s = r_i + r_j;
    return d2 <= s * s;
}

fn keep(i: u32, c_i: vec3<f32>, r_i: f32, j: u32, c_j: vec3<f32>, r_j: f32) -> bool {
    if i == j {
        return false;
    }
    let d2 = dist2(c_i, c_j);
    let proxy_j = 2.0 * r_j;
    let proxy_i = 2.0 * r_i;
    return collides(d2, r_i, r_j) && d2 <= proxy_j * proxy_j && (j > i || d2 > proxy_i * proxy_i);
}

fn keep_nns(i: u32, c_i: vec3<f32>, r_i: f32, j: u32, c_j: vec3<f32>, r_j: f32) -> bool {
    return j > i && collides(dist2(c_i, c_j), r_i, r_j);
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
