//! The part of [`Backend`] that every GPU backend shares: they rebuild on `update` (wgpu has no
//! refit) and detect through one pass that either collects or counts the pairs.

use crate::detect::{Backend, BackendInfo};
use crate::error::{Error, Result};
use crate::proxy::ProxyMode;
use crate::spheres::SphereSet;
use crate::types::Pair;
use crate::types::{DetectStats, GpuTimes};

/// A backend that builds from scratch and detects in one pass; [`Backend`] follows from it.
pub trait RebuildingBackend: Send {
    /// Name, device and limits.
    fn info(&self) -> BackendInfo;
    /// Builds over `spheres` in `mode`, replacing any earlier build.
    fn rebuild(&mut self, spheres: &SphereSet, mode: ProxyMode) -> Result<()>;
    /// Sphere count and mode of the current build, if any.
    fn built(&self) -> Option<(usize, ProxyMode)>;
    /// Runs detection: with `collect` the pairs (sorted) and counters, without only counters.
    fn detect(&mut self, collect: bool) -> Result<(Vec<Pair>, DetectStats)>;
    /// GPU time of the last build and detection, where measured.
    fn gpu_times(&self) -> GpuTimes;
    /// The structure of the last build in words, where it varies.
    fn structure(&self) -> Option<String> {
        None
    }
}

impl<T: RebuildingBackend> Backend for T {
    fn info(&self) -> BackendInfo {
        RebuildingBackend::info(self)
    }

    fn build(&mut self, spheres: &SphereSet, mode: ProxyMode) -> Result<()> {
        self.rebuild(spheres, mode)
    }

    fn update(&mut self, spheres: &SphereSet) -> Result<()> {
        let (n, mode) = self
            .built()
            .ok_or_else(|| Error::Usage("update asked for before build".into()))?;
        if spheres.len() != n {
            return Err(Error::Usage(format!(
                "update with {} spheres, built with {n}",
                spheres.len()
            )));
        }
        self.rebuild(spheres, mode)
    }

    fn find_pairs(&mut self) -> Result<(Vec<Pair>, DetectStats)> {
        self.detect(true)
    }

    fn count_pairs(&mut self) -> Result<DetectStats> {
        Ok(self.detect(false)?.1)
    }

    fn for_each_contact(&mut self, visit: &(dyn Fn(Pair) + Sync)) -> Result<DetectStats> {
        let (pairs, stats) = self.detect(true)?;
        pairs.into_iter().for_each(visit);
        Ok(stats)
    }

    fn gpu_times(&self) -> GpuTimes {
        RebuildingBackend::gpu_times(self)
    }

    fn structure(&self) -> Option<String> {
        RebuildingBackend::structure(self)
    }
}
