// Force accumulators with float atomics (SHADER_FLOAT32_ATOMIC); appended to dem_physics.wgsl.
// Twin: dem_force_cas.wgsl, for adapters without them.

@group(0) @binding(13) var<storage, read_write> force: array<atomic<f32>>;

fn add_force(i: u32, f: vec3<f32>) {
    atomicAdd(&force[3u * i], f.x);
    atomicAdd(&force[3u * i + 1u], f.y);
    atomicAdd(&force[3u * i + 2u], f.z);
}

// Zeroes sphere i's accumulator (for a step that did not clear the whole buffer).
fn clear_force(i: u32) {
    atomicStore(&force[3u * i], 0.0);
    atomicStore(&force[3u * i + 1u], 0.0);
    atomicStore(&force[3u * i + 2u], 0.0);
}

fn load_force(i: u32) -> vec3<f32> {
    return vec3(atomicLoad(&force[3u * i]), atomicLoad(&force[3u * i + 1u]), atomicLoad(&force[3u * i + 2u]));
}
