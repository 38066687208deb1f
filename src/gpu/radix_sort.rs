//! GPU radix sort of (u32 key, u32 value) pairs, recorded into the caller's command encoder.
//!
//! An LSD radix sort with 4-bit digits (`ceil(key_bits / 4)` passes). Each pass runs, in one
//! compute pass of the caller's encoder:
//!
//! 1. `histogram`: every sort block of [`BLOCK`] pairs (one workgroup of 128 threads, 16
//!    consecutive pairs per thread) counts its digits;
//! 2. an exclusive scan of those counts in (digit, block) order, by [`ExclusiveScan`] (prepared
//!    once per sort and recorded into the same compute pass);
//! 3. `scatter`: every block ranks its pairs per digit with per-thread counters and a
//!    workgroup-memory prefix sum (stable, no subgroup operations) and writes them to their place.
//!
//! Passes ping-pong between the caller's buffers and two scratch buffers; after an odd number of
//! passes the result is copied back, so it always ends in the caller's buffers.
//! The shader is `wgsl/core/radix_sort.wgsl`; its constants mirror the ones here, and its bindings
//! and `Params` are [`module`]'s (checked by `tests/bindings.rs`).

use super::scan::{ExclusiveScan, PreparedScan};
use super::shader::{Binding, WgslModule, shared_struct, wgsl};
use super::{Gpu, workgroups};
use encase::{DynamicUniformBuffer, ShaderSize};
use std::num::NonZeroU64;

/// The shader, embedded.
const SOURCE: &str = wgsl!("core/radix_sort.wgsl", "core/workgroup_scan.wgsl");
const ENTRY_POINTS: &[&str] = &["histogram", "scatter"];

const PARAMS: Binding = Binding::uniform(0, "params");
/// A pass reads the pairs from `KEYS_IN`/`VALUES_IN` and writes them to `KEYS_OUT`/`VALUES_OUT`.
const KEYS_IN: Binding = Binding::read(1, "keys_in");
const VALUES_IN: Binding = Binding::read(2, "values_in");
const KEYS_OUT: Binding = Binding::read_write(3, "keys_out");
const VALUES_OUT: Binding = Binding::read_write(4, "values_out");
const HIST: Binding = Binding::read_write(5, "hist");

/// The sort's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "radix_sort",
        SOURCE,
        ENTRY_POINTS,
        &[PARAMS, KEYS_IN, VALUES_IN, KEYS_OUT, VALUES_OUT, HIST],
        vec![shared_struct!(
            "Params",
            Params {
                n,
                shift,
                key_mask,
                blocks,
            }
        )],
    )
}

/// Bits per digit, i.e. per pass (keep in sync with `RADIX_BITS` in the shader).
const RADIX_BITS: u32 = 4;
/// Pairs per sort block, one workgroup each (keep in sync with `BLOCK` in the shader).
pub const BLOCK: u32 = 2048;

/// Parameters of one pass (its histogram and scatter). WGSL twin: `Params` in
/// `wgsl/core/radix_sort.wgsl`.
#[derive(Debug, Clone, Copy, Default, encase::ShaderType)]
struct Params {
    /// Number of pairs to sort.
    n: u32,
    /// Bit of the key where this pass's digit starts.
    shift: u32,
    /// Mask of the key bits that take part in the sort.
    key_mask: u32,
    /// Sort blocks (workgroups doing work).
    blocks: u32,
}

/// Size of [`Params`] \[bytes\].
const PARAMS_SIZE: u64 = Params::SHADER_SIZE.get();

/// Scratch space, grown on demand.
struct Scratch {
    /// Keys between passes (capacity `pairs`).
    keys: wgpu::Buffer,
    /// Values between passes (capacity `pairs`).
    values: wgpu::Buffer,
    /// Capacity of `keys` and `values` [pairs].
    pairs: u32,
    /// Digit counts, scanned in place.
    hist: wgpu::Buffer,
    /// Capacity of `hist` \[u32\].
    hist_len: u32,
}

