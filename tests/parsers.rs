//! The device parsers never panic and never loop (issue 17): the SCIP 2.0 reply reader, the
//! scan and parameter decoders, and the Dynamixel packet readers of both protocols, fed
//! arbitrary bytes and mutations of valid streams in arbitrary pieces. Each call of a reader
//! returns or consumes: the calls are bounded by the bytes given. (`stairbench bench fuzz` runs
//! millions of such inputs; its figure is in BENCHMARKS.md.)

use proptest::prelude::*;
use stairbench::sensor::dynamixel::packet::{self, Protocol, StatusReader};
use stairbench::sensor::fuzz::{self, Edit};
use stairbench::sensor::scip::codec;

fn scip_drain(bytes: &[u8], piece: usize) {
    assert_eq!(fuzz::scip_drain(bytes, piece).err(), None, "the SCIP reader loops");
}

fn dynamixel_drain(p: Protocol, bytes: &[u8], piece: usize) {
    assert_eq!(fuzz::dynamixel_drain(p, bytes, piece).err(), None, "the Dynamixel readers loop");
}

/// Edits from proptest's draws: (position, kind, byte).
fn edits(raw: &[(usize, u8, u8)]) -> Vec<Edit> {
    raw.iter()
        .map(|&(at, kind, b)| match kind % 5 {
            0 => Edit::Flip(at, b),
            1 => Edit::Insert(at, b),
            2 => Edit::Delete(at),
            3 => Edit::Truncate(at),
            _ => Edit::Repeat(at, usize::from(b)),
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn scip_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..4096), piece in 1usize..200) {
        scip_drain(&bytes, piece);
    }

    #[test]
    fn scip_mutated_streams(raw in proptest::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 0..12), piece in 1usize..500) {
        let s = fuzz::mutate(&fuzz::scip_stream(), &edits(&raw));
        scip_drain(&s, piece);
    }

    #[test]
    fn scip_decoding_never_panics(chars in proptest::collection::vec(any::<u8>(), 0..8), v in any::<u32>(), w in 0usize..6) {
        let _ = codec::decode(&chars);
        if let Some(e) = codec::encode(v, w) {
            prop_assert_eq!(codec::decode(&e), Some(v));
        }
        let _ = codec::line_checks(&chars);
    }

    #[test]
    fn dynamixel_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..2048), piece in 1usize..64, two in any::<bool>()) {
        let p = if two { Protocol::Two } else { Protocol::One };
        dynamixel_drain(p, &bytes, piece);
    }

    #[test]
    fn dynamixel_mutated_packets(params in proptest::collection::vec(any::<u8>(), 0..40), raw in proptest::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 0..6), piece in 1usize..32, two in any::<bool>()) {
        let p = if two { Protocol::Two } else { Protocol::One };
        let s = fuzz::mutate(&fuzz::dynamixel_stream(p, &params), &edits(&raw));
        dynamixel_drain(p, &s, piece);
    }

    #[test]
    fn stuffing_round_trips_and_a_valid_packet_reads_back(payload in proptest::collection::vec(any::<u8>(), 0..300)) {
        let stuffed = packet::stuff(&payload);
        prop_assert_eq!(packet::unstuff(&stuffed), payload.clone());
        let mut r = StatusReader::new(Protocol::Two);
        r.push(&packet::status(Protocol::Two, 7, 0, &payload));
        let s = r.next_status().expect("a status");
        prop_assert_eq!((s.id, s.error, s.params), (7, 0, payload));
    }
}
