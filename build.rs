//! Writes `is_kw`'s body from the scene grammar: every rule named `kw_…` in `grammar/*.pest` is
//! a keyword, whose pair the statements' readers skip (`scene::syntax::parser::is_kw`). Deriving
//! the list here means a keyword rule added to the grammar needs no second edit, and the parser
//! never classifies rules by their names at run time. Only `std`: the script must stay cheap.

use std::fmt::Write as _;

const GRAMMARS: [&str; 2] = ["grammar/expr.pest", "grammar/scene.pest"];

fn main() {
    let root = std::path::PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let mut names = Vec::new();
    for path in GRAMMARS {
        println!("cargo:rerun-if-changed={path}");
        let text = std::fs::read_to_string(root.join(path)).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
        names.extend(keyword_rules(&text));
    }
    let mut body = String::from("matches!(rule, ");
    for (i, name) in names.iter().enumerate() {
        let sep = if i == 0 { "" } else { " | " };
        write!(body, "{sep}Rule::{name}").unwrap();
    }
    body.push(')');
    if names.is_empty() {
        body = "{ let _ = rule; false }".to_string();
    }
    let out = std::path::Path::new(&std::env::var("OUT_DIR").unwrap()).join("keyword_rules.rs");
    std::fs::write(&out, body).unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
}

/// The names of the rules a grammar defines that start with `kw_`: a line `kw_NAME = …`
/// (pest rule names are ASCII letters, digits and `_`; a definition starts its line).
fn keyword_rules(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim_start();
        let name: String = line.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
        if name.starts_with("kw_") && line[name.len()..].trim_start().starts_with('=') {
            out.push(name);
        }
    }
    out
}
