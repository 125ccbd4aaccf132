//! A YAML document tree that remembers where every value came from.
//!
//! Graph files are parsed into this tree (not straight into structs) so that validation can
//! point at the exact line and column of an offending value, and so that duplicate mapping keys
//! (duplicate node ids) are seen rather than silently merged. Events come from `saphyr-parser`,
//! a maintained, pure-Rust YAML 1.2 parser.

use saphyr_parser::{Event, Parser, ScalarStyle};

use crate::diagnostic::Span;

/// One YAML value with its source span.
#[derive(Clone, Debug, PartialEq)]
pub struct Yaml {
    /// The value.
    pub kind: YamlKind,
    /// Where it is in the source text.
    pub span: Span,
}

/// The shape of a YAML value.
#[derive(Clone, Debug, PartialEq)]
pub enum YamlKind {
    /// A scalar: its text and whether it was written plain (unquoted), which decides whether
    /// `true`, `3` or `null` are typed values or strings.
    Scalar {
        /// The scalar's text.
        text: String,
        /// True for a plain (unquoted, non-block) scalar.
        plain: bool,
    },
    /// A sequence.
    Seq(Vec<Yaml>),
    /// A mapping, in source order; duplicate keys are kept so callers can report them.
    Map(Vec<(Yaml, Yaml)>),
}

impl Yaml {
    /// The scalar text, if this is a scalar.
    pub fn as_str(&self) -> Option<&str> {
        match &self.kind {
            YamlKind::Scalar { text, .. } => Some(text),
            _ => None,
        }
    }

    /// The mapping entries, if this is a mapping.
    pub fn as_map(&self) -> Option<&[(Yaml, Yaml)]> {
        match &self.kind {
            YamlKind::Map(m) => Some(m),
            _ => None,
        }
    }

    /// True for a plain `null`, `~` or empty scalar.
    pub fn is_null(&self) -> bool {
        matches!(&self.kind, YamlKind::Scalar { text, plain: true } if text.is_empty() || text == "~" || text == "null" || text == "Null" || text == "NULL")
    }

    /// A short description of the value's shape, for error messages.
    pub fn shape(&self) -> &'static str {
        match &self.kind {
            YamlKind::Scalar { .. } => "a scalar",
            YamlKind::Seq(_) => "a list",
            YamlKind::Map(_) => "a mapping",
        }
    }
}

/// A YAML syntax error with its position.
#[derive(Clone, Debug, PartialEq)]
pub struct YamlError {
    /// What the parser said.
    pub message: String,
    /// Where.
    pub span: Span,
}

/// Deepest nesting of collections accepted (the tree is built, compared and dropped by
/// recursion; graph files nest a few levels).
pub const MAX_DEPTH: usize = 128;

/// Most values a document may expand to through aliases (each alias copies its anchor's
/// tree, so nested aliases grow exponentially: the "billion laughs" document).
pub const MAX_ALIAS_VALUES: usize = 1_000_000;

/// The number of values in a tree (iterative: the tree may be deep).
fn count_values(y: &Yaml) -> usize {
    let mut n = 0;
    let mut todo = vec![y];
    while let Some(v) = todo.pop() {
        n += 1;
        match &v.kind {
            YamlKind::Scalar { .. } => {}
            YamlKind::Seq(items) => todo.extend(items),
            YamlKind::Map(entries) => todo.extend(entries.iter().flat_map(|(k, v)| [k, v])),
        }
    }
    n
}

