//! Parsing: text → [`Expr`], with pest for the shapes and one Pratt parser for precedence.
//!
//! No pest type leaves this module. Errors carry the byte span, line and column of the
//! problem, what was expected there and, where one is known, a hint.
//!
//! Nesting depth is guarded here, before pest or the Pratt parser recurse: pest's own call
//! limit is process-global and counts calls rather than depth, and both parsers recurse on
//! deeply nested input. Up to [`MAX_DEPTH`] levels are accepted on any thread: the parse runs
//! on a stack segment sized from the measured depth ([`with_stack_for_depth`], `stacker`), so
//! the limit is the same on an 8 MB main thread and a 2 MB worker. The limit is the one the
//! printer is held to: every expression the engine's own stages produce from parsed input
//! prints with less nesting than this (`tests/it/robust/roundtrip.rs`).

use std::cell::{Cell, RefCell};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::sync::OnceLock;

use num_bigint::BigInt;
use num_traits::{Num, Signed, ToPrimitive, Zero};
use pest::iterators::{Pair, Pairs};
use pest::pratt_parser::{Assoc, Op, PrattParser};
use pest::Parser as _;

use crate::expr::{Expr, Func, Node, Rational, Symbol};

#[derive(pest_derive::Parser)]
#[grammar = "../grammar/expr.pest"]
struct ExprGrammar;

/// The deepest nesting of parentheses, calls, unary signs or `^` chains accepted. The same
/// figure bounds the compiled tape's recursion (`compile::tape`), so anything that parses
/// also compiles. It is well above what printing produces for the engine's own output (a
/// 300-deep tower of calls prints with 300 levels; the simplifier keeps Horner forms at most
/// 64 deep), so printed text always re-parses.
pub const MAX_DEPTH: usize = 1000;

/// Stack reserved per level of nesting for pest's recursive descent and the Pratt parser,
/// with room to spare (measured in the dev profile: well under 4 KiB a level).
const STACK_PER_LEVEL: usize = 16 << 10;

/// Runs `f` (a parse of text nested `depth` levels deep) with enough stack for that depth,
/// growing onto a heap-allocated segment only when the current thread has too little left.
pub fn with_stack_for_depth<R>(depth: usize, f: impl FnOnce() -> R) -> R {
    let need = (64 << 10) + depth.saturating_mul(STACK_PER_LEVEL);
    stacker::maybe_grow(need, need.max(1 << 20), f)
}

/// The longest input accepted, in bytes.
pub const MAX_INPUT: usize = 4 << 20;

/// The largest decimal exponent written out in a literal (`1e5000`); larger ones are kept
/// as an unevaluated power of ten.
const MAX_LITERAL_EXPONENT: u64 = 1 << 40;

/// What the parser needs to know beyond the text: which names are declared functions and
/// which symbols are positive.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Declarations {
    /// Undefined functions the user declared (`V` so that `V(r)` is a call).
    pub functions: BTreeSet<String>,
    /// Symbols known to be strictly positive.
    pub positive: BTreeSet<String>,
    /// Indexed families and the inclusive range of indices declared for each (`x` → 0..=4
    /// when `x0` … `x4` are declared): `x[7]` is then refused rather than read as a new
    /// symbol `x7`. A family not listed is unchecked (the command line declares no names).
    pub families: BTreeMap<String, (u64, u64)>,
}

impl Declarations {
    /// No functions, no assumptions.
    pub fn new() -> Declarations {
        Declarations::default()
    }

    /// Declares functions by name.
    pub fn with_functions<S: AsRef<str>>(mut self, names: impl IntoIterator<Item = S>) -> Declarations {
        self.functions.extend(names.into_iter().map(|s| s.as_ref().to_string()));
        self
    }

    /// Declares positive symbols by name.
    pub fn with_positive<S: AsRef<str>>(mut self, names: impl IntoIterator<Item = S>) -> Declarations {
        self.positive.extend(names.into_iter().map(|s| s.as_ref().to_string()));
        self
    }

    /// Declares indexed families from plain names: every name that ends in digits after a
    /// letter or `_` (`x0`, `m12`, `θ1`) widens its family's range to cover that index.
    pub fn with_families_of<S: AsRef<str>>(mut self, names: impl IntoIterator<Item = S>) -> Declarations {
        for name in names {
            if let Some((base, k)) = split_index(name.as_ref()) {
                let range = self.families.entry(base.to_string()).or_insert((k, k));
                *range = (range.0.min(k), range.1.max(k));
            }
        }
        self
    }

    /// The symbol `name` with `primes` time derivatives, positive if declared so.
    pub fn symbol(&self, name: &str, primes: u8) -> Symbol {
        if primes == 0 && self.positive.contains(name) {
            Symbol::positive(name)
        } else {
            Symbol::new(name).with_primes(primes)
        }
    }
}

