//! Procedurally generated meshes, for use without any mesh file.
