//! The built-in functions of the grammar, each described once in [`SPECS`]: its name, arity,
//! float value, derivative, the exact facts `Expr::call` folds in (parity, value at 0 or 1),
//! and its LaTeX and SymPy names. Parsing, printing, numeric evaluation, differentiation and the
//! Python SymPy bridge read this table, so a new function's knowledge lives in one row. Code that
//! genuinely needs per-function code (the tape lowering's shared `sin_cos`, the Taylor
//! recurrences in `compile::taylor`, the egg rewrites in `simplify`) still matches on [`Func`],
//! exhaustively where a new function must be handled.
//!
//! `sqrt` is not here: it is the power `x^(1/2)`.

/// A built-in function. The discriminant indexes [`SPECS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Func {
    Sin,
    Cos,
    Tan,
    Exp,
    Log,
    Sinh,
    Cosh,
    Tanh,
    Asin,
    Acos,
    Atan,
    Atan2,
    Abs,
    Asinh,
    Acosh,
    Atanh,
    Sec,
    Csc,
    Coth,
    Erf,
}

/// How `f(-x)` relates to `f(x)`; `Expr::call` folds a negative argument out with it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Parity {
    /// `f(-x) = -f(x)`.
    Odd,
    /// `f(-x) = f(x)`.
    Even,
    /// Neither, or folded by code of its own (`abs`).
    None,
}

/// Everything the engine knows about one built-in function that is data rather than code.
pub struct Spec {
    /// The name as written in the grammar and printed in plain and Unicode forms.
    pub name: &'static str,
    /// How many arguments it takes.
    pub arity: usize,
    /// The value on floats (`args.len() == arity`).
    pub eval: fn(&[f64]) -> f64,
    /// `∂f/∂u`, written in the grammar's notation in the (first) argument `u` (`"cos(u)"`);
    /// `diff` parses each once and substitutes the argument. `None` for functions of two
    /// arguments, which `diff` handles by their gradient. Text rather than code keeps this
    /// table below the expression type `Expr`, which imports it (for
    /// `Expr::call`'s folds), while the table imports nothing.
    pub derivative: Option<&'static str>,
    /// Symmetry under `u → -u`.
    pub parity: Parity,
    /// The exact value at `u = 0`, when it is an integer.
    pub at_zero: Option<i64>,
    /// The exact value at `u = 1`, when it is an integer.
    pub at_one: Option<i64>,
    /// The LaTeX command, applied as `cmd\left(args\right)`; `None` for `abs`, printed as bars.
    pub latex: Option<&'static str>,
    /// The SymPy function of the same meaning.
    pub sympy: &'static str,
    /// The function the JIT back ends call for a one-argument instruction: it computes exactly
    /// what [`Spec::eval`] does, so compiled and interpreted code return the same bits. `None`
    /// for `abs` (one native instruction) and `atan2` (lowered as its own instruction).
    pub native: Option<extern "C" fn(f64) -> f64>,
}

/// An `extern "C"` wrapper of the `f64` method `$m`, for [`Spec::native`].
macro_rules! native {
    ($m:ident) => {{
        extern "C" fn wrapper(x: f64) -> f64 {
            f64::$m(x)
        }
        Some(wrapper as extern "C" fn(f64) -> f64)
    }};
    (recip $m:ident) => {{
        extern "C" fn wrapper(x: f64) -> f64 {
            1.0 / f64::$m(x)
        }
        Some(wrapper as extern "C" fn(f64) -> f64)
    }};
}

