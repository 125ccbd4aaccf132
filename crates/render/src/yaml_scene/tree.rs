//! The spanned YAML tree of a scene file: `saphyr-parser` events built into [`Node`]s that keep
//! the line:column of every value (anchors and aliases resolved, nesting bounded), and the typed
//! accessors the scene reader calls (`num`, `vec3`, `fields`, …), each failing with an error at
//! the offending value. The scene vocabulary itself is in the parent module.

use saphyr_parser::{Event, Parser, ScalarStyle};

use super::YamlSceneError;
use crate::math::{Rgb, Vec3};

#[derive(Clone, Debug)]
pub(super) struct Node {
    pub(super) kind: Kind,
    pub(super) line: usize,
    pub(super) col: usize,
}

#[derive(Clone, Debug)]
pub(super) enum Kind {
    Scalar(String, bool),
    Seq(Vec<Node>),
    Map(Vec<(Node, Node)>),
}

pub(super) type R<T> = Result<T, YamlSceneError>;

pub(super) fn err<T>(n: &Node, message: impl Into<String>) -> R<T> {
    Err(YamlSceneError {
        line: n.line,
        col: n.col,
        message: message.into(),
    })
}

/// Deepest nesting of collections accepted (scenes nest four levels; the tree is dropped by
/// recursion, which a document of `- - - …` would overflow).
pub(super) const MAX_DEPTH: usize = 128;

pub(super) fn parse_tree(src: &str) -> R<Node> {
    struct Open {
        line: usize,
        col: usize,
        map: bool,
        items: Vec<Node>,
    }
    let mut stack: Vec<Open> = Vec::new();
    let mut anchors: Vec<Option<Node>> = Vec::new();
    let mut root = None;
    for item in Parser::new_from_str(src) {
        let (event, span) = item.map_err(|e| YamlSceneError {
            line: e.marker().line().max(1),
            col: e.marker().col() + 1,
            message: e.info().to_string(),
        })?;
        let (line, col) = (span.start.line().max(1), span.start.col() + 1);
        let done = match event {
            Event::Scalar(text, style, anchor, _) => Some((
                Node {
                    kind: Kind::Scalar(text.into_owned(), style == ScalarStyle::Plain),
                    line,
                    col,
                },
                anchor,
            )),
            Event::Alias(id) => {
                let mut n = anchors.get(id).cloned().flatten().ok_or(YamlSceneError {
                    line,
                    col,
                    message: "alias of an unknown anchor".into(),
                })?;
                (n.line, n.col) = (line, col);
                Some((n, 0))
            }
            Event::SequenceStart(..) | Event::MappingStart(..) => {
                if stack.len() == MAX_DEPTH {
                    return Err(YamlSceneError {
                        line,
                        col,
                        message: format!("collections nested deeper than {MAX_DEPTH} levels"),
                    });
                }
                stack.push(Open {
                    line,
                    col,
                    map: matches!(event, Event::MappingStart(..)),
                    items: Vec::new(),
                });
                None
            }
            Event::SequenceEnd | Event::MappingEnd => {
                let o = stack.pop().ok_or(YamlSceneError {
                    line,
                    col,
                    message: "unbalanced collection".into(),
                })?;
                let kind = if o.map {
                    let mut it = o.items.into_iter();
                    let mut m = Vec::new();
                    while let (Some(k), Some(v)) = (it.next(), it.next()) {
                        m.push((k, v));
                    }
                    Kind::Map(m)
                } else {
                    Kind::Seq(o.items)
                };
                // Anchors on collections: the start event carried it; not tracked (rare in
                // scenes), aliases to them are reported as unknown.
                Some((
                    Node {
                        kind,
                        line: o.line,
                        col: o.col,
                    },
                    0,
                ))
            }
            _ => None,
        };
        if let Some((n, anchor)) = done {
            if anchor > 0 {
                if anchors.len() <= anchor {
                    anchors.resize(anchor + 1, None);
                }
                anchors[anchor] = Some(n.clone());
            }
            match stack.last_mut() {
                Some(p) => p.items.push(n),
                None => {
                    if root.is_none() {
                        root = Some(n)
                    }
                }
            }
        }
    }
    Ok(root.unwrap_or(Node {
        kind: Kind::Map(Vec::new()),
        line: 1,
        col: 1,
    }))
}

