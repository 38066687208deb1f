//! GPU timestamps around recorded work, where the device has them (`TIMESTAMP_QUERY` inside
//! encoders): the time a stage took on the GPU itself, without uploads, submission or waiting.
//!
//! [`GpuTimer`] holds numbered timestamp slots: commands mark slots, a resolve makes a run of
//! them readable and [`GpuTimer::ticks`] reads them back. Detection times spans
//! ([`GpuTimer::start`], [`GpuTimer::end`]: two slots each, resolved on their own); the DEM steps
//! mark the phases of a batch of steps and resolve them at once
//! (`engines/wgpu/step.rs`, `StepTimer`).

use super::Gpu;
use crate::error::Result;
use std::ops::Range;

/// Timestamp slots of a stage: one before its commands, one after.
#[derive(Debug, Clone, Copy)]
pub struct Span(pub u32);

/// Slots from one resolvable run to the next: a resolve writes at a multiple of
/// `QUERY_RESOLVE_BUFFER_ALIGNMENT` bytes of the read-back buffer, one `u64` per slot.
const RESOLVE_STRIDE: u32 = (wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT / 8) as u32;

/// Numbered timestamp slots and the buffer they are resolved into (slot `k` at `u64` `k`).
pub struct GpuTimer {
    queries: wgpu::QuerySet,
    resolved: wgpu::Buffer,
}

impl GpuTimer {
    /// Room for `spans` spans; `None` when the device cannot write timestamps in encoders.
    pub fn new(gpu: &Gpu, spans: u32) -> Option<GpuTimer> {
        Self::with_slots(gpu, "mochi.timer", spans * RESOLVE_STRIDE)
    }

    /// `slots` timestamp slots; `None` when the device cannot write timestamps in encoders.
    pub fn with_slots(gpu: &Gpu, label: &str, slots: u32) -> Option<GpuTimer> {
        let needed =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        if !gpu.device.features().contains(needed) {
            return None;
        }
        Some(GpuTimer {
            queries: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some(label),
                ty: wgpu::QueryType::Timestamp,
                count: slots,
            }),
            resolved: gpu.storage(
                &format!("{label}.resolved"),
                u64::from(slots) * 8,
                wgpu::BufferUsages::QUERY_RESOLVE,
            ),
        })
    }

    /// Writes the GPU's time into `slot` when the commands recorded so far have run.
    pub fn mark(&self, encoder: &mut wgpu::CommandEncoder, slot: u32) {
        encoder.write_timestamp(&self.queries, slot);
    }

    /// Makes the marked `slots` readable by [`ticks`](Self::ticks); a run starts at a multiple
    /// of the resolve alignment (32 slots), as span and batch runs do.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder, slots: Range<u32>) {
        debug_assert_eq!(slots.start % RESOLVE_STRIDE, 0, "an unaligned resolve");
        let offset = u64::from(slots.start) * 8;
        encoder.resolve_query_set(&self.queries, slots, &self.resolved, offset);
    }

    /// Records a copy of the resolved ticks of `slots` into `dst` at byte `offset` (a multiple
    /// of 4), to be read back with other results of the same submission.
    pub fn copy_ticks(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        slots: Range<u32>,
        dst: &wgpu::Buffer,
        offset: u64,
    ) {
        let bytes = u64::from(slots.end - slots.start) * 8;
        encoder.copy_buffer_to_buffer(
            &self.resolved,
            u64::from(slots.start) * 8,
            dst,
            offset,
            bytes,
        );
    }

    /// The resolved ticks of `slots` (after their commands completed).
    pub fn ticks(&self, gpu: &Gpu, slots: Range<u32>) -> Result<Vec<u64>> {
        let all: Vec<u64> = gpu.read(&self.resolved, slots.end as usize)?;
        Ok(all[slots.start as usize..].to_vec())
    }

    /// Milliseconds per tick of `gpu`'s timestamps.
    pub fn ms_per_tick(gpu: &Gpu) -> f64 {
        f64::from(gpu.queue.get_timestamp_period()) * 1e-6
    }

    /// Records the start of `span`.
    pub fn start(&self, encoder: &mut wgpu::CommandEncoder, span: Span) {
        self.mark(encoder, span.0 * RESOLVE_STRIDE);
    }

    /// Records the end of `span` and makes its timestamps readable.
    pub fn end(&self, encoder: &mut wgpu::CommandEncoder, span: Span) {
        let first = span.0 * RESOLVE_STRIDE;
        self.mark(encoder, first + 1);
        self.resolve(encoder, first..first + 2);
    }

    /// Milliseconds of each of `spans`, in one read-back (after their commands completed).
    pub fn spans_ms(&self, gpu: &Gpu, spans: &[Span]) -> Result<Vec<f64>> {
        let end = spans
            .iter()
            .map(|s| s.0 * RESOLVE_STRIDE + 2)
            .max()
            .unwrap_or(0);
        let ticks = self.ticks(gpu, 0..end)?;
        Ok(spans
            .iter()
            .map(|s| {
                let first = (s.0 * RESOLVE_STRIDE) as usize;
                ticks[first + 1].saturating_sub(ticks[first]) as f64 * Self::ms_per_tick(gpu)
            })
            .collect())
    }
}
