//! `manifest.json`: the description of a pattern sequence and of the frames that capture it.
//!
//! The schema is documented in `docs/capture-format.md`. Parsing is strict: an unknown key, a
//! wrong type or a value out of its domain is an error that names the key as a JSON path
//! (`blocks[1].periods[2]`).

use std::path::{Path, PathBuf};

use serde_json::{Map, Value, json};

use crate::pattern::ceil_log2;
use crate::{
    Axis, BitDepth, CodecError, GrayCodeSpec, GrayReference, HybridSpec, ImageSize, Pattern,
    PatternSequence, PhaseShiftSpec, ShiftSign, Unwrap,
};
use sl_image::ToneCurve;

/// The file name of a manifest inside a capture folder.
pub const MANIFEST_FILE: &str = "manifest.json";

/// Value of the `format` key.
pub const MANIFEST_FORMAT: &str = "sl-capture";

/// Version of the schema this crate reads and writes.
pub const MANIFEST_VERSION: u64 = 1;

/// One block of a manifest: the pattern and the files of its frames, in the block's order.
#[derive(Clone, Debug, PartialEq)]
pub struct ManifestBlock {
    /// Codec and parameters.
    pub pattern: Pattern,
    /// Frame files, relative to the frames folder (absolute paths are used as they are).
    pub frames: Vec<String>,
}

/// A parsed `manifest.json`.
#[derive(Clone, Debug, PartialEq)]
pub struct Manifest {
    /// Projector image size.
    pub projector: ImageSize,
    /// Bit depth of the rendered patterns (the captures may have any depth).
    pub bit_depth: BitDepth,
    /// Folder of the frames, relative to the manifest's folder (absolute allowed); `None`
    /// means the manifest's folder.
    pub frames_dir: Option<PathBuf>,
    /// Free text: where the capture comes from.
    pub description: Option<String>,
    /// A frame of the object under full white in colour (relative to the frames folder, as the
    /// blocks' frames): the colour of the scan. Not part of the pattern sequence; `None`
    /// (key `colour` absent): the colour comes from the blocks' frames.
    pub colour: Option<String>,
    /// The blocks in projection order.
    pub blocks: Vec<ManifestBlock>,
}

impl Manifest {
    /// Reads and validates a manifest file.
    ///
    /// # Errors
    /// [`CodecError::Io`], [`CodecError::ManifestJson`] (with line and column), or
    /// [`CodecError::Manifest`] naming the key.
    pub fn load(path: &Path) -> Result<Self, CodecError> {
        let text = std::fs::read_to_string(path).map_err(|e| CodecError::io(path, "read", e))?;
        Self::from_json_str(&text, path)
    }

    /// Parses and validates manifest text; `path` only names the source in errors.
    ///
    /// # Errors
    /// As [`Manifest::load`].
    pub fn from_json_str(text: &str, path: &Path) -> Result<Self, CodecError> {
        let value: Value =
            serde_json::from_str(text).map_err(|source| CodecError::ManifestJson {
                path: path.to_path_buf(),
                source,
            })?;
        Parser { path }.manifest(&value)
    }

    /// The pattern sequence the manifest describes.
    pub fn sequence(&self) -> PatternSequence {
        PatternSequence {
            projector: self.projector,
            blocks: self.blocks.iter().map(|b| b.pattern.clone()).collect(),
        }
    }

    /// Total number of frames.
    pub fn frame_count(&self) -> usize {
        self.blocks.iter().map(|b| b.frames.len()).sum()
    }

