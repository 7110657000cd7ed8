//! The memory budget: inputs and systems that would not fit are refused
//! up front, with the estimate, instead of the process being killed.
//!
//! One [`MemoryBudget`] bounds a whole run: reading the inputs (the bytes
//! read, decompressed and assembled into a mesh) and the solve's
//! precompute alike. The readers take it as their last argument and a
//! solve takes it with its options (`SolveOptions`). The default ([`MemoryBudget::default`]) is
//! `LSE_MEMORY_LIMIT` when set (bytes, with an optional `K`, `M`, `G` or
//! `T` suffix, powers of 1024; anything else, an empty value included, is
//! a [`MemoryLimitError`] from [`MemoryBudget::from_environment`]),
//! otherwise the smallest of three limits of the system, read when the
//! process first asks: the memory the kernel reports as available
//! (`MemAvailable` in `/proc/meminfo`), the process's address-space limit
//! (`RLIMIT_AS`, `ulimit -v`, from `/proc/self/limits`) and the memory
//! limit of its cgroup (v2 `memory.max`, v1 `memory.limit_in_bytes`, the
//! smallest along the cgroup's path); otherwise unlimited. The budget's
//! [`BudgetSource`] names which applied. These estimates are checked
//! against it, each before the memory is allocated:
//!
//! | what | estimate | where |
//! |---|---|---|
//! | a mesh file | [`MESH_BYTES_PER_FILE_BYTE`] × file size (× [`GZIP_EXPANSION`] when compressed) | [`crate::mesh::read_mesh`] |
//! | the bytes of a mesh read from a stream or decompressed | at most budget / [`MESH_BYTES_PER_FILE_BYTE`] bytes are read; one more is a refusal, never a parse of the prefix | [`crate::mesh::read_mesh`], [`crate::mesh::read_mesh_bytes`] |
//! | a mesh header's counts (OFF, PLY) | [`MESH_BYTES_PER_VERTEX`] × vertices + [`MESH_BYTES_PER_FACE`] × faces | the OFF and PLY readers |
//! | a mesh as it is assembled | the same per vertex and per triangle of the lists' capacity (a full list doubles; a polygon's fan counts its triangles), reserved fallibly | every mesh reader, at each vertex and polygon |
//! | a constraints file | [`CONSTRAINT_BYTES_PER_FILE_BYTE`] × file size; a stream at most budget / that many bytes, one more is a refusal | [`crate::constraints::read_constraints_file`] |
//! | a dense Householder block | its reflectors, `8 k min(k, m)` bytes, and its dense `(k − m)²` block of the normal matrix | [`crate::backend::qr::DenseHouseholder`] |
//! | a Cholesky factor | [`FACTOR_BYTES_PER_ENTRY`] × the factor's nnz from the symbolic analysis, on top of the resident set ([`MemoryBudget::check_on_top`]) | every formulation, between analysis and numeric factorisation |
//! | a faer `LLᵀ` or `LDLᵀ` factorisation | on top of the resident set: 8 bytes per stored value, faer's scratch (`factorize_numeric_*_scratch`) and the back end's own arrays; with faer's matrix-multiply kernel's per-thread buffer, against the address-space limit ([`check_address_space`]) | `FaerLlt` and `FaerLdlt`, between analysis and numeric factorisation |
//! | the `R` of a sparse QR of `Bᵀ` | 16 bytes × `nnz(R)` counted from the column elimination tree of `Bᵀ` (never forming `B Bᵀ`) | `sparse-givens` (each column order it tries) and `spqr`, before factoring |
//! | a response basis of `G` groups | `8 k (3 (l + m) + 6 n)` bytes, `k = 3 + 4G` columns ([`crate::handle::HandleBasis::estimated_bytes`]) | [`crate::handle::HandleBasis::new`]; the editor before its precompute |
//! | the four Matrix Market files of `solve` | from their headers together: 48 bytes per announced entry and 8 per column of `A` and `B`, and `C`, `D` dense | [`crate::mtx::read_system`], before any entry is read |
//!
//! What has no size up front is bounded as it is read: a stream (a pipe, a
//! device, gzip-compressed data) given as a mesh or constraints file is
//! read up to the bytes whose estimate fits the budget, and reaching that
//! cap is a refusal that names the budget and the bytes read (what was
//! read is never used: a prefix of a mesh can parse as a smaller mesh); a
//! line of a text mesh or Matrix Market file is at most 16 MiB or 1 MiB,
//! and a Matrix Market file at most 256 bytes per value its size line
//! announces.
//!
//! The estimates are deliberately rough (within a small factor): their job
//! is to turn "killed by the kernel" into a message with numbers in it.

