//! Plain data that several layers share: a found pair and the counters and timings of one
//! detection. A leaf: it imports nothing of this crate, so any module may use it without
//! creating an import cycle (`tests/modules.rs` checks the whole tree).

/// A colliding pair of spheres, by input index, always with `i < j`. Laid out as the GPU
/// writes pairs (`vec2<u32>`, `uint2`), so a read-back is a cast.
#[repr(C)]
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, bytemuck::Pod, bytemuck::Zeroable,
)]
pub struct Pair {
    /// The smaller index.
    pub i: u32,
    /// The larger index.
    pub j: u32,
}

impl Pair {
    /// The pair of `a` and `b` in either order (`a != b`).
    #[inline]
    pub fn new(a: u32, b: u32) -> Self {
        debug_assert_ne!(a, b, "a sphere never pairs with itself");
        Self {
            i: a.min(b),
            j: a.max(b),
        }
    }
}

/// Work counters of one detection.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DetectStats {
    /// Candidate pairs whose distance was tested (box or cell hits).
    pub candidates: u64,
    /// Colliding pairs found.
    pub pairs: u64,
}

/// Time the GPU itself spent in the last build and the last detection \[ms\], without uploads,
/// submission and read-back; `None` where the backend or device has no GPU timestamps.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GpuTimes {
    /// The last build (or update).
    pub build_ms: Option<f64>,
    /// The last detection pass.
    pub detect_ms: Option<f64>,
}
