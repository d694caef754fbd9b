//! The calibration of a binocular rig: two cameras triangulate, a projector (optional here)
//! labels the surface.

use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use crate::calibration::{check_json_models, normalized_axis, parse_file, read_text};
use crate::pose::PoseRepr;
use crate::{
    CalibrationFormat, CameraError, CameraModel, LoadConfig, Metadata, ProjectorModel,
    TurntableAxis, layouts,
};

/// Version of the binocular JSON files this crate writes.
pub const BINOCULAR_FORMAT_VERSION: u32 = 1;
/// The `kind` of a binocular JSON file (a one-camera calibration has none).
const KIND: &str = "binocular";

/// Two calibrated cameras, and optionally the projector, in the left camera's frame.
///
/// Files: [`BinocularCalibration::load`] reads this project's JSON (`"kind": "binocular"`),
/// SLMaster's binocular `caliInfo.yml` (`M1 D1 M2 D2 … Rlr Tlr … S`) and OpenCV's stereo
/// calibration in two files (`intrinsic(s).yml` with `M1 D1 M2 D2` and `extrinsic(s).yml`
/// with `R T`, found beside it); [`BinocularCalibration::save`] writes the JSON.
///
/// ```
/// use nalgebra::{Isometry3, Translation3, UnitQuaternion};
/// use sl_camera::{BinocularCalibration, CameraModel, Distortion, ImageSize, Intrinsics};
/// let camera = CameraModel::new(
///     Intrinsics::new(1200.0, 1200.0, 639.5, 511.5),
///     Distortion::from_opencv(&[-0.1, 0.05, 0.0, 0.0, 0.0])?,
///     ImageSize::new(1280, 1024),
/// )?;
/// let t_left_right = Isometry3::from_parts(
///     Translation3::new(150.0, 0.0, 10.0),
///     UnitQuaternion::from_euler_angles(0.0, -0.2, 0.0),
/// );
/// let pair = BinocularCalibration::new(camera, camera, t_left_right);
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("pair.json");
/// pair.save(&path)?;
/// let read = BinocularCalibration::load(&path)?;
/// assert_eq!((read.left, read.right), (pair.left, pair.right));
/// // The rotation is stored as a matrix: back to within rounding.
/// assert!((read.t_left_right.inverse() * pair.t_left_right).rotation.angle() < 1e-12);
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct BinocularCalibration {
    /// The left camera: its frame is the rig's.
    pub left: CameraModel,
    /// The right camera.
    pub right: CameraModel,
    /// The right camera's pose in the left camera's frame: `p_left = T_left_right · p_right`
    /// (mm).
    pub t_left_right: Isometry3<f64>,
    /// The projector and its pose in the left camera's frame, when it was calibrated too.
    pub projector: Option<(ProjectorModel, Isometry3<f64>)>,
    /// Stereo RMS reprojection error of the two cameras (px), when known.
    pub rms: Option<f64>,
    /// The turntable axis in the left camera's frame, when the rig has one and it was
    /// calibrated (as [`crate::Calibration::turntable`]).
    pub turntable: Option<TurntableAxis>,
    /// Who wrote the file, when, and notes.
    pub metadata: Metadata,
}

/// The JSON file.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct BinocularJson {
    version: u32,
    kind: String,
    left: CameraModel,
    right: CameraModel,
    #[serde(rename = "T_left_right")]
    t_left_right: PoseRepr,
    #[serde(default)]
    projector: Option<CameraModel>,
    #[serde(default, rename = "T_left_proj")]
    t_left_proj: Option<PoseRepr>,
    #[serde(default)]
    rms: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    turntable: Option<TurntableAxis>,
    #[serde(default)]
    metadata: Metadata,
}

impl BinocularCalibration {
    /// Two cameras, no projector, default metadata.
    pub fn new(left: CameraModel, right: CameraModel, t_left_right: Isometry3<f64>) -> Self {
        Self {
            left,
            right,
            t_left_right,
            projector: None,
            rms: None,
            turntable: None,
            metadata: Metadata::default(),
        }
    }

