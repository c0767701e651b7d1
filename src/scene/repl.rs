//! The interactive front end: rustyline on a terminal (history, tab completion of
//! statements, symbols and methods, multi-line input while a statement is unfinished), and
//! a plain line reader when standard input is not a terminal (pipes, tests), with the same
//! statements, the same history file and the same output.
//!
//! Everything the REPL shows — results and diagnostics — goes to standard output, in
//! order: it is one transcript. The REPL survives every error.

use std::cell::RefCell;
use std::io::{BufRead, IsTerminal, Write};
use std::path::PathBuf;
use std::rc::Rc;

use rustyline::completion::Completer;
use rustyline::highlight::Highlighter;
use rustyline::hint::Hinter;
use rustyline::history::{FileHistory, History};
use rustyline::validate::{ValidationContext, ValidationResult, Validator};
use rustyline::{Context, Editor, Helper};

use super::help::TOPICS;
use super::registry::statement_words;
use super::state::Session;
use super::state::{Mode, Options};
use super::syntax::parser::{is_incomplete, Unfinished};
use crate::cache::Cache;
use crate::simulate::METHODS;

/// The prompt.
pub const PROMPT: &str = "lagrangian> ";
const CONTINUATION: &str = "       ...> ";

/// Where the history lives: `$LAGRANGIAN_HISTORY`, else the user's data directory
/// (`$XDG_DATA_HOME/lagrangian/history`, `~/.local/share/lagrangian/history`).
pub fn history_path() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("LAGRANGIAN_HISTORY") {
        return Some(PathBuf::from(p));
    }
    let data = match std::env::var_os("XDG_DATA_HOME") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => PathBuf::from(std::env::var_os("HOME")?).join(".local").join("share"),
    };
    Some(data.join("lagrangian").join("history"))
}

/// Completion and multi-line validation for rustyline.
struct ReplHelper {
    names: Rc<RefCell<Vec<String>>>,
}

/// The word before the cursor and where it starts.
fn word_at(line: &str, pos: usize) -> (usize, &str) {
    let before = &line[..pos];
    let start = before
        .char_indices()
        .rev()
        .take_while(|(_, c)| c.is_alphanumeric() || *c == '_' || *c == '\'')
        .last()
        .map_or(pos, |(i, _)| i);
    (start, &line[start..pos])
}

/// Completions of the word ending at `pos`: statements at the start of a line, methods
/// after `with`, help topics after `help` (word by word), otherwise known symbols and derivations.
pub fn complete(line: &str, pos: usize, names: &[String]) -> (usize, Vec<String>) {
    let (start, word) = word_at(line, pos);
    let before: Vec<&str> = line[..start].split_whitespace().collect();
    let pool: Vec<String> = match before.last() {
        None => statement_words().map(str::to_string).chain(names.iter().cloned()).collect(),
        Some(&"with") => METHODS
            .iter()
            .flat_map(|m| std::iter::once(m.name).chain(m.aliases.iter().copied()))
            .map(str::to_string)
            .collect(),
        Some(&"help") => TOPICS.iter().map(|t| t.word.split(' ').next().unwrap_or(t.word).to_string()).collect(),
        // The next word of a topic of several words: `help energy ` → `at`.
        Some(_) if before.len() > 1 && before[0] == "help" => {
            let typed = before[1..].join(" ");
            TOPICS
                .iter()
                .filter_map(|t| t.word.strip_prefix(typed.as_str())?.strip_prefix(' ')?.split(' ').next())
                .map(str::to_string)
                .collect()
        }
        Some(&"as") | Some(&"format") => ["plain", "unicode", "latex"].iter().map(|s| s.to_string()).collect(),
        Some(&"plot") => ["phase", "energy", "path", "poincare", "work_precision"]
            .iter()
            .map(|s| s.to_string())
            .chain(names.iter().cloned())
            .collect(),
        _ => names
            .iter()
            .cloned()
            .chain(
                ["el", "legendre", "hamilton", "conserved", "pb", "energy", "accelerations"]
                    .iter()
                    .map(|s| s.to_string()),
            )
            .collect(),
    };
    let mut out: Vec<String> = pool.into_iter().filter(|c| c.starts_with(word) && c != word).collect();
    out.sort();
    out.dedup();
    (start, out)
}

impl Completer for ReplHelper {
    type Candidate = String;
    fn complete(&self, line: &str, pos: usize, _ctx: &Context<'_>) -> rustyline::Result<(usize, Vec<String>)> {
        Ok(complete(line, pos, &self.names.borrow()))
    }
}

impl Hinter for ReplHelper {
    type Hint = String;
}

impl Highlighter for ReplHelper {}

impl Validator for ReplHelper {
    fn validate(&self, ctx: &mut ValidationContext) -> rustyline::Result<ValidationResult> {
        Ok(if wants_more(ctx.input()) { ValidationResult::Incomplete } else { ValidationResult::Valid(None) })
    }
}

