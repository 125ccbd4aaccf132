//! Node parameters: declared types with defaults and ranges, and the values a graph gives them.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

use crate::yaml::{resolve_scalar, Scalar, Yaml, YamlKind};

/// A parameter value as written in a graph file (or on the command line).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ParamValue {
    /// `true` / `false`.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A float.
    Float(f64),
    /// A string (also paths and enum choices).
    Str(String),
    /// A list of values.
    List(Vec<ParamValue>),
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamValue::Bool(b) => write!(f, "{b}"),
            ParamValue::Int(i) => write!(f, "{i}"),
            ParamValue::Float(x) => write!(f, "{x}"),
            ParamValue::Str(s) => write!(f, "{s:?}"),
            ParamValue::List(l) => {
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

impl ParamValue {
    /// Canonical bytes for hashing: a tag byte then the value (floats by their bits, with
    /// `-0.0` folded into `0.0`).
    pub fn canonical(&self, out: &mut Vec<u8>) {
        match self {
            ParamValue::Bool(b) => {
                out.push(b'b');
                out.push(u8::from(*b));
            }
            ParamValue::Int(i) => {
                out.push(b'i');
                out.extend_from_slice(&i.to_le_bytes());
            }
            ParamValue::Float(x) => {
                out.push(b'f');
                let x = if *x == 0.0 { 0.0 } else { *x };
                out.extend_from_slice(&x.to_bits().to_le_bytes());
            }
            ParamValue::Str(s) => {
                out.push(b's');
                out.extend_from_slice(&(s.len() as u64).to_le_bytes());
                out.extend_from_slice(s.as_bytes());
            }
            ParamValue::List(l) => {
                out.push(b'l');
                out.extend_from_slice(&(l.len() as u64).to_le_bytes());
                for v in l {
                    v.canonical(out);
                }
            }
        }
    }

    /// Converts a YAML value. Mappings are not parameter values.
    pub fn from_yaml(y: &Yaml) -> Result<ParamValue, String> {
        match &y.kind {
            YamlKind::Scalar { text, plain } => Ok(match resolve_scalar(text, *plain) {
                Scalar::Null => return Err("a value is required here, not null".into()),
                Scalar::Bool(b) => ParamValue::Bool(b),
                Scalar::Int(i) => ParamValue::Int(i),
                Scalar::Float(x) => ParamValue::Float(x),
                Scalar::Str(s) => ParamValue::Str(s.to_string()),
            }),
            YamlKind::Seq(items) => items
                .iter()
                .map(ParamValue::from_yaml)
                .collect::<Result<_, _>>()
                .map(ParamValue::List),
            YamlKind::Map(_) => Err("expected a value, found a mapping".into()),
        }
    }

    /// Parses a command-line override value the way YAML would read it.
    pub fn parse_cli(text: &str) -> Result<ParamValue, String> {
        let y = crate::yaml::parse(text).map_err(|e| e.message)?;
        ParamValue::from_yaml(&y)
    }

    fn kind_name(&self) -> &'static str {
        match self {
            ParamValue::Bool(_) => "a boolean",
            ParamValue::Int(_) => "an integer",
            ParamValue::Float(_) => "a float",
            ParamValue::Str(_) => "a string",
            ParamValue::List(_) => "a list",
        }
    }
}

/// Whether a path parameter names a file the node reads or one it writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathRole {
    /// Read: the engine hashes the file's content into the cache key.
    Input,
    /// Written: the engine records the written file's digest and reruns if it is gone or changed.
    Output,
}

/// The declared type of a parameter.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamType {
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
    /// graph file's folder; input lists are hashed file by file like [`ParamType::Path`]. No
    /// frame patterns.
    PathList(PathRole),
    /// A list of floats (e.g. a 3-vector or a matrix in rows).
    FloatList {
        /// Required length, if fixed.
        len: Option<usize>,
    },
}

