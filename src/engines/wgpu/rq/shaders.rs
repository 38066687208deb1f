//! The wgpu-rq engine's WGSL modules: each one's composed source, entry points, bindings and
//! uniform, named once for the bind-group code and checked against the WGSL by
//! `tests/bindings.rs`.

use crate::engines::wgpu::granular::shader as granular;
use crate::engines::wgpu::step::{self, Variant, physics};
use crate::gpu::pair_output;
use crate::gpu::shader::{Binding, SharedStruct, Vec3f, WgslModule, shared_struct, wgsl};

/// Morton keys and proxy boxes of a detection build (`wgsl/rq/rq_build.wgsl`).
pub(crate) mod rq_build {
    use super::{Binding, SharedStruct, Vec3f, shared_struct, wgsl};

    pub const SOURCE: &str = wgsl!("core/proxy.wgsl", "rq/rq_build.wgsl");
    pub const ENTRY_POINTS: &[&str] = &["morton_keys", "proxy_boxes"];

    pub const PARAMS: Binding = Binding::uniform(0, "params");
    pub const SPHERES_IN: Binding = Binding::read(1, "spheres_in");
    pub const KEYS: Binding = Binding::read_write(2, "keys");
    pub const ORDER: Binding = Binding::read_write(3, "order");
    pub const SPHERES_SORTED: Binding = Binding::read_write(4, "spheres_sorted");
    pub const BOXES: Binding = Binding::read_write(5, "boxes");
    pub const BINDINGS: &[Binding] = &[PARAMS, SPHERES_IN, KEYS, ORDER, SPHERES_SORTED, BOXES];

    /// The build's uniform; WGSL twin: `BuildParams`.
    #[derive(Clone, Copy, Default, encase::ShaderType)]
    pub struct BuildParams {
        /// Lower corner of the centres' bounding box.
        pub lo: Vec3f,
        /// Number of spheres.
        pub n: u32,
        /// Morton cells per unit along each axis ([`morton::Grid`](crate::morton::Grid)).
        pub scale: Vec3f,
        /// [`ProxyMode::code`](crate::proxy::ProxyMode::code).
        pub mode: u32,
        /// Largest radius.
        pub r_max: f32,
        /// Relative padding of the boxes.
        pub pad_rel: f32,
        /// Invocations per dispatch row (2-D dispatch).
        pub row: u32,
    }

    pub(super) fn build_params() -> SharedStruct {
        shared_struct!(
            "BuildParams",
            BuildParams {
                lo,
                n,
                scale,
                mode,
                r_max,
                pad_rel,
                row,
            }
        )
    }
}

/// Detection by ray queries (`wgsl/rq/rq_pairs.wgsl`).
pub(crate) mod rq_pairs {
    use super::{Binding, SharedStruct, pair_output, shared_struct, wgsl};

    pub const SOURCE: &str = wgsl!(
        "rq/rq_pairs.wgsl",
        "rq/rq_walk.wgsl",
        "core/proxy.wgsl",
        "core/pair_output.wgsl"
    );
    pub const ENTRY_POINTS: &[&str] = &["find_pairs"];

    pub const PARAMS: Binding = Binding::uniform(0, "params");
    pub const SPHERES: Binding = Binding::read(1, "spheres");
    pub const IDS: Binding = Binding::read(2, "ids");
    pub const TLAS: Binding = Binding::acceleration_structure(5, "tlas");
    pub const BINDINGS: &[Binding] = &[
        PARAMS,
        SPHERES,
        IDS,
        TLAS,
        pair_output::COUNTERS,
        pair_output::PAIRS,
    ];

    /// The detection's uniform; WGSL twin: `PairParams`.
    #[derive(Clone, Copy, Default, encase::ShaderType)]
    pub struct PairParams {
        /// Number of spheres.
        pub n: u32,
        /// Room in the pair buffer.
        pub capacity: u32,
        /// [`ProxyMode::code`](crate::proxy::ProxyMode::code).
        pub mode: u32,
        /// Primitives per BLAS: sorted index = custom_data * chunk + primitive_index.
        pub chunk: u32,
        /// Invocations per dispatch row (2-D dispatch).
        pub row: u32,
    }