use std::path::Path;
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
    MemoryBudget::default().bytes
}

/// `LSE_MEMORY_LIMIT` read once per process: the budget it sets, the
/// process's ([`MemoryBudget::system`]) when it is not set, or the error
/// when it is set to something that is not a size.
fn environment_budget() -> &'static Result<MemoryBudget, MemoryLimitError> {
    static BUDGET: OnceLock<Result<MemoryBudget, MemoryLimitError>> = OnceLock::new();
    BUDGET.get_or_init(|| budget_from_variable(std::env::var_os(MEMORY_LIMIT_VARIABLE)))
}

/// The environment variable of the default budget.
pub const MEMORY_LIMIT_VARIABLE: &str = "LSE_MEMORY_LIMIT";

/// The budget `LSE_MEMORY_LIMIT`'s value (`None`: not set) names.
fn budget_from_variable(
    value: Option<std::ffi::OsString>,
) -> Result<MemoryBudget, MemoryLimitError> {
    let Some(value) = value else {
        return Ok(MemoryBudget::system());
    };
    match value.to_str().and_then(parse_bytes) {
        Some(bytes) => Ok(MemoryBudget {
            bytes,
            source: BudgetSource::Environment,
        }),
        None => Err(MemoryLimitError {
            value: value.to_string_lossy().into_owned(),
        }),
    }
}

/// `LSE_MEMORY_LIMIT` is set to something that is not a size: a positive
/// number of bytes with an optional unit of [`SIZE_UNITS`]
/// ([`parse_bytes`]). An empty value is such a value too: unset the
/// variable for the default budget.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "LSE_MEMORY_LIMIT={value:?} is not a size (a positive number of bytes, optionally followed by one unit: B, K or KiB, M or MiB, G or GiB, T or TiB, powers of 1024); unset it for the default budget"
)]
pub struct MemoryLimitError {
    /// The variable's value (lossily decoded if it is not UTF-8).
    pub value: String,
}

/// Where a [`MemoryBudget`] comes from, for messages and reports
/// (serialised as its lowercase word, [`BudgetSource::word`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BudgetSource {
    /// Given with the call ([`MemoryBudget::bytes`]: the solve options,
    /// the CLI's `--memory-limit`).
    Option,
    /// `LSE_MEMORY_LIMIT`.
    Environment,
    /// The memory the kernel reported as available (`MemAvailable`) when
    /// first asked.
    Available,
    /// The process's address-space limit (`RLIMIT_AS`, `ulimit -v`).
    AddressSpace,
    /// The memory limit of the process's cgroup (`memory.max` of cgroup
    /// v2, `memory.limit_in_bytes` of v1).
    Cgroup,
    /// No limit (no environment variable and none of the system's limits
    /// known, or [`MemoryBudget::unlimited`]).
    Unlimited,
}

