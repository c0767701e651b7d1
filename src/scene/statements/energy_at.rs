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

#[cfg(test)]
mod tests {
    use crate::scene::{ErrorKind, Mode, Options, SceneError, Session};

    fn run(scene: &str) -> Result<Vec<String>, SceneError> {
        let mut s = Session::new(Options::new(Mode::Scene));
        s.run_scene("test", scene)?;
        Ok(s.take_output())
    }

    /// The number printed by the scene's last line `E = …`.
    fn energy(scene: &str) -> f64 {
        let out = run(scene).unwrap_or_else(|e| panic!("{e:?}"));
        let last = out.last().expect("a printed line");
        last.strip_prefix("E = ").unwrap_or_else(|| panic!("{last}")).parse().unwrap()
    }

    /// The pendulum's h = ½ m l² θ'² − m g l cos θ, evaluated here by hand in f64.
    #[test]
    fn the_pendulum_energy_at_a_state_is_its_closed_form() {
        let (m, l, g, th, w) = (2.0_f64, 1.5_f64, 9.81_f64, 0.7_f64, 1.3_f64);
        let expected = 0.5 * m * l * l * w * w - m * g * l * th.cos();
        let got = energy(
            "coordinates θ\nparameters m = 2, l = 1.5, g = 9.81\nL = 1/2 m l^2 θ'^2 + m g l cos(θ)\nenergy at θ = 0.7, θ' = 1.3",
        );
        assert!((got - expected).abs() <= 1e-14 * expected.abs(), "{got} vs {expected}");
    }

    /// The same oscillator through L with a velocity and through H with the momentum p = m x'
    /// gives the same number, and it is the exact ½ m x'² + ½ k x² = 2.625.
    #[test]
    fn velocities_through_l_and_momenta_through_h_agree() {
        let through_l =
            energy("coordinates x\nparameters m = 2, k = 3\nL = 1/2 m x'^2 - 1/2 k x^2\nenergy at x = 0.5, x' = 1.5");
        let through_h =
            energy("coordinates x\nparameters m = 2, k = 3\nH = p_x^2/(2 m) + 1/2 k x^2\nenergy at x = 0.5, p_x = 3");
        assert_eq!(through_l, 2.625);
        assert_eq!(through_h, 2.625);
    }

    /// A state variable the energy needs and was not given is an error naming it, at the
    /// statement's words; so is an unknown name in the state, at that name.
    #[test]
    fn missing_and_foreign_state_values_are_refused_with_their_place() {
        let scene =
            "coordinates θ\nparameters m = 1, l = 1, g = 9.81\nL = 1/2 m l^2 θ'^2 + m g l cos(θ)\nenergy at θ = 1";
        let err = run(scene).unwrap_err();
        assert_eq!(err.kind, ErrorKind::MissingValue, "{err:?}");
        assert!(err.message.contains("`θ'`"), "{err:?}");
        let at = scene.find("energy at").unwrap();
        assert_eq!(err.span, Some((at, at + "energy at".len())));

        let scene = "coordinates x\nparameters m = 1\nL = 1/2 m x'^2\nenergy at x = 1, y = 2";
        let err = run(scene).unwrap_err();
        assert_eq!(err.kind, ErrorKind::UndefinedSymbol, "{err:?}");
        let y = scene.find("y = 2").unwrap();
        assert_eq!(err.span, Some((y, y + 1)));

        let scene = "coordinates x\nparameters m, k = 1\nL = 1/2 m x'^2 - 1/2 k x^2\nenergy at x = 1, x' = 2";
        let err = run(scene).unwrap_err();
        assert_eq!(err.kind, ErrorKind::MissingValue, "{err:?}");
        assert!(err.hint.as_deref().is_some_and(|h| h.contains("parameters m = ")), "{err:?}");
    }
}
