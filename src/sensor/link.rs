//! The byte pipes the real sensors talk through: a TCP connection (the UTM-30LX-EW on
//! Ethernet) or a serial port (the USB lidars, the Dynamixel on its USB adapter; `serialport`).
//! Reads wait at most a given time; a closed connection or an unplugged adapter is an error,
//! never a silent zero.

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

/// A byte pipe to a device.
pub trait Link: Send {
    /// Sends every byte.
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()>;
    /// Reads what has arrived into `buf`, waiting at most `timeout`: the bytes read (at least
    /// one), an error of kind `TimedOut` when nothing came, `UnexpectedEof` when the other end
    /// closed.
    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize>;
    /// What the link is (for messages): `tcp 192.168.0.10:10940`, `serial /dev/ttyACM0`.
    fn describe(&self) -> String;
}

/// A TCP connection.
pub struct TcpLink {
    stream: TcpStream,
    address: String,
}

impl TcpLink {
    /// Connects to `address` (`host:port`), waiting at most `timeout`.
    pub fn connect(address: &str, timeout: Duration) -> std::io::Result<Self> {
        let mut last = std::io::Error::new(ErrorKind::NotFound, format!("{address} resolves to no address"));
        for a in address.to_socket_addrs()? {
            match TcpStream::connect_timeout(&a, timeout) {
                Ok(stream) => {
                    stream.set_nodelay(true)?;
                    return Ok(Self { stream, address: address.to_string() });
                }
                Err(e) => last = e,
            }
        }
        Err(last)
    }
}

impl Link for TcpLink {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.stream.write_all(bytes)
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        self.stream.set_read_timeout(Some(timeout.max(Duration::from_micros(100))))?;
        match self.stream.read(buf) {
            Ok(0) => Err(std::io::Error::new(ErrorKind::UnexpectedEof, "the connection was closed")),
            Ok(n) => Ok(n),
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                Err(std::io::Error::new(ErrorKind::TimedOut, "no data"))
            }
            Err(e) => Err(e),
        }
    }

    fn describe(&self) -> String {
        format!("tcp {}", self.address)
    }
}

/// A serial port.
pub struct SerialLink {
    port: Box<dyn serialport::SerialPort>,
    path: String,
}

impl SerialLink {
    /// Opens `path` at `baud` (8 data bits, no parity, 1 stop bit, no flow control).
    pub fn open(path: &str, baud: u32) -> Result<Self, serialport::Error> {
        let port = serialport::new(path, baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(100))
            .open()?;
        Ok(Self { port, path: path.to_string() })
    }
}

impl Link for SerialLink {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        self.port.set_timeout(timeout.max(Duration::from_micros(100))).map_err(std::io::Error::other)?;
        match self.port.read(buf) {
            Ok(0) => Err(std::io::Error::new(ErrorKind::UnexpectedEof, "the port was closed")),
            Ok(n) => Ok(n),
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                Err(std::io::Error::new(ErrorKind::TimedOut, "no data"))
            }
            Err(e) => Err(e),
        }
    }

    fn describe(&self) -> String {
        format!("serial {}", self.path)
    }
}