impl BudgetSource {
    /// `option`, `environment`, `available`, `rlimit`, `cgroup` or
    /// `unlimited`: the word of reports.
    pub fn word(self) -> &'static str {
        match self {
            BudgetSource::Option => "option",
            BudgetSource::Environment => "environment",
            BudgetSource::Available => "available",
            BudgetSource::AddressSpace => "rlimit",
            BudgetSource::Cgroup => "cgroup",
            BudgetSource::Unlimited => "unlimited",
        }
    }

    /// Every source.
    const ALL: [BudgetSource; 6] = [
        BudgetSource::Option,
        BudgetSource::Environment,
        BudgetSource::Available,
        BudgetSource::AddressSpace,
        BudgetSource::Cgroup,
        BudgetSource::Unlimited,
    ];

    /// The source whose [`BudgetSource::word`] is `word`.
    fn from_word(word: &str) -> Option<BudgetSource> {
        BudgetSource::ALL.into_iter().find(|s| s.word() == word)
    }

    /// The source as messages name it.
    fn describe(self) -> &'static str {
        match self {
            BudgetSource::Option => "the memory budget of the solve options",
            BudgetSource::Environment => "LSE_MEMORY_LIMIT",
            BudgetSource::Available => {
                "the available memory; set LSE_MEMORY_LIMIT or the solve options' memory budget to change it"
            }
            BudgetSource::AddressSpace => {
                "the process's address-space limit (RLIMIT_AS); set LSE_MEMORY_LIMIT or the solve options' memory budget to a smaller budget"
            }
            BudgetSource::Cgroup => {
                "the memory limit of the process's cgroup; set LSE_MEMORY_LIMIT or the solve options' memory budget to a smaller budget"
            }
            BudgetSource::Unlimited => "no limit",
        }
    }
}

/// The memory a run may use: every estimate of reading its inputs (the
/// bytes read, decompressed and assembled), and of a solve's precompute
/// (the Cholesky or `LDLᵀ` factor's size, the QR factor's `R`, dense
/// Householder blocks, a response basis) is checked against it before the
/// memory is allocated, and what is beyond it is refused with a `TooLarge`
/// error ([`crate::error::ProblemError::TooLarge`],
/// [`crate::error::MeshError::TooLarge`],
/// [`crate::error::ConstraintError::TooLarge`]).
///
/// The default ([`MemoryBudget::default`]) is the process's:
/// `LSE_MEMORY_LIMIT` when set, otherwise the smallest of the available
/// memory, the address-space limit and the cgroup's memory limit,
/// otherwise unlimited (the module documentation).
/// [`MemoryBudget::from_environment`] is the same but reports a malformed
/// `LSE_MEMORY_LIMIT`. [`MemoryBudget::bytes`] sets one for a call,
/// whatever the environment says; the readers
/// ([`crate::mesh::read_mesh`],
/// [`crate::constraints::read_constraints_file`],
/// [`crate::mtx::read_system`]) take it, so one budget can bound a
/// whole run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MemoryBudget {
    bytes: u64,
    source: BudgetSource,
}

impl Default for MemoryBudget {
    /// The process's budget: `LSE_MEMORY_LIMIT` when set, otherwise the
    /// smallest of the system's limits ([`MemoryBudget::system`]), read
    /// once per process. A malformed `LSE_MEMORY_LIMIT` is ignored here;
    /// [`MemoryBudget::from_environment`] reports it, and front doors call
    /// that first.
    fn default() -> MemoryBudget {
        environment_budget()
            .clone()
            .unwrap_or_else(|_| MemoryBudget::system())
    }
}

impl serde::Serialize for MemoryBudget {
    /// `{"bytes": N, "source": "word"}`, `bytes` `null` when unlimited.
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut out = s.serialize_struct("MemoryBudget", 2)?;
        let bytes = (self.bytes != u64::MAX).then_some(self.bytes);
        out.serialize_field("bytes", &bytes)?;
        out.serialize_field("source", self.source.word())?;
        out.end()
    }
}

impl<'de> serde::Deserialize<'de> for MemoryBudget {
    /// The inverse of its serialisation: `{"bytes": N or null, "source":
    /// "word"}` (how a budget travels to other MPI ranks).
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<MemoryBudget, D::Error> {
        #[derive(serde::Deserialize)]
        struct Parts {
            bytes: Option<u64>,
            source: String,
        }
        let parts = Parts::deserialize(d)?;
        let source = BudgetSource::from_word(&parts.source).ok_or_else(|| {
            serde::de::Error::custom(format!("unknown budget source {:?}", parts.source))
        })?;
        Ok(MemoryBudget {
            bytes: parts.bytes.unwrap_or(u64::MAX),
            source,
        })
    }
}

