//! Printing: plain text (which re-parses to the identical expression), Unicode and LaTeX.
//!
//! All three share one layout pass: a sum prints its constant last and its negative terms
//! with `−`; a product splits into numerator and denominator (`p_x^2/(2 m)`); `x^(1/2)`
//! prints as a square root. Only the spelling of symbols, operators and powers differs.

use std::fmt::Write;

use num_traits::{One, Signed};

use crate::expr::{Expr, Func, Node, Rational, Symbol};

/// The three renderings of an expression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// ASCII operators, primes for time derivatives; re-parses to the same expression.
    Plain,
    /// `θ̇`, `θ̈`, superscript powers, `√`.
    Unicode,
    /// LaTeX math: `\dot{\theta}`, `\frac`, `\sin`.
    Latex,
}

impl std::str::FromStr for Format {
    type Err = String;
    fn from_str(s: &str) -> Result<Format, String> {
        match s {
            "plain" => Ok(Format::Plain),
            "unicode" => Ok(Format::Unicode),
            "latex" => Ok(Format::Latex),
            other => Err(format!("unknown format `{other}` (expected plain, unicode or latex)")),
        }
    }
}

/// Renders `e` in the plain form.
pub fn plain(e: &Expr) -> String {
    render(e, Format::Plain)
}

/// A number for a message: the plain form when short, else the exact value in scientific
/// notation to four digits (`1e-400`, not a fraction with 400 zeros); other expressions plain.
pub fn short_number(e: &Expr) -> String {
    const SHORT: usize = 24;
    let text = plain(e);
    let Some(r) = e.as_num() else { return text };
    if text.len() <= SHORT {
        return text;
    }
    // Leading digits of numerator and denominator give the mantissa; their lengths the
    // exponent. Exact to the digits shown, whatever the size.
    let lead = |digits: &str| -> (f64, i64) {
        let head: f64 = digits[..digits.len().min(17)].parse().unwrap_or(f64::NAN);
        (head / 10f64.powi(digits.len().min(17) as i32 - 1), digits.len() as i64 - 1)
    };
    let numer = r.numer().to_string();
    let (sign, numer) = match numer.strip_prefix('-') {
        Some(n) => ("-", n.to_string()),
        None => ("", numer),
    };
    let (a, ea) = lead(&numer);
    let (b, eb) = lead(&r.denom().to_string());
    let (mut m, mut exp) = (a / b, ea - eb);
    if m < 1.0 {
        m *= 10.0;
        exp -= 1;
    }
    let mantissa = format!("{m:.3}");
    let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
    format!("{sign}{mantissa}e{exp}")
}

/// Renders `e` in the given format.
pub fn render(e: &Expr, format: Format) -> String {
    Printer { format }.expr(e).text
}

/// `text` with every control character written as `\u{1b}` instead of sent raw, for
/// diagnostics that echo the user's input: an escape sequence in an input (`\x1b[2J`) must
/// not clear the user's screen, and a NUL must not vanish. Newlines, tabs and the `\r` of a
/// `\r\n` pair stay. Coloured diagnostics add their own escapes after this.
pub fn escape_controls(text: &str) -> String {
    escape_controls_at(text, &mut [])
}

/// [`escape_controls`], also moving each byte offset of `offsets` (a diagnostic's span) to the
/// same place in the escaped text.
pub fn escape_controls_at(text: &str, offsets: &mut [usize]) -> String {
    let original: Vec<usize> = offsets.to_vec();
    let mut moved = vec![false; offsets.len()];
    let mut out = String::with_capacity(text.len());
    let mut chars = text.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        for (k, &o) in original.iter().enumerate() {
            if !moved[k] && o <= i {
                offsets[k] = out.len();
                moved[k] = true;
            }
        }
        let keep = matches!(c, '\n' | '\t') || (c == '\r' && chars.peek().map(|p| p.1) == Some('\n'));
        if c.is_control() && !keep {
            out.push_str(&format!("\\u{{{:x}}}", u32::from(c)));
        } else {
            out.push(c);
        }
    }
    for (k, m) in moved.iter().enumerate() {
        if !m {
            offsets[k] = out.len();
        }
    }
    out
}

/// Renders a symbol on its own (coordinate names in tables and JSON).
pub fn symbol(s: &Symbol, format: Format) -> String {
    Printer { format }.symbol(s)
}