/// A reusable GPU radix sorter of (u32 key, u32 value) pairs: pipelines plus scratch buffers.
///
/// Sorting `n` pairs uses `8 n` bytes of scratch for keys and values and about `n / 128` u32
/// for digit counts (plus the scan's block sums); the scratch grows to the largest `n` seen and
/// is kept.
pub struct RadixSort {
    layout: wgpu::BindGroupLayout,
    histogram: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    scan: ExclusiveScan,
    scratch: Option<Scratch>,
}

impl RadixSort {
    /// Compiles the shader and builds the pipelines (no scratch yet).
    pub fn new(gpu: &Gpu) -> Self {
        let layout = bind_group_layout(gpu);
        let pipeline_layout = gpu
            .device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("mochi.sort.pipeline_layout"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
        let module = gpu.own_module("mochi.sort.module", SOURCE);
        let make = |label, entry| pipeline(gpu, &pipeline_layout, &module, label, entry);
        RadixSort {
            histogram: make("mochi.sort.histogram", "histogram"),
            scatter: make("mochi.sort.scatter", "scatter"),
            scan: ExclusiveScan::new(gpu),
            layout,
            scratch: None,
        }
    }

    /// Records into `encoder` the commands that sort the first `n` (key, value) pairs of
    /// `keys`/`values` (u32 each, STORAGE|COPY_SRC|COPY_DST usage) by the low `key_bits` bits of
    /// the key, ascending and stable; afterwards the sorted pairs are in `keys`/`values` again.
    /// Allocates or grows its scratch buffers as needed.
    ///
    /// - Bits of the keys above `key_bits` are ignored for ordering (masked in the shader) and
    ///   kept: the keys come out as they went in, only reordered. `key_bits` above 32 counts as
    ///   32; `key_bits == 0` or `n == 0` records nothing.
    /// - Parameters go into a uniform buffer of this call, written with `queue.write_buffer`,
    ///   so several calls may be recorded before one submit (into one encoder or several), as long
    ///   as they run in the order recorded (they share the scratch buffers).
    /// - `4 n` bytes must fit in `max_storage_buffer_binding_size` (128 MiB by default: 32 Mi
    ///   pairs); otherwise wgpu reports a validation error.
    ///
    /// # Panics
    /// If `keys` or `values` holds fewer than `n` u32 (a caller bug).
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        keys: &wgpu::Buffer,
        values: &wgpu::Buffer,
        n: u32,
        key_bits: u32,
    ) {
        let sort = self.prepare(gpu, keys, values, n, key_bits);
        if sort.passes.is_empty() {
            return;
        }
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("mochi.sort.pass"),
                timestamp_writes: None,
            });
            sort.record(&mut pass);
        }
        if let Some((sorted_keys, sorted_values)) = &sort.in_scratch {
            let bytes = u64::from(n) * 4;
            encoder.copy_buffer_to_buffer(sorted_keys, 0, keys, 0, bytes);
            encoder.copy_buffer_to_buffer(sorted_values, 0, values, 0, bytes);
        }
    }

    /// Prepares the sort [`encode`](Self::encode) records, for recording into compute passes
    /// (any number of times, each sorting the pairs as they are then): writes its parameters,
    /// grows the scratch if needed and makes its bind groups. Unlike `encode` it copies nothing
    /// back: after an odd number of passes the sorted pairs are in the scratch buffers
    /// ([`PreparedSort::sorted`] says where). Same conditions and panics as `encode`.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        keys: &wgpu::Buffer,
        values: &wgpu::Buffer,
        n: u32,
        key_bits: u32,
    ) -> PreparedSort {
        let bytes = u64::from(n) * 4;
        assert!(
            keys.size() >= bytes && values.size() >= bytes,
            "mochi.sort: {n} pairs do not fit in keys ({} bytes) and values ({} bytes)",
            keys.size(),
            values.size()
        );
        let key_bits = key_bits.min(32);
        let mut prepared = PreparedSort {
            histogram: self.histogram.clone(),
            scatter: self.scatter.clone(),
            scan: None,
            binds: None,
            passes: Vec::new(),
            groups: (0, 0),
            sorted: (keys.clone(), values.clone()),
            in_scratch: None,
        };
        if n == 0 || key_bits == 0 {
            return prepared;
        }
        let hist_len = n.div_ceil(BLOCK) * (1 << RADIX_BITS);
        self.reserve(gpu, n, hist_len);
        let Some(scratch) = &self.scratch else {
            unreachable!("reserve() always leaves scratch allocated");
        };
        // Every pass scans the same counts, so one prepared scan serves them all.
        let scan = self.scan.prepare(gpu, &scratch.hist, 0, hist_len);

        let passes = plan(n, key_bits);
        let (params, offsets) = params_buffer(gpu, &passes);
        let from_caller = self.bind(
            gpu,
            "mochi.sort.bind.caller_to_scratch",
            &params,
            [keys, values, &scratch.keys, &scratch.values],
            bytes,
            &scratch.hist,
        );
        let from_scratch = self.bind(
            gpu,
            "mochi.sort.bind.scratch_to_caller",
            &params,
            [&scratch.keys, &scratch.values, keys, values],
            bytes,
            &scratch.hist,
        );
        if offsets.len() % 2 == 1 {
            let in_scratch = (scratch.keys.clone(), scratch.values.clone());
            prepared.sorted = in_scratch.clone();
            prepared.in_scratch = Some(in_scratch);
        }
        prepared.groups = workgroups(n, BLOCK, gpu.limits.max_compute_workgroups_per_dimension);
        prepared.scan = Some(scan);
        prepared.binds = Some([from_caller, from_scratch]);
        prepared.passes = offsets;
        prepared
    }

    /// Makes sure the scratch holds `pairs` pairs and `hist_len` u32 of counts.
    fn reserve(&mut self, gpu: &Gpu, pairs: u32, hist_len: u32) {
        let (have_pairs, have_hist) = self
            .scratch
            .as_ref()
            .map_or((0, 0), |s| (s.pairs, s.hist_len));
        if have_pairs >= pairs && have_hist >= hist_len {
            return;
        }
        let pairs = pairs.max(have_pairs);
        let hist_len = hist_len.max(have_hist);
        let none = wgpu::BufferUsages::empty();
        let bytes = u64::from(pairs) * 4;
        self.scratch = Some(Scratch {
            keys: gpu.storage("mochi.sort.scratch_keys", bytes, none),
            values: gpu.storage("mochi.sort.scratch_values", bytes, none),
            pairs,
            hist: gpu.storage("mochi.sort.hist", u64::from(hist_len) * 4, none),
            hist_len,
        });
    }

    /// A bind group reading pairs from `io[0..2]` and writing them to `io[2..4]` (`bytes` of
    /// each), with the params slots and the count buffer.
    fn bind(
        &self,
        gpu: &Gpu,
        label: &str,
        params: &wgpu::Buffer,
        io: [&wgpu::Buffer; 4],
        bytes: u64,
        hist: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let sized = |buffer, size| {
            wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer,
                offset: 0,
                size: NonZeroU64::new(size),
            })
        };
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: PARAMS.binding,
            resource: sized(params, PARAMS_SIZE),
        }];
        for (at, buffer) in [KEYS_IN, VALUES_IN, KEYS_OUT, VALUES_OUT]
            .into_iter()
            .zip(io)
        {
            entries.push(wgpu::BindGroupEntry {
                binding: at.binding,
                resource: sized(buffer, bytes),
            });
        }
        entries.push(wgpu::BindGroupEntry {
            binding: HIST.binding,
            resource: hist.as_entire_binding(),
        });
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &self.layout,
            entries: &entries,
        })
    }
}

