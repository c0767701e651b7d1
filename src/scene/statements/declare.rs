//! `coordinates`, `parameters` and `functions`: the declarations that say what the names of
//! later expressions are. Each is refused where it would change what an earlier name means
//! (a name declared as something else, `t`, a coordinate declared twice); a parameter
//! declared again keeps its value and its `positive` unless the new declaration gives them.
//!
//! This file is the whole family: the types, their readers and their handlers. The grammar
//! rules are `coordinates`, `parameters` and `functions` in `grammar/scene.pest`; the rows are
//! in `scene/registry.rs`.

use std::collections::BTreeSet;

use crate::expr::Symbol;
use crate::scene::state::{At, Param, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `coordinates θ, φ`
#[derive(Clone, Debug)]
pub struct Coordinates(pub Vec<Src>);

/// `parameters m = 1, l positive`
#[derive(Clone, Debug)]
pub struct Parameters {
    /// Names and optional values.
    pub params: Vec<(Src, Option<Src>)>,
    /// `positive` at the end.
    pub positive: bool,
}

/// `functions V`
#[derive(Clone, Debug)]
pub struct Functions(pub Vec<Src>);

impl Coordinates {
    /// `coordinates θ, φ` or a family `coordinates x[0..4]`.
    pub fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Coordinates, SceneError> {
        let mut names = Vec::new();
        for q in r.inner(&p) {
            names.extend(r.family_or_name(&q)?);
        }
        Ok(Coordinates(r.declared(names)?))
    }
}

impl Parameters {
    /// `parameters …`: the names, their values if given, and `positive`.
    pub fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Parameters, SceneError> {
        let mut params = Vec::new();
        let mut positive = false;
        for q in r.inner(&p) {
            match q.as_rule() {
                Rule::param => {
                    let pspan = r.span(&q);
                    let mut it = q.into_inner();
                    let Some(first) = it.next() else { continue };
                    let names = r.declared(r.family_or_name(&first)?)?;
                    let values: Vec<Src> = it.map(|v| r.src(&v)).collect();
                    if values.is_empty() {
                        params.extend(names.into_iter().map(|n| (n, None)));
                    } else if values.len() == names.len() {
                        params.extend(names.into_iter().zip(values.into_iter().map(Some)));
                    } else {
                        return Err(SceneError::new(
                            ErrorKind::Syntax,
                            format!("`{}` has {} members but {} values", first.as_str(), names.len(), values.len()),
                        )
                        .at(pspan)
                        .hint("give one value per member, in order, or none; a parameter declared without a value goes before the family or gets `= value`"));
                    }
                }
                Rule::assumption => positive = true,
                _ => {}
            }
        }
        Ok(Parameters { params, positive })
    }
}

impl Functions {
    /// `functions V`.
    pub fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Functions, SceneError> {
        Ok(Functions(r.declared(r.inner(&p).into_iter().flat_map(|q| r.names(q)).collect())?))
    }
}

impl Stmt for Coordinates {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        s.declare_coordinates(&self.0)
    }
}

impl Stmt for Parameters {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        s.declare_parameters(&self.params, self.positive)
    }
}

impl Stmt for Functions {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        s.declare_functions(&self.0)
    }
}

impl Session {
    fn declare_coordinates(&mut self, names: &[Src]) -> Result<(), SceneError> {
        let mut seen = BTreeSet::new();
        for n in names {
            let name = n.text.as_str();
            if !seen.insert(name) || self.coords.iter().any(|c| c.name() == name) {
                return Err(SceneError::new(ErrorKind::Redeclared, format!("coordinate `{name}` is declared twice"))
                    .at(n.span)
                    .label("declared again here"));
            }
            if let Some(what) = self.name_in_use(name) {
                return Err(SceneError::new(ErrorKind::Redeclared, format!("`{name}` is already {what}"))
                    .at(n.span)
                    .label("already declared"));
            }
            if name == "t" {
                return Err(SceneError::new(ErrorKind::Redeclared, "`t` is time and cannot be a coordinate")
                    .at(n.span)
                    .hint("choose another name"));
            }
        }
        self.coords.extend(names.iter().map(|n| Symbol::new(&n.text)));
        Ok(())
    }

    fn declare_parameters(&mut self, params: &[(Src, Option<Src>)], positive: bool) -> Result<(), SceneError> {
        for (n, v) in params {
            let name = n.text.as_str();
            if let Some(what) = self.name_in_use(name).filter(|w| *w != "a parameter") {
                return Err(SceneError::new(ErrorKind::Redeclared, format!("`{name}` is already {what}"))
                    .at(n.span)
                    .label("already declared"));
            }
            let value = match v {
                Some(src) => {
                    let (e, refs) = self.expr(src)?;
                    if !refs.is_empty() {
                        return Err(SceneError::new(ErrorKind::Syntax, "a parameter value must be a number")
                            .at(src.span)
                            .hint("use numbers and earlier parameters only"));
                    }
                    Some(self.number(&e, src.span)?)
                }
                None => self.params.get(name).and_then(|p| p.value),
            };
            let was_positive = self.params.get(name).is_some_and(|p| p.positive);
            if positive {
                if let Some(x) = value.filter(|x| *x <= 0.0) {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("`{name}` is declared positive but its value is {x}"),
                    )
                    .at(n.span)
                    .hint("drop `positive` or give a positive value"));
                }
            }
            self.params.insert(name.to_string(), Param { value, positive: positive || was_positive });
        }
        Ok(())
    }

    fn declare_functions(&mut self, names: &[Src]) -> Result<(), SceneError> {
        for n in names {
            if let Some(what) = self.name_in_use(&n.text).filter(|w| *w != "a function") {
                return Err(SceneError::new(ErrorKind::Redeclared, format!("`{}` is already {what}", n.text))
                    .at(n.span)
                    .label("already declared"));
            }
            self.functions.insert(n.text.clone());
        }
        Ok(())
    }
}
