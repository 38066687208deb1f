//! Pair search over a [`SortedGrid`]: each unordered pair of neighbouring cells visited once.
//!
//! For the sphere at sorted position p in cell K the search covers the rest of its own cell and
//! the next cell along x (one contiguous run of the sorted array), plus the three-cell runs of the
//! four forward neighbour rows: 14 of the 27 cells, the other 13 being covered from the other side.
//! So every candidate pair is seen exactly once and the narrow phase (rule 1 of the method) alone
//! decides; rules 2–3 exist to deduplicate per-sphere rays, which this stencil never produces.
//! Where the grid keeps a table of cell starts (a dense layout) each run is two reads of it;
//! elsewhere, because the keys of the forward rows are K plus constants, the run boundaries are
//! found by pointers that only move forward over the sorted keys: no table, so memory stays
//! O(n) however sparse the scene.

use super::grid::SortedGrid;
use crate::proxy::collides;
use rayon::prelude::*;

/// Sorted spheres per parallel task; fixed so the output order does not depend on the threads.
const CHUNK: usize = 2048;

/// Receives the colliding pairs of one chunk (input indices, either order).
pub(crate) trait PairSink {
    fn pair(&mut self, a: u32, b: u32);
}

/// The parallel tasks of a [`search`] of `grid`: it takes one sink for each.
pub(crate) fn search_tasks(grid: &SortedGrid) -> usize {
    grid.keys.len().div_ceil(CHUNK)
}

/// Runs the search in parallel chunks, chunk `c`'s pairs into `sinks[c]` in a fixed order
/// (`sinks` has [`search_tasks`] entries); returns the candidates tested.
pub(crate) fn search<S: PairSink + Send>(grid: &SortedGrid, sinks: &mut [S]) -> u64 {
    let n = grid.keys.len();
    assert_eq!(sinks.len(), search_tasks(grid), "one sink per task");
    sinks
        .par_iter_mut()
        .enumerate()
        .map(|(c, sink)| {
            let range = c * CHUNK..((c + 1) * CHUNK).min(n);
            let mut hits = Hits::new(&grid.ids, sink);
            let candidates = match grid.starts.is_empty() {
                true => search_chunk(grid, range, &mut hits),
                false => search_chunk_dense(grid, range, &mut hits),
            };
            hits.flush();
            candidates
        })
        .sum()
}

/// Colliding pairs buffered by sorted position: every candidate is written and only a hit
/// advances the buffer ([`test_runs`]), so a test does not branch on its outcome; handed to the
/// sink by input index when the buffer is full and at the end of the chunk.
struct Hits<'a, S> {
    ids: &'a [u32],
    sink: &'a mut S,
    near: [u32; HITS],
    far: [u32; HITS],
    /// Buffered pairs; always below [`HITS`] between calls.
    len: usize,
}

const HITS: usize = 64;

impl<'a, S: PairSink> Hits<'a, S> {
    fn new(ids: &'a [u32], sink: &'a mut S) -> Self {
        Hits {
            ids,
            sink,
            near: [0; HITS],
            far: [0; HITS],
            len: 0,
        }
    }

    fn flush(&mut self) {
        for k in 0..self.len {
            let (p, q) = (self.near[k] as usize, self.far[k] as usize);
            self.sink.pair(self.ids[p], self.ids[q]);
        }
        self.len = 0;
    }
}

/// A run `[begin, end)` of the sorted array that moves forward as the key grows.
#[derive(Clone, Copy)]
struct Run {
    begin: usize,
    end: usize,
}

/// [`search_chunk`] over the grid's table of cell starts: each run read from the table.
fn search_chunk_dense<S: PairSink>(
    grid: &SortedGrid,
    range: std::ops::Range<usize>,
    hits: &mut Hits<S>,
) -> u64 {
    let keys = &grid.keys[..];
    let starts = &grid.starts[..];
    let offsets = grid.forward_row_offsets();
    let mut candidates = 0u64;
    for p in range {
        let key = keys[p] as usize;
        let rows = offsets.map(|o| {
            let lo = key + o as usize;
            Run {
                begin: starts[lo] as usize,
                end: starts[lo + 3] as usize,
            }
        });
        candidates += test_runs(grid, p, starts[key + 2] as usize, &rows, hits);
    }
    candidates
}

