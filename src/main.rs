//! The `caveflow` binary: a thin shell over [`caveflow::cli`].

use std::process::ExitCode;

fn main() -> ExitCode {
    match caveflow::cli::main() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
