//! Node parameters: the values a graph gives them, checked against their declared kinds.
//!
//! Parameters are declared with the `vfxgraph-params` types ([`ParamDesc`], [`Kind`],
//! [`PathRole`]) and hold its [`Value`](vfxgraph_params::Value), named [`ParamValue`] here (apart
//! from the artifact [`Value`](crate::Value)). This module adds what only the engine knows: a
//! value's YAML form, its canonical bytes for the cache key, frame patterns in paths.

use std::collections::BTreeMap;

use vfxgraph_params::Source;
pub use vfxgraph_params::{Kind, ParamCheck, ParamDesc, PathRole, Value as ParamValue};

use crate::yaml::{resolve_scalar, Scalar, Yaml, YamlKind};

/// Canonical bytes of `v` for hashing: a tag byte then the value (floats by their bits, with
/// `-0.0` folded into `0.0`).
pub fn canonical(v: &ParamValue, out: &mut Vec<u8>) {
    match v {
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
                canonical(v, out);
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
            .map(from_yaml)
            .collect::<Result<_, _>>()
            .map(ParamValue::List),
        YamlKind::Map(_) => Err("expected a value, found a mapping".into()),
    }
}

/// Parses a command-line override value the way YAML would read it.
pub fn parse_cli(text: &str) -> Result<ParamValue, String> {
    let y = crate::yaml::parse(text).map_err(|e| e.message)?;
    from_yaml(&y)
}

/// Checks `v` against `kind` ([`Kind::check`]) and a path's frame pattern.
pub fn check(kind: &Kind, v: ParamValue) -> Result<ParamValue, ParamCheck> {
    let v = kind.check(v)?;
    if let (Kind::Path(_), ParamValue::Str(s)) = (kind, &v) {
        crate::node::check_frame_pattern(s).map_err(ParamCheck::Range)?;
    }
    Ok(v)
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

impl Source for Params {
    fn value(&self, name: &str) -> Option<ParamValue> {
        self.get(name).cloned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks() {
        let f = Kind::Float { min: 0.0, max: 1.0 };
        assert_eq!(check(&f, ParamValue::Int(1)), Ok(ParamValue::Float(1.0)));
        assert!(matches!(
            check(&f, ParamValue::Float(2.0)),
            Err(ParamCheck::Range(_))
        ));
        assert!(matches!(
            check(&f, ParamValue::Str("x".into())),
            Err(ParamCheck::Type(_))
        ));
        assert!(matches!(
            check(&f, ParamValue::Float(f64::NAN)),
            Err(ParamCheck::Range(_))
        ));
        let e = Kind::Enum(&["srgb", "reinhard"]);
        assert!(check(&e, ParamValue::Str("srgb".into())).is_ok());
        assert!(matches!(
            check(&e, ParamValue::Str("aces".into())),
            Err(ParamCheck::Range(_))
        ));
        let l = Kind::PathList(PathRole::Input);
        let ok = ParamValue::List(vec![ParamValue::Str("a.png".into())]);
        assert_eq!(check(&l, ok.clone()), Ok(ok));
        assert!(matches!(
            check(&l, ParamValue::List(vec![ParamValue::Int(1)])),
            Err(ParamCheck::Type(_))
        ));
        assert!(matches!(
            check(&l, ParamValue::Str("a.png".into())),
            Err(ParamCheck::Type(_))
        ));
    }

    #[test]
    fn canonical_distinguishes_types() {
        let enc = |v: ParamValue| {
            let mut o = Vec::new();
            canonical(&v, &mut o);
            o
        };
        assert_ne!(enc(ParamValue::Int(1)), enc(ParamValue::Float(1.0)));
        assert_eq!(enc(ParamValue::Float(0.0)), enc(ParamValue::Float(-0.0)));
    }

    #[test]
    fn cli_values() {
        assert_eq!(parse_cli("2"), Ok(ParamValue::Int(2)));
        assert_eq!(parse_cli("0.5"), Ok(ParamValue::Float(0.5)));
        assert_eq!(
            parse_cli("reinhard"),
            Ok(ParamValue::Str("reinhard".into()))
        );
        assert_eq!(
            parse_cli("[1, 2]"),
            Ok(ParamValue::List(vec![
                ParamValue::Int(1),
                ParamValue::Int(2)
            ]))
        );
    }
}
