//! Errors shared by the commands: [`FileError`] for anything wrong in a file the user
//! gave (located by line and column so an editor can jump there), and [`CmdError`],
//! which tells `main` which exit code to use.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A problem in a user file, displayed `file:line:col: message` (GNU style, so editors
/// and CI logs link to it). Line and column are 1-based; the column counts characters.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FileError {
    /// The file as the user named it.
    pub file: PathBuf,
    /// 1-based line, when the problem has a place in the file.
    pub line: Option<usize>,
    /// 1-based column in characters, when known.
    pub col: Option<usize>,
    /// What is wrong and what was expected.
    pub message: String,
}

impl FileError {
    /// A problem with the file as a whole (cannot be read, empty, ...).
    pub fn whole(file: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Self { file: file.as_ref().to_path_buf(), line: None, col: None, message: message.into() }
    }

    /// A problem at a 1-based line and column.
    pub fn at(file: impl AsRef<Path>, line: usize, col: usize, message: impl Into<String>) -> Self {
        Self { file: file.as_ref().to_path_buf(), line: Some(line), col: Some(col), message: message.into() }
    }

    /// A problem at byte offset `offset` of `text` (the file's contents).
    pub fn at_offset(file: impl AsRef<Path>, text: &str, offset: usize, message: impl Into<String>) -> Self {
        let (line, col) = line_col(text, offset);
        Self::at(file, line, col, message)
    }

    /// A problem at the start of a byte span of `text` (what parsers such as `toml` report).
    pub fn at_span(
        file: impl AsRef<Path>,
        text: &str,
        span: Option<Range<usize>>,
        message: impl Into<String>,
    ) -> Self {
        match span {
            Some(s) => Self::at_offset(file, text, s.start, message),
            None => Self::whole(file, message),
        }
    }

    /// Reading the file failed.
    pub fn io(file: impl AsRef<Path>, err: &std::io::Error) -> Self {
        Self::whole(file, format!("cannot read: {err}"))
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(col) = self.col {
                write!(f, ":{col}")?;
            }
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for FileError {}

/// 1-based (line, column) of byte `offset` in `text`; the column counts characters, not
/// bytes, so it matches what an editor shows. Offsets past the end map to the end, and
/// offsets inside a multi-byte character to that character.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut end = offset.min(text.len());
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let before = &text[..end];
    let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let col = before[line_start..].chars().count() + 1;
    (line, col)
}

/// Why a command failed, and so which exit code `simrod` returns.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CmdError {
    /// The user asked for something invalid: a bad argument or a bad input file.
    /// Detected before any work starts. Exit code 2, as clap uses for its own errors.
    #[error("{0}")]
    Usage(String),
    /// Valid request, but the work failed (I/O while writing, ...). Exit code 1.
    #[error("{0}")]
    Runtime(String),
}

impl CmdError {
    /// The process exit code for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            CmdError::Usage(_) => 2,
            CmdError::Runtime(_) => 1,
        }
    }
}

impl From<FileError> for CmdError {
    /// A bad input file is the user's to fix, like a bad argument.
    fn from(e: FileError) -> Self {
        CmdError::Usage(e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_lines_and_characters() {
        let text = "ab\ncdé\nxyz";
        assert_eq!(line_col(text, 0), (1, 1));
        assert_eq!(line_col(text, 2), (1, 3)); // the newline itself
        assert_eq!(line_col(text, 3), (2, 1));
        // 'é' is two bytes; the byte after it is column 4.
        assert_eq!(line_col(text, 7), (2, 4));
        // Inside 'é' maps to 'é'.
        assert_eq!(line_col(text, 6), (2, 3));
        assert_eq!(line_col(text, 8), (3, 1));
        assert_eq!(line_col(text, 999), (3, 4));
    }

    #[test]
    fn display_is_file_line_col_message() {
        let e = FileError::at_offset("p.toml", "a = 1\nb = 2\n", 10, "bad b");
        assert_eq!(e.to_string(), "p.toml:2:5: bad b");
        assert_eq!(FileError::whole("p.toml", "gone").to_string(), "p.toml: gone");
        assert_eq!(FileError::at_span("x", "abc", None, "m").to_string(), "x: m");
    }

    #[test]
    fn exit_codes() {
        assert_eq!(CmdError::Usage("u".into()).exit_code(), 2);
        assert_eq!(CmdError::Runtime("r".into()).exit_code(), 1);
        let e: CmdError = FileError::whole("f", "m").into();
        assert_eq!(e, CmdError::Usage("f: m".into()));
    }
}
