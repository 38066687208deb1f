//! Pair files: CSV with header `i,j`, one pair per row, `i < j`, rows sorted.

use super::{io_error, parse_error, write_atomically};
use crate::error::Result;
use crate::types::Pair;
use rayon::slice::ParallelSliceMut;
use std::io::BufRead;
use std::path::Path;

/// Writes `pairs` sorted by (i, j), atomically.
pub fn write_pairs(path: &Path, mut pairs: Vec<Pair>) -> Result<()> {
    pairs.par_sort_unstable();
    write_atomically(path, |out| {
        writeln!(out, "i,j")?;
        for p in &pairs {
            writeln!(out, "{},{}", p.i, p.j)?;
        }
        Ok(())
    })
}

/// Reads a pair file and checks its header, that `i < j` and that rows are sorted and unique.
pub fn read_pairs(path: &Path) -> Result<Vec<Pair>> {
    let file = std::fs::File::open(path).map_err(io_error(path))?;
    let mut lines = std::io::BufReader::new(file).lines();
    match lines.next() {
        Some(Ok(h)) if h.trim() == "i,j" => {}
        Some(Err(e)) => return Err(io_error(path)(e)),
        _ => return Err(parse_error(path, Some(1), "the header must be i,j")),
    }
    let mut pairs: Vec<Pair> = Vec::new();
    for (k, line) in lines.enumerate() {
        let line_no = Some(k as u64 + 2);
        let line = line.map_err(io_error(path))?;
        let bad = |msg: &str| parse_error(path, line_no, format!("{msg}: {line:?}"));
        let (i, j) = line
            .trim()
            .split_once(',')
            .ok_or_else(|| bad("expected i,j"))?;
        let (i, j): (u32, u32) = match (i.trim().parse(), j.trim().parse()) {
            (Ok(i), Ok(j)) => (i, j),
            _ => return Err(bad("indices must be non-negative integers")),
        };
        if i >= j {
            return Err(bad("i must be less than j"));
        }
        let pair = Pair { i, j };
        if pairs.last().is_some_and(|&last| last >= pair) {
            return Err(bad("rows must be sorted and unique"));
        }
        pairs.push(pair);
    }
    Ok(pairs)
}