    /// The manifest as a JSON value (every parameter explicit).
    pub fn to_json(&self) -> Value {
        let mut root = Map::new();
        root.insert("format".into(), json!(MANIFEST_FORMAT));
        root.insert("version".into(), json!(MANIFEST_VERSION));
        if let Some(d) = &self.description {
            root.insert("description".into(), json!(d));
        }
        root.insert(
            "projector".into(),
            json!({"width": self.projector.width, "height": self.projector.height}),
        );
        root.insert("bit_depth".into(), json!(self.bit_depth.bits()));
        if let Some(d) = &self.frames_dir {
            root.insert("frames_dir".into(), json!(d.to_string_lossy()));
        }
        if let Some(c) = &self.colour {
            root.insert("colour".into(), json!(c));
        }
        let blocks: Vec<Value> = self
            .blocks
            .iter()
            .map(|b| {
                let mut o = pattern_json(&b.pattern);
                o.insert("frames".into(), json!(b.frames));
                Value::Object(o)
            })
            .collect();
        root.insert("blocks".into(), Value::Array(blocks));
        Value::Object(root)
    }

    /// Writes the manifest as pretty-printed JSON.
    ///
    /// # Errors
    /// [`CodecError::Io`] naming the file.
    pub fn save(&self, path: &Path) -> Result<(), CodecError> {
        let mut text = serde_json::to_string_pretty(&self.to_json()).unwrap_or_default();
        text.push('\n');
        std::fs::write(path, text).map_err(|e| CodecError::io(path, "write", e))
    }
}

fn gray_json(s: &GrayCodeSpec, with_axis: bool) -> Map<String, Value> {
    let mut o = Map::new();
    if with_axis {
        o.insert("codec".into(), json!("gray"));
        o.insert("axis".into(), json!(s.axis.name()));
    }
    o.insert("bits".into(), json!(s.bits));
    o.insert("reference".into(), json!(s.reference.name()));
    o.insert("binary".into(), json!(s.binary));
    o.insert("stripe_width".into(), json!(s.stripe_width));
    o.insert("origin".into(), json!(s.origin));
    o
}

fn pattern_json(p: &Pattern) -> Map<String, Value> {
    match p {
        Pattern::Gray(s) => gray_json(s, true),
        Pattern::Phase(s) => {
            let mut o = Map::new();
            o.insert("codec".into(), json!("phase"));
            o.insert("axis".into(), json!(s.axis.name()));
            o.insert("steps".into(), json!(s.steps));
            o.insert("periods".into(), json!(s.periods));
            o.insert("unwrap".into(), json!(s.unwrap.name()));
            o.insert("origin".into(), json!(s.origin));
            o.insert("phase_offset".into(), json!(s.phase_offset));
            o.insert("shift_sign".into(), json!(s.shift_sign.value() as i64));
            o.insert("gamma".into(), json!(s.gamma));
            if let Some(c) = &s.precompensation {
                o.insert("precompensation".into(), json!(c));
            }
            o
        }
        Pattern::Hybrid(s) => {
            let mut o = Map::new();
            o.insert("codec".into(), json!("hybrid"));
            o.insert("axis".into(), json!(s.axis.name()));
            o.insert("steps".into(), json!(s.steps));
            o.insert("periods".into(), json!(s.periods));
            o.insert("origin".into(), json!(s.origin));
            o.insert("phase_offset".into(), json!(s.phase_offset));
            o.insert("shift_sign".into(), json!(s.shift_sign.value() as i64));
            o.insert("gamma".into(), json!(s.gamma));
            if let Some(c) = &s.precompensation {
                o.insert("precompensation".into(), json!(c));
            }
            o.insert("gray".into(), Value::Object(gray_json(&s.gray, false)));
            o
        }
    }
}

/// Keys allowed at the top level.
const ROOT_KEYS: &[&str] = &[
    "format",
    "version",
    "description",
    "projector",
    "bit_depth",
    "frames_dir",
    "colour",
    "blocks",
    "metadata",
];
const GRAY_KEYS: &[&str] = &[
    "codec",
    "axis",
    "bits",
    "reference",
    "binary",
    "centered",
    "stripe_width",
    "origin",
    "frames",
];
const PHASE_KEYS: &[&str] = &[
    "codec",
    "axis",
    "steps",
    "periods",
    "unwrap",
    "origin",
    "phase_offset",
    "shift_sign",
    "gamma",
    "precompensation",
    "frames",
];
const HYBRID_KEYS: &[&str] = &[
    "codec",
    "axis",
    "steps",
    "periods",
    "origin",
    "phase_offset",
    "shift_sign",
    "gamma",
    "precompensation",
    "gray",
    "frames",
];
const HYBRID_GRAY_KEYS: &[&str] = &["bits", "reference", "binary", "stripe_width", "origin"];

