//! `help`: every statement with its form, what it does and an example (the examples are
//! parsed by a test, so they stay valid).

use super::syntax::error::did_you_mean;

pub use super::registry::{Topic, REGISTRY as TOPICS};

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
                Some(t) if t.word == "simulate" => {
                    let methods: Vec<String> =
                        crate::simulate::method::method_table().iter().map(|l| format!("    {l}")).collect();
                    format!("{}\n  {}\n  example: {}\n  methods:\n{}", t.form, t.about, t.example, methods.join("\n"))
                }
                Some(t) => format!("{}\n  {}\n  example: {}", t.form, t.about, t.example),
                None => match did_you_mean(w, TOPICS.iter().map(|t| t.word)) {
                    Some(s) => format!("no help for `{w}`; did you mean `{s}`?"),
                    None => format!("no help for `{w}`; `help` lists the statements"),
                },
            }
        }
    }
}
