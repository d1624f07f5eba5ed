//! Reading and writing point clouds: PLY (binary or ASCII) and PCD (PCL's format, binary or
//! ASCII, with its VIEWPOINT). Bad files give an error that says what is wrong, never a panic.

use super::PointCloud;
use nalgebra::Point3;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::Path;

/// Why a cloud file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum CloudIoError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file's path.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not a cloud this reader understands.
    #[error("{path}: {reason}")]
    Format {
        /// The file's path.
        path: String,
        /// What is wrong.
        reason: String,
    },
}

/// File formats for clouds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CloudFormat {
    /// Stanford PLY, binary little endian when written.
    Ply,
    /// PCL's PCD, binary when written.
    Pcd,
}

impl CloudFormat {
    /// The format named by a path's extension (`.ply`, `.pcd`).
    pub fn from_path(path: &Path) -> Option<Self> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "ply" => Some(Self::Ply),
            "pcd" => Some(Self::Pcd),
            _ => None,
        }
    }
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> CloudIoError + '_ {
    move |source| CloudIoError::Io { path: path.display().to_string(), source }
}

fn fmt_err(path: &Path, reason: impl Into<String>) -> CloudIoError {
    CloudIoError::Format { path: path.display().to_string(), reason: reason.into() }
}

/// Writes `cloud` to `path` in `format`: its points and its viewpoint. A sweep taken
/// moving keeps only its mean viewpoint (the rows' own origins are not written): read back,
/// its ground and risers are judged from there, not from where its last row was cast.
pub fn write_cloud(cloud: &PointCloud, path: &Path, format: CloudFormat) -> Result<(), CloudIoError> {
    let file = std::fs::File::create(path).map_err(io_err(path))?;
    let mut w = BufWriter::new(file);
    let n = cloud.len();
    let v = cloud.viewpoint();
    match format {
        CloudFormat::Ply => write!(
            w,
            "ply\nformat binary_little_endian 1.0\ncomment stairbench cloud, metres, gravity-aligned frame\n\
             comment viewpoint {} {} {}\nelement vertex {n}\nproperty float x\nproperty float y\n\
             property float z\nend_header\n",
            v.x, v.y, v.z
        ),
        CloudFormat::Pcd => write!(
            w,
            "# .PCD v0.7 - Point Cloud Data file format (stairbench)\nVERSION 0.7\nFIELDS x y z\n\
             SIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT {} {} {} 1 0 0 0\n\
             POINTS {n}\nDATA binary\n",
            v.x, v.y, v.z
        ),
    }
    .map_err(io_err(path))?;
    let mut buf = Vec::with_capacity(n * 12);
    for p in cloud.points() {
        for c in [p.x, p.y, p.z] {
            buf.extend_from_slice(&c.to_le_bytes());
        }
    }
    w.write_all(&buf).map_err(io_err(path))?;
    w.flush().map_err(io_err(path))
}

/// Reads a PLY or PCD cloud (by extension). Gravity is taken as -z, the viewpoint from the
/// file when it has one (PCD's VIEWPOINT, our PLY comment), else the origin.
pub fn read_cloud(path: &Path) -> Result<PointCloud, CloudIoError> {
    let format = CloudFormat::from_path(path)
        .ok_or_else(|| fmt_err(path, "unknown extension (expected .ply or .pcd)"))?;
    let file = std::fs::File::open(path).map_err(io_err(path))?;
    let mut r = BufReader::new(file);
    let header = read_header(&mut r, path, format)?;
    let points = match header.encoding {
        Encoding::Ascii => read_ascii(&mut r, &header, path)?,
        Encoding::BinaryLe => read_binary(&mut r, &header, path)?,
    };
    Ok(PointCloud::unorganized(points, header.viewpoint))
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    BinaryLe,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    F32,
    F64,
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
}

impl Scalar {
    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::F32 | Self::I32 | Self::U32 => 4,
            Self::F64 => 8,
        }
    }

    fn read_le(self, b: &[u8]) -> f64 {
        match self {
            Self::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Self::F64 => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
            Self::I8 => b[0] as i8 as f64,
            Self::U8 => b[0] as f64,
            Self::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Self::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Self::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Self::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        }
    }
}

struct Header {
    encoding: Encoding,
    count: usize,
    /// (scalar type, number of values) of each field of a record, in order.
    fields: Vec<(Scalar, usize)>,
    /// Index in `fields` of x, y, z.
    xyz: [usize; 3],
    viewpoint: Point3<f64>,
}