/// Strict reader of the JSON tree with key paths for errors.
struct Parser<'p> {
    path: &'p Path,
}

/// A JSON object with its key path.
struct Obj<'v> {
    map: &'v Map<String, Value>,
    at: String,
}

impl Parser<'_> {
    fn err(&self, key: impl Into<String>, message: impl Into<String>) -> CodecError {
        CodecError::Manifest {
            path: self.path.to_path_buf(),
            key: key.into(),
            message: message.into(),
        }
    }

    fn obj<'v>(&self, v: &'v Value, at: &str, allowed: &[&str]) -> Result<Obj<'v>, CodecError> {
        let map = v
            .as_object()
            .ok_or_else(|| self.err(at, "must be a JSON object"))?;
        for k in map.keys() {
            if !allowed.contains(&k.as_str()) {
                let head = |s: &str| s.chars().take(4).collect::<String>();
                let hint = allowed
                    .iter()
                    .find(|a| a.starts_with(&head(k)) || k.starts_with(&head(a)))
                    .map(|a| format!(" (did you mean '{a}'?)"))
                    .unwrap_or_default();
                return Err(self.err(
                    join(at, k),
                    format!("unknown key{hint}; allowed keys: {}", allowed.join(", ")),
                ));
            }
        }
        Ok(Obj {
            map,
            at: at.to_string(),
        })
    }

    fn get<'v>(&self, o: &Obj<'v>, key: &str) -> Option<&'v Value> {
        o.map.get(key).filter(|v| !v.is_null())
    }

    fn u64_opt(&self, o: &Obj<'_>, key: &str) -> Result<Option<u64>, CodecError> {
        match self.get(o, key) {
            None => Ok(None),
            Some(v) => v.as_u64().map(Some).ok_or_else(|| {
                self.err(
                    join(&o.at, key),
                    format!("must be a non-negative integer, got {v}"),
                )
            }),
        }
    }

    fn u32_req(&self, o: &Obj<'_>, key: &str) -> Result<u32, CodecError> {
        let v = self
            .u64_opt(o, key)?
            .ok_or_else(|| self.err(join(&o.at, key), "is required"))?;
        u32::try_from(v).map_err(|_| self.err(join(&o.at, key), format!("{v} is too large")))
    }

    /// A tone curve, `{"samples": [0, ..., 1]}` (`sl_image::ToneCurve`).
    fn curve_opt(&self, o: &Obj<'_>, key: &str) -> Result<Option<ToneCurve>, CodecError> {
        match self.get(o, key) {
            None => Ok(None),
            Some(v) => serde_json::from_value(v.clone()).map(Some).map_err(|e| {
                self.err(
                    join(&o.at, key),
                    format!(
                        "must be a tone curve {{\"samples\": [0, ..., 1]}} rising from 0 to 1: {e}"
                    ),
                )
            }),
        }
    }

    fn f64_opt(&self, o: &Obj<'_>, key: &str) -> Result<Option<f64>, CodecError> {
        match self.get(o, key) {
            None => Ok(None),
            Some(v) => v
                .as_f64()
                .filter(|x| x.is_finite())
                .map(Some)
                .ok_or_else(|| {
                    self.err(
                        join(&o.at, key),
                        format!("must be a finite number, got {v}"),
                    )
                }),
        }
    }

    fn str_opt<'v>(&self, o: &Obj<'v>, key: &str) -> Result<Option<&'v str>, CodecError> {
        match self.get(o, key) {
            None => Ok(None),
            Some(v) => v
                .as_str()
                .map(Some)
                .ok_or_else(|| self.err(join(&o.at, key), format!("must be a string, got {v}"))),
        }
    }

    fn bool_opt(&self, o: &Obj<'_>, key: &str) -> Result<Option<bool>, CodecError> {
        match self.get(o, key) {
            None => Ok(None),
            Some(v) => v.as_bool().map(Some).ok_or_else(|| {
                self.err(join(&o.at, key), format!("must be true or false, got {v}"))
            }),
        }
    }

    fn manifest(&self, v: &Value) -> Result<Manifest, CodecError> {
        let root = self.obj(v, "", ROOT_KEYS)?;
        if let Some(f) = self.str_opt(&root, "format")?
            && f != MANIFEST_FORMAT
        {
            {
                return Err(self.err("format", format!("expected '{MANIFEST_FORMAT}', got '{f}'")));
            }
        }
        if let Some(ver) = self.u64_opt(&root, "version")?
            && ver != MANIFEST_VERSION
        {
            {
                return Err(self.err(
                    "version",
                    format!("this reader knows version {MANIFEST_VERSION}, got {ver}"),
                ));
            }
        }
        let pv = self
            .get(&root, "projector")
            .ok_or_else(|| self.err("projector", "is required"))?;
        let po = self.obj(pv, "projector", &["width", "height"])?;
        let projector = ImageSize::new(self.u32_req(&po, "width")?, self.u32_req(&po, "height")?);
        for (key, side) in [("width", projector.width), ("height", projector.height)] {
            if side == 0 {
                return Err(self.err(
                    format!("projector.{key}"),
                    format!("must be at least 1 pixel, got {projector}"),
                ));
            }
        }
        let bit_depth = match self.u64_opt(&root, "bit_depth")? {
            None => BitDepth::Eight,
            Some(b) => BitDepth::from_bits(b)
                .ok_or_else(|| self.err("bit_depth", format!("must be 8 or 16, got {b}")))?,
        };
        let frames_dir = self.str_opt(&root, "frames_dir")?.map(PathBuf::from);
        let description = self.str_opt(&root, "description")?.map(str::to_string);
        let colour = self.str_opt(&root, "colour")?.map(str::to_string);
        if colour.as_deref() == Some("") {
            return Err(self.err("colour", "must name a frame file, got \"\""));
        }
        let bv = self
            .get(&root, "blocks")
            .ok_or_else(|| self.err("blocks", "is required"))?;
        let arr = bv
            .as_array()
            .ok_or_else(|| self.err("blocks", "must be an array"))?;
        if arr.is_empty() {
            return Err(self.err("blocks", "must hold at least one block"));
        }
        let mut blocks = Vec::with_capacity(arr.len());
        for (i, b) in arr.iter().enumerate() {
            blocks.push(self.block(b, &format!("blocks[{i}]"), projector)?);
        }
        let manifest = Manifest {
            projector,
            bit_depth,
            frames_dir,
            description,
            colour,
            blocks,
        };
        manifest.sequence().validate().map_err(|e| match e {
            CodecError::Parameter { name, message } => self.err(name, message),
            other => other,
        })?;
        Ok(manifest)
    }

    fn block(
        &self,
        v: &Value,
        at: &str,
        projector: ImageSize,
    ) -> Result<ManifestBlock, CodecError> {
        let codec = v.get("codec").and_then(Value::as_str).ok_or_else(|| {
            self.err(
                join(at, "codec"),
                "is required: one of 'gray', 'phase', 'hybrid'",
            )
        })?;
        let keys = match codec {
            "gray" => GRAY_KEYS,
            "phase" => PHASE_KEYS,
            "hybrid" => HYBRID_KEYS,
            other => {
                return Err(self.err(
                    join(at, "codec"),
                    format!("unknown codec '{other}': one of 'gray', 'phase', 'hybrid'"),
                ));
            }
        };
        let o = self.obj(v, at, keys)?;
        let axis_name = self
            .str_opt(&o, "axis")?
            .ok_or_else(|| self.err(join(at, "axis"), "is required"))?;
        let axis = Axis::from_name(axis_name).ok_or_else(|| {
            self.err(
                join(at, "axis"),
                format!("must be 'column' or 'row', got '{axis_name}'"),
            )
        })?;
        let extent = axis.extent(projector);
        let pattern = match codec {
            "gray" => Pattern::Gray(self.gray(&o, axis, extent, None)?),
            "phase" => {
                let steps = self.u32_req(&o, "steps")?;
                let periods = self.periods(&o)?;
                let unwrap = match self.str_opt(&o, "unwrap")? {
                    None => Unwrap::None,
                    Some(n) => Unwrap::from_name(n).ok_or_else(|| {
                        self.err(
                            join(at, "unwrap"),
                            format!("unknown method '{n}': one of 'none', 'hierarchical', 'heterodyne', 'number_theoretic'"),
                        )
                    })?,
                };
                let mut s = PhaseShiftSpec::new(axis, projector, steps, periods, unwrap);
                s.origin = self.f64_opt(&o, "origin")?.unwrap_or(s.origin);
                s.phase_offset = self.f64_opt(&o, "phase_offset")?.unwrap_or(0.0);
                s.shift_sign = self.shift_sign(&o)?;
                s.gamma = self.f64_opt(&o, "gamma")?.unwrap_or(1.0);
                s.precompensation = self.curve_opt(&o, "precompensation")?;
                Pattern::Phase(s)
            }
            _ => {
                let steps = self.u32_req(&o, "steps")?;
                let periods = self
                    .f64_opt(&o, "periods")?
                    .ok_or_else(|| self.err(join(at, "periods"), "is required (one number)"))?;
                let mut s = HybridSpec::complementary(axis, projector, steps, periods);
                s.origin = self.f64_opt(&o, "origin")?.unwrap_or(s.origin);
                s.gray.origin = s.origin;
                s.phase_offset = self.f64_opt(&o, "phase_offset")?.unwrap_or(0.0);
                s.shift_sign = self.shift_sign(&o)?;
                s.gamma = self.f64_opt(&o, "gamma")?.unwrap_or(1.0);
                s.precompensation = self.curve_opt(&o, "precompensation")?;
                if let Some(g) = self.get(&o, "gray") {
                    let go = self.obj(g, &join(at, "gray"), HYBRID_GRAY_KEYS)?;
                    s.gray = self.gray(&go, axis, extent, Some(&s.gray))?;
                }
                Pattern::Hybrid(s)
            }
        };
        let fv = self
            .get(&o, "frames")
            .ok_or_else(|| self.err(join(at, "frames"), "is required"))?;
        let fa = fv
            .as_array()
            .ok_or_else(|| self.err(join(at, "frames"), "must be an array of file names"))?;
        let mut frames = Vec::with_capacity(fa.len());
        for (i, f) in fa.iter().enumerate() {
            let name = f.as_str().filter(|s| !s.trim().is_empty()).ok_or_else(|| {
                self.err(
                    format!("{at}.frames[{i}]"),
                    format!("must be a file name, got {f}"),
                )
            })?;
            frames.push(name.to_string());
        }
        // The parameters first: a bad one also makes the frame count wrong, and is the cause.
        // The block codes the projector's side: say which, as its size bounds the parameters.
        let side = match axis {
            Axis::Column => "width",
            Axis::Row => "height",
        };
        pattern.validate().map_err(|e| match e {
            CodecError::Parameter { name, message } => self.err(
                join(at, &name),
                format!("{message} (the block codes projector.{side}, {extent} px)"),
            ),
            other => other,
        })?;
        if frames.len() != pattern.frame_count() {
            let by = match codec {
                "gray" => "bits, reference",
                "phase" => "steps, periods",
                _ => "steps, gray.bits, gray.reference",
            };
            return Err(self.err(
                join(at, "frames"),
                format!(
                    "the {codec} block's parameters ({by}) need {} frames, the list has {}",
                    pattern.frame_count(),
                    frames.len()
                ),
            ));
        }
        Ok(ManifestBlock { pattern, frames })
    }

    fn periods(&self, o: &Obj<'_>) -> Result<Vec<f64>, CodecError> {
        let key = join(&o.at, "periods");
        match self.get(o, "periods") {
            None => Err(self.err(key, "is required")),
            Some(Value::Array(a)) => a
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    v.as_f64().filter(|x| x.is_finite()).ok_or_else(|| {
                        self.err(
                            format!("{key}[{i}]"),
                            format!("must be a finite number, got {v}"),
                        )
                    })
                })
                .collect(),
            Some(v) => v
                .as_f64()
                .filter(|x| x.is_finite())
                .map(|x| vec![x])
                .ok_or_else(|| {
                    self.err(
                        key,
                        format!("must be a number or an array of numbers, got {v}"),
                    )
                }),
        }
    }

    fn shift_sign(&self, o: &Obj<'_>) -> Result<ShiftSign, CodecError> {
        match self.get(o, "shift_sign") {
            None => Ok(ShiftSign::Positive),
            Some(v) => v.as_i64().and_then(ShiftSign::from_value).ok_or_else(|| {
                self.err(
                    join(&o.at, "shift_sign"),
                    format!("must be 1 or -1, got {v}"),
                )
            }),
        }
    }

    /// A Gray spec; `base` gives the defaults inside a hybrid block.
    fn gray(
        &self,
        o: &Obj<'_>,
        axis: Axis,
        extent: u32,
        base: Option<&GrayCodeSpec>,
    ) -> Result<GrayCodeSpec, CodecError> {
        let default_bits = base.map_or_else(|| ceil_log2(u64::from(extent)).max(1), |b| b.bits);
        let bits = match self.u64_opt(o, "bits")? {
            None => default_bits,
            Some(b) => u32::try_from(b)
                .map_err(|_| self.err(join(&o.at, "bits"), format!("{b} is too large")))?,
        };
        let reference = match self.str_opt(o, "reference")? {
            None => base.map_or(GrayReference::Inverse, |b| b.reference),
            Some(n) => GrayReference::from_name(n).ok_or_else(|| {
                self.err(
                    join(&o.at, "reference"),
                    format!(
                        "unknown reference '{n}': one of 'inverse', 'white_black', 'phase_mean'"
                    ),
                )
            })?,
        };
        let binary = self.bool_opt(o, "binary")?.unwrap_or(false);
        let stripe_width = self
            .f64_opt(o, "stripe_width")?
            .unwrap_or_else(|| base.map_or(1.0, |b| b.stripe_width));
        let centered = if base.is_none() {
            self.bool_opt(o, "centered")?
        } else {
            None
        };
        let origin = match (self.f64_opt(o, "origin")?, centered) {
            (Some(_), Some(_)) => {
                return Err(self.err(
                    join(&o.at, "centered"),
                    "give either 'centered' or 'origin', not both",
                ));
            }
            (Some(v), None) => v,
            (None, c) => match base {
                Some(b) => b.origin,
                None => GrayCodeSpec::per_pixel_origin(extent, bits, c.unwrap_or(true)),
            },
        };
        Ok(GrayCodeSpec {
            axis,
            extent,
            bits,
            reference,
            binary,
            stripe_width,
            origin,
        })
    }
}

