//! Every WGSL module, exactly as the device gets it, parses and validates with naga (no GPU
//! needed), so a broken shader fails here with its name and the error's location.

use naga::valid::{Capabilities, ValidationFlags, Validator};

fn all_shaders() -> Vec<(String, String)> {
    let mut all: Vec<(String, String)> = mochi::backend::wgpu_rq::SHADERS
        .iter()
        .chain(&mochi::backend::wgpu_compute::SHADERS)
        .chain(&mochi::gpu::radix_sort::SHADERS)
        .chain(&mochi::gpu::scan::SHADERS)
        .chain(&mochi::render::SHADERS)
        .map(|&(name, source)| (name.to_owned(), source.to_owned()))
        .collect();
    all.extend(mochi::dem::wgpu_compute::shaders());
    all.extend(mochi::dem::wgpu_rq::shaders());
    all
}

#[test]
fn every_shader_parses_and_validates() {
    let mut failures = Vec::new();
    for (name, source) in all_shaders() {
        let source = source.as_str();
        let module = match naga::front::wgsl::parse_str(source) {
            Ok(m) => m,
            Err(e) => {
                failures.push(format!("{name}: {}", e.emit_to_string(source)));
                continue;
            }
        };
        if let Err(e) =
            Validator::new(ValidationFlags::all(), Capabilities::all()).validate(&module)
        {
            failures.push(format!("{name}: {}", e.emit_to_string(source)));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
