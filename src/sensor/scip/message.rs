//! SCIP 2.0 replies as they come off the wire: a stream of bytes cut into messages (an echo of
//! the command, a status line, data lines, an empty line), every check character verified.
//! The reader takes bytes in any pieces, never panics and never loops on garbage: a message
//! that grows past any SCIP reply's size, or a line that fails its check, is an error, and the
//! reader carries on from the next message.

use super::codec::line_checks;

/// Longest reply the reader holds before giving up on it: an ME scan of the UTM-30LX-EW's 1081
/// steps is 6717 bytes; this leaves room for the longest models.
pub const MAX_MESSAGE_BYTES: usize = 64 * 1024;

/// One reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Message {
    /// The echo of the command (for a streamed scan, its remaining scans replace the count).
    pub echo: Vec<u8>,
    /// The two status characters (`00` accepted, `99` scan data follows, others errors).
    pub status: [u8; 2],
    /// The data lines after the status, each without its check character.
    pub lines: Vec<Vec<u8>>,
}

impl Message {
    /// The echo as text (for messages and matching).
    pub fn echo_text(&self) -> String {
        String::from_utf8_lossy(&self.echo).into_owned()
    }

    /// The status as text.
    pub fn status_text(&self) -> String {
        String::from_utf8_lossy(&self.status).into_owned()
    }
}

/// A reply the reader could not take.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MessageError {
    /// A line's check character is wrong (a garbled byte).
    #[error("line {line} of the reply to `{echo}` fails its check character: {text:?}")]
    Check {
        /// The echo of the reply.
        echo: String,
        /// Which line (0 = the status).
        line: usize,
        /// The line as received.
        text: String,
    },
    /// The status line is not a status.
    #[error("the reply to `{echo}` has no status line ({text:?})")]
    NoStatus {
        /// The echo.
        echo: String,
        /// What stood there.
        text: String,
    },
    /// Bytes without an end for longer than any reply.
    #[error("{bytes} bytes without the end of a reply: not SCIP, or the stream is broken")]
    Overlong {
        /// How many were dropped.
        bytes: usize,
    },
}

/// Cuts a byte stream into [`Message`]s.
#[derive(Debug, Default)]
pub struct Reader {
    buf: Vec<u8>,
    /// The front of `buf` already searched for a reply's end (a reply arriving a byte at a
    /// time is searched once, not once per byte).
    searched: usize,
}

impl Reader {
    /// A reader with nothing buffered.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes bytes as they arrive.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Bytes held, not yet a whole reply.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Drops everything held (after a reconnection).
    pub fn clear(&mut self) {
        self.buf.clear();
        self.searched = 0;
    }

    /// The next whole reply, an error for a bad one (its bytes are consumed), or `None` when
    /// more bytes are needed. Each call that returns something consumes bytes.
    pub fn next_message(&mut self) -> Option<Result<Message, MessageError>> {
        // Stray line ends before a reply (after an error, between replies) are skipped.
        let start = self.buf.iter().position(|&b| b != b'\n' && b != b'\r').unwrap_or(self.buf.len());
        if start > 0 {
            self.buf.drain(..start);
            self.searched = self.searched.saturating_sub(start);
        }
        // The last byte searched may be the first of the end.
        let from = self.searched.saturating_sub(1);
        let Some(end) = self.buf[from..].windows(2).position(|w| w == b"\n\n").map(|e| e + from) else {
            if self.buf.len() > MAX_MESSAGE_BYTES {
                let bytes = self.buf.len();
                self.clear();
                return Some(Err(MessageError::Overlong { bytes }));
            }
            self.searched = self.buf.len();
            return None;
        };
        self.searched = 0;
        let raw: Vec<u8> = self.buf.drain(..end + 2).collect();
        Some(parse(&raw[..end]))
    }
}

/// One reply's bytes, without its final empty line.
fn parse(raw: &[u8]) -> Result<Message, MessageError> {
    let mut lines = raw.split(|&b| b == b'\n').map(|l| l.strip_suffix(b"\r").unwrap_or(l));
    let echo = lines.next().unwrap_or_default().to_vec();
    let echo_text = String::from_utf8_lossy(&echo).into_owned();
    let status_line = lines.next().unwrap_or_default();
    let text = |l: &[u8]| String::from_utf8_lossy(l).into_owned();
    if status_line.len() != 3 {
        return Err(MessageError::NoStatus { echo: echo_text, text: text(status_line) });
    }
    if !line_checks(status_line) {
        return Err(MessageError::Check { echo: echo_text, line: 0, text: text(status_line) });
    }
    let status = [status_line[0], status_line[1]];
    let mut data = Vec::new();
    for (i, l) in lines.enumerate() {
        if !line_checks(l) {
            return Err(MessageError::Check { echo: echo_text, line: i + 1, text: text(l) });
        }
        data.push(l[..l.len() - 1].to_vec());
    }
    Ok(Message { echo, status, lines: data })
}

