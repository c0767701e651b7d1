//! What prints a result: `print ITEM, …`, a bare derivation (`el`, `pb f, g`, `legendre`),
//! and `latex` / `unicode` / `plain` (reprint the last result) or `format NAME` (set the
//! default). Derivations are demanded here, so printing one builds it (and only it); what
//! was printed last is kept for a reprint in another format. `export` prints items the same
//! way (`Session::printed_item`).
//!
//! This file is the whole family: the types, their readers and their handlers. The grammar
//! rules are `print`, `derive_stmt` and `format_stmt` in `grammar/scene.pest`; the rows are
//! in `scene/registry.rs`.

use crate::cache::Value;
use crate::expr::Expr;
use crate::print::{render, Format};
use crate::scene::state::{At, Printed, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::{DerivCall, DerivKind, Item};
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `print …`
#[derive(Clone, Debug)]
pub struct Print {
    /// What to print.
    pub items: Vec<Item>,
    /// `as latex`.
    pub format: Option<Format>,
}

/// `el`, `legendre`, `pb f, g`: derive and print.
#[derive(Clone, Debug)]
pub struct Derive {
    /// The derivation.
    pub call: DerivCall,
    /// `as latex`.
    pub format: Option<Format>,
}

/// `latex` (reprint the last result) or `format unicode` (set the default).
#[derive(Clone, Debug)]
pub struct FormatStmt {
    /// The format.
    pub format: Format,
    /// `format …` sets the default; a bare format name reprints.
    pub set_default: bool,
}

impl Print {
    /// `print ITEM, … [as FORMAT]`.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Print, SceneError> {
        let mut items = Vec::new();
        let mut format = None;
        for q in r.inner(&p) {
            match q.as_rule() {
                Rule::print_item => items.push(r.item(q)?),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        Ok(Print { items, format })
    }
}

impl Derive {
    /// `el`, `pb f, g`, … with an optional format.
    pub fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Derive, SceneError> {
        let span = r.span(&p);
        let mut format = None;
        let mut kind = None;
        let mut args = Vec::new();
        for q in r.inner(&p) {
            match q.as_rule() {
                Rule::deriv_kw => kind = DerivKind::from_keyword(q.as_str()),
                Rule::sexpr => args.push(r.src(&q)),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        let kind = kind.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected a derivation").at(span))?;
        Ok(Derive { call: DerivCall { kind, args, span }, format })
    }
}

impl FormatStmt {
    /// `format NAME` (sets the default) or a bare format name (reprints).
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> FormatStmt {
        let set_default = p.as_str().trim_start().starts_with("format");
        let f = r.inner(&p).iter().find(|q| q.as_rule() == Rule::format_name).map(Reader::format_name);
        FormatStmt { format: f.unwrap_or(Format::Unicode), set_default }
    }
}

impl Stmt for Print {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        let mut printed = Vec::new();
        for item in &self.items {
            printed.push(s.printed_item(at, item)?);
        }
        s.print_all(printed, self.format);
        Ok(())
    }
}

impl Stmt for Derive {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        let call = &self.call;
        let v = s.derive_call(at, call)?;
        let printed = match v {
            Value::Expr(e) => {
                let label = match call.kind {
                    DerivKind::Legendre => "H".to_string(),
                    DerivKind::Energy => "E".to_string(),
                    _ => format!("{{{}}}", call.args.iter().map(|a| a.text.trim()).collect::<Vec<_>>().join(", ")),
                };
                Printed::Named(label, e)
            }
            Value::Lines(l) => Printed::Lines(l),
            _ => return Ok(()),
        };
        s.print_all(vec![printed], self.format);
        Ok(())
    }
}

impl Stmt for FormatStmt {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        if self.set_default {
            s.opts.format = self.format;
            s.output.push(format!("output format: {}", format_name(self.format)));
        } else if s.last_printed.is_empty() {
            s.output.push("nothing to reprint yet".to_string());
        } else {
            let last = s.last_printed.clone();
            s.print_all(last, Some(self.format));
        }
        Ok(())
    }
}

impl Session {
    pub(in crate::scene) fn printed_item(&mut self, at: At, item: &Item) -> Result<Printed, SceneError> {
        match item {
            Item::Derivation(call) => Ok(match self.derive_call(at, call)? {
                Value::Expr(e) => Printed::Named(call.kind.keyword().to_string(), e),
                Value::Lines(l) => Printed::Lines(l),
                _ => Printed::Lines(vec![]),
            }),
            Item::Expr(src) => {
                let (raw, refs) = self.expr(src)?;
                if let (Some(s), [(_, id)]) = (raw.as_sym(), &refs[..]) {
                    let name = s.name().to_string();
                    return Ok(match self.demand_def(at, *id)? {
                        Value::Expr(e) => Printed::Named(name, e),
                        Value::Lines(l) => Printed::Lines(l),
                        _ => Printed::Lines(vec![]),
                    });
                }
                Ok(Printed::Value(printable(&self.resolve(at, &raw, &refs)?)))
            }
        }
    }

    pub(in crate::scene) fn print_all(&mut self, printed: Vec<Printed>, format: Option<Format>) {
        let f = format.unwrap_or(self.opts.format);
        for p in &printed {
            match p {
                Printed::Named(n, e) => {
                    let name = match f {
                        // A bracket's label `{f, g}` is not a name: its braces are escaped.
                        Format::Latex if n.starts_with('{') => n.replace('{', "\\{").replace('}', "\\}"),
                        Format::Latex => render(&Expr::var(n), f),
                        _ => n.clone(),
                    };
                    self.output.push(format!("{name} = {}", render(e, f)));
                }
                Printed::Value(e) => self.output.push(render(e, f)),
                Printed::Lines(lines) => {
                    for l in lines {
                        self.output.push(crate::report::render_line(l, f));
                    }
                }
            }
        }
        self.last_printed = printed;
    }
}

/// An expression as `print` shows it: `0` when it is identically zero (a symbolic proof by
/// the canonical normal form, as a Jacobi-identity check expects), otherwise with
/// inverse-function compositions (`exp(log x)`, `sinh(asinh x)`, …) reduced under their domain
/// conditions.
fn printable(e: &Expr) -> Expr {
    if e.is_zero() {
        return e.clone();
    }
    if crate::canonical::decide_zero(e) == crate::canonical::ZeroCheck::Proven {
        return Expr::zero();
    }
    // The command line's `simplify` (identities such as sin² + cos² = 1 that tidying alone does
    // not see), kept when it is shorter: tidying orders the terms the way the notes print them.
    let tidied = crate::canonical::reduce::tidy(e);
    let simplified = crate::simplify::simplify(e);
    if simplified.op_count() < tidied.op_count() {
        crate::canonical::reduce::tidy(&simplified)
    } else {
        tidied
    }
}

fn format_name(f: Format) -> &'static str {
    match f {
        Format::Plain => "plain",
        Format::Unicode => "unicode",
        Format::Latex => "latex",
    }
}