/// Whether the line editor should ask for another line of `input`: the statement is
/// unfinished and the user has not just entered a blank line. A blank line ends an unfinished
/// statement, as in the piped REPL, so one unclosed `(` costs one error at the next Enter
/// instead of an editor that keeps asking for more.
pub fn wants_more(input: &str) -> bool {
    let gave_up = input.contains('\n') && input.rsplit('\n').next().is_some_and(|l| l.trim().is_empty());
    is_incomplete(input) && !gave_up
}

impl Helper for ReplHelper {}

/// How an entry went, for the caller's bookkeeping.
enum Entry {
    Ok,
    Error,
    Quit,
}

struct Repl {
    session: Session,
    history: Vec<String>,
    color: bool,
}

impl Repl {
    fn entry(&mut self, text: &str, out: &mut dyn Write) -> Entry {
        let trimmed = text.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            return Entry::Ok;
        }
        if ["quit", "exit", ":q"].contains(&trimmed) {
            return Entry::Quit;
        }
        if trimmed == "history" {
            for (i, h) in self.history.iter().enumerate() {
                let _ = writeln!(out, "{:>4}  {}", i + 1, crate::print::escape_controls(&h.replace('\n', " ")));
            }
            return Entry::Ok;
        }
        crate::cancel::reset_global();
        let result = self.session.run_line(text);
        crate::cancel::reset_global();
        for line in self.session.take_output() {
            let _ = writeln!(out, "{line}");
        }
        let _ = out.flush();
        for line in self.session.take_warnings() {
            eprintln!("{}", crate::print::escape_controls(&line));
        }
        match result {
            Ok(()) => Entry::Ok,
            Err(e) => {
                let _ = write!(out, "{}", e.render(self.color));
                let _ = writeln!(out);
                Entry::Error
            }
        }
    }
}

/// Runs the REPL until end of input or `quit`, starting from the derivations in `cache` (an
/// on-disk cache makes them outlive the session). Returns the number of entries that failed.
pub fn run(history: Option<PathBuf>, cache: Cache) -> usize {
    let mut opts = Options::new(Mode::Repl);
    opts.progress = super::engine::progress::Draw::from_env();
    opts.stem = "repl".to_string();
    let interactive = std::io::stdin().is_terminal() && std::io::stdout().is_terminal();
    let mut repl = Repl { session: Session::new(opts).with_cache(cache), history: Vec::new(), color: interactive };
    let mut file_history = FileHistory::new();
    if let Some(p) = &history {
        if let Some(dir) = p.parent() {
            let _ = std::fs::create_dir_all(dir);
        }
        if p.exists() {
            let _ = file_history.load(p);
        }
    }
    repl.history = file_history.iter().cloned().collect();
    let mut errors = 0;
    let stdout = std::io::stdout();
    if interactive {
        let names = Rc::new(RefCell::new(Vec::new()));
        let mut editor: Editor<ReplHelper, FileHistory> = match Editor::new() {
            Ok(e) => e,
            Err(e) => {
                eprintln!("error: cannot start the line editor: {e}");
                return 1;
            }
        };
        // Only now: rustyline's `Editor::new` replaces the SIGINT handler with its own for
        // the editor's lifetime (it keeps the previous one to restore on drop), which would
        // leave Ctrl-C during a statement without effect. At the prompt the terminal is in raw
        // mode and Ctrl-C stays a key for rustyline.
        install_ctrlc();
        editor.set_helper(Some(ReplHelper { names: names.clone() }));
        if let Some(p) = &history {
            let _ = editor.load_history(p);
        }
        println!("lagrangian {} — `help` lists the statements, Ctrl-D quits", env!("CARGO_PKG_VERSION"));
        loop {
            match editor.readline(PROMPT) {
                Ok(line) => {
                    let _ = editor.add_history_entry(line.as_str());
                    repl.history.push(line.clone());
                    if let Some(p) = &history {
                        let _ = editor.save_history(p);
                    }
                    let r = repl.entry(&line, &mut stdout.lock());
                    *names.borrow_mut() = repl.session.known_names();
                    match r {
                        Entry::Quit => break,
                        Entry::Error => errors += 1,
                        Entry::Ok => {}
                    }
                }
                Err(rustyline::error::ReadlineError::Interrupted) => continue,
                // Ctrl-D: end the prompt's line, so the shell's prompt starts on its own.
                Err(rustyline::error::ReadlineError::Eof) => {
                    println!();
                    break;
                }
                Err(e) => {
                    eprintln!("error: cannot read the terminal: {e}");
                    errors += 1;
                    break;
                }
            }
        }
        return errors;
    }
    // Not a terminal: read lines, join unfinished statements, echo each entry after the
    // prompt so the transcript reads like a session. An unfinished statement ends at a blank
    // line (as a terminal user would give up on it), so one unclosed `(` costs one error,
    // not the rest of the input; lines and entries are bounded like scene files.
    install_ctrlc();
    let stdin = std::io::stdin();
    let mut input = std::io::BufReader::new(stdin.lock());
    let mut pending = String::new();
    let mut open = Unfinished::default();
    let mut lookahead: Option<String> = None;
    loop {
        let read = match lookahead.take() {
            Some(l) => Ok(Some(l)),
            None => read_line_bounded(&mut input, MAX_LINE_BYTES),
        };
        let line = match read {
            Ok(Some(l)) => l,
            Ok(None) => break,
            Err(e) => {
                let mut out = stdout.lock();
                let _ = writeln!(out, "error: cannot read input: {e}");
                errors += 1;
                if e.kind() == std::io::ErrorKind::InvalidData {
                    continue;
                }
                break;
            }
        };
        let blank = line.trim().is_empty();
        if !pending.is_empty() {
            pending.push('\n');
        }
        pending.push_str(&line);
        open.push_line(&line);
        if open.is_incomplete() && !blank && pending.len() as u64 <= super::syntax::source::MAX_SCENE_BYTES {
            continue;
        }
        // An indented line continues the statement above it, as in a scene file
        // (`simulate …` then `    record when …`). The next line is looked at only when it
        // is already there, so a program that sends one statement and waits for its answer
        // is never kept waiting.
        if !blank && input_ready(&input) {
            if let Ok(Some(next)) = read_line_bounded(&mut input, MAX_LINE_BYTES) {
                let continues = next.starts_with([' ', '\t']) && !next.trim().is_empty();
                lookahead = Some(next);
                if continues && pending.len() as u64 <= super::syntax::source::MAX_SCENE_BYTES {
                    continue;
                }
            }
        }
        open = Unfinished::default();
        let text = std::mem::take(&mut pending);
        let mut out = stdout.lock();
        for (i, l) in text.lines().enumerate() {
            // The echo is the input as read: its control bytes are shown, not executed.
            let l = crate::print::escape_controls(l);
            let _ = writeln!(out, "{}{l}", if i == 0 { PROMPT } else { CONTINUATION });
        }
        if !text.trim().is_empty() {
            let _ = file_history.add(&text);
            repl.history.push(text.clone());
            if let Some(p) = &history {
                let _ = file_history.save(p);
            }
        }
        match repl.entry(&text, &mut out) {
            Entry::Quit => break,
            Entry::Error => errors += 1,
            Entry::Ok => {}
        }
    }
    if !pending.trim().is_empty() {
        let mut out = stdout.lock();
        let _ = writeln!(out, "{PROMPT}{}", crate::print::escape_controls(&pending));
        let _ = repl.entry(&pending, &mut out);
    }
    errors
}

