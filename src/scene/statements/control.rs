//! The statements about the session rather than the mechanics: `load FILE` (run another
//! scene's statements here), `help [TOPIC]`, `history` (the REPL's, which keeps it) and
//! `allow nonfinite` (later exports keep inf and NaN).
//!
//! `help` answers from the registry's rows, which sit above every statement file: the
//! registry hands its answer to the reader (`Help::read`), so this file imports no registry
//! and the scene's imports stay a tree.
//!
//! This file is the whole family: the types, their readers and their handlers. The grammar
//! rules are `load`, `help`, `history` and `allow` in `grammar/scene.pest`; the rows are in
//! `scene/registry.rs`.

use std::path::PathBuf;

use crate::scene::state::{At, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{Pair, Reader, Rule};
use crate::scene::syntax::source::read_scene;

/// The deepest chain of `load` statements.
const MAX_LOAD_DEPTH: usize = 8;

/// `load FILE`
#[derive(Clone, Debug)]
pub struct Load(pub Src);

/// `help`, `help TOPIC …`: the text it prints, answered when read.
#[derive(Clone, Debug)]
pub struct Help(pub String);

/// `history`
#[derive(Clone, Debug)]
pub struct History;

/// `allow nonfinite`: later exports keep inf and NaN.
#[derive(Clone, Debug)]
pub struct AllowNonfinite;

impl Load {
    /// `load FILE`.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Load, SceneError> {
        let span = r.span(&p);
        let path = r.inner(&p).into_iter().next().map(|q| r.path(q));
        Ok(Load(path.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected a file").at(span))?))
    }
}

/// The registry's help: the text for a topic (its words joined by single blanks) or, with
/// none, the overview; an unknown topic is `Err` with the nearest topic, if one is near.
pub(in crate::scene) type Answer = fn(Option<&str>) -> Result<String, Option<&'static str>>;

impl Help {
    /// `help [WORD …]`, answered by `answer`. An unknown topic is refused here, at the
    /// topic's words, as an unknown statement is.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>, answer: Answer) -> Result<Help, SceneError> {
        let words = r.inner(&p);
        let topic = (!words.is_empty()).then(|| words.iter().map(|q| q.as_str()).collect::<Vec<_>>().join(" "));
        answer(topic.as_deref()).map(Help).map_err(|near| {
            let span = match (words.first(), words.last()) {
                (Some(first), Some(last)) => (r.span(first).0, r.span(last).1),
                _ => r.span(&p),
            };
            SceneError::new(ErrorKind::UnknownStatement, format!("no help for `{}`", topic.unwrap_or_default()))
                .at(span)
                .label("not a help topic")
                .hint(match near {
                    Some(t) => format!("did you mean `help {t}`?"),
                    None => "`help` lists every topic".to_string(),
                })
        })
    }
}

impl Stmt for Load {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        s.load(&self.0)
    }
}

impl Stmt for Help {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        s.output.push(self.0.clone());
        Ok(())
    }
}

impl Stmt for History {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        s.output.push("(history is kept by the REPL)".to_string());
        Ok(())
    }
}

impl Stmt for AllowNonfinite {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        s.allow_nonfinite = true;
        Ok(())
    }
}

impl Session {
    fn load(&mut self, path: &Src) -> Result<(), SceneError> {
        if self.load_depth >= MAX_LOAD_DEPTH {
            return Err(SceneError::new(ErrorKind::Io, format!("`load` nested deeper than {MAX_LOAD_DEPTH} files"))
                .at(path.span)
                .hint("a scene probably loads itself"));
        }
        let p = PathBuf::from(&path.text);
        let full = if p.is_absolute() { p } else { self.opts.base_dir.join(p) };
        let text = read_scene(&full).map_err(|e| {
            if e.has_source() {
                e
            } else {
                let span = e.span.unwrap_or(path.span);
                let e = if e.span.is_none() { e.at(span) } else { e };
                e.with_source(&self.source)
            }
        })?;
        let name = full.display().to_string();
        self.load_depth += 1;
        let r = self.run_text(&name, &text);
        self.load_depth -= 1;
        r?;
        self.output.push(format!("loaded {name}"));
        Ok(())
    }
}
