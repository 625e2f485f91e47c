//! Files on the host through semihosting (QEMU, or a debugger that serves it): what the
//! trace and cost binaries write their results to. Each write traps to the host, so
//! [`HostOut`] batches them.

use cortex_m_semihosting::{nr, syscall};

/// A file on the host (`SYS_OPEN`/`SYS_WRITE`/`SYS_CLOSE`).
pub struct HostFile(usize);

impl HostFile {
    /// Create or truncate `name` (NUL-terminated) for binary writing.
    pub fn create(name: &str) -> Option<Self> {
        let len = name.len().checked_sub(1)?;
        // SAFETY: SYS_OPEN reads `len` bytes of the NUL-terminated name, which lives on.
        let fd = unsafe { syscall!(OPEN, name.as_ptr(), nr::open::W_TRUNC_BINARY, len) };
        (fd as isize != -1).then_some(Self(fd))
    }

    /// Write all of `data`; false on a host error.
    pub fn write_all(&mut self, mut data: &[u8]) -> bool {
        while !data.is_empty() {
            // SAFETY: the host reads `data.len()` bytes from a live slice.
            let left = unsafe { syscall!(WRITE, self.0, data.as_ptr(), data.len()) };
            match data.len().checked_sub(left) {
                Some(done) if left < data.len() => data = data.get(done..).unwrap_or(&[]),
                _ => return left == 0,
            }
        }
        true
    }

    /// Close; false on a host error.
    pub fn close(self) -> bool {
        // SAFETY: closes the handle this value owns.
        unsafe { syscall!(CLOSE, self.0) == 0 }
    }
}

/// A buffered writer to a host file of `N` bytes of buffer; any host error is a panic
/// (these binaries only run with a host attached).
pub struct HostOut<const N: usize> {
    file: HostFile,
    buf: [u8; N],
    len: usize,
}

impl<const N: usize> HostOut<N> {
    /// Write to `file` through an empty buffer.
    pub fn new(file: HostFile) -> Self {
        Self { file, buf: [0; N], len: 0 }
    }

    /// Append `bytes` (at most `N`).
    pub fn put(&mut self, bytes: &[u8]) {
        if self.len + bytes.len() > N {
            self.flush();
        }
        match self.buf.get_mut(self.len..self.len + bytes.len()) {
            Some(dst) => dst.copy_from_slice(bytes),
            None => defmt::panic!("record larger than the host buffer"),
        }
        self.len += bytes.len();
    }

    /// Write out what is buffered.
    pub fn flush(&mut self) {
        let data = self.buf.get(..self.len).unwrap_or(&[]);
        if !self.file.write_all(data) {
            defmt::panic!("semihosting write failed");
        }
        self.len = 0;
    }

    /// Flush and close the file.
    pub fn finish(mut self) {
        self.flush();
        if !self.file.close() {
            defmt::panic!("closing the host file failed");
        }
    }
}
