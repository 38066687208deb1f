//! The `mochi` command-line tool over the `mochi` library: its commands ([`commands`]) and the
//! paper's experiments that `mochi bench` runs ([`bench`](mod@bench)).
#![deny(unsafe_code)]

pub mod bench;
pub mod commands;
