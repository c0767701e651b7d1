//! The expression language's parse-time features (`src/parse.rs`, `grammar/expr.pest`).

mod indexed;
mod syntax;