/// A sort ready to be recorded (any number of times) into compute passes; made by
/// [`RadixSort::prepare`]. It holds its own parameters, bind groups and pipelines, and shares
/// the scratch buffers of its [`RadixSort`] (so recordings of sorts of one sorter must run in
/// the order recorded, as they do in one queue).
pub struct PreparedSort {
    histogram: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    /// `None` when there is nothing to sort.
    scan: Option<PreparedScan>,
    /// Binds reading the caller's buffers (even passes) and the scratch (odd passes).
    binds: Option<[wgpu::BindGroup; 2]>,
    /// Dynamic offset of each pass's parameters.
    passes: Vec<u32>,
    groups: (u32, u32),
    /// Where the sorted keys and values are after a recording.
    sorted: (wgpu::Buffer, wgpu::Buffer),
    /// The scratch keys and values, where the sort ends after an odd number of passes.
    in_scratch: Option<(wgpu::Buffer, wgpu::Buffer)>,
}

impl PreparedSort {
    /// Records the sort's dispatches into `pass`: every pass's histogram, scan and scatter.
    pub fn record(&self, pass: &mut wgpu::ComputePass<'_>) {
        let (Some(scan), Some(binds)) = (&self.scan, &self.binds) else {
            return;
        };
        for (k, &offset) in self.passes.iter().enumerate() {
            // Even passes read the caller's buffers, odd ones the scratch.
            let bind = &binds[k % 2];
            let sort = |pass: &mut wgpu::ComputePass<'_>, pipeline| {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, bind, &[offset]);
                pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
            };
            sort(pass, &self.histogram);
            scan.record(pass);
            sort(pass, &self.scatter);
        }
    }

    /// The buffers that hold the sorted keys and values after a recording: the caller's after
    /// an even number of passes (or none), else the scratch.
    pub fn sorted(&self) -> (&wgpu::Buffer, &wgpu::Buffer) {
        (&self.sorted.0, &self.sorted.1)
    }

    /// Passes each recording makes (one per digit of the keys).
    pub fn passes(&self) -> usize {
        self.passes.len()
    }
}

