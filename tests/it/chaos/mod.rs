//! Variational equations and chaos indicators (`src/chaos.rs`, scene `megno`/`lyapunov`/`fli`/`chaos_map`).

mod batch;
mod early_stop;
mod flow;
mod flow_statement;
mod indicators;
mod map_stop;
mod scene;
