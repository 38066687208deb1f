// Force accumulators as u32 bit patterns added by compare-and-swap loops, for adapters without
// float atomics; appended to dem_physics.wgsl. Twin: dem_force_f32.wgsl.

@group(0) @binding(13) var<storage, read_write> force: array<atomic<u32>>;

fn add_component(k: u32, x: f32) {
    var old = atomicLoad(&force[k]);
    loop {
        let swap = atomicCompareExchangeWeak(&force[k], old, bitcast<u32>(bitcast<f32>(old) + x));
        if swap.exchanged {
            break;
        }
        old = swap.old_value;
    }
}

fn add_force(i: u32, f: vec3<f32>) {
    add_component(3u * i, f.x);
    add_component(3u * i + 1u, f.y);
    add_component(3u * i + 2u, f.z);
}

// Zeroes sphere i's accumulator (for a step that did not clear the whole buffer).
fn clear_force(i: u32) {
    atomicStore(&force[3u * i], 0u);
    atomicStore(&force[3u * i + 1u], 0u);
    atomicStore(&force[3u * i + 2u], 0u);
}

fn load_force(i: u32) -> vec3<f32> {
    return vec3(
        bitcast<f32>(atomicLoad(&force[3u * i])),
        bitcast<f32>(atomicLoad(&force[3u * i + 1u])),
        bitcast<f32>(atomicLoad(&force[3u * i + 2u])),
    );
}
