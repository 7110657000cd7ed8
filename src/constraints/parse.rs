//! The JSON constraint format read straight into a [`ConstraintSet`]: one
//! pass over the text with serde's visitors, one constraint at a time,
//! never a document tree. A `serde_json::Value` tree of the format costs
//! 15–28 bytes per byte of text (a map node per constraint, a value per
//! number); this costs the constraints themselves.
//!
//! Every message and its precedence within a constraint are those of the
//! format's definition ([`super::parse_constraints`]): the constraint's
//! `type`, then its own fields in order, then unknown fields (the first in
//! byte order), `weight`, `group`. Constraints are checked in file order
//! as they are read, so the first invalid one is reported even when the
//! text after it is not JSON.
//!
//! A key repeated in one object, at any depth (a constraint's field, a key
//! of the top level or of `"mesh"`, a key inside an ignored value), is
//! [`ConstraintError::DuplicateKey`] with its line: a reader that keeps the
//! last value would silently drop the first.

use std::cell::RefCell;
use std::collections::HashSet;
use std::fmt;

use serde::Deserialize;
use serde::de::{self, DeserializeSeed, MapAccess, SeqAccess, Visitor};

use super::{Constraint, ConstraintKind, ConstraintSet};
use crate::error::ConstraintError;
use crate::mesh::MeshSignature;

/// Why a parse stopped: the format's own error, or serde_json's (syntax,
/// or the reader failed), to be mapped by the caller.
pub(super) enum Failure {
    Constraint(ConstraintError),
    Json(serde_json::Error),
}

/// Parses one document from `de` (and checks that nothing follows it).
pub(super) fn parse<'de, R: serde_json::de::Read<'de>>(
    de: &mut serde_json::Deserializer<R>,
) -> Result<ConstraintSet, Failure> {
    let failure = RefCell::new(None);
    let result = FileSeed {
        failure: Slot(&failure),
    }
    .deserialize(&mut *de)
    .and_then(|set| de.end().map(|()| set));
    result.map_err(|e| match failure.into_inner() {
        Some(c) => Failure::Constraint(at_line(c, e.line())),
        None => Failure::Json(e),
    })
}

/// A [`ConstraintError::DuplicateKey`] gets its line from serde_json's
/// error, whose position is where the visitor failed: right after the
/// repeated key.
fn at_line(e: ConstraintError, line: usize) -> ConstraintError {
    match e {
        ConstraintError::DuplicateKey { key, place, .. } => {
            ConstraintError::DuplicateKey { key, line, place }
        }
        other => other,
    }
}

/// Where an object is, for [`ConstraintError::DuplicateKey`].
#[derive(Clone, Copy)]
enum Place {
    Top,
    Mesh,
    Constraint(usize),
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Place::Top => f.write_str("at the top level"),
            Place::Mesh => f.write_str("in 'mesh'"),
            Place::Constraint(i) => write!(f, "in constraint {i}"),
        }
    }
}

/// The keys of one object seen so far, for those that are not a fixed
/// field (unknown keys, keys inside ignored values).
#[derive(Default)]
struct Keys(HashSet<Box<str>>);

impl Keys {
    /// Records `key`, or fails when it was seen.
    fn insert<E: de::Error>(
        &mut self,
        key: &str,
        failure: Slot<'_>,
        place: Place,
    ) -> Result<(), E> {
        if self.0.insert(key.into()) {
            Ok(())
        } else {
            Err(duplicate(failure, key, place))
        }
    }
}

/// The failure for `key` repeated in an object at `place` (its line is
/// filled in by [`parse`]).
fn duplicate<E: de::Error>(failure: Slot<'_>, key: &str, place: Place) -> E {
    failure.fail(ConstraintError::DuplicateKey {
        key: key.to_string(),
        line: 0,
        place: place.to_string(),
    })
}

/// Any JSON value, skipped, every object in it checked for a repeated key.
#[derive(Clone, Copy)]
struct Checked<'a> {
    failure: Slot<'a>,
    place: Place,
}

