//! Detection on the cpu engine: [`CpuBackend`] implements [`crate::Backend`].

use super::grid::SortedGrid;
use super::query::{PairSink, search, search_tasks};
use crate::detect::{Backend, BackendInfo};
use crate::error::{Error, Result, try_push, try_vec};
use crate::proxy::ProxyMode;
use crate::spheres::{MAX_SPHERES, Spheres};
use crate::types::DetectStats;
use crate::types::Pair;
use rayon::prelude::*;

/// The multi-threaded CPU backend.
#[derive(Debug, Default)]
pub struct CpuBackend {
    /// Mode of the last build; `None` before the first.
    mode: Option<ProxyMode>,
    grid: SortedGrid,
    /// The last pairs [`Backend::take_pairs`] handed over (the allocation kept between calls).
    pairs: Vec<Pair>,
    /// The search's sinks, one per task (their allocations kept between calls).
    collects: Vec<Collect>,
}

impl CpuBackend {
    /// A backend with nothing built yet.
    pub fn new() -> Self {
        Self::default()
    }

    fn built(&self) -> Result<&SortedGrid> {
        match self.mode {
            Some(_) => Ok(&self.grid),
            None => Err(Error::Usage("detection asked for before build".into())),
        }
    }
}

/// Collects pairs until memory runs out, then only counts them; each pair in the block of
/// spheres its first index falls in (2^`shift` spheres a block), for [`sort_by_first`]. Kept
/// between searches, so its blocks' allocations are reused.
#[derive(Debug, Default)]
struct Collect {
    shift: u32,
    blocks: Vec<Vec<Pair>>,
    /// Pairs that found no memory.
    lost: u64,
}
impl Collect {
    /// Emptied, for `blocks` blocks of 2^`shift` spheres.
    fn reset(&mut self, shift: u32, blocks: usize) {
        self.shift = shift;
        self.blocks.resize_with(blocks, Vec::new);
        self.blocks.iter_mut().for_each(Vec::clear);
        self.lost = 0;
    }
}
impl PairSink for Collect {
    #[inline(always)]
    fn pair(&mut self, a: u32, b: u32) {
        let pair = Pair::new(a, b);
        let block = &mut self.blocks[(pair.i >> self.shift) as usize];
        if self.lost > 0 || try_push(block, pair, String::new).is_err() {
            self.lost += 1;
        }
    }
}

#[derive(Default)]
struct Count(u64);
impl PairSink for Count {
    #[inline(always)]
    fn pair(&mut self, _: u32, _: u32) {
        self.0 += 1;
    }
}

struct Visit<'a>(&'a (dyn Fn(Pair) + Sync), u64);
impl PairSink for Visit<'_> {
    #[inline(always)]
    fn pair(&mut self, a: u32, b: u32) {
        self.1 += 1;
        (self.0)(Pair::new(a, b));
    }
}

/// Blocks of [`sort_by_first`] per thread: enough that the threads share the work evenly
/// although the first index of a pair is more often a small one.
const BLOCKS_PER_THREAD: usize = 16;

/// Every colliding pair of `grid`, sorted, into `pairs`, through `collects` (both allocations
/// reused).
fn sorted_pairs(
    grid: &SortedGrid,
    collects: &mut Vec<Collect>,
    pairs: &mut Vec<Pair>,
) -> Result<DetectStats> {
    let n = grid.ids.len();
    let shift = n
        .div_ceil(BLOCKS_PER_THREAD * rayon::current_num_threads())
        .next_power_of_two()
        .trailing_zeros();
    let blocks = (n >> shift) + 1;
    collects.resize_with(search_tasks(grid), Collect::default);
    collects.iter_mut().for_each(|c| c.reset(shift, blocks));
    let candidates = search(grid, collects);
    let kept: usize = collects.iter().flat_map(|c| &c.blocks).map(Vec::len).sum();
    let lost: u64 = collects.iter().map(|c| c.lost).sum();
    let found = kept as u64 + lost;
    let too_many = || Error::OutOfMemory {
        what: format!("{found} colliding pairs"),
        bytes: found.saturating_mul(std::mem::size_of::<Pair>() as u64),
    };
    pairs.clear();
    if lost > 0 || pairs.try_reserve_exact(kept).is_err() {
        return Err(too_many());
    }
    sort_by_first(collects, (n, shift), pairs)?;
    Ok(DetectStats {
        candidates,
        pairs: found,
    })
}