impl fmt::Display for ParamType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamType::Bool => write!(f, "bool"),
            ParamType::Int { min, max } => {
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
            ParamType::Float { min, max } => {
                write!(f, "float")?;
                if min.is_finite() || max.is_finite() {
                    write!(f, " in [{min}, {max}]")?;
                }
                Ok(())
            }
            ParamType::Str => write!(f, "string"),
            ParamType::Enum(c) => write!(f, "one of {}", c.join(" | ")),
            ParamType::Path(PathRole::Input) => write!(f, "input path"),
            ParamType::Path(PathRole::Output) => write!(f, "output path"),
            ParamType::PathList(PathRole::Input) => write!(f, "list of input paths"),
            ParamType::PathList(PathRole::Output) => write!(f, "list of output paths"),
            ParamType::FloatList { len: Some(n) } => write!(f, "list of {n} floats"),
            ParamType::FloatList { len: None } => write!(f, "list of floats"),
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

impl ParamType {
    /// Checks `v` and normalizes it (an integer given to a float parameter becomes a float).
    pub fn check(&self, v: ParamValue) -> Result<ParamValue, ParamCheck> {
        let wrong = |v: &ParamValue, want: &str| {
            ParamCheck::Type(format!("expected {want}, found {} `{v}`", v.kind_name()))
        };
        match (self, v) {
            (ParamType::Bool, v @ ParamValue::Bool(_)) => Ok(v),
            (ParamType::Int { min, max }, ParamValue::Int(i)) => {
                if i < *min || i > *max {
                    Err(ParamCheck::Range(format!("{i} is outside {self}")))
                } else {
                    Ok(ParamValue::Int(i))
                }
            }
            (ParamType::Float { min, max }, ParamValue::Int(i)) => ParamType::Float {
                min: *min,
                max: *max,
            }
            .check(ParamValue::Float(i as f64)),
            (ParamType::Float { min, max }, ParamValue::Float(x)) => {
                if !x.is_finite() {
                    Err(ParamCheck::Range(format!("{x} is not a finite number")))
                } else if x < *min || x > *max {
                    Err(ParamCheck::Range(format!("{x} is outside {self}")))
                } else {
                    Ok(ParamValue::Float(x))
                }
            }
            (ParamType::Path(_), ParamValue::Str(s)) => {
                match crate::node::check_frame_pattern(&s) {
                    Ok(()) => Ok(ParamValue::Str(s)),
                    Err(e) => Err(ParamCheck::Range(e)),
                }
            }
            (ParamType::Str, v @ ParamValue::Str(_)) => Ok(v),
            (ParamType::Enum(choices), ParamValue::Str(s)) => {
                if choices.contains(&s.as_str()) {
                    Ok(ParamValue::Str(s))
                } else {
                    Err(ParamCheck::Range(format!(
                        "`{s}` is not {}",
                        ParamType::Enum(choices)
                    )))
                }
            }
            (ParamType::PathList(_), ParamValue::List(items)) => {
                for it in &items {
                    if !matches!(it, ParamValue::Str(_)) {
                        return Err(wrong(it, "a path (string) in the list"));
                    }
                }
                Ok(ParamValue::List(items))
            }
            (ParamType::FloatList { len }, ParamValue::List(items)) => {
                let mut out = Vec::with_capacity(items.len());
                for it in items {
                    match it {
                        ParamValue::Int(i) => out.push(ParamValue::Float(i as f64)),
                        ParamValue::Float(x) if x.is_finite() => out.push(ParamValue::Float(x)),
                        other => return Err(wrong(&other, "a finite number in the list")),
                    }
                }
                match len {
                    Some(n) if *n != out.len() => Err(ParamCheck::Range(format!(
                        "expected {n} numbers, found {}",
                        out.len()
                    ))),
                    _ => Ok(ParamValue::List(out)),
                }
            }
            (t, v) => Err(wrong(&v, &t.to_string())),
        }
    }
}

/// A declared parameter.
#[derive(Clone, Debug)]
pub struct ParamSpec {
    /// Name used in the graph file.
    pub name: &'static str,
    /// Its type.
    pub ty: ParamType,
    /// Default value; `None` means required.
    pub default: Option<ParamValue>,
    /// One line of documentation.
    pub doc: &'static str,
    /// False for cosmetic params (labels, verbosity) that must not invalidate the cache.
    pub affects_output: bool,
}

impl ParamSpec {
    /// A required parameter.
    pub fn required(name: &'static str, ty: ParamType, doc: &'static str) -> Self {
        ParamSpec {
            name,
            ty,
            default: None,
            doc,
            affects_output: true,
        }
    }

    /// An optional parameter with a default.
    pub fn optional(
        name: &'static str,
        ty: ParamType,
        default: ParamValue,
        doc: &'static str,
    ) -> Self {
        ParamSpec {
            name,
            ty,
            default: Some(default),
            doc,
            affects_output: true,
        }
    }

    /// Marks the parameter cosmetic: it does not enter the cache key.
    pub fn cosmetic(mut self) -> Self {
        self.affects_output = false;
        self
    }
}

/// The checked parameter values of one node, defaults filled in.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Params {
    values: BTreeMap<String, ParamValue>,
}

impl Params {
    /// Builds from checked values.
    pub fn new(values: BTreeMap<String, ParamValue>) -> Self {
        Params { values }
    }

    /// The raw value.
    pub fn get(&self, name: &str) -> Option<&ParamValue> {
        self.values.get(name)
    }

    /// All values by name.
    pub fn iter(&self) -> impl Iterator<Item = (&String, &ParamValue)> {
        self.values.iter()
    }

