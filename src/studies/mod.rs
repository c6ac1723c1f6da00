//! Studies that train policies or predictors and then evaluate them (the top layer): the
//! lambda x alpha sweep and the downstream prediction study. `eval` only evaluates.

pub mod downstream;
pub mod sweep;