// Binding strength of the printed form, lowest first.
const SUM: u8 = 1;
const PRODUCT: u8 = 2;
const UNARY: u8 = 3;
const POWER: u8 = 4;
const ATOM: u8 = 5;

struct Piece {
    text: String,
    prec: u8,
}

struct Printer {
    format: Format,
}

impl Printer {
    /// Recurses once per level of the expression; deep ones (a 300-deep tower of calls, a
    /// library-built chain) continue on a heap-allocated stack segment instead of overflowing.
    fn expr(&self, e: &Expr) -> Piece {
        stacker::maybe_grow(64 << 10, 1 << 20, || self.expr_here(e))
    }

    fn expr_here(&self, e: &Expr) -> Piece {
        match e.node() {
            Node::Num(r) => self.number(r),
            Node::Sym(s) => Piece { text: self.symbol(s), prec: ATOM },
            Node::Pi => Piece {
                text: match self.format {
                    Format::Plain => "pi",
                    Format::Unicode => "π",
                    Format::Latex => "\\pi",
                }
                .into(),
                prec: ATOM,
            },
            Node::Add(ts) => self.sum(ts),
            Node::Mul(_) | Node::Pow(..) => self.product(e),
            Node::Call(f, args) => Piece { text: self.call(*f, args), prec: ATOM },
            Node::Apply { name, orders, args } => Piece { text: self.apply(name, orders, args), prec: ATOM },
            Node::Undefined => Piece { text: "undefined".into(), prec: ATOM },
        }
    }

    fn wrap(&self, p: Piece, min: u8) -> String {
        if p.prec >= min {
            p.text
        } else if self.format == Format::Latex {
            format!("\\left({}\\right)", p.text)
        } else {
            format!("({})", p.text)
        }
    }

    fn number(&self, r: &Rational) -> Piece {
        let neg = r.is_negative();
        let a = r.abs();
        let text = if a.is_integer() {
            a.numer().to_string()
        } else if self.format == Format::Latex {
            format!("\\frac{{{}}}{{{}}}", a.numer(), a.denom())
        } else {
            format!("{}/{}", a.numer(), a.denom())
        };
        let prec = if a.is_integer() || self.format == Format::Latex { ATOM } else { PRODUCT };
        if neg {
            Piece { text: format!("-{text}"), prec: UNARY }
        } else {
            Piece { text, prec }
        }
    }

    fn symbol(&self, s: &Symbol) -> String {
        let primes = s.primes() as usize;
        match self.format {
            Format::Plain => format!("{}{}", s.name(), "'".repeat(primes)),
            Format::Unicode => {
                let mark = match primes {
                    0 => "",
                    1 => "\u{307}",
                    2 => "\u{308}",
                    3 => "\u{20db}",
                    _ => "",
                };
                if primes > 3 {
                    format!("{}{}", s.name(), "'".repeat(primes))
                } else {
                    // The combining dot goes on the first character (θ̇1, not θ1̇).
                    let mut chars = s.name().chars();
                    let first = chars.next().unwrap_or('?');
                    format!("{first}{mark}{}", chars.as_str())
                }
            }
            Format::Latex => {
                let core = latex_name(s.name());
                match primes {
                    0 => core,
                    1 => format!("\\dot{{{core}}}"),
                    2 => format!("\\ddot{{{core}}}"),
                    3 => format!("\\dddot{{{core}}}"),
                    n => format!("{core}^{{({n})}}"),
                }
            }
        }
    }

    fn sum(&self, ts: &[Expr]) -> Piece {
        // Constant last (`x + 1`, not `1 + x`), and a positive term first where there is one
        // (`1 - cos(θ)`, not `-cos(θ) + 1`).
        let mut order: Vec<&Expr> = ts.iter().filter(|t| t.as_num().is_none()).collect();
        order.extend(ts.iter().filter(|t| t.as_num().is_some()));
        if let Some(i) = order.iter().position(|t| !t.is_negative_form()) {
            let lead = order.remove(i);
            order.insert(0, lead);
        }
        let mut out = String::new();
        for (i, t) in order.into_iter().enumerate() {
            let negative = t.is_negative_form();
            let body = if negative { t.neg() } else { t.clone() };
            let text = self.wrap(self.expr(&body), PRODUCT);
            match (i, negative) {
                (0, false) => out.push_str(&text),
                (0, true) => {
                    out.push('-');
                    out.push_str(&text);
                }
                (_, false) => {
                    out.push_str(" + ");
                    out.push_str(&text);
                }
                (_, true) => {
                    out.push_str(" - ");
                    out.push_str(&text);
                }
            }
        }
        Piece { text: out, prec: SUM }
    }