/// `at.key`, or `key` at the root.
fn join(at: &str, key: &str) -> String {
    if at.is_empty() {
        key.to_string()
    } else {
        format!("{at}.{key}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Manifest, CodecError> {
        Manifest::from_json_str(text, Path::new("m.json"))
    }

    fn names(n: usize) -> String {
        let v: Vec<String> = (0..n).map(|i| format!("\"{i:02}.png\"")).collect();
        format!("[{}]", v.join(","))
    }

    #[test]
    fn round_trip_through_json() {
        let p = ImageSize::new(1920, 1080);
        let seq = PatternSequence::new(p)
            .with(Pattern::Gray(GrayCodeSpec::per_pixel(
                Axis::Column,
                p,
                true,
            )))
            .with(Pattern::Hybrid(HybridSpec::complementary(
                Axis::Row,
                p,
                4,
                17.5,
            )));
        let m = seq.manifest(BitDepth::Sixteen);
        let text = serde_json::to_string(&m.to_json()).unwrap();
        let back = parse(&text).unwrap();
        assert_eq!(back, m);
        let seq2 = PatternSequence::new(p).with(Pattern::Phase(PhaseShiftSpec {
            gamma: 2.2,
            shift_sign: ShiftSign::Negative,
            phase_offset: -std::f64::consts::PI,
            ..PhaseShiftSpec::new(
                Axis::Column,
                p,
                5,
                vec![64.0, 58.0, 53.0],
                Unwrap::Heterodyne,
            )
        }));
        let m = seq2.manifest(BitDepth::Eight);
        assert_eq!(parse(&m.to_json().to_string()).unwrap(), m);
        // A measured response pre-compensated in a hybrid block survives the round trip; a
        // malformed one is named by its key.
        let curve = ToneCurve::from_samples(vec![0.0, 0.1, 0.45, 1.0]).unwrap();
        let seq3 = PatternSequence::new(p).with(Pattern::Hybrid(
            HybridSpec::complementary(Axis::Column, p, 3, 40.0).precompensated(curve),
        ));
        let m = seq3.manifest(BitDepth::Eight);
        let text = m.to_json().to_string();
        assert!(
            text.contains("\"precompensation\":{\"samples\":[0.0,0.1,0.45,1.0]}"),
            "{text}"
        );
        assert_eq!(parse(&text).unwrap(), m);
        let bad = text.replace("0.45", "0.05");
        let e = parse(&bad).unwrap_err().to_string();
        assert!(e.contains("precompensation"), "{e}");
    }

    #[test]
    fn defaults_for_hand_written_manifests() {
        let text = format!(
            r#"{{"projector": {{"width": 1920, "height": 1080}},
                "blocks": [{{"codec": "gray", "axis": "row", "frames": {}}}]}}"#,
            names(22)
        );
        let m = parse(&text).unwrap();
        let Pattern::Gray(g) = &m.blocks[0].pattern else {
            panic!()
        };
        assert_eq!(g.bits, 11);
        assert_eq!(g.origin, -0.5 - 484.0); // centred: (2048 - 1080) / 2
        assert_eq!(m.bit_depth, BitDepth::Eight);
    }

    #[test]
    fn errors_name_the_key() {
        let cases = [
            (
                r#"{"projector": {"width": 10, "height": 10}, "blocks": [], "extra": 1}"#,
                "extra",
            ),
            (
                r#"{"projector": {"width": 10}, "blocks": []}"#,
                "projector.height",
            ),
            (
                r#"{"projector": {"width": 10, "height": 10}, "blocks": [{"codec": "moire"}]}"#,
                "blocks[0].codec",
            ),
            (
                r#"{"projector": {"width": 1920, "height": 10}, "blocks": [{"codec": "phase", "axis": "column", "steps": 4, "period": 3, "frames": []}]}"#,
                "did you mean 'periods'",
            ),
            (
                r#"{"projector": {"width": 1920, "height": 10}, "blocks": [{"codec": "phase", "axis": "column", "steps": 4, "periods": [1, "x"], "frames": []}]}"#,
                "blocks[0].periods[1]",
            ),
            (
                r#"{"projector": {"width": 1920, "height": 10}, "blocks": [{"codec": "phase", "axis": "column", "steps": 4, "periods": [64, 58, 53], "unwrap": "heterodyne", "frames": ["a"]}]}"#,
                "need 12 frames, the list has 1",
            ),
            (
                r#"{"projector": {"width": 1920, "height": 10}, "blocks": [{"codec": "phase", "axis": "column", "steps": 2, "periods": 1, "frames": ["a", "b"]}]}"#,
                "blocks[0].steps",
            ),
            (
                r#"{"projector": {"width": 1920, "height": 10}, "blocks": [{"codec": "phase", "axis": "diagonal", "steps": 3, "periods": 1, "frames": []}]}"#,
                "blocks[0].axis",
            ),
        ];
        for (text, needle) in cases {
            let e = parse(text).unwrap_err();
            assert!(
                e.to_string().contains(needle),
                "expected '{needle}' in: {e}"
            );
        }
        let e = parse("{\n  \"projector\": ,\n}").unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
    }
}
