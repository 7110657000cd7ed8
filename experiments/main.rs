//! The `experiments` program: regenerates `results/` (data, PNG and SVG
//! plots, renders of original and deformed meshes). Work in progress.

mod plot;
mod render;
mod text;

fn main() {}
