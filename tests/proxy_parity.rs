//! The rule of `src/proxy.rs` and its WGSL copy (`wgsl/core/proxy.wgsl`) agree on a table of boundary
//! cases (`common/rule_cases.rs`). Where the squared distance lies within rounding of a threshold
//! (`proxy::near_boundary`) a GPU that fuses multiply-adds may differ; everywhere else, and on
//! every axis-aligned case (exact in any arithmetic), they must agree. Runs the WGSL on any
//! adapter (lavapipe in CI); under `CI=true` a missing adapter fails. The CUDA copy is tested
//! the same way in `optix.rs`.

mod common;

use common::rule_cases::{assert_same_decisions, cases, records};
use mochi::ProxyMode;
use mochi::gpu::shader::Binding;

/// The test kernel's bindings.
const CASES: Binding = Binding::read(0, "cases");
const KEPT: Binding = Binding::read_write(1, "kept");

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

#[test]
fn wgsl_rule_matches_the_rust_rule() {
    let Some(gpu) = common::open_gpu("the WGSL rule") else {
        return;
    };
    let source = format!("{}{KERNEL}", include_str!("../wgsl/core/proxy.wgsl"));
    let module = gpu.module("mochi.test.proxy_parity", &source);
    let pipeline = gpu.pipeline("mochi.test.proxy_parity", &module, "main");
    for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
        let cases = cases();
        let words = records(&cases, mode);
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
                &[(CASES, &input), (KEPT, &output)],
                ((cases.len() as u32).div_ceil(64), 1),
            );
            gpu.queue.submit([encoder.finish()]);
        })
        .unwrap();
        let kept: Vec<u32> = gpu.read(&output, cases.len()).unwrap();
        assert_same_decisions(mode, &cases, &kept, true);
    }
}
