//! What a batch of GPU DEM steps leaves for the host (the contacts of its last step, the bounds
//! of its end state, its timestamps), copied by the batch's own commands into one of two
//! host-readable buffers and mapped while the next batch runs: the host records and submits
//! batch k + 1 before it waits for batch k, so the GPU is not left idle between batches.
//!
//! Invariant: at most one batch is in flight per buffer; [`BatchReadback::submit`] takes the
//! buffer the previous [`BatchReadback::finish`] unmapped.

use crate::dem::stepper::StageTimes;
use crate::engines::wgpu::step::{MAX_BATCH, StepTimer};
use crate::error::{Error, Result};
use crate::gpu::Gpu;
use std::sync::mpsc::{Receiver, channel};

/// Byte offsets in a read-back buffer.
const CONTACTS_AT: u64 = 0;
const REBINS_AT: u64 = 4;
const BOUNDS_AT: u64 = 8;
const TICKS_AT: u64 = 32;

/// The bounds' bytes: the reduction's six order-preserving keys (lo xyz, hi xyz).
const BOUNDS_BYTES: u64 = 24;

/// Two host-readable buffers that batches copy their results into, alternately.
pub(crate) struct BatchReadback {
    buffers: [wgpu::Buffer; 2],
    next: usize,
}

/// A submitted batch whose results are on their way to the host.
pub(crate) struct InFlight {
    slot: usize,
    index: wgpu::SubmissionIndex,
    mapped: Receiver<std::result::Result<(), wgpu::BufferAsyncError>>,
    /// Its steps marked phase by phase (0: not timed).
    profiled: u32,
    /// Its steps, where it counted those that re-binned (a step with a skin).
    rebinning: Option<u32>,
}

/// What a finished batch read back.
pub(crate) struct BatchResults {
    /// Contacts of its last step.
    pub contacts: u64,
    /// The bounds' keys of its end state (where the batch reduced them).
    pub bounds: [u32; 6],
    /// Its phase times (`None` without a timer).
    pub times: Option<StageTimes>,
    /// Its steps, and those that re-binned (where it counted them).
    pub rebins: Option<(u32, u32)>,
}

impl BatchReadback {
    pub fn new(gpu: &Gpu) -> Self {
        let buffer = |k: usize| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(&format!("mochi.dem.readback{k}")),
                size: TICKS_AT + StepTimer::ticks_bytes(MAX_BATCH),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        BatchReadback {
            buffers: [buffer(0), buffer(1)],
            next: 0,
        }
    }

    /// Records, at the end of a batch in `encoder`, the copies of its contact counter (a `u32`
    /// at the start of `counters`), of its count of steps that re-binned (a `u32` in a buffer at
    /// a byte offset, where given), of its reduced `bounds` (where given) and of its `profiled`
    /// steps' ticks (after [`StepTimer::end`]).
    pub fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        counters: &wgpu::Buffer,
        rebins: Option<(&wgpu::Buffer, u64)>,
        bounds: Option<&wgpu::Buffer>,
        timer: Option<(&StepTimer, u32)>,
    ) {
        let dst = &self.buffers[self.next];
        encoder.copy_buffer_to_buffer(counters, 0, dst, CONTACTS_AT, 4);
        if let Some((buffer, at)) = rebins {
            encoder.copy_buffer_to_buffer(buffer, at, dst, REBINS_AT, 4);
        }
        if let Some(bounds) = bounds {
            encoder.copy_buffer_to_buffer(bounds, 0, dst, BOUNDS_AT, BOUNDS_BYTES);
        }
        if let Some((timer, profiled)) = timer {
            timer.copy_ticks(encoder, profiled, dst, TICKS_AT);
        }
    }

    /// Submits the batch recorded in `encoder` (ending with [`record`](Self::record), its
    /// `profiled` steps timed; `rebinning`: its steps, where it counted those that re-binned)
    /// and starts mapping its results.
    pub fn submit(
        &mut self,
        gpu: &Gpu,
        encoder: wgpu::CommandEncoder,
        profiled: u32,
        rebinning: Option<u32>,
    ) -> Result<InFlight> {
        let index = gpu.checked("running DEM steps", || gpu.queue.submit([encoder.finish()]))?;
        let slot = self.next;
        self.next = 1 - slot;
        let (tx, mapped) = channel();
        self.buffers[slot]
            .slice(..)
            .map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
        Ok(InFlight {
            slot,
            index,
            mapped,
            profiled,
            rebinning,
        })
    }

    /// Waits for `batch` and reads its results.
    pub fn finish(&self, gpu: &Gpu, batch: InFlight) -> Result<BatchResults> {
        gpu.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(batch.index),
                timeout: None,
            })
            .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))?;
        batch
            .mapped
            .recv()
            .map_err(|_| Error::Gpu("read-back was cancelled".into()))?
            .map_err(|e| Error::Gpu(format!("read-back failed: {e}")))?;
        let buffer = &self.buffers[batch.slot];
        let results = {
            let view = buffer
                .get_mapped_range(..)
                .map_err(|e| Error::Gpu(format!("read-back failed: {e}")))?;
            let word = |at: u64| {
                let at = at as usize;
                u32::from_le_bytes(view[at..at + 4].try_into().expect("4 bytes"))
            };
            let ticks_end = (TICKS_AT + StepTimer::ticks_bytes(batch.profiled)) as usize;
            let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&view[TICKS_AT as usize..ticks_end]);
            let rebins = batch.rebinning.map(|steps| (steps, word(REBINS_AT)));
            // The timed first step re-bins: the others' builds weigh what their re-binnings do.
            let build_share = match rebins {
                Some((steps, r)) => r as f64 / steps.max(1) as f64,
                None => 1.0,
            };
            BatchResults {
                contacts: word(CONTACTS_AT) as u64,
                bounds: std::array::from_fn(|k| word(BOUNDS_AT + 4 * k as u64)),
                times: (batch.profiled > 0)
                    .then(|| StepTimer::phases(gpu, &ticks, batch.profiled, build_share)),
                rebins,
            }
        };
        buffer.unmap();
        Ok(results)
    }
}
