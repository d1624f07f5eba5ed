//! Reading a recording back: the raw lidar rows of every sweep (so perception can be rerun on
//! them, or the sweeps fed to the loop again as a [`Source`]), what perception found and
//! what was planned at the time, and the attached scenario and parameters. Messages are read
//! into the same types they were written from ([`super::messages`]). A truncated or corrupt
//! file gives every complete record before the damage, and says where it stopped.

use super::foxglove::{LaserScan, PointCloud};
use super::messages::{PerceptionMsg, PlanMsg, SweepMsg, TrajectoryMsg, ViewMsg};
use crate::cancel::Cancel;
use crate::sensor::{LidarModel, ScanRow, SensorError, Source, Sweep};
use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use nalgebra::Vector3;
use std::collections::HashMap;

/// A sweep as recorded.
#[derive(Debug, Clone)]
pub struct RecordedSweep {
    /// When it was taken (log time), seconds.
    pub stamp_s: f64,
    /// Its rows and what is needed to assemble them.
    pub sweep: Sweep,
    /// What perception found on it at the time (`/perception/result`), if recorded.
    pub perception: Option<PerceptionMsg>,
    /// The cloud assembled at the time (`/cloud`), if recorded.
    pub cloud: Option<Vec<nalgebra::Point3<f32>>>,
    /// How its view was taken into the step map and the surroundings (`/run/view`), if
    /// recorded.
    pub view: Option<ViewMsg>,
    /// The plan made after this sweep (`/plan`), if recorded.
    pub plan: Option<PlanMsg>,
    /// Its planned q(t) (`/plan/trajectory`), if recorded.
    pub trajectory: Option<TrajectoryMsg>,
}

/// What a recording holds.
#[derive(Debug, Default)]
pub struct Recording {
    /// Every sweep, in order.
    pub sweeps: Vec<RecordedSweep>,
    /// Attachments by name (`scenario.toml`, `params.toml`).
    pub attachments: HashMap<String, Vec<u8>>,
    /// Metadata records by name.
    pub metadata: HashMap<String, std::collections::BTreeMap<String, String>>,
    /// Messages read, per topic.
    pub counts: std::collections::BTreeMap<String, usize>,
    /// Why reading stopped before the end of the file, if it did (damage).
    pub damage: Option<String>,
}

/// Why a recording cannot be read at all.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The file.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not an MCAP file.
    #[error("{0}: not an MCAP file ({1})")]
    NotMcap(String, String),
}

/// Reads the recording at `path`.
pub fn read(path: &std::path::Path) -> Result<Recording, ReplayError> {
    let bytes =
        std::fs::read(path).map_err(|source| ReplayError::Io { path: path.display().to_string(), source })?;
    read_bytes(&bytes).map_err(|e| ReplayError::NotMcap(path.display().to_string(), e))
}

/// A message's payload as `T`, or why not.
fn parse<'a, T: serde::Deserialize<'a>>(topic: &str, data: &'a [u8]) -> Result<T, String> {
    serde_json::from_slice(data).map_err(|e| format!("bad {topic} message: {e}"))
}

/// [`read`] from memory.
pub fn read_bytes(bytes: &[u8]) -> Result<Recording, String> {
    if !bytes.starts_with(mcap::MAGIC) {
        return Err("it does not start with MCAP's magic bytes".into());
    }
    let (sound, damage) = sound_prefix(bytes);
    let records = Flattened::new(&bytes[..sound]);
    let mut rec = Recording { damage, ..Recording::default() };
    let mut topics: HashMap<u16, String> = HashMap::new();
    let mut open: Option<(RecordedSweep, usize)> = None;
    for r in records {
        let r = match r {
            Ok(r) => r,
            Err(e) => {
                rec.damage = Some(format!("stopped at damaged data: {e}"));
                break;
            }
        };
        let (header, data) = match r {
            Record::Channel(c) => {
                topics.insert(c.id, c.topic);
                continue;
            }
            Record::Attachment { header, data, .. } => {
                rec.attachments.insert(header.name, data.into_owned());
                continue;
            }
            Record::Metadata(m) => {
                rec.metadata.insert(m.name, m.metadata);
                continue;
            }
            Record::Message { header, data } => (header, data),
            _ => continue,
        };
        let Some(topic) = topics.get(&header.channel_id) else { continue };
        *rec.counts.entry(topic.clone()).or_default() += 1;
        if let Err(e) = take(topic, &data, header.log_time, &mut rec, &mut open) {
            rec.damage = Some(e);
            break;
        }
    }
    // A sweep whose rows were cut off by damage is not replayed.
    if let Some((s, rows)) = open.take() {
        if s.sweep.rows.len() == rows {
            rec.sweeps.push(s);
        } else if rec.damage.is_none() {
            rec.damage = Some(format!("the last sweep has {} of its {rows} rows", s.sweep.rows.len()));
        }
    }
    Ok(rec)
}

