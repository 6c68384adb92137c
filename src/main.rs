//! The `caveflow` binary: a thin shell over [`caveflow::cli`].

use std::process::ExitCode;

fn main() -> ExitCode {
    match caveflow::cli::main() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", caveflow::cli::error_text(e.as_ref()));
            ExitCode::from(2)
        }
    }
}
