//! The pair output of the detection shaders (`wgsl/core/pair_output.wgsl`): a counter that counts
//! every pair, a buffer that keeps as many as fit, and the host loop that grows the buffer and
//! reruns until every pair fits, then sorts the pairs on the GPU ([`PairSort`]) and reads them
//! back. Nothing is ever truncated.

use super::pair_sort::PairSort;
use super::shader::Binding;
use super::{Gpu, Staging};
use crate::error::{Error, Result};
use crate::types::DetectStats;
use crate::types::Pair;

/// The counters in every detection shader (`pair_output.wgsl`).
pub(crate) const COUNTERS: Binding = Binding::read_write(3, "counters");
/// The pair buffer in every detection shader.
pub(crate) const PAIRS: Binding = Binding::read_write(4, "pairs");

/// What a detection hands its pairs to, once, sorted, where they lie (a read-back's mapping).
pub type TakePairs<'a> = &'a mut dyn FnMut(&[Pair]);

/// GPU buffers receiving the pairs of one detection.
pub struct PairOutput {
    /// Pairs found, candidates (low word, high word), unused.
    pub counters: wgpu::Buffer,
    /// `vec2<u32>` pairs, room for `capacity`.
    pub pairs: wgpu::Buffer,
    /// Pairs that fit in `pairs`.
    pub capacity: u32,
    /// Host-readable copies of the counters and of the pairs, kept between detections.
    counters_back: Staging,
    pairs_back: Staging,
}

impl PairOutput {
    /// Output with room for `capacity` pairs.
    pub fn new(gpu: &Gpu, capacity: u32) -> Self {
        PairOutput {
            counters: gpu.storage("mochi.pairs.counters", 16, wgpu::BufferUsages::empty()),
            // One pair more than the capacity: the pair sort's flag goes after the last pair.
            pairs: gpu.storage(
                "mochi.pairs.pairs",
                (capacity as u64 + 1) * 8,
                wgpu::BufferUsages::empty(),
            ),
            capacity,
            counters_back: Staging::default(),
            pairs_back: Staging::default(),
        }
    }

    /// Runs a detection over `spheres` spheres: zeroes [`Self::counters`] (an upload, ahead of
    /// the commands submitted next, so no clear is recorded into the timed work) and calls
    /// `run(capacity)`, which must submit the shader with this output bound. With `take`, grows
    /// the buffer until every pair fits and hands `take` the pairs sorted (by `sort`, on the GPU)
    /// where they lie, in the read-back's mapping; without, only counts.
    pub fn detect(
        &mut self,
        gpu: &Gpu,
        mut take: Option<TakePairs<'_>>,
        (sort, spheres): (&mut PairSort, u32),
        mut run: impl FnMut(&PairOutput, u32) -> Result<()>,
    ) -> Result<DetectStats> {
        loop {
            let capacity = if take.is_some() { self.capacity } else { 0 };
            gpu.queue.write_buffer(&self.counters, 0, &[0; 16]);
            run(self, capacity)?;
            let counters: Vec<u32> =
                gpu.read_through(&mut self.counters_back, &self.counters, 4)?;
            let stats = DetectStats {
                pairs: counters[0] as u64,
                candidates: counters[1] as u64 | (counters[2] as u64) << 32,
            };
            let Some(take) = take.as_mut() else {
                return Ok(stats);
            };
            if counters[0] > capacity {
                self.grow(gpu, counters[0])?;
                continue;
            }
            let count = counters[0] as usize;
            let bucketed = gpu.checked("sorting the pairs", || {
                let mut encoder = gpu.device.create_command_encoder(&Default::default());
                let bucketed = sort.encode(gpu, &mut encoder, &self.pairs, counters[0], spheres);
                gpu.queue.submit([encoder.finish()]);
                bucketed
            })?;
            if bucketed {
                // The sort's flag comes back with the pairs, after the last; the pairs are
                // taken only where no bucket was too long for it.
                let back = &mut self.pairs_back;
                let sorted =
                    gpu.read_through_with(back, &self.pairs, count + 1, |read: &[Pair]| {
                        let (pairs, flag) = read.split_at(count);
                        let long_bucket = flag[0].i != 0;
                        if !long_bucket {
                            take(pairs);
                        }
                        !long_bucket
                    })?;
                if sorted {
                    return Ok(stats);
                }
                gpu.checked("sorting the pairs", || {
                    let mut encoder = gpu.device.create_command_encoder(&Default::default());
                    sort.encode_radix(gpu, &mut encoder, &self.pairs, counters[0], spheres);
                    gpu.queue.submit([encoder.finish()]);
                })?;
            }
            gpu.read_through_with(&mut self.pairs_back, &self.pairs, count, |pairs| {
                take(pairs)
            })?;
            return Ok(stats);
        }
    }

    /// Makes room for `needed` pairs (and some slack), within the adapter's limits.
    fn grow(&mut self, gpu: &Gpu, needed: u32) -> Result<()> {
        let limits = &gpu.limits;
        let limit = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size)
            / 8
            - 1;
        if needed as u64 > limit {
            return Err(Error::TooLarge {
                what: format!("pairs in one detection on {}", gpu.info.name),
                got: needed as u64,
                limit,
            });
        }
        let capacity = (needed as u64 + needed as u64 / 8).min(limit) as u32;
        let counters_back = std::mem::take(&mut self.counters_back);
        *self = gpu.checked("growing the pair buffer", || PairOutput::new(gpu, capacity))?;
        self.counters_back = counters_back;
        Ok(())
    }
}