/// Tests sorted sphere p against the rest of the run of its own cell and the next along x, up
/// to `own_end`, and against `rows`; returns the candidates tested.
#[inline(always)]
fn test_runs<S: PairSink>(
    grid: &SortedGrid,
    p: usize,
    own_end: usize,
    rows: &[Run; 4],
    hits: &mut Hits<S>,
) -> u64 {
    let spheres = &grid.spheres[..];
    let s = spheres[p];
    let (c_i, r_i) = ([s[0], s[1], s[2]], s[3]);
    // The buffer's length in a local (a register) while the runs are tested.
    let mut len = hits.len;
    let mut test = |q: usize| {
        let t = spheres[q];
        let hit = collides(c_i, r_i, [t[0], t[1], t[2]], t[3]);
        hits.near[len % HITS] = p as u32;
        hits.far[len % HITS] = q as u32;
        len += hit as usize;
        if len == HITS {
            hits.len = len;
            hits.flush();
            len = 0;
        }
    };
    (p + 1..own_end).for_each(&mut test);
    let mut candidates = (own_end - p - 1) as u64;
    for run in rows {
        (run.begin..run.end).for_each(&mut test);
        candidates += (run.end - run.begin) as u64;
    }
    hits.len = len;
    candidates
}

fn search_chunk<S: PairSink>(
    grid: &SortedGrid,
    range: std::ops::Range<usize>,
    hits: &mut Hits<S>,
) -> u64 {
    let keys = &grid.keys[..];
    let n = keys.len();
    let offsets = grid.forward_row_offsets();

    let first = keys[range.start];
    let mut own_end = keys.partition_point(|&k| k <= first + 1);
    let mut rows = offsets.map(|o| Run {
        begin: keys.partition_point(|&k| k < first + o),
        end: keys.partition_point(|&k| k <= first + o + 2),
    });
    let mut current = first;
    let mut candidates = 0u64;

    for p in range {
        let key = keys[p];
        if key != current {
            current = key;
            while own_end < n && keys[own_end] <= key + 1 {
                own_end += 1;
            }
            for (run, &o) in rows.iter_mut().zip(&offsets) {
                let lo = key + o;
                while run.begin < n && keys[run.begin] < lo {
                    run.begin += 1;
                }
                run.end = run.end.max(run.begin);
                while run.end < n && keys[run.end] <= lo + 2 {
                    run.end += 1;
                }
            }
        }
        candidates += test_runs(grid, p, own_end, &rows, hits);
    }
    candidates
}

/// Full-neighbourhood gather over a [`SortedGrid`], for the DEM: `out[p] = each(p, runs)` for
/// every sorted position p (`out` has one slot per sphere), where `runs` are the nine runs of the
/// sorted array that hold the 27 cells around p's cell (p itself included; the caller skips it).
/// Each sphere sees each of its neighbours, so a pair is seen from both sides: what a
/// deterministic, atomic-free force sum needs.
pub(crate) fn gather<T, F>(grid: &SortedGrid, out: &mut [T], each: F)
where
    T: Send,
    F: Fn(usize, &[std::ops::Range<usize>; 9]) -> T + Sync,
{
    assert_eq!(out.len(), grid.keys.len(), "one output slot per sphere");
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, slots)| {
            let len = slots.len();
            let mut outs = slots.iter_mut();
            walk_chunk(grid, c * CHUNK, len, |p, runs| {
                *outs.next().expect("one slot per sphere") = each(p, runs);
            });
        });
}