/// `x12` → (`x`, 12): a name that ends in decimal digits after a non-digit, read as a member
/// of an indexed family. Leading zeros (`x01`) are not an index: `x[1]` names `x1`.
pub fn split_index(name: &str) -> Option<(&str, u64)> {
    let base = name.trim_end_matches(|c: char| c.is_ascii_digit());
    let digits = &name[base.len()..];
    if base.is_empty() || digits.is_empty() || (digits.len() > 1 && digits.starts_with('0')) {
        return None;
    }
    digits.parse().ok().map(|k| (base, k))
}

/// The most terms the indexed sums of one expression may expand to (all sums together,
/// nested ones counted per instance): a resource limit, so a typo in a range is an error
/// rather than a parse that runs for minutes.
pub const MAX_SUM_TERMS: usize = 10_000;

/// Whether `name` is the exact constant π (`pi` or `π`), which the parser reads as a number:
/// it cannot name a coordinate, a parameter or a function.
pub fn is_constant_name(name: &str) -> bool {
    matches!(name, "pi" | "π")
}

/// A parse error with its location.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// What went wrong.
    pub message: String,
    /// Byte range of the offending text.
    pub span: (usize, usize),
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
    /// The source line the error is on.
    pub source_line: String,
    /// A suggestion, when one is known.
    pub hint: Option<String>,
}

impl ParseError {
    fn new(input: &str, span: (usize, usize), message: impl Into<String>) -> ParseError {
        let start = span.0.min(input.len());
        let before = &input[..floor_char_boundary(input, start)];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before[line_start..].chars().count() + 1;
        let line_end = input[line_start..].find('\n').map_or(input.len(), |i| line_start + i);
        ParseError {
            message: message.into(),
            span: (start, span.1.max(start)),
            line,
            column,
            source_line: input[line_start..line_end].to_string(),
            hint: None,
        }
    }

    /// An error at byte `pos` of `input`.
    pub fn at(input: &str, pos: usize, message: impl Into<String>) -> ParseError {
        ParseError::new(input, (pos, pos + 1), message)
    }

    /// The same error for a piece of a longer text that starts at byte `offset` of `whole`
    /// (one side of `Q = …, P = …`): its line, column and snippet are those of `whole`, so the
    /// caret points into what the user wrote, not into the piece alone.
    pub fn within(self, whole: &str, offset: usize) -> ParseError {
        let span = (self.span.0 + offset, self.span.1 + offset);
        let hint = self.hint;
        let mut e = ParseError::new(whole, span, self.message);
        e.hint = hint;
        e
    }

    fn with_hint(mut self, hint: impl Into<String>) -> ParseError {
        self.hint = Some(hint.into());
        self
    }
}

fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    while i > 0 && !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "error: {} (line {}, column {})", self.message, self.line, self.column)?;
        // Long lines (100,000 parentheses) show a window around the column, not the line.
        const BEFORE: usize = 60;
        const AFTER: usize = 20;
        let col = self.column.saturating_sub(1);
        let skip = col.saturating_sub(BEFORE);
        let total = self.source_line.chars().count();
        let shown: String = self.source_line.chars().skip(skip).take(col - skip + AFTER).collect();
        let (lead, pad) = if skip > 0 { ("…", 1) } else { ("", 0) };
        let tail = if skip + shown.chars().count() < total { "…" } else { "" };
        writeln!(f, "  | {lead}{shown}{tail}")?;
        write!(f, "  | {}^", " ".repeat(col - skip + pad))?;
        if let Some(h) = &self.hint {
            write!(f, "\n  = hint: {h}")?;
        }
        Ok(())
    }
}

impl std::error::Error for ParseError {}

/// Applies a pending unary minus (see `Ctx::expr`).
fn resolve((e, negated): (Expr, bool)) -> Expr {
    if negated {
        e.neg()
    } else {
        e
    }
}

/// An operand of the Pratt parser whose operation chain may still grow.
///
/// A chain `a + b − c + …` or `a b / c …` is collected and built by one call of the n-ary
/// constructor, so a sum of N terms costs one sort, not N re-sorts of every partial sum (the
/// left fold was quadratic: 20,000 terms took 23 s). Sums are associative in the canonical
/// form, so this gives the same node as the fold. Products are not quite: a rational
/// coefficient times a lone sum distributes (`2 (a + b) = 2a + 2b`), so once a factor is a
/// sum the rest of that chain is folded one factor at a time, exactly as before.
enum Operand {
    /// A finished expression and its pending unary minus.
    Done(Expr, bool),
    /// The terms of a sum, signs applied.
    Sum(Vec<Expr>),
    /// The factors of a product and its pending unary minus; `folded` once a factor was a sum
    /// (then `factors` holds the one running product).
    Product { factors: Vec<Expr>, negated: bool, folded: bool },
}

impl Operand {
    /// The expression so far and its pending unary minus.
    fn finish(self) -> (Expr, bool) {
        match self {
            Operand::Done(e, negated) => (e, negated),
            Operand::Sum(terms) => (Expr::add(terms), false),
            Operand::Product { mut factors, negated, folded } => {
                if folded || factors.len() == 1 {
                    (factors.pop().unwrap_or_else(Expr::one), negated)
                } else {
                    (Expr::mul(factors), negated)
                }
            }
        }
    }

