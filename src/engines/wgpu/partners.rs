//! The partners of a wgpu step's history slots read back without their springs: the GPU picks
//! each slot's partner into one list (`wgsl/dem/slot_partners.wgsl`), one word of a slot's 8
//! (16 with the load history), so that a snapshot or a rank's count of its contacts reads an
//! eighth of the history or less.

use crate::error::{Error, Result};
use crate::gpu::Gpu;
use crate::gpu::shader::{Binding, WgslModule, shared_struct, wgsl};
use std::ops::Range;

/// The picker's shader, embedded.
const SOURCE: &str = wgsl!("dem/slot_partners.wgsl");
const PARAMS: Binding = Binding::uniform(0, "params");
const ENTRIES: Binding = Binding::read(1, "entries");
const PARTNERS: Binding = Binding::read_write(2, "partners");
/// Workgroup size (as in the shader).
const GROUP: u32 = 256;

/// The picker's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "slot_partners",
        SOURCE,
        &["pick_partners"],
        &[PARAMS, ENTRIES, PARTNERS],
        vec![shared_struct!(
            "PickParams",
            PickParams {
                slots,
                width,
                first,
                row,
            }
        )],
    )
}

/// WGSL twin: `PickParams` in `wgsl/dem/slot_partners.wgsl`.
#[derive(Debug, Clone, Copy, Default, encase::ShaderType)]
struct PickParams {
    slots: u32,
    width: u32,
    first: u32,
    row: u32,
}

/// The pipeline that picks the partners (made at a step's first pick).
pub(crate) struct PartnerPicker {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
}

impl PartnerPicker {
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.own_module("mochi.slot_partners", SOURCE);
        PartnerPicker {
            pipeline: gpu.pipeline("mochi.slot_partners", &module, "pick_partners"),
            params: gpu.uniform("mochi.slot_partners.params", &PickParams::default()),
        }
    }

    /// The partner of every slot of `parts` (each a buffer of entries and the slots it holds,
    /// its first slot at its start; the ranges follow one another from slot 0), `width` words
    /// a slot, in slot order.
    pub fn pick(
        &self,
        gpu: &Gpu,
        parts: &[(&wgpu::Buffer, Range<usize>)],
        width: usize,
    ) -> Result<Vec<u32>> {
        let slots = parts.iter().map(|(_, r)| r.end).max().unwrap_or(0);
        if slots == 0 {
            return Ok(Vec::new());
        }
        let too_many = || Error::Usage(format!("{slots} history slots to read at once"));
        let list = gpu.checked("the list of the history's partners", || {
            gpu.storage(
                "mochi.slot_partners.list",
                slots as u64 * 4,
                wgpu::BufferUsages::empty(),
            )
        })?;
        for (entries, range) in parts.iter().filter(|(_, r)| !r.is_empty()) {
            let count = u32::try_from(range.len()).map_err(|_| too_many())?;
            let groups = gpu.grid(count, GROUP);
            let params = PickParams {
                slots: count,
                width: width as u32,
                first: u32::try_from(range.start).map_err(|_| too_many())?,
                row: groups.0 * GROUP,
            };
            gpu.write_uniform(&self.params, &params);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let bound = [
                (PARAMS, &self.params),
                (ENTRIES, *entries),
                (PARTNERS, &list),
            ];
            gpu.pass(
                &mut encoder,
                "mochi.slot_partners",
                &self.pipeline,
                &bound,
                groups,
            );
            gpu.queue.submit([encoder.finish()]);
        }
        gpu.read(&list, slots)
    }
}