/// [`gather`] that also hands `each` the `width` entries of `side[p·width ..]` to write: the
/// contact history of sphere p (`side` has `width` entries per sphere, `width` ≥ 1).
pub(crate) fn gather_with_side<T, S, F>(
    grid: &SortedGrid,
    out: &mut [T],
    side: &mut [S],
    width: usize,
    each: F,
) where
    T: Send,
    S: Send,
    F: Fn(usize, &[std::ops::Range<usize>; 9], &mut [S]) -> T + Sync,
{
    let n = grid.keys.len();
    assert_eq!(out.len(), n, "one output slot per sphere");
    assert_eq!(side.len(), n * width, "`width` side entries per sphere");
    out.par_chunks_mut(CHUNK)
        .zip(side.par_chunks_mut(CHUNK * width))
        .enumerate()
        .for_each(|(c, (slots, sides))| {
            let len = slots.len();
            let mut outs = slots.iter_mut().zip(sides.chunks_mut(width));
            walk_chunk(grid, c * CHUNK, len, |p, runs| {
                let (slot, side) = outs.next().expect("one slot per sphere");
                *slot = each(p, runs, side);
            });
        });
}

/// Calls `visit(p, runs)` for the `len` sorted positions from `start` on, in order, with the
/// nine runs of the 27 cells around p's cell.
#[inline(always)]
fn walk_chunk(
    grid: &SortedGrid,
    start: usize,
    len: usize,
    mut visit: impl FnMut(usize, &[std::ops::Range<usize>; 9]),
) {
    let keys = &grid.keys[..];
    let n = keys.len();
    let offsets = grid.all_row_offsets();
    let first = keys[start];
    let mut runs: [std::ops::Range<usize>; 9] = std::array::from_fn(|r| {
        let lo = first.wrapping_add(offsets[r]);
        keys.partition_point(|&k| k < lo)..keys.partition_point(|&k| k <= lo + 2)
    });
    let mut current = first;
    for p in start..start + len {
        let key = keys[p];
        if key != current {
            current = key;
            for (run, &o) in runs.iter_mut().zip(&offsets) {
                let lo = key.wrapping_add(o);
                while run.start < n && keys[run.start] < lo {
                    run.start += 1;
                }
                run.end = run.end.max(run.start);
                while run.end < n && keys[run.end] <= lo + 2 {
                    run.end += 1;
                }
            }
        }
        visit(p, &runs);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engines::cpu::grid::tests::random_set;
    use crate::spheres::SphereSet;

    struct Pairs(Vec<(u32, u32)>);
    impl PairSink for Pairs {
        fn pair(&mut self, a: u32, b: u32) {
            self.0.push((a.min(b), a.max(b)));
        }
    }

    #[test]
    fn the_table_of_cell_starts_finds_what_the_walk_over_the_keys_finds() {
        // A dense random set (a table is kept), searched with the table and without.
        let n = 6000;
        let (centers, radii) = random_set(n, 12345, 9.0, 0.1..0.4);
        let spheres = SphereSet::new(centers, radii).unwrap();
        let mut grid = SortedGrid::default();
        grid.bin(spheres.view(), 2.0 * spheres.max_radius())
            .unwrap();
        assert!(!grid.starts.is_empty(), "a dense set keeps a table");
        let found = |grid: &SortedGrid| {
            let mut sinks: Vec<_> = (0..search_tasks(grid)).map(|_| Pairs(Vec::new())).collect();
            let candidates = search(grid, &mut sinks);
            let mut pairs: Vec<_> = sinks.into_iter().flat_map(|c| c.0).collect();
            pairs.sort_unstable();
            (pairs, candidates)
        };
        let with_table = found(&grid);
        assert!(with_table.0.len() > n / 2, "{} pairs", with_table.0.len());
        grid.starts.clear();
        assert_eq!(found(&grid), with_table);
        // The same grid binned again, dense then sparse (a few spheres far out): as a new one.
        grid.bin(spheres.view(), 2.0 * spheres.max_radius())
            .unwrap();
        assert_eq!(found(&grid), with_table);
        let mut spread = spheres.centers().to_vec();
        spread[0] = [1e4, 0.0, 0.0];
        spread[1] = [0.0, -1e4, 1e4];
        let sparse = SphereSet::new(spread, spheres.radii().to_vec()).unwrap();
        grid.bin(sparse.view(), 2.0 * sparse.max_radius()).unwrap();
        assert!(grid.starts.is_empty(), "a sparse set keeps no table");
        let mut fresh = SortedGrid::default();
        fresh.bin(sparse.view(), 2.0 * sparse.max_radius()).unwrap();
        assert_eq!(found(&grid), found(&fresh));
    }
}
