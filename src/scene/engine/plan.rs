//! The plan: what each piece of work was (built, reused, loaded from the disk cache or
//! skipped, and why), and its text for `lagrangian run --explain`.

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

/// The plan as text, for `--explain`.
pub fn explain(plan: &[PlanEntry]) -> String {
    let mut s = String::from("plan:\n");
    for e in plan {
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
    let count = |f: &dyn Fn(&Status) -> bool| plan.iter().filter(|e| f(&e.status)).count();
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
