//! Dynamixel packets, both protocols (ROBOTIS e-manual, "Protocol 1.0" and "Protocol 2.0"):
//! instruction packets built, status packets read from a byte stream that may hold anything
//! (noise, an echo of our own request on a half-duplex bus, a packet cut short). The reader
//! never panics and never loops: a header it cannot make a valid packet of is skipped one
//! byte at a time.
//!
//! Protocol 1.0: `FF FF ID LEN INST params CHK`, LEN = params + 2, CHK = !(ID + LEN + INST +
//! params). Protocol 2.0: `FF FF FD 00 ID LEN_L LEN_H INST params CRC_L CRC_H`, LEN = params +
//! 3 after byte stuffing (`FF FF FD` in the payload becomes `FF FF FD FD`), CRC-16 with
//! polynomial 0x8005 over everything before it.

/// Which protocol (`1` or `2` in a configuration file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub enum Protocol {
    /// Protocol 1.0 (the MX-64's factory firmware).
    One,
    /// Protocol 2.0 (the MX-64 with 2.0 firmware).
    Two,
}

impl TryFrom<u8> for Protocol {
    type Error = String;

    fn try_from(v: u8) -> Result<Self, String> {
        match v {
            1 => Ok(Protocol::One),
            2 => Ok(Protocol::Two),
            _ => Err(format!("protocol {v}: the MX-64 speaks 1 or 2")),
        }
    }
}

impl From<Protocol> for u8 {
    fn from(p: Protocol) -> u8 {
        match p {
            Protocol::One => 1,
            Protocol::Two => 2,
        }
    }
}

/// Instructions the bench sends.
pub mod instruction {
    /// Ping.
    pub const PING: u8 = 0x01;
    /// Read.
    pub const READ: u8 = 0x02;
    /// Write.
    pub const WRITE: u8 = 0x03;
    /// Protocol 2.0's status packets carry this in the instruction's place.
    pub const STATUS: u8 = 0x55;
}

/// A status packet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Status {
    /// The device's id.
    pub id: u8,
    /// The error byte (Protocol 1.0: a bit per error; 2.0: bit 7 the alert, bits 0-6 a number).
    pub error: u8,
    /// The parameters (the data read, a ping's model number).
    pub params: Vec<u8>,
}

/// Protocol 1.0's checksum of `bytes` (ID through the last parameter).
pub fn checksum1(bytes: &[u8]) -> u8 {
    !bytes.iter().fold(0u8, |s, &b| s.wrapping_add(b))
}

/// Protocol 2.0's CRC-16 (polynomial 0x8005, initial 0, no reflection).
pub fn crc16(bytes: &[u8]) -> u16 {
    bytes.iter().fold(0u16, |mut crc, &b| {
        crc ^= u16::from(b) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 { (crc << 1) ^ 0x8005 } else { crc << 1 };
        }
        crc
    })
}

/// `FF FF FD` in a payload becomes `FF FF FD FD`.
pub fn stuff(payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(payload.len() + 4);
    for &b in payload {
        out.push(b);
        if out.len() >= 3 && out[out.len() - 3..] == [0xff, 0xff, 0xfd] {
            out.push(0xfd);
        }
    }
    out
}

/// `FF FF FD FD` in a payload becomes `FF FF FD`.
pub fn unstuff(payload: &[u8]) -> Vec<u8> {
    let mut out: Vec<u8> = Vec::with_capacity(payload.len());
    let mut i = 0;
    while i < payload.len() {
        out.push(payload[i]);
        if out.len() >= 3 && out[out.len() - 3..] == [0xff, 0xff, 0xfd] && payload.get(i + 1) == Some(&0xfd) {
            i += 1;
        }
        i += 1;
    }
    out
}

/// An instruction packet.
pub fn instruction(protocol: Protocol, id: u8, instruction: u8, params: &[u8]) -> Vec<u8> {
    match protocol {
        Protocol::One => {
            let mut p = vec![0xff, 0xff, id, (params.len() + 2) as u8, instruction];
            p.extend_from_slice(params);
            let chk = checksum1(&p[2..]);
            p.push(chk);
            p
        }
        Protocol::Two => {
            let mut body = vec![instruction];
            body.extend_from_slice(params);
            let body = stuff(&body);
            let len = (body.len() + 2) as u16;
            let mut p = vec![0xff, 0xff, 0xfd, 0x00, id, len as u8, (len >> 8) as u8];
            p.extend_from_slice(&body);
            let crc = crc16(&p);
            p.extend_from_slice(&crc.to_le_bytes());
            p
        }
    }
}

