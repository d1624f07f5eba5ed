//! The Hokuyo lidar's SCIP 2.0 protocol (the UTM-30LX-EW over TCP, its USB relatives over a
//! serial port): the character codec ([`codec`]), replies cut from the byte stream
//! ([`message`]), the sensor's parameters (`PP`) checked against the lidar model, a streamed
//! scan decoded (`MD`, `ME`), and the driver ([`driver`]).

pub mod codec;
pub mod driver;
pub mod message;

pub use driver::{Lidar, LidarConfig, LidarError};
pub use message::{Message, MessageError, Reader};

use crate::sensor::LidarModel;
use std::collections::BTreeMap;

/// The sensor's beam geometry and range, from its `PP` reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SensorParams {
    /// Model (`MODL`).
    pub model: String,
    /// Shortest range, mm (`DMIN`); smaller values in a scan are error codes.
    pub dmin_mm: u32,
    /// Longest range, mm (`DMAX`).
    pub dmax_mm: u32,
    /// Steps per revolution (`ARES`).
    pub ares: u32,
    /// First measured step (`AMIN`).
    pub amin: u32,
    /// Last measured step (`AMAX`).
    pub amax: u32,
    /// The step straight ahead (`AFRT`).
    pub afrt: u32,
    /// Mirror speed, rpm (`SCAN`).
    pub scan_rpm: u32,
}

/// Why a reply is not what a command expects.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReplyError {
    /// A parameter is missing from `PP`.
    #[error("the PP reply has no {0}")]
    Missing(&'static str),
    /// A parameter is not a number.
    #[error("the PP reply's {key} is not a number: {value:?}")]
    NotNumber {
        /// Which.
        key: &'static str,
        /// What stood there.
        value: String,
    },
    /// The scan's time stamp line is missing or malformed.
    #[error("the scan has no time stamp line")]
    NoStamp,
    /// The scan's data has a length that is not a whole number of values.
    #[error("the scan's data is {chars} characters: not a whole number of {width}-character values")]
    Ragged {
        /// Characters.
        chars: usize,
        /// Characters per value.
        width: usize,
    },
    /// A character out of SCIP's range.
    #[error("the scan's data has a character out of SCIP's range")]
    BadCharacter,
    /// The geometry of the sensor differs from the lidar model's.
    #[error("the sensor's {what} is {sensor}, the configured lidar model's {model}")]
    Mismatch {
        /// Which figure.
        what: &'static str,
        /// The sensor's value.
        sensor: String,
        /// The model's.
        model: String,
    },
}

/// The `KEY:value` lines of a `PP`, `VV` or `II` reply (without their `;`).
pub fn key_values(m: &Message) -> BTreeMap<String, String> {
    m.lines
        .iter()
        .filter_map(|l| {
            let text = String::from_utf8_lossy(l);
            let text = text.strip_suffix(';').unwrap_or(&text);
            text.split_once(':').map(|(k, v)| (k.trim().to_string(), v.to_string()))
        })
        .collect()
}

impl SensorParams {
    /// The parameters of a `PP` reply.
    pub fn from_pp(m: &Message) -> Result<Self, ReplyError> {
        let kv = key_values(m);
        let num = |key: &'static str| -> Result<u32, ReplyError> {
            let v = kv.get(key).ok_or(ReplyError::Missing(key))?;
            let digits: String = v.chars().take_while(char::is_ascii_digit).collect();
            digits.parse().map_err(|_| ReplyError::NotNumber { key, value: v.clone() })
        };
        Ok(Self {
            model: kv.get("MODL").cloned().ok_or(ReplyError::Missing("MODL"))?,
            dmin_mm: num("DMIN")?,
            dmax_mm: num("DMAX")?,
            ares: num("ARES")?,
            amin: num("AMIN")?,
            amax: num("AMAX")?,
            afrt: num("AFRT")?,
            scan_rpm: num("SCAN")?,
        })
    }

    /// Steps measured in a scan.
    pub fn steps(&self) -> usize {
        self.amax.saturating_sub(self.amin) as usize + 1
    }

    /// Time of one mirror revolution, seconds.
    pub fn scan_period_s(&self) -> f64 {
        60.0 / f64::from(self.scan_rpm.max(1))
    }

    /// Time from one step to the next, seconds: 60 / (SCAN x ARES).
    pub fn step_s(&self) -> f64 {
        60.0 / (f64::from(self.scan_rpm.max(1)) * f64::from(self.ares.max(1)))
    }

    /// Checks the sensor against the configured lidar model: beams, angular resolution, a
    /// field of view centred on the front step, the row period, and ranges within the
    /// sensor's. A mismatch names both values.
    pub fn check(&self, model: &LidarModel) -> Result<(), ReplyError> {
        let mismatch =
            |what, sensor: String, model: String| Err(ReplyError::Mismatch { what, sensor, model });
        if self.steps() != model.beams() {
            return mismatch(
                "beam count (AMAX - AMIN + 1)",
                self.steps().to_string(),
                model.beams().to_string(),
            );
        }
        let res_deg = 360.0 / f64::from(self.ares.max(1));
        let model_res = model.spec().resolution_deg;
        if (res_deg - model_res).abs() > 1e-9 {
            return mismatch(
                "angular resolution (360 / ARES)",
                format!("{res_deg} deg"),
                format!("{model_res} deg"),
            );
        }
        if self.afrt.checked_sub(self.amin) != self.amax.checked_sub(self.afrt) {
            let sensor = format!("steps {}..{} around {}", self.amin, self.amax, self.afrt);
            return mismatch("field of view", sensor, "centred on the front step".into());
        }
        if (self.scan_period_s() - model.row_period_s()).abs() > 1e-9 {
            return mismatch(
                "scan period (60 / SCAN)",
                format!("{} s", self.scan_period_s()),
                format!("{} s", model.row_period_s()),
            );
        }
        let (dmin, dmax) = (f64::from(self.dmin_mm) * 1e-3, f64::from(self.dmax_mm) * 1e-3);
        if model.range_min_m() < dmin || model.range_max_m() > dmax {
            return mismatch(
                "range (DMIN..DMAX)",
                format!("{dmin}..{dmax} m"),
                format!("{}..{} m", model.range_min_m(), model.range_max_m()),
            );
        }
        Ok(())
    }
}

