//! Reading a recording back: the raw lidar rows of every sweep (so perception can be rerun on
//! them), what perception found at the time, and the attached scenario and parameters. A
//! truncated or corrupt file gives every complete record before the damage, and says where it
//! stopped.

use crate::scenario::LidarSpec;
use crate::sensor::{LidarModel, ScanRow, Sweep};
use mcap::read::{ChunkFlattener, Options};
use mcap::records::Record;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;
use std::collections::HashMap;

/// A sweep as recorded.
#[derive(Debug, Clone)]
pub struct RecordedSweep {
    /// When it was assembled (log time), seconds.
    pub stamp_s: f64,
    /// Its rows and what is needed to assemble them.
    pub sweep: Sweep,
    /// What perception found on it at the time (`/perception/result`), if recorded.
    pub perception: Option<Value>,
    /// The cloud assembled at the time (`/cloud`), if recorded.
    pub cloud: Option<Vec<nalgebra::Point3<f32>>>,
    /// The plan made after this sweep (`/plan`), if recorded.
    pub plan: Option<Value>,
    /// Its planned q(t) (`/plan/trajectory`), if recorded.
    pub trajectory: Option<Value>,
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

/// [`read`] from memory.
pub fn read_bytes(bytes: &[u8]) -> Result<Recording, String> {
    if !bytes.starts_with(mcap::MAGIC) {
        return Err("it does not start with MCAP's magic bytes".into());
    }
    let options = Options::IgnoreEndMagic | Options::ValidateChunkCrcs;
    let records = ChunkFlattener::new_with_options(bytes, options).map_err(|e| e.to_string())?;
    let mut rec = Recording::default();
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
        match r {
            Record::Channel(c) => {
                topics.insert(c.id, c.topic);
            }
            Record::Attachment { header, data, .. } => {
                rec.attachments.insert(header.name, data.into_owned());
            }
            Record::Metadata(m) => {
                rec.metadata.insert(m.name, m.metadata);
            }
            Record::Message { header, data } => {
                let Some(topic) = topics.get(&header.channel_id) else { continue };
                *rec.counts.entry(topic.clone()).or_default() += 1;
                let Ok(v) = serde_json::from_slice::<Value>(&data) else {
                    rec.damage = Some(format!("a {topic} message is not JSON"));
                    break;
                };
                let stamp_s = header.log_time as f64 * 1e-9;
                match topic.as_str() {
                    "/lidar/sweep" => {
                        if let Some((s, _)) = open.take() {
                            rec.sweeps.push(s);
                        }
                        match sweep_of(&v, stamp_s) {
                            Ok(s) => open = Some(s),
                            Err(e) => {
                                rec.damage = Some(format!("bad /lidar/sweep message: {e}"));
                                break;
                            }
                        }
                    }
                    "/lidar/scan" => {
                        if let Some((s, _)) = open.as_mut() {
                            match row_of(&v) {
                                Ok(row) => s.sweep.rows.push(row),
                                Err(e) => {
                                    rec.damage = Some(format!("bad /lidar/scan message: {e}"));
                                    break;
                                }
                            }
                        }
                    }
                    "/perception/result" => {
                        if let Some((s, _)) = open.as_mut() {
                            s.perception = Some(v);
                        }
                    }
                    "/plan" => {
                        if let Some((s, _)) = open.as_mut() {
                            s.plan = Some(v);
                        }
                    }
                    "/plan/trajectory" => {
                        if let Some((s, _)) = open.as_mut() {
                            s.trajectory = Some(v);
                        }
                    }
                    "/cloud" => {
                        if let Some((s, _)) = open.as_mut() {
                            s.cloud = super::foxglove::point_cloud_xyz(&v);
                        }
                    }
                    _ => {}
                }
            }
            _ => {}
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

fn sweep_of(v: &Value, stamp_s: f64) -> Result<(RecordedSweep, usize), String> {
    let spec: LidarSpec = serde_json::from_value(v["lidar"].clone()).map_err(|e| e.to_string())?;
    // The spec is checked as part of a scenario (its validation covers the lidar table).
    crate::scenario::Scenario { lidar: spec.clone(), ..Default::default() }
        .validate()
        .map_err(|e| format!("{}: {}", e.field, e.reason))?;
    let rows = v["rows"].as_u64().ok_or("no row count")? as usize;
    let nums = |x: &Value, n: usize| -> Result<Vec<f64>, String> {
        let a = x.as_array().ok_or("not an array")?;
        let out: Vec<f64> = a.iter().filter_map(Value::as_f64).collect();
        if out.len() == n && out.iter().all(|x| x.is_finite()) {
            Ok(out)
        } else {
            Err("bad numbers".into())
        }
    };
    let t = nums(&v["mount_to_world"]["translation"], 3)?;
    let r = nums(&v["mount_to_world"]["rotation"], 4)?;
    // The recorded quaternion was unit already: taken as is, so the replayed assembly is
    // bit for bit the recorded one (renormalizing would change the last bits).
    let q = Quaternion::new(r[0], r[1], r[2], r[3]);
    let rotation = if (q.norm() - 1.0).abs() < 1e-12 {
        UnitQuaternion::new_unchecked(q)
    } else {
        UnitQuaternion::try_new(q, 1e-9).ok_or("the mount rotation is not a rotation")?
    };
    let mount_to_world = Isometry3::from_parts(Translation3::new(t[0], t[1], t[2]), rotation);
    let sweep = Sweep { rows: Vec::with_capacity(rows), lidar: LidarModel::from_spec(&spec), mount_to_world };
    Ok((RecordedSweep { stamp_s, sweep, perception: None, cloud: None, plan: None, trajectory: None }, rows))
}

fn row_of(v: &Value) -> Result<ScanRow, String> {
    let num = |k: &str| v[k].as_f64().filter(|x| x.is_finite()).ok_or_else(|| format!("no {k}"));
    let g = v["stairbench_gravity_mount"].as_array().ok_or("no gravity")?;
    let g: Vec<f64> = g.iter().filter_map(Value::as_f64).collect();
    if g.len() != 3 {
        return Err("gravity is not 3 numbers".into());
    }
    let ranges = v["ranges"].as_array().ok_or("no ranges")?;
    let ranges_m: Vec<f32> = ranges.iter().map(|x| x.as_f64().unwrap_or(0.0) as f32).collect();
    Ok(ScanRow {
        stamp_s: num("stairbench_stamp_s")?,
        tilt_rad: num("stairbench_tilt_rad")?,
        ranges_m,
        gravity_mount: Vector3::new(g[0], g[1], g[2]),
    })
}
