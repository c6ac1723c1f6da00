//! One module per `rtr` subcommand: its arguments and its handler, `run`.

pub mod animate;
pub mod args;
pub mod bench;
pub mod curate;
pub mod data;
pub mod downstream;
pub mod eval;
pub mod map;
pub mod model;
pub mod probe;
pub mod recordings;
pub mod render;
pub mod scenarios;
pub mod sim2real;
pub mod sweep;
pub mod train;
