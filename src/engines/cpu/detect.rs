//! Detection on the cpu engine: [`CpuBackend`] implements [`crate::Backend`].

use super::grid::SortedGrid;
use super::query::{PairSink, search};
use crate::detect::{Backend, BackendInfo};
use crate::error::{Error, Result, try_push};
use crate::proxy::ProxyMode;
use crate::spheres::{MAX_SPHERES, SphereSet};
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
/// spheres its first index falls in (`block` spheres a block), for [`sort_by_first`].
struct Collect {
    block: u32,
    blocks: Vec<Vec<Pair>>,
    /// Pairs that found no memory.
    lost: u64,
}
impl Collect {
    fn new(block: u32, blocks: usize) -> Self {
        Collect {
            block,
            blocks: vec![Vec::new(); blocks],
            lost: 0,
        }
    }
}
impl PairSink for Collect {
    #[inline(always)]
    fn pair(&mut self, a: u32, b: u32) {
        let pair = Pair::new(a, b);
        let block = &mut self.blocks[(pair.i / self.block) as usize];
        if self.lost > 0 || try_push(block, pair, String::new).is_err() {
            self.lost += 1;
        }
    }
}

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

/// Every colliding pair of `grid`, sorted, into `pairs` (its allocation reused).
fn sorted_pairs(grid: &SortedGrid, pairs: &mut Vec<Pair>) -> Result<DetectStats> {
    let n = grid.ids.len();
    let blocks = 4 * rayon::current_num_threads();
    let block = n.div_ceil(blocks).max(1) as u32;
    let blocks = n.div_ceil(block as usize).max(1);
    let chunks = search(grid, || Collect::new(block, blocks));
    let candidates = chunks.iter().map(|c| c.1).sum();
    let kept: usize = chunks.iter().flat_map(|c| &c.0.blocks).map(Vec::len).sum();
    let lost: u64 = chunks.iter().map(|c| c.0.lost).sum();
    let found = kept as u64 + lost;
    let too_many = || Error::OutOfMemory {
        what: format!("{found} colliding pairs"),
        bytes: found.saturating_mul(std::mem::size_of::<Pair>() as u64),
    };
    pairs.clear();
    if lost > 0 || pairs.try_reserve_exact(kept).is_err() {
        return Err(too_many());
    }
    let collected: Vec<&Collect> = chunks.iter().map(|(chunk, _)| chunk).collect();
    sort_by_first(&collected, (n, block), pairs);
    Ok(DetectStats {
        candidates,
        pairs: found,
    })
}

/// The pairs collected in `chunks` (indices below `n`, in blocks of `block` spheres by their
/// first index) into `out` (empty, with room for them all), sorted by (i, j): each block on its
/// own thread, its pairs counted and placed by `i`, then each sphere's few (it touches few
/// others) sorted by `j`. Linear in pairs and spheres, where a comparison sort of the pairs is
/// not; the same order on any number of threads.
fn sort_by_first(chunks: &[&Collect], (n, block): (usize, u32), out: &mut Vec<Pair>) {
    let blocks = n.div_ceil(block as usize).max(1);
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
    regions.into_par_iter().enumerate().for_each(|(b, region)| {
        let first = b * block as usize;
        let spheres = (n - first).min(block as usize);
        let parts = || chunks.iter().flat_map(|c| &c.blocks[b]);
        let mut starts = vec![0u32; spheres + 1];
        for pair in parts() {
            starts[pair.i as usize - first + 1] += 1;
        }
        for k in 0..spheres {
            starts[k + 1] += starts[k];
        }
        for pair in parts() {
            let place = &mut starts[pair.i as usize - first];
            region[*place as usize] = *pair;
            *place += 1;
        }
        region
            .chunk_by_mut(|a, b| a.i == b.i)
            .for_each(|pairs| pairs.sort_unstable_by_key(|p| p.j));
    });
}

impl Backend for CpuBackend {
    fn info(&self) -> BackendInfo {
        BackendInfo {
            name: "cpu",
            device: format!("CPU, {} threads", rayon::current_num_threads()),
            max_spheres: MAX_SPHERES as u64,
        }
    }

    fn build(&mut self, spheres: &SphereSet, mode: ProxyMode) -> Result<()> {
        self.grid.bin(spheres, mode.cell_size(spheres.max_radius()));
        self.mode = Some(mode);
        Ok(())
    }

    fn update(&mut self, spheres: &SphereSet) -> Result<()> {
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
        let mut pairs = Vec::new();
        let stats = sorted_pairs(self.built()?, &mut pairs)?;
        Ok((pairs, stats))
    }

    fn take_pairs(&mut self, take: &mut dyn FnMut(&[Pair])) -> Result<DetectStats> {
        self.built()?;
        let stats = sorted_pairs(&self.grid, &mut self.pairs)?;
        take(&self.pairs);
        Ok(stats)
    }

    fn count_pairs(&mut self) -> Result<DetectStats> {
        let chunks = search(self.built()?, || Count(0));
        Ok(DetectStats {
            candidates: chunks.iter().map(|c| c.1).sum(),
            pairs: chunks.iter().map(|c| c.0.0).sum(),
        })
    }

    fn for_each_contact(&mut self, visit: &(dyn Fn(Pair) + Sync)) -> Result<DetectStats> {
        let chunks = search(self.built()?, || Visit(visit, 0));
        Ok(DetectStats {
            candidates: chunks.iter().map(|c| c.1).sum(),
            pairs: chunks.iter().map(|c| c.0.1).sum(),
        })
    }
}
