//! The workspace of faer's dense matrix-multiply kernel, which the
//! supernodal factorisations and solves of faer call for every product of
//! more than 16 × 16 × 16: counted against the address-space limit and
//! reserved before the work, so that it is refused with a typed error
//! instead of aborting the process.
//!
//! On x86-64 with AVX2 and FMA (or AVX-512), faer 0.24 multiplies through
//! `private-gemm-x86` 0.1, which keeps one buffer per thread, made the
//! first time that thread multiplies: `Vec::with_capacity` of two blocks
//! of the size it takes for the L3 cache (`src/lib.rs`, the thread-local
//! `MEM`), whose failure aborts. Its size does not depend on the problem
//! (on a machine whose L3 it reads as 300 MiB, 600 MiB a thread), and the
//! crate offers no setting for it. Its pages are touched only as far as a
//! product needs them, so it costs address space (`RLIMIT_AS`), hardly
//! resident memory. [`reserve`] checks, before a factorisation, that the
//! buffers of the threads that will multiply still fit under the limit
//! with what the factorisation itself allocates, and then makes them (one
//! small product on each such thread), so that nothing later depends on
//! the allocator's luck.

use std::cell::Cell;

use faer::{Accum, Mat, Par};

use crate::error::ProblemError;
use crate::limits::{check_address_space, format_bytes};

thread_local! {
    /// Whether this thread has made its kernel workspace (it then keeps
    /// it for its lifetime).
    static RESERVED: Cell<bool> = const { Cell::new(false) };
}

/// Bytes of address space the kernel's buffer takes on one thread: two
/// blocks of `L3` bytes, each rounded up to 4 KiB pages, where `L3` is the
/// cache size as `private-gemm-x86` reads it ([`kernel_l3_bytes`]).
pub(crate) fn workspace_bytes() -> u64 {
    2 * kernel_l3_bytes().div_ceil(4096) * 4096
}

/// The L3 size `private-gemm-x86` 0.1.22 works with (`src/cache.rs`): for
/// each cache of `/sys/devices/system/cpu/cpu*/cache/index*` holding data,
/// its size over the number of CPUs sharing it; those of each level times
/// the number of CPUs sharing an L1, the L3 also times the number of
/// physical cores; then at least 32 KiB (L1), 256 KiB and 4 × L1 (L2),
/// 2 MiB and 4 × L2 (L3). Where the crate takes the last cache of a
/// level it reads, this takes the largest (its order is the file system's).
fn kernel_l3_bytes() -> u64 {
    static L3: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *L3.get_or_init(|| {
        let (levels, l1_shared) = read_caches().unwrap_or(([0; 3], 1));
        let l1 = (levels[0] * l1_shared).max(32 << 10);
        let l2 = (levels[1] * l1_shared).max(256 << 10).max(4 * l1);
        let cores = num_cpus::get_physical() as u64;
        (levels[2] * l1_shared * cores).max(2 << 20).max(4 * l2)
    })
}

/// Per level 1–3, the largest data cache's size per sharing CPU, and the
/// most CPUs sharing an L1, from sysfs.
fn read_caches() -> Option<([u64; 3], u64)> {
    let mut levels = [0u64; 3];
    let mut l1_shared = 1;
    for cpu in std::fs::read_dir("/sys/devices/system/cpu").ok()?.flatten() {
        let Ok(indices) = std::fs::read_dir(cpu.path().join("cache")) else {
            continue;
        };
        for index in indices.flatten() {
            let Some((level, bytes, shared)) = read_cache(&index.path()) else {
                continue;
            };
            if level == 1 {
                l1_shared = l1_shared.max(shared);
            }
            if let Some(slot) = levels.get_mut(level.wrapping_sub(1)) {
                *slot = (*slot).max(bytes / shared.max(1));
            }
        }
    }
    Some((levels, l1_shared))
}

