//! The slots each sphere holds of a granular step's history, apart from the empty ones
//! (`wgsl/dem/held_slots.wgsl`): copied to the saved history a batch's redo begins from, or
//! packed row after row for the host to read back (whole, or their partners alone, one word of a
//! slot's 8 or 16, for a snapshot's or a rank's count of its contacts), where whole buffers moved
//! every slot of every row, most of them empty.

use crate::error::{Result, try_vec};
use crate::gpu::shader::{Binding, WgslModule, shared_struct, wgsl};
use crate::gpu::{Gpu, Staging};
use std::ops::Range;
use std::sync::Mutex;

/// The kernels' shader, embedded.
const SOURCE: &str = wgsl!("dem/held_slots.wgsl");
const PARAMS: Binding = Binding::uniform(0, "params");
const HELD: Binding = Binding::read(1, "held");
const FROM: Binding = Binding::read(2, "from_slots");
const TO: Binding = Binding::read_write(3, "to_slots");
const PACKED_AT: Binding = Binding::read(4, "packed_at");
const PARTNERS: Binding = Binding::read_write(5, "partners");
/// Workgroup size (as in the shader).
const GROUP: u32 = 256;

/// The kernels' WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "held_slots",
        SOURCE,
        &["save_held", "pack_held", "pick_held"],
        &[PARAMS, HELD, FROM, TO, PACKED_AT, PARTNERS],
        vec![shared_struct!(
            "SlotParams",
            SlotParams {
                first,
                rows,
                slots,
                vectors,
                row,
                pad0,
                pad1,
                pad2,
            }
        )],
    )
}

/// WGSL twin: `SlotParams` in `wgsl/dem/held_slots.wgsl`.
#[derive(Debug, Clone, Copy, Default, PartialEq, encase::ShaderType)]
struct SlotParams {
    first: u32,
    rows: u32,
    slots: u32,
    vectors: u32,
    row: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

/// One part of a history: its entries' buffer and its rows (the first `rows.start` rows of
/// the history are in the parts before it).
pub(crate) struct Part<'a> {
    pub entries: &'a wgpu::Buffer,
    pub rows: Range<u32>,
}

/// A history's shape: slots a row and bytes a slot (a multiple of 16).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shape {
    pub slots: u32,
    pub entry_bytes: u64,
}

/// What a read-back of the held slots takes of each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Take {
    /// Every word.
    Slots,
    /// The partner's stable id alone.
    Partners,
}

/// The kernels (made at a step's first use) and the saves' parameters, one uniform a part (a
/// batch records every part's pass before it is submitted).
pub(crate) struct HeldSlots {
    save: wgpu::ComputePipeline,
    pack: wgpu::ComputePipeline,
    pick: wgpu::ComputePipeline,
    saving: Mutex<Vec<(wgpu::Buffer, SlotParams)>>,
}

