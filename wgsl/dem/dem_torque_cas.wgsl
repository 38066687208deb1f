// Torque accumulators as u32 bit patterns added by compare-and-swap loops, by state index; appended
// to the granular step with dem_force_cas.wgsl. Twin: dem_torque_f32.wgsl.

@group(0) @binding(19) var<storage, read_write> torque: array<atomic<u32>>;

fn add_torque_component(k: u32, x: f32) {
    var old = atomicLoad(&torque[k]);
    loop {
        let swap = atomicCompareExchangeWeak(&torque[k], old, bitcast<u32>(bitcast<f32>(old) + x));
        if swap.exchanged {
            break;
        }
        old = swap.old_value;
    }
}

fn add_torque(i: u32, t: vec3<f32>) {
    add_torque_component(3u * i, t.x);
    add_torque_component(3u * i + 1u, t.y);
    add_torque_component(3u * i + 2u, t.z);
}

// Zeroes sphere i's accumulator once its torque is applied.
fn clear_torque(i: u32) {
    atomicStore(&torque[3u * i], 0u);
    atomicStore(&torque[3u * i + 1u], 0u);
    atomicStore(&torque[3u * i + 2u], 0u);
}

fn load_torque(i: u32) -> vec3<f32> {
    return vec3(
        bitcast<f32>(atomicLoad(&torque[3u * i])),
        bitcast<f32>(atomicLoad(&torque[3u * i + 1u])),
        bitcast<f32>(atomicLoad(&torque[3u * i + 2u])),
    );
}