/// Connects Ctrl-C to the process-wide token: while a statement runs it stops the statement
/// (at the integrator's next step, the simplifier's next iteration, the figure's next point)
/// and the REPL returns to the prompt.
fn install_ctrlc() {
    if let Err(e) = crate::cancel::install_ctrlc(crate::cancel::SecondPress::Ignore) {
        eprintln!("warning: {e}");
    }
}

/// Whether the next input line can be read without waiting: bytes already buffered, or the
/// descriptor readable now (data or end of input).
fn input_ready(input: &std::io::BufReader<std::io::StdinLock<'_>>) -> bool {
    if !input.buffer().is_empty() {
        return true;
    }
    #[cfg(unix)]
    {
        let mut fd = libc::pollfd { fd: 0, events: libc::POLLIN, revents: 0 };
        // SAFETY: one valid `pollfd` for standard input, a zero timeout.
        let ready = unsafe { libc::poll(&mut fd, 1, 0) };
        ready > 0
    }
    #[cfg(not(unix))]
    {
        false
    }
}

/// The longest input line the piped REPL reads (a statement longer than this is a scene file).
const MAX_LINE_BYTES: usize = 1 << 20;

/// One line of at most `max` bytes without its terminator; `None` at the end of input. A
/// longer line is skipped to its end and reported (`InvalidData`), so an endless line (from
/// `/dev/zero`) costs `max` bytes of memory, never more.
#[doc(hidden)]
pub fn read_line_bounded(input: &mut impl BufRead, max: usize) -> std::io::Result<Option<String>> {
    let mut buf = Vec::new();
    let mut too_long = false;
    let mut any = false;
    loop {
        let chunk = input.fill_buf()?;
        if chunk.is_empty() {
            break;
        }
        any = true;
        let (take, done) = match chunk.iter().position(|&b| b == b'\n') {
            Some(i) => (i + 1, true),
            None => (chunk.len(), false),
        };
        if !too_long {
            buf.extend_from_slice(&chunk[..take]);
            if buf.len() > max + 1 {
                too_long = true;
                buf = Vec::new();
            }
        }
        input.consume(take);
        if done {
            break;
        }
    }
    if !any {
        return Ok(None);
    }
    if too_long {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("a line is longer than the limit of {} MB; it was skipped", max >> 20),
        ));
    }
    if buf.last() == Some(&b'\n') {
        buf.pop();
        if buf.last() == Some(&b'\r') {
            buf.pop();
        }
    }
    String::from_utf8(buf)
        .map(Some)
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "a line is not valid UTF-8; it was skipped"))
}