    pub(super) fn pair_params() -> SharedStruct {
        shared_struct!(
            "PairParams",
            PairParams {
                n,
                capacity,
                mode,
                chunk,
                row,
            }
        )
    }
}

/// The DEM step's proxy boxes and contact resolution (`wgsl/rq/dem_rq.wgsl`), followed by the
/// shared physics ([`physics`]), in three variants: the paper's law and its per-pair stiffness
/// (`wgsl/rq/dem_rq_frictionless.wgsl`) and the granular step (`wgsl/rq/dem_rq_granular.wgsl`,
/// [`granular`]).
pub(crate) mod dem_rq {
    use super::{Binding, SharedStruct, granular, physics, shared_struct, wgsl};
    use crate::engines::wgpu::step::{Accumulators, Variant};

    const FRICTIONLESS: &str = wgsl!(
        "rq/dem_rq.wgsl",
        "rq/dem_rq_frictionless.wgsl",
        "rq/rq_walk.wgsl"
    );
    const GRANULAR: &str = wgsl!(
        "rq/dem_rq.wgsl",
        "rq/dem_rq_granular.wgsl",
        "rq/rq_walk.wgsl"
    );
    const PROXY: &str = wgsl!("core/proxy.wgsl");

    /// The paper's step with the accumulators `atomics` (one of [`physics::FORCE_VARIANTS`]).
    pub fn source(atomics: Accumulators) -> String {
        format!("{FRICTIONLESS}{}{PROXY}", physics::frictionless(atomics))
    }

    /// The granular step (`variant`: Mindlin's spring or Mindlin–Deresiewicz) with the
    /// accumulators `atomics`.
    pub fn granular_source(atomics: Accumulators, variant: Variant) -> String {
        let physics = physics::granular(atomics, variant);
        format!("{GRANULAR}{physics}{PROXY}")
    }

    /// The source of `variant` with the accumulators `atomics`.
    pub fn variant_source(variant: Variant, atomics: Accumulators) -> String {
        match variant {
            Variant::Paper | Variant::PerPair => source(atomics),
            Variant::Granular | Variant::Loaded => granular_source(atomics, variant),
        }
    }

    /// The entry points of every variant.
    pub const ENTRY_POINTS: &[&str] = &["proxy_boxes", "resolve", "integrate"];
    /// The granular variant's: the mesh walls' kernels too.
    pub const GRANULAR_ENTRY_POINTS: &[&str] = &[
        "proxy_boxes",
        "resolve",
        "mesh_walls_near",
        "mesh_wall_contacts",
        "advance_clumps",
        "integrate_clumped",
        "integrate",
    ];

    pub const RQ_PARAMS: Binding = Binding::uniform(0, "rq");
    pub const BOXES: Binding = Binding::read_write(5, "boxes");
    pub const TLAS: Binding = Binding::acceleration_structure(6, "tlas");
    pub const COUNTERS: Binding = Binding::read_write(14, "counters");

    /// Every binding of the paper's step, the physics' included.
    pub fn bindings() -> Vec<Binding> {
        [RQ_PARAMS, BOXES, TLAS, COUNTERS]
            .into_iter()
            .chain(physics::BINDINGS.iter().copied())
            .collect()
    }

    /// Every binding of the granular step.
    pub fn granular_bindings() -> Vec<Binding> {
        bindings().into_iter().chain(granular::bindings()).collect()
    }

    /// The step's ray-query uniform; WGSL twin: `RqParams`.
    #[derive(Clone, Copy, Default, encase::ShaderType)]
    pub struct RqParams {
        /// Primitives per BLAS: sphere index = custom_data * chunk + primitive_index.
        pub chunk: u32,
        /// Relative padding of the boxes.
        pub pad_rel: f32,
        /// [`ProxyMode::code`](crate::proxy::ProxyMode::code).
        pub mode: u32,
        /// Largest radius.
        pub r_max: f32,
    }

    pub(super) fn rq_params() -> SharedStruct {
        shared_struct!(
            "RqParams",
            RqParams {
                chunk,
                pad_rel,
                mode,
                r_max,
            }
        )
    }
}