    /// Appends a term (subtracted when `subtract`) to this operand read as a sum.
    fn push_term(self, term: Operand, subtract: bool) -> Operand {
        let mut terms = match self {
            Operand::Sum(terms) => terms,
            other => vec![resolve(other.finish())],
        };
        let term = resolve(term.finish());
        terms.push(if subtract { term.neg() } else { term });
        Operand::Sum(terms)
    }

    /// Multiplies this operand, read as a product, by `factor` (already raised to −1 for a
    /// division); `factor_negated` is the factor's pending unary minus.
    fn push_factor(self, factor: Expr, factor_negated: bool) -> Operand {
        let (mut factors, negated, mut folded) = match self {
            Operand::Product { factors, negated, folded } => (factors, negated, folded),
            other => {
                let (e, negated) = other.finish();
                let folded = matches!(e.node(), Node::Add(_));
                (vec![e], negated, folded)
            }
        };
        if !folded && matches!(factor.node(), Node::Add(_)) {
            let running = Expr::mul(std::mem::take(&mut factors));
            factors.push(running);
            folded = true;
        }
        if folded {
            let running = factors.pop().unwrap_or_else(Expr::one);
            factors.push(running.times(&factor));
        } else {
            factors.push(factor);
        }
        Operand::Product { factors, negated: negated != factor_negated, folded }
    }
}

fn pratt() -> &'static PrattParser<Rule> {
    static PRATT: OnceLock<PrattParser<Rule>> = OnceLock::new();
    PRATT.get_or_init(|| {
        PrattParser::new()
            .op(Op::infix(Rule::add, Assoc::Left) | Op::infix(Rule::sub, Assoc::Left))
            .op(Op::infix(Rule::mul, Assoc::Left)
                | Op::infix(Rule::div, Assoc::Left)
                | Op::infix(Rule::implicit, Assoc::Left))
            .op(Op::prefix(Rule::neg) | Op::prefix(Rule::plus))
            .op(Op::infix(Rule::pow, Assoc::Right))
    })
}

/// What a character that only looks like a Latin or Greek letter is (Cyrillic `х`, full-width
/// `ｘ`), or a combining mark; `None` for every other character. Names are ASCII or Greek
/// (README): a look-alike would make a second symbol that prints like the first, so `x + х`
/// would not simplify and nothing would say why. The command line and scenes refuse them.
pub fn lookalike_kind(c: char) -> Option<&'static str> {
    let u = u32::from(c);
    if (0x0400..=0x052F).contains(&u) {
        Some("a Cyrillic letter")
    } else if (0xFF01..=0xFF5E).contains(&u) {
        Some("a full-width character")
    } else if [0x0300..=0x036F, 0x1AB0..=0x1AFF, 0x1DC0..=0x1DFF, 0x20D0..=0x20FF, 0xFE20..=0xFE2F]
        .iter()
        .any(|r| r.contains(&u))
    {
        Some("a combining mark")
    } else {
        None
    }
}

/// The one message for a look-alike character `c` of kind `what` ([`lookalike_kind`]): the
/// parser, the command line's name lists, coordinate names and scenes all say the same.
pub fn lookalike_message(c: char, what: &str) -> String {
    format!("`{c}` (U+{:04X}) is {what} that looks like another; names are ASCII or Greek", u32::from(c))
}

/// What to do about a look-alike character.
pub const LOOKALIKE_HINT: &str = "retype the name with a Latin or Greek keyboard layout";

/// Refuses the first look-alike character of `input` ([`lookalike_kind`]) at its location.
/// Every expression and every name the engine reads goes through this, so no command can
/// take Cyrillic `х` for a new constant beside `x`.
pub fn refuse_lookalikes(input: &str) -> Result<(), ParseError> {
    match input.char_indices().find_map(|(i, c)| lookalike_kind(c).map(|w| (i, c, w))) {
        None => Ok(()),
        Some((i, c, what)) => {
            Err(ParseError::new(input, (i, i + c.len_utf8()), lookalike_message(c, what)).with_hint(LOOKALIKE_HINT))
        }
    }
}

/// Parses an expression with no declared functions or assumptions.
pub fn parse(input: &str) -> Result<Expr, ParseError> {
    parse_with(input, &Declarations::default())
}

/// Parses an expression.
pub fn parse_with(input: &str, decls: &Declarations) -> Result<Expr, ParseError> {
    if input.len() > MAX_INPUT {
        return Err(ParseError::new(
            input,
            (MAX_INPUT, input.len()),
            format!("input too long ({} bytes; the limit is {MAX_INPUT})", input.len()),
        ));
    }
    if input.trim().is_empty() {
        return Err(ParseError::new(input, (0, input.len()), "empty input: expected an expression"));
    }
    refuse_lookalikes(input)?;
    let depth = check_paren_depth(input)?;
    with_stack_for_depth(depth, || parse_checked(input, decls))
}

