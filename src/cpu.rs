//! CPU state that our kernels depend on: the upper halves of the x86-64
//! vector registers.
//!
//! This crate is compiled for the x86-64 baseline, so its kernels use
//! 128-bit SSE instructions. The dense kernels of faer and its gemm crates
//! pick 256- and 512-bit AVX code at run time and can return with the
//! upper halves of the vector registers still "dirty". Until a
//! `vzeroupper`, every legacy SSE instruction on such a thread then pays a
//! state-transition penalty or a false dependency on the upper half (Intel
//! optimisation manual, §"Mixing AVX code with SSE code"). On the AVX-512
//! machine this crate is measured on, the handle basis's per-frame kernel
//! ran several times slower after a faer factorisation had run on the same
//! threads, and at full speed after a `vzeroupper` (compare
//! `cargo bench --bench editor` with the calls to
//! [`clear_upper_vector_state`] removed).
//!
//! [`clear_upper_vector_state`] issues `vzeroupper` when the CPU has AVX
//! (nothing otherwise, and nothing on other architectures). It costs a
//! few cycles; call it where a hot SSE loop starts on a thread that may
//! have run faer: at the start of each parallel task (`rayon`'s
//! `for_each_init` / `map_init`) and after a faer call on the calling
//! thread.

/// `vzeroupper` when the CPU supports AVX; nothing otherwise. Values in
/// the lower 128 bits of the registers (all that SSE code uses) are kept,
/// and Rust code compiled without AVX keeps nothing in the upper halves,
/// so this never changes a result, only the speed of what follows.
#[inline]
pub(crate) fn clear_upper_vector_state() {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU supports AVX (checked just above), the only
            // requirement of `vzeroupper`.
            unsafe { vzeroupper() }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn vzeroupper() {
    std::arch::x86_64::_mm256_zeroupper();
}
