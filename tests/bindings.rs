//! The Rust side's table of every WGSL module (`mochi::gpu::shader::WgslModule`: entry points,
//! bindings, shared structs) agrees with the WGSL as naga reads it (no GPU needed): every global
//! the shader binds is in the table with the same group, binding and address space/access, and
//! nothing else is; every struct the shader keeps in a uniform or storage buffer has a Rust twin
//! in the table, with the same size and the same member at each offset (WGSL's from naga's
//! `Layouter`, Rust's from `encase`).

use mochi::gpu::shader::{Binding, BindingKind, StructLayout, WgslModule};
use naga::proc::Layouter;
use naga::{AddressSpace, Handle, Module, StorageAccess, Type, TypeInner};
use std::collections::BTreeSet;

fn all_modules() -> Vec<WgslModule> {
    mochi::gpu::shaders()
        .into_iter()
        .chain(mochi::render::shaders())
        .chain(mochi::engines::wgpu::compute::shaders())
        .chain(mochi::engines::wgpu::rq::shaders())
        .collect()
}

/// Every bound global of `module` as a [`Binding`] (`Err` for one of a kind the table has no
/// words for).
fn wgsl_bindings(module: &Module) -> Vec<Result<Binding, String>> {
    module
        .global_variables
        .iter()
        .filter_map(|(_, g)| {
            let at = g.binding.as_ref()?;
            let name: &'static str = g.name.clone().unwrap_or_default().leak();
            let kind = match (g.space, &module.types[g.ty].inner) {
                (AddressSpace::Uniform, _) => Ok(BindingKind::Uniform),
                (AddressSpace::Storage { access }, _) => Ok(BindingKind::Storage {
                    read_only: !access.contains(StorageAccess::STORE),
                }),
                (AddressSpace::Handle, TypeInner::AccelerationStructure { .. }) => {
                    Ok(BindingKind::AccelerationStructure)
                }
                (space, inner) => Err(format!("{name}: {space:?} {inner:?}")),
            };
            Some(kind.map(|kind| Binding {
                group: at.group,
                binding: at.binding,
                name,
                kind,
            }))
        })
        .collect()
}

/// The struct named `name` in `module`.
fn wgsl_struct(module: &Module, name: &str) -> Option<Handle<Type>> {
    module.types.iter().find_map(|(h, t)| {
        (t.name.as_deref() == Some(name) && matches!(t.inner, TypeInner::Struct { .. }))
            .then_some(h)
    })
}

/// Size (from naga's `Layouter`) and member offsets of the WGSL struct `ty`, by offset.
fn wgsl_layout(module: &Module, layouter: &Layouter, ty: Handle<Type>) -> StructLayout {
    let TypeInner::Struct { members, .. } = &module.types[ty].inner else {
        unreachable!("wgsl_struct finds structs only")
    };
    StructLayout {
        size: u64::from(layouter[ty].size),
        members: members
            .iter()
            .map(|m| {
                let name: &'static str = m.name.clone().unwrap_or_default().leak();
                (name, u64::from(m.offset))
            })
            .collect(),
    }
}

/// The struct a buffer global holds, itself or as its array's element.
fn buffer_struct(module: &Module, ty: Handle<Type>) -> Option<String> {
    let ty = match module.types[ty].inner {
        TypeInner::Array { base, .. } => base,
        _ => ty,
    };
    let t = &module.types[ty];
    matches!(t.inner, TypeInner::Struct { .. }).then(|| t.name.clone().unwrap_or_default())
}

/// Every disagreement between `m`'s table and its WGSL.
fn disagreements(m: &WgslModule) -> Vec<String> {
    let module = match naga::front::wgsl::parse_str(&m.source) {
        Ok(module) => module,
        Err(e) => return vec![e.emit_to_string(&m.source)],
    };
    let mut out = Vec::new();

    // Entry points, both ways.
    let wgsl: BTreeSet<&str> = module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    let rust: BTreeSet<&str> = m.entry_points.iter().copied().collect();
    for e in wgsl.difference(&rust) {
        out.push(format!("entry point {e} is not in the Rust table"));
    }
    for e in rust.difference(&wgsl) {
        out.push(format!(
            "entry point {e} of the Rust table is not in the WGSL"
        ));
    }

    // Bindings, both ways: same group, number, name and kind.
    let mut wgsl = BTreeSet::new();
    for b in wgsl_bindings(&module) {
        match b {
            Ok(b) => {
                wgsl.insert(format!("{b:?}"));
            }
            Err(e) => out.push(format!("a global of a kind the table cannot name: {e}")),
        }
    }
    let rust: BTreeSet<String> = m.bindings.iter().map(|b| format!("{b:?}")).collect();
    if rust.len() != m.bindings.len() {
        out.push("the Rust table lists a binding twice".into());
    }
    for b in wgsl.difference(&rust) {
        out.push(format!("WGSL has {b}, the Rust table does not"));
    }
    for b in rust.difference(&wgsl) {
        out.push(format!("the Rust table has {b}, the WGSL does not"));
    }

    // Shared structs: size and each member's offset.
    let mut layouter = Layouter::default();
    if let Err(e) = layouter.update(module.to_ctx()) {
        out.push(format!("naga cannot lay out the types: {e}"));
        return out;
    }
    let shared: BTreeSet<&str> = m.structs.iter().map(|s| s.name).collect();
    for (_, g) in module.global_variables.iter() {
        let buffer = matches!(
            g.space,
            AddressSpace::Uniform | AddressSpace::Storage { .. }
        );
        if let Some(name) = buffer_struct(&module, g.ty).filter(|_| buffer)
            && !shared.contains(name.as_str())
        {
            out.push(format!(
                "struct {name} (in {}) has no Rust twin in the table",
                g.name.as_deref().unwrap_or("?")
            ));
        }
    }
    for s in &m.structs {
        let Some(ty) = wgsl_struct(&module, s.name) else {
            out.push(format!("struct {} is not in the WGSL", s.name));
            continue;
        };
        let wgsl = wgsl_layout(&module, &layouter, ty);
        let mut rust = (s.layout)();
        rust.members.sort_by_key(|&(_, offset)| offset);
        if wgsl != rust {
            out.push(format!(
                "struct {}: WGSL lays it out as {wgsl:?}, the Rust twin as {rust:?}",
                s.name
            ));
        }
    }
    out
}

#[test]
fn every_module_binds_and_lays_out_what_the_rust_side_says() {
    let modules = all_modules();
    assert!(modules.len() >= 14, "only {} modules listed", modules.len());
    let failures: Vec<String> = modules
        .iter()
        .flat_map(|m| {
            disagreements(m)
                .into_iter()
                .map(move |e| format!("{}: {e}", m.label))
        })
        .collect();
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}