impl MemoryBudget {
    /// A budget of `bytes` for one call, whatever the environment says.
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

    /// The process's budget, or the error of a malformed
    /// `LSE_MEMORY_LIMIT` (read once per process; set but empty is
    /// malformed too). What a front door calls before anything else.
    pub fn from_environment() -> Result<MemoryBudget, MemoryLimitError> {
        environment_budget().clone()
    }

    /// The system's budget, whatever `LSE_MEMORY_LIMIT` says: the smallest
    /// of `MemAvailable` ([`available_memory`]), the address-space limit
    /// ([`address_space_limit`]) and the cgroup's memory limit
    /// ([`cgroup_memory_limit`]), the source naming which; unlimited when
    /// none is known. Read once per process.
    pub fn system() -> MemoryBudget {
        static SYSTEM: OnceLock<MemoryBudget> = OnceLock::new();
        *SYSTEM.get_or_init(|| {
            smallest(&[
                (available_memory(), BudgetSource::Available),
                (address_space_limit(), BudgetSource::AddressSpace),
                (cgroup_memory_limit(), BudgetSource::Cgroup),
            ])
        })
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
        let (estimate, budget) = format_apart(estimate, self.bytes);
        Err(format!(
            "{} about {estimate}, more than the memory budget of {budget} ({})",
            what(),
            self.source.describe(),
        ))
    }

    /// [`MemoryBudget::check`] of `extra` bytes still to be allocated on
    /// top of what the process holds now ([`resident_bytes`]): the budget
    /// is of the whole process, so what it already holds (the mesh, the
    /// problem, the matrices) counts too. `what` names `extra`.
    pub(crate) fn check_on_top(
        self,
        extra: u64,
        what: impl FnOnce() -> String,
    ) -> Result<(), String> {
        let resident = resident_bytes().unwrap_or(0);
        let what = std::cell::Cell::new(Some(what));
        let name = || what.take().map(|w| w()).unwrap_or_default();
        self.check(extra.saturating_add(resident), || {
            format!(
                "{} {} on top of the {} this process holds; together",
                name(),
                format_bytes(extra),
                format_bytes(resident)
            )
        })?;
        // Under an address-space limit it is the mapped bytes that the
        // kernel compares with the limit, and they exceed the resident
        // ones (thread stacks, the allocator's reserved heaps, mapped
        // files): the same `extra` must fit on top of them too.
        check_address_space(extra, name)
    }
}

/// Under an address-space limit (`RLIMIT_AS`), limits glibc's `malloc` to
/// one arena (`mallopt(M_ARENA_MAX, 1)`), once per process; `true` when
/// it is (now or already) in force. Without such a limit it does nothing.
///
/// Why: glibc gives each thread that allocates an arena of its own, up to
/// 8 × the number of cores, and reserves each one's heap as a 64 MiB
/// mapping (`HEAP_MAX_SIZE`, twice the largest mmap threshold on 64-bit)
/// at the thread's first allocation. Those pages are never touched, so
/// they cost no memory, but every byte counts against `RLIMIT_AS`: on a
/// 2-core machine 16 arenas reserve 1 GiB, more than the limits a user
/// sets with `ulimit -v`, and they appear at a moment no estimate made
/// before the work can see (a thread of rayon's pool allocating for the
/// first time), so an ordinary infallible allocation then aborts the
/// process. With one arena every thread allocates from the main heap,
/// which grows (and counts) only as far as it is used, so the mapped size
/// the budget checks against ([`check_address_space`]) is what the
/// process really has. The cost is contention on one lock, which the
/// factorisations hardly see (they allocate their scratch once per call).
/// It is applied only under an address-space limit (where the arenas'
/// reservation matters), and only when a door asks: the command-line tool
/// at start, before any thread, and the Python module when it is loaded
/// (arenas made before then stay, and new threads share them); the
/// library itself changes no allocator setting. Elsewhere than glibc it
/// does nothing and returns `false`.
pub fn cap_allocator_arenas() -> bool {
    static CAPPED: OnceLock<bool> = OnceLock::new();
    *CAPPED.get_or_init(|| {
        if address_space_limit().is_none() {
            return false;
        }
        #[cfg(all(target_os = "linux", target_env = "gnu"))]
        {
            // SAFETY: mallopt only sets a parameter of the allocator; it
            // is safe to call at any time, from any thread.
            unsafe { libc::mallopt(libc::M_ARENA_MAX, 1) == 1 }
        }
        #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
        {
            false
        }
    })
}

