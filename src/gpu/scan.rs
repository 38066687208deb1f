//! GPU exclusive prefix sum of u32 (wrapping), in place, recorded into the caller's command
//! encoder or compute pass.
//!
//! Reduce-then-scan over levels of [`SCAN_BLOCK`] entries: level 0 is the caller's range, level
//! k + 1 holds one total per block of level k (in a scratch buffer of the scan), down to a level
//! of at most [`SCAN_BLOCK`] entries. A scan runs `reduce` on every level but the last, bottom up
//! (block totals into the next level), then `scan` on every level, top down (each block scans its
//! entries in place and adds the scanned total of the blocks before it, read from the next
//! level). Level 0 is read twice and written once; two levels cover 2^20 entries, three 2^30.
//! Levels of more than 65535 blocks use a 2-D dispatch.
//!
//! The shader is `wgsl/core/scan.wgsl`; its constants mirror the ones here, and its bindings and
//! `Params` are [`module`]'s (checked by `tests/bindings.rs`).

use super::shader::{Binding, WgslModule, shared_struct, wgsl};
use super::{Gpu, workgroups};
use encase::{DynamicUniformBuffer, ShaderSize};
use std::num::NonZeroU64;

/// The shader, embedded.
const SOURCE: &str = wgsl!("core/scan.wgsl", "core/workgroup_scan.wgsl");
const ENTRY_POINTS: &[&str] = &["reduce", "scan"];

const PARAMS: Binding = Binding::uniform(0, "params");
const DATA: Binding = Binding::read_write(1, "data");
const SUMS: Binding = Binding::read_write(2, "sums");

/// The scan's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "scan",
        SOURCE,
        ENTRY_POINTS,
        &[PARAMS, DATA, SUMS],
        vec![shared_struct!(
            "Params",
            Params {
                len,
                src,
                dst,
                blocks,
                in_data,
                has_carry,
            }
        )],
    )
}

/// Entries per workgroup (keep in sync with `BLOCK` in the shader).
pub const SCAN_BLOCK: u32 = 1024;

/// Parameters of one dispatch. WGSL twin: `Params` in `wgsl/core/scan.wgsl`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, encase::ShaderType)]
struct Params {
    /// Entries of the level.
    len: u32,
    /// Offset of the level in its buffer \[u32\].
    src: u32,
    /// Offset of the next level in the block-sum buffer \[u32\]: where `reduce` writes the block
    /// totals and `scan` reads the carries.
    dst: u32,
    /// Blocks of the level (workgroups doing work).
    blocks: u32,
    /// 1: the level is in the caller's buffer; 0: in the block-sum buffer.
    in_data: u32,
    /// `scan`: 1 to add the carries of the next level, 0 on the last level.
    has_carry: u32,
}

/// Size of [`Params`] \[bytes\].
const PARAMS_SIZE: u64 = Params::SHADER_SIZE.get();

/// One level of a scan: `len` entries at `offset` \[u32\] of the caller's range (level 0, offset
/// relative to the bound range) or of the block-sum buffer (the others).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Level {
    offset: u32,
    len: u32,
}

/// The levels of a scan of `len` entries whose level 0 starts at `offset0` of the bound range:
/// each next level holds the totals of the previous one's blocks, up to a level of at most
/// [`SCAN_BLOCK`] entries. Returns the levels and the u32 that levels 1.. take in the block-sum
/// buffer.
fn scan_levels(offset0: u32, len: u32) -> (Vec<Level>, u32) {
    let mut levels = vec![Level {
        offset: offset0,
        len,
    }];
    let mut end = 0;
    while levels[levels.len() - 1].len > SCAN_BLOCK {
        let len = levels[levels.len() - 1].len.div_ceil(SCAN_BLOCK);
        levels.push(Level { offset: end, len });
        end += len;
    }
    (levels, end)
}

/// The two kernels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kernel {
    Reduce,
    Scan,
}

