//! The one integration-test binary (ripgrep/polars style): one module per layer.

mod cli;
mod engine;
mod io;
mod mechanisms;
mod output;
mod props;
mod rilling;
mod stability;
mod stress;
mod surface_cone;
mod sweep;
