//! GPU timestamps around recorded work, where the device has them (`TIMESTAMP_QUERY` inside
//! encoders): the time a stage took on the GPU itself, without uploads, submission or waiting.

use super::Gpu;
use crate::error::Result;

/// Timestamp slots of a stage: one before its commands, one after.
#[derive(Debug, Clone, Copy)]
pub struct Span(pub u32);

/// A small set of timestamp slots, two per span.
pub struct GpuTimer {
    queries: wgpu::QuerySet,
    /// Each span's two ticks, at its own aligned offset.
    resolved: wgpu::Buffer,
    spans: u32,
}

/// u64 entries between two spans' ticks in the resolve buffer.
const STRIDE: usize = (wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT / 8) as usize;

impl GpuTimer {
    /// Room for `spans` spans; `None` when the device cannot write timestamps in encoders.
    pub fn new(gpu: &Gpu, spans: u32) -> Option<GpuTimer> {
        let needed =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        if !gpu.device.features().contains(needed) {
            return None;
        }
        Some(GpuTimer {
            queries: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("mochi.timer"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * spans,
            }),
            resolved: gpu.storage(
                "mochi.timer.resolved",
                spans as u64 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT,
                wgpu::BufferUsages::QUERY_RESOLVE,
            ),
            spans,
        })
    }

    /// Records the start of `span`.
    pub fn start(&self, encoder: &mut wgpu::CommandEncoder, span: Span) {
        encoder.write_timestamp(&self.queries, 2 * span.0);
    }

    /// Records the end of `span` and makes its timestamps readable.
    pub fn end(&self, encoder: &mut wgpu::CommandEncoder, span: Span) {
        encoder.write_timestamp(&self.queries, 2 * span.0 + 1);
        let offset = span.0 as u64 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;
        encoder.resolve_query_set(
            &self.queries,
            2 * span.0..2 * span.0 + 2,
            &self.resolved,
            offset,
        );
    }

    /// Milliseconds between the start and end of `span` (after its commands completed).
    pub fn read_ms(&self, gpu: &Gpu, span: Span) -> Result<f64> {
        let ticks: Vec<u64> = gpu.read(&self.resolved, self.spans as usize * STRIDE)?;
        let at = span.0 as usize * STRIDE;
        let (a, b) = (ticks[at], ticks[at + 1]);
        Ok(b.saturating_sub(a) as f64 * gpu.queue.get_timestamp_period() as f64 * 1e-6)
    }
}

/// Milliseconds of `span`, or `None` without a timer (call after the span's commands completed).
pub fn read_ms(gpu: &Gpu, timer: Option<&GpuTimer>, span: Span) -> Result<Option<f64>> {
    timer.map(|t| t.read_ms(gpu, span)).transpose()
}
