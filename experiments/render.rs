//! The rasteriser of the figures, now in the library
//! ([`lse_deform::render`], feature `render`): re-exported here so that the
//! experiments keep writing `crate::render::…`.

pub use lse_deform::render::*;