    /// Products and powers: coefficient and positive powers above, negative powers below.
    fn product(&self, e: &Expr) -> Piece {
        let (coeff, rest) = e.coeff_rest();
        if coeff.is_negative() {
            let inner = self.product(&Expr::mul([Expr::num(-coeff), rest]));
            let text = format!("-{}", self.wrap(inner, PRODUCT));
            return Piece { text, prec: UNARY };
        }
        let mut numer: Vec<Piece> = Vec::new();
        let mut denom: Vec<Piece> = Vec::new();
        // Sums among the factors: a rational times a lone sum distributes when it is built
        // (`2 (x + 1)` is `2 x + 2`), so plain output must never spell such a product.
        let (mut numer_sums, mut denom_sums) = (Vec::new(), Vec::new());
        let (mut numer_other, mut denom_other) = (0usize, 0usize);
        for f in rest.factors() {
            let (b, x) = f.base_exp();
            let is_sum = matches!(b.node(), Node::Add(_));
            if x.is_negative_form() {
                let x = x.neg();
                if is_sum && x.is_one() {
                    denom_sums.push(self.power(&b, &x));
                } else {
                    denom_other += 1;
                    denom.push(self.power(&b, &x));
                }
            } else if is_sum && x.is_one() {
                numer_sums.push(self.power(&b, &x));
            } else {
                numer_other += 1;
                numer.push(self.power(&b, &x));
            }
        }
        let n_text = coeff.numer().to_string();
        let d_text = coeff.denom().to_string();
        let plain = self.format == Format::Plain;
        // `n (a + b) (c + d)` would distribute `n` over the first sum on re-parsing:
        // group the sums, `n ((a + b) (c + d))`; a lone sum goes last, after the division.
        let coeff_on_sums = plain && !coeff.numer().is_one() && numer_other == 0 && !numer_sums.is_empty();
        let lone_sum_last = coeff_on_sums && numer_sums.len() == 1;
        // `1/1000 (a + b)/(c + d)` would distribute `1/1000` over `a + b` on re-parsing: when
        // the numerator is only sums, a coefficient `1/q` goes last, `(a + b)/(c + d)/1000`
        // (found by tests/it/robust/fuzz.rs).
        let coeff_trails = plain
            && coeff.numer().is_one()
            && !coeff.denom().is_one()
            && numer_other == 0
            && !numer_sums.is_empty()
            && denom_other == 0
            && !denom_sums.is_empty();
        // `1/(2 (x + 1))` likewise: the coefficient stays in front, `1/2/(x + 1)`.
        let coeff_under_sums =
            plain && !coeff_trails && !coeff.denom().is_one() && denom_other == 0 && !denom_sums.is_empty();
        let mut trailing = Vec::new();
        if coeff_on_sums {
            if lone_sum_last {
                trailing = numer_sums.split_off(0);
            } else {
                let grouped = self.join_factors(numer_sums.split_off(0));
                numer.push(Piece { text: format!("({grouped})"), prec: ATOM });
            }
        }
        if coeff_under_sums {
            // The whole coefficient leads, as physicists write it: `1/2 p^2/(m1 + m2)`.
            numer.insert(0, Piece { text: format!("{n_text}/{d_text}"), prec: ATOM });
        } else if !coeff.numer().is_one() || rest.is_one() || (numer.is_empty() && numer_sums.is_empty()) {
            let text = if coeff.numer().is_one() && !rest.is_one() { "1".to_string() } else { n_text };
            numer.insert(0, Piece { text, prec: ATOM });
        }
        numer.extend(numer_sums);
        if !coeff.denom().is_one() && !coeff_under_sums && !coeff_trails {
            denom.insert(0, Piece { text: d_text.clone(), prec: ATOM });
        }
        denom.extend(denom_sums);
        // `join_factors` parenthesises pieces that bind looser than a power, so a lone piece
        // that was wrapped is an atom afterwards (wrapping it again printed `1/((x + 1))`).
        let joined_prec = |pieces: &[Piece]| match pieces {
            [one] if one.prec < POWER => ATOM,
            [one] => one.prec,
            _ => PRODUCT,
        };
        let numer_prec = joined_prec(&numer);
        let mut text = self.join_factors(numer);
        let mut prec = numer_prec;
        if !denom.is_empty() {
            let den_prec = joined_prec(&denom);
            let den_text = self.join_factors(denom);
            text = match self.format {
                Format::Latex => format!("\\frac{{{text}}}{{{den_text}}}"),
                _ => {
                    let den = self.wrap(Piece { text: den_text, prec: den_prec }, POWER);
                    format!("{text}/{den}")
                }
            };
            prec = if self.format == Format::Latex { ATOM } else { PRODUCT };
        }
        if coeff_trails {
            text = format!("{text}/{d_text}");
            prec = PRODUCT;
        }
        if !trailing.is_empty() {
            text = format!("{text} {}", self.join_factors(trailing));
            prec = PRODUCT;
        }
        Piece { text, prec }
    }

