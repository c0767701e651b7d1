//! `energy at q = …, q' = …`: the energy function `h = Σ q' ∂L/∂q' − L` (or `H`) evaluated at
//! one state, with the scene's parameter values. It reads the same `h` as the `energy`
//! statement prints (the session's `Energy` derivation), so the number and the formula never
//! disagree; a state variable `h` needs and was not given is an error naming it, never a
//! silent zero. The value is printed in full (the shortest text that reads back as the same
//! `f64`), not to the six decimals of messages: it is a result, compared with others.
//!
//! This file is the whole statement: its type, its reader, its handler. Its grammar rule is
//! `energy_at` in `grammar/scene.pest` and its row is in `scene/registry.rs`.

use std::collections::HashMap;

use crate::cache::Value;
use crate::expr::Symbol;
use crate::scene::state::{At, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::{DerivKind, Src};
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `energy at θ = 1, θ' = 0`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct EnergyAt {
    /// The state: coordinates with their velocities (`θ'`) or momenta (`p_θ`).
    pub state: Vec<(Src, Src)>,
    /// The words `energy at`.
    pub word: Span,
}

impl EnergyAt {
    /// Reads the rule `energy_at`: its `init` pairs, in order.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<EnergyAt, SceneError> {
        let span = r.span(&p);
        let (mut state, mut word) = (Vec::new(), span);
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::kw_at => word = (span.0, r.span(&q).1),
                Rule::init => {
                    let mut it = q.into_inner();
                    if let (Some(s), Some(v)) = (it.next(), it.next()) {
                        state.push((r.src(&s), r.src(&v)));
                    }
                }
                _ => {}
            }
        }
        Ok(EnergyAt { state, word })
    }
}

impl Stmt for EnergyAt {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        if s.coords.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared")
                .at(self.word)
                .hint("declare them first, for example `coordinates θ`"));
        }
        let mut given: HashMap<String, f64> = HashMap::new();
        for (sym, val) in &self.state {
            let key = s.state_key(sym)?;
            let v = s.resolved(at, val)?;
            let x = s.number(&v, val.span)?;
            if given.insert(key.clone(), x).is_some() {
                return Err(SceneError::new(ErrorKind::Syntax, format!("`{key}` is given twice")).at(sym.span));
            }
        }
        let h = match s.derive(at, DerivKind::Energy, Vec::new(), self.word)? {
            Value::Expr(h) => h,
            _ => return Err(SceneError::new(ErrorKind::Derivation, "the energy is not an expression").at(self.word)),
        };
        let lookup = |sym: &Symbol| {
            let name = sym.to_string();
            given.get(&name).copied().or_else(|| s.params.get(&name).and_then(|p| p.value))
        };
        match crate::eval::eval_with(&h, &lookup) {
            Ok(e) if e.is_finite() => {
                s.output.push(format!("E = {e}"));
                Ok(())
            }
            Ok(e) => Err(SceneError::new(ErrorKind::BadNumber, format!("the energy at this state is {e}")).at(at.span)),
            Err(crate::eval::EvalError::Unbound(name)) => {
                let (what, hint) = if s.params.contains_key(&name) {
                    ("has no value", format!("give it one: `parameters {name} = …`"))
                } else {
                    ("is not given", format!("add `{name} = …` to the state"))
                };
                Err(SceneError::new(ErrorKind::MissingValue, format!("the energy needs `{name}`, which {what}"))
                    .at(self.word)
                    .hint(hint))
            }
            Err(e) => Err(SceneError::new(ErrorKind::BadNumber, e.to_string()).at(at.span)),
        }
    }
}
