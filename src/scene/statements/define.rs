//! `NAME = …`: a definition, an expression or a derivation (`H = legendre(L)`), recorded lazily:
//! its value is computed only when an output asks for it (`Session::demand_def`), and a later
//! definition of the same name supersedes it for the expressions that follow. In the REPL a
//! definition is also an output, printed at once.
//!
//! This file is the whole statement: its type, its reader, its handler. Its grammar rule is
//! `definition` in `grammar/scene.pest` and its row is in `scene/registry.rs`.

use crate::cache::Value;
use crate::expr::Expr;
use crate::scene::state::{At, DefBody, DefEntry, Mode, Printed, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::{DefValue, Src};
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `name = …`
#[derive(Clone, Debug)]
pub struct Define {
    /// The name defined.
    pub name: Src,
    /// Its value.
    pub value: DefValue,
}

impl Define {
    /// `name = …`: an expression or a derivation.
    pub fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Define, SceneError> {
        let span = r.span(&p);
        let mut it = r.inner(&p).into_iter();
        let name = it.next().map(|n| r.declared(vec![r.src(&n)])).transpose()?.and_then(|mut v| v.pop());
        let value = it.next();
        match (name, value) {
            (Some(name), Some(v)) if v.as_rule() == Rule::derivation => {
                Ok(Define { name, value: DefValue::Derivation(r.deriv_call(v)?) })
            }
            (Some(name), Some(v)) => Ok(Define { name, value: DefValue::Expr(r.src(&v)) }),
            _ => Err(SceneError::new(ErrorKind::Syntax, "malformed definition").at(span)),
        }
    }
}

impl Stmt for Define {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.define(at, &self.name, &self.value)
    }
}

impl Session {
    pub(in crate::scene) fn define(&mut self, at: At, name: &Src, value: &DefValue) -> Result<(), SceneError> {
        let n = name.text.as_str();
        if let Some(what) = self.name_in_use(n).filter(|w| *w != "a definition") {
            return Err(SceneError::new(ErrorKind::Redeclared, format!("`{n}` is already {what}"))
                .at(name.span)
                .label("cannot be redefined")
                .hint("choose another name for the definition"));
        }
        if n == "t" {
            return Err(SceneError::new(ErrorKind::Redeclared, "`t` is time and cannot be defined").at(name.span));
        }
        let body = match value {
            DefValue::Expr(src) => {
                let (raw, refs) = self.expr(src)?;
                DefBody::Expr { raw, refs }
            }
            DefValue::Derivation(call) => {
                let mut args = Vec::new();
                for a in &call.args {
                    args.push(self.expr(a)?);
                }
                DefBody::Deriv { kind: call.kind, args, span: call.span }
            }
        };
        let id = self.defs.len();
        self.defs.push(DefEntry { name: n.to_string(), body, line: at.line, value: None, demanded: false });
        // The value of the definition this one supersedes is a memo: a later definition that
        // captured the old version recomputes it from its body, and a REPL redefining `L` ten
        // thousand times does not keep ten thousand derived values.
        if let Some(old) = self.def_names.insert(n.to_string(), id) {
            self.defs[old].value = None;
            // Nothing can reach an unreferenced superseded definition: in a long-lived REPL
            // its body goes too (a scene keeps it, for the plan's list of skipped work).
            if self.opts.mode == Mode::Repl && !self.referenced.contains(&old) {
                match &mut self.defs[old].body {
                    DefBody::Expr { raw, refs } => {
                        *raw = Expr::zero();
                        *refs = Vec::new();
                    }
                    DefBody::Deriv { args, .. } => *args = Vec::new(),
                }
            }
        }
        if self.opts.mode == Mode::Repl {
            let v = self.demand_def(at, id)?;
            let printed = match v {
                Value::Expr(e) => Printed::Named(n.to_string(), e),
                Value::Lines(l) => Printed::Lines(l),
                _ => return Ok(()),
            };
            self.print_all(vec![printed], None);
        }
        Ok(())
    }
}
