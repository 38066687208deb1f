// The ray-query loop shared by detection (rq_pairs.wgsl) and the DEM step (dem_rq.wgsl): one
// zero-length point ray from the centre of sphere p, which hands every AABB candidate (the
// sphere q whose proxy box holds the centre) to the including shader. Needs `tlas` bound; the
// including shader defines
//   struct Walker { p: u32, s: vec4<f32>, ... }   sphere p, s = centre/radius, and whatever its
//                                                  visits accumulate
//   fn walk_chunk() -> u32                         primitives per BLAS: sphere q =
//                                                  custom_data * chunk + primitive_index
//   fn visit(w: ptr<function, Walker>, q: u32)     one candidate q

fn rq_walk(w: ptr<function, Walker>) {
    var query: ray_query;
    rayQueryInitialize(&query, tlas, RayDesc(0u, 0xffu, 0.0, 0.0, (*w).s.xyz, vec3(0.0, 0.0, 1.0)));
    while rayQueryProceed(&query) {
        let hit = rayQueryGetCandidateIntersection(&query);
        if hit.kind != RAY_QUERY_INTERSECTION_AABB {
            continue;
        }
        visit(w, hit.instance_custom_data * walk_chunk() + hit.primitive_index);
    }
}
