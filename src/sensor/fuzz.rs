//! The device parsers driven on arbitrary bytes, for the property tests (`tests/parsers.rs`)
//! and `stairbench bench fuzz`: valid streams to start from, seeded mutations of them, and
//! drivers that feed a reader in pieces and drain it, reporting a reader that loops (more
//! replies than the bytes given could hold) instead of spinning.

use super::dynamixel::packet::{self, PacketReader, Protocol, StatusReader};
use super::scip::{scan_lines, Reader, Scan, SensorParams};
use rand::Rng;

/// A reader gave more messages than its input could hold: it loops.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Looped;

/// A valid SCIP 2.0 stream: a PP reply, an MD acknowledgement, a streamed scan of 1081 steps.
pub fn scip_stream() -> Vec<u8> {
    let mut s = b"PP\n00P\nMODL:UTM-30LX-EW;I\nDMIN:23;7\nDMAX:60000;J\nARES:1440;^\nAMIN:0;?\nAMAX:1080;Z\nAFRT:540;0\nSCAN:2400;U\n\nMD0000108001000\n00P\n\nMD0000108001000\n99b\n".to_vec();
    let values: Vec<(u32, Option<u32>)> = (0..1081).map(|i| (1000 + i, None)).collect();
    for l in scan_lines(123_456, &values) {
        s.extend(l);
        s.push(b'\n');
    }
    s.push(b'\n');
    s
}

/// A valid Dynamixel stream of `protocol`: a status packet and an instruction carrying
/// `params`.
pub fn dynamixel_stream(protocol: Protocol, params: &[u8]) -> Vec<u8> {
    let mut s = packet::status(protocol, 1, 0, params);
    s.extend(packet::instruction(protocol, 1, 2, params));
    s
}

/// Feeds `bytes` to a SCIP reader in pieces of `piece` bytes, draining it after each, and
/// decodes every reply as a scan (with and without intensities) and as a PP reply. Returns the
/// replies and errors the reader gave.
pub fn scip_drain(bytes: &[u8], piece: usize) -> Result<usize, Looped> {
    let mut r = Reader::new();
    let mut seen = 0;
    for chunk in bytes.chunks(piece.max(1)) {
        r.push(chunk);
        let mut calls = 0;
        while let Some(m) = r.next_message() {
            calls += 1;
            if calls > bytes.len() + 1 {
                return Err(Looped);
            }
            seen += 1;
            if let Ok(m) = m {
                let _ = Scan::from_message(&m, false);
                let _ = Scan::from_message(&m, true);
                let _ = SensorParams::from_pp(&m);
            }
        }
    }
    Ok(seen)
}

/// Feeds `bytes` to the status reader (the driver's side) and the instruction reader (the
/// emulator's side) of `protocol` in pieces, draining both. Returns the packets they gave.
pub fn dynamixel_drain(protocol: Protocol, bytes: &[u8], piece: usize) -> Result<usize, Looped> {
    let mut packets = PacketReader::new(protocol);
    let mut statuses = StatusReader::new(protocol);
    let mut seen = 0;
    for chunk in bytes.chunks(piece.max(1)) {
        packets.push(chunk);
        statuses.push(chunk);
        let mut calls = 0;
        while packets.next_packet().is_some() || statuses.next_status().is_some() {
            calls += 1;
            if calls > bytes.len() + 1 {
                return Err(Looped);
            }
            seen += 1;
        }
    }
    Ok(seen)
}

/// One edit of a byte stream.
#[derive(Debug, Clone, Copy)]
pub enum Edit {
    /// XOR the byte at the position (taken modulo the length) with a non-zero mask.
    Flip(usize, u8),
    /// Insert a byte before the position.
    Insert(usize, u8),
    /// Delete the byte at the position.
    Delete(usize),
    /// Cut the stream at the position.
    Truncate(usize),
    /// Repeat the `len` bytes from the position after themselves.
    Repeat(usize, usize),
}

/// `stream` with `edits` applied in order; positions are taken modulo the current length.
pub fn mutate(stream: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut s = stream.to_vec();
    for e in edits {
        if s.is_empty() {
            if let Edit::Insert(_, b) = e {
                s.push(*b);
            }
            continue;
        }
        let n = s.len();
        match *e {
            Edit::Flip(at, m) => s[at % n] ^= m | 1,
            Edit::Insert(at, b) => s.insert(at % n, b),
            Edit::Delete(at) => {
                s.remove(at % n);
            }
            Edit::Truncate(at) => s.truncate(at % n),
            Edit::Repeat(at, len) => {
                let a = at % n;
                let b = (a + len).min(n);
                let copy = s[a..b].to_vec();
                s.splice(b..b, copy);
            }
        }
    }
    s
}

/// One input drawn from `rng`: most often a mutation (1 to 8 edits) of `valid`, sometimes
/// arbitrary bytes (up to `valid`'s length), and `piece` sizes from one byte to a whole stream.
pub fn draw(rng: &mut impl Rng, valid: &[u8]) -> (Vec<u8>, usize) {
    let piece = match rng.random_range(0..4) {
        0 => 1,
        1 => rng.random_range(1..16),
        2 => rng.random_range(16..256),
        _ => valid.len().max(1),
    };
    if rng.random_range(0..8) == 0 {
        let n = rng.random_range(0..=valid.len());
        return ((0..n).map(|_| rng.random()).collect(), piece);
    }
    let edits: Vec<Edit> = (0..rng.random_range(1..=8))
        .map(|_| {
            let at = rng.random_range(0..valid.len().max(1) + 1);
            match rng.random_range(0..10) {
                0..=4 => Edit::Flip(at, rng.random()),
                5 | 6 => Edit::Insert(at, rng.random()),
                7 => Edit::Delete(at),
                8 => Edit::Truncate(at),
                _ => Edit::Repeat(at, rng.random_range(1..80)),
            }
        })
        .collect();
    (mutate(valid, &edits), piece)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_valid_streams_read_back_whole_in_any_pieces() {
        let s = scip_stream();
        for piece in [1, 3, 64, 65, 1000, s.len()] {
            assert_eq!(scip_drain(&s, piece), Ok(3), "piece {piece}");
        }
        // The packet reader (the servo's side) reads both packets; the status reader reads
        // both in 1.0 (where an instruction is framed as a status) and only the status in 2.0.
        for (p, packets) in [(Protocol::One, 4), (Protocol::Two, 3)] {
            let d = dynamixel_stream(p, &[0xFF, 0xFF, 0xFD, 1, 2]);
            for piece in [1, 2, 7, d.len()] {
                assert_eq!(dynamixel_drain(p, &d, piece), Ok(packets), "{p:?} in pieces of {piece}");
            }
        }
    }

    #[test]
    fn edits_do_what_they_say() {
        let s = b"abcdef";
        assert_eq!(mutate(s, &[Edit::Truncate(3)]), b"abc");
        assert_eq!(mutate(s, &[Edit::Repeat(1, 2)]), b"abcbcdef");
        assert_eq!(mutate(s, &[Edit::Delete(6)]), b"bcdef");
        assert_eq!(mutate(s, &[Edit::Insert(2, b'x')]), b"abxcdef");
        assert_eq!(mutate(b"", &[Edit::Flip(0, 1), Edit::Insert(0, b'z')]), b"z");
    }
}