    /// Checks both cameras (and the projector), and that the cameras stand apart.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] naming `left.…`, `right.…`, `projector.…` or
    /// `T_left_right`.
    pub fn validate(&self) -> Result<(), CameraError> {
        let prefixed = |e: CameraError, prefix: &str| match e {
            CameraError::InvalidParameter { parameter, message } => {
                CameraError::invalid(format!("{prefix}.{parameter}"), message)
            }
            other => other,
        };
        self.left.validate().map_err(|e| prefixed(e, "left"))?;
        self.right.validate().map_err(|e| prefixed(e, "right"))?;
        if let Some((p, _)) = &self.projector {
            p.validate().map_err(|e| prefixed(e, "projector"))?;
        }
        let t = self.t_left_right.translation.vector;
        let finite = t.iter().all(|v| v.is_finite())
            && self
                .t_left_right
                .rotation
                .coords
                .iter()
                .all(|v| v.is_finite());
        if let Some(axis) = &self.turntable {
            let mut check = *axis;
            check.normalize()?;
        }
        if !finite || t.norm() < 1e-6 {
            return Err(CameraError::invalid(
                "T_left_right",
                format!(
                    "the cameras' centres are {} mm apart: a binocular rig needs a baseline",
                    t.norm()
                ),
            ));
        }
        Ok(())
    }

    /// Reads a binocular calibration (see the type docs for the files).
    ///
    /// # Errors
    /// [`CameraError::Io`], [`CameraError::Json`], [`CameraError::Syntax`],
    /// [`CameraError::MissingKey`] (the image size a layout lacks names the option that gives
    /// it), [`CameraError::BadValue`].
    pub fn load(path: impl AsRef<Path>) -> Result<Self, CameraError> {
        Self::load_with(path, &LoadConfig::default())
    }

    /// [`BinocularCalibration::load`] with the sizes a layout does not store.
    ///
    /// # Errors
    /// As [`BinocularCalibration::load`].
    pub fn load_with(path: impl AsRef<Path>, options: &LoadConfig) -> Result<Self, CameraError> {
        let path = path.as_ref();
        let format = CalibrationFormat::from_path(path)?;
        let name = path.display().to_string();
        if format == CalibrationFormat::Json {
            return Self::from_json(&read_text(path)?, &name);
        }
        let doc = parse_file(path, format)?;
        let pair = if doc.has("M1") {
            let e = extrinsic_sibling(path);
            let extrinsics = if !doc.has("Rlr") && e.is_file() && e != path {
                Some(parse_file(&e, CalibrationFormat::from_path(&e)?)?)
            } else {
                None
            };
            layouts::binocular::read_pair(&doc, extrinsics.as_ref(), options)?
        } else {
            let i = intrinsic_sibling(path);
            if !i.is_file() || i == path {
                return Err(doc.missing(
                    "M1",
                    Some(&format!(
                        "a two-camera calibration: its intrinsics (M1 D1 M2 D2) were looked for \
                         in {}",
                        i.display()
                    )),
                ));
            }
            let intrinsics = parse_file(&i, CalibrationFormat::from_path(&i)?)?;
            layouts::binocular::read_pair(&intrinsics, Some(&doc), options)?
        };
        let (left, right, t_left_right) = pair;
        let mut c = Self::new(left, right, t_left_right);
        c.metadata.notes = format!("imported from {name}");
        c.validate().map_err(|e| e.in_file(&name, "", None))?;
        Ok(c)
    }

