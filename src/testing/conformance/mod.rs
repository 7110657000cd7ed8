//! The conformance kit (cargo feature `proptest`): one call per seam —
//! [`spd`], [`qr`], [`ldlt`] — runs, against any back end, the properties
//! every back end of this crate passes (docs/backends.md §8 states them and
//! the contract behind them, docs/backends.md §1–§7):
//!
//! | property | SPD | QR | `LDLᵀ` |
//! |---|---|---|---|
//! | [`Property::Named`] | ✓ | ✓ | ✓ |
//! | [`Property::Exactness`] | null-space method | null-space method | KKT |
//! | [`Property::RankSets`] | | ✓ | |
//! | [`Property::Operations`] | | ✓ | |
//! | [`Property::Oracle`] | null-space method, elimination | null-space method | KKT |
//! | [`Property::Refusal`] | a matrix that is not positive definite | | a dependent constraint |
//! | [`Property::SeveralFactors`] | ✓ | ✓ | ✓ |
//! | [`Property::Budget`] | ✓ | ✓ | ✓ |
//! | [`Property::Interruption`] | ✓ | ✓ | ✓ |
//! | [`Property::Columns`] | ✓ | ✓ | ✓ |
//!
//! Every property runs [`KitConfig::cases`] generated cases (proptest,
//! with shrinking; interruption a quarter of them, since each case waits
//! twice for [`crate::interrupt::CONSULT_INTERVAL`]), and every property
//! runs even after another failed: the answer lists each failing property
//! with its minimal case and the seed that reproduces it
//! ([`KitFailure`]). A panic inside the back end is a failure of the
//! property that met it, never of the caller.
//!
//! A researcher's own test (`lse-deform = { version = "0.1", features =
//! ["proptest"] }` in `[dev-dependencies]`), with their back end in place
//! of faer's:
//!
//! ```
//! use std::sync::Arc;
//! use lse_deform::backend::spd::FaerLlt;
//! use lse_deform::testing::conformance::{self, KitConfig};
//!
//! let report = conformance::assert_conforms(conformance::spd(
//!     Arc::new(FaerLlt::auto()),
//!     &KitConfig::with_cases(2),
//! ));
//! assert_eq!(report.backend, "faer-auto");
//! ```

// One file per seam: `spd`, `qr` and `ldlt` hold each call with the cases
// and checks only it runs. The leaves they share: `kit` (what the kit
// checks and answers, and the runner), `common` (tolerances, dense
// arithmetic, budgets), `method` (checks through a method, the
// interruption trap) and `strategies` (cases several kits draw). Nothing
// is defined here; the re-exports keep every public path.
mod common;
mod kit;
mod ldlt;
mod method;
mod qr;
mod spd;
mod strategies;

pub use common::{BACKWARD_ERROR, COLUMNS, EXACTNESS, ORACLE};
pub use kit::{
    KitConfig, KitFailure, KitReport, Passed, Property, PropertyFailure, Seam, assert_conforms,
};
pub use ldlt::{KktCase, ldlt};
pub use qr::{qr, qr_operations};
pub use spd::{RefusalCase, spd};
pub use strategies::{GridCase, grid_lower};
