//! The pairs of a detection sorted on the GPU, (i, j) ascending, i < j in each, recorded into
//! the caller's encoder ahead of the read-back (`wgsl/core/pair_sort.wgsl`). Bucketed where the pairs
//! are not far outnumbered by the spheres: each pair ranked in its first index's bucket, the
//! buckets' starts by an [`ExclusiveScan`], the pairs placed in their buckets and ordered in them
//! by their second index; a bucket too long for that is copied as it is and flagged, and the
//! caller has [`PairSort::encode_radix`] sort the pairs again: split into their two indices,
//! sorted stably by j, then by i, with the [`RadixSort`], and joined back.
//! Its bindings and `Params` are [`module`]'s (checked by `tests/bindings.rs`).

use super::Gpu;
use super::radix_sort::RadixSort;
use super::scan::ExclusiveScan;
use super::shader::{Binding, WgslModule, shared_struct, wgsl};

/// The shader, embedded.
const SOURCE: &str = wgsl!("core/pair_sort.wgsl");
const ENTRY_POINTS: &[&str] = &["count", "place", "order", "split", "join"];
/// Workgroup size of every kernel (as in the shader).
const GROUP: u32 = 256;

const PARAMS: Binding = Binding::uniform(0, "params");
const PAIRS: Binding = Binding::read_write(1, "pairs");
const FIRSTS: Binding = Binding::read_write(2, "firsts");
const SECONDS: Binding = Binding::read_write(3, "seconds");
const BUCKETS: Binding = Binding::read_write(4, "buckets");
const RANKS: Binding = Binding::read_write(5, "ranks");
const GROUPED: Binding = Binding::read_write(6, "grouped");
const LONG_BUCKET: Binding = Binding::read_write(7, "long_bucket");

/// The bucketed sort runs where the spheres (one bucket each, cleared and scanned) number at most
/// this many times the pairs; past that the radix sort's passes over the pairs cost less.
const BUCKETS_PER_PAIR: u64 = 64;

/// The pair sort's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "pair_sort",
        SOURCE,
        ENTRY_POINTS,
        &[
            PARAMS,
            PAIRS,
            FIRSTS,
            SECONDS,
            BUCKETS,
            RANKS,
            GROUPED,
            LONG_BUCKET,
        ],
        vec![shared_struct!("Params", Params { count, row })],
    )
}

/// Parameters of every kernel. WGSL twin: `Params` in `wgsl/core/pair_sort.wgsl`.
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

/// The bucketed sort's buffers: a bucket per sphere (and one past the last) for up to
/// `spheres` spheres, a rank and a place per pair for up to `room` pairs, and the long-bucket
/// flag.
struct Buckets {
    buckets: wgpu::Buffer,
    ranks: wgpu::Buffer,
    grouped: wgpu::Buffer,
    long_bucket: wgpu::Buffer,
    spheres: u32,
    room: u32,
}

/// Sorts pair buffers on the GPU; pipelines made once, buffers grown on demand.
pub struct PairSort {
    count: wgpu::ComputePipeline,
    place: wgpu::ComputePipeline,
    order: wgpu::ComputePipeline,
    split: wgpu::ComputePipeline,
    join: wgpu::ComputePipeline,
    scan: ExclusiveScan,
    sort: RadixSort,
    params: wgpu::Buffer,
    buckets: Option<Buckets>,
    halves: Option<Halves>,
}

