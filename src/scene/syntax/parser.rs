//! Scene text → statements. The text is first split into logical statements (one per line,
//! continued while a bracket is open, while a line ends with an operator or a comma, or when
//! the next line is indented or starts with an operator); each statement is then parsed by the pest grammar
//! in `grammar/scene.pest`, which reuses the expression rules of `grammar/expr.pest`.
//!
//! The pest types leave this module only for the statements' readers: each statement reads its
//! own pairs with a `Reader`, and the registry (`scene/registry.rs`) hands the parser its
//! `Language`. Nothing outside the scene sees them. Every span is a byte range of the whole
//! scene text.

pub(crate) use pest::iterators::Pair;
use pest::Parser as _;

use super::ast::{DerivCall, DerivKind, EnsembleSpec, EventSpec, Item, SimSpec, Src, StabilizeSpec};
use super::error::{did_you_mean, ErrorKind, SceneError, Span};
use crate::print::Format;

#[derive(pest_derive::Parser)]
#[grammar = "../grammar/expr.pest"]
#[grammar = "../grammar/scene.pest"]
struct SceneGrammar;

/// The longest statement accepted, in bytes (one Lagrangian may be long; a scene's
/// statements are each parsed separately).
pub const MAX_STATEMENT: usize = 1 << 20;

/// Splits `text` into the byte ranges of its logical statements (blank and comment-only
/// lines are dropped).
pub fn split_statements(text: &str) -> Vec<Span> {
    let mut out = Vec::new();
    let mut start: Option<usize> = None;
    let mut depth: i64 = 0;
    let mut continues = false;
    let mut offset = 0;
    for raw in text.split_inclusive('\n') {
        let line_start = offset;
        offset += raw.len();
        let code = strip_comment(raw);
        let trimmed = code.trim();
        if trimmed.is_empty() {
            if start.is_some() && (depth > 0 || continues) {
                continue;
            }
            if let Some(s) = start.take() {
                out.push((s, line_start));
            }
            continue;
        }
        let leads_with_operator = trimmed.starts_with(['+', '-', '*', '/', '^', '·', '×']);
        let indented = raw.starts_with([' ', '\t']);
        match start {
            Some(_) if depth > 0 || continues || leads_with_operator || indented => {}
            Some(s) => {
                out.push((s, line_start));
                start = Some(line_start);
                depth = 0;
            }
            None => {
                start = Some(line_start);
                depth = 0;
            }
        }
        for c in code.chars() {
            match c {
                '(' | '[' => depth += 1,
                ')' | ']' => depth -= 1,
                _ => {}
            }
        }
        continues = trimmed.ends_with(['+', '-', '*', '/', '^', ',', '=', '·', '×', '\\']) && !trimmed.ends_with("..");
    }
    if let Some(s) = start {
        out.push((s, text.len()));
    }
    // Trim trailing whitespace from each range so spans end at the last character.
    out.into_iter()
        .map(|(s, e)| {
            let t = text[s..e].trim_end();
            (s, s + t.len())
        })
        .filter(|(s, e)| e > s)
        .collect()
}

/// Whether `text` is an unfinished statement (a bracket still open, or a last line ending
/// with an operator or a comma): the REPL then asks for another line.
pub fn is_incomplete(text: &str) -> bool {
    let mut open = Unfinished::default();
    for line in text.lines() {
        open.push_line(line);
    }
    open.is_incomplete()
}

/// [`is_incomplete`] kept line by line, so a reader joining continuation lines pays for each
/// line once (rescanning the whole statement per line made a 10⁵-line piped statement
/// quadratic: 16 000 lines took 6.6 s).
#[derive(Default)]
pub struct Unfinished {
    /// Open `(` and `[` minus closing ones.
    depth: i64,
    /// The last line with code, comment and surrounding blanks removed.
    last: String,
}

impl Unfinished {
    /// Takes the next line of the statement.
    pub fn push_line(&mut self, line: &str) {
        let code = strip_comment(line);
        for c in code.chars() {
            match c {
                '(' | '[' => self.depth += 1,
                ')' | ']' => self.depth -= 1,
                _ => {}
            }
        }
        if !code.trim().is_empty() {
            code.trim().clone_into(&mut self.last);
        }
    }