/// One dispatch of a prepared scan.
#[derive(Debug, Clone, Copy)]
struct Step {
    kernel: Kernel,
    /// Dynamic offset of its params slot \[bytes\].
    offset: u32,
    groups: (u32, u32),
}

/// Every dispatch of a scan over `levels`, in order, with its parameters.
fn plan(levels: &[Level], max_per_dim: u32) -> Vec<(Kernel, Params, (u32, u32))> {
    let at = |k: usize| {
        let level = levels[k];
        Params {
            len: level.len,
            src: level.offset,
            blocks: level.len.div_ceil(SCAN_BLOCK),
            in_data: u32::from(k == 0),
            ..Params::default()
        }
    };
    let groups = |k: usize| workgroups(levels[k].len, SCAN_BLOCK, max_per_dim);
    let top = levels.len() - 1;
    let mut out = Vec::with_capacity(2 * top + 1);
    for k in 0..top {
        let params = Params {
            dst: levels[k + 1].offset,
            ..at(k)
        };
        out.push((Kernel::Reduce, params, groups(k)));
    }
    for k in (0..=top).rev() {
        let params = if k < top {
            Params {
                dst: levels[k + 1].offset,
                has_carry: 1,
                ..at(k)
            }
        } else {
            at(k)
        };
        out.push((Kernel::Scan, params, groups(k)));
    }
    out
}

/// A reusable GPU exclusive scan of u32: pipelines plus a scratch buffer for the block sums.
///
/// Scanning `len` entries uses about `len / 1023` u32 of scratch; it grows to the largest `len`
/// seen and is kept.
pub struct ExclusiveScan {
    layout: wgpu::BindGroupLayout,
    reduce: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    /// Block sums of all levels but the first, and its capacity \[u32\].
    sums: Option<(wgpu::Buffer, u32)>,
}

/// A scan of one range, ready to be recorded (any number of times) into compute passes; made by
/// [`ExclusiveScan::prepare`]. It holds its own parameters, bind group and pipelines.
pub struct PreparedScan {
    reduce: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    /// `None` when there is nothing to scan.
    bind: Option<wgpu::BindGroup>,
    steps: Vec<Step>,
}

impl PreparedScan {
    /// Records the scan's dispatches into `pass`. Each recording scans the range again, as it
    /// is when those dispatches run; wgpu orders them after the pass's earlier dispatches that
    /// write it. Recordings share the scan's block-sum scratch with every other scan of the same
    /// [`ExclusiveScan`], so they must run in the order recorded (as they do in one queue).
    pub fn record(&self, pass: &mut wgpu::ComputePass<'_>) {
        let Some(bind) = &self.bind else { return };
        for step in &self.steps {
            pass.set_pipeline(match step.kernel {
                Kernel::Reduce => &self.reduce,
                Kernel::Scan => &self.scan,
            });
            pass.set_bind_group(0, bind, &[step.offset]);
            pass.dispatch_workgroups(step.groups.0, step.groups.1, 1);
        }
    }

    /// Number of dispatches each recording makes (0 for an empty range).
    pub fn dispatches(&self) -> usize {
        self.steps.len()
    }
}