impl<'de> DeserializeSeed<'de> for Checked<'_> {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Checked<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_bool<E: de::Error>(self, _: bool) -> Result<(), E> {
        Ok(())
    }

    fn visit_i64<E: de::Error>(self, _: i64) -> Result<(), E> {
        Ok(())
    }

    fn visit_u64<E: de::Error>(self, _: u64) -> Result<(), E> {
        Ok(())
    }

    fn visit_f64<E: de::Error>(self, _: f64) -> Result<(), E> {
        Ok(())
    }

    fn visit_str<E: de::Error>(self, _: &str) -> Result<(), E> {
        Ok(())
    }

    fn visit_unit<E: de::Error>(self) -> Result<(), E> {
        Ok(())
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while seq.next_element_seed(self)?.is_some() {}
        Ok(())
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut keys = Keys::default();
        while let Some(key) = map.next_key::<String>()? {
            keys.insert::<A::Error>(&key, self.failure, self.place)?;
            map.next_value_seed(self)?;
        }
        Ok(())
    }
}

/// [`ConstraintError::Json`] from serde_json's error: its message without
/// the " at line L column C" that the fields carry.
pub(super) fn json_error(e: &serde_json::Error) -> ConstraintError {
    ConstraintError::Json {
        line: e.line(),
        column: e.column(),
        message: strip_position(&e.to_string()).to_string(),
    }
}

fn strip_position(message: &str) -> &str {
    if let Some(i) = message.rfind(" at line ") {
        let rest = &message[i + " at line ".len()..];
        let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
        if let Some((line, column)) = rest.split_once(" column ")
            && digits(line)
            && digits(column)
        {
            return &message[..i];
        }
    }
    message
}

/// Where the format's error is left for [`parse`] while serde unwinds
/// with a placeholder.
#[derive(Clone, Copy)]
struct Slot<'a>(&'a RefCell<Option<ConstraintError>>);

impl Slot<'_> {
    fn fail<E: de::Error>(self, e: ConstraintError) -> E {
        *self.0.borrow_mut() = Some(e);
        E::custom("invalid constraints file")
    }
}

/// Visitor methods for every JSON type but the one a visitor takes: each
/// calls `self.refuse()`.
macro_rules! refuse_other_types {
    ($($method:ident($($arg:ty)?)),*) => {
        $(fn $method<E: de::Error>(self, $(_: $arg)?) -> Result<Self::Value, E> {
            Err(self.refuse())
        })*
    };
}

/// The scalar visitor methods refused with `self.refuse()`.
macro_rules! refuse_scalars {
    () => {
        refuse_other_types!(
            visit_bool(bool),
            visit_i64(i64),
            visit_u64(u64),
            visit_f64(f64),
            visit_str(&str),
            visit_unit()
        );
    };
}

// ---------------------------------------------------------------------------
// The top level: {"mesh": …, "constraints": […], anything else ignored}

struct FileSeed<'a> {
    failure: Slot<'a>,
}

impl<'de> DeserializeSeed<'de> for FileSeed<'_> {
    type Value = ConstraintSet;
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<ConstraintSet, D::Error> {
        d.deserialize_any(self)
    }
}

const TOP_LEVEL: &str = "the top level must be an object with a 'constraints' array";

impl FileSeed<'_> {
    fn refuse<E: de::Error>(&self) -> E {
        self.failure.fail(ConstraintError::Shape {
            message: TOP_LEVEL.into(),
        })
    }
}

impl<'de> Visitor<'de> for FileSeed<'_> {
    type Value = ConstraintSet;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an object with a 'constraints' array")
    }

    refuse_scalars!();

    fn visit_seq<A: SeqAccess<'de>>(self, _: A) -> Result<ConstraintSet, A::Error> {
        Err(self.refuse())
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<ConstraintSet, A::Error> {
        let mut set = ConstraintSet::new();
        let mut mesh = None;
        let (mut listed, mut meshed) = (false, false);
        let mut keys = Keys::default();
        let failure = self.failure;
        while let Some(key) = map.next_key_seed(KeySeed(TOP_KEYS))? {
            match key {
                Key::Known(TopKey::Constraints) => {
                    if listed {
                        return Err(duplicate(failure, "constraints", Place::Top));
                    }
                    map.next_value_seed(ListSeed {
                        failure,
                        set: &mut set,
                    })?;
                    listed = true;
                }
                Key::Known(TopKey::Mesh) => {
                    if meshed {
                        return Err(duplicate(failure, "mesh", Place::Top));
                    }
                    mesh = map.next_value_seed(MeshSeed { failure })?;
                    meshed = true;
                }
                Key::Unknown(name) => {
                    keys.insert::<A::Error>(&name, failure, Place::Top)?;
                    map.next_value_seed(Checked {
                        failure,
                        place: Place::Top,
                    })?;
                }
            }
        }
        if !listed {
            return Err(self.refuse());
        }
        set.mesh = mesh;
        Ok(set)
    }
}

