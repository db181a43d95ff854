//! Errors for people: every input problem names the file, the field and what would be right.

use std::fmt;
use std::path::{Path, PathBuf};

/// Everything that can go wrong in streak. Library code returns this; the CLI prints it.
#[derive(Debug)]
pub enum Error {
    /// A problem in a user's input file: which file, which field (or line), what is wrong.
    Input {
        /// The file at fault.
        file: PathBuf,
        /// Where in it: a field path such as `object[1].keyframe[2].t`, or a line.
        field: String,
        /// What is wrong and what would be right.
        message: String,
    },
    /// A file could not be read or written.
    Io {
        /// The file that could not be read or written.
        file: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A value out of its range where no file is involved (a scene or method built in code):
    /// which setting, what is wrong and what would be right.
    Invalid {
        /// The setting at fault, as its builder or the command line names it.
        field: String,
        /// What is wrong and what would be right.
        message: String,
    },
    /// A request that is invalid on its face (a bad command-line value, an impossible size).
    Usage(String),
}

impl Error {
    /// An input error in `file` at `field`.
    pub fn input(file: &Path, field: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Input {
            file: file.to_path_buf(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// A value out of its range at `field`, where no file is involved.
    pub fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Invalid {
            field: field.into(),
            message: message.into(),
        }
    }

    /// This error as found in `file` at `within`: an [`Error::Invalid`] becomes an
    /// [`Error::Input`] whose field is `within.field` (or `within` when it is empty); other errors
    /// are already placed and stay as they are.
    #[must_use]
    pub fn in_file(self, file: &Path, within: &str) -> Self {
        match self {
            Error::Invalid { field, message } => Error::Input {
                file: file.to_path_buf(),
                field: match (within.is_empty(), field.is_empty()) {
                    (true, _) => field,
                    (false, true) => within.to_string(),
                    (false, false) => format!("{within}.{field}"),
                },
                message,
            },
            other => other,
        }
    }

    /// This error as met reading a file that `field` of `file` names: a file that cannot be read
    /// becomes an [`Error::Input`] on `file` at `field` ("cannot read …"), so that the message
    /// says which setting named it; a mistake inside the named file stays as it is, naming that
    /// file.
    #[must_use]
    pub fn named_by(self, file: &Path, field: &str) -> Self {
        match self {
            Error::Io {
                file: named,
                source,
            } => Error::Input {
                file: file.to_path_buf(),
                field: field.to_string(),
                message: format!("cannot read {}: {source}", named.display()),
            },
            other => other,
        }
    }

    /// An I/O error on `file`.
    pub fn io(file: &Path, source: std::io::Error) -> Self {
        Error::Io {
            file: file.to_path_buf(),
            source,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Input {
                file,
                field,
                message,
            } => write!(f, "{}: {}: {}", file.display(), field, message),
            Error::Io { file, source } => write!(f, "{}: {}", file.display(), source),
            Error::Invalid { field, message } => write!(f, "{field}: {message}"),
            Error::Usage(message) => f.write_str(message),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// `value` as a message shows it: plainly where that is short, in scientific notation where
/// plain digits would run to dozens (10⁻³⁰⁰ is 300 zeros).
#[must_use]
pub fn shown(value: f64) -> String {
    if value == 0.0 || !value.is_finite() || (1e-4..1e15).contains(&value.abs()) {
        value.to_string()
    } else {
        format!("{value:e}")
    }
}

/// Result with streak's error.
pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_shown_plainly_unless_that_runs_long() {
        assert_eq!(shown(36.0), "36");
        assert_eq!(shown(0.001), "0.001");
        assert_eq!(shown(0.0), "0");
        assert_eq!(shown(-2.5e-300), "-2.5e-300");
        assert_eq!(shown(1e300), "1e300");
        assert_eq!(shown(f64::NAN), "NaN");
    }
}
