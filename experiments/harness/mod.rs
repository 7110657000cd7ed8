//! The infrastructure of the studies: the run's context and mesh cases
//! ([`context`]), the list entry every study registers ([`registry`]),
//! found or created tool environments ([`environment`]), plots
//! ([`plot`]) and their text ([`text`]), and measures and scenes that more
//! than one study uses ([`measures`], [`timing`], [`conflict_scene`]).
//! Nothing here imports a study.

pub mod conflict_scene;
pub mod context;
pub mod demo;
pub mod environment;
pub mod measures;
pub mod plot;
pub mod registry;
pub mod text;
pub mod timing;
