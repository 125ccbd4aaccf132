//! Positions in a graph file and the errors that point at them.
//!
//! Validation collects every problem it finds into [`Diagnostics`] rather than stopping at the
//! first. Each [`Diagnostic`] renders as `file:line:column: message` with the offending text, and
//! implements [`miette::Diagnostic`] so the CLI can draw the source snippet.

use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;

/// A place in a source text: 1-based line and column (in characters), and the byte range.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Span {
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub col: usize,
    /// Byte offset of the start.
    pub offset: usize,
    /// Length in bytes (at least 1 when rendered).
    pub len: usize,
}

impl Span {
    /// A one-character span.
    pub fn point(line: usize, col: usize, offset: usize) -> Span {
        Span {
            line,
            col,
            offset,
            len: 1,
        }
    }
}

/// What kind of problem a diagnostic reports; stable names, used by tests and `--json`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// The YAML itself does not parse.
    Syntax,
    /// A required top-level key is missing or a key has the wrong shape.
    Structure,
    /// `type:` names no registered node type.
    UnknownNodeType,
    /// A parameter the node type does not declare.
    UnknownParam,
    /// An input or output port the node type does not declare.
    UnknownPort,
    /// A parameter value of the wrong type.
    ParamType,
    /// A parameter value outside the declared range or choices.
    ParamRange,
    /// A required parameter is missing.
    MissingParam,
    /// A required input port is not connected.
    MissingInput,
    /// The connected output's type does not fit the input.
    TypeMismatch,
    /// `inputs:` names a node that does not exist.
    DanglingReference,
    /// The graph has a cycle.
    Cycle,
    /// Two nodes share one id.
    DuplicateId,
    /// A frame range that does not parse or is empty.
    Frames,
    /// A command-line override (`--set`) that does not apply.
    Override,
}

impl ErrorKind {
    /// A short stable code, e.g. `unknown-node-type`.
    pub fn code(self) -> &'static str {
        match self {
            ErrorKind::Syntax => "syntax",
            ErrorKind::Structure => "structure",
            ErrorKind::UnknownNodeType => "unknown-node-type",
            ErrorKind::UnknownParam => "unknown-param",
            ErrorKind::UnknownPort => "unknown-port",
            ErrorKind::ParamType => "param-type",
            ErrorKind::ParamRange => "param-range",
            ErrorKind::MissingParam => "missing-param",
            ErrorKind::MissingInput => "missing-input",
            ErrorKind::TypeMismatch => "type-mismatch",
            ErrorKind::DanglingReference => "dangling-reference",
            ErrorKind::Cycle => "cycle",
            ErrorKind::DuplicateId => "duplicate-id",
            ErrorKind::Frames => "frames",
            ErrorKind::Override => "override",
        }
    }
}

/// One problem in a graph file.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    /// What kind of problem.
    pub kind: ErrorKind,
    /// The message, naming the node and the offending value.
    pub message: String,
    /// Where, if the problem has a place in the file.
    pub span: Option<Span>,
    /// The source text under the span.
    pub text: String,
    /// A hint (e.g. "did you mean `blur`?").
    pub help: Option<String>,
}

/// All problems found in one graph file.
#[derive(Clone, Debug)]
pub struct Diagnostics {
    /// The graph file.
    pub file: PathBuf,
    /// Its text, for snippets.
    pub source: Arc<str>,
    /// The problems, in source order.
    pub items: Vec<Diagnostic>,
}

impl Diagnostics {
    /// Starts an empty list for `file`.
    pub fn new(file: PathBuf, source: Arc<str>) -> Self {
        Diagnostics {
            file,
            source,
            items: Vec::new(),
        }
    }

    /// Records a problem at `span`.
    pub fn push(&mut self, kind: ErrorKind, span: Option<Span>, message: impl Into<String>) {
        self.push_help(kind, span, message, None);
    }

