//! The memory budget: inputs and systems that would not fit are refused up
//! front, with the estimate, instead of the process being killed.
//!
//! A solve's budget is a [`MemoryBudget`], one of its options
//! (`SolveOptions`). Its default, which is also the budget of reading input
//! files, is `LSE_MEMORY_LIMIT` when set (bytes, with an optional `K`, `M`,
//! `G` or `T` suffix, powers of 1024), otherwise the memory the kernel
//! reports as available (`MemAvailable` in `/proc/meminfo`) when the process
//! starts using it, otherwise unlimited. These estimates are checked against
//! it, each before the memory is allocated:
//!
//! | what | estimate | where |
//! |---|---|---|
//! | a mesh file | [`MESH_BYTES_PER_FILE_BYTE`] × file size (× [`GZIP_EXPANSION`] when compressed) | [`crate::mesh::read_mesh`] |
//! | a mesh header's counts (OFF, PLY) | [`MESH_BYTES_PER_VERTEX`] × vertices + [`MESH_BYTES_PER_FACE`] × faces | the OFF and PLY readers |
//! | a constraints file | [`CONSTRAINT_BYTES_PER_FILE_BYTE`] × file size | [`crate::constraints::read_constraints`] |
//! | a dense Householder block | its reflectors, `8 k min(k, m)` bytes, and its dense `(k − m)²` block of the normal matrix | [`crate::backend::qr::DenseHouseholder`] |
//! | a Cholesky factor | [`FACTOR_BYTES_PER_ENTRY`] × the factor's nnz from the symbolic analysis | every formulation, between analysis and numeric factorisation |
//! | the `R` of a sparse QR of `Bᵀ` | 16 bytes × `nnz(R)` counted from the column elimination tree of `Bᵀ` (never forming `B Bᵀ`) | `sparse-givens` (each column order it tries) and `spqr`, before factoring |
//! | a response basis of `G` groups | `8 k (3 (l + m) + 6 n)` bytes, `k = 3 + 4G` columns ([`crate::handle::HandleBasis::estimated_bytes`]) | [`crate::handle::HandleBasis::new`]; the editor before its precompute |
//! | the four Matrix Market files of `solve` | from their headers together: 48 bytes per announced entry and 8 per column of `A` and `B`, and `C`, `D` dense | [`crate::mtx::read_system`], before any entry is read |
//!
//! What has no size up front is bounded as it is read: a stream (a pipe, a
//! device) given as a mesh or constraints file is read up to the bytes
//! whose estimate fits the budget and refused beyond, a line of a text mesh
//! or Matrix Market file is at most 16 MiB or 1 MiB, and a Matrix Market
//! file at most 256 bytes per value its size line announces.
//!
//! The estimates are deliberately rough (within a small factor): their job
//! is to turn "killed by the kernel" into a message with numbers in it.

use std::sync::OnceLock;

/// Bytes of a loaded mesh per byte of an uncompressed file, an upper
/// estimate: a binary PLY with `float` coordinates and `int` indices holds
/// 12 bytes per vertex and 13 per face in the file, and 32 + 32 in memory
/// (positions, faces and their source line numbers), and the PLY reader
/// keeps the file's bytes too.
pub const MESH_BYTES_PER_FILE_BYTE: u64 = 4;

/// Assumed expansion of gzip-compressed mesh files (text meshes typically
/// compress 3–4×).
pub const GZIP_EXPANSION: u64 = 4;

/// Bytes of a loaded mesh per vertex: three `f64` and a line number.
pub const MESH_BYTES_PER_VERTEX: u64 = 32;

/// Bytes of a loaded mesh per face: three `usize` and a line number.
pub const MESH_BYTES_PER_FACE: u64 = 32;

/// Bytes of parsing per byte of a constraints file: the constraints, built
/// as the file is read (no JSON document tree; `tests/parse_memory.rs`
/// measures about 3 bytes per byte of a typical file, most of it the moment
/// the list doubles its capacity), with room for files where every
/// constraint names a group of its own.
pub const CONSTRAINT_BYTES_PER_FILE_BYTE: u64 = 8;

/// Bytes per entry of a Cholesky factor: the `f64` value and, amortised over
/// a supernode, a little of its row index.
pub const FACTOR_BYTES_PER_ENTRY: u64 = 12;

/// The default memory budget in bytes (see the module documentation), read
/// once per process: what [`MemoryBudget::default`] holds.
pub fn memory_budget() -> u64 {
    default_budget().bytes
}

/// The default budget with its source, read once.
fn default_budget() -> MemoryBudget {
    static BUDGET: OnceLock<MemoryBudget> = OnceLock::new();
    *BUDGET.get_or_init(|| {
        let from_env = std::env::var("LSE_MEMORY_LIMIT")
            .ok()
            .and_then(|s| parse_bytes(&s));
        match (from_env, available_memory()) {
            (Some(bytes), _) => MemoryBudget {
                bytes,
                source: BudgetSource::Environment,
            },
            (None, Some(bytes)) => MemoryBudget {
                bytes,
                source: BudgetSource::Available,
            },
            (None, None) => MemoryBudget::unlimited(),
        }
    })
}