impl ExclusiveScan {
    /// Compiles the shader and builds the pipelines (no scratch yet).
    pub fn new(gpu: &Gpu) -> Self {
        let layout = bind_group_layout(gpu);
        let pipeline_layout = gpu
            .device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("mochi.scan.pipeline_layout"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
        let module = gpu.own_module("mochi.scan.module", SOURCE);
        let make = |label, entry| {
            gpu.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(label),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some(entry),
                    // Both kernels write each workgroup variable before reading it.
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &[],
                        zero_initialize_workgroup_memory: false,
                    },
                    cache: None,
                })
        };
        ExclusiveScan {
            reduce: make("mochi.scan.reduce", "reduce"),
            scan: make("mochi.scan.scan", "scan"),
            layout,
            sums: None,
        }
    }

    /// Records into `encoder` an in-place exclusive prefix sum of the first `len` u32 of `data`
    /// (STORAGE|COPY_SRC|COPY_DST usage), so `data[i]` becomes the sum of the old `data[0..i]`
    /// (wrapping u32 arithmetic). One compute pass; `len == 0` records nothing.
    ///
    /// Parameters go into a uniform buffer of this call, so several scans may be recorded before
    /// one submit (into one encoder or several), as long as they run in the order recorded
    /// (they share the block-sum scratch). `4 len` bytes must fit in
    /// `max_storage_buffer_binding_size`, otherwise wgpu reports a validation error.
    ///
    /// # Panics
    /// If `data` holds fewer than `len` u32 (a caller bug).
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        data: &wgpu::Buffer,
        len: u32,
    ) {
        self.encode_range(gpu, encoder, data, 0, len);
    }

    /// As [`encode`](Self::encode), for the `len` u32 of `data` from `offset` \[u32\] on: only
    /// that range changes. Only the range (widened down to the device's storage offset
    /// alignment) is bound, so it is the range that must fit in `max_storage_buffer_binding_size`.
    ///
    /// # Panics
    /// If `data` holds fewer than `offset + len` u32, or `offset + len` is within 2 * 1024 of
    /// 2^32 (caller bugs).
    pub fn encode_range(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        data: &wgpu::Buffer,
        offset: u32,
        len: u32,
    ) {
        let prepared = self.prepare(gpu, data, offset, len);
        if prepared.dispatches() == 0 {
            return;
        }
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("mochi.scan.pass"),
            timestamp_writes: None,
        });
        prepared.record(&mut pass);
    }

    /// Prepares a scan of the `len` u32 of `data` from `offset` \[u32\] on, for recording into
    /// compute passes (several times if wanted, e.g. once per pass of a radix sort): writes its
    /// parameters with `queue.write_buffer`, grows the block-sum scratch if needed and makes its
    /// bind group. Same conditions and panics as [`encode_range`](Self::encode_range).
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        data: &wgpu::Buffer,
        offset: u32,
        len: u32,
    ) -> PreparedScan {
        let end = u64::from(offset) + u64::from(len);
        assert!(
            data.size() >= end * 4,
            "mochi.scan: u32 {offset}..{end} do not fit in data ({} bytes)",
            data.size()
        );
        assert!(
            end <= u64::from(u32::MAX - 2 * SCAN_BLOCK),
            "mochi.scan: u32 {offset}..{end} reach too close to 2^32"
        );
        let mut prepared = PreparedScan {
            reduce: self.reduce.clone(),
            scan: self.scan.clone(),
            bind: None,
            steps: Vec::new(),
        };
        if len == 0 {
            return prepared;
        }

        // Bind from `offset` rounded down to the storage offset alignment.
        let align = u64::from(gpu.limits.min_storage_buffer_offset_alignment).max(4);
        let bind_at = (u64::from(offset) * 4) / align * align;
        let offset0 = offset - (bind_at / 4) as u32;
        let (levels, sums_len) = scan_levels(offset0, len);
        let sums = self.reserve(gpu, sums_len);

        let dispatches = plan(&levels, gpu.limits.max_compute_workgroups_per_dimension);
        let align = u64::from(gpu.limits.min_uniform_buffer_offset_alignment).max(1);
        let mut slots = DynamicUniformBuffer::new_with_alignment(Vec::new(), align);
        let offsets: Vec<u32> = dispatches
            .iter()
            .map(|(_, p, _)| {
                let at = slots.write(p).expect("a Vec grows to any number of slots");
                u32::try_from(at).expect("the params buffer of one scan is far below 4 GiB")
            })
            .collect();
        let bytes = slots.into_inner();
        let params = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("mochi.scan.params"),
            size: bytes.len() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue.write_buffer(&params, 0, &bytes);

        let binding = |buffer, offset, size| {
            wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer,
                offset,
                size: NonZeroU64::new(size),
            })
        };
        prepared.bind = Some(gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("mochi.scan.bind"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: PARAMS.binding,
                    resource: binding(&params, 0, PARAMS_SIZE),
                },
                wgpu::BindGroupEntry {
                    binding: DATA.binding,
                    resource: binding(data, bind_at, end * 4 - bind_at),
                },
                wgpu::BindGroupEntry {
                    binding: SUMS.binding,
                    resource: sums.as_entire_binding(),
                },
            ],
        }));
        prepared.steps = dispatches
            .iter()
            .zip(offsets)
            .map(|(&(kernel, _, groups), offset)| Step {
                kernel,
                offset,
                groups,
            })
            .collect();
        prepared
    }

    /// The block-sum scratch, grown to hold at least `len` u32.
    fn reserve(&mut self, gpu: &Gpu, len: u32) -> wgpu::Buffer {
        let have = self.sums.as_ref().map_or(0, |s| s.1);
        if self.sums.is_none() || have < len {
            let len = len.max(have).max(4);
            let buffer = gpu.storage(
                "mochi.scan.sums",
                u64::from(len) * 4,
                wgpu::BufferUsages::empty(),
            );
            self.sums = Some((buffer, len));
        }
        let Some((buffer, _)) = &self.sums else {
            unreachable!("allocated above")
        };
        buffer.clone()
    }
}

