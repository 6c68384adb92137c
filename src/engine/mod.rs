//! The REBOP flow engine. One module per mechanism.

pub mod result;
