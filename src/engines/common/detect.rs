//! What every GPU engine's detection layer shares: [`GpuBackend`], one pass that either
//! collects or counts the pairs, from which [`Backend`] follows (the update checks, the three
//! detection methods).

use crate::detect::{Backend, BackendInfo};
use crate::error::{Error, Result};
use crate::gpu::pair_output::TakePairs;
use crate::proxy::ProxyMode;
use crate::spheres::Spheres;
use crate::types::Pair;
use crate::types::{DetectStats, GpuTimes};
use rayon::prelude::*;

/// A backend that detects in one pass over its current build; [`Backend`] follows from it.
pub(crate) trait GpuBackend: Send {
    /// Name, device and limits.
    fn info(&self) -> BackendInfo;
    /// Builds over `spheres` in `mode`, replacing any earlier build.
    fn build(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()>;
    /// Sphere count and mode of the current build, if any.
    fn built(&self) -> Option<(usize, ProxyMode)>;
    /// Brings the current build up to date after the spheres moved; `spheres` has the build's
    /// count. A rebuild unless the engine can refit (wgpu cannot).
    fn refresh(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()> {
        self.build(spheres, mode)
    }
    /// Runs detection: with `take`, hands it the pairs (sorted), once; without, only counts.
    fn detect(&mut self, take: Option<TakePairs<'_>>) -> Result<DetectStats>;
    /// [`Backend::finish`].
    fn finish(&mut self) -> Result<()>;
    /// [`Backend::takes_centers`].
    fn takes_centers(&self) -> bool {
        false
    }
    /// [`Backend::move_centers`] where the engine takes centres straight into its upload
    /// (`centers` has the build's count); `Ok(false)` where it does not.
    fn move_centers(&mut self, _centers: &[[f32; 3]]) -> Result<bool> {
        Ok(false)
    }
    /// GPU time of the last build and detection, where measured.
    fn gpu_times(&self) -> GpuTimes;
    /// The structure of the last build in words, where it varies.
    fn structure(&self) -> Option<String> {
        None
    }
}

impl<T: GpuBackend> Backend for T {
    fn info(&self) -> BackendInfo {
        GpuBackend::info(self)
    }

    fn build(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()> {
        GpuBackend::build(self, spheres, mode)
    }

    fn update(&mut self, spheres: Spheres<'_>) -> Result<()> {
        let mode = built_count(self, spheres.len())?;
        self.refresh(spheres, mode)
    }

    fn finish(&mut self) -> Result<()> {
        GpuBackend::finish(self)
    }

    fn takes_centers(&self) -> bool {
        GpuBackend::takes_centers(self)
    }

    fn move_centers(&mut self, centers: &[[f32; 3]]) -> Result<bool> {
        built_count(self, centers.len())?;
        GpuBackend::move_centers(self, centers)
    }

    fn find_pairs(&mut self) -> Result<(Vec<Pair>, DetectStats)> {
        let mut found = Vec::new();
        let stats = self.detect(Some(&mut |pairs: &[Pair]| {
            // Many pairs are copied out on every core.
            found = match pairs.len() < PARALLEL_COPY_PAIRS {
                true => pairs.to_vec(),
                false => pairs.par_iter().copied().collect(),
            }
        }))?;
        Ok((found, stats))
    }

    fn take_pairs(&mut self, take: &mut dyn FnMut(&[Pair])) -> Result<DetectStats> {
        self.detect(Some(take))
    }

    fn count_pairs(&mut self) -> Result<DetectStats> {
        self.detect(None)
    }

    fn for_each_contact(&mut self, visit: &(dyn Fn(Pair) + Sync)) -> Result<DetectStats> {
        self.detect(Some(&mut |pairs: &[Pair]| {
            pairs.par_iter().copied().for_each(visit)
        }))
    }

    fn gpu_times(&self) -> GpuTimes {
        GpuBackend::gpu_times(self)
    }

    fn structure(&self) -> Option<String> {
        GpuBackend::structure(self)
    }
}

/// Pairs copied out of a read-back on the rayon pool from this many on.
const PARALLEL_COPY_PAIRS: usize = 1 << 17;

/// The mode of `backend`'s build, where it was built over `n` spheres; else the usage error
/// of an update of `n` spheres.
fn built_count(backend: &impl GpuBackend, n: usize) -> Result<ProxyMode> {
    let (built, mode) = backend
        .built()
        .ok_or_else(|| Error::Usage("update asked for before build".into()))?;
    if n != built {
        return Err(Error::Usage(format!(
            "update with {n} spheres, built with {built}"
        )));
    }
    Ok(mode)
}