/// The bind-group layout of both kernels; the shader's `@group(0)` bindings.
fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("mochi.scan.bind_group_layout"),
            entries: &[
                PARAMS.layout_entry(true, NonZeroU64::new(PARAMS_SIZE)),
                DATA.layout_entry(false, None),
                SUMS.layout_entry(false, None),
            ],
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens(levels: &[Level]) -> Vec<u32> {
        levels.iter().map(|l| l.len).collect()
    }

    #[test]
    fn levels_end_at_one_block() {
        let (levels, sums) = scan_levels(3, 16);
        assert_eq!(levels, vec![Level { offset: 3, len: 16 }]);
        assert_eq!(sums, 0);
        let (levels, sums) = scan_levels(0, SCAN_BLOCK);
        assert_eq!(lens(&levels), vec![SCAN_BLOCK]);
        assert_eq!(sums, 0);
        let (levels, sums) = scan_levels(0, SCAN_BLOCK + 1);
        assert_eq!(lens(&levels), vec![SCAN_BLOCK + 1, 2]);
        assert_eq!(sums, 2);
        let (levels, sums) = scan_levels(5, 1 << 27);
        assert_eq!(lens(&levels), vec![1 << 27, 1 << 17, 128]);
        assert_eq!(levels[1].offset, 0);
        assert_eq!(levels[2].offset, 1 << 17);
        assert_eq!(sums, (1 << 17) + 128);
    }

    #[test]
    fn plan_reduces_up_then_scans_down() {
        let (levels, _) = scan_levels(0, 1 << 27);
        let steps = plan(&levels, 65535);
        let kinds: Vec<_> = steps.iter().map(|s| s.0).collect();
        use Kernel::{Reduce, Scan};
        assert_eq!(kinds, vec![Reduce, Reduce, Scan, Scan, Scan]);
        // Level 0 has 131072 blocks: a 2-D grid.
        assert_eq!(steps[0].2, (65535, 3));
        assert_eq!(steps[0].1.blocks, 1 << 17);
        assert_eq!((steps[0].1.in_data, steps[0].1.dst), (1, 0));
        assert_eq!((steps[1].1.in_data, steps[1].1.dst), (0, 1 << 17));
        // The top level scans without carries; the others add the next level's.
        assert_eq!((steps[2].1.len, steps[2].1.has_carry), (128, 0));
        assert_eq!((steps[3].1.len, steps[3].1.has_carry), (1 << 17, 1));
        assert_eq!(
            (steps[4].1.len, steps[4].1.has_carry, steps[4].1.in_data),
            (1 << 27, 1, 1)
        );
        let (levels, _) = scan_levels(0, 7);
        let steps = plan(&levels, 65535);
        assert_eq!(steps.len(), 1);
        assert_eq!((steps[0].0, steps[0].1.has_carry), (Kernel::Scan, 0));
    }
}
