//! The optix steps' position update, `mochi_advance` of `optix/physics.cuh`, is the twin of
//! `src/particles/position.rs`'s `advance` bit for bit: compiled as host C++ (no fused
//! multiply-adds, as NVRTC compiles it for the GPU), it leaves the same centre and residual
//! from the same centre, residual and displacement, on a table of slow and fast steps at every
//! distance from the origin. (The wgpu steps' update, `advance_position` of
//! `wgsl/dem/dem_params.wgsl`, computes its error from the operands' bits: its Rust twin is
//! `position::sum_error_by_bits`, tested against TwoSum in the library, and the GPU itself by
//! `tests/positions.rs`.) Needs a C++17 compiler (`c++`) and no GPU; skips with a note without
//! one (CI has one).

mod common;

use mochi::dem::position::{advance, normalised};
use std::fmt::Write;
use std::process::{Command, Stdio};

/// Reads `hi lo d` (f32 bits in hex) a line and prints the pair `mochi_advance` leaves.
const TWIN: &str = r#"
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#define __forceinline__ inline
#define __device__
struct float3 { float x, y, z; };
struct float4 { float x, y, z, w; };
inline float3 make_float3(float x, float y, float z) { return {x, y, z}; }
inline float4 make_float4(float x, float y, float z, float w) { return {x, y, z, w}; }
#include "physics.cuh"
static float from_bits(uint32_t u) { float f; std::memcpy(&f, &u, 4); return f; }
static uint32_t to_bits(float f) { uint32_t u; std::memcpy(&u, &f, 4); return u; }
int main() {
    uint32_t a, b, c;
    while (std::scanf("%x %x %x", &a, &b, &c) == 3) {
        float hi = from_bits(a), lo = from_bits(b);
        mochi_advance(hi, lo, from_bits(c));
        std::printf("%08x %08x\n", to_bits(hi), to_bits(lo));
    }
    return 0;
}
"#;

#[test]
fn the_cuda_position_update_is_the_rust_one() {
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("position_twin.cpp");
    std::fs::write(&source, TWIN).unwrap();
    let binary = dir.path().join("position_twin");
    if common::twin::compile(&source, &binary, &[], "the CUDA position update").is_none() {
        return;
    }
    // A coordinate from 1e-6 to 1e6 m either side, its residual a normalised part of its
    // spacing, and a displacement from a millionth of the spacing to a thousand spacings.
    let mut rand = common::noise(43);
    let mut cases = Vec::new();
    for _ in 0..20_000 {
        let hi = 10f32.powf(12.0 * rand()) * rand().signum();
        let spacing = hi.abs().next_up() - hi.abs();
        let lo = spacing * rand() * 0.999;
        let d = spacing * 10f32.powf(9.0 * rand() - 3.0) * rand().signum();
        assert!(normalised(hi, lo));
        cases.push((hi, lo, d));
    }
    let mut table = String::new();
    for (hi, lo, d) in &cases {
        let [a, b, c] = [hi, lo, d].map(|x| x.to_bits());
        writeln!(table, "{a:08x} {b:08x} {c:08x}").unwrap();
    }
    let mut run = Command::new(&binary)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // Written from a thread: the answers fill the output pipe while the table goes in.
    let mut input = run.stdin.take().unwrap();
    let writer =
        std::thread::spawn(move || std::io::Write::write_all(&mut input, table.as_bytes()));
    let out = run.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    assert!(out.status.success());
    let report = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = report.lines().collect();
    assert_eq!(lines.len(), cases.len());
    for ((hi, lo, d), line) in cases.into_iter().zip(lines) {
        let (mut a, mut b) = (hi, lo);
        advance(&mut a, &mut b, d);
        assert_eq!(
            line,
            format!("{:08x} {:08x}", a.to_bits(), b.to_bits()),
            "{hi} + {lo} moved by {d}"
        );
    }
}