/// What a status code means (SCIP 2.0 spec pp. 11-15, 23; UTM-30LX), for errors: the codes of
/// every command first, then those of `command`'s kind.
pub fn status_meaning(command: &[u8], status: [u8; 2]) -> &'static str {
    let general = match &status {
        b"00" => Some("command received without error"),
        b"99" => Some("scan data follows"),
        b"0A" => Some("unable to create transmission data or reply internally"),
        b"0B" => Some("buffer shortage, or a command repeated while being processed"),
        b"0C" => Some("command with insufficient parameters"),
        b"0D" => Some("undefined command"),
        b"0E" => Some("undefined command (or the sensor is in time-adjust mode)"),
        b"0F" => Some("command with insufficient parameters"),
        b"0G" => Some("string in the command longer than 16 characters"),
        b"0H" => Some("string in the command has invalid characters"),
        b"0I" => Some("the sensor is in firmware update mode"),
        _ => None,
    };
    if let Some(m) = general {
        return m;
    }
    let kind = command.get(..2).unwrap_or_default();
    let code = std::str::from_utf8(&status).ok().and_then(|s| s.parse::<u8>().ok());
    match (kind, code) {
        (b"MD" | b"MS" | b"ME" | b"GD" | b"GS" | b"GE", Some(c)) => match c {
            1 => "starting step is not a number",
            2 => "end step is not a number",
            3 => "cluster count is not a number",
            4 => "end step out of range",
            5 => "end step smaller than the starting step",
            6 => "scan interval is not a number",
            7 => "number of scans is not a number",
            10 => "the laser is off",
            21..=49 => "processing stopped to verify an error",
            50..=97 => "hardware trouble (laser, motor or other malfunction)",
            98 => "resuming after confirming normal laser operation",
            _ => "unknown status",
        },
        (b"TM", Some(c)) => match c {
            1 => "invalid control code",
            2 => "adjust mode requested while already on",
            3 => "adjust mode off requested while already off",
            4 => "time requested while adjust mode is off",
            _ => "unknown status",
        },
        (b"BM", Some(1)) => "unable to turn the laser on: laser malfunction",
        (b"BM", Some(2)) => "the laser is already on",
        _ => "unknown status",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::scip::codec::check_char;

    fn with_check(line: &[u8]) -> Vec<u8> {
        let mut l = line.to_vec();
        l.push(check_char(line));
        l
    }

    #[test]
    fn replies_are_cut_from_bytes_in_any_pieces() {
        let mut stream = b"PP\n00P\nMODL:UTM-30LX-EW;I\nDMIN:23;7\n\nQT\n00P\n\n".to_vec();
        stream.extend(b"MD0000108001000\n99b\n");
        stream.extend(with_check(b"m2@0"));
        stream.extend(b"\n");
        stream.extend(with_check(b"0CB1Dh00G"));
        stream.extend(b"\n\n");
        for piece in [1, 2, 7, stream.len()] {
            let mut r = Reader::new();
            let mut got = Vec::new();
            for chunk in stream.chunks(piece) {
                r.push(chunk);
                while let Some(m) = r.next_message() {
                    got.push(m.expect("valid"));
                }
            }
            assert_eq!(got.len(), 3, "pieces of {piece}");
            assert_eq!(got[0].echo, b"PP");
            assert_eq!(got[0].lines, vec![b"MODL:UTM-30LX-EW;".to_vec(), b"DMIN:23;".to_vec()]);
            assert_eq!(&got[1].status, b"00");
            assert_eq!(&got[2].status, b"99");
            assert_eq!(got[2].lines, vec![b"m2@0".to_vec(), b"0CB1Dh00G".to_vec()]);
            assert_eq!(r.pending(), 0);
        }
    }

    #[test]
    fn a_garbled_line_is_an_error_and_the_next_reply_still_reads() {
        let mut r = Reader::new();
        r.push(b"MD0000108001000\n99b\nm2@0?\n0CB1Dh00X\n\nQT\n00P\n\n");
        let e = r.next_message().expect("a result").expect_err("bad check");
        assert!(matches!(e, MessageError::Check { line: 2, .. }), "{e}");
        assert_eq!(r.next_message().expect("next").expect("valid").echo, b"QT");
        r.push(b"XX\n0\n\n");
        assert!(matches!(r.next_message(), Some(Err(MessageError::NoStatus { .. }))));
        r.push(&vec![b'A'; MAX_MESSAGE_BYTES + 10]);
        assert!(matches!(r.next_message(), Some(Err(MessageError::Overlong { .. }))));
        assert!(r.next_message().is_none());
    }

    #[test]
    fn statuses_have_their_meanings() {
        assert_eq!(status_meaning(b"MD0000108001000", *b"04"), "end step out of range");
        assert_eq!(status_meaning(b"MD", *b"55"), "hardware trouble (laser, motor or other malfunction)");
        assert_eq!(status_meaning(b"TM1", *b"04"), "time requested while adjust mode is off");
        assert_eq!(status_meaning(b"XX", *b"0D"), "undefined command");
    }
}
