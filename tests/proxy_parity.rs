//! The rule of `src/proxy.rs` and its WGSL copy (`wgsl/proxy.wgsl`) agree on a table of boundary
//! cases: touching to the ulp, proxy boundaries to the ulp, radius ratio 120, coincident centres,
//! a sphere with itself. Where the squared distance lies within rounding of a threshold
//! (`proxy::near_boundary`) a GPU that fuses multiply-adds may differ; everywhere else, and on
//! every axis-aligned case (exact in any arithmetic), they must agree. Runs the WGSL on any adapter (lavapipe in CI); under `CI=true` a missing
//! adapter fails.

mod common;

use mochi::ProxyMode;
use mochi::proxy::{keep_in, near_boundary};

/// One candidate: (i, c_i, r_i, j, c_j, r_j).
type Case = (u32, [f32; 3], f32, u32, [f32; 3], f32);

const KERNEL: &str = r#"
struct Case { c_i: vec3<f32>, r_i: f32, c_j: vec3<f32>, r_j: f32, i: u32, j: u32, mode: u32, _pad: u32 }
@group(0) @binding(0) var<storage, read> cases: array<Case>;
@group(0) @binding(1) var<storage, read_write> kept: array<u32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= arrayLength(&cases) { return; }
    let c = cases[k];
    kept[k] = select(0u, 1u, keep_in(c.mode, c.i, c.c_i, c.r_i, c.j, c.c_j, c.r_j));
}
"#;

fn next_up(x: f32) -> f32 {
    f32::from_bits(x.to_bits() + 1)
}

fn next_down(x: f32) -> f32 {
    f32::from_bits(x.to_bits() - 1)
}

fn cases() -> Vec<Case> {
    let mut cases = Vec::new();
    let origin = [0.1f32, -0.2, 0.3];
    for &(r_i, r_j) in &[
        (1.0f32, 1.0f32),
        (0.5, 60.0),
        (0.0005, 0.06),
        (0.3, 0.7),
        (1e-4, 1.0),
    ] {
        // Along each axis and a diagonal, at the touching distance and the proxy boundaries.
        for dir in [
            [1.0f32, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, -1.0],
            [0.6, 0.8, 0.0],
        ] {
            for d in [r_i + r_j, 2.0 * r_j, 2.0 * r_i] {
                for d in [next_down(d), d, next_up(d)] {
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
    cases
}

#[test]
fn wgsl_rule_matches_the_rust_rule() {
    let Some(gpu) = common::open_gpu("the WGSL rule") else {
        return;
    };
    let source = format!("{}{KERNEL}", include_str!("../wgsl/proxy.wgsl"));
    let module = gpu.module("mochi.test.proxy_parity", &source);
    let pipeline = gpu.pipeline("mochi.test.proxy_parity", &module, "main");
    for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
        let cases = cases();
        let words: Vec<u32> = cases
            .iter()
            .flat_map(|&(i, c_i, r_i, j, c_j, r_j)| {
                let f = |x: f32| x.to_bits();
                let code = match mode {
                    ProxyMode::Mochi => 0,
                    ProxyMode::Nns => 1,
                };
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
                    code,
                    0,
                ]
            })
            .collect();
        let input = gpu.storage(
            "mochi.test.cases",
            words.len() as u64 * 4,
            wgpu::BufferUsages::empty(),
        );
        let output = gpu.storage(
            "mochi.test.kept",
            cases.len() as u64 * 4,
            wgpu::BufferUsages::empty(),
        );
        gpu.checked("running the parity kernel", || {
            gpu.queue
                .write_buffer(&input, 0, bytemuck::cast_slice(&words));
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            gpu.pass(
                &mut encoder,
                "mochi.test.proxy_parity",
                &pipeline,
                &[(0, &input), (1, &output)],
                ((cases.len() as u32).div_ceil(64), 1),
            );
            gpu.queue.submit([encoder.finish()]);
        })
        .unwrap();
        let kept: Vec<u32> = gpu.read(&output, cases.len()).unwrap();
        let mut differ = Vec::new();
        for (case, &gpu_kept) in cases.iter().zip(&kept) {
            let &(i, c_i, r_i, j, c_j, r_j) = case;
            let axis_aligned = (0..3).filter(|&a| c_i[a] != c_j[a]).count() <= 1;
            let may_differ = !axis_aligned && near_boundary(c_i, r_i, c_j, r_j);
            if keep_in(mode, i, c_i, r_i, j, c_j, r_j) != (gpu_kept == 1) && !may_differ {
                differ.push(format!(
                    "{case:?}: rust {} wgsl {}",
                    gpu_kept != 1,
                    gpu_kept == 1
                ));
            }
        }
        assert!(
            differ.is_empty(),
            "{mode:?}: {} of {} cases differ:\n{}",
            differ.len(),
            cases.len(),
            differ.join("\n")
        );
    }
}