/// Parses one YAML document into a spanned tree. An empty document is an empty mapping.
/// Nesting deeper than [`MAX_DEPTH`] and aliases expanding to more than [`MAX_ALIAS_VALUES`]
/// values are errors.
pub fn parse(src: &str) -> Result<Yaml, YamlError> {
    let offsets = CharOffsets::new(src);
    let mut stack: Vec<Frame> = Vec::new();
    // Each anchor's tree and its number of values.
    let mut anchors: Vec<Option<(Yaml, usize)>> = Vec::new();
    let mut alias_values = 0usize;
    let mut root: Option<Yaml> = None;
    let parser = Parser::new_from_str(src);
    for item in parser {
        let (event, span) = item.map_err(|e| YamlError {
            message: e.info().to_string(),
            span: offsets.point(e.marker().index(), e.marker().line(), e.marker().col()),
        })?;
        let start = offsets.point(span.start.index(), span.start.line(), span.start.col());
        let end_index = span.end.index();
        let finished: Option<(Yaml, usize)> = match event {
            Event::Scalar(text, style, anchor, _tag) => {
                let mut sp = start;
                sp.len = offsets.byte(end_index).saturating_sub(sp.offset).max(1);
                let value = Yaml {
                    kind: YamlKind::Scalar {
                        text: text.into_owned(),
                        plain: style == ScalarStyle::Plain,
                    },
                    span: sp,
                };
                Some((value, anchor))
            }
            Event::Alias(id) => match anchors.get(id).and_then(|a| a.as_ref()) {
                Some((v, n)) => {
                    alias_values += n;
                    if alias_values > MAX_ALIAS_VALUES {
                        return Err(YamlError {
                            message: format!(
                                "aliases expand to more than {MAX_ALIAS_VALUES} values"
                            ),
                            span: start,
                        });
                    }
                    let mut v = v.clone();
                    v.span = start;
                    Some((v, 0))
                }
                None => {
                    return Err(YamlError {
                        message: "alias refers to an unknown anchor".into(),
                        span: start,
                    })
                }
            },
            Event::SequenceStart(anchor, _) => {
                if stack.len() == MAX_DEPTH {
                    return Err(YamlError {
                        message: format!("collections nested deeper than {MAX_DEPTH} levels"),
                        span: start,
                    });
                }
                stack.push(Frame {
                    start,
                    anchor,
                    items: Vec::new(),
                    is_map: false,
                });
                None
            }
            Event::MappingStart(anchor, _) => {
                if stack.len() == MAX_DEPTH {
                    return Err(YamlError {
                        message: format!("collections nested deeper than {MAX_DEPTH} levels"),
                        span: start,
                    });
                }
                stack.push(Frame {
                    start,
                    anchor,
                    items: Vec::new(),
                    is_map: true,
                });
                None
            }
            Event::SequenceEnd | Event::MappingEnd => {
                let frame = stack.pop().ok_or_else(|| YamlError {
                    message: "unbalanced collection".into(),
                    span: start,
                })?;
                let kind = if frame.is_map {
                    let mut entries = Vec::with_capacity(frame.items.len() / 2);
                    let mut it = frame.items.into_iter();
                    while let (Some(k), Some(v)) = (it.next(), it.next()) {
                        entries.push((k, v));
                    }
                    YamlKind::Map(entries)
                } else {
                    YamlKind::Seq(frame.items)
                };
                let mut sp = frame.start;
                sp.len = offsets.byte(end_index).saturating_sub(sp.offset).max(1);
                Some((Yaml { kind, span: sp }, frame.anchor))
            }
            Event::DocumentEnd | Event::StreamEnd => {
                // A second document is ignored: graph files are one document.
                if root.is_some() {
                    break;
                }
                None
            }
            _ => None,
        };
        if let Some((value, anchor)) = finished {
            if anchor > 0 {
                if anchors.len() <= anchor {
                    anchors.resize(anchor + 1, None);
                }
                anchors[anchor] = Some((value.clone(), count_values(&value)));
            }
            match stack.last_mut() {
                Some(parent) => parent.items.push(value),
                None => {
                    root = Some(value);
                }
            }
        }
    }
    Ok(root.unwrap_or(Yaml {
        kind: YamlKind::Map(Vec::new()),
        span: Span::point(1, 1, 0),
    }))
}

struct Frame {
    start: Span,
    anchor: usize,
    items: Vec<Yaml>,
    is_map: bool,
}

/// Maps the parser's character indices to byte offsets.
struct CharOffsets {
    bytes: Vec<usize>,
}

impl CharOffsets {
    fn new(src: &str) -> Self {
        let mut bytes: Vec<usize> = src.char_indices().map(|(b, _)| b).collect();
        bytes.push(src.len());
        CharOffsets { bytes }
    }

    fn byte(&self, char_index: usize) -> usize {
        self.bytes
            .get(char_index)
            .copied()
            .unwrap_or_else(|| *self.bytes.last().unwrap_or(&0))
    }

    /// `line` 1-based and `col` 0-based as the parser gives them.
    fn point(&self, char_index: usize, line: usize, col: usize) -> Span {
        Span::point(line.max(1), col + 1, self.byte(char_index))
    }
}

/// Interprets a YAML 1.2 core-schema plain scalar.
#[derive(Clone, Debug, PartialEq)]
pub enum Scalar<'a> {
    /// `null`, `~` or empty.
    Null,
    /// `true` / `false`.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A float (including `.inf`, `.nan`).
    Float(f64),
    /// Anything else, or any quoted scalar.
    Str(&'a str),
}