impl Header {
    fn record_size(&self) -> usize {
        self.fields.iter().map(|(s, c)| s.size() * c).sum()
    }
}

/// At most this many points are read (a guard against headers that claim absurd counts).
const MAX_POINTS: usize = 200_000_000;

fn read_header(r: &mut impl BufRead, path: &Path, format: CloudFormat) -> Result<Header, CloudIoError> {
    let mut lines = Vec::new();
    loop {
        let mut line = String::new();
        let n = r.read_line(&mut line).map_err(io_err(path))?;
        if n == 0 {
            return Err(fmt_err(path, "the header ends before its last line"));
        }
        if lines.len() > 1000 {
            return Err(fmt_err(path, "header longer than 1000 lines"));
        }
        let line = line.trim().to_string();
        let last = match format {
            CloudFormat::Ply => line == "end_header",
            CloudFormat::Pcd => line.starts_with("DATA"),
        };
        lines.push(line);
        if last {
            break;
        }
    }
    match format {
        CloudFormat::Ply => parse_ply_header(&lines, path),
        CloudFormat::Pcd => parse_pcd_header(&lines, path),
    }
}

fn ply_scalar(name: &str) -> Option<Scalar> {
    Some(match name {
        "float" | "float32" => Scalar::F32,
        "double" | "float64" => Scalar::F64,
        "char" | "int8" => Scalar::I8,
        "uchar" | "uint8" => Scalar::U8,
        "short" | "int16" => Scalar::I16,
        "ushort" | "uint16" => Scalar::U16,
        "int" | "int32" => Scalar::I32,
        "uint" | "uint32" => Scalar::U32,
        _ => return None,
    })
}

fn find_xyz(names: &[String], path: &Path) -> Result<[usize; 3], CloudIoError> {
    let find =
        |n: &str| names.iter().position(|x| x == n).ok_or_else(|| fmt_err(path, format!("no `{n}` field")));
    Ok([find("x")?, find("y")?, find("z")?])
}

fn parse_ply_header(lines: &[String], path: &Path) -> Result<Header, CloudIoError> {
    if lines.first().map(String::as_str) != Some("ply") {
        return Err(fmt_err(path, "not a PLY file (first line is not `ply`)"));
    }
    let mut encoding = None;
    let mut count = None;
    let mut names = Vec::new();
    let mut fields = Vec::new();
    let mut viewpoint = Point3::origin();
    let mut in_vertex = false;
    for l in &lines[1..] {
        let w: Vec<&str> = l.split_whitespace().collect();
        match w.as_slice() {
            ["format", "ascii", _] => encoding = Some(Encoding::Ascii),
            ["format", "binary_little_endian", _] => encoding = Some(Encoding::BinaryLe),
            ["format", other, ..] => return Err(fmt_err(path, format!("unsupported PLY format `{other}`"))),
            ["comment", "viewpoint", x, y, z] => {
                if let (Ok(x), Ok(y), Ok(z)) = (x.parse(), y.parse(), z.parse()) {
                    viewpoint = Point3::new(x, y, z);
                }
            }
            ["element", "vertex", n] => {
                if count.is_some() || !fields.is_empty() {
                    return Err(fmt_err(path, "the vertex element must come first"));
                }
                count =
                    Some(n.parse::<usize>().map_err(|_| fmt_err(path, format!("bad vertex count `{n}`")))?);
                in_vertex = true;
            }
            ["element", ..] => {
                if count.is_none() {
                    return Err(fmt_err(path, "the vertex element must come first"));
                }
                in_vertex = false;
            }
            ["property", "list", ..] if in_vertex => {
                return Err(fmt_err(path, "list properties in vertices are not supported"))
            }
            ["property", ty, name] if in_vertex => {
                let s = ply_scalar(ty).ok_or_else(|| fmt_err(path, format!("unknown PLY type `{ty}`")))?;
                fields.push((s, 1));
                names.push(name.to_string());
            }
            _ => {}
        }
    }
    let encoding = encoding.ok_or_else(|| fmt_err(path, "no `format` line"))?;
    let count = count.ok_or_else(|| fmt_err(path, "no vertex element"))?;
    if count > MAX_POINTS {
        return Err(fmt_err(path, format!("{count} vertices is more than {MAX_POINTS}")));
    }
    let xyz = find_xyz(&names, path)?;
    Ok(Header { encoding, count, fields, xyz, viewpoint })
}

