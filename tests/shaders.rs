//! Every WGSL module, exactly as the device gets it, parses and validates with naga and
//! translates to SPIR-V as wgpu's Vulkan backend does (no GPU needed), so a broken shader fails
//! here with its name and the error's location, and one that trips naga's SPIR-V writer (a
//! pointer to a member of a local struct passed to a function did) with its name, under every
//! set of `override` values the engines give its pipelines.

use naga::valid::{Capabilities, ValidationFlags, Validator};

fn all_shaders() -> Vec<(String, String)> {
    mochi::gpu::shaders()
        .into_iter()
        .chain(mochi::render::shaders())
        .chain(mochi::engines::wgpu::compute::shaders())
        .chain(mochi::engines::wgpu::rq::shaders())
        .map(|m| (m.label, m.source))
        .collect()
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
        let info =
            match Validator::new(ValidationFlags::all(), Capabilities::all()).validate(&module) {
                Ok(info) => info,
                Err(e) => {
                    failures.push(format!("{name}: {}", e.emit_to_string(source)));
                    continue;
                }
            };
        for constants in pipeline_constants(&module) {
            let said = format!("{name} {:?}", constants.iter().collect::<Vec<_>>());
            let (module, info) = match naga::back::pipeline_constants::process_overrides(
                &module, &info, None, &constants,
            ) {
                Ok(processed) => processed,
                Err(e) => {
                    failures.push(format!("{said}: {e}"));
                    continue;
                }
            };
            let options = naga::back::spv::Options::default();
            let spirv = std::panic::catch_unwind(|| {
                naga::back::spv::write_vec(&module, &info, &options, None)
            });
            match spirv {
                Ok(Ok(_)) => {}
                Ok(Err(e)) => failures.push(format!("{said}: SPIR-V: {e}")),
                Err(_) => failures.push(format!("{said}: naga's SPIR-V writer panicked")),
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every set of `override` values the engines make `module`'s pipelines with: the defaults, and
/// `ONE_MATERIAL` set where the module declares it (the granular step's `DemModule::constants`).
fn pipeline_constants(module: &naga::Module) -> Vec<naga::back::PipelineConstants> {
    let mut sets = vec![naga::back::PipelineConstants::default()];
    let declares = |name: &str| {
        module
            .overrides
            .iter()
            .any(|(_, o)| o.name.as_deref() == Some(name))
    };
    if declares("ONE_MATERIAL") {
        let mut one = naga::back::PipelineConstants::default();
        one.insert("ONE_MATERIAL".into(), 1.0);
        sets.push(one);
    }
    sets
}

/// The `u32` value of the WGSL constant `name` (a literal) in `module`.
fn wgsl_u32(module: &naga::Module, name: &str) -> u32 {
    let (_, constant) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no constant {name}"));
    match module.global_expressions[constant.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => v,
        ref e => panic!("{name} is not a u32 literal: {e:?}"),
    }
}

/// The value of `#define name <n>u` in a CUDA source.
fn cuda_define(source: &str, name: &str) -> u32 {
    let line = source
        .lines()
        .find_map(|l| {
            l.strip_prefix("#define ")?
                .strip_prefix(name)?
                .strip_prefix(' ')
        })
        .unwrap_or_else(|| panic!("no #define {name}"));
    line.trim()
        .trim_end_matches('u')
        .parse()
        .unwrap_or_else(|e| panic!("#define {name} {line}: {e}"))
}

#[test]
fn mode_codes_agree_with_the_device_programs() {
    use mochi::ProxyMode;
    let wgsl = naga::front::wgsl::parse_str(include_str!("../wgsl/core/proxy.wgsl")).unwrap();
    let cuda = include_str!("../optix/device.cuh");
    for (mode, wgsl_name, cuda_name) in [
        (ProxyMode::Mochi, "MODE_MOCHI", "MOCHI_MODE_MOCHI"),
        (ProxyMode::Nns, "MODE_NNS", "MOCHI_MODE_NNS"),
    ] {
        assert_eq!(wgsl_u32(&wgsl, wgsl_name), mode.code(), "{wgsl_name}");
        assert_eq!(cuda_define(cuda, cuda_name), mode.code(), "{cuda_name}");
    }
}
