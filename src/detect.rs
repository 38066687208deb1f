//! Collision detection: the [`Backend`] trait every engine implements (the registry that opens
//! one is the `engines` registry).
//!
//! The contract of every backend: **exact** — after [`Backend::build`], [`Backend::find_pairs`]
//! returns every pair {i, j} with |c_i − c_j| ≤ r_i + r_j (decided by
//! [`crate::proxy::collides`]), each exactly once with `i < j`, and nothing else. Boxes
//! and cells are conservative (padded), so extra candidates are possible but missed pairs never.
//! One caveat of floating point: a GPU may decide a pair whose squared distance is within an ulp
//! or two of a threshold of the rule the other way ([`crate::proxy::near_boundary`]).
//! [`ProxyMode`] chooses the paper's proxy spheres or the older fixed-radius boxes; both modes
//! find the same pairs and differ only in the work done.

use crate::error::Result;
use crate::proxy::ProxyMode;
use crate::spheres::Spheres;
use crate::types::{DetectStats, GpuTimes, Pair};

/// What a backend is and what it can take.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BackendInfo {
    /// Backend name, as on the command line (`cpu`, …).
    pub name: &'static str,
    /// The device it runs on, in words (adapter name, thread count).
    pub device: String,
    /// Largest number of spheres one build accepts.
    pub max_spheres: u64,
}

/// A collision-detection backend (see the module docs for the contract).
///
/// Call [`build`](Backend::build) once for a sphere set, [`update`](Backend::update) after the
/// spheres moved, then any of the detection methods as often as needed.
pub trait Backend: Send {
    /// Name, device and limits.
    fn info(&self) -> BackendInfo;

    /// Builds the acceleration structure over `spheres` in `mode`, having copied them into the
    /// backend's own memory. Errors are reported here; a GPU backend may return while the
    /// device still works on the build (the next detection waits for it, and a caller timing
    /// the build alone calls [`finish`](Backend::finish)).
    fn build(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()>;

    /// Waits until the device has finished the work submitted so far (a build): what a caller
    /// timing a build calls. A backend that works synchronously has nothing to wait for.
    fn finish(&mut self) -> Result<()> {
        Ok(())
    }

    /// Brings the structure up to date after the spheres moved (same count and radii): a refit
    /// where the backend can, else a rebuild.
    fn update(&mut self, spheres: Spheres<'_>) -> Result<()>;

    /// Whether [`move_centers`](Backend::move_centers) takes centres straight (never answers
    /// `Ok(false)`): the backend keeps its own copy of the spheres, and a caller that only
    /// moves them need not keep a [`SphereSet`](crate::SphereSet) for
    /// [`update`](Backend::update).
    fn takes_centers(&self) -> bool {
        false
    }

    /// Moves the built spheres to `centers` (as many as were built, radii unchanged) and brings
    /// the structure up to date, where this backend takes centres from the caller's memory
    /// straight into its own, checking them there as [`SphereSet`](crate::SphereSet) does (refused centres leave
    /// the build as it was): `Ok(true)`. `Ok(false)` where it does not, having done nothing:
    /// the caller then moves a [`SphereSet`](crate::SphereSet) and calls [`update`](Backend::update).
    fn move_centers(&mut self, centers: &[[f32; 3]]) -> Result<bool> {
        let _ = centers;
        Ok(false)
    }

    /// Every colliding pair, each once with `i < j`, sorted by `(i, j)`.
    fn find_pairs(&mut self) -> Result<(Vec<Pair>, DetectStats)>;

    /// [`find_pairs`](Backend::find_pairs) handing the pairs to `take`, once, where they lie
    /// (a GPU backend's read-back): a caller that converts them copies them once.
    fn take_pairs(&mut self, take: &mut dyn FnMut(&[Pair])) -> Result<DetectStats> {
        let (pairs, stats) = self.find_pairs()?;
        take(&pairs);
        Ok(stats)
    }

    /// Counts the colliding pairs without storing them.
    fn count_pairs(&mut self) -> Result<DetectStats>;

    /// Calls `visit` once for each colliding pair (possibly from several threads at once).
    fn for_each_contact(&mut self, visit: &(dyn Fn(Pair) + Sync)) -> Result<DetectStats>;

    /// GPU time of the last build and detection, where measured.
    fn gpu_times(&self) -> GpuTimes {
        GpuTimes::default()
    }

    /// The structure of the last build in words (cells, levels, table), where it varies.
    fn structure(&self) -> Option<String> {
        None
    }
}
