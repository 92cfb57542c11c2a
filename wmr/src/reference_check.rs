//! Checks a generated reference page of the book against the code, or
//! rewrites it under [`WRITE_ENV`] (D185). Only std: wmr's
//! `reference` module and the `reference` tests of robot-file and
//! wmr-protocol (which wmr depends on) include this one file.

use std::path::Path;

/// Set (to anything) to rewrite the generated reference pages instead of
/// checking them: `WMR_WRITE_REFERENCE=1 cargo test --release --workspace
/// --test reference`.
pub const WRITE_ENV: &str = "WMR_WRITE_REFERENCE";

/// Why a generated page could not be checked.
#[derive(Debug)]
pub enum ReferenceError {
    /// The committed page differs from the code's.
    Differs {
        /// The page, relative to the repository.
        page: String,
        /// The command that rewrites it.
        command: String,
    },
    /// Reading or writing the page.
    Io {
        /// The page.
        page: String,
        /// What failed.
        error: std::io::Error,
    },
}

impl std::fmt::Display for ReferenceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Differs { page, command } => {
                write!(
                    f,
                    "{page} differs from the code: run `{command}` and commit it"
                )
            }
            Self::Io { page, error } => write!(f, "{page}: {error}"),
        }
    }
}

impl std::error::Error for ReferenceError {}

/// Compares the page at `path` (`page` names it in messages) with `want`;
/// with [`WRITE_ENV`] set, writes `want` there instead. `command` is the
/// command that rewrites it, for the message.
pub fn check_or_write(
    path: &Path,
    page: &str,
    want: &str,
    command: &str,
) -> Result<(), ReferenceError> {
    let io = |error| ReferenceError::Io {
        page: page.to_string(),
        error,
    };
    if std::env::var_os(WRITE_ENV).is_some() {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(io)?;
        }
        return std::fs::write(path, want).map_err(io);
    }
    let have = match std::fs::read_to_string(path) {
        Ok(s) => s,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
        Err(e) => return Err(io(e)),
    };
    if have == want {
        Ok(())
    } else {
        Err(ReferenceError::Differs {
            page: page.to_string(),
            command: command.to_string(),
        })
    }
}