/// A status packet (what a device sends; for emulators and tests).
pub fn status(protocol: Protocol, id: u8, error: u8, params: &[u8]) -> Vec<u8> {
    match protocol {
        Protocol::One => {
            let mut p = vec![0xff, 0xff, id, (params.len() + 2) as u8, error];
            p.extend_from_slice(params);
            let chk = checksum1(&p[2..]);
            p.push(chk);
            p
        }
        Protocol::Two => {
            let mut params_with_error = vec![error];
            params_with_error.extend_from_slice(params);
            instruction(Protocol::Two, id, instruction::STATUS, &params_with_error)
        }
    }
}

/// Longest Protocol 2.0 packet the reader accepts, bytes (the MX-64's whole control table is
/// under 700 bytes).
const MAX_LEN_2: usize = 1024;

/// A packet as framed on the wire: its id, its instruction byte (Protocol 1.0: the
/// instruction, or a status's error byte; 2.0: the instruction, 0x55 for a status) and its
/// parameters (unstuffed).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// The device's id.
    pub id: u8,
    /// The instruction byte.
    pub instruction: u8,
    /// The parameters.
    pub params: Vec<u8>,
}

/// What the reader found at the front of its buffer.
enum Found {
    /// A valid packet of `n` bytes.
    Packet(Packet, usize),
    /// Not a packet here: drop a byte.
    Skip,
    /// A packet framed whole (header, id, length) whose checksum failed: its `n` bytes are
    /// noted, and a byte dropped (its length may be what was garbled).
    Corrupt(usize),
    /// Need more bytes.
    More,
}

/// Frames packets in a byte stream that may hold anything.
#[derive(Debug)]
pub struct PacketReader {
    protocol: Protocol,
    buf: Vec<u8>,
    /// Our own request, which a bus that echoes (one wire, both ways) hands back first.
    echo: Option<Vec<u8>>,
    /// Bytes dropped as not a packet since the last call to [`PacketReader::take_dropped`].
    dropped: usize,
    /// The last packet framed whole whose checksum failed, since the last call to
    /// [`PacketReader::take_corrupt`].
    corrupt: Option<Vec<u8>>,
}

impl PacketReader {
    /// A reader for `protocol`.
    pub fn new(protocol: Protocol) -> Self {
        Self { protocol, buf: Vec::new(), echo: None, dropped: 0, corrupt: None }
    }

    /// Takes bytes as they arrive.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Drops everything held.
    pub fn clear(&mut self) {
        self.buf.clear();
        self.echo = None;
        self.corrupt = None;
    }

    /// The request just sent: if the bus hands it back, it is skipped (a Protocol 1.0 ping
    /// echoed would otherwise read as a status with an error).
    pub fn expect_echo(&mut self, request: &[u8]) {
        self.echo = Some(request.to_vec());
    }

    /// Bytes dropped as not part of a valid packet since last asked (garbled bytes, a wrong
    /// baud rate or protocol show here).
    pub fn take_dropped(&mut self) -> usize {
        std::mem::take(&mut self.dropped)
    }

    /// The last packet framed whole whose checksum (Protocol 1.0) or CRC (2.0) failed since
    /// last asked: a reply garbled on the bus, worth asking again.
    pub fn take_corrupt(&mut self) -> Option<Vec<u8>> {
        self.corrupt.take()
    }

    /// The next valid packet in the stream, or `None` when more bytes are needed. Each call
    /// either returns a packet or leaves fewer bytes than a packet needs.
    pub fn next_packet(&mut self) -> Option<Packet> {
        if let Some(echo) = &self.echo {
            if self.buf.len() < echo.len() && echo.starts_with(&self.buf) {
                return None;
            }
            if self.buf.starts_with(echo) {
                self.buf.drain(..echo.len());
            }
            self.echo = None;
        }
        // Bytes passed over are dropped at once at the end (not one shift of the buffer each).
        let mut at = 0;
        let packet = loop {
            let found = match self.protocol {
                Protocol::One => find1(&self.buf[at..]),
                Protocol::Two => find2(&self.buf[at..]),
            };
            match found {
                Found::Packet(p, n) => {
                    at += n;
                    break Some(p);
                }
                Found::Skip => {
                    at += 1;
                    self.dropped += 1;
                }
                Found::Corrupt(n) => {
                    self.corrupt = Some(self.buf[at..at + n].to_vec());
                    at += 1;
                    self.dropped += 1;
                }
                Found::More => break None,
            }
        };
        self.buf.drain(..at);
        packet
    }
}

