//! Linear-algebra back ends behind the two traits the formulations are
//! written against: [`qr::QrBackend`] (QR of `Bᵀ` with rank detection) and
//! [`spd::SpdBackend`] (sparse Cholesky with symbolic and numeric phases kept
//! apart).

pub mod qr;
pub mod spd;
#[cfg(feature = "suitesparse")]
mod suitesparse;