    /// Records a problem with a hint.
    pub fn push_help(
        &mut self,
        kind: ErrorKind,
        span: Option<Span>,
        message: impl Into<String>,
        help: Option<String>,
    ) {
        let text = span
            .and_then(|s| self.source.get(s.offset..s.offset + s.len))
            .map(|t| t.lines().next().unwrap_or("").to_string())
            .unwrap_or_default();
        self.items.push(Diagnostic {
            kind,
            message: message.into(),
            span,
            text,
            help,
        });
    }

    /// True when nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Sorts by position (problems without a place last).
    pub fn sort(&mut self) {
        self.items.sort_by_key(|d| {
            d.span
                .map(|s| (0, s.line, s.col))
                .unwrap_or((1, usize::MAX, 0))
        });
    }

    /// One renderable report per problem, for miette.
    pub fn reports(&self) -> Vec<Report> {
        self.items
            .iter()
            .map(|d| Report {
                file: self.file.display().to_string(),
                source: self.source.clone(),
                diag: d.clone(),
            })
            .collect()
    }
}

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, d) in self.items.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{}", self.file.display())?;
            if let Some(s) = d.span {
                write!(f, ":{}:{}", s.line, s.col)?;
            }
            write!(f, ": error[{}]: {}", d.kind.code(), d.message)?;
            if !d.text.is_empty() {
                write!(f, " (at `{}`)", d.text)?;
            }
            if let Some(h) = &d.help {
                write!(f, "; {h}")?;
            }
        }
        Ok(())
    }
}

impl std::error::Error for Diagnostics {}

/// One diagnostic with its file and source, renderable by miette with a source snippet.
#[derive(Debug)]
pub struct Report {
    file: String,
    source: Arc<str>,
    diag: Diagnostic,
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(s) = self.diag.span {
            write!(f, ":{}:{}", s.line, s.col)?;
        }
        write!(
            f,
            ": error[{}]: {}",
            self.diag.kind.code(),
            self.diag.message
        )
    }
}

impl std::error::Error for Report {}

impl miette::Diagnostic for Report {
    fn help<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        self.diag
            .help
            .as_ref()
            .map(|h| Box::new(h.clone()) as Box<dyn fmt::Display>)
    }

    fn source_code(&self) -> Option<&dyn miette::SourceCode> {
        self.diag
            .span
            .map(|_| &self.source as &dyn miette::SourceCode)
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = miette::LabeledSpan> + '_>> {
        let s = self.diag.span?;
        let len = s
            .len
            .max(1)
            .min(self.source.len().saturating_sub(s.offset).max(1));
        Some(Box::new(std::iter::once(miette::LabeledSpan::new(
            Some("here".into()),
            s.offset,
            len,
        ))))
    }
}

/// Closest candidate by edit distance, for "did you mean" hints. Ties go to the
/// alphabetically first candidate, so the hint does not depend on the candidates' order (some
/// come from hash maps).
pub fn suggest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<String> {
    let mut best: Option<(usize, &str)> = None;
    for c in candidates {
        let prefix = !c.is_empty() && (word.starts_with(c) || c.starts_with(word));
        let d = if prefix { 1 } else { levenshtein(word, c) };
        if d <= (word.len().max(3) / 3).max(2) && best.is_none_or(|(bd, bc)| (d, c) < (bd, bc)) {
            best = Some((d, c));
        }
    }
    best.map(|(_, c)| format!("did you mean `{c}`?"))
}

fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != *cb))
                .min(prev[j + 1] + 1)
                .min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggestions() {
        assert_eq!(
            suggest("tonemapp", ["tonemap", "exposure"]).as_deref(),
            Some("did you mean `tonemap`?")
        );
        assert_eq!(suggest("zzzzzz", ["tonemap", "exposure"]), None);
    }

    #[test]
    fn a_tie_is_broken_by_name_not_by_order() {
        // "blub" is one edit from both.
        let a = suggest("blub", ["blur", "club"]);
        let b = suggest("blub", ["club", "blur"]);
        assert_eq!(a.as_deref(), Some("did you mean `blur`?"));
        assert_eq!(a, b);
    }
}