/// One streamed scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// The sensor's time of the scan's first step, ms (24 bits).
    pub stamp_ms: u32,
    /// Range of each step, mm (values below DMIN are error codes).
    pub ranges_mm: Vec<u32>,
    /// Intensity of each step (`ME` only).
    pub intensities: Option<Vec<u32>>,
    /// Remaining scans, from the echo (it counts down; 0 for an endless stream).
    pub remaining: Option<u32>,
}

impl Scan {
    /// The scan of an `MD` (3-character ranges) or `ME` (range and intensity) message; a
    /// value split over two data lines is joined first.
    pub fn from_message(m: &Message, with_intensity: bool) -> Result<Self, ReplyError> {
        let stamp_line = m.lines.first().ok_or(ReplyError::NoStamp)?;
        let stamp_ms = (stamp_line.len() == 4)
            .then(|| codec::decode(stamp_line))
            .flatten()
            .ok_or(ReplyError::NoStamp)?;
        let data: Vec<u8> = m.lines[1..].concat();
        let width = if with_intensity { 6 } else { 3 };
        if !data.len().is_multiple_of(width) {
            return Err(ReplyError::Ragged { chars: data.len(), width });
        }
        let values: Vec<u32> =
            data.chunks_exact(3).map(codec::decode).collect::<Option<_>>().ok_or(ReplyError::BadCharacter)?;
        let (ranges_mm, intensities) = if with_intensity {
            (
                values.iter().step_by(2).copied().collect(),
                Some(values.iter().skip(1).step_by(2).copied().collect()),
            )
        } else {
            (values, None)
        };
        let remaining =
            m.echo.get(13..15).and_then(|d| std::str::from_utf8(d).ok()).and_then(|d| d.parse().ok());
        Ok(Self { stamp_ms, ranges_mm, intensities, remaining })
    }

    /// The ranges in metres, with the sensor's error codes (below DMIN) and anything beyond
    /// the model's range as 0, "no return", as the simulated rows have them.
    pub fn ranges_m(&self, p: &SensorParams, model: &LidarModel) -> Vec<f32> {
        self.ranges_mm
            .iter()
            .map(|&mm| {
                let r = f64::from(mm) * 1e-3;
                if mm < p.dmin_mm || !model.in_range(r) {
                    0.0
                } else {
                    r as f32
                }
            })
            .collect()
    }
}

