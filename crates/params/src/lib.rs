//! # vfxgraph-params
//!
//! A parameter is declared once, where the algorithm lives: an options struct's field is its
//! name, its Rust type is the parameter's type, `Default` is its default, the field's doc comment
//! is its documentation and `#[param(range = MIN..=MAX)]` its range. `#[derive(Options)]` turns
//! the struct into [`ParamDesc`]s and a reader ([`Options::read`]); `#[derive(Choice)]` turns a
//! unit-only enum into an enum parameter (its variants in snake case), so a choice is never
//! spelled twice and has no fallback arm.
//!
//! The crate has no dependencies (the derive aside; serde behind the `serde` feature) and knows
//! nothing of the engine: the algorithm crates (geometry, matchmove, render, imaging, …) derive
//! [`Options`] on their structs, and the engine declares its nodes' parameters with these same types
//! ([`ParamDesc`], [`Kind`], [`Value`], [`PathRole`]), checks graph values with
//! [`Kind::check`] and reads options structs back through its [`Source`].
//! COLMAP's option manager binds command-line names to the fields of its option structs the same
//! way; Meshroom's node descriptions list each parameter once.
//!
//! Field types: integers (`Option<usize>` is an int whose −1 is `None`), `f64`, `f32`
//! (`Option<f64>` and `Option<f32>` are floats whose 0 is `None`: off), `bool`,
//! `String`, `Vec<f64>` and `[f64; N]` (float lists), `Vec<String>` (path lists) and
//! `#[derive(Choice)]` enums.
//!
//! Field attributes (`#[param(...)]`, comma-separated):
//! - `range = MIN..=MAX`: the numeric range (either side may be omitted: `0.0..=`).
//! - `name = "..."`: the parameter's name when it is not the field's.
//! - `doc = "..."`: the documentation when it is not the doc comment's first paragraph.
//! - `skip`: not a parameter (its value is the default's).
//! - `flatten`: the field is itself an [`Options`] struct whose parameters are listed here.
//! - `toggle = "name"` (on an `Option<T>` field, `T: Options`): a boolean parameter `name`
//!   (documented by the field's doc comment) whose default is `Default`'s `is_some()`; when true
//!   the field is `Some(T::read(..))`, else `None`. `T`'s parameters follow, after the struct's
//!   other fields.
//! - `path = "input"` / `path = "output"` (on a `String` field): a file path the caller resolves
//!   (the engine: against the graph file, an input's content entering the cache key); its
//!   default is `Default`'s (usually empty: no file). On a `Vec<String>` field: a list of paths.
//! - `required`: the parameter has no default (a graph must give it); `Default`'s value of the
//!   field is not a parameter default (the struct still needs `Default`, for its other fields).
//! - `cosmetic`: does not enter the cache key (labels, verbosity).
//!
//! Struct attribute `#[param(check)]`: [`Options::read`] ends with the struct's inherent
//! `fn check(&self) -> Result<(), String>`.

use std::fmt;

pub use vfxgraph_params_derive::{Choice, Options};

/// Whether a path parameter names a file the node reads or one it writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathRole {
    /// Read: the engine hashes the file's content into the cache key.
    Input,
    /// Written: the engine records the written file's digest and reruns if it is gone or changed.
    Output,
}

/// A parameter's type.
#[derive(Clone, Debug, PartialEq)]
pub enum Kind {
    /// `true` / `false`.
    Bool,
    /// An integer in `[min, max]`.
    Int {
        /// Smallest allowed.
        min: i64,
        /// Largest allowed.
        max: i64,
    },
    /// A finite float in `[min, max]` (integers are accepted).
    Float {
        /// Smallest allowed.
        min: f64,
        /// Largest allowed.
        max: f64,
    },
    /// Any string.
    Str,
    /// One of the listed strings.
    Enum(&'static [&'static str]),
    /// A file path, relative to the graph file's folder. Per-frame nodes may use a frame
    /// pattern (`%04d` or `####`).
    Path(PathRole),
    /// A list of file paths (e.g. the photographs of an exposure stack), each relative to the
    /// graph file's folder; input lists are hashed file by file like [`Kind::Path`]. No
    /// frame patterns.
    PathList(PathRole),
    /// A list of floats (e.g. a 3-vector or a matrix in rows), of a fixed length or any.
    FloatList {
        /// Required length, if fixed.
        len: Option<usize>,
    },
}

/// A parameter value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `true` / `false`.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A float.
    Float(f64),
    /// A string (also paths and enum choices).
    Str(String),
    /// A list of values.
    List(Vec<Value>),
}

