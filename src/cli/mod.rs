//! Commands of the `lse-deform` tool that live in their own files.

pub mod render;
