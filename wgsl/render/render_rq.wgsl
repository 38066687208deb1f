// Render path wgpu-rq: `trace` runs a ray query over a BLAS of the spheres' boxes (Morton
// order, one instance); each AABB candidate is tested against its sphere, and a nearer hit is
// committed with rayQueryGenerateIntersection, which shortens the ray so that farther boxes are
// culled. render_common.wgsl is appended to this file.
enable wgpu_ray_query;

@group(0) @binding(5) var tlas: acceleration_structure;

fn trace(o: vec3<f32>, d: vec3<f32>, t_max: f32, first: bool) -> Hit {
    var best = Hit(t_max, NONE);
    if view.n == 0u {
        return best;
    }
    var rq: ray_query;
    rayQueryInitialize(&rq, tlas, RayDesc(0u, 0xffu, 0.0, t_max, o, d));
    while rayQueryProceed(&rq) {
        let candidate = rayQueryGetCandidateIntersection(&rq);
        if candidate.kind != RAY_QUERY_INTERSECTION_AABB {
            continue;
        }
        let k = candidate.primitive_index;
        let t = hit_sphere(o, d, spheres[k]);
        if t < best.t {
            best = Hit(t, k);
            rayQueryGenerateIntersection(&rq, t);
            if first {
                rayQueryTerminate(&rq);
            }
        }
    }
    return best;
}