/// Every WGSL module of this engine (detection and DEM step), exactly as the device may get it.
pub fn modules() -> Vec<WgslModule> {
    let mut all = vec![
        WgslModule::new(
            "rq_build",
            rq_build::SOURCE,
            rq_build::ENTRY_POINTS,
            rq_build::BINDINGS,
            vec![rq_build::build_params()],
        ),
        WgslModule::new(
            "rq_pairs",
            rq_pairs::SOURCE,
            rq_pairs::ENTRY_POINTS,
            rq_pairs::BINDINGS,
            vec![rq_pairs::pair_params()],
        ),
    ];
    for (name, atomics) in physics::FORCE_VARIANTS {
        all.push(WgslModule {
            label: format!("dem_rq_{name}"),
            source: dem_rq::source(atomics),
            entry_points: dem_rq::ENTRY_POINTS,
            bindings: dem_rq::bindings(),
            structs: [vec![dem_rq::rq_params()], step::law_structs().to_vec()].concat(),
        });
        for (model, variant) in [("", Variant::Granular), ("_md", Variant::Loaded)] {
            all.push(WgslModule {
                label: format!("dem_rq_granular_{name}{model}"),
                source: dem_rq::granular_source(atomics, variant),
                entry_points: dem_rq::GRANULAR_ENTRY_POINTS,
                bindings: dem_rq::granular_bindings(),
                structs: [
                    vec![dem_rq::rq_params()],
                    step::law_structs().to_vec(),
                    step::material_table().to_vec(),
                    crate::engines::common::clumps::clump_structs().to_vec(),
                    vec![
                        step::cohesion_params(),
                        crate::engines::common::walls::mesh_params(),
                        crate::engines::common::walls::mesh_wall_row(),
                    ],
                ]
                .concat(),
            });
        }
    }
    all
}

#[cfg(test)]
mod tests {
    use super::rq_build::{self, BuildParams};
    use crate::gpu;
    use crate::morton;

    #[test]
    fn the_wgsl_morton_keys_are_the_host_ones() {
        let Some(gpu) = gpu::test_gpu("the WGSL Morton keys") else {
            return;
        };
        // Corners, a flat axis, points between cells and on their borders.
        let rows: Vec<[f32; 4]> = (0..1000u32)
            .map(|i| {
                let f = |m: u32, s: f32| ((i * m) % 997) as f32 * s - 3.0;
                [f(7, 0.013), f(13, 1.0 / 1023.0), 2.5, 0.1]
            })
            .collect();
        let centres: Vec<[f32; 3]> = rows.iter().map(|r| [r[0], r[1], r[2]]).collect();
        let grid = morton::Grid::of(&centres);
        let n = rows.len() as u32;
        let params = BuildParams {
            lo: grid.lo.into(),
            n,
            scale: grid.scale.into(),
            row: 256 * n.div_ceil(256),
            ..BuildParams::default()
        };
        let none = wgpu::BufferUsages::empty();
        let uniform = gpu.uniform("test.morton.params", &params);
        let spheres = gpu.storage("test.morton.spheres", u64::from(n) * 16, none);
        let keys = gpu.storage("test.morton.keys", u64::from(n) * 4, none);
        let order = gpu.storage("test.morton.order", u64::from(n) * 4, none);
        gpu.queue
            .write_buffer(&spheres, 0, bytemuck::cast_slice(&rows));
        let module = gpu.own_module("test.morton", rq_build::SOURCE);
        let pipeline = gpu.pipeline("test.morton", &module, "morton_keys");
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        gpu.pass(
            &mut encoder,
            "test.morton",
            &pipeline,
            &[
                (rq_build::PARAMS, &uniform),
                (rq_build::SPHERES_IN, &spheres),
                (rq_build::KEYS, &keys),
                (rq_build::ORDER, &order),
            ],
            (n.div_ceil(256), 1),
        );
        gpu.queue.submit([encoder.finish()]);
        let got: Vec<u32> = gpu.read(&keys, rows.len()).unwrap();
        for (i, (&key, &c)) in got.iter().zip(&centres).enumerate() {
            assert_eq!(key, grid.key(c), "sphere {i} at {c:?}");
        }
    }
}
