// A thread's lanes: the subgroup it runs in (adapters with wgpu's SUBGROUP feature;
// lanes_single.wgsl otherwise, where every thread is a subgroup of one lane). Both define `Lanes`
// (an entry point's argument) and the functions below, so a kernel that shares work among its
// lanes is written once. Call them from subgroup-uniform control flow: every lane of the subgroup
// must reach the same calls.

struct Lanes {
    @builtin(subgroup_invocation_id) lane: u32,
    @builtin(subgroup_size) size: u32,
}

fn lane_index(l: Lanes) -> u32 {
    return l.lane;
}

fn lane_count(l: Lanes) -> u32 {
    return l.size;
}

// The sum of x over the lanes up to and including this one.
fn lanes_inclusive_add(x: u32) -> u32 {
    return subgroupInclusiveAdd(x);
}

// The sum of x over every lane.
fn lanes_add(x: u32) -> u32 {
    return subgroupAdd(x);
}

// x of lane `source`.
fn lane_u32(x: u32, source: u32) -> u32 {
    return subgroupShuffle(x, source);
}

fn lane_vec2u(x: vec2<u32>, source: u32) -> vec2<u32> {
    return subgroupShuffle(x, source);
}

fn lane_vec4u(x: vec4<u32>, source: u32) -> vec4<u32> {
    return subgroupShuffle(x, source);
}

fn lane_vec3f(x: vec3<f32>, source: u32) -> vec3<f32> {
    return subgroupShuffle(x, source);
}

fn lane_vec4f(x: vec4<f32>, source: u32) -> vec4<f32> {
    return subgroupShuffle(x, source);
}

// x of the lane `delta` below this one (this lane's own x where there is none).
fn lane_below_u32(x: u32, delta: u32) -> u32 {
    return subgroupShuffleUp(x, delta);
}

fn lane_below_vec3f(x: vec3<f32>, delta: u32) -> vec3<f32> {
    return subgroupShuffleUp(x, delta);
}
