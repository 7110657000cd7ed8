//! Typed configuration choices: the [`Word`] trait every word enum
//! implements (its names, aliases and the one [`ParseWordError`]), and
//! the choices that reports carry: [`Method`], [`Energy`], [`ArapEnergy`],
//! [`ArapInit`]. Front doors (CLI, Python, the
//! editor) parse words into these types; inside the library only the types
//! travel. The report serialises them back as the same words.

use serde::Serializer;

use crate::error::ParseWordError;

/// A closed set of values, each named by one word on the command line, in
/// Python, in the editor and in reports.
pub trait Word: Copy + PartialEq + Sized + 'static {
    /// What a value names, for messages (`"method"`).
    const WHAT: &'static str;

    /// Every value.
    fn all() -> &'static [Self];

    /// The word of a value.
    fn name(self) -> &'static str;

    /// Other accepted words (spellings kept for compatibility).
    fn aliases() -> &'static [(&'static str, Self)] {
        &[]
    }

    /// The values listed in an error message (default: all; back ends
    /// list those of this build).
    fn listed() -> Vec<Self> {
        Self::all().to_vec()
    }

    /// The value named by `word` (a name or an alias).
    ///
    /// Errors: [`ParseWordError`] listing [`Word::listed`].
    fn parse_word(word: &str) -> Result<Self, ParseWordError> {
        Self::all()
            .iter()
            .copied()
            .find(|v| v.name() == word)
            .or_else(|| {
                Self::aliases()
                    .iter()
                    .find(|(alias, _)| *alias == word)
                    .map(|&(_, v)| v)
            })
            .ok_or_else(|| ParseWordError {
                what: Self::WHAT,
                word: word.to_string(),
                expected: Self::listed().into_iter().map(Self::name).collect(),
            })
    }
}

/// Serialises a [`Word`] as its name (for `#[serde(serialize_with)]` and
/// `Serialize` impls).
pub(crate) fn serialize_word<T: Word, S: Serializer>(value: &T, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(value.name())
}

/// Deserialises any `FromStr` choice from its word (for
/// `#[serde(deserialize_with)]`): the parse error, with the accepted
/// words, becomes the deserialisation error.
#[cfg(feature = "editor")]
pub(crate) fn deserialize_word<'de, T, D>(d: D) -> Result<T, D::Error>
where
    T: std::str::FromStr,
    T::Err: std::fmt::Display,
    D: serde::Deserializer<'de>,
{
    let word = <String as serde::Deserialize>::deserialize(d)?;
    word.parse().map_err(serde::de::Error::custom)
}

/// Implements `Display` (the name), `FromStr` ([`Word::parse_word`]) and
/// `Serialize` (the name) for a [`Word`] type.
macro_rules! word_traits {
    ($t:ty) => {
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str($crate::choice::Word::name(*self))
            }
        }

        impl std::str::FromStr for $t {
            type Err = $crate::error::ParseWordError;
            /// Errors: [`ParseWordError`](crate::error::ParseWordError)
            /// listing the accepted words.
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                <$t as $crate::choice::Word>::parse_word(s)
            }
        }

        impl serde::Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                $crate::choice::serialize_word(self, s)
            }
        }
    };
}
pub(crate) use word_traits;

/// A formulation (docs/formulations.md §2–§6), as a typed choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Method {
    /// The null-space QR method, the paper's.
    #[default]
    NullSpaceQr,
    /// Penalty weights on the hard rows.
    Penalty,
    /// Lagrange multipliers.
    Kkt,
    /// Elimination of the position-constrained unknowns (`eliminate`;
    /// `elimination` is accepted as an alias).
    Eliminate,
}

impl Method {
    /// Every method, in the order they are listed to users.
    pub const ALL: [Method; 4] = [
        Method::NullSpaceQr,
        Method::Penalty,
        Method::Kkt,
        Method::Eliminate,
    ];

    /// The name the CLI, Python and reports use.
    pub fn name(self) -> &'static str {
        match self {
            Method::NullSpaceQr => "nullspace-qr",
            Method::Penalty => "penalty",
            Method::Kkt => "kkt",
            Method::Eliminate => "eliminate",
        }
    }
}

impl Word for Method {
    const WHAT: &'static str = "method";
    fn all() -> &'static [Self] {
        &Method::ALL
    }
    fn name(self) -> &'static str {
        Method::name(self)
    }
    fn aliases() -> &'static [(&'static str, Self)] {
        &[("elimination", Method::Eliminate)]
    }
}

word_traits!(Method);

/// The deformation energy: the paper's linear Laplacian energy, or
/// as-rigid-as-possible iterations on the same formulations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Energy {
    /// `‖L(X − P)‖²` plus the soft terms (the `Deformer`).
    #[default]
    Laplacian,
    /// As-rigid-as-possible (`arap::ArapDeformer`, docs/arap.md).
    Arap,
}

impl Word for Energy {
    const WHAT: &'static str = "energy";
    fn all() -> &'static [Self] {
        &[Energy::Laplacian, Energy::Arap]
    }
    fn name(self) -> &'static str {
        match self {
            Energy::Laplacian => "laplacian",
            Energy::Arap => "arap",
        }
    }
}

word_traits!(Energy);

/// Which ARAP energy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ArapEnergy {
    /// Sorkine & Alexa 2007: each vertex's rotation applies to its spokes.
    Spokes,
    /// Chao et al. 2010: each vertex's rotation applies to every edge of
    /// its incident triangles (libigl's default for triangle meshes).
    #[default]
    SpokesAndRims,
}

impl ArapEnergy {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            ArapEnergy::Spokes => "spokes",
            ArapEnergy::SpokesAndRims => "spokes-and-rims",
        }
    }
}

impl Word for ArapEnergy {
    const WHAT: &'static str = "ARAP energy";
    fn all() -> &'static [Self] {
        &[ArapEnergy::Spokes, ArapEnergy::SpokesAndRims]
    }
    fn name(self) -> &'static str {
        ArapEnergy::name(self)
    }
}

word_traits!(ArapEnergy);

/// The initial guess of the iterations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ArapInit {
    /// The rest pose with every hard position constraint's vertex moved to
    /// its target (libigl's tutorials; the other constraint kinds hold from
    /// the first global step on).
    Rest,
    /// One global step with every rotation the identity: the linear
    /// (gradient-domain) deformation, which is Laplacian editing with the
    /// symmetric cotangent Laplacian `½(cot α + cot β)` and `δ = L P`.
    #[default]
    Linear,
}

impl ArapInit {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            ArapInit::Rest => "rest",
            ArapInit::Linear => "linear",
        }
    }
}

impl Word for ArapInit {
    const WHAT: &'static str = "ARAP initial guess";
    fn all() -> &'static [Self] {
        &[ArapInit::Rest, ArapInit::Linear]
    }
    fn name(self) -> &'static str {
        ArapInit::name(self)
    }
}

word_traits!(ArapInit);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_round_trip_aliases_parse_and_errors_list_the_words() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>(), Ok(m));
            assert_eq!(serde_json::to_value(m).unwrap(), m.name());
        }
        assert_eq!("elimination".parse::<Method>(), Ok(Method::Eliminate));
        let e = "qr".parse::<Method>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown method 'qr' (expected one of: nullspace-qr, penalty, kkt, eliminate)"
        );
    }
}
