//! The pairs of a detection sorted on the GPU, (i, j) ascending, i < j in each: split into their
//! two indices (`wgsl/pair_sort.wgsl`), sorted stably by j, then stably by i with the
//! [`RadixSort`], and joined back, all recorded into the caller's encoder ahead of the read-back.
//! Its bindings and `Params` are [`module`]'s (checked by `tests/bindings.rs`).

use super::Gpu;
use super::radix_sort::RadixSort;
use super::shader::{Binding, WgslModule, shared_struct, wgsl};

/// The shader, embedded.
const SOURCE: &str = wgsl!("pair_sort.wgsl");
const ENTRY_POINTS: &[&str] = &["split", "join"];
/// Workgroup size of both kernels (as in the shader).
const GROUP: u32 = 256;

const PARAMS: Binding = Binding::uniform(0, "params");
const PAIRS: Binding = Binding::read_write(1, "pairs");
const FIRSTS: Binding = Binding::read_write(2, "firsts");
const SECONDS: Binding = Binding::read_write(3, "seconds");

/// The split-and-join WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "pair_sort",
        SOURCE,
        ENTRY_POINTS,
        &[PARAMS, PAIRS, FIRSTS, SECONDS],
        vec![shared_struct!("Params", Params { count, row })],
    )
}

/// Parameters of a split or join. WGSL twin: `Params` in `wgsl/pair_sort.wgsl`.
#[derive(Debug, Clone, Copy, Default, encase::ShaderType)]
struct Params {
    /// Pairs.
    count: u32,
    /// Invocations per dispatch row.
    row: u32,
}

/// The two indices of up to `room` pairs while they are sorted.
struct Halves {
    firsts: wgpu::Buffer,
    seconds: wgpu::Buffer,
    room: u32,
}

/// Sorts pair buffers on the GPU; pipelines made once, index buffers grown on demand.
pub struct PairSort {
    split: wgpu::ComputePipeline,
    join: wgpu::ComputePipeline,
    sort: RadixSort,
    params: wgpu::Buffer,
    halves: Option<Halves>,
}

impl PairSort {
    /// Compiles the shaders and builds the pipelines.
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.module("mochi.pair_sort", SOURCE);
        PairSort {
            split: gpu.pipeline("mochi.pair_sort.split", &module, "split"),
            join: gpu.pipeline("mochi.pair_sort.join", &module, "join"),
            sort: RadixSort::new(gpu),
            params: gpu.uniform("mochi.pair_sort.params", &Params::default()),
            halves: None,
        }
    }

    /// Records into `encoder` the sort of the first `count` pairs of `pairs` (`vec2<u32>`, each
    /// index below `spheres`), ascending by the first index, then the second.
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        pairs: &wgpu::Buffer,
        count: u32,
        spheres: u32,
    ) {
        if count < 2 {
            return;
        }
        if self.halves.as_ref().is_none_or(|h| h.room < count) {
            let none = wgpu::BufferUsages::empty();
            let bytes = u64::from(count) * 4;
            self.halves = Some(Halves {
                firsts: gpu.storage("mochi.pair_sort.firsts", bytes, none),
                seconds: gpu.storage("mochi.pair_sort.seconds", bytes, none),
                room: count,
            });
        }
        let Some(h) = &self.halves else {
            unreachable!("allocated above")
        };
        let (x, y) = gpu.grid(count, GROUP);
        gpu.write_uniform(
            &self.params,
            &Params {
                count,
                row: x * GROUP,
            },
        );
        let buffers = [
            (PARAMS, &self.params),
            (PAIRS, pairs),
            (FIRSTS, &h.firsts),
            (SECONDS, &h.seconds),
        ];
        let split = gpu.bind("mochi.pair_sort.split", &self.split, &buffers);
        let join = gpu.bind("mochi.pair_sort.join", &self.join, &buffers);
        let bits = u32::BITS - (spheres.max(2) - 1).leading_zeros();
        gpu.dispatch(
            encoder,
            "mochi.pair_sort.split",
            &self.split,
            &split,
            (x, y),
        );
        // Stable sorts, the minor key first.
        self.sort
            .encode(gpu, encoder, &h.seconds, &h.firsts, count, bits);
        self.sort
            .encode(gpu, encoder, &h.firsts, &h.seconds, count, bits);
        gpu.dispatch(encoder, "mochi.pair_sort.join", &self.join, &join, (x, y));
    }
}