    /// Reads this project's binocular JSON; `file` names the text in errors.
    ///
    /// # Errors
    /// [`CameraError::Json`] (a one-camera calibration file is named as such),
    /// [`CameraError::UnsupportedVersion`], [`CameraError::BadValue`];
    /// [`CameraError::Implausible`] naming the device and the key when a camera (or the
    /// projector) makes no physical sense ([`CameraModel::check_physical`]).
    pub fn from_json(text: &str, file: &str) -> Result<Self, CameraError> {
        let probe: serde_json::Value =
            serde_json::from_str(text).map_err(|source| CameraError::Json {
                file: file.to_owned(),
                source,
            })?;
        if probe.get("kind").and_then(|k| k.as_str()) != Some(KIND) {
            return Err(CameraError::BadValue {
                file: file.to_owned(),
                line: None,
                key: "kind".into(),
                message: format!(
                    "not a two-camera calibration (\"kind\": \"{KIND}\"): a camera–projector \
                     calibration is read by Calibration::load"
                ),
            });
        }
        let found = probe.get("version").and_then(serde_json::Value::as_u64);
        if found != Some(u64::from(BINOCULAR_FORMAT_VERSION)) {
            return Err(CameraError::UnsupportedVersion {
                file: file.to_owned(),
                found: found.unwrap_or(0),
                supported: BINOCULAR_FORMAT_VERSION,
            });
        }
        let repr: BinocularJson =
            serde_json::from_str(text).map_err(|source| CameraError::Json {
                file: file.to_owned(),
                source,
            })?;
        let t_left_right = repr
            .t_left_right
            .to_isometry()
            .map_err(|e| e.in_file(file, "T_left_right", None))?;
        let projector = match (repr.projector, repr.t_left_proj) {
            (Some(p), Some(t)) => Some((
                p,
                t.to_isometry()
                    .map_err(|e| e.in_file(file, "T_left_proj", None))?,
            )),
            (None, None) => None,
            _ => {
                return Err(CameraError::BadValue {
                    file: file.to_owned(),
                    line: None,
                    key: "projector".into(),
                    message: "give both `projector` and `T_left_proj`, or neither".into(),
                });
            }
        };
        let turntable = normalized_axis(repr.turntable, file)?;
        let c = Self {
            left: repr.left,
            right: repr.right,
            t_left_right,
            projector,
            rms: repr.rms,
            turntable,
            metadata: repr.metadata,
        };
        c.validate().map_err(|e| e.in_file(file, "", None))?;
        check_json_models(
            file,
            &[
                ("left camera", "left", Some(&c.left)),
                ("right camera", "right", Some(&c.right)),
                (
                    "projector",
                    "projector",
                    c.projector.as_ref().map(|(p, _)| p),
                ),
            ],
        )?;
        Ok(c)
    }

    /// This project's binocular JSON (pretty-printed).
    ///
    /// # Errors
    /// The error of [`BinocularCalibration::validate`].
    pub fn to_json(&self) -> Result<String, CameraError> {
        self.validate()?;
        let repr = BinocularJson {
            version: BINOCULAR_FORMAT_VERSION,
            kind: KIND.into(),
            left: self.left,
            right: self.right,
            t_left_right: PoseRepr::from_isometry(&self.t_left_right),
            projector: self.projector.map(|(p, _)| p),
            t_left_proj: self
                .projector
                .as_ref()
                .map(|(_, t)| PoseRepr::from_isometry(t)),
            rms: self.rms,
            turntable: self.turntable,
            metadata: self.metadata.clone(),
        };
        let mut text = serde_json::to_string_pretty(&repr).map_err(|source| CameraError::Json {
            file: "(binocular calibration being written)".into(),
            source,
        })?;
        text.push('\n');
        Ok(text)
    }

    /// Writes the JSON to `path` (`.json`).
    ///
    /// # Errors
    /// [`CameraError::UnknownExtension`] for another extension; [`CameraError::Io`].
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), CameraError> {
        let path = path.as_ref();
        if CalibrationFormat::from_path(path)? != CalibrationFormat::Json {
            return Err(CameraError::invalid(
                "path",
                format!(
                    "{}: two-camera calibrations are written as JSON (.json)",
                    path.display()
                ),
            ));
        }
        let text = self.to_json()?;
        std::fs::write(path, text).map_err(|source| CameraError::Io {
            path: path.to_owned(),
            source,
        })
    }
}

/// `extrinsic(s).yml` beside `intrinsic(s).yml` (the name's last `intrinsic` replaced).
fn extrinsic_sibling(path: &Path) -> PathBuf {
    replace_in_name(path, "intrinsic", "extrinsic")
}