/// The level, size in bytes and number of sharing CPUs of the cache
/// described in the sysfs directory `dir`; `None` for an instruction cache
/// or what cannot be read.
fn read_cache(dir: &std::path::Path) -> Option<(usize, u64, u64)> {
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok();
    let kind = read("type")?;
    if !matches!(kind.trim(), "Data" | "Unified") {
        return None;
    }
    let level = read("level")?.trim().parse().ok()?;
    let size = read("size")?;
    let size = size.trim();
    let (digits, shift) = match size.as_bytes().last()? {
        b'K' => (&size[..size.len() - 1], 10),
        b'M' => (&size[..size.len() - 1], 20),
        b'G' => (&size[..size.len() - 1], 30),
        _ => (size, 0),
    };
    let bytes = digits.parse::<u64>().ok()? << shift;
    let shared = read("shared_cpu_list")?
        .trim()
        .split(',')
        .map(|item| match item.split_once('-') {
            Some((a, b)) => b.parse::<u64>().unwrap_or(0) + 1 - a.parse::<u64>().unwrap_or(0),
            None => 1,
        })
        .sum();
    Some((level, bytes, shared))
}

/// Checks that the kernel workspace of the threads a factorisation at
/// `par` multiplies on (this thread, and with `Par::Rayon` every thread of
/// rayon's pool) that have not made it yet, plus `then` bytes the caller
/// allocates afterwards, fit under the address-space limit, and makes it
/// on each of them. `what` names the factorisation in the refusal.
pub(crate) fn reserve(par: Par, then: u64, what: &str) -> Result<(), ProblemError> {
    let threads = missing(par);
    let per_thread = workspace_bytes();
    let workspace = per_thread.saturating_mul(threads);
    check_address_space(workspace.saturating_add(then), || {
        format!(
            "{what}: faer's matrix-multiply kernel, {} on each of the {threads} threads without it yet, and the factorisation's {} would map",
            format_bytes(per_thread),
            format_bytes(then),
        )
    })
    .map_err(|detail| ProblemError::TooLarge { detail })?;
    make_here();
    if matches!(par, Par::Rayon(_)) {
        rayon::broadcast(|_| make_here());
    }
    Ok(())
}

/// How many of the threads `par` multiplies on have no workspace yet.
fn missing(par: Par) -> u64 {
    let here = u64::from(!RESERVED.get());
    match par {
        Par::Seq => here,
        Par::Rayon(_) => {
            let pool: u64 = rayon::broadcast(|_| u64::from(!RESERVED.get()))
                .into_iter()
                .sum();
            // This thread is counted by the broadcast when it is one of
            // the pool's.
            match rayon::current_thread_index() {
                Some(_) => pool,
                None => pool + here,
            }
        }
    }
}

/// Makes this thread's kernel workspace, if it has none: one product of
/// 17 × 17 matrices (the smallest that faer does not hand to its small
/// kernel), on this thread only.
fn make_here() {
    if RESERVED.get() {
        return;
    }
    let a = Mat::<f64>::zeros(17, 17);
    let mut c = Mat::<f64>::zeros(17, 17);
    first_product(&a, &mut c);
    RESERVED.set(true);
}

/// `c = a a` for the 17 × 17 operands of [`make_here`], on this thread:
/// the product whose first run on a thread makes its kernel workspace.
fn first_product(a: &Mat<f64>, c: &mut Mat<f64>) {
    faer::linalg::matmul::matmul(
        c.as_mut(),
        Accum::Replace,
        a.as_ref(),
        a.as_ref(),
        1.0,
        Par::Seq,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
    /// The address space one fresh thread's first product maps (its
    /// operands, and so the allocator's arena for the thread, made
    /// before).
    fn mapped_by_a_first_product() -> i64 {
        std::thread::spawn(|| {
            let a = Mat::<f64>::zeros(17, 17);
            let mut c = Mat::<f64>::zeros(17, 17);
            let before = crate::limits::mapped_bytes().unwrap();
            first_product(&a, &mut c);
            crate::limits::mapped_bytes().unwrap() as i64 - before as i64
        })
        .join()
        .unwrap()
    }

    /// The estimate is what the kernel maps on a thread's first product
    /// (within a page or two), where faer multiplies through
    /// `private-gemm-x86`. Other tests of this binary may map or unmap
    /// memory meanwhile: one of a few fresh threads must see it exactly.
    #[test]
    #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
    fn the_workspace_is_what_a_thread_maps_on_its_first_product() {
        let avx = std::arch::is_x86_feature_detected!("avx512f")
            || (std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma"));
        if !avx {
            return;
        }
        let per_thread = workspace_bytes() as i64;
        let seen: Vec<i64> = (0..5).map(|_| mapped_by_a_first_product()).collect();
        assert!(
            seen.iter().any(|&g| (g - per_thread).abs() <= 64 << 10),
            "estimated {per_thread}, mapped {seen:?}"
        );
    }
}