    /// Sets a value (used by overrides; callers check the type first).
    pub fn set(&mut self, name: &str, v: ParamValue) {
        self.values.insert(name.to_string(), v);
    }

    /// A float parameter (integers convert).
    pub fn f64(&self, name: &str) -> f64 {
        match self.values.get(name) {
            Some(ParamValue::Float(x)) => *x,
            Some(ParamValue::Int(i)) => *i as f64,
            other => panic!("param `{name}` is not a float: {other:?} (node spec bug)"),
        }
    }

    /// An integer parameter.
    pub fn i64(&self, name: &str) -> i64 {
        match self.values.get(name) {
            Some(ParamValue::Int(i)) => *i,
            other => panic!("param `{name}` is not an int: {other:?} (node spec bug)"),
        }
    }

    /// A boolean parameter.
    pub fn bool(&self, name: &str) -> bool {
        match self.values.get(name) {
            Some(ParamValue::Bool(b)) => *b,
            other => panic!("param `{name}` is not a bool: {other:?} (node spec bug)"),
        }
    }

    /// A string, enum or path parameter as written.
    pub fn str(&self, name: &str) -> &str {
        match self.values.get(name) {
            Some(ParamValue::Str(s)) => s,
            other => panic!("param `{name}` is not a string: {other:?} (node spec bug)"),
        }
    }

    /// A path-list parameter as written.
    pub fn strs(&self, name: &str) -> Vec<&str> {
        match self.values.get(name) {
            Some(ParamValue::List(l)) => l
                .iter()
                .map(|v| match v {
                    ParamValue::Str(s) => s.as_str(),
                    other => panic!("param `{name}` holds {other:?} (node spec bug)"),
                })
                .collect(),
            other => panic!("param `{name}` is not a list: {other:?} (node spec bug)"),
        }
    }

    /// A float-list parameter.
    pub fn f64s(&self, name: &str) -> Vec<f64> {
        match self.values.get(name) {
            Some(ParamValue::List(l)) => l
                .iter()
                .map(|v| match v {
                    ParamValue::Float(x) => *x,
                    ParamValue::Int(i) => *i as f64,
                    other => panic!("param `{name}` holds {other:?} (node spec bug)"),
                })
                .collect(),
            other => panic!("param `{name}` is not a list: {other:?} (node spec bug)"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks() {
        let f = ParamType::Float { min: 0.0, max: 1.0 };
        assert_eq!(f.check(ParamValue::Int(1)), Ok(ParamValue::Float(1.0)));
        assert!(matches!(
            f.check(ParamValue::Float(2.0)),
            Err(ParamCheck::Range(_))
        ));
        assert!(matches!(
            f.check(ParamValue::Str("x".into())),
            Err(ParamCheck::Type(_))
        ));
        assert!(matches!(
            f.check(ParamValue::Float(f64::NAN)),
            Err(ParamCheck::Range(_))
        ));
        let e = ParamType::Enum(&["srgb", "reinhard"]);
        assert!(e.check(ParamValue::Str("srgb".into())).is_ok());
        assert!(matches!(
            e.check(ParamValue::Str("aces".into())),
            Err(ParamCheck::Range(_))
        ));
        let l = ParamType::PathList(PathRole::Input);
        let ok = ParamValue::List(vec![ParamValue::Str("a.png".into())]);
        assert_eq!(l.check(ok.clone()), Ok(ok));
        assert!(matches!(
            l.check(ParamValue::List(vec![ParamValue::Int(1)])),
            Err(ParamCheck::Type(_))
        ));
        assert!(matches!(
            l.check(ParamValue::Str("a.png".into())),
            Err(ParamCheck::Type(_))
        ));
    }

    #[test]
    fn canonical_distinguishes_types() {
        let enc = |v: ParamValue| {
            let mut o = Vec::new();
            v.canonical(&mut o);
            o
        };
        assert_ne!(enc(ParamValue::Int(1)), enc(ParamValue::Float(1.0)));
        assert_eq!(enc(ParamValue::Float(0.0)), enc(ParamValue::Float(-0.0)));
    }

    #[test]
    fn cli_values() {
        assert_eq!(ParamValue::parse_cli("2"), Ok(ParamValue::Int(2)));
        assert_eq!(ParamValue::parse_cli("0.5"), Ok(ParamValue::Float(0.5)));
        assert_eq!(
            ParamValue::parse_cli("reinhard"),
            Ok(ParamValue::Str("reinhard".into()))
        );
        assert_eq!(
            ParamValue::parse_cli("[1, 2]"),
            Ok(ParamValue::List(vec![
                ParamValue::Int(1),
                ParamValue::Int(2)
            ]))
        );
    }
}
