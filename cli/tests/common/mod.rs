//! Shared by the tool's tests: the library's test helpers (`tests/common`: which GPU tests run,
//! CI's adapters) and the binary run as a user runs it ([`cli`]).
#![allow(dead_code)] // each test file uses the part it needs

pub mod cli;

#[path = "../../../tests/common/mod.rs"]
mod library;
#[allow(unused_imports)] // the tests that run only the binary take none of them
pub use library::*;