#[derive(Clone, Copy)]
enum TopKey {
    Constraints,
    Mesh,
}

const TOP_KEYS: &[(&str, TopKey)] = &[("constraints", TopKey::Constraints), ("mesh", TopKey::Mesh)];

/// `"mesh"`: `null` or a [`MeshSignature`].
struct MeshSeed<'a> {
    failure: Slot<'a>,
}

impl<'de> DeserializeSeed<'de> for MeshSeed<'_> {
    type Value = Option<MeshSignature>;
    fn deserialize<D: de::Deserializer<'de>>(
        self,
        d: D,
    ) -> Result<Option<MeshSignature>, D::Error> {
        Option::<MeshSignature>::deserialize(d).map_err(|e| {
            let text = e.to_string();
            let said = strip_position(&text);
            // serde's derived reader refuses a repeated field with
            // "duplicate field `name`".
            if let Some(key) = said
                .strip_prefix("duplicate field `")
                .and_then(|k| k.strip_suffix('`'))
            {
                return duplicate(self.failure, key, Place::Mesh);
            }
            let message = format!(
                "'mesh' must be {{\"vertices\": n, \"faces\": m, \"fingerprint\": \"…\"}}: {said}"
            );
            self.failure.fail(ConstraintError::Shape { message })
        })
    }
}

/// `"constraints"`: the array, each element pushed as it is read.
struct ListSeed<'a, 's> {
    failure: Slot<'a>,
    set: &'s mut ConstraintSet,
}

impl<'de> DeserializeSeed<'de> for ListSeed<'_, '_> {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl ListSeed<'_, '_> {
    fn refuse<E: de::Error>(&self) -> E {
        self.failure.fail(ConstraintError::Shape {
            message: "'constraints' must be an array".into(),
        })
    }
}

impl<'de> Visitor<'de> for ListSeed<'_, '_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an array of constraints")
    }

    refuse_scalars!();

    fn visit_map<A: MapAccess<'de>>(self, _: A) -> Result<(), A::Error> {
        Err(self.refuse())
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let failure = self.failure;
        loop {
            let index = self.set.len();
            let Some(c) = seq.next_element_seed(ItemSeed { failure, index })? else {
                return Ok(());
            };
            self.set.push(c).map_err(|e| failure.fail::<A::Error>(e))?;
        }
    }
}

// ---------------------------------------------------------------------------
// One constraint.

/// The fields of a constraint object.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Field {
    Type,
    Vertex,
    Vertices,
    T,
    Barycentric,
    Target,
    Vector,
    Weight,
    Group,
    /// `name`: free text, ignored.
    Name,
    /// `comment`: free text, ignored.
    Comment,
}

const FIELDS: &[(&str, Field)] = &[
    ("type", Field::Type),
    ("vertex", Field::Vertex),
    ("vertices", Field::Vertices),
    ("t", Field::T),
    ("barycentric", Field::Barycentric),
    ("target", Field::Target),
    ("vector", Field::Vector),
    ("weight", Field::Weight),
    ("group", Field::Group),
    ("name", Field::Name),
    ("comment", Field::Comment),
];

/// The fields that belong to one type or another (a field of another type
/// is an unknown field).
const KIND_FIELDS: [(Field, &str); 6] = [
    (Field::Vertex, "vertex"),
    (Field::Vertices, "vertices"),
    (Field::T, "t"),
    (Field::Barycentric, "barycentric"),
    (Field::Target, "target"),
    (Field::Vector, "vector"),
];

/// A key: one of `names`, or another (kept for the message).
enum Key<K> {
    Known(K),
    Unknown(String),
}

