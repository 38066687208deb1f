// A thread's lanes where the adapter has no subgroup operations: every thread is a subgroup of
// one lane (lanes_subgroups.wgsl has the contract).

// Nothing to know about subgroups here (a builtin nobody reads stands in).
struct Lanes {
    @builtin(local_invocation_id) unused: vec3<u32>,
}

fn lane_index(l: Lanes) -> u32 {
    return 0u;
}

fn lane_count(l: Lanes) -> u32 {
    return 1u;
}

fn lanes_inclusive_add(x: u32) -> u32 {
    return x;
}

fn lanes_add(x: u32) -> u32 {
    return x;
}

fn lane_u32(x: u32, source: u32) -> u32 {
    return x;
}

fn lane_vec2u(x: vec2<u32>, source: u32) -> vec2<u32> {
    return x;
}

fn lane_vec4u(x: vec4<u32>, source: u32) -> vec4<u32> {
    return x;
}

fn lane_vec3f(x: vec3<f32>, source: u32) -> vec3<f32> {
    return x;
}

fn lane_vec4f(x: vec4<f32>, source: u32) -> vec4<f32> {
    return x;
}

fn lane_below_u32(x: u32, delta: u32) -> u32 {
    return x;
}

fn lane_below_vec3f(x: vec3<f32>, delta: u32) -> vec3<f32> {
    return x;
}