/// One declared parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamDesc {
    /// Its name.
    pub name: &'static str,
    /// Its type.
    pub kind: Kind,
    /// Its default (from the struct's `Default`); `None`: required.
    pub default: Option<Value>,
    /// One line of documentation.
    pub doc: &'static str,
    /// True for params that must not enter the cache key.
    pub cosmetic: bool,
}

impl ParamDesc {
    /// A required parameter (no default), affecting the output.
    pub fn required(name: &'static str, kind: Kind, doc: &'static str) -> Self {
        ParamDesc {
            name,
            kind,
            default: None,
            doc,
            cosmetic: false,
        }
    }

    /// A parameter with a default, affecting the output.
    pub fn optional(name: &'static str, kind: Kind, default: Value, doc: &'static str) -> Self {
        ParamDesc {
            default: Some(default),
            ..ParamDesc::required(name, kind, doc)
        }
    }

    /// The same parameter, cosmetic: it does not enter the cache key.
    pub fn cosmetic(self) -> Self {
        ParamDesc {
            cosmetic: true,
            ..self
        }
    }
}

impl fmt::Display for Value {
    /// As a graph file would write it: strings quoted, lists in brackets.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{b}"),
            Value::Int(i) => write!(f, "{i}"),
            Value::Float(x) => write!(f, "{x}"),
            Value::Str(s) => write!(f, "{s:?}"),
            Value::List(l) => {
                write!(f, "[")?;
                for (i, v) in l.iter().enumerate() {
                    if i > 0 {
                        write!(f, ", ")?;
                    }
                    write!(f, "{v}")?;
                }
                write!(f, "]")
            }
        }
    }
}

impl Value {
    /// What kind of value it is, with its article ("an integer").
    pub fn kind_name(&self) -> &'static str {
        match self {
            Value::Bool(_) => "a boolean",
            Value::Int(_) => "an integer",
            Value::Float(_) => "a float",
            Value::Str(_) => "a string",
            Value::List(_) => "a list",
        }
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Kind::Bool => write!(f, "bool"),
            Kind::Int { min, max } => {
                write!(f, "int")?;
                if *min != i64::MIN || *max != i64::MAX {
                    write!(
                        f,
                        " in [{}, {}]",
                        bound(*min, i64::MIN),
                        bound(*max, i64::MAX)
                    )?;
                }
                Ok(())
            }
            Kind::Float { min, max } => {
                write!(f, "float")?;
                if min.is_finite() || max.is_finite() {
                    write!(f, " in [{min}, {max}]")?;
                }
                Ok(())
            }
            Kind::Str => write!(f, "string"),
            Kind::Enum(c) => write!(f, "one of {}", c.join(" | ")),
            Kind::Path(PathRole::Input) => write!(f, "input path"),
            Kind::Path(PathRole::Output) => write!(f, "output path"),
            Kind::PathList(PathRole::Input) => write!(f, "list of input paths"),
            Kind::PathList(PathRole::Output) => write!(f, "list of output paths"),
            Kind::FloatList { len: Some(n) } => write!(f, "list of {n} floats"),
            Kind::FloatList { len: None } => write!(f, "list of floats"),
        }
    }
}

fn bound(v: i64, inf: i64) -> String {
    if v == inf {
        if v < 0 { "-inf" } else { "inf" }.to_string()
    } else {
        v.to_string()
    }
}

/// Why a value does not fit a parameter's type.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamCheck {
    /// Wrong kind of value.
    Type(String),
    /// Right kind, outside the range or choices.
    Range(String),
}