/// [`parse_with`] after the size and depth checks, on a stack deep enough for the input.
fn parse_checked(input: &str, decls: &Declarations) -> Result<Expr, ParseError> {
    let pairs = ExprGrammar::parse(Rule::input, input).map_err(|e| from_pest(input, e))?;
    let scope = Scope::default();
    let mut ctx = Ctx { input, decls, scope: &scope };
    let mut exprs = pairs.filter(|p| p.as_rule() == Rule::expr);
    let Some(top) = exprs.next() else {
        return Err(ParseError::new(input, (0, input.len()), "expected an expression"));
    };
    let e = ctx.expr(top.clone())?;
    if e.is_undefined() {
        let span = top.as_span();
        return Err(ParseError::new(
            input,
            (span.start(), span.end()),
            "the expression is undefined (it divides by zero)",
        ));
    }
    Ok(e)
}

/// Rejects nesting deeper than [`MAX_DEPTH`] before any recursive parser sees it; returns the
/// deepest nesting found.
fn check_paren_depth(input: &str) -> Result<usize, ParseError> {
    let mut depth = 0usize;
    let mut deepest = 0usize;
    for (i, c) in input.char_indices() {
        match c {
            '(' => {
                depth += 1;
                deepest = deepest.max(depth);
                if depth > MAX_DEPTH {
                    return Err(ParseError::new(input, (i, i + 1), format!("nesting deeper than {MAX_DEPTH} levels"))
                        .with_hint("split the expression into named parts"));
                }
            }
            ')' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(deepest)
}

fn friendly(rule: &Rule) -> &'static str {
    match rule {
        Rule::expr | Rule::paren | Rule::call | Rule::symbol | Rule::number | Rule::call_head => "an expression",
        Rule::add | Rule::sub | Rule::mul | Rule::div | Rule::pow | Rule::implicit => "an operator",
        Rule::neg | Rule::plus => "a sign",
        Rule::EOI => "end of input",
        Rule::name => "a name",
        Rule::primes => "`'`",
        Rule::partials => "`∂`",
        Rule::indexed_sum | Rule::indexed => "an expression",
        Rule::index_expr | Rule::index_inner | Rule::index_int | Rule::index_name | Rule::index_op => {
            "an index (a whole number, or an index bound by `sum`)"
        }
        Rule::index_range => "a range `a..b`",
        Rule::sum_single | Rule::sum_pair => "`i = a..b` or `i < j in a..b`",
        _ => "something else",
    }
}

/// Whether the innermost parenthesis still open at the end of `before` is a `sum(`.
fn inside_sum(before: &str) -> bool {
    let mut open = Vec::new();
    for (i, c) in before.char_indices() {
        match c {
            '(' => open.push(i),
            ')' => {
                open.pop();
            }
            _ => {}
        }
    }
    open.last().is_some_and(|&i| before[..i].ends_with("sum"))
}

fn from_pest(input: &str, e: pest::error::Error<Rule>) -> ParseError {
    let (start, end) = match e.location {
        pest::error::InputLocation::Pos(p) => (p, p),
        pest::error::InputLocation::Span(s) => s,
    };
    let message = match &e.variant {
        pest::error::ErrorVariant::ParsingError { positives, .. } => {
            let mut expected: Vec<&str> = positives.iter().map(friendly).collect();
            expected.sort_unstable();
            expected.dedup();
            let found = input[start.min(input.len())..].chars().next();
            let found = match found {
                Some(')') if expected.contains(&"an expression") && !expected.contains(&"an operator") => {
                    "`)`".to_string()
                }
                Some(c) => format!("`{c}`"),
                None => "end of input".to_string(),
            };
            if expected.is_empty() {
                format!("unexpected {found}")
            } else {
                format!("expected {}, found {found}", expected.join(" or "))
            }
        }
        pest::error::ErrorVariant::CustomError { message } => message.clone(),
    };
    let mut err = ParseError::new(input, (start, end.max(start + 1)), message);
    let rest = &input[start.min(input.len())..];
    if inside_sum(&input[..start.min(input.len())]) {
        err = err.with_hint("an indexed sum is `sum(i = 0..4, body)` or `sum(i < j in 0..4, body)`, ranges inclusive");
    } else if rest.starts_with(')') {
        err = err.with_hint("a parenthesis or call is empty or unbalanced");
    } else if rest.is_empty() && input.matches('(').count() > input.matches(')').count() {
        err = err.with_hint("a `(` is never closed");
    } else if rest.starts_with(')') || input.matches(')').count() > input.matches('(').count() {
        err = err.with_hint("a `)` has no matching `(`");
    }
    err
}

struct Ctx<'a> {
    input: &'a str,
    decls: &'a Declarations,
    scope: &'a Scope,
}

/// The indices bound by the enclosing `sum(…)`s, innermost last, and what the expansion has
/// cost so far (terms, and bytes of body text walked) against [`MAX_SUM_TERMS`] and
/// [`MAX_INPUT`].
#[derive(Default)]
struct Scope {
    bound: RefCell<Vec<(String, u64)>>,
    terms: Cell<usize>,
    bytes: Cell<usize>,
}

