// Torque accumulators with float atomics (SHADER_FLOAT32_ATOMIC), by state index; appended to
// the granular step with dem_force_f32.wgsl. Twin: dem_torque_cas.wgsl.

@group(0) @binding(19) var<storage, read_write> torque: array<atomic<f32>>;

fn add_torque(i: u32, t: vec3<f32>) {
    atomicAdd(&torque[3u * i], t.x);
    atomicAdd(&torque[3u * i + 1u], t.y);
    atomicAdd(&torque[3u * i + 2u], t.z);
}

// Zeroes sphere i's accumulator once its torque is applied.
fn clear_torque(i: u32) {
    atomicStore(&torque[3u * i], 0.0);
    atomicStore(&torque[3u * i + 1u], 0.0);
    atomicStore(&torque[3u * i + 2u], 0.0);
}

fn load_torque(i: u32) -> vec3<f32> {
    return vec3(atomicLoad(&torque[3u * i]), atomicLoad(&torque[3u * i + 1u]), atomicLoad(&torque[3u * i + 2u]));
}
