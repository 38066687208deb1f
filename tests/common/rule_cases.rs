//! Boundary cases of the proxy rule, for the parity tests of its WGSL and CUDA copies against
//! `src/proxy.rs`: touching to the ulp, proxy boundaries to the ulp, radius ratio 120, radii at
//! both ends of the accepted range (`MIN_RADIUS` and `MAX_MAGNITUDE`),
//! coincident centres, a sphere with itself.

use mochi::ProxyMode;
use mochi::proxy::{keep_in, near_boundary};

/// One candidate: (i, c_i, r_i, j, c_j, r_j).
pub type Case = (u32, [f32; 3], f32, u32, [f32; 3], f32);

/// Every case, both orders of each pair.
pub fn cases() -> Vec<Case> {
    let mut cases = Vec::new();
    for &(r_i, r_j) in &[
        (1.0f32, 1.0f32),
        (0.5, 60.0),
        (0.0005, 0.06),
        (0.3, 0.7),
        (1e-4, 1.0),
        (1e-12, 1e-12),
        (1e-12, 3e-12),
        (1e-12, 1.0),
        (2.5e17, 1e18),
    ] {
        // Near the spheres' own scale, so the differences keep their bits.
        let origin = [0.1f32, -0.2, 0.3].map(|x| x * r_i);
        // Along each axis and a diagonal, at the touching distance and the proxy boundaries.
        for dir in [
            [1.0f32, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, -1.0],
            [0.6, 0.8, 0.0],
        ] {
            for d in [r_i + r_j, 2.0 * r_j, 2.0 * r_i] {
                for d in [d.next_down(), d, d.next_up()] {
                    let c_j = std::array::from_fn(|a| origin[a] + dir[a] * d);
                    cases.push((3, origin, r_i, 7, c_j, r_j));
                    cases.push((7, c_j, r_j, 3, origin, r_i));
                }
            }
        }
        cases.push((1, origin, r_i, 2, origin, r_j)); // coincident centres
        cases.push((2, origin, r_j, 1, origin, r_i));
        cases.push((5, origin, r_i, 5, origin, r_i)); // a sphere with itself
    }
    // Gaps of 10^5 of the smallest radii (whose squares underflowed at radii of 1e-30).
    cases.push((0, [0.0; 3], 1e-12, 1, [1e-7, 0.0, 0.0], 1e-12));
    cases.push((1, [1e-7, 0.0, 0.0], 1e-12, 0, [0.0; 3], 1e-12));
    cases
}

/// The cases as records of 12 words: c_i, r_i, c_j, r_j (as bits), i, j, mode, padding.
pub fn records(cases: &[Case], mode: ProxyMode) -> Vec<u32> {
    cases
        .iter()
        .flat_map(|&(i, c_i, r_i, j, c_j, r_j)| {
            let f = |x: f32| x.to_bits();
            [
                f(c_i[0]),
                f(c_i[1]),
                f(c_i[2]),
                f(r_i),
                f(c_j[0]),
                f(c_j[1]),
                f(c_j[2]),
                f(r_j),
                i,
                j,
                mode.code(),
                0,
            ]
        })
        .collect()
}

/// The cases where a device's decisions `kept` (1: kept) differ from `src/proxy.rs`. With
/// `fused` (a device that may fuse multiply-adds), a case off the axes within rounding of a
/// threshold ([`near_boundary`]) may differ; axis-aligned cases are exact in any arithmetic.
pub fn differences(mode: ProxyMode, cases: &[Case], kept: &[u32], fused: bool) -> Vec<String> {
    assert_eq!(kept.len(), cases.len());
    let mut differ = Vec::new();
    for (case, &device_kept) in cases.iter().zip(kept) {
        let &(i, c_i, r_i, j, c_j, r_j) = case;
        let may_differ = fused && near_boundary(c_i, r_i, c_j, r_j);
        let rust = keep_in(mode, i, c_i, r_i, j, c_j, r_j);
        if rust != (device_kept == 1) && !may_differ {
            differ.push(format!(
                "{mode:?} {case:?}: rust {rust}, device {}",
                device_kept == 1
            ));
        }
    }
    differ
}

/// Asserts that a device's decisions `kept` match `src/proxy.rs` on every case of `mode`, as
/// [`differences`] judges them, listing the cases that differ.
pub fn assert_same_decisions(mode: ProxyMode, cases: &[Case], kept: &[u32], fused: bool) {
    let differ = differences(mode, cases, kept, fused);
    assert!(
        differ.is_empty(),
        "{mode:?}: {} of {} cases differ:\n{}",
        differ.len(),
        cases.len(),
        differ.join("\n")
    );
}