/// Reads status packets from a byte stream (the host's side).
#[derive(Debug)]
pub struct StatusReader {
    packets: PacketReader,
}

impl StatusReader {
    /// A reader for `protocol`.
    pub fn new(protocol: Protocol) -> Self {
        Self { packets: PacketReader::new(protocol) }
    }

    /// Takes bytes as they arrive.
    pub fn push(&mut self, bytes: &[u8]) {
        self.packets.push(bytes);
    }

    /// Drops everything held.
    pub fn clear(&mut self) {
        self.packets.clear();
    }

    /// See [`PacketReader::expect_echo`].
    pub fn expect_echo(&mut self, request: &[u8]) {
        self.packets.expect_echo(request);
    }

    /// See [`PacketReader::take_dropped`].
    pub fn take_dropped(&mut self) -> usize {
        self.packets.take_dropped()
    }

    /// See [`PacketReader::take_corrupt`].
    pub fn take_corrupt(&mut self) -> Option<Vec<u8>> {
        self.packets.take_corrupt()
    }

    /// The next status packet in the stream, or `None` when more bytes are needed
    /// (Protocol 2.0 instruction packets, an echo of ours, are passed over).
    pub fn next_status(&mut self) -> Option<Status> {
        loop {
            let p = self.packets.next_packet()?;
            match self.packets.protocol {
                Protocol::One => return Some(Status { id: p.id, error: p.instruction, params: p.params }),
                Protocol::Two => {
                    if let (instruction::STATUS, Some((&error, rest))) =
                        (p.instruction, p.params.split_first())
                    {
                        return Some(Status { id: p.id, error, params: rest.to_vec() });
                    }
                }
            }
        }
    }
}

fn find1(buf: &[u8]) -> Found {
    if buf.is_empty() {
        return Found::More;
    }
    if buf[0] != 0xff {
        return Found::Skip;
    }
    if buf.len() < 2 {
        return Found::More;
    }
    if buf[1] != 0xff {
        return Found::Skip;
    }
    if buf.len() < 4 {
        return Found::More;
    }
    let (id, len) = (buf[2], buf[3] as usize);
    if id == 0xff || len < 2 {
        return Found::Skip;
    }
    let n = 4 + len;
    if buf.len() < n {
        return Found::More;
    }
    if checksum1(&buf[2..n - 1]) != buf[n - 1] {
        return Found::Corrupt(n);
    }
    Found::Packet(Packet { id, instruction: buf[4], params: buf[5..n - 1].to_vec() }, n)
}

