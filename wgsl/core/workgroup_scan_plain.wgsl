// Scan across a workgroup of WG threads in workgroup memory, for adapters without subgroup
// operations; with them, workgroup_scan_subgroups.wgsl replaces this file. Both define
// `SubgroupLanes` (an entry point's argument), `scan_kind` and `workgroup_scan`, so the shaders
// that scan are written once. Needs workgroup_scan.wgsl appended.

// Nothing to know about subgroups here (a builtin the scan does not read stands in).
struct SubgroupLanes {
    @builtin(local_invocation_id) unused: vec3<u32>,
}

// How this workgroup scans: always in workgroup memory here.
fn scan_kind(t: u32, lanes: SubgroupLanes) -> u32 {
    return 0u;
}

fn workgroup_scan(t: u32, x: u32, lanes: SubgroupLanes, kind: u32) -> vec2<u32> {
    return shared_scan(t, x);
}
