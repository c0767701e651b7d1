//! The expression core: the tree and its constructors, the built-in function table, differentiation.

mod diff;
mod func;
mod tree;
