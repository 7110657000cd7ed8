//! The infrastructure of the studies: the run's context and mesh cases
//! ([`context`]), the list entry every study registers ([`registry`]),
//! found or created tool environments ([`environment`]), plots
//! ([`plot`]) and their text ([`text`]), table cells and statistics
//! ([`rows`]), and measures and scenes that more
//! than one study uses ([`measures`], [`timing`], [`conflict_scene`]);
//! and `viz-demo`, a development aid drawing one plot of each kind
//! ([`demo`]). Nothing here imports a study.

pub mod conflict_scene;
pub mod context;
pub mod demo;
pub mod environment;
pub mod measures;
pub mod plot;
pub mod registry;
pub mod rows;
pub mod text;
pub mod timing;
