//! Any bytes given to the Matrix Market reader give a matrix or a typed
//! error naming the file; a matrix that comes back has the shape it
//! reports and finite entries. Sizes are checked against a small memory
//! budget (64 MiB), so a header announcing a huge matrix is refused before
//! anything is allocated for it.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use lse_deform::mtx::{MatrixFile, read_matrix_from};

fuzz_target!(
    init: {
        // SAFETY: set once, before the fuzzer starts any thread.
        unsafe { std::env::set_var("LSE_MEMORY_LIMIT", "64M") };
    },
    |data: &[u8]| {
        match read_matrix_from(data, Path::new("fuzz.mtx")) {
            Ok(MatrixFile::Sparse(m)) => {
                assert!(m.val().iter().all(|v| v.is_finite()));
                let (rows, cols) = (m.nrows(), m.ncols());
                let col_ptr = m.symbolic().col_ptr();
                assert_eq!(col_ptr.len(), cols + 1);
                assert!(m.symbolic().row_idx().iter().all(|&i| i < rows));
            }
            Ok(MatrixFile::Dense(m)) => {
                assert!(m.is_all_finite());
            }
            Err(e) => assert!(e.to_string().contains("fuzz.mtx"), "{e}"),
        }
    }
);
