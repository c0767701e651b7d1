//! The scene language as text: the pieces several statements share ([`ast`]: sources,
//! derivation calls, the `simulate` options; each statement file under `statements/` holds its
//! own type and reader), the parser over `grammar/scene.pest` and the `Reader` every statement
//! reads its pairs with ([`parser`]), a scene file as read ([`source`]: size limit, UTF-8,
//! line breaks, look-alike characters), and the errors every stage reports with a span
//! ([`error`]). Which rule is which statement is the registry's (`scene/registry.rs`), handed
//! to the parser; nothing here imports a statement or runs one.

pub mod ast;
pub mod error;
pub mod parser;
pub mod source;
