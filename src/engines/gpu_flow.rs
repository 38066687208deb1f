//! A flow event's look at a wgpu engine's state without reading every sphere back
//! (`wgsl/flow_scan.wgsl`): one pass lists the spheres that leave and those near the inflows,
//! the two things an event needs to remove and insert ([`super::flow_step`]).

use crate::error::Result;
use crate::gpu::Gpu;
use crate::gpu::shader::{Binding, WgslModule, shared_struct, wgsl};
use glam::Vec3;

/// The shader, embedded.
const SOURCE: &str = wgsl!("flow_scan.wgsl");
const ENTRY_POINT: &str = "flow_scan";
/// Workgroup size (as in the shader).
const GROUP: u32 = 256;
/// Entries of the list of spheres near an inflow at first (it grows to what an event needs).
const FIRST_ROOM: u32 = 4096;

const PARAMS: Binding = Binding::uniform(0, "params");
const POS: Binding = Binding::read(1, "pos");
const BOXES: Binding = Binding::read(2, "boxes");
const COUNTS: Binding = Binding::read_write(3, "counts");
const NEAR: Binding = Binding::read_write(4, "near");
const LEAVING: Binding = Binding::read_write(5, "leaving");

/// The scan's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "flow_scan",
        SOURCE,
        &[ENTRY_POINT],
        &[PARAMS, POS, BOXES, COUNTS, NEAR, LEAVING],
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
            }
        )],
    )
}

/// WGSL twin: `FlowParams` in `wgsl/flow_scan.wgsl`.
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
}

/// What a flow event asks of the state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FlowQuery {
    /// Boxes (lo, hi) whose spheres are listed (around the inflows that insert).
    pub near: Vec<(Vec3, Vec3)>,
    /// Boxes whose spheres leave.
    pub outflows: Vec<(Vec3, Vec3)>,
    /// Centres below this height leave.
    pub floor: Option<f32>,
}

/// What the scan found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scan {
    /// State index and radius of every sphere that leaves, in no order.
    pub leaving: Vec<(u32, f32)>,
    /// Centre and radius of every other sphere in a box of [`FlowQuery::near`], in no order.
    pub near: Vec<(Vec3, f32)>,
}

/// The scan's pipeline and buffers (the list grown on demand).
pub(crate) struct FlowScan {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    counts: wgpu::Buffer,
    near: wgpu::Buffer,
    room: u32,
    leaving: wgpu::Buffer,
    leaving_room: u32,
}

impl FlowScan {
    /// The pipeline (compiled once per device) and first buffers.
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.module("mochi.flow_scan", SOURCE);
        let none = wgpu::BufferUsages::empty();
        FlowScan {
            pipeline: gpu.pipeline("mochi.flow_scan", &module, ENTRY_POINT),
            params: gpu.uniform("mochi.flow_scan.params", &FlowParams::default()),
            counts: gpu.storage("mochi.flow_scan.counts", 8, none),
            near: gpu.storage("mochi.flow_scan.near", FIRST_ROOM as u64 * 16, none),
            room: FIRST_ROOM,
            leaving: gpu.storage("mochi.flow_scan.leaving", FIRST_ROOM as u64 * 8, none),
            leaving_room: FIRST_ROOM,
        }
    }

    /// Scans the first `n` rows of `pos` (`x, y, z, r` each) for `query`.
    pub fn scan(
        &mut self,
        gpu: &Gpu,
        pos: &wgpu::Buffer,
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
        let boxes = gpu.storage("mochi.flow_scan.boxes", corners.len() as u64 * 16, none);
        gpu.queue
            .write_buffer(&boxes, 0, bytemuck::cast_slice(&corners));
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
            };
            gpu.write_uniform(&self.params, &params);
            let bind = gpu.bind(
                "mochi.flow_scan",
                &self.pipeline,
                &[
                    (PARAMS, &self.params),
                    (POS, pos),
                    (BOXES, &boxes),
                    (COUNTS, &self.counts),
                    (NEAR, &self.near),
                    (LEAVING, &self.leaving),
                ],
            );
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            encoder.clear_buffer(&self.counts, 0, None);
            gpu.dispatch(
                &mut encoder,
                "mochi.flow_scan",
                &self.pipeline,
                &bind,
                groups,
            );
            gpu.checked("scanning for a flow event", || {
                gpu.queue.submit([encoder.finish()])
            })?;
            let [leaving, listed] =
                <[u32; 2]>::try_from(gpu.read::<u32>(&self.counts, 2)?).expect("two counts read");
            if listed > self.room || leaving > self.leaving_room {
                // A list overflowed: again with room for all.
                self.room = self.room.max(listed.next_power_of_two());
                self.leaving_room = self.leaving_room.max(leaving.next_power_of_two());
                (self.near, self.leaving) = gpu.checked("growing the flow scan's lists", || {
                    (
                        gpu.storage("mochi.flow_scan.near", self.room as u64 * 16, none),
                        gpu.storage(
                            "mochi.flow_scan.leaving",
                            self.leaving_room as u64 * 8,
                            none,
                        ),
                    )
                })?;
                continue;
            }
            let gone: Vec<[u32; 2]> = match leaving {
                0 => Vec::new(),
                _ => gpu.read(&self.leaving, leaving as usize)?,
            };
            let leaving = gone
                .iter()
                .map(|&[row, r]| (row, f32::from_bits(r)))
                .collect();
            let rows: Vec<[f32; 4]> = match listed {
                0 => Vec::new(),
                _ => gpu.read(&self.near, listed as usize)?,
            };
            let near = rows
                .iter()
                .map(|p| (Vec3::new(p[0], p[1], p[2]), p[3]))
                .collect();
            return Ok(Scan { leaving, near });
        }
    }
}