struct KeySeed<K: 'static>(&'static [(&'static str, K)]);

impl<'de, K: Copy> DeserializeSeed<'de> for KeySeed<K> {
    type Value = Key<K>;
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<Key<K>, D::Error> {
        d.deserialize_str(self)
    }
}

impl<K: Copy> Visitor<'_> for KeySeed<K> {
    type Value = Key<K>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a key")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<Key<K>, E> {
        Ok(match self.0.iter().find(|(name, _)| *name == v) {
            Some(&(_, k)) => Key::Known(k),
            None => Key::Unknown(v.to_owned()),
        })
    }
}

/// A field's value as far as the format needs it.
#[derive(Debug)]
enum Loose {
    U64(u64),
    I64(i64),
    F64(f64),
    Str(String),
    /// The first [`KEPT_ITEMS`] items and the array's length.
    Array {
        items: Vec<Loose>,
        len: usize,
    },
    /// `true`, `false`, `null`, an object, or inside an array a string
    /// that is not a number word or a nested array.
    Other,
}

/// Items of an array kept: no field has more than three, and one more
/// says "too many" with the length.
const KEPT_ITEMS: usize = 4;

impl Loose {
    /// A number, or the strings "NaN", "inf", "-inf" (any case) so that
    /// non-finite values written by other programs are reported as
    /// non-finite rather than as a type error.
    fn number(&self) -> Option<f64> {
        match self {
            Loose::U64(u) => Some(*u as f64),
            Loose::I64(i) => Some(*i as f64),
            Loose::F64(x) => Some(*x),
            Loose::Str(s) => number_word(s),
            _ => None,
        }
    }

    fn as_u64(&self) -> Option<u64> {
        match self {
            Loose::U64(u) => Some(*u),
            _ => None,
        }
    }

    /// The kept items and the length.
    fn as_array(&self) -> Option<(&[Loose], usize)> {
        match self {
            Loose::Array { items, len } => Some((items, *len)),
            _ => None,
        }
    }
}

fn number_word(s: &str) -> Option<f64> {
    match s.to_ascii_lowercase().as_str() {
        "nan" => Some(f64::NAN),
        "inf" | "infinity" | "+inf" => Some(f64::INFINITY),
        "-inf" | "-infinity" => Some(f64::NEG_INFINITY),
        _ => None,
    }
}

/// Reads a [`Loose`]; `nested` inside an array (where only numbers and
/// number words matter); objects in it are checked for repeated keys
/// ([`Checked`]) as constraint `index`'s.
#[derive(Clone, Copy)]
struct LooseSeed<'a> {
    nested: bool,
    failure: Slot<'a>,
    index: usize,
}

impl<'a> LooseSeed<'a> {
    fn checked(&self) -> Checked<'a> {
        Checked {
            failure: self.failure,
            place: Place::Constraint(self.index),
        }
    }
}

