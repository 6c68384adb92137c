//! The one integration-test binary (ripgrep/polars style): one module per layer.

// As in the crate: `!(x <= tol)` fails on NaN as well as on a value beyond the tolerance.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(feature = "analysis")]
mod backanalysis;
mod balance;
mod calibration;
mod cli;
mod dataset;
mod demo;
mod determinism;
mod draw_control;
mod engine;
mod fixtures;
mod fuzz;
mod io;
mod io_rules;
mod layering;
mod marker_pass;
mod massflow;
mod mechanisms;
mod newcomer;
mod output;
mod plan;
mod props;
mod records;
mod report;
mod rilling;
mod scenario_rules;
mod short_reasons;
mod stability;
mod stress;
mod study;
mod study_ray;
mod surface_cone;
mod sweep;
mod synthetic_records;
mod trace;
mod vanishing_jump;
mod vtk;
mod walls;