/// `Err(detail)` when mapping `extra` more bytes of address space, on top
/// of what the process has mapped ([`mapped_bytes`]), would exceed its
/// address-space limit ([`address_space_limit`], read now; `Ok` when there
/// is none). The kernel compares every new mapping with that limit, and
/// past it an allocation fails; a library that cannot report the failure
/// (faer's matrix-multiply kernel) aborts the process. Mapped is not
/// resident: reserved but untouched pages count here, not in
/// [`resident_bytes`]. `what` names `extra`.
pub(crate) fn check_address_space(extra: u64, what: impl FnOnce() -> String) -> Result<(), String> {
    let Some(limit) = address_space_limit() else {
        return Ok(());
    };
    let mapped = mapped_bytes().unwrap_or(0);
    let budget = MemoryBudget {
        bytes: limit,
        source: BudgetSource::AddressSpace,
    };
    budget.check(mapped.saturating_add(extra), || {
        format!(
            "{} {} of address space on top of the {} this process has mapped; together",
            what(),
            format_bytes(extra),
            format_bytes(mapped)
        )
    })
}

/// Bytes of this process's resident memory (`VmRSS` of
/// `/proc/self/status`), where the system says; what a check of memory
/// still to be allocated adds to its estimate when the budget is of the
/// whole process.
pub(crate) fn resident_bytes() -> Option<u64> {
    status_bytes("VmRSS:")
}

/// Bytes of address space this process has mapped (`VmSize` of
/// `/proc/self/status`), what the kernel holds against `RLIMIT_AS`.
pub(crate) fn mapped_bytes() -> Option<u64> {
    status_bytes("VmSize:")
}

/// The field `name` (with its colon) of `/proc/self/status`, given there
/// in kB (KiB), in bytes.
fn status_bytes(name: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(name))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The most bytes a whole-or-refused read of `file` (named `name`) may
/// take within `budget` at `per_byte` bytes of memory per byte read:
/// a regular file's size is checked first, so that one beyond the budget
/// is refused before it is read (`Err` with the detail); a stream (a pipe,
/// a device) reports no size and is capped only. The caller reads at most
/// the cap plus one byte and refuses the read that reaches it
/// ([`beyond_the_cap`]).
pub(crate) fn file_read_cap(
    file: &std::fs::File,
    name: &str,
    budget: MemoryBudget,
    per_byte: u64,
) -> Result<u64, String> {
    // Only a regular file's length is the number of bytes it will deliver
    // (a pipe reports 0).
    let size = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len());
    if let Some(size) = size {
        budget.check(size.saturating_mul(per_byte), || {
            format!("{name} ({}) would need", format_bytes(size))
        })?;
    }
    Ok(budget.limit() / per_byte)
}

/// The detail of a refusal of `name`, a stream that went on beyond `cap`,
/// the bytes read (`after`: e.g. " after decompression"), the most that
/// `budget` allows at `per_byte` bytes of memory (of `of`) per byte read.
pub(crate) fn beyond_the_cap(
    budget: MemoryBudget,
    name: &str,
    cap: u64,
    after: &str,
    per_byte: u64,
    of: &str,
) -> String {
    format!(
        "{name} goes on beyond the {} read{after}, the most that the memory budget of {} ({}) allows at {per_byte} bytes of {of} per byte",
        format_bytes(cap),
        format_bytes(budget.bytes),
        budget.source.describe(),
    )
}

/// The smallest known limit (the first of equal ones), unlimited when none
/// is known.
fn smallest(limits: &[(Option<u64>, BudgetSource)]) -> MemoryBudget {
    limits
        .iter()
        .filter_map(|&(bytes, source)| bytes.map(|bytes| MemoryBudget { bytes, source }))
        .reduce(|best, b| if b.bytes < best.bytes { b } else { best })
        .unwrap_or_else(MemoryBudget::unlimited)
}