/// The pairs collected in `chunks` (indices below `n`, in blocks of 2^`shift` spheres by their
/// first index) into `out` (empty, with room for them all), sorted by (i, j): each block on its
/// own thread, its pairs counted and placed by `i`, then the few pairs of each sphere that has
/// several (a sphere touches few others) sorted by `j`. Linear in pairs and spheres, where a
/// comparison sort of the pairs is not; the same order on any number of threads. Its tables
/// of each block's spheres are allocated fallibly.
fn sort_by_first(chunks: &[Collect], (n, shift): (usize, u32), out: &mut Vec<Pair>) -> Result<()> {
    let blocks = chunks.first().map_or(0, |c| c.blocks.len());
    let sizes: Vec<usize> = (0..blocks)
        .map(|b| chunks.iter().map(|c| c.blocks[b].len()).sum())
        .collect();
    out.resize(sizes.iter().sum(), Pair { i: 0, j: 0 });
    let mut regions = Vec::with_capacity(blocks);
    let mut rest = out.as_mut_slice();
    for &size in &sizes {
        let (region, after) = rest.split_at_mut(size);
        regions.push(region);
        rest = after;
    }
    regions
        .into_par_iter()
        .enumerate()
        .try_for_each(|(b, region)| {
            let first = b << shift;
            let spheres = n.saturating_sub(first).min(1 << shift);
            let parts = || chunks.iter().flat_map(|c| &c.blocks[b]);
            let table = || -> Result<Vec<u32>> {
                let mut v = try_vec(spheres + 1, || format!("pair tables of {spheres} spheres"))?;
                v.resize(spheres + 1, 0);
                Ok(v)
            };
            let mut starts = table()?;
            for pair in parts() {
                starts[pair.i as usize - first + 1] += 1;
            }
            for k in 0..spheres {
                starts[k + 1] += starts[k];
            }
            // Placed by `i`; the spheres given a second pair listed (without a branch), so that
            // only their pairs are then sorted by `j`.
            let mut cursor = table()?;
            cursor.copy_from_slice(&starts);
            let mut several = table()?;
            let mut listed = 0;
            for &pair in parts() {
                let k = pair.i as usize - first;
                let place = cursor[k];
                region[place as usize] = pair;
                cursor[k] = place + 1;
                several[listed] = k as u32;
                listed += (place == starts[k] + 1) as usize;
            }
            for &k in &several[..listed] {
                let k = k as usize;
                sort_by_second(&mut region[starts[k] as usize..starts[k + 1] as usize]);
            }
            Ok(())
        })
}

/// Sorts the few pairs of one sphere by `j`, by insertion.
fn sort_by_second(pairs: &mut [Pair]) {
    for k in 1..pairs.len() {
        let pair = pairs[k];
        let mut place = k;
        while place > 0 && pairs[place - 1].j > pair.j {
            pairs[place] = pairs[place - 1];
            place -= 1;
        }
        pairs[place] = pair;
    }
}

/// The per-task sinks of a one-off search of `grid`.
fn sinks<S: Default>(grid: &SortedGrid) -> Vec<S> {
    (0..search_tasks(grid)).map(|_| S::default()).collect()
}

impl Backend for CpuBackend {
    fn info(&self) -> BackendInfo {
        BackendInfo {
            name: "cpu",
            device: format!("CPU, {} threads", rayon::current_num_threads()),
            max_spheres: MAX_SPHERES as u64,
        }
    }

    fn build(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()> {
        // Built only once binned: a failed binning leaves nothing to search.
        self.mode = None;
        self.grid
            .bin(spheres, mode.cell_size(spheres.max_radius()))?;
        self.mode = Some(mode);
        Ok(())
    }

    fn update(&mut self, spheres: Spheres<'_>) -> Result<()> {
        let mode = self
            .mode
            .ok_or_else(|| Error::Usage("update asked for before build".into()))?;
        if spheres.len() != self.grid.ids.len() {
            return Err(Error::Usage(format!(
                "update with {} spheres, built with {}",
                spheres.len(),
                self.grid.ids.len()
            )));
        }
        self.build(spheres, mode)
    }

    fn find_pairs(&mut self) -> Result<(Vec<Pair>, DetectStats)> {
        self.built()?;
        let mut pairs = Vec::new();
        let stats = sorted_pairs(&self.grid, &mut self.collects, &mut pairs)?;
        Ok((pairs, stats))
    }

    fn take_pairs(&mut self, take: &mut dyn FnMut(&[Pair])) -> Result<DetectStats> {
        self.built()?;
        let stats = sorted_pairs(&self.grid, &mut self.collects, &mut self.pairs)?;
        take(&self.pairs);
        Ok(stats)
    }

    fn count_pairs(&mut self) -> Result<DetectStats> {
        let grid = self.built()?;
        let mut counts: Vec<Count> = sinks(grid);
        let candidates = search(grid, &mut counts);
        Ok(DetectStats {
            candidates,
            pairs: counts.iter().map(|c| c.0).sum(),
        })
    }

    fn for_each_contact(&mut self, visit: &(dyn Fn(Pair) + Sync)) -> Result<DetectStats> {
        let grid = self.built()?;
        let mut visits: Vec<Visit> = (0..search_tasks(grid)).map(|_| Visit(visit, 0)).collect();
        let candidates = search(grid, &mut visits);
        Ok(DetectStats {
            candidates,
            pairs: visits.iter().map(|c| c.1).sum(),
        })
    }
}