impl Kind {
    /// Checks `v` and normalizes it (an integer given to a float parameter becomes a float).
    /// A path is any string here; its caller checks what a path may hold (the engine: frame
    /// patterns).
    pub fn check(&self, v: Value) -> Result<Value, ParamCheck> {
        let wrong = |v: &Value, want: &str| {
            ParamCheck::Type(format!("expected {want}, found {} `{v}`", v.kind_name()))
        };
        match (self, v) {
            (Kind::Bool, v @ Value::Bool(_)) => Ok(v),
            (Kind::Int { min, max }, Value::Int(i)) => {
                if i < *min || i > *max {
                    Err(ParamCheck::Range(format!("{i} is outside {self}")))
                } else {
                    Ok(Value::Int(i))
                }
            }
            (Kind::Float { .. }, Value::Int(i)) => self.check(Value::Float(i as f64)),
            (Kind::Float { min, max }, Value::Float(x)) => {
                if !x.is_finite() {
                    Err(ParamCheck::Range(format!("{x} is not a finite number")))
                } else if x < *min || x > *max {
                    Err(ParamCheck::Range(format!("{x} is outside {self}")))
                } else {
                    Ok(Value::Float(x))
                }
            }
            (Kind::Path(_) | Kind::Str, v @ Value::Str(_)) => Ok(v),
            (Kind::Enum(choices), Value::Str(s)) => {
                if choices.contains(&s.as_str()) {
                    Ok(Value::Str(s))
                } else {
                    Err(ParamCheck::Range(format!("`{s}` is not {self}")))
                }
            }
            (Kind::PathList(_), Value::List(items)) => {
                for it in &items {
                    if !matches!(it, Value::Str(_)) {
                        return Err(wrong(it, "a path (string) in the list"));
                    }
                }
                Ok(Value::List(items))
            }
            (Kind::FloatList { len }, Value::List(items)) => {
                let mut out = Vec::with_capacity(items.len());
                for it in items {
                    match it {
                        Value::Int(i) => out.push(Value::Float(i as f64)),
                        Value::Float(x) if x.is_finite() => out.push(Value::Float(x)),
                        other => return Err(wrong(&other, "a finite number in the list")),
                    }
                }
                match len {
                    Some(n) if *n != out.len() => Err(ParamCheck::Range(format!(
                        "expected {n} numbers, found {}",
                        out.len()
                    ))),
                    _ => Ok(Value::List(out)),
                }
            }
            (t, v) => Err(wrong(&v, &t.to_string())),
        }
    }
}

/// Checked parameter values by name (the engine's are one).
pub trait Source {
    /// The value of parameter `name`, if it has one.
    fn value(&self, name: &str) -> Option<Value>;
}

/// A map is a source (for tests and for callers without an engine).
impl Source for std::collections::BTreeMap<String, Value> {
    fn value(&self, name: &str) -> Option<Value> {
        self.get(name).cloned()
    }
}

/// An options struct whose fields are parameters (`#[derive(Options)]`).
pub trait Options: Sized {
    /// The parameters, in field order (a `toggle`'s parameters last), with `Default`'s values
    /// as their defaults.
    fn params() -> Vec<ParamDesc>;
    /// The parameters with the values of `d` as their defaults: a `flatten`ed struct's
    /// defaults are its field's value in the outer struct's `Default` (so an outer struct may
    /// default an inner field differently, as the tracker's 0 = automatic feature count).
    fn params_from(d: &Self) -> Vec<ParamDesc>;
    /// Reads every parameter from `src` and checks the result (`#[param(check)]`). An error
    /// names the parameter or says what is wrong with the combination.
    fn read(src: &dyn Source) -> Result<Self, String>;
}

/// A Rust type that can be one parameter.
pub trait Field: Sized {
    /// The parameter type, within the field's `range` (bounds as written, converted).
    fn kind(min: Option<f64>, max: Option<f64>) -> Kind;
    /// The value of `self`.
    fn to_value(&self) -> Value;
    /// Reads a value; `None` when it is of another kind or does not fit.
    fn from_value(v: Value) -> Option<Self>;
}

/// A unit-only enum that is an enum parameter (`#[derive(Choice)]`).
pub trait Choice: Sized + Copy + 'static {
    /// The choices, in declaration order.
    const CHOICES: &'static [&'static str];
    /// The choice's name.
    fn choice(&self) -> &'static str;
    /// The variant named `name`.
    fn from_choice(name: &str) -> Option<Self>;
}

/// Reads parameter `name` of `src` as a `T`, with an error naming it.
pub fn read_field<T: Field>(src: &dyn Source, name: &str) -> Result<T, String> {
    let v = src
        .value(name)
        .ok_or_else(|| format!("parameter `{name}` has no value"))?;
    let shown = format!("{v:?}");
    T::from_value(v).ok_or_else(|| format!("parameter `{name}`: {shown} does not fit"))
}

macro_rules! int_field {
    ($lo:expr; $($t:ty),*) => {$(
        impl Field for $t {
            fn kind(min: Option<f64>, max: Option<f64>) -> Kind {
                Kind::Int {
                    min: min.map_or($lo, |m| m as i64),
                    max: max.map_or(i64::MAX, |m| m as i64),
                }
            }
            fn to_value(&self) -> Value {
                Value::Int(*self as i64)
            }
            fn from_value(v: Value) -> Option<Self> {
                match v {
                    Value::Int(i) => <$t>::try_from(i).ok(),
                    _ => None,
                }
            }
        }
    )*};
}
int_field!(i64::MIN; i64, i32);
int_field!(0; u64, u32, usize, u8);

impl Field for f64 {
    fn kind(min: Option<f64>, max: Option<f64>) -> Kind {
        Kind::Float {
            min: min.unwrap_or(f64::NEG_INFINITY),
            max: max.unwrap_or(f64::INFINITY),
        }
    }
    fn to_value(&self) -> Value {
        Value::Float(*self)
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Float(x) => Some(x),
            Value::Int(i) => Some(i as f64),
            _ => None,
        }
    }
}