impl HeldSlots {
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.own_module("mochi.held_slots", SOURCE);
        HeldSlots {
            save: gpu.pipeline("mochi.held_slots.save", &module, "save_held"),
            pack: gpu.pipeline("mochi.held_slots.pack", &module, "pack_held"),
            pick: gpu.pipeline("mochi.held_slots.pick", &module, "pick_held"),
            saving: Mutex::new(Vec::new()),
        }
    }

    /// Records into `encoder` the copy of each row's first `held[row]` slots of every part of
    /// `parts` to the same places of its buffer in `saved`.
    pub fn save(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        held: &wgpu::Buffer,
        (parts, saved): (&[Part<'_>], &[wgpu::Buffer]),
        shape: Shape,
    ) {
        let mut saving = self.saving.lock().unwrap_or_else(|e| e.into_inner());
        for (k, (part, to)) in parts.iter().zip(saved).enumerate() {
            let Some((params, groups)) = params_of(gpu, part, shape) else {
                continue;
            };
            if saving.len() <= k {
                saving.push((gpu.uniform("mochi.held_slots.save", &params), params));
            } else if saving[k].1 != params {
                gpu.write_uniform(&saving[k].0, &params);
                saving[k].1 = params;
            }
            let bound = [
                (PARAMS, &saving[k].0),
                (HELD, held),
                (FROM, part.entries),
                (TO, to),
            ];
            gpu.pass(encoder, "mochi.held_slots.save", &self.save, &bound, groups);
        }
    }

    /// What `take` asks of the held slots of `parts` (`held`: each row's count, at most a
    /// row's slots, as on the device in `held_rows`), row after row, read back.
    pub fn pack(
        &self,
        gpu: &Gpu,
        (held, held_rows): (&[u32], &wgpu::Buffer),
        parts: &[Part<'_>],
        (shape, take): (Shape, Take),
    ) -> Result<Vec<u32>> {
        // Each row's first slot in its part's list, and each list's length.
        let mut packed_at = Vec::with_capacity(held.len());
        let mut lengths = Vec::with_capacity(parts.len());
        for part in parts {
            let rows = &held[part.rows.start as usize..part.rows.end as usize];
            let mut at = 0u32;
            packed_at.extend(rows.iter().map(|&c| {
                let first = at;
                at += c;
                first
            }));
            lengths.push(at as u64);
        }
        let total: u64 = lengths.iter().sum();
        let words = match take {
            Take::Slots => (shape.entry_bytes / 4) as usize,
            Take::Partners => 1,
        };
        let mut packed = try_vec(total as usize * words, || {
            format!("the contact history's {total} held slots")
        })?;
        let none = wgpu::BufferUsages::empty();
        let places = gpu.checked("the places of the held slots", || {
            gpu.storage(
                "mochi.held_slots.packed_at",
                held.len().max(1) as u64 * 4,
                none,
            )
        })?;
        gpu.queue
            .write_buffer(&places, 0, bytemuck::cast_slice(&packed_at));
        // One staging buffer for every part's list, replaced where a later list is longer.
        let mut staging = Staging::default();
        for (part, &length) in parts.iter().zip(&lengths) {
            let Some((params, groups)) = params_of(gpu, part, shape).filter(|_| length > 0) else {
                continue;
            };
            let list = gpu.checked("the list of the held slots", || {
                gpu.storage("mochi.held_slots.list", length * words as u64 * 4, none)
            })?;
            let uniform = gpu.uniform("mochi.held_slots.pack", &params);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let (pipeline, list_binding) = match take {
                Take::Slots => (&self.pack, TO),
                Take::Partners => (&self.pick, PARTNERS),
            };
            let bound = [
                (PARAMS, &uniform),
                (HELD, held_rows),
                (FROM, part.entries),
                (list_binding, &list),
                (PACKED_AT, &places),
            ];
            gpu.pass(
                &mut encoder,
                "mochi.held_slots.pack",
                pipeline,
                &bound,
                groups,
            );
            gpu.queue.submit([encoder.finish()]);
            let count = length as usize * words;
            gpu.read_through_with(&mut staging, &list, count, |values: &[u32]| {
                packed.extend_from_slice(values)
            })?;
        }
        Ok(packed)
    }
}

/// The parameters and dispatch of `part`'s pass (`None`: it has no slots).
fn params_of(gpu: &Gpu, part: &Part<'_>, shape: Shape) -> Option<(SlotParams, (u32, u32))> {
    let rows = part.rows.end - part.rows.start;
    // A part's slots fit a binding, so their count fits a u32.
    let threads = rows * shape.slots;
    (threads > 0).then(|| {
        let groups = gpu.grid(threads, GROUP);
        let params = SlotParams {
            first: part.rows.start,
            rows,
            slots: shape.slots,
            vectors: (shape.entry_bytes / 16) as u32,
            row: groups.0 * GROUP,
            ..SlotParams::default()
        };
        (params, groups)
    })
}