impl Scope {
    fn value(&self, name: &str) -> Option<u64> {
        self.bound.borrow().iter().rev().find(|(n, _)| n == name).map(|(_, v)| *v)
    }
}

impl Ctx<'_> {
    fn err(&self, pair: &Pair<Rule>, message: impl Into<String>) -> ParseError {
        let s = pair.as_span();
        ParseError::new(self.input, (s.start(), s.end()), message)
    }

    /// A unary minus in front of a product negates the whole product (`-(a+b) c` is
    /// `−1·(a+b)·c`, not `(−a−b)·c`). Both have the same value, but only the first is the node
    /// the printer wrote: the canonical form distributes a coefficient over a lone sum, so
    /// negating the first factor early would not re-parse printed products identically. The
    /// sign is therefore carried as a flag through `*`, `/` and juxtaposition, and applied at
    /// the enclosing sum, power or parenthesis.
    fn expr(&mut self, pair: Pair<Rule>) -> Result<Expr, ParseError> {
        let chain = self.check_chains(pair.clone().into_inner())?;
        let input = self.input;
        let ctx = &*self;
        with_stack_for_depth(chain, || {
            pratt()
                .map_primary(|p| ctx.primary(p).map(|e| Operand::Done(e, false)))
                .map_prefix(|op, rhs| {
                    let (e, negated) = rhs?.finish();
                    Ok(match op.as_rule() {
                        Rule::neg => Operand::Done(e, !negated),
                        _ => Operand::Done(e, negated),
                    })
                })
                .map_infix(|lhs, op, rhs| {
                    let (lhs, rhs) = (lhs?, rhs?);
                    Ok(match op.as_rule() {
                        Rule::add => lhs.push_term(rhs, false),
                        Rule::sub => lhs.push_term(rhs, true),
                        Rule::mul | Rule::implicit => {
                            let (r, rn) = rhs.finish();
                            lhs.push_factor(r, rn)
                        }
                        Rule::div => {
                            let (r, rn) = rhs.finish();
                            if r.is_zero() {
                                let s = op.as_span();
                                return Err(ParseError::new(input, (s.start(), s.end()), "division by zero"));
                            }
                            lhs.push_factor(Expr::pow(r, Expr::int(-1)), rn)
                        }
                        _ => {
                            let (l, r) = (resolve(lhs.finish()), resolve(rhs.finish()));
                            Operand::Done(Expr::pow(l, r), false)
                        }
                    })
                })
                .parse(pair.into_inner())
                .map(|operand| resolve(operand.finish()))
        })
    }

    /// Guards the Pratt parser's recursion: runs of unary signs and chains of `^`. Returns the
    /// longest run, which sizes the stack for the Pratt parse of this level.
    fn check_chains(&self, pairs: Pairs<Rule>) -> Result<usize, ParseError> {
        let mut run = 0usize;
        let mut longest = 0usize;
        for p in pairs {
            match p.as_rule() {
                Rule::neg | Rule::plus | Rule::pow => {
                    run += 1;
                    longest = longest.max(run);
                    if run > MAX_DEPTH {
                        return Err(self
                            .err(&p, format!("more than {MAX_DEPTH} chained signs or powers"))
                            .with_hint("split the expression into named parts"));
                    }
                }
                Rule::add | Rule::sub | Rule::mul | Rule::div | Rule::implicit => run = 0,
                _ => {}
            }
        }
        Ok(longest)
    }

    fn primary(&self, pair: Pair<Rule>) -> Result<Expr, ParseError> {
        match pair.as_rule() {
            Rule::number => self.number(&pair),
            Rule::symbol => self.symbol(pair),
            Rule::paren => {
                let inner = pair.into_inner().next();
                match inner {
                    Some(e) => {
                        let mut ctx = Ctx { input: self.input, decls: self.decls, scope: self.scope };
                        ctx.expr(e)
                    }
                    None => Err(ParseError::new(self.input, (0, 0), "empty parentheses")),
                }
            }
            Rule::call => self.call(pair),
            Rule::indexed_sum => self.indexed_sum(pair),
            Rule::indexed => self.indexed(pair),
            _ => Err(self.err(&pair, "unexpected input")),
        }
    }

    fn number(&self, pair: &Pair<Rule>) -> Result<Expr, ParseError> {
        let text = pair.as_str();
        let (mantissa, exponent) = match text.find(['e', 'E']) {
            Some(i) => (&text[..i], &text[i + 1..]),
            None => (text, ""),
        };
        let (int_part, frac_part) = match mantissa.find('.') {
            Some(i) => (&mantissa[..i], &mantissa[i + 1..]),
            None => (mantissa, ""),
        };
        let digits = format!("{int_part}{frac_part}");
        let digits = if digits.is_empty() { "0".to_string() } else { digits };
        let numer = BigInt::from_str_radix(&digits, 10).map_err(|_| self.err(pair, "malformed number"))?;
        let mut exp10 = BigInt::from(-(frac_part.len() as i64));
        if !exponent.is_empty() {
            let e = BigInt::from_str_radix(exponent.trim_start_matches('+'), 10)
                .map_err(|_| self.err(pair, "malformed exponent"))?;
            exp10 += e;
        }
        if exp10.abs() > BigInt::from(MAX_LITERAL_EXPONENT) {
            return Err(
                self.err(pair, format!("decimal exponent {exp10} is too large (the limit is {MAX_LITERAL_EXPONENT})"))
            );
        }
        let mantissa = Expr::num(Rational::from_integer(numer.clone()));
        if exp10.is_zero() || numer.is_zero() {
            return Ok(mantissa);
        }
        let e = exp10.to_i64().unwrap_or(0);
        // Expr::pow folds 10^e exactly while the result stays small, and keeps it
        // unevaluated beyond that (`1e99999999`).
        Ok(mantissa.times(&Expr::pow(Expr::int(10), Expr::int(e))))
    }

    fn symbol(&self, pair: Pair<Rule>) -> Result<Expr, ParseError> {
        let text = pair.as_str();
        let mut name = text;
        let mut primes = 0usize;
        for p in pair.clone().into_inner() {
            match p.as_rule() {
                Rule::name => name = p.as_str(),
                Rule::primes => primes = p.as_str().len(),
                _ => {}
            }
        }
        if Func::from_name(name).is_some() || ["sqrt", "cot"].contains(&name) {
            return Err(self
                .err(&pair, format!("`{name}` is a function and needs its argument in parentheses"))
                .with_hint(format!("write `{name}(x)`, with no space before `(`")));
        }
        if self.decls.functions.contains(name) {
            return Err(self
                .err(&pair, format!("`{name}` is declared a function, so it must be called"))
                .with_hint(format!("write `{name}(…)` with its arguments")));
        }
        if let Some(v) = self.scope.value(name) {
            if primes > 0 {
                return Err(self
                    .err(&pair, format!("`{name}` is an index of an enclosing `sum`, a number with no time derivative"))
                    .with_hint(format!("write `{name}` without primes, or name the index differently")));
            }
            return Ok(Expr::int(v as i64));
        }
        if is_constant_name(name) {
            if primes > 0 {
                return Err(self
                    .err(&pair, format!("`{name}` is the constant π, which has no time derivative"))
                    .with_hint("a variable needs another name, such as `phi` or `p_i`"));
            }
            return Ok(Expr::pi());
        }
        let primes = u8::try_from(primes).map_err(|_| self.err(&pair, "too many primes"))?;
        Ok(Expr::sym(self.decls.symbol(name, primes)))
    }

    /// The value of an index expression (`i + 1`) under the enclosing sums' bindings, which
    /// must be a whole number ≥ 0.
    fn index_value(&self, pair: Pair<Rule>) -> Result<u64, ParseError> {
        let total = self.signed_index(pair.clone())?;
        u64::try_from(total).map_err(|_| {
            self.err(&pair, format!("the index `{}` is {total}, and indices are whole numbers ≥ 0", pair.as_str()))
        })
    }

    /// The value of an index expression, of either sign (a range's upper bound below zero
    /// only makes the range empty).
    fn signed_index(&self, pair: Pair<Rule>) -> Result<i128, ParseError> {
        let mut total: i128 = 0;
        let mut sign: i128 = 1;
        for p in pair.clone().into_inner() {
            match p.as_rule() {
                Rule::index_op => sign = if p.as_str() == "-" { -1 } else { 1 },
                Rule::index_int => {
                    let v: u64 = p.as_str().parse().map_err(|_| {
                        self.err(&p, "index too large").with_hint("indices are whole numbers below 2^64")
                    })?;
                    total += sign * i128::from(v);
                }
                Rule::index_name => {
                    let name = p.as_str();
                    let Some(v) = self.scope.value(name) else {
                        return Err(self
                            .err(&p, format!("`{name}` is not an index bound by an enclosing `sum`"))
                            .with_hint(format!(
                                "bind it, as in `sum({name} = 0..4, …)`, or write a whole number such as `x[0]`"
                            )));
                    };
                    total += sign * i128::from(v);
                }
                _ => {}
            }
        }
        Ok(total)
    }

    /// `x[i]'`: the symbol named by the family and the index's value (`x3'`), refused when a
    /// declared family's range does not hold that index.
    fn indexed(&self, pair: Pair<Rule>) -> Result<Expr, ParseError> {
        let mut base = "";
        let mut index = None;
        let mut primes = 0usize;
        for p in pair.clone().into_inner() {
            match p.as_rule() {
                Rule::name => base = p.as_str(),
                Rule::index_inner => index = p.into_inner().next(),
                Rule::primes => primes = p.as_str().len(),
                _ => {}
            }
        }
        let Some(index) = index else {
            return Err(self.err(&pair, "malformed index"));
        };
        let ispan = index.as_span();
        let k = self.index_value(index)?;
        if Func::from_name(base).is_some()
            || ["sqrt", "cot", "sum"].contains(&base)
            || is_constant_name(base)
            || self.decls.functions.contains(base)
            || self.scope.value(base).is_some()
        {
            return Err(self
                .err(&pair, format!("`{base}` is a function, a constant or an index, and cannot be indexed"))
                .with_hint("indexed names are families of plain symbols, such as `x[i]` for `x0`, `x1`, …"));
        }
        // A momentum `p_x[i]` belongs to the coordinate family `x`.
        let family = self
            .decls
            .families
            .get(base)
            .map(|r| (base, *r))
            .or_else(|| base.strip_prefix("p_").and_then(|c| self.decls.families.get(c).map(|r| (c, *r))));
        if let Some((fam, (lo, hi))) = family {
            if k < lo || k > hi {
                return Err(ParseError::new(
                    self.input,
                    (ispan.start(), ispan.end()),
                    format!("index {k} is outside `{fam}`'s declared range {lo}..{hi}"),
                )
                .with_hint(format!("`{fam}` is declared for indices {lo}..{hi}; check the sum's range or the index")));
            }
        }
        let name = format!("{base}{k}");
        let primes = u8::try_from(primes).map_err(|_| self.err(&pair, "too many primes"))?;
        Ok(Expr::sym(self.decls.symbol(&name, primes)))
    }

    /// `sum(i = a..b, body)` and `sum(i < j in a..b, body)`: the body parsed once per value
    /// (or per pair i < j) with the index bound, and the terms added as a written-out chain
    /// `body₀ + body₁ + …` in parentheses would be, so the tree is the same node.
    fn indexed_sum(&self, pair: Pair<Rule>) -> Result<Expr, ParseError> {
        let mut binder = None;
        let mut body = None;
        for p in pair.clone().into_inner() {
            match p.as_rule() {
                Rule::sum_single | Rule::sum_pair => binder = Some(p),
                Rule::expr => body = Some(p),
                _ => {}
            }
        }
        let (Some(binder), Some(body)) = (binder, body) else {
            return Err(self
                .err(&pair, "malformed sum")
                .with_hint("write `sum(i = 0..4, …)` or `sum(i < j in 0..4, …)`"));
        };
        let paired = binder.as_rule() == Rule::sum_pair;
        let mut names = Vec::new();
        let mut range = None;
        for p in binder.into_inner() {
            match p.as_rule() {
                Rule::index_name => names.push(p),
                Rule::index_range => range = Some(p),
                _ => {}
            }
        }
        let Some(range) = range else {
            return Err(self.err(&pair, "malformed sum range"));
        };
        for (k, n) in names.iter().enumerate() {
            let name = n.as_str();
            if self.scope.value(name).is_some() || names[..k].iter().any(|m| m.as_str() == name) {
                return Err(self
                    .err(n, format!("the index `{name}` is already bound by an enclosing `sum`"))
                    .with_hint("give the inner sum's index another name (`j`, `k`, …)"));
            }
            if is_constant_name(name) || Func::from_name(name).is_some() || self.decls.functions.contains(name) {
                return Err(self.err(n, format!("`{name}` cannot name an index")).with_hint("use `i`, `j`, `k`, …"));
            }
        }
        let mut bounds = range.clone().into_inner().filter(|p| p.as_rule() == Rule::index_expr);
        let (Some(lo), Some(hi)) = (bounds.next(), bounds.next()) else {
            return Err(self.err(&range, "malformed sum range"));
        };
        let (lo, hi) = (self.index_value(lo)?, self.signed_index(hi)?);
        let count: u128 = if i128::from(lo) > hi {
            0
        } else {
            let n = (hi - i128::from(lo)) as u128 + 1;
            if paired {
                n * (n - 1) / 2
            } else {
                n
            }
        };
        // A bound that moves with an enclosing index (`j = i+1..4`) may leave nothing for the
        // last values of that index: an empty sum, zero, as written out. A range of fixed
        // numbers that holds nothing is a mistake.
        if count == 0 && range.clone().into_inner().flatten().any(|p| p.as_rule() == Rule::index_name) {
            return Ok(Expr::int(0));
        }
        if count == 0 {
            let what = if paired { "no pair i < j" } else { "no index" };
            return Err(self
                .err(&range, format!("the range {lo}..{hi} is empty: it holds {what}"))
                .with_hint("ranges are inclusive and ascending, as in `0..4` for 0, 1, 2, 3, 4"));
        }
        let terms_after = u128::try_from(self.scope.terms.get()).unwrap_or(u128::MAX).saturating_add(count);
        let bytes_after = u128::try_from(self.scope.bytes.get())
            .unwrap_or(u128::MAX)
            .saturating_add(count.saturating_mul(body.as_str().len() as u128));
        if terms_after > MAX_SUM_TERMS as u128 || bytes_after > MAX_INPUT as u128 {
            return Err(self
                .err(&range, format!("the sums expand to more than {MAX_SUM_TERMS} terms or {MAX_INPUT} bytes of text"))
                .with_hint(format!("this range has {count} terms; a smaller range, or fewer nested sums, fits")));
        }
        self.scope.terms.set(terms_after as usize);
        self.scope.bytes.set(bytes_after as usize);
        let hi = hi as u64; // lo ≤ hi here, and lo is a u64
        let mut terms = Vec::with_capacity(count as usize);
        let first = names[0].as_str().to_string();
        let second = names.get(1).map(|n| n.as_str().to_string());
        let mut parse_with_bound = |values: &[(String, u64)]| -> Result<(), ParseError> {
            self.scope.bound.borrow_mut().extend(values.iter().cloned());
            let mut ctx = Ctx { input: self.input, decls: self.decls, scope: self.scope };
            let term = ctx.expr(body.clone());
            let mut bound = self.scope.bound.borrow_mut();
            let keep = bound.len() - values.len();
            bound.truncate(keep);
            terms.push(term?);
            Ok(())
        };
        for i in lo..=hi {
            match &second {
                None => parse_with_bound(&[(first.clone(), i)])?,
                Some(j_name) => {
                    for j in (i..=hi).skip(1) {
                        parse_with_bound(&[(first.clone(), i), (j_name.clone(), j)])?;
                    }
                }
            }
        }
        Ok(Expr::add(terms))
    }

    fn call(&self, pair: Pair<Rule>) -> Result<Expr, ParseError> {
        let mut inner = pair.clone().into_inner();
        let Some(head) = inner.next() else {
            return Err(self.err(&pair, "malformed call"));
        };
        let mut name = "";
        let mut primes = 0usize;
        let mut partials: Vec<u32> = Vec::new();
        for p in head.clone().into_inner() {
            match p.as_rule() {
                Rule::name => name = p.as_str(),
                Rule::primes => primes = p.as_str().len(),
                Rule::partials => {
                    for part in p.as_str().split('∂').filter(|s| !s.is_empty()) {
                        let n: String = part
                            .chars()
                            .filter_map(|c| (c as u32).checked_sub(0x2080).and_then(|d| char::from_digit(d, 10)))
                            .collect();
                        partials.push(n.parse().unwrap_or(0));
                    }
                }
                _ => {}
            }
        }
        if name == "sum" && !self.decls.functions.contains(name) {
            return Err(self
                .err(&pair, "`sum` needs an index and its range before the summand")
                .with_hint("an indexed sum is `sum(i = 0..4, body)` or `sum(i < j in 0..4, body)`, ranges inclusive"));
        }
        let mut args = Vec::new();
        for a in inner {
            let mut ctx = Ctx { input: self.input, decls: self.decls, scope: self.scope };
            args.push(ctx.expr(a)?);
        }
        let builtin_arity = match name {
            "sqrt" | "cot" => Some(1),
            _ => Func::from_name(name).map(Func::arity),
        };
        if let Some(want) = builtin_arity {
            if primes > 0 || !partials.is_empty() {
                return Err(self
                    .err(&head, format!("`{name}` is a built-in function; primes and `∂` apply to declared functions"))
                    .with_hint(format!("differentiate explicitly, or declare your own function instead of `{name}`")));
            }
            if args.len() != want {
                let what =
                    if args.is_empty() { "no arguments".to_string() } else { format!("{} arguments", args.len()) };
                return Err(self.err(
                    &pair,
                    format!("`{name}` takes {want} argument{}, found {what}", if want == 1 { "" } else { "s" }),
                ));
            }
            return Ok(match (name, Func::from_name(name)) {
                ("sqrt", _) => args[0].sqrt(),
                ("cot", _) => Expr::call(Func::Cos, args.clone()).over(&Expr::call(Func::Sin, args)),
                (_, Some(f)) => Expr::call(f, args),
                (_, None) => return Err(self.err(&head, format!("unknown function `{name}`"))),
            });
        }
        if self.decls.functions.contains(name) {
            if args.is_empty() {
                return Err(self.err(&pair, format!("`{name}` needs at least one argument")));
            }
            let mut orders = vec![0u32; args.len()];
            if primes > 0 {
                if args.len() != 1 {
                    return Err(self
                        .err(&head, "primes differentiate a function of one argument")
                        .with_hint(format!("write `∂₁{name}(…)` for a partial derivative by the first argument")));
                }
                orders[0] = primes as u32;
            }
            for k in partials {
                if k == 0 || k as usize > args.len() {
                    return Err(self.err(
                        &head,
                        format!(
                            "`∂{}` names argument {k}, but `{name}` has {} argument(s)",
                            crate::print::subscript(&k.to_string()),
                            args.len()
                        ),
                    ));
                }
                orders[k as usize - 1] += 1;
            }
            return Ok(Expr::apply(name, orders, args));
        }
        Err(self.err(&head, format!("unknown function `{name}`")).with_hint(format!(
            "for a product write `{name} (…)` or `{name}*(…)`; to use `{name}` as a function, declare it (for example `--functions {name}`)"
        )))
    }
}
