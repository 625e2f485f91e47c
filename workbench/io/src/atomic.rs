//! Replace a file atomically: readers (and a crash) see either the old file or the
//! complete new one, never a half-written one, and a failed run keeps the old result.
//!
//! The data goes to a hidden temporary file in the same directory (a rename is only
//! atomic within one file system), which is flushed and fsynced, then renamed over the
//! target; the directory is fsynced too so the rename survives a power cut. On any
//! error, or a panic in the writer, the temporary file is removed.
//!
//! A signal (SIGINT, SIGTERM, SIGHUP) ends the process between two writes: with
//! [`clean_up_on_signals`] installed, the temporary files of unfinished writes are
//! removed first, and the process exits with 128 + the signal's number.
//!
//! A symlink is followed (the link stays, its target gets the new contents). A target
//! that exists and is neither a regular file nor a directory (`/dev/null`, a FIFO,
//! `/dev/stdout`) is written directly: renaming over it would replace the device node,
//! and a stream has no old contents to protect.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Mutex, MutexGuard};

/// Buffer between the writer closure and the file: big enough that a CSV row never
/// becomes a syscall of its own.
const BUF_BYTES: usize = 1 << 16;

/// Distinguishes temporary files of concurrent writes within one process.
static COUNTER: AtomicU32 = AtomicU32::new(0);

/// The temporary files of the writes in progress. Held while a temporary file is
/// created or renamed, and by the signal thread while it removes them and exits: a
/// write is either finished (renamed) or cleaned up, never left behind.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn live() -> MutexGuard<'static, Vec<PathBuf>> {
    // A panic while holding it cannot leave the list inconsistent (push/retain only).
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Remove the temporary files of unfinished writes when the process gets SIGINT,
/// SIGTERM or SIGHUP, then exit with 128 + the signal. Call once, at start-up, in a
/// binary (a library must not take over a process's signals). The handler runs on a
/// thread of its own, so it may lock and delete (nothing runs in signal context).
pub fn clean_up_on_signals() -> io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new().name("signals".into()).spawn(move || {
        if let Some(sig) = signals.forever().next() {
            let files = live();
            for f in files.iter() {
                let _ = fs::remove_file(f);
            }
            // Exit with the lock held: no write can rename its file in between.
            std::process::exit(128 + sig);
        }
    })?;
    Ok(())
}

/// Write `path` through `write`, atomically. The closure gets a buffered writer; its
/// error (or any I/O error of the flush, sync or rename) is returned unchanged and
/// leaves `path` as it was.
pub fn write_atomic<F>(path: &Path, write: F) -> io::Result<()>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    // Checked before resolving links: `/dev/stdout` leads to names like `pipe:[42]`.
    if let Ok(m) = fs::metadata(path) {
        if !m.is_file() && !m.is_dir() {
            return write_stream(path, write);
        }
    }
    let path = &resolve_symlink(path)?;
    let file_name = path.file_name().ok_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, format!("{} does not name a file", path.display()))
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let (file, tmp_path) = create_temp(&dir, &file_name.to_string_lossy())?;
    let mut guard = TempGuard { path: tmp_path, armed: true };

    let mut out = BufWriter::with_capacity(BUF_BYTES, file);
    write(&mut out)?;
    out.flush()?;
    let file = out.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()?;
    drop(file);

    {
        let mut files = live();
        fs::rename(&guard.path, path)?;
        guard.armed = false;
        files.retain(|f| *f != guard.path);
    }
    sync_dir(&dir);
    Ok(())
}

/// The file a symlink (chain) points to, so the rename replaces the target and keeps
/// the link; other paths unchanged.
fn resolve_symlink(path: &Path) -> io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = fs::read_link(&p)?;
                p = match p.parent() {
                    Some(dir) => dir.join(link), // `join` keeps an absolute `link` as is
                    None => link,
                };
            }
            _ => return Ok(p),
        }
    }
    Err(io::Error::other(format!("{}: too many levels of symbolic links", path.display())))
}

/// Writes to a device or FIFO in place.
fn write_stream<F>(path: &Path, write: F) -> io::Result<()>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let file = OpenOptions::new().write(true).open(path)?;
    let mut out = BufWriter::with_capacity(BUF_BYTES, file);
    write(&mut out)?;
    out.flush()
}

/// Creates `.<name>.<pid>.<n>.tmp` next to the target; `create_new` so that an
/// existing file (another process's temp file) is never clobbered.
fn create_temp(dir: &Path, name: &str) -> io::Result<(File, PathBuf)> {
    let pid = std::process::id();
    let mut last_err = None;
    for _ in 0..16 {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{name}.{pid}.{n}.tmp"));
        let mut files = live();
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => {
                files.push(tmp.clone());
                return Ok((f, tmp));
            }
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last_err = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last_err.unwrap_or_else(|| io::Error::other("no free temporary file name")))
}

