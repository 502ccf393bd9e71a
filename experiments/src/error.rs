//! Errors of the command-line tool and their exit codes.

use std::fmt;

/// An error that ends the program with a message and an exit code.
#[derive(Debug)]
pub struct CliError {
    message: String,
    code: u8,
}

impl CliError {
    /// Bad input (file, CSV, scene, option value): exit code 2.
    pub fn input(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: 2,
        }
    }

    /// Failure of the run itself (library, I/O): exit code 1.
    pub fn runtime(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: 1,
        }
    }

    /// A resumed run that has already reached its scene's end: nothing is
    /// wrong, but nothing was run either; exit code 3, so that a job that
    /// requeues itself can tell a finished run from a failed one.
    pub fn finished(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: 3,
        }
    }

    /// An error another MPI rank reports: this rank ends with its code,
    /// silently, so that the message is printed once.
    pub fn reported_elsewhere(code: u8) -> Self {
        CliError {
            message: String::new(),
            code,
        }
    }

    /// Whether the message is for this rank to print.
    pub fn is_reported_here(&self) -> bool {
        !self.message.is_empty()
    }

    pub fn exit_code(&self) -> u8 {
        self.code
    }

    /// The same error, its message led by `context` (the file it concerns).
    pub fn within(self, context: impl fmt::Display) -> Self {
        CliError {
            message: format!("{context}: {}", self.message),
            code: self.code,
        }
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for CliError {}

pub type CliResult<T = ()> = Result<T, CliError>;

/// Creates an output directory (and its parents), naming it in the error.
pub fn create_output_dir(dir: &std::path::Path) -> CliResult {
    std::fs::create_dir_all(dir).map_err(|e| {
        CliError::runtime(format!(
            "{}: cannot create the output directory: {e}",
            dir.display()
        ))
    })
}