/// `MemAvailable` of `/proc/meminfo`, bytes (Linux only).
pub(crate) fn available_memory() -> Option<u64> {
    parse_meminfo(&std::fs::read_to_string("/proc/meminfo").ok()?)
}

/// `MemAvailable` of the text of `/proc/meminfo` (kB, i.e. KiB), bytes.
fn parse_meminfo(info: &str) -> Option<u64> {
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The soft limit of the process's address space (`RLIMIT_AS`, what
/// `ulimit -v` sets), bytes, from `/proc/self/limits` (Linux only; read
/// there rather than through `getrlimit` so the crate needs no `libc`);
/// `None` when unlimited or unknown.
pub fn address_space_limit() -> Option<u64> {
    parse_address_space(&std::fs::read_to_string("/proc/self/limits").ok()?)
}

/// The soft limit of the line `Max address space  SOFT  HARD  bytes` of
/// `/proc/self/limits`; `None` for `unlimited`.
fn parse_address_space(limits: &str) -> Option<u64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// The memory limit of the process's cgroup, bytes: the smallest
/// `memory.max` (cgroup v2) or `memory.limit_in_bytes` (v1) of its cgroup
/// and the cgroup's ancestors under `/sys/fs/cgroup` (a limit applies to
/// everything below it), as named in `/proc/self/cgroup`; `None` when
/// there is no limit (`max`, or v1's near-`i64::MAX` "no limit") or no
/// cgroup file (Linux only).
pub(crate) fn cgroup_memory_limit() -> Option<u64> {
    let membership = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    cgroup_limit_under(Path::new("/sys/fs/cgroup"), &membership)
}

/// [`cgroup_memory_limit`] with the cgroup file system mounted at `root`
/// and `membership` the text of `/proc/self/cgroup`: lines
/// `ID:CONTROLLERS:PATH`, `0::PATH` for v2 (files under `root`), a
/// `memory` controller for v1 (files under `root/memory`).
fn cgroup_limit_under(root: &Path, membership: &str) -> Option<u64> {
    /// Values from here up mean "no limit" (v1 writes `i64::MAX` rounded
    /// down to a page).
    const NO_LIMIT: u64 = 1 << 62;
    let mut limits = Vec::new();
    for line in membership.lines() {
        let mut fields = line.splitn(3, ':');
        let (Some(id), Some(controllers), Some(path)) =
            (fields.next(), fields.next(), fields.next())
        else {
            continue;
        };
        let (dir, file) = if id == "0" && controllers.is_empty() {
            (root.to_path_buf(), "memory.max")
        } else if controllers.split(',').any(|c| c == "memory") {
            (root.join("memory"), "memory.limit_in_bytes")
        } else {
            continue;
        };
        let mut cgroup = dir.join(path.trim_start_matches('/'));
        loop {
            if let Ok(text) = std::fs::read_to_string(cgroup.join(file))
                && let Ok(bytes) = text.trim().parse::<u64>()
                && bytes < NO_LIMIT
            {
                limits.push(bytes);
            }
            if cgroup == dir || !cgroup.pop() {
                break;
            }
        }
    }
    limits.into_iter().min()
}

/// The units [`parse_bytes`] accepts, for messages.
pub const SIZE_UNITS: &str = "B, K or KiB, M or MiB, G or GiB, T or TiB (powers of 1024, any case)";

/// `"8G"`, `"512 MiB"`, `"1000000"` → bytes: decimal digits, then optional
/// spaces and at most one unit of [`SIZE_UNITS`] (powers of 1024); `None`
/// if malformed (any other unit, a unit repeated, a sign, a fraction) or
/// zero.
pub fn parse_bytes(s: &str) -> Option<u64> {
    let s = s.trim();
    let (digits, unit) = match s.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((i, _)) => s.split_at(i),
        None => (s, ""),
    };
    let shift = match unit.trim_start().to_ascii_uppercase().as_str() {
        "" | "B" => 0,
        "K" | "KIB" => 10,
        "M" | "MIB" => 20,
        "G" | "GIB" => 30,
        "T" | "TIB" => 40,
        _ => return None,
    };
    let n: u64 = digits.parse().ok()?;
    n.checked_mul(1u64 << shift).filter(|&b| b > 0)
}

