//! PLY writer: one header, then the body encoded in parallel chunks.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::header::format_header;
use super::{
    PlyElement, PlyEncoding, PlyFormat, PlyProperty, PlyPropertyKind, PlyScalar, PlyScalarType,
};
use crate::{CloudError, PointCloud};

/// Points encoded per chunk of a binary body: 64 Ki points is 1.5 to 3.6 MiB, big enough for
/// the rayon pool to pay off and for `write` calls to be cheap, small enough to bound the extra
/// memory whatever the cloud size.
const CHUNK_POINTS: usize = 1 << 16;

/// The vertex element we write for `cloud` in `format`.
fn vertex_element(cloud: &PointCloud, format: PlyFormat) -> PlyElement {
    let f = match format.scalar {
        PlyScalar::Float => PlyScalarType::Float,
        PlyScalar::Double => PlyScalarType::Double,
    };
    let prop = |name: &str, t| PlyProperty {
        name: name.to_owned(),
        kind: PlyPropertyKind::Scalar(t),
    };
    let mut properties = vec![prop("x", f), prop("y", f), prop("z", f)];
    if cloud.normals().is_some() {
        properties.extend([prop("nx", f), prop("ny", f), prop("nz", f)]);
    }
    if cloud.colors().is_some() {
        let u = PlyScalarType::UChar;
        properties.extend([prop("red", u), prop("green", u), prop("blue", u)]);
    }
    if cloud.quality().is_some() {
        properties.push(prop("quality", PlyScalarType::Float));
    }
    PlyElement {
        name: "vertex".into(),
        count: cloud.len() as u64,
        properties,
    }
}

