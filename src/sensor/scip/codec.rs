//! SCIP 2.0's character encoding and check characters (Hokuyo, "Communication Protocol
//! Specification for SCIP2.0 Standard", C-42-03320B, pp. 6-10): each character carries six bits
//! as `value + 0x30`, the most significant first (2, 3 or 4 characters per value); a line's
//! check character is the low six bits of the sum of its bytes plus 0x30, the `;` before the
//! check character of a parameter line (`PP`, `VV`, `II`) not summed.

/// The check character of `bytes` (the line without its check character and LF).
pub fn check_char(bytes: &[u8]) -> u8 {
    let sum = bytes.iter().fold(0u32, |s, &b| s.wrapping_add(u32::from(b)));
    ((sum & 0x3f) as u8) + 0x30
}

/// Whether `line` (without its LF) ends with the right check character: a data, status or
/// time-stamp line summed whole, or a parameter line `NAME:value;C` summed up to the `;`.
/// Accepts both readings for a parameter line, as a robust reader should (urg_c does too).
pub fn line_checks(line: &[u8]) -> bool {
    let Some((&check, body)) = line.split_last() else { return false };
    if body.is_empty() {
        return false;
    }
    if check_char(body) == check {
        return true;
    }
    matches!(body.split_last(), Some((b';', before)) if check_char(before) == check)
}

/// Decodes a SCIP value of 1 to 4 characters (each 0x30..=0x6f); `None` for a character out
/// of range or a length SCIP does not use.
pub fn decode(chars: &[u8]) -> Option<u32> {
    if chars.is_empty() || chars.len() > 4 {
        return None;
    }
    chars.iter().try_fold(0u32, |v, &c| (0x30..=0x6f).contains(&c).then(|| (v << 6) | u32::from(c - 0x30)))
}

/// Encodes `value` in `width` characters (2, 3 or 4); `None` when it does not fit.
pub fn encode(value: u32, width: usize) -> Option<Vec<u8>> {
    if !(1..=4).contains(&width) || u64::from(value) >= 1u64 << (6 * width) {
        return None;
    }
    Some((0..width).rev().map(|k| ((value >> (6 * k)) & 0x3f) as u8 + 0x30).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_specifications_encoding_examples() {
        // SCIP 2.0 spec pp. 6-8: 1234 = "CB", 5432 = "1Dh", 16 000 000 = "m2@0".
        assert_eq!(decode(b"CB"), Some(1234));
        assert_eq!(decode(b"1Dh"), Some(5432));
        assert_eq!(decode(b"m2@0"), Some(16_000_000));
        assert_eq!(encode(1234, 2).as_deref(), Some(&b"CB"[..]));
        assert_eq!(encode(5432, 3).as_deref(), Some(&b"1Dh"[..]));
        assert_eq!(encode(16_000_000, 4).as_deref(), Some(&b"m2@0"[..]));
        assert_eq!(encode(4096, 2), None, "12 bits hold 0..=4095");
        assert_eq!(decode(b"oooo"), Some((1 << 24) - 1));
        assert_eq!(decode(b"C\x7f"), None, "a character above 0x6f");
        assert_eq!(decode(b""), None);
    }

    #[test]
    fn check_characters_of_the_published_lines() {
        // Status lines (spec pp. 11, 14) and a UTM-30LX-EW's PP reply, the `;` not summed.
        for line in [
            &b"00P"[..],
            b"99b",
            b"MODL:UTM-30LX-EW;I",
            b"DMIN:23;7",
            b"DMAX:60000;J",
            b"ARES:1440;^",
            b"AMIN:0;?",
            b"AMAX:1080;Z",
            b"AFRT:540;0",
            b"SCAN:2400;U",
        ] {
            assert!(line_checks(line), "{}", String::from_utf8_lossy(line));
        }
        // Hokuyo's wiki: VV and II replies of a URG-04LX.
        for line in [
            &b"VEND:Hokuyo Automatic Co.,Ltd.;["[..],
            b"PROT:SCIP 2.0;N",
            b"SERI:H0614967;V",
            b"STAT:Sensor works well.;8",
            b"FIRM:3.1.00(18/Jan./2007);`",
        ] {
            assert!(line_checks(line), "{}", String::from_utf8_lossy(line));
        }
        assert_eq!(check_char(b"00"), b'P');
        assert_eq!(check_char(b"99"), b'b');
        assert!(!line_checks(b"00Q"), "a wrong check character");
        assert!(!line_checks(b"DMIN:24;7"));
        assert!(!line_checks(b"P"), "no body");
        // A data line of the spec's values: 1234, 5432, 23 in three characters each.
        let data = b"0CB1Dh00G";
        let mut line = data.to_vec();
        line.push(check_char(data));
        assert!(line_checks(&line));
    }
}