/// Where a [`MemoryBudget`] comes from, for messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BudgetSource {
    /// Given with the solve ([`MemoryBudget::bytes`], the solve options).
    Option,
    /// `LSE_MEMORY_LIMIT`.
    Environment,
    /// The memory the kernel reported as available when first asked.
    Available,
    /// No limit (no environment variable and no `/proc/meminfo`, or
    /// [`MemoryBudget::unlimited`]).
    Unlimited,
}

/// The memory a solve may use: every estimate of its precompute (the
/// Cholesky or `LDLᵀ` factor's size, the QR factor's `R`, dense Householder
/// blocks, a response basis) is checked against it before the memory is
/// allocated, and a solve beyond it is refused with
/// [`crate::error::ProblemError::TooLarge`].
///
/// The default ([`MemoryBudget::default`]) is the process's:
/// `LSE_MEMORY_LIMIT` when set, otherwise the available memory, otherwise
/// unlimited (the module documentation), so a solve given no budget
/// behaves as one did before budgets were options. [`MemoryBudget::bytes`]
/// sets one for a solve, whatever the environment says. Input files are
/// read before any solve and are checked against the default.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MemoryBudget {
    bytes: u64,
    source: BudgetSource,
}

impl Default for MemoryBudget {
    /// The process's budget: `LSE_MEMORY_LIMIT` when set, otherwise the
    /// available memory, otherwise unlimited (read once per process).
    fn default() -> MemoryBudget {
        default_budget()
    }
}

impl MemoryBudget {
    /// A budget of `bytes` for one solve, whatever the environment says.
    pub fn bytes(bytes: u64) -> MemoryBudget {
        MemoryBudget {
            bytes,
            source: BudgetSource::Option,
        }
    }

    /// No limit.
    pub fn unlimited() -> MemoryBudget {
        MemoryBudget {
            bytes: u64::MAX,
            source: BudgetSource::Unlimited,
        }
    }

    /// The budget in bytes (`u64::MAX` when unlimited).
    pub fn limit(self) -> u64 {
        self.bytes
    }

    /// Where it comes from.
    pub fn source(self) -> BudgetSource {
        self.source
    }

    /// `Err(detail)` when `estimate` exceeds the budget; the detail names
    /// the estimate, what it is made of, the budget and where the budget
    /// comes from.
    pub fn check(self, estimate: u64, what: impl FnOnce() -> String) -> Result<(), String> {
        if estimate <= self.bytes {
            return Ok(());
        }
        let source = match self.source {
            BudgetSource::Option => "the memory budget of the solve options",
            BudgetSource::Environment => "LSE_MEMORY_LIMIT",
            BudgetSource::Available | BudgetSource::Unlimited => {
                "the available memory; set LSE_MEMORY_LIMIT or the solve options' memory budget to change it"
            }
        };
        Err(format!(
            "{} about {}, more than the memory budget of {} ({source})",
            what(),
            format_bytes(estimate),
            format_bytes(self.bytes),
        ))
    }
}

/// `MemAvailable` of `/proc/meminfo`, bytes (Linux only).
pub fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// `"8G"`, `"512M"`, `"1000000"` → bytes (powers of 1024); `None` if
/// malformed or zero.
pub fn parse_bytes(s: &str) -> Option<u64> {
    let s = s.trim();
    let (digits, unit) = match s.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((i, _)) => s.split_at(i),
        None => (s, ""),
    };
    let shift = match unit.trim().to_ascii_uppercase().trim_end_matches("IB") {
        "" | "B" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return None,
    };
    let n: u64 = digits.parse().ok()?;
    n.checked_mul(1u64 << shift).filter(|&b| b > 0)
}

/// `1.5 GiB`, `300 MiB`, … for messages.
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// `Err(detail)` when `estimate` exceeds the default budget
/// ([`MemoryBudget::default`]): the checks of input files, which come
/// before any solve.
pub fn check(estimate: u64, what: impl FnOnce() -> String) -> Result<(), String> {
    MemoryBudget::default().check(estimate, what)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_sizes() {
        assert_eq!(parse_bytes("1000"), Some(1000));
        assert_eq!(parse_bytes("8G"), Some(8 << 30));
        assert_eq!(parse_bytes("512 MiB"), Some(512 << 20));
        assert_eq!(parse_bytes("2k"), Some(2048));
        assert_eq!(parse_bytes("0"), None);
        assert_eq!(parse_bytes("-1"), None);
        assert_eq!(parse_bytes("12X"), None);
        assert_eq!(parse_bytes("99999999999T"), None);
    }

    #[test]
    fn formats_sizes() {
        assert_eq!(format_bytes(512), "512 B");
        assert_eq!(format_bytes(3 << 29), "1.5 GiB");
    }

    #[test]
    fn check_names_the_numbers() {
        let budget = MemoryBudget::bytes(10);
        assert!(budget.check(10, || unreachable!()).is_ok());
        let e = MemoryBudget::bytes(1 << 30)
            .check(3 << 30, || "the factor's 1e9 entries need".into())
            .unwrap_err();
        assert!(
            e.starts_with("the factor's 1e9 entries need about 3.0 GiB"),
            "{e}"
        );
        assert!(e.contains("budget of 1.0 GiB"), "{e}");
        assert!(
            e.ends_with("(the memory budget of the solve options)"),
            "{e}"
        );
    }
}