impl<'de> DeserializeSeed<'de> for LooseSeed<'_> {
    type Value = Loose;
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<Loose, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for LooseSeed<'_> {
    type Value = Loose;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_bool<E: de::Error>(self, _: bool) -> Result<Loose, E> {
        Ok(Loose::Other)
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Loose, E> {
        Ok(Loose::I64(v))
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Loose, E> {
        Ok(Loose::U64(v))
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Loose, E> {
        Ok(Loose::F64(v))
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<Loose, E> {
        Ok(if self.nested {
            number_word(v).map_or(Loose::Other, Loose::F64)
        } else {
            Loose::Str(v.to_owned())
        })
    }

    fn visit_unit<E: de::Error>(self) -> Result<Loose, E> {
        Ok(Loose::Other)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Loose, A::Error> {
        if self.nested {
            while seq.next_element_seed(self.checked())?.is_some() {}
            return Ok(Loose::Other);
        }
        let mut items = Vec::new();
        let mut len = 0usize;
        loop {
            let more = if len < KEPT_ITEMS {
                seq.next_element_seed(LooseSeed {
                    nested: true,
                    ..self
                })?
                .map(|item| items.push(item))
                .is_some()
            } else {
                seq.next_element_seed(self.checked())?.is_some()
            };
            if !more {
                return Ok(Loose::Array { items, len });
            }
            len += 1;
        }
    }

    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Loose, A::Error> {
        self.checked().visit_map(map)?;
        Ok(Loose::Other)
    }
}

/// Constraint `index` of the array.
struct ItemSeed<'a> {
    failure: Slot<'a>,
    index: usize,
}

impl<'de> DeserializeSeed<'de> for ItemSeed<'_> {
    type Value = Constraint;
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<Constraint, D::Error> {
        d.deserialize_any(self)
    }
}

impl ItemSeed<'_> {
    fn refuse<E: de::Error>(&self) -> E {
        self.failure.fail(ConstraintError::BadField {
            index: self.index,
            field: "constraint",
            problem: "must be a JSON object".into(),
        })
    }
}

impl<'de> Visitor<'de> for ItemSeed<'_> {
    type Value = Constraint;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a constraint object")
    }

    refuse_scalars!();

    fn visit_seq<A: SeqAccess<'de>>(self, _: A) -> Result<Constraint, A::Error> {
        Err(self.refuse())
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Constraint, A::Error> {
        let mut raw = Raw::default();
        let (failure, index) = (self.failure, self.index);
        let place = Place::Constraint(index);
        let loose = LooseSeed {
            nested: false,
            failure,
            index,
        };
        // The fields seen (bit `field as usize`) and the unknown keys.
        let mut seen = 0u32;
        let mut unknown = Keys::default();
        while let Some(key) = map.next_key_seed(KeySeed(FIELDS))? {
            match key {
                Key::Known(field) => {
                    let bit = 1u32 << field as usize;
                    if seen & bit != 0 {
                        let name = FIELDS.iter().find(|(_, f)| *f == field).map(|(n, _)| *n);
                        return Err(duplicate(failure, name.unwrap_or("?"), place));
                    }
                    seen |= bit;
                    if matches!(field, Field::Name | Field::Comment) {
                        map.next_value_seed(loose.checked())?;
                    } else {
                        raw.values[field as usize] = Some(map.next_value_seed(loose)?);
                    }
                }
                Key::Unknown(name) => {
                    unknown.insert::<A::Error>(&name, failure, place)?;
                    map.next_value_seed(loose.checked())?;
                    if raw.unknown.as_ref().is_none_or(|u| name < *u) {
                        raw.unknown = Some(name);
                    }
                }
            }
        }
        raw.into_constraint(self.index)
            .map_err(|e| self.failure.fail(e))
    }
}

/// The fields of one constraint object as read (each at most once).
#[derive(Default)]
struct Raw {
    values: [Option<Loose>; 9],
    /// The first (in byte order) key that is no field of any type.
    unknown: Option<String>,
}

impl Raw {
    fn get(&self, field: Field) -> Option<&Loose> {
        self.values[field as usize].as_ref()
    }

    fn into_constraint(mut self, index: usize) -> Result<Constraint, ConstraintError> {
        let ty = match self.values[Field::Type as usize].take() {
            Some(Loose::Str(s)) => s,
            Some(_) => {
                return Err(ConstraintError::BadField {
                    index,
                    field: "type",
                    problem: "must be a string".into(),
                });
            }
            None => {
                return Err(ConstraintError::BadField {
                    index,
                    field: "type",
                    problem: "is missing".into(),
                });
            }
        };
        let f = Fields { index, raw: &self };
        let (kind, allowed): (ConstraintKind, &[&str]) = match ty.as_str() {
            "position" => (
                ConstraintKind::Position {
                    vertex: f.vertex("vertex")?,
                    target: f.vec3("target")?,
                },
                &["vertex", "target"],
            ),
            "edge" => (
                ConstraintKind::Edge {
                    vertices: f.vertices::<2>()?,
                    t: f.number("t")?,
                    target: f.vec3("target")?,
                },
                &["vertices", "t", "target"],
            ),
            "face" => (
                ConstraintKind::Face {
                    vertices: f.vertices::<3>()?,
                    barycentric: f.numbers::<2>("barycentric")?,
                    target: f.vec3("target")?,
                },
                &["vertices", "barycentric", "target"],
            ),
            "relative" => (
                ConstraintKind::Relative {
                    vertices: f.vertices::<2>()?,
                    vector: f.vec3("vector")?,
                },
                &["vertices", "vector"],
            ),
            _ => {
                return Err(ConstraintError::UnknownType { index, found: ty });
            }
        };
        // The first offending key in byte order: a field of another type
        // or no field at all.
        let mut offending = self.unknown.as_deref();
        for (field, name) in KIND_FIELDS {
            if self.get(field).is_some()
                && !allowed.contains(&name)
                && offending.is_none_or(|o| name < o)
            {
                offending = Some(name);
            }
        }
        if let Some(field) = offending {
            return Err(ConstraintError::UnknownField {
                index,
                field: field.to_string(),
                kind: ty,
                allowed: format!("type, {}, weight, group, name, comment", allowed.join(", ")),
            });
        }
        let weight = match self.get(Field::Weight) {
            None => None,
            Some(v) => Some(v.number().ok_or_else(|| ConstraintError::BadField {
                index,
                field: "weight",
                problem: "must be a number".into(),
            })?),
        };
        let group = match self.values[Field::Group as usize].take() {
            None => None,
            Some(Loose::Str(name)) => Some(name),
            Some(_) => {
                return Err(ConstraintError::BadField {
                    index,
                    field: "group",
                    problem: "must be a string (the group's name)".into(),
                });
            }
        };
        Ok(Constraint {
            kind,
            weight,
            group,
        })
    }
}