/// One row per [`Func`], in declaration order (checked by a unit test).
pub const SPECS: [Spec; 20] = [
    Spec {
        name: "sin",
        arity: 1,
        eval: |a| a[0].sin(),
        derivative: Some("cos(u)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        latex: Some("\\sin"),
        sympy: "sin",
        native: native!(sin),
    },
    Spec {
        name: "cos",
        arity: 1,
        eval: |a| a[0].cos(),
        derivative: Some("-sin(u)"),
        parity: Parity::Even,
        at_zero: Some(1),
        at_one: None,
        latex: Some("\\cos"),
        sympy: "cos",
        native: native!(cos),
    },
    Spec {
        name: "tan",
        arity: 1,
        eval: |a| a[0].tan(),
        derivative: Some("cos(u)^(-2)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        latex: Some("\\tan"),
        sympy: "tan",
        native: native!(tan),
    },
    Spec {
        name: "exp",
        arity: 1,
        eval: |a| a[0].exp(),
        derivative: Some("exp(u)"),
        parity: Parity::None,
        at_zero: Some(1),
        at_one: None,
        latex: Some("\\exp"),
        sympy: "exp",
        native: native!(exp),
    },
    Spec {
        name: "log",
        arity: 1,
        eval: |a| a[0].ln(),
        derivative: Some("u^(-1)"),
        parity: Parity::None,
        at_zero: None,
        at_one: Some(0),
        latex: Some("\\log"),
        sympy: "log",
        native: native!(ln),
    },
    Spec {
        name: "sinh",
        arity: 1,
        eval: |a| a[0].sinh(),
        derivative: Some("cosh(u)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        latex: Some("\\sinh"),
        sympy: "sinh",
        native: native!(sinh),
    },
    Spec {
        name: "cosh",
        arity: 1,
        eval: |a| a[0].cosh(),
        derivative: Some("sinh(u)"),
        parity: Parity::Even,
        at_zero: Some(1),
        at_one: None,
        latex: Some("\\cosh"),
        sympy: "cosh",
        native: native!(cosh),
    },
    Spec {
        name: "tanh",
        arity: 1,
        eval: |a| a[0].tanh(),
        derivative: Some("cosh(u)^(-2)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        latex: Some("\\tanh"),
        sympy: "tanh",
        native: native!(tanh),
    },
    Spec {
        name: "asin",
        arity: 1,
        eval: |a| a[0].asin(),
        derivative: Some("(1 - u^2)^(-1/2)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        latex: Some("\\arcsin"),
        sympy: "asin",
        native: native!(asin),
    },
    Spec {
        name: "acos",
        arity: 1,
        eval: |a| a[0].acos(),
        derivative: Some("-(1 - u^2)^(-1/2)"),
        parity: Parity::None,
        at_zero: None,
        at_one: Some(0),
        latex: Some("\\arccos"),
        sympy: "acos",
        native: native!(acos),
    },
    Spec {
        name: "atan",
        arity: 1,
        eval: |a| a[0].atan(),
        derivative: Some("(1 + u^2)^(-1)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        latex: Some("\\arctan"),
        sympy: "atan",
        native: native!(atan),
    },
    Spec {
        name: "atan2",
        arity: 2,
        eval: |a| a[0].atan2(a[1]),
        derivative: None,
        parity: Parity::None,
        at_zero: None,
        at_one: None,
        latex: Some("\\operatorname{atan2}"),
        sympy: "atan2",
        native: None,
    },
    Spec {
        name: "abs",
        arity: 1,
        eval: |a| a[0].abs(),
        // d|u|/du = |u|/u, defined wherever u ≠ 0.
        derivative: Some("abs(u)/u"),
        parity: Parity::None,
        at_zero: None,
        at_one: None,
        latex: None,
        sympy: "Abs",
        native: None,
    },
    Spec {
        name: "asinh",
        arity: 1,
        eval: |a| a[0].asinh(),
        derivative: Some("(1 + u^2)^(-1/2)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        // What SymPy's `latex()` prints; there is no `\asinh` command.
        latex: Some("\\operatorname{asinh}"),
        sympy: "asinh",
        native: native!(asinh),
    },
    Spec {
        name: "acosh",
        arity: 1,
        // NaN below 1, as `log` is below 0: the real branch only.
        eval: |a| a[0].acosh(),
        derivative: Some("(u^2 - 1)^(-1/2)"),
        parity: Parity::None,
        at_zero: None,
        at_one: Some(0),
        latex: Some("\\operatorname{acosh}"),
        sympy: "acosh",
        native: native!(acosh),
    },
    Spec {
        name: "atanh",
        arity: 1,
        // NaN outside [−1, 1], ±∞ at ±1.
        eval: |a| a[0].atanh(),
        derivative: Some("(1 - u^2)^(-1)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        latex: Some("\\operatorname{atanh}"),
        sympy: "atanh",
        native: native!(atanh),
    },
    Spec {
        name: "sec",
        arity: 1,
        // The reciprocal, as the Taylor recurrence computes it (`1/cos`), bit for bit.
        eval: |a| 1.0 / a[0].cos(),
        derivative: Some("sec(u) tan(u)"),
        parity: Parity::Even,
        at_zero: Some(1),
        at_one: None,
        latex: Some("\\sec"),
        sympy: "sec",
        native: native!(recip cos),
    },
    Spec {
        name: "csc",
        arity: 1,
        eval: |a| 1.0 / a[0].sin(),
        // −csc u cot u = −cos u / sin² u.
        derivative: Some("-csc(u)^2 cos(u)"),
        parity: Parity::Odd,
        at_zero: None,
        at_one: None,
        latex: Some("\\csc"),
        sympy: "csc",
        native: native!(recip sin),
    },
    Spec {
        name: "coth",
        arity: 1,
        // `1/tanh` rather than `cosh/sinh`, which is ∞/∞ = NaN for |u| above about 710.
        eval: |a| 1.0 / a[0].tanh(),
        derivative: Some("-sinh(u)^(-2)"),
        parity: Parity::Odd,
        at_zero: None,
        at_one: None,
        latex: Some("\\coth"),
        sympy: "coth",
        native: native!(recip tanh),
    },
    Spec {
        name: "erf",
        arity: 1,
        eval: |a| libm::erf(a[0]),
        // 2/√π · e^(−u²), with the exact π.
        derivative: Some("2 pi^(-1/2) exp(-u^2)"),
        parity: Parity::Odd,
        at_zero: Some(0),
        at_one: None,
        latex: Some("\\operatorname{erf}"),
        sympy: "erf",
        native: {
            extern "C" fn wrapper(x: f64) -> f64 {
                libm::erf(x)
            }
            Some(wrapper as extern "C" fn(f64) -> f64)
        },
    },
];

impl Func {
    /// Every built-in function, in declaration order.
    pub const ALL: [Func; 20] = [
        Func::Sin,
        Func::Cos,
        Func::Tan,
        Func::Exp,
        Func::Log,
        Func::Sinh,
        Func::Cosh,
        Func::Tanh,
        Func::Asin,
        Func::Acos,
        Func::Atan,
        Func::Atan2,
        Func::Abs,
        Func::Asinh,
        Func::Acosh,
        Func::Atanh,
        Func::Sec,
        Func::Csc,
        Func::Coth,
        Func::Erf,
    ];

    /// This function's row of [`SPECS`].
    pub fn spec(self) -> &'static Spec {
        &SPECS[self as usize]
    }

    /// The name as written in the grammar.
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// Looks a built-in up by name.
    pub fn from_name(name: &str) -> Option<Func> {
        Func::ALL.into_iter().find(|f| f.name() == name)
    }

    /// How many arguments the function takes.
    pub fn arity(self) -> usize {
        self.spec().arity
    }

    /// Evaluates the function on floats.
    pub fn eval(self, args: &[f64]) -> f64 {
        (self.spec().eval)(args)
    }
}
