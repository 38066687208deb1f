// Scan across a workgroup in workgroup memory, shared by workgroup_scan_plain.wgsl and
// workgroup_scan_subgroups.wgsl. Needs `WG` (threads per workgroup, a power of two) defined by the
// shader.

// Ping-pong halves for the scan across threads.
var<workgroup> part: array<u32, 2u * WG>;

// Inclusive scan of x over the workgroup's threads (Hillis-Steele, one barrier per step):
// returns (inclusive prefix of thread t, workgroup total). Call from uniform control flow.
fn shared_scan(t: u32, x: u32) -> vec2<u32> {
    part[t] = x;
    workgroupBarrier();
    var cur = 0u;
    for (var off = 1u; off < WG; off <<= 1u) {
        var y = part[cur + t];
        if t >= off {
            y += part[cur + t - off];
        }
        cur = WG - cur;
        part[cur + t] = y;
        workgroupBarrier();
    }
    let result = vec2(part[cur + t], part[cur + WG - 1u]);
    // Nobody writes `part` again before every thread has read its result.
    workgroupBarrier();
    return result;
}