    fn join_factors(&self, pieces: Vec<Piece>) -> String {
        let mut out = String::new();
        for (i, p) in pieces.into_iter().enumerate() {
            let text = self.wrap(p, POWER);
            if i > 0 {
                let starts_numeric = text.starts_with(|c: char| c.is_ascii_digit() || c == '.');
                let sep = match (self.format, starts_numeric) {
                    (Format::Plain, true) => "*",
                    (Format::Unicode, true) => "·",
                    (Format::Latex, true) => " \\cdot ",
                    _ => " ",
                };
                out.push_str(sep);
            }
            out.push_str(&text);
        }
        out
    }

    /// `b^x` with a non-negative-form exponent.
    fn power(&self, b: &Expr, x: &Expr) -> Piece {
        if x.is_one() {
            return self.expr(b);
        }
        if x.as_num().is_some_and(|r| *r == Rational::new(1.into(), 2.into())) {
            let inner = self.expr(b);
            let text = match self.format {
                Format::Plain => format!("sqrt({})", inner.text),
                Format::Unicode => format!("√{}", self.wrap(inner, ATOM)),
                Format::Latex => format!("\\sqrt{{{}}}", inner.text),
            };
            return Piece { text, prec: ATOM };
        }
        let base = self.wrap(self.expr(b), ATOM);
        let text = match (self.format, x.as_num()) {
            (Format::Unicode, Some(r)) if r.is_integer() => format!("{base}{}", superscript(&r.numer().to_string())),
            (Format::Latex, _) => format!("{base}^{{{}}}", self.expr(x).text),
            _ => format!("{base}^{}", self.wrap(self.expr(x), POWER)),
        };
        Piece { text, prec: POWER }
    }

    fn call(&self, f: Func, args: &[Expr]) -> String {
        let parts: Vec<String> = args.iter().map(|a| self.expr(a).text).collect();
        let joined = parts.join(", ");
        match self.format {
            Format::Latex => match f.spec().latex {
                Some(cmd) => format!("{cmd}\\left({joined}\\right)"),
                None => format!("\\left|{joined}\\right|"),
            },
            _ => format!("{}({joined})", f.name()),
        }
    }

    fn apply(&self, name: &str, orders: &[u32], args: &[Expr]) -> String {
        let parts: Vec<String> = args.iter().map(|a| self.expr(a).text).collect();
        let joined = parts.join(", ");
        let total: u32 = orders.iter().sum();
        let latex = self.format == Format::Latex;
        let fname = if latex { latex_name(name) } else { name.to_string() };
        let (open, close) = if latex { ("\\left(", "\\right)") } else { ("(", ")") };
        if total == 0 {
            return format!("{fname}{open}{joined}{close}");
        }
        if args.len() == 1 {
            let primes = "'".repeat(total as usize);
            return format!("{fname}{primes}{open}{joined}{close}");
        }
        let mut head = String::new();
        for (i, &n) in orders.iter().enumerate() {
            for _ in 0..n {
                if latex {
                    let _ = write!(head, "\\partial_{{{}}}", i + 1);
                } else {
                    head.push('∂');
                    head.push_str(&subscript(&(i + 1).to_string()));
                }
            }
        }
        format!("{head}{fname}{open}{joined}{close}")
    }
}

fn superscript(digits: &str) -> String {
    digits
        .chars()
        .map(|c| match c {
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            '9' => '⁹',
            '-' => '⁻',
            other => other,
        })
        .collect()
}