    /// Whether the lines so far leave a bracket open or end with an operator.
    pub fn is_incomplete(&self) -> bool {
        let last = self.last.as_str();
        self.depth > 0 || (last.ends_with(['+', '-', '*', '/', '^', ',', '=', '·', '×', '\\']) && !last.ends_with(".."))
    }
}

/// The line without its `#` comment.
fn strip_comment(line: &str) -> &str {
    match line.find('#') {
        Some(i) => &line[..i],
        None => line,
    }
}

/// What the parser needs from the statement registry: how to read a statement's pest pair
/// (its rule says which statement it is) and which words start a statement (for "did you
/// mean"). The registry passes it in, so this module imports no statement.
pub(crate) struct Language<T> {
    /// Reads one statement's pair.
    pub read: for<'i> fn(&Reader, Pair<'i, Rule>) -> Result<T, SceneError>,
    /// The words that start a statement.
    pub words: fn() -> Vec<&'static str>,
}

/// Parses the statement in `text[start..end]` (spans are positions in `text`) with `lang`.
pub(crate) fn parse_statement_at<T>(
    text: &str,
    start: usize,
    end: usize,
    lang: &Language<T>,
) -> Result<Option<T>, SceneError> {
    let src = &text[start..end];
    if src.len() > MAX_STATEMENT {
        return Err(SceneError::new(
            ErrorKind::TooLarge,
            format!("statement too long ({} bytes; the limit is {MAX_STATEMENT})", src.len()),
        )
        .at((start, start + 1))
        .hint("split it into named parts: `T = …`, `V = …`, `L = T - V`"));
    }
    let depth = check_depth(src, start)?;
    crate::parse::with_stack_for_depth(depth, || parse_checked(src, start, lang))
}

/// [`parse_statement_at`] after the size and depth checks, on a stack deep enough for it.
fn parse_checked<T>(src: &str, start: usize, lang: &Language<T>) -> Result<Option<T>, SceneError> {
    let pairs = match SceneGrammar::parse(Rule::statement, src) {
        Ok(p) => p,
        Err(e) => return Err(syntax_error(src, start, e, &(lang.words)())),
    };
    let r = Reader { base: start };
    for pair in pairs {
        if pair.as_rule() == Rule::EOI {
            continue;
        }
        return (lang.read)(&r, pair).map(Some);
    }
    Ok(None)
}

