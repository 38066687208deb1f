//! The clumps of the optix granular step on the GPU (`optix/clumps.cuh`): their rows
//! ([`ClumpRows`]) in buffers, each component's state row (written by the integration every
//! step), the bodies kept at a batch's start for a redo, and the bodies read back.

use super::device::cuda;
use crate::clump::ClumpSet;
use crate::engines::common::clumps::{ClumpBodyRow, ClumpRows};
use crate::error::{OptixError, Result};
use cudarc::driver::{CudaSlice, CudaStream};
use std::sync::Arc;

/// A run's clumps on the device.
pub(super) struct DeviceClumps {
    /// Each component's clump, by stable id (one unread entry without clumps).
    pub of: CudaSlice<u32>,
    /// Each component's state row this step, by stable id.
    pub rows: CudaSlice<u32>,
    /// The clumps' states ([`ClumpBodyRow`]s as words).
    pub bodies: CudaSlice<u32>,
    /// The states at the batch's start.
    bodies_start: CudaSlice<u32>,
    /// The kinds' [`ClumpShapeRow`](crate::engines::common::clumps::ClumpShapeRow)s as words.
    pub shapes: CudaSlice<u32>,
    /// The kinds' components: centre in the principal frame and radius.
    pub parts: CudaSlice<f32>,
    /// The clumps as given: their kinds, and the bodies the rows read back replace.
    set: ClumpSet,
}

impl DeviceClumps {
    /// The clumps of `set` on `stream`'s device.
    pub fn upload(stream: &Arc<CudaStream>, set: &ClumpSet) -> Result<Self> {
        let rows = ClumpRows::of(set);
        let alloc = cuda("allocating the clumps");
        let words = |bytes: &[u8]| -> std::result::Result<CudaSlice<u32>, OptixError> {
            let mut words: Vec<u32> = bytemuck::pod_collect_to_vec(bytes);
            words.resize(words.len().max(1), 0);
            stream.clone_htod(&words).map_err(&alloc)
        };
        let parts: Vec<f32> = rows.parts.iter().flatten().copied().collect();
        let bodies = words(bytemuck::cast_slice(&rows.bodies))?;
        Ok(Self {
            of: words(bytemuck::cast_slice(&rows.of))?,
            rows: words(bytemuck::cast_slice(&rows.of))?,
            bodies_start: stream.clone_dtod(&bodies).map_err(&alloc)?,
            bodies,
            shapes: words(bytemuck::cast_slice(&rows.shapes))?,
            parts: match parts.is_empty() {
                true => stream.alloc_zeros(4),
                false => stream.clone_htod(&parts),
            }
            .map_err(&alloc)?,
            set: set.clone(),
        })
    }

    /// Whether the run has clumps.
    pub fn any(&self) -> bool {
        !self.set.clumps.is_empty()
    }

    /// The number of clumps.
    pub fn count(&self) -> u32 {
        self.set.clumps.len() as u32
    }

    /// The number of their component spheres (the run's first stable ids).
    pub fn components(&self) -> u32 {
        self.set.component_count() as u32
    }

    /// Keeps the bodies as a batch starts.
    pub fn keep_start(&mut self, stream: &Arc<CudaStream>) -> Result<()> {
        if self.any() {
            let copy = cuda("keeping the clumps at the batch's start");
            stream
                .memcpy_dtod(&self.bodies, &mut self.bodies_start)
                .map_err(copy)?;
        }
        Ok(())
    }

    /// Puts back the bodies the batch started from.
    pub fn restore_start(&mut self, stream: &Arc<CudaStream>) -> Result<()> {
        if self.any() {
            let copy = cuda("going back to the clumps at the batch's start");
            stream
                .memcpy_dtod(&self.bodies_start, &mut self.bodies)
                .map_err(copy)?;
        }
        Ok(())
    }

    /// The clumps as the device holds them now (the kinds as given).
    pub fn read(&self, stream: &Arc<CudaStream>) -> Result<ClumpSet> {
        if !self.any() {
            return Ok(ClumpSet::default());
        }
        let words = stream
            .clone_dtoh(&self.bodies)
            .map_err(cuda("reading the clumps back"))?;
        let rows: Vec<ClumpBodyRow> = bytemuck::pod_collect_to_vec(&words);
        Ok(ClumpRows::bodies_into(&self.set, &rows))
    }
}