/// The bind-group layout both kernels share; the shader's `@group(0)` bindings.
fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let storage = |at: Binding| at.layout_entry(false, None);
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("mochi.sort.bind_group_layout"),
            entries: &[
                PARAMS.layout_entry(true, NonZeroU64::new(PARAMS_SIZE)),
                storage(KEYS_IN),
                storage(VALUES_IN),
                storage(KEYS_OUT),
                storage(VALUES_OUT),
                storage(HIST),
            ],
        })
}

/// A compute pipeline for `entry` with the shared layout. Every kernel writes each workgroup
/// variable before reading it, so wgpu's zero-initialisation of workgroup memory is skipped.
fn pipeline(
    gpu: &Gpu,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    label: &str,
    entry: &str,
) -> wgpu::ComputePipeline {
    gpu.device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(layout),
            module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &[],
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        })
}

/// A uniform buffer of this call holding each pass's parameters, each at its dynamic offset
/// (aligned to the device's uniform offset alignment), and those offsets.
fn params_buffer(gpu: &Gpu, passes: &[Params]) -> (wgpu::Buffer, Vec<u32>) {
    let align = u64::from(gpu.limits.min_uniform_buffer_offset_alignment).max(1);
    let mut slots = DynamicUniformBuffer::new_with_alignment(Vec::new(), align);
    let offsets = passes
        .iter()
        .map(|p| {
            let at = slots.write(p).expect("a Vec grows to any number of slots");
            u32::try_from(at).expect("the params buffer of one sort is far below 4 GiB")
        })
        .collect();
    let bytes = slots.into_inner();
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("mochi.sort.params"),
        size: bytes.len() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    gpu.queue.write_buffer(&buffer, 0, &bytes);
    (buffer, offsets)
}

/// The parameters of each pass of a sort of `n` pairs by `key_bits` (1..=32) bits, in order;
/// the histogram and the scatter of a pass share them.
fn plan(n: u32, key_bits: u32) -> Vec<Params> {
    let key_mask = if key_bits >= 32 {
        u32::MAX
    } else {
        (1u32 << key_bits) - 1
    };
    (0..key_bits.div_ceil(RADIX_BITS))
        .map(|pass| Params {
            n,
            shift: pass * RADIX_BITS,
            key_mask,
            blocks: n.div_ceil(BLOCK),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_pass_per_digit() {
        let passes = plan(5000, 30);
        let shifts: Vec<u32> = passes.iter().map(|p| p.shift).collect();
        assert_eq!(shifts, vec![0, 4, 8, 12, 16, 20, 24, 28]);
        assert!(
            passes
                .iter()
                .all(|p| p.n == 5000 && p.blocks == 3 && p.key_mask == (1 << 30) - 1)
        );
        assert_eq!(plan(1, 32)[0].key_mask, u32::MAX);
        assert_eq!(plan(1, 1).len(), 1);
    }
}