/// `intrinsic(s).yml` beside `extrinsic(s).yml`.
fn intrinsic_sibling(path: &Path) -> PathBuf {
    replace_in_name(path, "extrinsic", "intrinsic")
}

fn replace_in_name(path: &Path, from: &str, to: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    match name.rfind(from) {
        Some(i) => path.with_file_name(format!("{}{to}{}", &name[..i], &name[i + from.len()..])),
        None => path.to_path_buf(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two-camera capture of `binocular_sdk` (`SL_DATA_EXTRA`): OpenCV's two files, the
    /// right camera ~300 mm to the left camera's right (`T ≈ (−299.8, −3.95, 33.6)` maps left
    /// into right coordinates), toed in by ~13.6°; no size stored, so it must be given.
    #[test]
    fn reads_the_binocular_sdk_pair() {
        let Some(extra) = std::env::var_os("SL_DATA_EXTRA") else {
            eprintln!("SL_DATA_EXTRA not set: skipping binocular_sdk");
            return;
        };
        let cali = Path::new(&extra).join("binocular_sdk/cali");
        let err = BinocularCalibration::load(cali.join("intrinsic.yml")).unwrap_err();
        assert!(err.to_string().contains("camera-size"), "{err}");
        let options = LoadConfig {
            camera_size: Some(crate::ImageSize::new(2048, 1536)),
            ..LoadConfig::default()
        };
        for file in ["intrinsic.yml", "extrinsic.yml"] {
            let c = BinocularCalibration::load_with(cali.join(file), &options).unwrap();
            assert!((c.left.intrinsics.fx - 4588.053).abs() < 1e-3);
            assert!((c.right.intrinsics.cx - 1006.109).abs() < 1e-3);
            let centre = c.t_left_right.translation.vector;
            assert!((centre.norm() - 301.7).abs() < 0.5, "{centre}");
            assert!(
                centre.x > 290.0,
                "the right camera is to the right: {centre}"
            );
            let angle = c.t_left_right.rotation.angle().to_degrees();
            assert!((angle - 13.57).abs() < 0.1, "{angle}");
        }
    }

    #[test]
    fn json_round_trips_and_a_one_camera_file_is_named() {
        let camera = CameraModel::new(
            crate::Intrinsics::new(1000.0, 1000.0, 319.5, 239.5),
            crate::Distortion::from_opencv(&[-0.1, 0.02, 0.0, 0.0, 0.0]).unwrap(),
            crate::ImageSize::new(640, 480),
        )
        .unwrap();
        let mut pair =
            BinocularCalibration::new(camera, camera, Isometry3::translation(120.0, 0.0, 0.0));
        pair.projector = Some((camera, Isometry3::translation(60.0, -30.0, 0.0)));
        pair.rms = Some(0.12);
        let text = pair.to_json().unwrap();
        assert_eq!(BinocularCalibration::from_json(&text, "t").unwrap(), pair);
        // With a turntable axis: read back as written, and a zero direction named by its key.
        pair.turntable = Some(TurntableAxis {
            direction: nalgebra::Vector3::new(0.0, -1.0, 0.0),
            point_mm: nalgebra::Point3::new(0.0, 80.0, 600.0),
            angle_offset_deg: 0.0,
            angle_scale: 1.0,
        });
        let text = pair.to_json().unwrap();
        assert!(text.contains("\"turntable\""), "{text}");
        assert_eq!(BinocularCalibration::from_json(&text, "t").unwrap(), pair);
        let zero = text.replacen("-1.0", "0.0", 1);
        let err = BinocularCalibration::from_json(&zero, "z.json").unwrap_err();
        assert!(err.to_string().contains("turntable.direction"), "{err}");
        let single = crate::Calibration::new(camera).to_json().unwrap();
        let err = BinocularCalibration::from_json(&single, "one.json").unwrap_err();
        assert!(err.to_string().contains("Calibration::load"), "{err}");
        let err = BinocularCalibration::new(camera, camera, Isometry3::identity())
            .validate()
            .unwrap_err();
        assert!(err.to_string().contains("baseline"), "{err}");
    }
}
