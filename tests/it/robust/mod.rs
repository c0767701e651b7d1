//! Bad input, budgets, interrupts, I/O at the edges, scaling, memory and fuzzing: nothing panics, hangs or is silently wrong.

mod bad_input;
mod budgets;
mod fuzz;
mod interrupt;
mod io;
mod roundtrip;
mod terminate;
mod unclear;
mod values;
