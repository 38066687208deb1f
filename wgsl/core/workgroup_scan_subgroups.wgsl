// Scan across a workgroup of WG threads on subgroup operations (adapters with wgpu's SUBGROUP
// feature; workgroup_scan_plain.wgsl otherwise): each subgroup scans its own values, one subgroup
// scans the subgroups' totals, three barriers in all instead of log2(WG) + 2 (docs/performance-log/
// has what it saves). It needs every subgroup to be a full run
// of consecutive local indices in lane order, as on every driver we know, but neither Vulkan nor
// WebGPU promises it: a workgroup that finds otherwise (scan_kind) scans in workgroup memory, so
// the result is right on any adapter. Needs workgroup_scan.wgsl appended.

struct SubgroupLanes {
    @builtin(subgroup_invocation_id) lane: u32,
    @builtin(subgroup_size) size: u32,
}

const SCAN_SHARED: u32 = 0u;
const SCAN_SUBGROUPS: u32 = 1u;

var<workgroup> irregular_subgroups: atomic<u32>;
var<workgroup> subgroup_totals: array<u32, WG>;

// SCAN_SUBGROUPS when every subgroup of the workgroup is a full run of consecutive local indices
// starting at a multiple of its size, in lane order; else SCAN_SHARED. Workgroup-uniform; call
// once per invocation from uniform control flow (it holds a barrier).
fn scan_kind(t: u32, lanes: SubgroupLanes) -> u32 {
    if t == 0u {
        atomicStore(&irregular_subgroups, 0u);
    }
    workgroupBarrier();
    let start = t - lanes.lane;
    let run = subgroupBroadcastFirst(start) == start && start % lanes.size == 0u;
    let full = subgroupAdd(1u) == lanes.size;
    if !(run && full) {
        atomicStore(&irregular_subgroups, 1u);
    }
    return select(SCAN_SUBGROUPS, SCAN_SHARED, workgroupUniformLoad(&irregular_subgroups) != 0u);
}

// Inclusive scan of x over the workgroup's threads: returns (inclusive prefix of thread t,
// workgroup total). `kind` from scan_kind. Call from uniform control flow.
fn workgroup_scan(t: u32, x: u32, lanes: SubgroupLanes, kind: u32) -> vec2<u32> {
    if kind == SCAN_SHARED {
        return shared_scan(t, x);
    }
    let inclusive = subgroupInclusiveAdd(x);
    let subgroup = t / lanes.size;
    let subgroups = WG / lanes.size;
    if lanes.lane == lanes.size - 1u {
        subgroup_totals[subgroup] = inclusive;
    }
    workgroupBarrier();
    // The first subgroup scans the totals, a subgroup's worth at a time.
    if subgroup == 0u {
        var carry = 0u;
        for (var first = 0u; first < subgroups; first += lanes.size) {
            let k = first + lanes.lane;
            var total = 0u;
            if k < subgroups {
                total = subgroup_totals[k];
            }
            let scanned = carry + subgroupInclusiveAdd(total);
            if k < subgroups {
                subgroup_totals[k] = scanned;
            }
            carry += subgroupAdd(total);
        }
    }
    workgroupBarrier();
    var before = 0u;
    if subgroup > 0u {
        before = subgroup_totals[subgroup - 1u];
    }
    let result = vec2(before + inclusive, subgroup_totals[subgroups - 1u]);
    // Nobody writes the totals again before every thread has read its result.
    workgroupBarrier();
    return result;
}