/// The message lines of a scan: the 4-character stamp with its check, then the encoded
/// values cut in 64-character blocks, each with its check (the inverse of
/// [`Scan::from_message`], for emulators and tests).
pub fn scan_lines(stamp_ms: u32, values: &[(u32, Option<u32>)]) -> Vec<Vec<u8>> {
    let with_check = |body: &[u8]| {
        let mut l = body.to_vec();
        l.push(codec::check_char(body));
        l
    };
    let stamp = codec::encode(stamp_ms & 0xff_ffff, 4).unwrap_or_default();
    let mut data = Vec::with_capacity(values.len() * 6);
    for (r, i) in values {
        data.extend(codec::encode((*r).min(262_143), 3).unwrap_or_default());
        if let Some(i) = i {
            data.extend(codec::encode((*i).min(262_143), 3).unwrap_or_default());
        }
    }
    let mut lines = vec![with_check(&stamp)];
    lines.extend(data.chunks(64).map(with_check));
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pp() -> Message {
        let mut r = Reader::new();
        r.push(b"PP\n00P\nMODL:UTM-30LX-EW;I\nDMIN:23;7\nDMAX:60000;J\nARES:1440;^\nAMIN:0;?\nAMAX:1080;Z\nAFRT:540;0\nSCAN:2400;U\n\n");
        r.next_message().expect("a reply").expect("valid")
    }

    #[test]
    fn the_utm_30lx_ew_parameters_fit_the_default_lidar_and_a_mismatch_names_both_values() {
        let p = SensorParams::from_pp(&pp()).expect("parameters");
        assert_eq!(p.model, "UTM-30LX-EW");
        assert_eq!(
            (p.dmin_mm, p.dmax_mm, p.ares, p.amin, p.amax, p.afrt, p.scan_rpm),
            (23, 60000, 1440, 0, 1080, 540, 2400)
        );
        assert!((p.step_s() - 60.0 / (2400.0 * 1440.0)).abs() < 1e-15);
        let model = LidarModel::from_spec(&crate::scenario::LidarSpec::default());
        p.check(&model).expect("the paper's lidar");
        let urg = SensorParams { ares: 1024, amin: 44, amax: 725, afrt: 384, scan_rpm: 600, ..p.clone() };
        let e = urg.check(&model).expect_err("a URG-04LX is not the model").to_string();
        assert!(e.contains("682") && e.contains("1081"), "{e}");
        let slow = SensorParams { scan_rpm: 1200, ..p };
        let e = slow.check(&model).expect_err("another period").to_string();
        assert!(e.contains("0.05 s") && e.contains("0.025 s"), "{e}");
    }

    #[test]
    fn a_scan_with_a_value_across_two_lines_decodes() {
        // 30 values 1000..1029: the 22nd straddles the 64-character line (notes: SCIP A6).
        let values: Vec<(u32, Option<u32>)> = (1000..1030).map(|v| (v, None)).collect();
        let lines = scan_lines(16_000_000, &values);
        assert_eq!(lines[1].len(), 65, "64 characters and the check");
        assert_eq!(&lines[1][..], b"0?X0?Y0?Z0?[0?\\0?]0?^0?_0?`0?a0?b0?c0?d0?e0?f0?g0?h0?i0?j0?k0?l0E");
        assert_eq!(&lines[2][..], b"?m0?n0?o0@00@10@20@30@40@5f");
        let mut bytes = b"MD0000002901001\n99b\n".to_vec();
        for l in &lines {
            bytes.extend(l);
            bytes.push(b'\n');
        }
        bytes.push(b'\n');
        let mut r = Reader::new();
        r.push(&bytes);
        let m = r.next_message().expect("a reply").expect("valid");
        let s = Scan::from_message(&m, false).expect("a scan");
        assert_eq!(s.stamp_ms, 16_000_000);
        assert_eq!(s.ranges_mm, (1000..1030).collect::<Vec<_>>());
        assert_eq!(s.remaining, Some(1));
        // With intensities: pairs.
        let pairs: Vec<(u32, Option<u32>)> = (0..5).map(|k| (2000 + k, Some(100 + k))).collect();
        let mut m2 = m.clone();
        m2.lines = scan_lines(5, &pairs)
            .into_iter()
            .map(|mut l| {
                l.pop();
                l
            })
            .collect();
        let s = Scan::from_message(&m2, true).expect("a scan");
        assert_eq!(s.ranges_mm, vec![2000, 2001, 2002, 2003, 2004]);
        assert_eq!(s.intensities, Some(vec![100, 101, 102, 103, 104]));
        m2.lines[1].pop();
        assert!(matches!(Scan::from_message(&m2, true), Err(ReplyError::Ragged { .. })));
    }

    #[test]
    fn error_codes_below_dmin_are_no_return() {
        let p = SensorParams::from_pp(&pp()).expect("parameters");
        let model = LidarModel::from_spec(&crate::scenario::LidarSpec::default());
        let s = Scan {
            stamp_ms: 0,
            ranges_mm: vec![1, 5, 22, 23, 1500, 40_000],
            intensities: None,
            remaining: None,
        };
        assert_eq!(
            s.ranges_m(&p, &model),
            vec![0.0, 0.0, 0.0, 0.0, 1.5, 0.0],
            "23 mm is below the model's 0.1 m"
        );
    }
}
