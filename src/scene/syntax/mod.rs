//! The scene language as text: its statements ([`ast`]), the parser over `grammar/scene.pest`
//! ([`parser`]), the errors every stage reports with a span ([`error`]) and the `help` topics
//! ([`help`]), all derived from the statement [`registry`]. Nothing here runs a statement.

pub mod ast;
pub mod error;
pub mod help;
pub mod parser;
pub mod registry;