/// Subscript digits, as used by `∂₁` in the grammar.
pub fn subscript(digits: &str) -> String {
    digits.chars().map(|c| c.to_digit(10).and_then(|d| char::from_u32(0x2080 + d)).unwrap_or(c)).collect()
}

const GREEK: [(char, &str); 48] = [
    ('α', "alpha"),
    ('β', "beta"),
    ('γ', "gamma"),
    ('δ', "delta"),
    ('ε', "epsilon"),
    ('ζ', "zeta"),
    ('η', "eta"),
    ('θ', "theta"),
    ('ι', "iota"),
    ('κ', "kappa"),
    ('λ', "lambda"),
    ('μ', "mu"),
    ('ν', "nu"),
    ('ξ', "xi"),
    ('ο', "o"),
    ('π', "pi"),
    ('ρ', "rho"),
    ('σ', "sigma"),
    ('τ', "tau"),
    ('υ', "upsilon"),
    ('φ', "phi"),
    ('χ', "chi"),
    ('ψ', "psi"),
    ('ω', "omega"),
    ('Α', "A"),
    ('Β', "B"),
    ('Γ', "\\Gamma"),
    ('Δ', "\\Delta"),
    ('Ε', "E"),
    ('Ζ', "Z"),
    ('Η', "H"),
    ('Θ', "\\Theta"),
    ('Ι', "I"),
    ('Κ', "K"),
    ('Λ', "\\Lambda"),
    ('Μ', "M"),
    ('Ν', "N"),
    ('Ξ', "\\Xi"),
    ('Ο', "O"),
    ('Π', "\\Pi"),
    ('Ρ', "P"),
    ('Σ', "\\Sigma"),
    ('Τ', "T"),
    ('Υ', "\\Upsilon"),
    ('Φ', "\\Phi"),
    ('Χ', "X"),
    ('Ψ', "\\Psi"),
    ('Ω', "\\Omega"),
];

/// `θ1` → `\theta_{1}`, `p_x` → `p_{x}`, `omega0` → `omega_{0}`.
fn latex_name(name: &str) -> String {
    let (stem, sub) = match name.find('_') {
        Some(i) => (&name[..i], Some(&name[i + 1..])),
        None => {
            let cut = name.trim_end_matches(|c: char| c.is_ascii_digit()).len();
            if cut > 0 && cut < name.len() {
                (&name[..cut], Some(&name[cut..]))
            } else {
                (name, None)
            }
        }
    };
    let mut out = String::new();
    for c in stem.chars() {
        match GREEK.iter().find(|(g, _)| *g == c) {
            Some((_, tex)) if tex.starts_with('\\') => out.push_str(tex),
            Some((_, tex)) if tex.len() > 1 => {
                out.push('\\');
                out.push_str(tex);
            }
            Some((_, tex)) => out.push_str(tex),
            None => out.push(c),
        }
        if !c.is_ascii() && stem.chars().count() > 1 {
            out.push(' ');
        }
    }
    let out = out.trim_end().to_string();
    let out = if stem.chars().count() > 1 && stem.chars().all(|c| c.is_ascii_alphabetic()) {
        format!("\\mathrm{{{out}}}")
    } else {
        out
    };
    match sub {
        Some(s) if !s.is_empty() => format!("{out}_{{{}}}", latex_name(s)),
        _ => out,
    }
}

// An expression shows as its plain form, which re-parses to it: the printer owns how an
// expression looks, so the core type knows nothing of printing.
impl std::fmt::Debug for Expr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&plain(self))
    }
}

impl std::fmt::Display for Expr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&plain(self))
    }
}

/// A number for messages: short, deterministic. Whole numbers below 10¹⁵ as integers; other
/// numbers from 10⁻⁴ to 10¹⁵ to six decimals (so `0.1 + 0.2` reads `0.3`), or in full when six
/// decimals would hide that they are not whole (`1.0000001`, not `1.`); anything larger or
/// smaller in scientific notation (`1e308`, not 309 digits; `2.5e-7`, not `0.`).
pub fn fmt_num(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == x.trunc() && x.abs() < 1e15 {
        return format!("{x:.0}");
    }
    if !(1e-4..1e15).contains(&x.abs()) {
        return format!("{x:e}");
    }
    let s = format!("{x:.6}");
    let s = s.trim_end_matches('0');
    if s.ends_with('.') {
        format!("{x}")
    } else {
        s.to_string()
    }
}
