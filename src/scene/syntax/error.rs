//! Scene and REPL errors: what went wrong, where (a byte span in the source), what was
//! expected, and a hint where one is known. Rendered by miette with the source line and a
//! caret under the span.

use std::fmt;
use std::sync::Arc;

use miette::{Diagnostic, GraphicalReportHandler, GraphicalTheme, LabeledSpan, NamedSource, SourceCode};

/// A byte range in the scene text.
pub type Span = (usize, usize);

/// What kind of mistake an error reports (tests and the REPL branch on it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorKind {
    /// The statement's shape is wrong (a missing `=`, an unbalanced parenthesis).
    Syntax,
    /// The first word names no statement, or `help`'s topic no help topic.
    UnknownStatement,
    /// A symbol that is neither a coordinate, a parameter, a definition nor `t`.
    UndefinedSymbol,
    /// A parameter or initial value that a numeric step needs has no value.
    MissingValue,
    /// An integrator name that does not exist.
    UnknownMethod,
    /// A time span that ends before it starts, or a bad step or tolerance.
    BadNumber,
    /// Something the statement needs has not been declared or defined (`el` with no `L`).
    Undeclared,
    /// A name declared twice in conflicting ways.
    Redeclared,
    /// A derivation failed (a singular Hessian, a non-separable Hamiltonian for a splitting
    /// method).
    Derivation,
    /// The integration stopped with an error.
    Numeric,
    /// A library stage this statement needs has not been built yet.
    NotAvailable,
    /// An output file could not be written, or an input file read.
    Io,
    /// The scene file is not UTF-8.
    Encoding,
    /// The scene file is larger than the limit.
    TooLarge,
    /// Ctrl-C stopped the statement (see [`crate::cancel`]); nothing it was computing is kept.
    Interrupted,
}

/// An error in a scene or a REPL line.
#[derive(Clone)]
pub struct SceneError {
    /// What kind of mistake.
    pub kind: ErrorKind,
    /// One sentence: what went wrong.
    pub message: String,
    /// Where, as a byte range of the source.
    pub span: Option<Span>,
    /// The text under the caret: usually what was expected there.
    pub label: Option<String>,
    /// How to fix it, when known.
    pub hint: Option<String>,
    source: Option<Arc<NamedSource<String>>>,
}

impl SceneError {
    /// An error of `kind` with no location yet.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> SceneError {
        SceneError { kind, message: message.into(), span: None, label: None, hint: None, source: None }
    }

    /// Places the error at `span`.
    pub fn at(mut self, span: Span) -> SceneError {
        self.span = Some(span);
        self
    }

    /// The label under the caret.
    pub fn label(mut self, label: impl Into<String>) -> SceneError {
        self.label = Some(label.into());
        self
    }

    /// A suggestion.
    pub fn hint(mut self, hint: impl Into<String>) -> SceneError {
        self.hint = Some(hint.into());
        self
    }

    /// Attaches the source text the span refers to (done once per scene or REPL line).
    pub fn with_source(mut self, source: &Arc<NamedSource<String>>) -> SceneError {
        if self.source.is_none() {
            self.source = Some(source.clone());
        }
        self
    }

    /// Whether a source is attached.
    pub fn has_source(&self) -> bool {
        self.source.is_some()
    }

    /// The full diagnostic: message, source line, caret, label and hint. `color` selects
    /// the coloured theme (for terminals); tests use the plain one.
    pub fn render(&self, color: bool) -> String {
        let theme = if color { GraphicalTheme::unicode() } else { GraphicalTheme::unicode_nocolor() };
        let handler = GraphicalReportHandler::new_themed(theme).with_width(100);
        let safe = self.terminal_safe();
        let mut out = String::new();
        if handler.render_report(&mut out, &safe).is_err() {
            out = safe.to_string();
        }
        out
    }

    /// This error with the control characters of its texts and source escaped
    /// ([`crate::print::escape_controls`]) and its span moved to match: a scene or REPL line
    /// holding `\x1b[2J` is shown, not executed by the terminal.
    fn terminal_safe(&self) -> SceneError {
        use crate::print::{escape_controls, escape_controls_at};
        let mut span = self.span;
        let source = self.source.as_ref().map(|src| {
            let text = src.inner();
            if !text.chars().any(char::is_control) || escape_controls(text) == *text {
                return src.clone();
            }
            let mut at = [span.map_or(0, |s| s.0), span.map_or(0, |s| s.1)];
            let safe = escape_controls_at(text, &mut at);
            span = span.map(|_| (at[0], at[1]));
            Arc::new(NamedSource::new(src.name(), safe))
        });
        SceneError {
            kind: self.kind,
            message: escape_controls(&self.message),
            span,
            label: self.label.as_deref().map(escape_controls),
            hint: self.hint.as_deref().map(escape_controls),
            source,
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl fmt::Debug for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SceneError")
            .field("kind", &self.kind)
            .field("message", &self.message)
            .field("span", &self.span)
            .field("label", &self.label)
            .field("hint", &self.hint)
            .finish()
    }
}

impl std::error::Error for SceneError {}

impl Diagnostic for SceneError {
    fn code<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        let code = match self.kind {
            ErrorKind::Syntax => "scene::syntax",
            ErrorKind::UnknownStatement => "scene::unknown_statement",
            ErrorKind::UndefinedSymbol => "scene::undefined_symbol",
            ErrorKind::MissingValue => "scene::missing_value",
            ErrorKind::UnknownMethod => "scene::unknown_method",
            ErrorKind::BadNumber => "scene::bad_number",
            ErrorKind::Undeclared => "scene::undeclared",
            ErrorKind::Redeclared => "scene::redeclared",
            ErrorKind::Derivation => "scene::derivation",
            ErrorKind::Numeric => "scene::numeric",
            ErrorKind::NotAvailable => "scene::not_available",
            ErrorKind::Io => "scene::io",
            ErrorKind::Encoding => "scene::encoding",
            ErrorKind::TooLarge => "scene::too_large",
            ErrorKind::Interrupted => "scene::interrupted",
        };
        Some(Box::new(code))
    }

    fn help<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        self.hint.as_ref().map(|h| Box::new(h) as Box<dyn fmt::Display>)
    }

    fn source_code(&self) -> Option<&dyn SourceCode> {
        match (&self.source, self.span) {
            (Some(s), Some(_)) => Some(&**s as &dyn SourceCode),
            _ => None,
        }
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = LabeledSpan> + '_>> {
        let (start, end) = self.span?;
        self.source.as_ref()?;
        let label = LabeledSpan::new(self.label.clone(), start, end.saturating_sub(start).max(1));
        Some(Box::new(std::iter::once(label)))
    }
}

pub use crate::suggest::{did_you_mean, edit_distance};
