//! The reference pages the README points to: the scenario keys, the inputs, the outputs and
//! the commands; then notes on the method, its validation, its resolution and its
//! performance, in our own words. They hold no code. Figures are under
//! `tests/figures/` in the repository (the links are relative to this directory, so they
//! resolve where the Markdown files are read in the repository; rustdoc shows the text).

#[doc = include_str!("scenario.md")]
pub mod scenario {}

#[doc = include_str!("inputs.md")]
pub mod inputs {}

#[doc = include_str!("outputs.md")]
pub mod outputs {}

#[doc = include_str!("commands.md")]
pub mod commands {}

#[doc = include_str!("draw_control.md")]
pub mod draw_control {}

#[doc = include_str!("physics.md")]
pub mod physics {}

#[doc = include_str!("validation.md")]
pub mod validation {}

#[doc = include_str!("performance.md")]
pub mod performance {}

#[doc = include_str!("resolution.md")]
pub mod resolution {}

#[doc = include_str!("references.md")]
pub mod references {}
