//! `help`: every statement with its form, what it does and an example (the examples are
//! parsed by a test, so they stay valid).

use super::error::did_you_mean;

/// One statement's help: keyword, form, description, example.
pub struct Topic {
    /// The keyword.
    pub word: &'static str,
    /// The statement's form.
    pub form: &'static str,
    /// What it does.
    pub about: &'static str,
    /// A complete example statement.
    pub example: &'static str,
}

/// Every topic, in the order `help` lists them.
pub const TOPICS: &[Topic] = &[
    Topic { word: "coordinates", form: "coordinates q1, q2, …", about: "declares the generalized coordinates; `q'` is the velocity of `q`, `p_q` its momentum", example: "coordinates θ" },
    Topic { word: "parameters", form: "parameters a = VALUE, b, … [positive]", about: "declares constants, with optional values (needed to simulate); `positive` applies to all of them", example: "parameters m = 1, l = 1, g = 9.81 positive" },
    Topic { word: "functions", form: "functions V, …", about: "declares undefined functions such as a general potential `V(r)`; `V'(r)` is its derivative", example: "functions V" },
    Topic { word: "define", form: "NAME = EXPRESSION | NAME = el(L) | legendre(L) | hamilton(H) | conserved(L) | pb(f, g) | energy(L)", about: "defines `L`, `H` or any named expression; derivations on the right are computed only when an output needs them", example: "L = 1/2 m l^2 θ'^2 - m g l (1 - cos(θ))" },
    Topic { word: "el", form: "el [as FORMAT]", about: "prints the Euler–Lagrange equations E_i = d/dt ∂L/∂q'_i − ∂L/∂q_i = 0", example: "el" },
    Topic { word: "legendre", form: "legendre [as FORMAT]", about: "prints the Hamiltonian H(q, p) obtained from L by the Legendre transform", example: "legendre" },
    Topic { word: "hamilton", form: "hamilton [as FORMAT]", about: "prints Hamilton's equations q' = ∂H/∂p, p' = −∂H/∂q (H from `H = …` or from L)", example: "hamilton" },
    Topic { word: "conserved", form: "conserved [as FORMAT]", about: "prints the conserved quantities (ignorable coordinates, energy) with the reason for each", example: "conserved" },
    Topic { word: "pb", form: "pb f, g", about: "prints the Poisson bracket {f, g} = Σ ∂f/∂q ∂g/∂p − ∂f/∂p ∂g/∂q", example: "pb θ, p_θ" },
    Topic { word: "energy", form: "energy", about: "prints the energy function h = Σ q' ∂L/∂q' − L (or H)", example: "energy" },
    Topic { word: "print", form: "print ITEM, … [as plain|unicode|latex]", about: "prints expressions, definitions or derivations", example: "print L as latex" },
    Topic { word: "simulate", form: "simulate q = …, q' = … for t in A..B [with METHOD] [dt = … | steps = … | tol = …] [record|stop when EXPR [= EXPR] [rising|falling]] [as NAME]", about: "integrates the equations of motion. Methods: leapfrog, verlet, yoshida4, yoshida6, yoshida8, blanes_moan, symplectic_euler (splitting: need H = T(p) + V(q)), midpoint, gauss4, gauss6 (implicit, symplectic), euler, rk4 (explicit), dop853 (adaptive, default). Velocities are turned into momenta through L when the method integrates H", example: "simulate θ = 3.0, θ' = 0 for t in 0..20 with gauss6 dt = 0.01" },
    Topic { word: "plot", form: "plot phase [q] | energy | path x, y | poincare x, y | EXPR, … vs t  [from RUN, …] [to FILE.svg|FILE.png]", about: "draws a phase portrait (with contours of H for one coordinate: O and X points and the separatrix), the relative energy error, a configuration-space path, a Poincaré section or time series", example: "plot phase to pendulum_phase.svg" },
    Topic { word: "export", form: "export [ITEM, …] [from RUN] to FILE.csv|FILE.json", about: "writes a run's state (or expressions along it) as CSV or JSON, or derived equations as JSON", example: "export t, θ, θ' to pendulum.csv" },
    Topic { word: "load", form: "load FILE", about: "runs the statements of a scene file in this session", example: "load examples/pendulum.scene" },
    Topic { word: "format", form: "format plain|unicode|latex", about: "sets the default output format (Unicode at start)", example: "format latex" },
    Topic { word: "latex", form: "latex | unicode | plain", about: "reprints the last result in that format", example: "latex" },
    Topic { word: "history", form: "history", about: "lists the remembered input lines (REPL)", example: "history" },
    Topic { word: "help", form: "help [STATEMENT]", about: "this help", example: "help simulate" },
];

/// The help text for `word`, or the overview.
pub fn help(word: Option<&str>) -> String {
    match word {
        None => {
            let mut s = String::from("statements (`help NAME` for details):\n");
            for t in TOPICS {
                s.push_str(&format!("  {:<12} {}\n", t.word, t.form));
            }
            s.push_str("`#` starts a comment; a statement continues on the next line while a bracket is open, after a trailing operator, or on an indented line.");
            s
        }
        Some(w) => {
            let w = if ["plain", "unicode"].contains(&w) { "latex" } else { w };
            let found = TOPICS.iter().find(|t| t.word == w || (t.word == "define" && ["L", "H", "="].contains(&w)));
            match found {
                Some(t) => format!("{}\n  {}\n  example: {}", t.form, t.about, t.example),
                None => match did_you_mean(w, TOPICS.iter().map(|t| t.word)) {
                    Some(s) => format!("no help for `{w}`; did you mean `{s}`?"),
                    None => format!("no help for `{w}`; `help` lists the statements"),
                },
            }
        }
    }
}