/// Resolves a scalar the way YAML 1.2's core schema does for plain scalars.
pub fn resolve_scalar(text: &str, plain: bool) -> Scalar<'_> {
    if !plain {
        return Scalar::Str(text);
    }
    match text {
        "" | "~" | "null" | "Null" | "NULL" => return Scalar::Null,
        "true" | "True" | "TRUE" => return Scalar::Bool(true),
        "false" | "False" | "FALSE" => return Scalar::Bool(false),
        ".inf" | ".Inf" | ".INF" | "+.inf" | "+.Inf" | "+.INF" => {
            return Scalar::Float(f64::INFINITY)
        }
        "-.inf" | "-.Inf" | "-.INF" => return Scalar::Float(f64::NEG_INFINITY),
        ".nan" | ".NaN" | ".NAN" => return Scalar::Float(f64::NAN),
        _ => {}
    }
    let digits = text.trim_start_matches(['-', '+']);
    if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
        if let Ok(i) = text.parse::<i64>() {
            return Scalar::Int(i);
        }
    }
    if let Some(hex) = text.strip_prefix("0x") {
        if let Ok(i) = i64::from_str_radix(hex, 16) {
            return Scalar::Int(i);
        }
    }
    let looks_numeric = text
        .bytes()
        .all(|b| b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+' | b'e' | b'E'))
        && text.bytes().any(|b| b.is_ascii_digit());
    if looks_numeric {
        if let Ok(f) = text.parse::<f64>() {
            return Scalar::Float(f);
        }
    }
    Scalar::Str(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_point_at_values() {
        let src = "version: 1\nnodes:\n  a:\n    type: read_image\n";
        let y = parse(src).unwrap();
        let m = y.as_map().unwrap();
        assert_eq!(m[0].0.as_str(), Some("version"));
        assert_eq!((m[0].1.span.line, m[0].1.span.col), (1, 10));
        let nodes = m[1].1.as_map().unwrap();
        let a = nodes[0].1.as_map().unwrap();
        assert_eq!(a[0].1.as_str(), Some("read_image"));
        assert_eq!((a[0].1.span.line, a[0].1.span.col), (4, 11));
        let sp = a[0].1.span;
        assert_eq!(&src[sp.offset..sp.offset + sp.len], "read_image");
    }

    #[test]
    fn duplicate_keys_are_kept() {
        let y = parse("a: 1\na: 2\n").unwrap();
        assert_eq!(y.as_map().unwrap().len(), 2);
    }

    #[test]
    fn syntax_error_has_position() {
        let e = parse("a: [1, 2\nb: 3\n").unwrap_err();
        assert!(e.span.line >= 1, "{e:?}");
        assert!(!e.message.is_empty());
    }

    #[test]
    fn aliases_resolve() {
        let y = parse("a: &x {k: 1}\nb: *x\n").unwrap();
        let m = y.as_map().unwrap();
        assert_eq!(m[1].1.as_map().unwrap()[0].1.as_str(), Some("1"));
    }

    /// Regression (found in review, reproduced with the fuzz harness: a hang): nested aliases
    /// (a "billion laughs" document, 10^9 values from 500 bytes) grew the tree exponentially;
    /// now an error at the alias that crosses the budget.
    #[test]
    fn alias_bombs_are_refused() {
        let mut doc = String::from("l0: &l0 [x, x, x, x, x, x, x, x, x, x]\n");
        for k in 1..9 {
            let refs = vec![format!("*l{}", k - 1); 10].join(", ");
            doc += &format!("l{k}: &l{k} [{refs}]\n");
        }
        let e = parse(&doc).unwrap_err();
        assert!(e.message.contains("more than 1000000 values"), "{e:?}");
        assert_eq!(e.span.line, 6, "{e:?}"); // l5 (10^6 values) crosses it
                                             // Ten thousand values through aliases are fine.
        let small: String = doc.lines().take(4).map(|l| format!("{l}\n")).collect();
        assert!(parse(&small).is_ok());
    }

    /// Regression (found in review, reproduced with the fuzz harness: a stack overflow on a
    /// 2 MiB thread): deep block nesting (`- - - …`) made a tree too deep to drop; now an error.
    #[test]
    fn deep_nesting_is_refused() {
        let e = parse(&"- ".repeat(100_000)).unwrap_err();
        assert!(e.message.contains("deeper than 128"), "{e:?}");
        assert!(parse(&format!("{}x", "- ".repeat(100))).is_ok());
    }

    #[test]
    fn core_schema() {
        assert_eq!(resolve_scalar("12", true), Scalar::Int(12));
        assert_eq!(resolve_scalar("-3", true), Scalar::Int(-3));
        assert_eq!(resolve_scalar("1.5", true), Scalar::Float(1.5));
        assert_eq!(resolve_scalar("1e3", true), Scalar::Float(1000.0));
        assert_eq!(resolve_scalar("true", true), Scalar::Bool(true));
        assert_eq!(resolve_scalar("true", false), Scalar::Str("true"));
        assert_eq!(resolve_scalar("0..=239", true), Scalar::Str("0..=239"));
        assert_eq!(resolve_scalar("~", true), Scalar::Null);
    }
}