fn find2(buf: &[u8]) -> Found {
    const HEADER: [u8; 4] = [0xff, 0xff, 0xfd, 0x00];
    let have = buf.len().min(4);
    if have == 0 {
        return Found::More;
    }
    if buf[..have] != HEADER[..have] {
        return Found::Skip;
    }
    if buf.len() < 7 {
        return Found::More;
    }
    let id = buf[4];
    let len = usize::from(u16::from_le_bytes([buf[5], buf[6]]));
    if !(3..=MAX_LEN_2).contains(&len) || id == 0xfd || id == 0xff {
        return Found::Skip;
    }
    let n = 7 + len;
    if buf.len() < n {
        return Found::More;
    }
    let crc = u16::from_le_bytes([buf[n - 2], buf[n - 1]]);
    if crc16(&buf[..n - 2]) != crc {
        return Found::Corrupt(n);
    }
    let body = unstuff(&buf[7..n - 2]);
    match body.split_first() {
        Some((&inst, rest)) => Found::Packet(Packet { id, instruction: inst, params: rest.to_vec() }, n),
        None => Found::Skip,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(s: &str) -> Vec<u8> {
        s.split_whitespace().map(|b| u8::from_str_radix(b, 16).expect("hex")).collect()
    }

    #[test]
    fn protocol_1_packets_of_the_e_manual() {
        assert_eq!(instruction(Protocol::One, 1, 3, &[0x0c, 0x64, 0xaa]), hex("FF FF 01 05 03 0C 64 AA DC"));
        assert_eq!(instruction(Protocol::One, 1, instruction::PING, &[]), hex("FF FF 01 02 01 FB"));
        assert_eq!(
            instruction(Protocol::One, 1, instruction::READ, &[0x2b, 0x01]),
            hex("FF FF 01 04 02 2B 01 CC")
        );
        assert_eq!(
            instruction(Protocol::One, 0xfe, instruction::WRITE, &[0x03, 0x01]),
            hex("FF FF FE 04 03 03 01 F6")
        );
        assert_eq!(status(Protocol::One, 1, 0x24, &[]), hex("FF FF 01 02 24 D8"));
        let mut r = StatusReader::new(Protocol::One);
        r.push(&hex("FF FF 01 03 00 20 DB"));
        assert_eq!(r.next_status(), Some(Status { id: 1, error: 0, params: vec![0x20] }));
    }

    #[test]
    fn protocol_2_packets_crc_and_stuffing_of_the_e_manual() {
        assert_eq!(crc16(b"123456789"), 0xfee8, "CRC-16/BUYPASS check value");
        assert_eq!(crc16(&hex("FF FF FD 00 01 03 00 01")), 0x4e19);
        assert_eq!(
            instruction(Protocol::Two, 1, instruction::PING, &[]),
            hex("FF FF FD 00 01 03 00 01 19 4E")
        );
        assert_eq!(
            instruction(Protocol::Two, 1, instruction::READ, &[0x84, 0x00, 0x04, 0x00]),
            hex("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")
        );
        assert_eq!(
            instruction(Protocol::Two, 1, instruction::WRITE, &[0x74, 0x00, 0x00, 0x02, 0x00, 0x00]),
            hex("FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89")
        );
        assert_eq!(
            status(Protocol::Two, 1, 0, &[0x06, 0x04, 0x26]),
            hex("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D")
        );
        // Stuffing (vectors of the dynamixel2 crate's tests) and a stuffed write's length.
        assert_eq!(stuff(&hex("FF FF FD 00")), hex("FF FF FD FD 00"));
        assert_eq!(stuff(&hex("FF FF FD FF FF FD")), hex("FF FF FD FD FF FF FD FD"));
        assert_eq!(stuff(&hex("FF FF 01 FD")), hex("FF FF 01 FD"));
        assert_eq!(unstuff(&hex("FF FF FD FD")), hex("FF FF FD"));
        assert_eq!(unstuff(&hex("FF FF 01 FD FD")), hex("FF FF 01 FD FD"));
        assert_eq!(
            instruction(Protocol::Two, 1, instruction::WRITE, &[0x74, 0x00, 0xff, 0xff, 0xfd, 0x00]),
            hex("FF FF FD 00 01 0A 00 03 74 00 FF FF FD FD 00 21 E7")
        );
        let mut r = StatusReader::new(Protocol::Two);
        r.push(&hex("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0"));
        assert_eq!(r.next_status(), Some(Status { id: 1, error: 0, params: vec![0xa6, 0, 0, 0] }));
    }

    #[test]
    fn the_reader_skips_noise_echoes_and_bad_checksums() {
        let mut r = StatusReader::new(Protocol::Two);
        let mut stream = vec![0x00, 0xff, 0x13];
        stream.extend(instruction(Protocol::Two, 1, instruction::PING, &[])); // our own echo
        let mut bad = status(Protocol::Two, 1, 0, &[1, 2]);
        bad[8] ^= 0x40;
        stream.extend(&bad);
        stream.extend(status(Protocol::Two, 1, 0x80, &[7]));
        for b in &stream {
            r.push(&[*b]);
        }
        assert_eq!(r.next_status(), Some(Status { id: 1, error: 0x80, params: vec![7] }));
        assert_eq!(r.take_corrupt(), Some(bad), "the garbled status is noted whole");
        assert_eq!(r.take_corrupt(), None);
        assert!(r.take_dropped() > 0);
        assert_eq!(r.next_status(), None);
    }
}