impl Node {
    pub(super) fn describe(&self) -> String {
        match &self.kind {
            Kind::Scalar(s, _) => format!("`{s}`"),
            Kind::Seq(_) => "a list".into(),
            Kind::Map(_) => "a mapping".into(),
        }
    }
    pub(super) fn str(&self, what: &str) -> R<&str> {
        match &self.kind {
            Kind::Scalar(s, _) => Ok(s),
            _ => err(
                self,
                format!("{what}: expected a string, found {}", self.describe()),
            ),
        }
    }
    pub(super) fn num(&self, what: &str) -> R<f64> {
        match &self.kind {
            Kind::Scalar(s, true) => match s.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => err(
                    self,
                    format!("{what}: expected a finite number, found `{s}`"),
                ),
            },
            _ => err(
                self,
                format!("{what}: expected a number, found {}", self.describe()),
            ),
        }
    }
    pub(super) fn list(&self, what: &str) -> R<&[Node]> {
        match &self.kind {
            Kind::Seq(v) => Ok(v),
            _ => err(
                self,
                format!("{what}: expected a list, found {}", self.describe()),
            ),
        }
    }
    pub(super) fn nums<const N: usize>(&self, what: &str) -> R<[f64; N]> {
        let l = self.list(what)?;
        if l.len() != N {
            return err(
                self,
                format!("{what}: expected {N} numbers, found {}", l.len()),
            );
        }
        let mut out = [0.0; N];
        for (o, n) in out.iter_mut().zip(l) {
            *o = n.num(what)?;
        }
        Ok(out)
    }
    pub(super) fn vec3(&self, what: &str) -> R<Vec3> {
        Ok(Vec3::from_array(self.nums::<3>(what)?))
    }
    pub(super) fn rgb(&self, what: &str) -> R<Rgb> {
        // A single number is a grey.
        if let Kind::Scalar(..) = self.kind {
            let v = self.num(what)?;
            if v < 0.0 {
                return err(self, format!("{what} must be ≥ 0"));
            }
            return Ok(Rgb::splat(v));
        }
        let [r, g, b] = self.nums::<3>(what)?;
        if r < 0.0 || g < 0.0 || b < 0.0 {
            return err(self, format!("{what} must be ≥ 0"));
        }
        Ok(Rgb::new(r, g, b))
    }
    pub(super) fn mat3(&self, what: &str) -> R<[[f64; 3]; 3]> {
        let rows = self.list(what)?;
        if rows.len() != 3 {
            return err(
                self,
                format!("{what}: expected 3 rows, found {}", rows.len()),
            );
        }
        Ok([
            rows[0].nums::<3>(what)?,
            rows[1].nums::<3>(what)?,
            rows[2].nums::<3>(what)?,
        ])
    }
    pub(super) fn bool(&self, what: &str) -> R<bool> {
        match &self.kind {
            Kind::Scalar(s, true) if s == "true" => Ok(true),
            Kind::Scalar(s, true) if s == "false" => Ok(false),
            _ => err(
                self,
                format!("{what}: expected true or false, found {}", self.describe()),
            ),
        }
    }
    /// A mapping with only the allowed keys (duplicates rejected).
    pub(super) fn fields(&self, what: &str, allowed: &[&str]) -> R<Fields<'_>> {
        let Kind::Map(m) = &self.kind else {
            return err(
                self,
                format!("{what}: expected a mapping, found {}", self.describe()),
            );
        };
        let mut out: Vec<(&str, &Node)> = Vec::new();
        for (k, v) in m {
            let key = k.str("key")?;
            if !allowed.contains(&key) {
                return err(
                    k,
                    format!(
                        "{what}: unknown field `{key}`; expected one of {}",
                        allowed.join(", ")
                    ),
                );
            }
            if out.iter().any(|(o, _)| *o == key) {
                return err(k, format!("{what}: duplicate field `{key}`"));
            }
            out.push((key, v));
        }
        Ok(Fields {
            node: self,
            what: what.to_string(),
            items: out,
        })
    }
}

pub(super) struct Fields<'a> {
    node: &'a Node,
    what: String,
    items: Vec<(&'a str, &'a Node)>,
}

impl<'a> Fields<'a> {
    pub(super) fn get(&self, k: &str) -> Option<&'a Node> {
        self.items
            .iter()
            .find(|(key, _)| *key == k)
            .map(|(_, v)| *v)
    }
    pub(super) fn req(&self, k: &str) -> R<&'a Node> {
        self.get(k).map_or_else(
            || err(self.node, format!("{}: missing `{k}`", self.what)),
            Ok,
        )
    }
    pub(super) fn num_or(&self, k: &str, d: f64) -> R<f64> {
        self.get(k).map_or(Ok(d), |n| n.num(k))
    }
    pub(super) fn rgb_or(&self, k: &str, d: Rgb) -> R<Rgb> {
        self.get(k).map_or(Ok(d), |n| n.rgb(k))
    }
}
