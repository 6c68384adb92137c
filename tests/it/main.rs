//! The one integration-test binary (ripgrep/polars style): one module per layer.

mod cli;
mod engine;
mod io;
mod output;
mod props;
mod stability;