/// Makes the rename durable. Best effort: some file systems refuse to fsync a
/// directory, and the data itself is already safe by then.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// Removes the temporary file unless the rename consumed it.
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            let mut files = live();
            let _ = fs::remove_file(&self.path);
            files.retain(|f| *f != self.path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_new_and_replaces_existing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.csv");
        write_atomic(&p, |w| w.write_all(b"first")).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"first");
        write_atomic(&p, |w| w.write_all(b"second, longer")).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"second, longer");
        assert_eq!(entries(dir.path()), ["out.csv"]);
    }

    #[test]
    fn error_midway_keeps_old_file_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.csv");
        fs::write(&p, "old contents").unwrap();
        // Write more than the buffer so some data really reached the temp file.
        let err = write_atomic(&p, |w| {
            for _ in 0..(3 * BUF_BYTES / 10) {
                w.write_all(b"new data\n")?;
            }
            Err(io::Error::other("simulated failure"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "simulated failure");
        assert_eq!(fs::read_to_string(&p).unwrap(), "old contents");
        assert_eq!(entries(dir.path()), ["out.csv"]);
    }

    #[test]
    fn panic_in_writer_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.csv");
        let r = std::panic::catch_unwind(|| {
            let _ = write_atomic(&p, |w| {
                w.write_all(b"partial")?;
                panic!("writer bug");
            });
        });
        assert!(r.is_err());
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn missing_directory_is_an_error_and_creates_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/dir/out.csv");
        let err = write_atomic(&p, |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        assert!(entries(dir.path()).is_empty());
    }

    #[cfg(unix)]
    #[test]
    fn symlink_is_kept_and_its_target_replaced() {
        let dir = tempfile::tempdir().unwrap();
        fs::create_dir(dir.path().join("runs")).unwrap();
        let target = dir.path().join("runs/real.csv");
        fs::write(&target, "old").unwrap();
        let link = dir.path().join("latest.csv");
        std::os::unix::fs::symlink("runs/real.csv", &link).unwrap();
        write_atomic(&link, |w| w.write_all(b"new")).unwrap();
        assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(fs::read_to_string(&target).unwrap(), "new");
        assert_eq!(entries(&dir.path().join("runs")), ["real.csv"]);
        // A dangling link gets its target created.
        fs::remove_file(&target).unwrap();
        write_atomic(&link, |w| w.write_all(b"again")).unwrap();
        assert_eq!(fs::read_to_string(&target).unwrap(), "again");
    }

    /// A special file is never renamed over: here a socket, which cannot be opened
    /// for writing, so the write fails and the socket stays.
    #[cfg(unix)]
    #[test]
    fn special_files_are_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let sock = dir.path().join("out.sock");
        let _listener = std::os::unix::net::UnixListener::bind(&sock).unwrap();
        assert!(write_atomic(&sock, |w| w.write_all(b"x")).is_err());
        assert!(fs::metadata(&sock).unwrap().file_type().is_socket());
        assert_eq!(entries(dir.path()), ["out.sock"]);
    }

    /// A FIFO (like `--out /dev/stdout` into a pipe) is streamed to.
    #[cfg(unix)]
    #[test]
    fn fifo_is_written_in_place() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("out.fifo");
        let ok =
            std::process::Command::new("mkfifo").arg(&fifo).status().map(|s| s.success()).unwrap_or(false);
        assert!(ok, "mkfifo failed");
        let (tx, rx) = std::sync::mpsc::channel();
        {
            let fifo = fifo.clone();
            // Detached: if the FIFO were (wrongly) renamed over, this would block forever,
            // and the timeout below fails the test instead of hanging it.
            std::thread::spawn(move || tx.send(fs::read_to_string(fifo).unwrap()));
        }
        write_atomic(&fifo, |w| w.write_all(b"streamed")).unwrap();
        let got = rx.recv_timeout(std::time::Duration::from_secs(10));
        assert_eq!(got.as_deref(), Ok("streamed"));
        assert!(fs::metadata(&fifo).unwrap().file_type().is_fifo());
        assert_eq!(entries(dir.path()), ["out.fifo"]);
    }

    #[test]
    fn path_without_file_name_is_refused() {
        for p in ["", "..", "/"] {
            let err = write_atomic(Path::new(p), |_| Ok(())).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{p:?}");
        }
    }

    #[test]
    fn target_that_is_a_directory_fails_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        fs::create_dir(dir.path().join("sub")).unwrap();
        fs::write(dir.path().join("sub/keep"), "k").unwrap();
        assert!(write_atomic(&dir.path().join("sub"), |w| w.write_all(b"x")).is_err());
        assert_eq!(entries(dir.path()), ["sub"]);
        assert_eq!(fs::read_to_string(dir.path().join("sub/keep")).unwrap(), "k");
    }
}
