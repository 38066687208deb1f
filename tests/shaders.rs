//! Every WGSL module, exactly as the device gets it, parses and validates with naga (no GPU
//! needed), so a broken shader fails here with its name and the error's location.

use naga::valid::{Capabilities, ValidationFlags, Validator};

fn all_shaders() -> Vec<(&'static str, &'static str)> {
    let mut all = mochi::backend::wgpu_rq::SHADERS.to_vec();
    all.extend(mochi::backend::wgpu_compute::SHADERS);
    all.extend(mochi::gpu::radix_sort::SHADERS);
    all.extend(mochi::gpu::scan::SHADERS);
    all
}

#[test]
fn every_shader_parses_and_validates() {
    let mut failures = Vec::new();
    for (name, source) in all_shaders() {
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