/// `1.5 GiB`, `300 MiB`, … for messages.
pub(crate) fn format_bytes(bytes: u64) -> String {
    format_bytes_to(bytes, 1)
}

/// [`format_bytes`] with `decimals` decimals.
fn format_bytes_to(bytes: u64, decimals: usize) -> String {
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
        format!("{value:.decimals$} {}", UNITS[unit])
    }
}

/// `a` and `b` as [`format_bytes`] writes them, with as many decimals (up
/// to three) as it takes to tell them apart, and in bytes when three do
/// not: an estimate just over a budget never reads as equal to it.
pub(crate) fn format_apart(a: u64, b: u64) -> (String, String) {
    for decimals in 1..=3 {
        let (x, y) = (format_bytes_to(a, decimals), format_bytes_to(b, decimals));
        if x != y || a == b {
            return (x, y);
        }
    }
    (format!("{a} bytes"), format!("{b} bytes"))
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

    /// Every source and an unlimited budget survive a round trip through
    /// JSON (how rank 0's budget reaches the other MPI ranks), and an
    /// unknown source is an error, not a default.
    #[test]
    fn budgets_round_trip_through_json() {
        let bounded = BudgetSource::ALL
            .into_iter()
            .filter(|&s| s != BudgetSource::Unlimited);
        for source in bounded {
            let budget = MemoryBudget {
                bytes: 7 << 20,
                source,
            };
            let text = serde_json::to_string(&budget).unwrap();
            assert_eq!(
                serde_json::from_str::<MemoryBudget>(&text).unwrap(),
                budget,
                "{text}"
            );
        }
        let unlimited = serde_json::to_string(&MemoryBudget::unlimited()).unwrap();
        assert_eq!(unlimited, r#"{"bytes":null,"source":"unlimited"}"#);
        assert_eq!(
            serde_json::from_str::<MemoryBudget>(&unlimited).unwrap(),
            MemoryBudget::unlimited()
        );
        let odd = serde_json::from_str::<MemoryBudget>(r#"{"bytes":1,"source":"guess"}"#);
        assert!(odd.unwrap_err().to_string().contains("guess"));
    }

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
        assert_eq!(parse_bytes("3 KiB"), Some(3 << 10));
        assert_eq!(parse_bytes("7b"), Some(7));
    }

    /// A unit outside the list, or two units, is refused. (Before: the
    /// parser stripped any number of trailing `iB`s, so `5iB`, `5 ib`,
    /// `5BIB` and `5KiBiB` were sizes.)
    #[test]
    fn units_outside_the_list_are_refused() {
        for word in [
            "5iB", "5 ib", "5BIB", "5KiBiB", "5KB", "5 K B", "5Ki", "1.5G", "+5", "5GiBs",
        ] {
            assert_eq!(parse_bytes(word), None, "{word}");
        }
    }

    #[test]
    fn formats_sizes() {
        assert_eq!(format_bytes(512), "512 B");
        assert_eq!(format_bytes(3 << 29), "1.5 GiB");
    }

    /// A finding of the latest round of faults: at 1120M the refusal read "about 1.1 GiB,
    /// more than … 1.1 GiB".
    #[test]
    fn a_refusal_tells_the_estimate_from_the_budget() {
        let budget = 1120 << 20;
        assert_eq!(
            format_apart(1160 << 20, budget),
            ("1.13 GiB".into(), "1.09 GiB".into())
        );
        assert_eq!(
            format_apart(budget + 1, budget),
            ("1174405121 bytes".into(), "1174405120 bytes".into())
        );
        assert_eq!(format_apart(3 << 30, 1 << 30).0, "3.0 GiB");
        let e = MemoryBudget::bytes(budget)
            .check(1160 << 20, || "the factor needs".into())
            .unwrap_err();
        assert!(
            e.contains("about 1.13 GiB, more than the memory budget of 1.09 GiB"),
            "{e}"
        );
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

    #[test]
    fn a_malformed_environment_value_is_an_error_naming_it() {
        for value in ["abc", "-1", "0", "1.5G", "", " ", "12X"] {
            let e = budget_from_variable(Some(value.into())).unwrap_err();
            assert_eq!(e.value, value);
            let shown = e.to_string();
            assert!(
                shown.starts_with(&format!("LSE_MEMORY_LIMIT={value:?} is not a size")),
                "{shown}"
            );
        }
        let b = budget_from_variable(Some("2G".into())).unwrap();
        assert_eq!(
            (b.limit(), b.source()),
            (2 << 30, BudgetSource::Environment)
        );
        assert_eq!(budget_from_variable(None), Ok(MemoryBudget::system()));
    }

    #[test]
    fn the_system_budget_is_the_smallest_known_limit() {
        use BudgetSource::*;
        let b = smallest(&[
            (Some(8 << 30), Available),
            (None, AddressSpace),
            (Some(1 << 30), Cgroup),
        ]);
        assert_eq!((b.limit(), b.source()), (1 << 30, Cgroup));
        let b = smallest(&[
            (Some(8 << 30), Available),
            (Some(4 << 30), AddressSpace),
            (None, Cgroup),
        ]);
        assert_eq!((b.limit(), b.source()), (4 << 30, AddressSpace));
        let b = smallest(&[(Some(1 << 30), Available), (Some(1 << 30), Cgroup)]);
        assert_eq!(b.source(), Available);
        assert_eq!(smallest(&[(None, Available)]), MemoryBudget::unlimited());
    }

    #[test]
    fn reads_meminfo_and_the_address_space_limit() {
        let meminfo = "MemTotal:       32000000 kB\nMemAvailable:   2048 kB\n";
        assert_eq!(parse_meminfo(meminfo), Some(2 << 20));
        let limits = "Limit                     Soft Limit           Hard Limit           Units     \n\
                      Max stack size            8388608              unlimited            bytes     \n\
                      Max address space         1073741824           unlimited            bytes     \n";
        assert_eq!(parse_address_space(limits), Some(1 << 30));
        let unlimited = limits.replace("1073741824", "unlimited ");
        assert_eq!(parse_address_space(&unlimited), None);
    }

    #[test]
    fn reads_the_cgroup_limit_along_the_path_in_v1_and_v2() {
        let root = tempfile::tempdir().unwrap();
        let write = |path: &str, text: &str| {
            let path = root.path().join(path);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        };
        // v2: the smallest along /a/b, "max" meaning none.
        write("a/memory.max", "1073741824\n");
        write("a/b/memory.max", "max\n");
        assert_eq!(cgroup_limit_under(root.path(), "0::/a/b\n"), Some(1 << 30));
        write("a/b/memory.max", "536870912\n");
        assert_eq!(cgroup_limit_under(root.path(), "0::/a/b\n"), Some(1 << 29));
        // v1: the memory controller's hierarchy; near i64::MAX means none.
        write("memory/p/memory.limit_in_bytes", "9223372036854771712\n");
        let v1 = "4:memory:/p\n3:cpuset:/\n";
        assert_eq!(cgroup_limit_under(root.path(), v1), None);
        write("memory/p/memory.limit_in_bytes", "268435456\n");
        assert_eq!(cgroup_limit_under(root.path(), v1), Some(256 << 20));
        assert_eq!(cgroup_limit_under(root.path(), "1:cpu:/\n"), None);
    }

    #[test]
    fn a_budget_serialises_as_bytes_and_the_source_word() {
        let json = serde_json::to_string(&MemoryBudget::bytes(1024)).unwrap();
        assert_eq!(json, r#"{"bytes":1024,"source":"option"}"#);
        let json = serde_json::to_string(&MemoryBudget::unlimited()).unwrap();
        assert_eq!(json, r#"{"bytes":null,"source":"unlimited"}"#);
    }
}