/// How many leading bytes of an MCAP file hold sound top-level records, and why it ends
/// there if not at the end. A damaged chunk header can claim an uncompressed size of
/// exabytes, and the reader reserves it before decompressing (an abort, not an error); a
/// chunk is taken only when its records fit in the file and its uncompressed size is
/// within what any codec reaches (1024 times the compressed size, plus 1 MiB).
fn sound_prefix(bytes: &[u8]) -> (usize, Option<String>) {
    const CHUNK: u8 = 0x06;
    let u64_at =
        |at: usize| bytes.get(at..at + 8).map(|b| u64::from_le_bytes(b.try_into().unwrap_or([0; 8])));
    let u32_at =
        |at: usize| bytes.get(at..at + 4).map(|b| u32::from_le_bytes(b.try_into().unwrap_or([0; 4])));
    let mut at = mcap::MAGIC.len();
    while at < bytes.len() {
        let (Some(&op), Some(len)) = (bytes.get(at), u64_at(at + 1)) else { break };
        let body = at + 9;
        let Some(end) = usize::try_from(len).ok().and_then(|l| body.checked_add(l)) else {
            return (at, Some(format!("stopped at damaged data: a record at byte {at} claims {len} bytes")));
        };
        if end > bytes.len() {
            break; // cut short: the reader reports it
        }
        if op == CHUNK {
            // start, end times; uncompressed size, CRC; compression; records length.
            let uncompressed = u64_at(body + 16).unwrap_or(u64::MAX);
            let name_len = u32_at(body + 28).map_or(usize::MAX, |n| n as usize);
            let compressed =
                body.checked_add(name_len.saturating_add(32)).and_then(u64_at).unwrap_or(u64::MAX);
            if compressed > len || uncompressed > compressed.saturating_mul(1024).saturating_add(1 << 20) {
                return (
                    at,
                    Some(format!("stopped at damaged data: the chunk at byte {at} claims {uncompressed} bytes uncompressed")),
                );
            }
        }
        at = end;
    }
    (bytes.len(), None)
}

/// The records of an MCAP file with its chunks unpacked, as the mcap crate's
/// `ChunkFlattener` gives them, but with a limit on a record's claimed length: a byte
/// flipped in a chunk's compressed data (its CRC is checked only once the chunk is read)
/// can make a record inside it claim exabytes, and the crate's reader reserved that much
/// and aborted (tests/record.rs's damaged-file test, seen on a clean clone). No record is
/// longer than 16 times the file (a chunk's contents compress a few times at most).
struct Flattened<'a> {
    rest: &'a [u8],
    reader: LinearReader,
}

impl<'a> Flattened<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        let options = LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_validate_chunk_crcs(true)
            .with_record_length_limit(bytes.len().saturating_mul(16).max(1 << 20));
        Self { rest: bytes, reader: LinearReader::new_with_options(options) }
    }
}

impl Iterator for Flattened<'_> {
    type Item = Result<Record<'static>, mcap::McapError>;

    fn next(&mut self) -> Option<Self::Item> {
        while let Some(event) = self.reader.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let n = need.min(self.rest.len());
                    self.reader.insert(n).copy_from_slice(&self.rest[..n]);
                    self.reader.notify_read(n);
                    self.rest = &self.rest[n..];
                }
                Ok(LinearReadEvent::Record { data, opcode }) => {
                    return Some(mcap::parse_record(opcode, data).map(|r| r.into_owned()))
                }
                Err(e) => return Some(Err(e)),
            }
        }
        None
    }
}

