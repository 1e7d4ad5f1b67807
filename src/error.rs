//! Typed library errors. Every variant that concerns input names the file or
//! field at fault, so the CLI can print it without a backtrace.

use std::path::PathBuf;

/// Result alias used throughout the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in terraclip's library code.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or writing a file failed at the OS level. The OS's words
    /// are in the message and not also a `source`: the CLI prints an
    /// error's chain, which would say them twice.
    #[error("{path}: {os}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        os: std::io::Error,
    },
    /// A file was readable but its contents are not acceptable.
    #[error("{path}: {reason}")]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A parameter (scene field, CLI value) is out of range or malformed.
    #[error("{field}: {reason}")]
    BadValue {
        /// The field or flag, as the user wrote it (`lod.n`, `--size`).
        field: String,
        /// What is wrong with the value.
        reason: String,
    },
}

impl Error {
    /// An OS-level failure on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            os: source,
        }
    }
    pub(crate) fn file(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        Error::BadFile {
            path: path.into(),
            reason: reason.into(),
        }
    }
    pub(crate) fn value(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::BadValue {
            field: field.into(),
            reason: reason.into(),
        }
    }
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a
/// rename, so a reader never sees a half-written output or golden.
///
/// With `TERRACLIP_TEST_STALL_WRITE_MS=N` set, the write stops for N ms
/// after the first half of the bytes is on disk: the hook that lets
/// `tests/inputs.rs` kill a process while its output is half-written, which
/// no timing could otherwise hit reliably.
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    write_atomic_with(path, |f| {
        let stall = std::env::var("TERRACLIP_TEST_STALL_WRITE_MS")
            .ok()
            .and_then(|v| v.parse::<u64>().ok());
        if let Some(ms) = stall {
            let (head, tail) = bytes.split_at(bytes.len() / 2);
            f.write_all(head)?;
            f.flush()?;
            std::thread::sleep(std::time::Duration::from_millis(ms));
            f.write_all(tail)?;
        } else {
            f.write_all(bytes)?;
        }
        Ok(())
    })
}

/// The temporary file beside `path` that [`write_atomic`] writes first;
/// `part` tells apart several temporaries of one output.
pub fn temp_path(path: &std::path::Path, part: &str) -> Result<PathBuf> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| Error::file(path, "output path has no file name"))?;
    Ok(dir.join(format!(
        ".{}.tmp-{}{part}",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// [`write_atomic`] of what `fill` writes into the temporary file: for an
/// output too large to hold in memory.
pub fn write_atomic_with(
    path: &std::path::Path,
    fill: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = temp_path(path, "")?;
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        fill(&mut f)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}
