//! The names of the crate's own back ends: [`SpdKind`], [`LdltKind`] and
//! [`QrKind`], the typed choices the CLI, Python and the editor parse from
//! words and the reports print. A leaf under the seams: the built-in back
//! ends name themselves by their kind, and the
//! [`catalogue`](crate::backend::catalogue), above them, makes a back end
//! from its kind ([`SpdKind::backend`], [`LdltKind::backend`],
//! [`QrKind::backend`]). Public as `backend::spd::SpdKind`,
//! `backend::ldlt::LdltKind` and `backend::qr::QrKind`.

/// An SPD back end, as a typed choice ([`SpdKind::backend`] makes it;
/// `FromStr` reads the CLI's and Python's names, [`SpdKind::name`] gives
/// them back).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SpdKind {
    /// faer's supernodal Cholesky.
    FaerSupernodal,
    /// faer's simplicial (column by column) Cholesky.
    FaerSimplicial,
    /// faer's choice between the two, from the symbolic factor's density.
    FaerAuto,
    /// nalgebra-sparse's CSC Cholesky.
    Nalgebra,
    /// SuiteSparse CHOLMOD (cargo feature `suitesparse`).
    Cholmod,
    /// MUMPS's multifrontal Cholesky, on one rank or many (cargo feature
    /// `mumps`).
    Mumps,
}

impl SpdKind {
    /// Every kind, in the order they are listed to users.
    pub const ALL: [SpdKind; 6] = [
        SpdKind::FaerSupernodal,
        SpdKind::FaerSimplicial,
        SpdKind::FaerAuto,
        SpdKind::Nalgebra,
        SpdKind::Cholmod,
        SpdKind::Mumps,
    ];

    /// The name the CLI and Python use.
    pub fn name(self) -> &'static str {
        match self {
            SpdKind::FaerSupernodal => "faer-supernodal",
            SpdKind::FaerSimplicial => "faer-simplicial",
            SpdKind::FaerAuto => "faer-auto",
            SpdKind::Nalgebra => "nalgebra",
            SpdKind::Cholmod => "cholmod",
            SpdKind::Mumps => "mumps",
        }
    }

    /// Whether this build has the back end (`Cholmod` needs the cargo
    /// feature `suitesparse`, `Mumps` the feature `mumps`).
    pub fn in_this_build(self) -> bool {
        let missing = (self == SpdKind::Cholmod && !cfg!(feature = "suitesparse"))
            || (self == SpdKind::Mumps && !cfg!(feature = "mumps"));
        !missing
    }

    /// The kinds of this build, in [`SpdKind::ALL`]'s order.
    pub fn available() -> Vec<SpdKind> {
        SpdKind::ALL
            .into_iter()
            .filter(|k| k.in_this_build())
            .collect()
    }
}

impl crate::choice::Word for SpdKind {
    const WHAT: &'static str = "SPD back end";
    fn all() -> &'static [Self] {
        &SpdKind::ALL
    }
    fn name(self) -> &'static str {
        SpdKind::name(self)
    }
    fn listed() -> Vec<Self> {
        SpdKind::available()
    }
}

crate::choice::word_traits!(SpdKind);

/// An `LDLᵀ` back end, as a typed choice ([`LdltKind::backend`] makes
/// it); serialised in reports as its word.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum LdltKind {
    /// faer's choice between the two below, from the symbolic factor's
    /// density.
    #[default]
    FaerAuto,
    /// faer's simplicial (column by column) `LDLᵀ`.
    FaerSimplicial,
    /// faer's supernodal `LDLᵀ` (dense blocks of columns).
    FaerSupernodal,
    /// MUMPS's multifrontal `LDLᵀ` in the given order, on one rank or many
    /// (cargo feature `mumps`).
    Mumps,
}

impl LdltKind {
    /// Every kind, in the order they are listed to users.
    pub const ALL: [LdltKind; 4] = [
        LdltKind::FaerAuto,
        LdltKind::FaerSimplicial,
        LdltKind::FaerSupernodal,
        LdltKind::Mumps,
    ];

    /// The word in reports.
    pub fn name(self) -> &'static str {
        match self {
            LdltKind::FaerAuto => "faer-ldlt-auto",
            LdltKind::FaerSimplicial => "faer-ldlt-simplicial",
            LdltKind::FaerSupernodal => "faer-ldlt-supernodal",
            LdltKind::Mumps => "mumps-ldlt",
        }
    }

    /// The `LDLᵀ` variant an SPD back-end choice selects (the CLI's and
    /// Python's `spd` for the KKT method): faer's automatic, simplicial or
    /// supernodal factorisation for the faer kinds; `None` for the others,
    /// which have no `LDLᵀ`.
    pub fn for_spd(spd: SpdKind) -> Option<LdltKind> {
        match spd {
            SpdKind::FaerAuto => Some(LdltKind::FaerAuto),
            SpdKind::FaerSimplicial => Some(LdltKind::FaerSimplicial),
            SpdKind::FaerSupernodal => Some(LdltKind::FaerSupernodal),
            SpdKind::Mumps => Some(LdltKind::Mumps),
            SpdKind::Nalgebra | SpdKind::Cholmod => None,
        }
    }

    /// Whether this build has the back end (`Mumps` needs the cargo
    /// feature `mumps`).
    pub(crate) fn in_this_build(self) -> bool {
        self != LdltKind::Mumps || cfg!(feature = "mumps")
    }
}

impl crate::choice::Word for LdltKind {
    const WHAT: &'static str = "LDLT back end";
    fn all() -> &'static [Self] {
        &LdltKind::ALL
    }
    fn name(self) -> &'static str {
        LdltKind::name(self)
    }
}

crate::choice::word_traits!(LdltKind);

/// A QR back end, as a typed choice ([`QrKind::backend`] makes it;
/// `FromStr` reads the CLI's and Python's names, [`QrKind::name`] gives
/// them back).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum QrKind {
    /// [`DenseHouseholder`](crate::backend::qr::DenseHouseholder): the paper's method per independent block.
    DenseHouseholder,
    /// [`SparseGivens`](crate::backend::qr::SparseGivens): row-by-row Givens on the whole sparse `Bᵀ`.
    SparseGivens,
    /// SuiteSparseQR (cargo feature `suitesparse`).
    Spqr,
}

impl QrKind {
    /// Every kind, in the order they are listed to users.
    pub const ALL: [QrKind; 3] = [QrKind::DenseHouseholder, QrKind::SparseGivens, QrKind::Spqr];

    /// The name the CLI and Python use.
    pub fn name(self) -> &'static str {
        match self {
            QrKind::DenseHouseholder => "dense-householder",
            QrKind::SparseGivens => "sparse-givens",
            QrKind::Spqr => "spqr",
        }
    }

    /// Whether this build has the back end (`Spqr` needs the cargo feature
    /// `suitesparse`).
    pub fn in_this_build(self) -> bool {
        self != QrKind::Spqr || cfg!(feature = "suitesparse")
    }

    /// The kinds of this build, in [`QrKind::ALL`]'s order.
    pub fn available() -> Vec<QrKind> {
        QrKind::ALL
            .into_iter()
            .filter(|k| k.in_this_build())
            .collect()
    }
}

impl crate::choice::Word for QrKind {
    const WHAT: &'static str = "QR back end";
    fn all() -> &'static [Self] {
        &QrKind::ALL
    }
    fn name(self) -> &'static str {
        QrKind::name(self)
    }
    fn listed() -> Vec<Self> {
        QrKind::available()
    }
}

crate::choice::word_traits!(QrKind);