/// Takes one message of `topic` into the recording (a new sweep, or a part of the open one).
fn take(
    topic: &str,
    data: &[u8],
    log_time_ns: u64,
    rec: &mut Recording,
    open: &mut Option<(RecordedSweep, usize)>,
) -> Result<(), String> {
    match topic {
        "/lidar/sweep" => {
            if let Some((s, _)) = open.take() {
                rec.sweeps.push(s);
            }
            *open = Some(sweep_of(parse(topic, data)?, log_time_ns as f64 * 1e-9)?);
        }
        "/lidar/scan" => {
            if let Some((s, _)) = open.as_mut() {
                s.sweep.rows.push(row_of(parse(topic, data)?)?);
            }
        }
        "/perception/result" => {
            if let Some((s, _)) = open.as_mut() {
                s.perception = Some(parse(topic, data)?);
            }
        }
        "/run/view" => {
            if let Some((s, _)) = open.as_mut() {
                s.view = Some(parse(topic, data)?);
            }
        }
        "/plan" => {
            if let Some((s, _)) = open.as_mut() {
                s.plan = Some(parse(topic, data)?);
            }
        }
        "/plan/trajectory" => {
            if let Some((s, _)) = open.as_mut() {
                s.trajectory = Some(parse(topic, data)?);
            }
        }
        "/cloud" => {
            if let Some((s, _)) = open.as_mut() {
                s.cloud = parse::<PointCloud>(topic, data)?.xyz();
            }
        }
        _ => {}
    }
    Ok(())
}

fn sweep_of(m: SweepMsg, stamp_s: f64) -> Result<(RecordedSweep, usize), String> {
    // The spec is checked as part of a scenario (its validation covers the lidar table).
    crate::scenario::Scenario { lidar: m.lidar.clone(), ..Default::default() }
        .validate()
        .map_err(|e| format!("bad /lidar/sweep message: {}: {}", e.field, e.reason))?;
    let mount_to_world = m.mount_to_world.isometry().map_err(|e| format!("bad /lidar/sweep message: {e}"))?;
    let sweep =
        Sweep { rows: Vec::with_capacity(m.rows), lidar: LidarModel::from_spec(&m.lidar), mount_to_world };
    let s = RecordedSweep {
        stamp_s,
        sweep,
        perception: None,
        cloud: None,
        view: None,
        plan: None,
        trajectory: None,
    };
    Ok((s, m.rows))
}

fn row_of(m: LaserScan) -> Result<ScanRow, String> {
    let [x, y, z] = m.stairbench_gravity_mount;
    let mount_to_world = match &m.stairbench_mount_to_world {
        Some(pose) => Some(pose.isometry().map_err(|e| format!("bad /lidar/scan message: {e}"))?),
        None => None,
    };
    Ok(ScanRow {
        stamp_s: m.stairbench_stamp_s,
        tilt_rad: m.stairbench_tilt_rad,
        ranges_m: m.ranges,
        gravity_mount: Vector3::new(x, y, z),
        mount_to_world,
    })
}

/// A recording's sweeps as a [`Source`]: each call gives the next recorded sweep, as it was
/// recorded; after the last, [`SensorError::Exhausted`].
pub struct ReplaySource {
    sweeps: std::vec::IntoIter<Sweep>,
    given: usize,
}

impl ReplaySource {
    /// The sweeps of `rec`, in order.
    pub fn new(rec: &Recording) -> Self {
        let sweeps: Vec<Sweep> = rec.sweeps.iter().map(|s| s.sweep.clone()).collect();
        Self { sweeps: sweeps.into_iter(), given: 0 }
    }
}

impl Source for ReplaySource {
    fn sweep(
        &mut self,
        cancel: &Cancel,
        on_rows: &mut dyn FnMut(usize, usize),
    ) -> Result<Sweep, SensorError> {
        if cancel.is_cancelled() {
            return Err(SensorError::Cancelled { rows: 0 });
        }
        let sweep = self.sweeps.next().ok_or(SensorError::Exhausted { given: self.given })?;
        self.given += 1;
        on_rows(sweep.rows.len(), sweep.rows.len());
        Ok(sweep)
    }
}
