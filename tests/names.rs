//! Every enum a user names (`mochi::names`): its names read back in any case, others refused
//! with the list, and (with the `clap` feature, which the tool turns on) the same names on the
//! command line.

use mochi::ProxyMode;
use mochi::engines::wgpu::compute::{GridBuild, Structure};
use mochi::engines::{BackendChoice, BackendKind};
use mochi::names::{Named, parse};
use mochi::render::{ColorChoice, RenderChoice};
use mochi::scenes::{Layout, Scene};

/// Every value's name, in the order of [`Named::ALL`].
fn names<T: Named>() -> Vec<&'static str> {
    T::ALL.iter().map(|v| v.name()).collect()
}

#[test]
fn every_name_is_read_back_in_any_case_and_others_are_refused_with_the_list() {
    fn round_trip<T: Named + PartialEq + std::fmt::Debug>() {
        for &value in T::ALL {
            assert_eq!(parse::<T>(value.name(), "x"), Ok(value));
            let upper = value.name().to_ascii_uppercase();
            assert_eq!(parse::<T>(&upper, "x"), Ok(value));
        }
        let names = names::<T>();
        let unique: std::collections::BTreeSet<_> = names.iter().collect();
        assert_eq!(unique.len(), names.len(), "{names:?}");
        let refused = parse::<T>("nothing-of-that-name", "thing").unwrap_err();
        assert!(
            refused.starts_with("unknown thing \"nothing-of-that-name\": use "),
            "{refused}"
        );
        assert!(refused.ends_with(&format!(" or {}", names[names.len() - 1])));
    }
    round_trip::<ProxyMode>();
    round_trip::<BackendKind>();
    round_trip::<BackendChoice>();
    round_trip::<Structure>();
    round_trip::<GridBuild>();
    round_trip::<Scene>();
    round_trip::<Layout>();
    round_trip::<mochi::dem::scene::SceneKind>();
    round_trip::<RenderChoice>();
    round_trip::<ColorChoice>();
    assert_eq!(BackendKind::ALL, <BackendKind as Named>::ALL);
    assert_eq!(
        names::<BackendChoice>(),
        ["auto", "optix", "wgpu-rq", "wgpu-compute", "cpu"]
    );
    assert_eq!(
        names::<Scene>(),
        [
            "freefall", "slab", "poly1.2", "poly12", "poly120", "polylog", "pour"
        ]
    );
}

/// Where the command line's names come from `clap`'s derive, they are these.
#[cfg(feature = "clap")]
#[test]
fn the_command_line_reads_the_same_names() {
    fn same<T: Named + clap::ValueEnum + PartialEq + std::fmt::Debug>() {
        let by_clap: Vec<String> = T::value_variants()
            .iter()
            .map(|v| v.to_possible_value().unwrap().get_name().to_owned())
            .collect();
        assert_eq!(by_clap, names::<T>());
        for &value in T::ALL {
            assert_eq!(T::from_str(value.name(), true), Ok(value));
        }
    }
    same::<ProxyMode>();
    same::<BackendKind>();
    same::<BackendChoice>();
    same::<Structure>();
    same::<GridBuild>();
    same::<Scene>();
    same::<Layout>();
    same::<mochi::dem::scene::SceneKind>();
    same::<RenderChoice>();
    same::<ColorChoice>();
}
