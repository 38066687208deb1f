//! The history a granular batch begins from, kept for a redo with its held slots alone: the GPU
//! copies each sphere's first `held` slots of the old history into the saved copy
//! (`wgsl/dem/save_held.wgsl`), where copying whole buffers moved every slot of every row, most
//! of them empty.

use crate::gpu::Gpu;
use crate::gpu::shader::{Binding, WgslModule, shared_struct, wgsl};

/// The saver's shader, embedded.
const SOURCE: &str = wgsl!("dem/save_held.wgsl");
const PARAMS: Binding = Binding::uniform(0, "params");
const HELD: Binding = Binding::read(1, "held");
const FROM: Binding = Binding::read(2, "from_slots");
const TO: Binding = Binding::read_write(3, "to_slots");
/// Workgroup size (as in the shader).
const GROUP: u32 = 256;

/// The saver's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "save_held",
        SOURCE,
        &["save_held"],
        &[PARAMS, HELD, FROM, TO],
        vec![shared_struct!(
            "SaveParams",
            SaveParams {
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

/// WGSL twin: `SaveParams` in `wgsl/dem/save_held.wgsl`.
#[derive(Debug, Clone, Copy, Default, PartialEq, encase::ShaderType)]
struct SaveParams {
    first: u32,
    rows: u32,
    slots: u32,
    vectors: u32,
    row: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

/// One part of a history to save: its entries, the saved copy's, and its rows (the first
/// `rows.start` of the history are in the parts before it).
pub(crate) struct SavedPart<'a> {
    pub from: &'a wgpu::Buffer,
    pub to: &'a wgpu::Buffer,
    pub rows: std::ops::Range<u32>,
}

/// The pipeline that saves the held slots (made at a step's first batch) and one parameter
/// uniform a part (a batch records every part's pass before it is submitted).
pub(crate) struct HeldSaver {
    pipeline: wgpu::ComputePipeline,
    params: Vec<(wgpu::Buffer, SaveParams)>,
}

impl HeldSaver {
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.own_module("mochi.save_held", SOURCE);
        HeldSaver {
            pipeline: gpu.pipeline("mochi.save_held", &module, "save_held"),
            params: Vec::new(),
        }
    }

    /// Records into `encoder` the copy of each row's first `held[row]` slots (`slots` a row,
    /// `entry_bytes` a slot, a multiple of 16) of every part of `parts`.
    pub fn record(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        held: &wgpu::Buffer,
        parts: &[SavedPart<'_>],
        (slots, entry_bytes): (u32, u64),
    ) {
        for (k, part) in parts.iter().enumerate() {
            let rows = part.rows.end - part.rows.start;
            // Every row's slots are within one part, so their count fits a u32 as its
            // binding's size does.
            let threads = rows * slots;
            if threads == 0 {
                continue;
            }
            let groups = gpu.grid(threads, GROUP);
            let params = SaveParams {
                first: part.rows.start,
                rows,
                slots,
                vectors: (entry_bytes / 16) as u32,
                row: groups.0 * GROUP,
                ..SaveParams::default()
            };
            if self.params.len() <= k {
                let buffer = gpu.uniform("mochi.save_held.params", &params);
                self.params.push((buffer, params));
            } else if self.params[k].1 != params {
                gpu.write_uniform(&self.params[k].0, &params);
                self.params[k].1 = params;
            }
            let bound = [
                (PARAMS, &self.params[k].0),
                (HELD, held),
                (FROM, part.from),
                (TO, part.to),
            ];
            gpu.pass(encoder, "mochi.save_held", &self.pipeline, &bound, groups);
        }
    }
}