/// Writes `cloud` as a PLY file at `path`, atomically.
///
/// The data goes to a temporary file in the same directory which is flushed to disk and then
/// renamed over `path`, so a failed or interrupted write never leaves a half-written file in
/// place of a good one. See [`PlyFormat`] for what is written.
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{read_ply, write_ply, PlyFormat, PointCloud};
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("two.ply");
/// let cloud = PointCloud::from_positions(vec![Point3::new(0.1, 0.2, 0.3), Point3::new(1e3, -2.0, 7.5)]);
/// write_ply(&path, &cloud, PlyFormat::default())?;
/// assert_eq!(read_ply(&path)?, cloud); // double precision: bit-exact round trip
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_ply(path: &Path, cloud: &PointCloud, format: PlyFormat) -> Result<(), CloudError> {
    /// Distinguishes temporary files of concurrent writes from one process.
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp: PathBuf = dir.join(format!(
        ".{name}.{}.{}.tmp",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| CloudError::io(&tmp, "create", e))?;
        let mut w = BufWriter::with_capacity(1 << 20, file);
        encode(&mut w, cloud, format).map_err(|e| CloudError::io(&tmp, "write", e))?;
        let file = w
            .into_inner()
            .map_err(|e| CloudError::io(&tmp, "write", e.into_error()))?;
        file.sync_all()
            .map_err(|e| CloudError::io(&tmp, "sync", e))?;
        drop(file);
        std::fs::rename(&tmp, path).map_err(|e| CloudError::io(path, "rename", e))
    })();
    if result.is_err() {
        // Best effort: the temporary file may not even exist.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `cloud` as PLY to any writer (errors name `<writer>`). See [`write_ply`].
pub fn write_ply_to_writer<W: Write>(
    writer: W,
    cloud: &PointCloud,
    format: PlyFormat,
) -> Result<(), CloudError> {
    let mut w = BufWriter::with_capacity(1 << 16, writer);
    encode(&mut w, cloud, format)
        .and_then(|()| w.flush())
        .map_err(|e| CloudError::io("<writer>", "write", e))
}

/// The PLY file for `cloud` as bytes. See [`write_ply`].
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::{read_ply_from_bytes, write_ply_to_bytes, PlyEncoding, PlyFormat, PlyScalar, PointCloud};
/// let cloud = PointCloud::from_positions(vec![Point3::new(1.0, 2.0, 3.0)]);
/// let fmt = PlyFormat { encoding: PlyEncoding::Ascii, scalar: PlyScalar::Float };
/// let bytes = write_ply_to_bytes(&cloud, fmt);
/// assert!(bytes.ends_with(b"end_header\n1 2 3\n"));
/// assert_eq!(read_ply_from_bytes(&bytes)?, cloud);
/// # Ok::<(), sl_cloud::CloudError>(())
/// ```
pub fn write_ply_to_bytes(cloud: &PointCloud, format: PlyFormat) -> Vec<u8> {
    let mut out = Vec::new();
    // Writing into a Vec cannot fail: the io::Result is always Ok.
    let _ = encode(&mut out, cloud, format);
    out
}

fn encode<W: Write>(w: &mut W, cloud: &PointCloud, format: PlyFormat) -> std::io::Result<()> {
    let vertex = vertex_element(cloud, format);
    w.write_all(format_header(format.encoding, std::slice::from_ref(&vertex)).as_bytes())?;
    let stride = vertex.fixed_size().unwrap_or(0);
    match (format.encoding, format.scalar) {
        (PlyEncoding::Ascii, scalar) => encode_ascii(w, cloud, scalar),
        (PlyEncoding::BinaryLittleEndian, PlyScalar::Float) => {
            encode_binary::<false, false, W>(w, cloud, stride)
        }
        (PlyEncoding::BinaryLittleEndian, PlyScalar::Double) => {
            encode_binary::<false, true, W>(w, cloud, stride)
        }
        (PlyEncoding::BinaryBigEndian, PlyScalar::Float) => {
            encode_binary::<true, false, W>(w, cloud, stride)
        }
        (PlyEncoding::BinaryBigEndian, PlyScalar::Double) => {
            encode_binary::<true, true, W>(w, cloud, stride)
        }
    }
}

/// Copies `src` at `*off` in `rec` and advances; never panics (records are sized from the header).
#[inline(always)]
fn put(rec: &mut [u8], off: &mut usize, src: &[u8]) {
    if let Some(dst) = rec.get_mut(*off..*off + src.len()) {
        dst.copy_from_slice(src);
    }
    *off += src.len();
}

#[inline(always)]
fn put_real<const BE: bool, const DOUBLE: bool>(rec: &mut [u8], off: &mut usize, v: f64) {
    match (BE, DOUBLE) {
        (false, true) => put(rec, off, &v.to_le_bytes()),
        (true, true) => put(rec, off, &v.to_be_bytes()),
        (false, false) => put(rec, off, &(v as f32).to_le_bytes()),
        (true, false) => put(rec, off, &(v as f32).to_be_bytes()),
    }
}

fn encode_binary<const BE: bool, const DOUBLE: bool, W: Write>(
    w: &mut W,
    cloud: &PointCloud,
    stride: usize,
) -> std::io::Result<()> {
    if stride == 0 {
        return Ok(());
    }
    let (pos, nor, col, qual) = (
        cloud.positions(),
        cloud.normals(),
        cloud.colors(),
        cloud.quality(),
    );
    let mut buf = Vec::new();
    for start in (0..cloud.len()).step_by(CHUNK_POINTS) {
        let end = (start + CHUNK_POINTS).min(cloud.len());
        buf.clear();
        buf.resize((end - start) * stride, 0);
        buf.par_chunks_mut(stride)
            .zip(start..end)
            .for_each(|(rec, i)| {
                let mut off = 0;
                if let Some(p) = pos.get(i) {
                    for v in [p.x, p.y, p.z] {
                        put_real::<BE, DOUBLE>(rec, &mut off, v);
                    }
                }
                if let Some(n) = nor.and_then(|n| n.get(i)) {
                    for v in [n.x, n.y, n.z] {
                        put_real::<BE, DOUBLE>(rec, &mut off, v);
                    }
                }
                if let Some(c) = col.and_then(|c| c.get(i)) {
                    put(rec, &mut off, c);
                }
                if let Some(q) = qual.and_then(|q| q.get(i)) {
                    put(
                        rec,
                        &mut off,
                        &if BE { q.to_be_bytes() } else { q.to_le_bytes() },
                    );
                }
            });
        w.write_all(&buf)?;
    }
    Ok(())
}

fn encode_ascii<W: Write>(w: &mut W, cloud: &PointCloud, scalar: PlyScalar) -> std::io::Result<()> {
    // `{}` prints the shortest decimal that parses back to the same value: the ASCII round trip
    // is exact for `f64` (Double) and for the `f32` rounding (Float).
    let real = |w: &mut W, v: f64| match scalar {
        PlyScalar::Double => write!(w, "{v}"),
        PlyScalar::Float => write!(w, "{}", v as f32),
    };
    for i in 0..cloud.len() {
        if let Some(p) = cloud.positions().get(i) {
            real(w, p.x)?;
            w.write_all(b" ")?;
            real(w, p.y)?;
            w.write_all(b" ")?;
            real(w, p.z)?;
        }
        if let Some(n) = cloud.normals().and_then(|n| n.get(i)) {
            for v in [n.x, n.y, n.z] {
                w.write_all(b" ")?;
                real(w, v)?;
            }
        }
        if let Some([r, g, b]) = cloud.colors().and_then(|c| c.get(i)) {
            write!(w, " {r} {g} {b}")?;
        }
        if let Some(q) = cloud.quality().and_then(|q| q.get(i)) {
            write!(w, " {q}")?;
        }
        w.write_all(b"\n")?;
    }
    Ok(())
}
