//! The plan: what each piece of work was (built, reused, loaded from the disk cache or
//! skipped, and why), and its text for `lagrangian run --explain`.

use crate::scene::session::{deriv_step, DefBody, Session};

pub use crate::cache::Step;

/// What happened to one piece of work.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Status {
    /// Computed in this run.
    Built,
    /// Found in the session's derivation cache (same symbolic content as earlier work in
    /// this process: an earlier statement, REPL entry or `load`).
    Reused,
    /// Read from the on-disk derivation cache (same symbolic content as an earlier process).
    Loaded,
    /// Not computed, with the reason.
    Skipped(String),
}

/// One line of the plan.
#[derive(Clone, Debug)]
pub struct PlanEntry {
    /// The kind of work.
    pub step: Step,
    /// What exactly (`of L`, `run 1 with gauss6`).
    pub what: String,
    /// The statement's line that caused it (1-based), if any.
    pub line: Option<usize>,
    /// Built, reused, loaded or skipped.
    pub status: Status,
}

impl Session {
    // ----- the plan ------------------------------------------------------------------------

    pub(in crate::scene) fn finish_plan(&mut self) {
        // Lazy definitions and simulations nothing asked for.
        for d in &self.defs {
            if let (DefBody::Deriv { kind, .. }, false) = (&d.body, d.demanded) {
                self.plan.push(PlanEntry {
                    step: deriv_step(*kind),
                    what: format!("`{}` ({})", d.name, kind.keyword()),
                    line: Some(d.line),
                    status: Status::Skipped(format!("no output uses `{}`", d.name)),
                });
            }
        }
        for r in &self.runs {
            if r.result.is_none() {
                self.plan.push(PlanEntry {
                    step: Step::Integrate,
                    what: format!(
                        "{} ({})",
                        r.name,
                        r.spec.method.as_ref().map_or(crate::simulate::DEFAULT_METHOD.name(), |m| m.text.as_str())
                    ),
                    line: Some(r.line),
                    status: Status::Skipped(format!("no plot or export uses `{}`", r.name)),
                });
            }
        }
        // The standard derivations of the system that nothing needed.
        let has_l = self.def_names.contains_key("L");
        let has_h = self.def_names.contains_key("H") || has_l;
        let mut standard = Vec::new();
        if has_l {
            standard.push(Step::EulerLagrange);
            standard.push(Step::Legendre);
        }
        if has_h {
            standard.push(Step::Hamilton);
            standard.push(Step::Conserved);
            standard.push(Step::Energy);
            standard.push(Step::Bracket);
        }
        for step in standard {
            if !self.plan.iter().any(|e| e.step == step) {
                self.plan.push(PlanEntry {
                    step,
                    what: String::new(),
                    line: None,
                    status: Status::Skipped("no output needs it".to_string()),
                });
            }
        }
    }

    /// The plan as text, for `--explain`.
    pub fn explain(&self) -> String {
        let mut s = String::from("plan:\n");
        for e in &self.plan {
            let status = match &e.status {
                Status::Built => "built  ".to_string(),
                Status::Reused => "reused ".to_string(),
                Status::Loaded => "loaded ".to_string(),
                Status::Skipped(_) => "skipped".to_string(),
            };
            let line = e.line.map_or("        ".to_string(), |l| format!("line {l:<3}"));
            let mut what = e.step.name().to_string();
            if !e.what.is_empty() {
                what.push(' ');
                what.push_str(&e.what);
            }
            let why = match &e.status {
                Status::Skipped(r) => format!(" — {r}"),
                Status::Reused => " — same symbolic input as earlier in this session".to_string(),
                Status::Loaded => " — from the disk cache".to_string(),
                Status::Built => String::new(),
            };
            s.push_str(&format!("  {status} {line} {what}{why}\n"));
        }
        let count = |f: &dyn Fn(&Status) -> bool| self.plan.iter().filter(|e| f(&e.status)).count();
        s.push_str(&format!(
            "{} built, {} reused, {} skipped",
            count(&|s| *s == Status::Built),
            count(&|s| *s == Status::Reused),
            count(&|s| matches!(s, Status::Skipped(_)))
        ));
        let loaded = count(&|s| *s == Status::Loaded);
        if loaded > 0 {
            s.push_str(&format!(", {loaded} loaded from the disk cache"));
        }
        s.push('\n');
        s
    }
}
