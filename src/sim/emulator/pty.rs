//! A pseudo-terminal pair: the emulator keeps the master side, a driver opens the slave's path
//! as it would a USB serial adapter. The emulator also holds the slave open, to read the baud
//! rate the driver set (a device on a real wire hears garbage at the wrong rate) and so the
//! master does not see a hang-up between the driver's opens.

use std::fs::File;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};

/// A pseudo-terminal.
pub struct Pty {
    /// The master side (read what the driver writes, write what it reads).
    pub master: File,
    slave: OwnedFd,
    /// The slave's path, for the driver (`/dev/pts/N`).
    pub path: String,
}

impl Pty {
    /// A new pair, the slave in raw mode.
    pub fn open() -> io::Result<Self> {
        // SAFETY: posix_openpt returns a new fd or -1; it is owned by the File at once.
        let fd = unsafe { libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY | libc::O_CLOEXEC) };
        if fd < 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: fd is a valid, open descriptor we own.
        let master = unsafe { File::from_raw_fd(fd) };
        // SAFETY: grantpt and unlockpt take the master's fd, valid here.
        if unsafe { libc::grantpt(fd) } != 0 || unsafe { libc::unlockpt(fd) } != 0 {
            return Err(io::Error::last_os_error());
        }
        let mut name = [0 as libc::c_char; 128];
        // SAFETY: the buffer is 128 bytes, its length passed; ptsname_r writes a NUL-terminated
        // path into it or fails.
        if unsafe { libc::ptsname_r(fd, name.as_mut_ptr(), name.len()) } != 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: ptsname_r succeeded, so name holds a NUL-terminated string.
        let path = unsafe { std::ffi::CStr::from_ptr(name.as_ptr()) }.to_string_lossy().into_owned();
        let slave_file = std::fs::OpenOptions::new().read(true).write(true).open(&path)?;
        let slave = OwnedFd::from(slave_file);
        let pty = Self { master, slave, path };
        pty.make_raw()?;
        Ok(pty)
    }

    /// Raw mode on the slave: no echo, no line editing, no output processing.
    fn make_raw(&self) -> io::Result<()> {
        let fd = self.slave.as_raw_fd();
        // SAFETY: termios is plain data, all zeroes a valid value.
        let mut t: libc::termios = unsafe { std::mem::zeroed() };
        // SAFETY: tcgetattr fills the struct from a valid fd, or fails.
        if unsafe { libc::tcgetattr(fd, &mut t) } != 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: cfmakeraw edits the struct in place.
        unsafe { libc::cfmakeraw(&mut t) };
        // SAFETY: a valid fd and a filled termios.
        if unsafe { libc::tcsetattr(fd, libc::TCSANOW, &t) } != 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    }

    /// The baud rate the slave is set to (what the driver asked for), read with `TCGETS2`
    /// (a driver may set any rate, as `serialport` does with `BOTHER`).
    pub fn baud(&self) -> Option<u32> {
        let fd = self.slave.as_raw_fd();
        // SAFETY: termios2 is plain data, all zeroes a valid value.
        let mut t: libc::termios2 = unsafe { std::mem::zeroed() };
        // SAFETY: the ioctl fills the struct from a valid tty fd, or fails.
        if unsafe { libc::ioctl(fd, libc::TCGETS2, &mut t) } != 0 {
            return None;
        }
        Some(t.c_ospeed)
    }

    /// Hangs up: the master and the emulator's slave are closed, the driver's next read fails
    /// (a cable pulled).
    pub fn hang_up(self) {
        let Self { master, slave, .. } = self;
        drop(master);
        drop(slave);
    }

    /// Waits at most `timeout_ms` for bytes from the driver; the bytes read (0 when none came).
    pub fn read_timeout(&mut self, buf: &mut [u8], timeout_ms: i32) -> io::Result<usize> {
        read_timeout(&mut self.master, buf, timeout_ms)
    }
}

/// Waits at most `timeout_ms` for `f` to be readable, then reads: the bytes read, 0 when
/// nothing came in time, an `UnexpectedEof` error when the other end is gone.
pub fn read_timeout<F: std::io::Read + AsRawFd>(
    f: &mut F,
    buf: &mut [u8],
    timeout_ms: i32,
) -> io::Result<usize> {
    let mut pfd = libc::pollfd { fd: f.as_raw_fd(), events: libc::POLLIN, revents: 0 };
    // SAFETY: one valid pollfd for the duration of the call.
    let n = unsafe { libc::poll(&mut pfd, 1, timeout_ms) };
    if n < 0 {
        let e = io::Error::last_os_error();
        return if e.kind() == io::ErrorKind::Interrupted { Ok(0) } else { Err(e) };
    }
    if n == 0 {
        return Ok(0);
    }
    match f.read(buf) {
        Ok(0) => Err(io::Error::new(io::ErrorKind::UnexpectedEof, "the other end is gone")),
        Ok(k) => Ok(k),
        Err(e) if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted => Ok(0),
        Err(e) => Err(e),
    }
}