struct Fields<'a> {
    index: usize,
    raw: &'a Raw,
}

impl Fields<'_> {
    fn get(&self, field: &'static str) -> Result<&Loose, ConstraintError> {
        let (_, key) = FIELDS
            .iter()
            .find(|(name, _)| *name == field)
            .expect("a field of the format");
        self.raw.get(*key).ok_or_else(|| ConstraintError::BadField {
            index: self.index,
            field,
            problem: "is missing".into(),
        })
    }

    fn number(&self, field: &'static str) -> Result<f64, ConstraintError> {
        self.get(field)?
            .number()
            .ok_or_else(|| ConstraintError::BadField {
                index: self.index,
                field,
                problem: "must be a number".into(),
            })
    }

    fn numbers<const K: usize>(&self, field: &'static str) -> Result<[f64; K], ConstraintError> {
        let bad = || ConstraintError::BadField {
            index: self.index,
            field,
            problem: format!("must be an array of {K} numbers"),
        };
        let (items, len) = self.get(field)?.as_array().ok_or_else(bad)?;
        if len != K {
            return Err(bad());
        }
        let mut out = [0.0; K];
        for (o, v) in out.iter_mut().zip(items) {
            *o = v.number().ok_or_else(bad)?;
        }
        Ok(out)
    }

    fn vec3(&self, field: &'static str) -> Result<[f64; 3], ConstraintError> {
        self.numbers::<3>(field)
    }

    fn vertex_value(&self, field: &'static str, v: &Loose) -> Result<usize, ConstraintError> {
        let bad = || ConstraintError::BadField {
            index: self.index,
            field,
            problem: "must hold non-negative integer vertex indices".into(),
        };
        let u = v.as_u64().ok_or_else(bad)?;
        // An index too large for this platform is out of range of any mesh.
        usize::try_from(u).map_err(|_| ConstraintError::VertexOutOfRange {
            index: self.index,
            vertex: u,
            vertex_count: 0,
        })
    }

    fn vertex(&self, field: &'static str) -> Result<usize, ConstraintError> {
        self.vertex_value(field, self.get(field)?)
    }

    fn vertices<const K: usize>(&self) -> Result<[usize; K], ConstraintError> {
        let field = "vertices";
        let items = self
            .get(field)?
            .as_array()
            .filter(|&(_, len)| len == K)
            .ok_or_else(|| ConstraintError::BadField {
                index: self.index,
                field,
                problem: format!("must be an array of {K} vertex indices"),
            })?
            .0;
        let mut out = [0usize; K];
        for (o, v) in out.iter_mut().zip(items) {
            *o = self.vertex_value(field, v)?;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_are_stripped_only_when_they_are_positions() {
        assert_eq!(
            strip_position("EOF while parsing at line 3 column 7"),
            "EOF while parsing"
        );
        assert_eq!(
            strip_position("x at line y column 2"),
            "x at line y column 2"
        );
        assert_eq!(strip_position("plain"), "plain");
    }
}