fn parse_pcd_header(lines: &[String], path: &Path) -> Result<Header, CloudIoError> {
    let mut names: Vec<String> = Vec::new();
    let (mut sizes, mut types, mut counts) = (Vec::new(), Vec::new(), Vec::new());
    let (mut points, mut encoding) = (None, None);
    let mut viewpoint = Point3::origin();
    for l in lines {
        if l.starts_with('#') || l.is_empty() {
            continue;
        }
        let mut w = l.split_whitespace();
        let key = w.next().unwrap_or("");
        let rest: Vec<&str> = w.collect();
        match key {
            "FIELDS" => names = rest.iter().map(|s| s.to_string()).collect(),
            "SIZE" => sizes = rest.iter().map(|s| s.parse::<usize>().unwrap_or(0)).collect(),
            "TYPE" => types = rest.iter().map(|s| s.to_string()).collect(),
            "COUNT" => counts = rest.iter().map(|s| s.parse::<usize>().unwrap_or(0)).collect(),
            "POINTS" => points = rest.first().and_then(|s| s.parse::<usize>().ok()),
            "VIEWPOINT" => {
                let v: Vec<f64> = rest.iter().filter_map(|s| s.parse().ok()).collect();
                if v.len() >= 3 && v.iter().all(|x| x.is_finite()) {
                    viewpoint = Point3::new(v[0], v[1], v[2]);
                }
            }
            "DATA" => {
                encoding = match rest.first().copied() {
                    Some("ascii") => Some(Encoding::Ascii),
                    Some("binary") => Some(Encoding::BinaryLe),
                    Some(other) => {
                        return Err(fmt_err(
                            path,
                            format!("PCD DATA `{other}` is not supported (use ascii or binary)"),
                        ))
                    }
                    None => None,
                }
            }
            _ => {}
        }
    }
    if counts.is_empty() {
        counts = vec![1; names.len()];
    }
    if names.is_empty()
        || sizes.len() != names.len()
        || types.len() != names.len()
        || counts.len() != names.len()
    {
        return Err(fmt_err(path, "FIELDS, SIZE, TYPE and COUNT disagree"));
    }
    let mut fields = Vec::new();
    for i in 0..names.len() {
        let s = match (types[i].as_str(), sizes[i]) {
            ("F", 4) => Scalar::F32,
            ("F", 8) => Scalar::F64,
            ("I", 1) => Scalar::I8,
            ("U", 1) => Scalar::U8,
            ("I", 2) => Scalar::I16,
            ("U", 2) => Scalar::U16,
            ("I", 4) => Scalar::I32,
            ("U", 4) => Scalar::U32,
            (t, s) => {
                return Err(fmt_err(path, format!("field `{}` has unsupported TYPE {t} SIZE {s}", names[i])))
            }
        };
        if counts[i] == 0 {
            return Err(fmt_err(path, format!("field `{}` has COUNT 0", names[i])));
        }
        fields.push((s, counts[i]));
    }
    let count = points.ok_or_else(|| fmt_err(path, "no POINTS line"))?;
    if count > MAX_POINTS {
        return Err(fmt_err(path, format!("{count} points is more than {MAX_POINTS}")));
    }
    let encoding = encoding.ok_or_else(|| fmt_err(path, "no DATA line"))?;
    let xyz = find_xyz(&names, path)?;
    Ok(Header { encoding, count, fields, xyz, viewpoint })
}

/// Offset in a binary record (or index in an ASCII row) of field `f`'s first value.
fn offsets(h: &Header, binary: bool) -> Vec<usize> {
    let mut acc = 0;
    h.fields
        .iter()
        .map(|(s, c)| {
            let o = acc;
            acc += if binary { s.size() * c } else { *c };
            o
        })
        .collect()
}

fn read_binary(r: &mut impl Read, h: &Header, path: &Path) -> Result<Vec<Point3<f32>>, CloudIoError> {
    let size = h.record_size();
    let offs = offsets(h, true);
    let mut data = Vec::new();
    r.take((size * h.count) as u64).read_to_end(&mut data).map_err(io_err(path))?;
    if data.len() < size * h.count {
        return Err(fmt_err(
            path,
            format!("truncated: {} of {} points present", data.len() / size.max(1), h.count),
        ));
    }
    Ok(data
        .chunks_exact(size)
        .map(|rec| {
            let c = |k: usize| h.fields[h.xyz[k]].0.read_le(&rec[offs[h.xyz[k]]..]) as f32;
            Point3::new(c(0), c(1), c(2))
        })
        .collect())
}

