//! A flow event's look at a wgpu engine's state without reading every sphere back
//! (`wgsl/dem/flow_scan.wgsl`): one pass lists the spheres that leave and those near the inflows,
//! the two things an event of the flow step needs to remove and insert.

use crate::engines::common::flow::{FlowQuery, Leaving, Scan};
use crate::error::Result;
use crate::gpu::Gpu;
use crate::gpu::shader::{Binding, WgslModule, shared_struct, wgsl};
use glam::Vec3;

/// The shader, embedded.
const SOURCE: &str = wgsl!("dem/flow_scan.wgsl");
const ENTRY_POINT: &str = "flow_scan";
/// Workgroup size (as in the shader).
const GROUP: u32 = 256;
/// Entries of each list at first (they grow to what an event needs).
const FIRST_ROOM: u32 = 4096;

const PARAMS: Binding = Binding::uniform(0, "params");
const POS: Binding = Binding::read(1, "pos");
const BOXES: Binding = Binding::read(2, "boxes");
const FOUND: Binding = Binding::read_write(3, "found");
const SPIN: Binding = Binding::read(4, "spin");

/// The scan's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "flow_scan",
        SOURCE,
        &[ENTRY_POINT],
        &[PARAMS, POS, BOXES, FOUND, SPIN],
        vec![shared_struct!(
            "FlowParams",
            FlowParams {
                n,
                row,
                near_boxes,
                out_boxes,
                floor_on,
                floor,
                room,
                leaving_room,
                materials,
            }
        )],
    )
}

/// WGSL twin: `FlowParams` in `wgsl/dem/flow_scan.wgsl`.
#[derive(Debug, Clone, Copy, Default, encase::ShaderType)]
struct FlowParams {
    n: u32,
    row: u32,
    near_boxes: u32,
    out_boxes: u32,
    floor_on: u32,
    floor: f32,
    room: u32,
    leaving_room: u32,
    materials: u32,
}

/// Words before the lists in the scan's output.
const HEADER: usize = 4;

/// The scan's pipeline and buffers (the lists grown on demand).
pub(crate) struct FlowScan {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    boxes: wgpu::Buffer,
    /// The counts and both lists, read back together ([`HEADER`] words, then the lists).
    found: wgpu::Buffer,
    /// Bound as the spins where the state has none (the paper's step: every sphere of the
    /// first material); never read.
    no_spin: wgpu::Buffer,
    room: u32,
    leaving_room: u32,
}

impl FlowScan {
    /// The pipeline (compiled once per device) and first buffers.
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.own_module("mochi.flow_scan", SOURCE);
        let none = wgpu::BufferUsages::empty();
        FlowScan {
            pipeline: gpu.pipeline("mochi.flow_scan", &module, ENTRY_POINT),
            params: gpu.uniform("mochi.flow_scan.params", &FlowParams::default()),
            boxes: gpu.storage("mochi.flow_scan.boxes", 16, none),
            found: gpu.storage(
                "mochi.flow_scan.found",
                found_words(FIRST_ROOM, FIRST_ROOM) * 4,
                none,
            ),
            no_spin: gpu.storage("mochi.flow_scan.no_spin", 16, none),
            room: FIRST_ROOM,
            leaving_room: FIRST_ROOM,
        }
    }

    /// Scans the first `n` rows of `pos` (`x, y, z, r` each) for `query`, the leaving spheres'
    /// materials from `spin` (the granular step's ω rows in the order of `pos`; `None`: all of
    /// the first material).
    pub fn scan(
        &mut self,
        gpu: &Gpu,
        pos: &wgpu::Buffer,
        spin: Option<&wgpu::Buffer>,
        n: u32,
        query: &FlowQuery,
    ) -> Result<Scan> {
        let corners: Vec<[f32; 4]> = query
            .near
            .iter()
            .chain(&query.outflows)
            .flat_map(|&(lo, hi)| [lo.extend(0.0).to_array(), hi.extend(0.0).to_array()])
            .collect();
        let none = wgpu::BufferUsages::empty();
        let bytes = corners.len() as u64 * 16;
        if self.boxes.size() < bytes {
            self.boxes = gpu.storage("mochi.flow_scan.boxes", bytes, none);
        }
        gpu.queue
            .write_buffer(&self.boxes, 0, bytemuck::cast_slice(&corners));
        let groups = gpu.grid(n, GROUP);
        loop {
            let params = FlowParams {
                n,
                row: groups.0 * GROUP,
                near_boxes: query.near.len() as u32,
                out_boxes: query.outflows.len() as u32,
                floor_on: query.floor.is_some() as u32,
                floor: query.floor.unwrap_or(0.0),
                room: self.room,
                leaving_room: self.leaving_room,
                materials: spin.is_some() as u32,
            };
            gpu.write_uniform(&self.params, &params);
            let bind = gpu.bind(
                "mochi.flow_scan",
                &self.pipeline,
                &[
                    (PARAMS, &self.params),
                    (POS, pos),
                    (BOXES, &self.boxes),
                    (FOUND, &self.found),
                    (SPIN, spin.unwrap_or(&self.no_spin)),
                ],
            );
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            encoder.clear_buffer(&self.found, 0, Some(HEADER as u64 * 4));
            gpu.dispatch(
                &mut encoder,
                "mochi.flow_scan",
                &self.pipeline,
                &bind,
                groups,
            );
            gpu.queue.submit([encoder.finish()]);
            let words = found_words(self.room, self.leaving_room) as usize;
            let found: Vec<u32> = gpu.read(&self.found, words)?;
            let (leaving, listed) = (found[0], found[1]);
            if listed > self.room || leaving > self.leaving_room {
                // A list overflowed: again with room for all.
                self.room = self.room.max(listed.next_power_of_two());
                self.leaving_room = self.leaving_room.max(leaving.next_power_of_two());
                let bytes = found_words(self.room, self.leaving_room) * 4;
                self.found = gpu.checked("growing the flow scan's lists", || {
                    gpu.storage("mochi.flow_scan.found", bytes, none)
                })?;
                continue;
            }
            let f = f32::from_bits;
            let near_words = &found[HEADER..HEADER + 4 * listed as usize];
            let near = near_words
                .chunks_exact(4)
                .map(|w| (Vec3::new(f(w[0]), f(w[1]), f(w[2])), f(w[3])))
                .collect();
            let at = HEADER + 4 * self.room as usize;
            let leaving = found[at..at + LEAVING_WORDS * leaving as usize]
                .chunks_exact(LEAVING_WORDS)
                .map(|w| Leaving {
                    row: w[0],
                    radius: f(w[1]),
                    material: w[2] as u8,
                })
                .collect();
            return Ok(Scan { leaving, near });
        }
    }
}

/// Words of a leaving entry: state index, radius, material.
const LEAVING_WORDS: usize = 3;

/// Words of the scan's output with lists of `room` near and `leaving_room` leaving entries.
fn found_words(room: u32, leaving_room: u32) -> u64 {
    HEADER as u64 + 4 * room as u64 + LEAVING_WORDS as u64 * leaving_room as u64
}