/// Guards pest's recursion on deeply nested parentheses (pest recurses per level); returns
/// the deepest nesting, which sizes the parser's stack.
fn check_depth(src: &str, base: usize) -> Result<usize, SceneError> {
    let mut depth = 0usize;
    let mut deepest = 0usize;
    for (i, c) in src.char_indices() {
        match c {
            '(' => {
                depth += 1;
                deepest = deepest.max(depth);
                if depth > crate::parse::MAX_DEPTH {
                    return Err(SceneError::new(
                        ErrorKind::Syntax,
                        format!("nesting deeper than {} levels", crate::parse::MAX_DEPTH),
                    )
                    .at((base + i, base + i + 1))
                    .hint("split the expression into named parts"));
                }
            }
            ')' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(deepest)
}

fn friendly(rule: &Rule) -> Option<&'static str> {
    Some(match rule {
        Rule::expr | Rule::sexpr | Rule::paren | Rule::call | Rule::symbol | Rule::number | Rule::call_head => {
            "an expression"
        }
        Rule::add | Rule::sub | Rule::mul | Rule::div | Rule::pow | Rule::implicit | Rule::simplicit => "an operator",
        Rule::EOI => "end of statement",
        Rule::name | Rule::name_list => "a name",
        Rule::primes => "`'`",
        Rule::param => "a parameter name",
        Rule::init => "an initial value like `θ = 3.0`",
        Rule::time_span | Rule::bound | Rule::signed_number => "a time span like `0..20`",
        Rule::method => "`with METHOD`",
        Rule::step => "`dt = …`",
        Rule::tolerance => "`tol = …`",
        Rule::steps => "`steps = …`",
        Rule::every => "`every N`",
        Rule::drift => "`drift = …`",
        Rule::max_steps => "`max_steps = …`",
        Rule::time_limit => "`time_limit = …`",
        Rule::megno_stop | Rule::kw_stop => "`stop megno >= LEVEL after T`",
        Rule::kw_after => "`after T` (the time from which MEGNO may stop an orbit)",
        Rule::at_least => "`>=` (or `≥`)",
        Rule::points => "`points N`",
        Rule::event | Rule::event_kind => "`record when …` or `stop when …`",
        Rule::direction => "`rising` or `falling`",
        Rule::stabilize | Rule::stabilize_kind => "`stabilize projection`, `stabilize baumgarte` or `stabilize none`",
        Rule::as_format | Rule::format_name => "a format (`plain`, `unicode`, `latex`)",
        Rule::path | Rule::quoted_path | Rule::bare_path => "a file name",
        Rule::assumption => "`positive`",
        Rule::print_item | Rule::derivation | Rule::deriv_kw => "something to print",
        Rule::map_range => "a range like `θ = -3..3`",
        Rule::chaos_kw => "an indicator (`lyapunov`, `megno`, `fli`)",
        Rule::plot_chaos
        | Rule::plot_phase
        | Rule::plot_energy
        | Rule::plot_path
        | Rule::plot_poincare
        | Rule::plot_series
        | Rule::plot_separation
        | Rule::plot_work_precision => {
            "a plot (`phase`, `energy`, `path x, y`, `poincare q, p`, `separation a, b`, `work_precision`, or expressions)"
        }
        _ => return None,
    })
}

fn syntax_error(src: &str, base: usize, e: pest::error::Error<Rule>, words: &[&str]) -> SceneError {
    let pos = match e.location {
        pest::error::InputLocation::Pos(p) => p,
        pest::error::InputLocation::Span((s, _)) => s,
    };
    let first_word: String = src.trim_start().chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
    let word_start = src.len() - src.trim_start().len();
    let is_known = words.contains(&first_word.as_str());
    // A first word that is no statement and is not followed by `=` is an unknown statement.
    let after = src.trim_start()[first_word.len()..].trim_start();
    let looks_like_definition = after.starts_with('=') && !after.starts_with("==");
    if !first_word.is_empty() && !is_known && !looks_like_definition {
        let span = (base + word_start, base + word_start + first_word.len());
        let mut err = SceneError::new(ErrorKind::UnknownStatement, format!("unknown statement `{first_word}`"))
            .at(span)
            .label("not a statement");
        err = match did_you_mean(&first_word, words.iter().copied()) {
            Some(s) => err.hint(format!("did you mean `{s}`? (`help` lists every statement)")),
            None => err.hint("a statement starts with a keyword (`help` lists them) or is a definition `name = …`"),
        };
        return err;
    }
    let (expected, found) = match &e.variant {
        pest::error::ErrorVariant::ParsingError { positives, .. } => {
            let mut exp: Vec<&str> = positives.iter().filter_map(friendly).collect();
            exp.sort_unstable();
            exp.dedup();
            let rest = &src[pos.min(src.len())..];
            let word: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            let found = match rest.chars().next() {
                Some(_) if !word.is_empty() => format!("`{word}`"),
                Some(c) => format!("`{c}`"),
                None => "the end of the statement".to_string(),
            };
            (exp, found)
        }
        pest::error::ErrorVariant::CustomError { message } => (vec![], message.clone()),
    };
    let message = if expected.is_empty() {
        format!("unexpected {found}")
    } else {
        format!("expected {}, found {found}", expected.join(" or "))
    };
    let label = if expected.is_empty() { "here".to_string() } else { format!("expected {}", expected.join(" or ")) };
    // `… as r record when …`: the run's name must end the statement.
    let before: Vec<&str> = src[..pos.min(src.len())].split_whitespace().rev().take(2).collect();
    if let [name, "as"] = before.as_slice() {
        if !found.starts_with("the end") {
            return SceneError::new(
                ErrorKind::Syntax,
                format!("`as {name}` ends the statement, but {found} follows it"),
            )
            .at((base + pos, base + pos + 1))
            .label("after the name")
            .hint({
                let options = src[pos..].trim();
                let options = options.rfind(" as ").map_or(options, |i| &options[..i]);
                format!("put the options first and the name last: `… {options} as {name}`")
            });
        }
    }
    let mut err = SceneError::new(ErrorKind::Syntax, message).at((base + pos, base + pos + 1)).label(label);
    let opens = src.matches('(').count();
    let closes = src.matches(')').count();
    if opens > closes {
        err = err.hint("a `(` is never closed");
    } else if closes > opens {
        err = err.hint("a `)` has no matching `(`");
    } else if is_known {
        err = err.hint(format!("`help {first_word}` shows the statement's form with an example"));
    }
    err
}

/// Keyword pairs carry no information beyond the statement's rule. The rules are every `kw_*`
/// rule of the grammar, listed by `build.rs` as it reads `grammar/*.pest` (a test checks the
/// list against the rules pest generated).
#[doc(hidden)]
pub fn is_kw(rule: Rule) -> bool {
    include!(concat!(env!("OUT_DIR"), "/keyword_rules.rs"))
}

/// The settings one statement's options have given so far, each with the clause that gave it
/// first. Reading a setting twice would keep one value and drop the other without a word
/// (`tol = 1e-9 … tol = 1e-6` ran at the second), so the second clause is refused at its span,
/// naming the first. Clauses that add to a list (`record when …`, `stop when …`) are not
/// settings and never come here.
#[derive(Default)]
pub(crate) struct Settings {
    /// The setting, the word that gave it, and the clause as written.
    first: Vec<(&'static str, &'static str, Src)>,
}

impl Settings {
    /// Records that `clause` (the whole option as written, starting with `word`) gives
    /// `setting`, or refuses it when an earlier clause gave that setting.
    pub(crate) fn give(&mut self, setting: &'static str, word: &'static str, clause: Src) -> Result<(), SceneError> {
        let Some((_, first_word, first)) = self.first.iter().find(|(s, _, _)| *s == setting) else {
            self.first.push((setting, word, clause));
            return Ok(());
        };
        let message = if *first_word == word {
            format!("`{word}` is given twice")
        } else {
            format!("`{word}` and `{first_word}` both set {setting}")
        };
        let label = if *first_word == word { "again here".to_string() } else { format!("also sets {setting}") };
        Err(SceneError::new(ErrorKind::Syntax, message)
            .at(clause.span)
            .label(label)
            .hint(format!("keep one of `{}` (given first) and `{}`", first.text, clause.text)))
    }

    /// The setting a `simulate`-like option clause gives (two words may give one setting:
    /// `steps = N` is the step `(t1 − t0)/N`), and the word it starts with; `None` for a
    /// clause that is not a setting.
    fn of(rule: Rule) -> Option<(&'static str, &'static str)> {
        Some(match rule {
            Rule::method => ("the method", "with"),
            Rule::step => ("the step", "dt"),
            Rule::steps => ("the step", "steps"),
            Rule::tolerance => ("the tolerance", "tol"),
            Rule::every => ("every", "every"),
            Rule::points => ("points", "points"),
            Rule::drift => ("drift", "drift"),
            Rule::max_steps => ("max_steps", "max_steps"),
            Rule::time_limit => ("time_limit", "time_limit"),
            Rule::stabilize => ("stabilize", "stabilize"),
            _ => return None,
        })
    }
}

/// Refuses a name given twice in one list of a statement (`ritz … from x = 0, x = 1`,
/// `average … with x = A cos(θ), x = B cos(θ)`, `solve a, a`): its reader would keep one of the
/// two and drop the other without a word. The second is refused at its span; `what` says what a
/// list of `name = …` gives (`start value`), `None` for a list of names. Names compare as written: these
/// lists name coordinates and new symbols, which have one spelling.
pub(crate) fn once_each<'a>(names: impl IntoIterator<Item = &'a Src>, what: Option<&str>) -> Result<(), SceneError> {
    let mut seen: Vec<&Src> = Vec::new();
    for n in names {
        if seen.iter().any(|f| f.text.trim() == n.text.trim()) {
            let name = n.text.trim();
            return Err(SceneError::new(ErrorKind::Syntax, format!("`{name}` is given twice"))
                .at(n.span)
                .label("again here")
                .hint(match what {
                    Some(what) => format!("keep one {what} for `{name}`"),
                    None => format!("name `{name}` once"),
                }));
        }
        seen.push(n);
    }
    Ok(())
}