fn read_ascii(r: &mut impl BufRead, h: &Header, path: &Path) -> Result<Vec<Point3<f32>>, CloudIoError> {
    let offs = offsets(h, false);
    let mut out = Vec::with_capacity(h.count.min(10_000_000));
    let mut line = String::new();
    while out.len() < h.count {
        line.clear();
        if r.read_line(&mut line).map_err(io_err(path))? == 0 {
            return Err(fmt_err(path, format!("truncated: {} of {} points present", out.len(), h.count)));
        }
        let vals: Vec<&str> = line.split_whitespace().collect();
        if vals.is_empty() {
            continue;
        }
        let get = |k: usize| -> Result<f32, CloudIoError> {
            let s = vals
                .get(offs[h.xyz[k]])
                .ok_or_else(|| fmt_err(path, format!("point {} has too few values", out.len())))?;
            s.parse::<f32>().map_err(|_| fmt_err(path, format!("point {}: `{s}` is not a number", out.len())))
        };
        out.push(Point3::new(get(0)?, get(1)?, get(2)?));
    }
    Ok(out)
}

/// Reads `x,y,z` rows (commas or white space; `#` comments), such as the paper's
/// `voxels.txt`. The viewpoint is the frame's origin (the paper's data: the lidar's frame).
pub fn read_xyz_text(path: &Path) -> Result<PointCloud, CloudIoError> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    let mut points = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let vals: Vec<&str> =
            line.split(|c: char| c == ',' || c.is_whitespace()).filter(|s| !s.is_empty()).collect();
        if vals.len() < 3 {
            return Err(fmt_err(path, format!("line {}: expected x, y, z", n + 1)));
        }
        let mut xyz = [0f32; 3];
        for (k, v) in vals.iter().take(3).enumerate() {
            xyz[k] =
                v.parse().map_err(|_| fmt_err(path, format!("line {}: `{v}` is not a number", n + 1)))?;
        }
        points.push(Point3::from(xyz));
    }
    Ok(PointCloud::unorganized(points, Point3::origin()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> PointCloud {
        let pts =
            vec![Point3::new(1.0, 2.0, 3.0), Point3::new(-0.5, 0.25, 0.0), Point3::new(f32::NAN, 0.0, 1.0)];
        PointCloud::unorganized(pts, Point3::new(0.0, 0.0, 1.4))
    }

    #[test]
    fn ply_and_pcd_round_trip() {
        let dir = std::env::temp_dir().join(format!("stairbench-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (name, f) in [("a.ply", CloudFormat::Ply), ("a.pcd", CloudFormat::Pcd)] {
            let p = dir.join(name);
            write_cloud(&sample(), &p, f).unwrap();
            let back = read_cloud(&p).unwrap();
            assert_eq!(back.len(), 3);
            assert_eq!(back.points()[0], Point3::new(1.0, 2.0, 3.0));
            assert!(back.points()[2].x.is_nan());
            assert!((back.viewpoint().z - 1.4).abs() < 1e-6);
        }
    }

    #[test]
    fn ascii_pcd_with_extra_fields_and_bad_files() {
        let dir = std::env::temp_dir().join(format!("stairbench-io2-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("b.pcd");
        std::fs::write(&p, "VERSION 0.7\nFIELDS rgb x y z\nSIZE 4 4 4 4\nTYPE U F F F\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n7 1 2 3\n8 4 5 6\n").unwrap();
        let c = read_cloud(&p).unwrap();
        assert_eq!(c.points()[1], Point3::new(4.0, 5.0, 6.0));
        std::fs::write(
            &p,
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 5\nDATA binary\n\x01\x02",
        )
        .unwrap();
        let e = read_cloud(&p).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
        std::fs::write(&p, "garbage").unwrap();
        assert!(read_cloud(&p).is_err());
        let q = dir.join("c.ply");
        std::fs::write(
            &q,
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
        )
        .unwrap();
        assert!(read_cloud(&q).unwrap_err().to_string().contains("no `z` field"));
    }
}
