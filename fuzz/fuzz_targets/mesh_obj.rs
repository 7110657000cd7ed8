//! Any bytes given to the OBJ reader, plain or gzip-compressed, give a
//! mesh or a typed error; a mesh that comes back passes validation again.
#![no_main]

use libfuzzer_sys::fuzz_target;
use lse_deform::Mesh;
use lse_deform::mesh::{MeshFormat, read_mesh_bytes};

fuzz_target!(|data: &[u8]| {
    if let Ok(loaded) = read_mesh_bytes(
        data,
        MeshFormat::Obj,
        lse_deform::limits::MemoryBudget::default(),
    ) {
        let m = loaded.mesh;
        assert!(Mesh::new(m.positions().to_vec(), m.faces().to_vec()).is_ok());
    }
});
