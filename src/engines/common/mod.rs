//! What every GPU engine shares (optix and the wgpu engines alike): the detection layer over one
//! pass ([`detect`]), the state in rows and the batch loop ([`rows`]), the clumps' rows
//! ([`clumps`]), the mesh walls' tables ([`walls`]) and the flows between batches ([`flow`]).

pub(crate) mod clumps;
pub(crate) mod detect;
pub(crate) mod flow;
pub(crate) mod rows;
pub(crate) mod walls;