impl Field for f32 {
    fn kind(min: Option<f64>, max: Option<f64>) -> Kind {
        f64::kind(min, max)
    }
    /// The shortest decimal that reads back as `self` (`1e-5_f32` is shown and stored as
    /// `1e-5`, not as its binary value 9.99999974737875e-6).
    fn to_value(&self) -> Value {
        let short: f64 = self.to_string().parse().unwrap_or(f64::from(*self));
        Value::Float(if short as f32 == *self {
            short
        } else {
            f64::from(*self)
        })
    }
    fn from_value(v: Value) -> Option<Self> {
        f64::from_value(v).map(|x| x as f32)
    }
}

impl Field for bool {
    fn kind(_: Option<f64>, _: Option<f64>) -> Kind {
        Kind::Bool
    }
    fn to_value(&self) -> Value {
        Value::Bool(*self)
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Bool(b) => Some(b),
            _ => None,
        }
    }
}

impl Field for String {
    fn kind(_: Option<f64>, _: Option<f64>) -> Kind {
        Kind::Str
    }
    fn to_value(&self) -> Value {
        Value::Str(self.clone())
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Str(s) => Some(s),
            _ => None,
        }
    }
}

/// A list of paths: only with `#[param(path = "input")]` or `"output"` (its kind is then a path
/// list of that role).
impl Field for Vec<String> {
    fn kind(_: Option<f64>, _: Option<f64>) -> Kind {
        Kind::PathList(PathRole::Input)
    }
    fn to_value(&self) -> Value {
        Value::List(self.iter().map(|s| Value::Str(s.clone())).collect())
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::List(items) => items.into_iter().map(String::from_value).collect(),
            _ => None,
        }
    }
}

fn floats(v: Value) -> Option<Vec<f64>> {
    match v {
        Value::List(items) => items.into_iter().map(f64::from_value).collect(),
        _ => None,
    }
}

impl Field for Vec<f64> {
    fn kind(_: Option<f64>, _: Option<f64>) -> Kind {
        Kind::FloatList { len: None }
    }
    fn to_value(&self) -> Value {
        Value::List(self.iter().map(|x| Value::Float(*x)).collect())
    }
    fn from_value(v: Value) -> Option<Self> {
        floats(v)
    }
}

impl<const N: usize> Field for [f64; N] {
    fn kind(_: Option<f64>, _: Option<f64>) -> Kind {
        Kind::FloatList { len: Some(N) }
    }
    fn to_value(&self) -> Value {
        Value::List(self.iter().map(|x| Value::Float(*x)).collect())
    }
    fn from_value(v: Value) -> Option<Self> {
        floats(v)?.try_into().ok()
    }
}

/// An optional index or count: `-1` is `None` (an int parameter whose range starts at −1).
impl Field for Option<usize> {
    fn kind(min: Option<f64>, max: Option<f64>) -> Kind {
        Kind::Int {
            min: min.map_or(-1, |m| m as i64),
            max: max.map_or(i64::MAX, |m| m as i64),
        }
    }
    fn to_value(&self) -> Value {
        Value::Int(self.map_or(-1, |i| i as i64))
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Int(-1) => Some(None),
            Value::Int(i) => usize::try_from(i).ok().map(Some),
            _ => None,
        }
    }
}

/// An optional length or threshold: `0` is `None` (off), any positive value `Some`.
macro_rules! off_at_zero {
    ($($t:ty),*) => {$(
        impl Field for Option<$t> {
            fn kind(min: Option<f64>, max: Option<f64>) -> Kind {
                <$t>::kind(min, max)
            }
            fn to_value(&self) -> Value {
                self.unwrap_or(0.0).to_value()
            }
            fn from_value(v: Value) -> Option<Self> {
                <$t>::from_value(v).map(|x| (x > 0.0).then_some(x))
            }
        }
    )*};
}
off_at_zero!(f32, f64);

/// [`Field::from_value`] of a [`Choice`] (the derive's `Field` impl calls it).
pub fn choice_from_value<C: Choice>(v: Value) -> Option<C> {
    match v {
        Value::Str(s) => C::from_choice(&s),
        _ => None,
    }
}

/// Checks that every value of a list is positive (a common `check` rule), naming the param.
pub fn all_positive(name: &str, values: &[f64]) -> Result<(), String> {
    if values.iter().any(|t| t.is_nan() || *t <= 0.0) {
        return Err(format!("`{name}` must all be positive"));
    }
    Ok(())
}