/// Reads a statement's pest pairs into its statement type: the helpers every statement's
/// reader shares (spans, names, paths, formats, the `simulate`-like options).
#[doc(hidden)]
pub struct Reader {
    base: usize,
}

impl Reader {
    /// The text of a pair without the blanks and comments pest's implicit rules may have
    /// consumed at its end (expressions never contain `#`).
    pub(crate) fn src(&self, p: &Pair<Rule>) -> Src {
        let s = p.as_span();
        let raw = p.as_str();
        let text = raw.split('#').next().unwrap_or(raw).trim_end();
        Src { text: text.to_string(), span: (self.base + s.start(), self.base + s.start() + text.len()) }
    }

    pub(crate) fn span(&self, p: &Pair<Rule>) -> Span {
        let s = p.as_span();
        (self.base + s.start(), self.base + s.end())
    }

    pub(crate) fn names(&self, p: Pair<Rule>) -> Vec<Src> {
        p.into_inner().filter(|q| q.as_rule() == Rule::name).map(|q| self.src(&q)).collect()
    }

    /// A declared name, or the members of a family `x[0..4]` (x0 … x4, each with the family's
    /// span): the plain symbols that `x[i]` names in expressions.
    pub(crate) fn family_or_name(&self, q: &Pair<Rule>) -> Result<Vec<Src>, SceneError> {
        if q.as_rule() != Rule::name_family {
            return Ok(vec![self.src(q)]);
        }
        let span = self.span(q);
        let mut inner = q.clone().into_inner();
        let base = inner.next().map(|n| n.as_str().to_string()).unwrap_or_default();
        let bounds: Vec<Option<u64>> =
            inner.next().map(|r| r.into_inner().map(|b| b.as_str().parse().ok()).collect()).unwrap_or_default();
        let (lo, hi) = match bounds[..] {
            [Some(lo), Some(hi)] => (lo, hi),
            _ => {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    "a family's range needs two whole numbers below 2^64",
                )
                .at(span))
            }
        };
        if lo > hi {
            return Err(SceneError::new(ErrorKind::BadNumber, format!("the range {lo}..{hi} of `{base}` is empty"))
                .at(span)
                .hint("ranges are inclusive and ascending, as in `x[0..4]` for x0 … x4"));
        }
        if hi - lo >= crate::parse::MAX_SUM_TERMS as u64 {
            return Err(SceneError::new(
                ErrorKind::TooLarge,
                format!("`{base}[{lo}..{hi}]` declares more than {} names", crate::parse::MAX_SUM_TERMS),
            )
            .at(span));
        }
        Ok((lo..=hi).map(|k| Src { text: format!("{base}{k}"), span }).collect())
    }

    /// The names a statement declares (coordinates, parameters, functions, definitions),
    /// refusing `pi`: expressions read it as the exact constant, so a declaration would
    /// otherwise be silently ignored.
    pub(crate) fn declared(&self, names: Vec<Src>) -> Result<Vec<Src>, SceneError> {
        match names.iter().find(|n| crate::parse::is_constant_name(&n.text)) {
            Some(n) => Err(SceneError::new(
                ErrorKind::Redeclared,
                format!("`{}` is the constant π and cannot be declared", n.text),
            )
            .at(n.span)
            .label("the exact constant π")
            .hint(
                "π is built in and exact: delete the declaration, or give another quantity another name, such as `phi`",
            )),
            None => Ok(names),
        }
    }

    pub(crate) fn format(&self, p: Pair<Rule>) -> Format {
        let name = p.into_inner().find(|q| q.as_rule() == Rule::format_name).map(|q| q.as_str().to_string());
        match name.as_deref() {
            Some("latex") => Format::Latex,
            Some("plain") => Format::Plain,
            _ => Format::Unicode,
        }
    }

    pub(crate) fn format_name(p: &Pair<Rule>) -> Format {
        match p.as_str() {
            "latex" => Format::Latex,
            "plain" => Format::Plain,
            _ => Format::Unicode,
        }
    }

    /// An empty piece of source at the statement's start (for a part a malformed statement
    /// lacks; the grammar makes it rare).
    pub(crate) fn empty(&self) -> Src {
        Src { text: String::new(), span: (self.base, self.base) }
    }

    pub(crate) fn path(&self, p: Pair<Rule>) -> Src {
        let inner = p.into_inner().next();
        match inner {
            Some(q) if q.as_rule() == Rule::quoted_path => {
                let s = self.span(&q);
                let t = q.as_str();
                Src { text: t[1..t.len() - 1].to_string(), span: s }
            }
            Some(q) => self.src(&q),
            None => self.empty(),
        }
    }

    pub(crate) fn deriv_call(&self, p: Pair<Rule>) -> Result<DerivCall, SceneError> {
        let span = self.span(&p);
        let mut kind = None;
        let mut args = Vec::new();
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::deriv_kw => kind = DerivKind::from_keyword(q.as_str()),
                Rule::sexpr => args.push(self.src(&q)),
                _ => {}
            }
        }
        let kind = kind.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected a derivation").at(span))?;
        Ok(DerivCall { kind, args, span })
    }

    pub(crate) fn item(&self, p: Pair<Rule>) -> Result<Item, SceneError> {
        let span = self.span(&p);
        let Some(q) = p.into_inner().next() else {
            return Err(SceneError::new(ErrorKind::Syntax, "expected something to print").at(span));
        };
        Ok(match q.as_rule() {
            Rule::derivation => Item::Derivation(self.deriv_call(q)?),
            Rule::deriv_kw => match DerivKind::from_keyword(q.as_str()) {
                Some(kind) => Item::Derivation(DerivCall { kind, args: vec![], span }),
                None => Item::Expr(self.src(&q)),
            },
            _ => Item::Expr(self.src(&q)),
        })
    }

    /// The statement's parts without its keyword pairs.
    pub(crate) fn inner<'i>(&self, p: &Pair<'i, Rule>) -> Vec<Pair<'i, Rule>> {
        p.clone().into_inner().filter(|q| !is_kw(q.as_rule())).collect()
    }

    /// `simulate …`.
    pub fn simulate_stmt(&self, p: Pair<Rule>) -> Result<SimSpec, SceneError> {
        self.simulate(self.inner(&p), self.span(&p))
    }

    pub(crate) fn simulate<'i>(&self, inner: Vec<Pair<'i, Rule>>, span: Span) -> Result<SimSpec, SceneError> {
        let mut inits = Vec::new();
        let mut time_var = None;
        let mut t0 = None;
        let mut t1 = None;
        let mut span_span = span;
        let mut method = None;
        let mut dt = None;
        let mut tol = None;
        let mut steps = None;
        let mut events = Vec::new();
        let mut name = None;
        let mut stabilize = None;
        let mut every = None;
        let mut points = None;
        let mut drift = None;
        let mut max_steps = None;
        let mut time_limit = None;
        let mut ensemble = None;
        let mut given = Settings::default();
        for q in inner.into_iter().filter(|q| !is_kw(q.as_rule())) {
            if let Some((setting, word)) = Settings::of(q.as_rule()) {
                given.give(setting, word, self.src(&q))?;
            }
            match q.as_rule() {
                Rule::ensemble => ensemble = Some(self.ensemble(q)),
                Rule::init => {
                    let mut it = q.into_inner();
                    if let (Some(s), Some(v)) = (it.next(), it.next()) {
                        inits.push((self.src(&s), self.src(&v)));
                    }
                }
                Rule::name if time_var.is_none() => time_var = Some(self.src(&q)),
                Rule::name => name = Some(self.src(&q)),
                Rule::time_span => {
                    span_span = self.span(&q);
                    let mut it = q.into_inner();
                    t0 = it.next().map(|b| self.src(&b));
                    t1 = it.next().map(|b| self.src(&b));
                }
                Rule::method => method = q.into_inner().last().map(|n| self.src(&n)),
                Rule::step => dt = q.into_inner().last().map(|n| self.src(&n)),
                Rule::tolerance => tol = q.into_inner().last().map(|n| self.src(&n)),
                Rule::steps => steps = q.into_inner().last().map(|n| self.src(&n)),
                Rule::every => every = q.into_inner().last().map(|n| self.src(&n)),
                Rule::points => points = q.into_inner().last().map(|n| self.src(&n)),
                Rule::drift => drift = q.into_inner().last().map(|n| self.src(&n)),
                Rule::max_steps => max_steps = q.into_inner().last().map(|n| self.src(&n)),
                Rule::time_limit => time_limit = q.into_inner().last().map(|n| self.src(&n)),
                Rule::stabilize => {
                    let sspan = self.span(&q);
                    let mut kind = String::new();
                    let mut rate = None;
                    for r in q.into_inner() {
                        match r.as_rule() {
                            Rule::stabilize_kind => kind = r.as_str().to_string(),
                            Rule::sexpr => rate = Some(self.src(&r)),
                            _ => {}
                        }
                    }
                    stabilize = Some(StabilizeSpec { kind, rate, span: sspan });
                }
                Rule::event => {
                    let espan = self.span(&q);
                    let mut terminal = false;
                    let mut exprs = Vec::new();
                    let mut rising = None;
                    for r in q.into_inner() {
                        match r.as_rule() {
                            Rule::event_kind => terminal = r.as_str() == "stop",
                            Rule::sexpr => exprs.push(self.src(&r)),
                            Rule::direction => rising = Some(r.as_str() == "rising"),
                            _ => {}
                        }
                    }
                    let mut it = exprs.into_iter();
                    if let Some(lhs) = it.next() {
                        events.push(EventSpec { terminal, lhs, rhs: it.next(), rising, span: espan });
                    }
                }
                _ => {}
            }
        }
        let missing = || SceneError::new(ErrorKind::Syntax, "malformed `simulate`").at(span);
        Ok(SimSpec {
            inits,
            time_var: time_var.ok_or_else(missing)?,
            t0: t0.ok_or_else(missing)?,
            t1: t1.ok_or_else(missing)?,
            span_span,
            method,
            dt,
            tol,
            steps,
            events,
            name,
            stabilize,
            every,
            points,
            drift,
            max_steps,
            time_limit,
            ensemble,
        })
    }

    pub(crate) fn ensemble(&self, q: Pair<Rule>) -> EnsembleSpec {
        let espan = self.span(&q);
        let parts: Vec<Pair<Rule>> = q.into_inner().filter(|q| !is_kw(q.as_rule())).collect();
        let src = |i: usize| parts.get(i).map_or(Src { text: String::new(), span: espan }, |p| self.src(p));
        let (mut from, mut to) = (src(1), src(1));
        if let Some(ts) = parts.get(1) {
            let mut it = ts.clone().into_inner();
            from = it.next().map_or(from, |b| self.src(&b));
            to = it.next().map_or(to, |b| self.src(&b));
        }
        EnsembleSpec {
            var: src(0),
            from,
            to,
            step: src(2),
            on: src(3),
            value: src(4),
            solve: src(5),
            positive: parts.get(6).is_some_and(|p| p.as_str() == ">"),
            span: espan,
        }
    }

    /// A tuple `(a, b, …)` of expressions: `jacobian`'s map, `geodesic`'s metric rows and ends,
    /// `ritz`'s `near`.
    pub(crate) fn tuple(&self, p: Pair<Rule>) -> Vec<Src> {
        p.into_inner().filter(|x| x.as_rule() == Rule::sexpr).map(|x| self.src(&x)).collect()
    }
}