impl PairSort {
    /// Compiles the shaders and builds the pipelines.
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.own_module("mochi.pair_sort", SOURCE);
        PairSort {
            count: gpu.pipeline("mochi.pair_sort.count", &module, "count"),
            place: gpu.pipeline("mochi.pair_sort.place", &module, "place"),
            order: gpu.pipeline("mochi.pair_sort.order", &module, "order"),
            scan: ExclusiveScan::new(gpu),
            buckets: None,
            split: gpu.pipeline("mochi.pair_sort.split", &module, "split"),
            join: gpu.pipeline("mochi.pair_sort.join", &module, "join"),
            sort: RadixSort::new(gpu),
            params: gpu.uniform("mochi.pair_sort.params", &Params::default()),
            halves: None,
        }
    }

    /// Records into `encoder` the sort of the first `count` pairs of `pairs` (`vec2<u32>`, each
    /// index below `spheres`, i < j), ascending by the first index, then the second. Returns
    /// whether it was bucketed: then it also copies a flag into the pair after the last
    /// (`pairs` must have room for `count + 1`), and where that flag's first word is not 0 a
    /// bucket was too long and the pairs are not yet sorted: the caller records
    /// [`encode_radix`](Self::encode_radix) after reading it.
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        pairs: &wgpu::Buffer,
        count: u32,
        spheres: u32,
    ) -> bool {
        if count < 2 || u64::from(spheres) > BUCKETS_PER_PAIR * u64::from(count) {
            self.encode_radix(gpu, encoder, pairs, count, spheres);
            return false;
        }
        let none = wgpu::BufferUsages::empty();
        if self
            .buckets
            .as_ref()
            .is_none_or(|b| b.spheres < spheres || b.room < count)
        {
            let spheres = spheres.max(self.buckets.as_ref().map_or(0, |b| b.spheres));
            let room = count.max(self.buckets.as_ref().map_or(0, |b| b.room));
            self.buckets = Some(Buckets {
                buckets: gpu.storage(
                    "mochi.pair_sort.buckets",
                    (u64::from(spheres) + 1) * 4,
                    none,
                ),
                ranks: gpu.storage("mochi.pair_sort.ranks", u64::from(room) * 4, none),
                grouped: gpu.storage("mochi.pair_sort.grouped", u64::from(room) * 8, none),
                long_bucket: gpu.storage("mochi.pair_sort.long_bucket", 8, none),
                spheres,
                room,
            });
        }
        let Some(b) = &self.buckets else {
            unreachable!("allocated above")
        };
        let (x, y) = self.set_count(gpu, count);
        // Every kernel reads the parameters, the pairs and the buckets, besides its own.
        let run = |encoder: &mut wgpu::CommandEncoder,
                   label: &str,
                   pipeline: &wgpu::ComputePipeline,
                   own: &[(Binding, &wgpu::Buffer)]| {
            let mut buffers = vec![
                (PARAMS, &self.params),
                (PAIRS, pairs),
                (BUCKETS, &b.buckets),
            ];
            buffers.extend_from_slice(own);
            let group = gpu.bind(label, pipeline, &buffers);
            gpu.dispatch(encoder, label, pipeline, &group, (x, y));
        };
        let bucket_words = u64::from(spheres) + 1;
        encoder.clear_buffer(&b.buckets, 0, Some(bucket_words * 4));
        encoder.clear_buffer(&b.long_bucket, 0, None);
        run(
            encoder,
            "mochi.pair_sort.count",
            &self.count,
            &[(RANKS, &b.ranks)],
        );
        self.scan
            .encode(gpu, encoder, &b.buckets, bucket_words as u32);
        let placed = [(RANKS, &b.ranks), (GROUPED, &b.grouped)];
        run(encoder, "mochi.pair_sort.place", &self.place, &placed);
        let ordered = [(GROUPED, &b.grouped), (LONG_BUCKET, &b.long_bucket)];
        run(encoder, "mochi.pair_sort.order", &self.order, &ordered);
        encoder.copy_buffer_to_buffer(&b.long_bucket, 0, pairs, u64::from(count) * 8, 8);
        true
    }

    /// Writes the kernels' parameters for `count` pairs; returns their dispatch grid.
    fn set_count(&self, gpu: &Gpu, count: u32) -> (u32, u32) {
        let (x, y) = gpu.grid(count, GROUP);
        gpu.write_uniform(
            &self.params,
            &Params {
                count,
                row: x * GROUP,
            },
        );
        (x, y)
    }

    /// Records into `encoder` the radix sort of the first `count` pairs of `pairs` (as
    /// [`encode`](Self::encode) sorts them).
    pub fn encode_radix(
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
        let (x, y) = self.set_count(gpu, count);
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