/// The one statement of `s`, read by `read` (typed, so a test sees the statement's own
/// fields), or what went wrong: a parse error, no statement, or a grammar rule other than
/// `rule`. For the statements' tests (`tests/it/scene/syntax.rs`).
#[doc(hidden)]
pub fn try_read_one<T>(
    s: &str,
    rule: Rule,
    read: for<'i> fn(&Reader, Pair<'i, Rule>) -> Result<T, SceneError>,
) -> Result<T, String> {
    thread_local!(static RULE: std::cell::Cell<Option<Rule>> = const { std::cell::Cell::new(None) });
    let lang = Language { read, words: Vec::new };
    let seen = Language {
        read: |_, p| {
            RULE.with(|r| r.set(Some(p.as_rule())));
            Ok(())
        },
        words: Vec::new,
    };
    parse_statement_at(s, 0, s.len(), &seen).map_err(|e| format!("{s}: {e:?}"))?;
    let chosen = RULE.with(|r| r.get());
    if chosen != Some(rule) {
        return Err(format!("{s}: the grammar chose {chosen:?}, not {rule:?}"));
    }
    match parse_statement_at(s, 0, s.len(), &lang) {
        Ok(Some(v)) => Ok(v),
        Ok(None) => Err(format!("{s}: no statement")),
        Err(e) => Err(format!("{s}: {e:?}")),
    }
}
