//! The calibration of a whole rig (camera, projector, extrinsics, turntable) and its files.

use std::fmt;
use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use crate::filestorage::{Document, parse_xml, parse_yaml, to_xml, to_yaml};
use crate::layouts::{
    self, CalibrationLayout, LoadConfig, LoadedCalibration, extrinsics_sibling, intrinsics_sibling,
};
use crate::pose::PoseRepr;
use crate::{CameraError, CameraModel, DistortionModel, ProjectorModel, TurntableAxis};
use sl_image::ToneCurve;

/// Version of the JSON calibration format this build writes and reads. Files with another
/// version are refused with [`CameraError::UnsupportedVersion`].
pub const CALIBRATION_FORMAT_VERSION: u32 = 1;

/// How far the turntable direction may be from unit length in a validated calibration:
/// a few ulps of rounding after normalisation, nothing a human would type.
const UNIT_TOLERANCE: f64 = 1e-9;

/// The calibration of a structured-light rig: the camera, and optionally the projector, the
/// camera–projector extrinsics and the turntable axis, with RMS errors and metadata.
///
/// Frames and units: `t_cam_proj` maps projector coordinates into camera coordinates
/// (`p_cam = T_cam_proj * p_proj`), translations in millimetres; the turntable axis is given
/// in the camera frame.
///
/// Files: [`Calibration::load`] and [`Calibration::save`] pick the format from the
/// extension: `.json` is this project's own format (versioned, lossless); `.yml`/`.yaml` and
/// `.xml` are OpenCV FileStorage in the layouts of OpenCV's calibration sample
/// (`camera_matrix`, `distortion_coefficients`, `image_width`, `image_height`) when there is
/// no projector, and of SLStudio (`Kc kc Kp kp Rp Tp`, where `Rp`/`Tp` map camera coordinates
/// into projector coordinates, i.e. `T_proj_cam = T_cam_proj⁻¹`) when there is one.
///
/// ```
/// use sl_camera::{Calibration, CameraModel, Distortion, ImageSize, Intrinsics};
/// let camera = CameraModel::new(
///     Intrinsics::new(1440.4, 1437.1, 667.8, 354.2),
///     Distortion::from_opencv(&[0.5466, -20.20, -0.02203, 0.008259, 211.1])?,
///     ImageSize::new(1280, 720),
/// )?;
/// let mut calib = Calibration::new(camera);
/// calib.rms.camera = Some(0.21);
/// let dir = tempfile::tempdir().unwrap();
/// for name in ["c.json", "c.yml", "c.xml"] {
///     let path = dir.path().join(name);
///     calib.save(&path)?;
///     assert_eq!(Calibration::load(&path)?.camera, calib.camera);
/// }
/// println!("{calib}"); // readable summary, as `slscan info` prints it
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
///
/// # JSON format (version 1)
///
/// Every key below is read; `projector`, `T_cam_proj`, `turntable`, `rms`, `metadata`, the
/// RMS values, `skew`, `angle_offset_deg` (0) and `angle_scale` (1) may be omitted or `null`.
/// Unknown keys are errors (they are typos, or a newer format, which has another `version`).
/// Distortion `model` is `none`, `plumb_bob` (`k1 k2 p1 p2 k3`) or `rational`
/// (`k1 k2 p1 p2 k3 k4 k5 k6`). `T_cam_proj.rotation` is the rotation matrix row by row.
///
/// ```
/// # use sl_camera::Calibration;
/// let text = r#"{
///   "version": 1,
///   "camera": {
///     "intrinsics": {"fx": 1440.4, "fy": 1437.1, "cx": 667.8, "cy": 354.2, "skew": 0.0},
///     "distortion": {"model": "plumb_bob",
///                    "k1": 0.5466, "k2": -20.2, "p1": -0.02203, "p2": 0.008259, "k3": 211.1},
///     "size": {"width": 1280, "height": 720}
///   },
///   "projector": {
///     "intrinsics": {"fx": 2210.0, "fy": 2208.5, "cx": 955.0, "cy": 1102.0},
///     "distortion": {"model": "none"},
///     "size": {"width": 1920, "height": 1080}
///   },
///   "T_cam_proj": {"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
///                  "translation_mm": [-160.0, 0.0, 25.0]},
///   "turntable": {"direction": [0, -1, 0], "point_mm": [0, 80, 600],
///                 "angle_offset_deg": 0.0, "angle_scale": 1.0},
///   "rms": {"camera": 0.19, "projector": null, "stereo": 0.27},
///   "metadata": {"tool_version": "sl-camera 0.1.0", "created": "2024-06-11T10:21:07Z",
///                "notes": ""}
/// }"#;
/// let calib = Calibration::from_json(text, "example.json")?;
/// assert_eq!(calib.t_cam_proj.unwrap().translation.vector.x, -160.0);
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// The camera.
    pub camera: CameraModel,
    /// The projector, modelled as an inverse camera.
    pub projector: Option<ProjectorModel>,
    /// Pose of the projector in the camera frame: `p_cam = T_cam_proj * p_proj` (mm).
    pub t_cam_proj: Option<Isometry3<f64>>,
    /// The turntable axis in the camera frame.
    pub turntable: Option<TurntableAxis>,
    /// The projector's response as the camera sees it (`slscan calibrate response`): the
    /// decoders correct the phase with it (`sl_codec::DecodeConfig::projector_response`).
    /// Written as `"projector_response": {"samples": [...]}`; only this project's JSON format
    /// holds it (OpenCV's layouts have no place for it).
    pub projector_response: Option<ToneCurve>,
    /// RMS reprojection errors.
    pub rms: RmsErrors,
    /// Who wrote the file, when, and notes.
    pub metadata: Metadata,
}

/// RMS reprojection errors in pixels (square root of the mean squared 2-D residual norm, as
/// OpenCV reports them), when known.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RmsErrors {
    /// Camera calibration RMS (px).
    #[serde(default)]
    pub camera: Option<f64>,
    /// Projector calibration RMS (projector px).
    #[serde(default)]
    pub projector: Option<f64>,
    /// Stereo (camera–projector) calibration RMS (px).
    #[serde(default)]
    pub stereo: Option<f64>,
}

/// Free-form information about a calibration file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metadata {
    /// The tool that wrote it; defaults to `sl-camera <version>`.
    #[serde(default = "default_tool_version")]
    pub tool_version: String,
    /// Creation time as an RFC 3339 string (`2024-06-11T10:21:07Z`), supplied by the caller;
    /// this crate never reads the clock.
    #[serde(default)]
    pub created: Option<String>,
    /// Notes.
    #[serde(default)]
    pub notes: String,
}

fn default_tool_version() -> String {
    format!("sl-camera {}", env!("CARGO_PKG_VERSION"))
}

impl Default for Metadata {
    fn default() -> Self {
        Self {
            tool_version: default_tool_version(),
            created: None,
            notes: String::new(),
        }
    }
}

/// File formats of [`Calibration::load`] and [`Calibration::save`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CalibrationFormat {
    /// This project's JSON (`.json`).
    Json,
    /// OpenCV FileStorage YAML (`.yml`, `.yaml`).
    OpenCvYaml,
    /// OpenCV FileStorage XML (`.xml`).
    OpenCvXml,
}

impl CalibrationFormat {
    /// The format of a path, by its (case-insensitive) extension.
    ///
    /// # Errors
    /// [`CameraError::UnknownExtension`] for another extension.
    pub fn from_path(path: &Path) -> Result<Self, CameraError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("json") => Ok(Self::Json),
            Some("yml" | "yaml") => Ok(Self::OpenCvYaml),
            Some("xml") => Ok(Self::OpenCvXml),
            _ => Err(CameraError::UnknownExtension {
                path: path.to_owned(),
            }),
        }
    }
}

/// The JSON file.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CalibrationJson {
    version: u32,
    camera: CameraModel,
    #[serde(default)]
    projector: Option<CameraModel>,
    #[serde(default, rename = "T_cam_proj")]
    t_cam_proj: Option<PoseRepr>,
    #[serde(default)]
    turntable: Option<TurntableAxis>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    projector_response: Option<ToneCurve>,
    #[serde(default)]
    rms: RmsErrors,
    #[serde(default)]
    metadata: Metadata,
}

#[derive(Deserialize)]
struct VersionProbe {
    version: Option<serde_json::Value>,
}

impl Calibration {
    /// A calibration of a camera alone, with default metadata.
    pub fn new(camera: CameraModel) -> Self {
        Self {
            camera,
            projector: None,
            t_cam_proj: None,
            turntable: None,
            projector_response: None,
            rms: RmsErrors::default(),
            metadata: Metadata::default(),
        }
    }

    /// The projector-to-camera pose inverted: `p_proj = T_proj_cam * p_cam`.
    pub fn t_proj_cam(&self) -> Option<Isometry3<f64>> {
        self.t_cam_proj.map(|t| t.inverse())
    }

    /// Loads a calibration: JSON by its `.json` extension, OpenCV FileStorage (`.yml`,
    /// `.yaml`, `.xml`) in any of the [`CalibrationLayout`]s, detected by its keys. For files
    /// that do not store everything (scan3d-capture's image sizes), use
    /// [`Calibration::load_with`].
    ///
    /// # Errors
    /// [`CameraError::Io`] if the file cannot be read, [`CameraError::UnknownExtension`],
    /// and the errors of [`Calibration::from_json`], [`Calibration::from_opencv_yaml`] and
    /// [`Calibration::from_opencv_xml`], which name the file, the line and the key.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, CameraError> {
        Ok(Self::load_with(path, &LoadConfig::default())?.calibration)
    }

    /// Loads a calibration in any [`CalibrationLayout`] (detected by its keys unless
    /// `options.layout` says which), with the sizes a layout does not store taken from
    /// `options`, and says which layout it was and which files were read. OpenCV's stereo
    /// sample is read from its two files, whichever is named: `intrinsics.yml` and the
    /// `extrinsics.yml` beside it (a missing extrinsics file leaves the calibration without
    /// extrinsics).
    ///
    /// ```
    /// use sl_camera::{Calibration, CalibrationLayout, ImageSize, LoadConfig};
    /// // A scan3d-capture calibration.yml, as cv::FileStorage writes it (no image sizes).
    /// let m = |rows: usize, cols: usize, data: &str| {
    ///     format!("!!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {data} ]\n")
    /// };
    /// let text = format!(
    ///     "%YAML:1.0\ncam_K: {}cam_kc: {}proj_K: {}proj_kc: {}R: {}T: {}cam_error: 0.12\n",
    ///     m(3, 3, "1400., 0., 640., 0., 1400., 512., 0., 0., 1."),
    ///     m(1, 5, "0., 0., 0., 0., 0."),
    ///     m(3, 3, "2000., 0., 512., 0., 2000., 768., 0., 0., 1."),
    ///     m(1, 5, "0., 0., 0., 0., 0."),
    ///     m(3, 3, "1., 0., 0., 0., 1., 0., 0., 0., 1."),
    ///     m(3, 1, "-150., 0., 0."),
    /// );
    /// let dir = tempfile::tempdir().unwrap();
    /// let path = dir.path().join("calibration.yml");
    /// std::fs::write(&path, text).unwrap();
    /// assert!(Calibration::load(&path).is_err()); // the image sizes are needed
    /// let options = LoadConfig {
    ///     camera_size: Some(ImageSize::new(1280, 1024)),
    ///     projector_size: Some(ImageSize::new(1024, 768)),
    ///     ..LoadConfig::default()
    /// };
    /// let loaded = Calibration::load_with(&path, &options)?;
    /// assert_eq!(loaded.layout, CalibrationLayout::Scan3dCapture);
    /// // p_proj = R p_cam + T: the projector sits at x = +150 mm in the camera frame.
    /// let t_cam_proj = loaded.calibration.t_cam_proj.unwrap();
    /// assert!((t_cam_proj.translation.vector.x - 150.0).abs() < 1e-12);
    /// # Ok::<(), sl_camera::CameraError>(())
    /// ```
    ///
    /// # Errors
    /// As [`Calibration::load`]; [`CameraError::MissingKey`] naming the size a layout lacks
    /// and the option that gives it.
    pub fn load_with(
        path: impl AsRef<Path>,
        options: &LoadConfig,
    ) -> Result<LoadedCalibration, CameraError> {
        let path = path.as_ref();
        let format = CalibrationFormat::from_path(path)?;
        if format == CalibrationFormat::Json {
            if let Some(layout) = options.layout
                && layout != CalibrationLayout::Json
            {
                return Err(CameraError::invalid(
                    "layout",
                    format!(
                        "{}: a .json file cannot be read as {layout}",
                        path.display()
                    ),
                ));
            }
            let calibration = Self::from_json(&read_text(path)?, &path.display().to_string())?;
            return Ok(LoadedCalibration {
                calibration,
                layout: CalibrationLayout::Json,
                files: vec![path.to_owned()],
            });
        }
        let doc = parse_file(path, format)?;
        let layout = match options.layout {
            Some(l) => l,
            None => layouts::detect(&doc).ok_or_else(|| layouts::unknown_layout(&doc))?,
        };
        if layout != CalibrationLayout::OpenCvStereo {
            let calibration = layouts::read_document(&doc, layout, options)?;
            return Ok(LoadedCalibration {
                calibration,
                layout,
                files: vec![path.to_owned()],
            });
        }
        // OpenCV's stereo sample: the intrinsics file and the extrinsics file beside it.
        let (calibration, other) = if doc.has("M1") {
            let e = extrinsics_sibling(path);
            let extrinsics = if e.is_file() && e != path {
                Some(parse_file(&e, CalibrationFormat::from_path(&e)?)?)
            } else {
                None
            };
            let c = layouts::read_stereo_pair(&doc, extrinsics.as_ref(), options)?;
            (c, extrinsics.map(|_| e))
        } else {
            let i = intrinsics_sibling(path);
            if !i.is_file() || i == path {
                return Err(doc.missing(
                    "M1",
                    Some(&format!(
                        "this is the stereo sample's extrinsics file; its intrinsics (M1 D1 M2 \
                         D2) were looked for in {}",
                        i.display()
                    )),
                ));
            }
            let intrinsics = parse_file(&i, CalibrationFormat::from_path(&i)?)?;
            let c = layouts::read_stereo_pair(&intrinsics, Some(&doc), options)?;
            (c, Some(i))
        };
        let mut files = vec![path.to_owned()];
        files.extend(other);
        Ok(LoadedCalibration {
            calibration,
            layout,
            files,
        })
    }

    /// Saves the calibration, choosing the format by extension (see [`Calibration::load`]):
    /// JSON, or FileStorage in SLStudio's layout when there is a projector and OpenCV's
    /// calibration sample's when there is none ([`CalibrationLayout::default_for`]).
    /// FileStorage files keep everything except the distinction between a 4- and a
    /// 5-coefficient distortion (both are the same model).
    ///
    /// # Errors
    /// [`CameraError::UnknownExtension`], [`CameraError::Io`], or the error of
    /// [`Calibration::validate`].
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), CameraError> {
        let path = path.as_ref();
        let layout = match CalibrationFormat::from_path(path)? {
            CalibrationFormat::Json => CalibrationLayout::Json,
            _ => CalibrationLayout::default_for(self),
        };
        self.save_as(path, layout).map(|_| ())
    }

    /// Saves the calibration in a [`CalibrationLayout`], as the other system writes it
    /// (`.yml`/`.yaml` as FileStorage YAML, `.xml` as XML; JSON needs `.json`), and returns
    /// the files written: for OpenCV's stereo sample, `path` is the intrinsics file and the
    /// extrinsics file is written beside it (`intrinsics.yml` → `extrinsics.yml`). What the
    /// layout has no key for is written under extra keys the other system ignores (see
    /// `docs/formats.md`), so [`Calibration::load`] reads it all back.
    ///
    /// # Errors
    /// [`CameraError::UnknownExtension`], [`CameraError::Io`], the error of
    /// [`Calibration::validate`], and [`CameraError::InvalidParameter`] when the layout
    /// cannot hold the calibration (scan3d-capture or OpenCV's stereo sample without a
    /// projector, OpenCV's calibration sample with one) or the extension does not fit it.
    pub fn save_as(
        &self,
        path: impl AsRef<Path>,
        layout: CalibrationLayout,
    ) -> Result<Vec<PathBuf>, CameraError> {
        let path = path.as_ref();
        let format = CalibrationFormat::from_path(path)?;
        let write = |p: &Path, text: String| {
            std::fs::write(p, text).map_err(|source| CameraError::Io {
                path: p.to_owned(),
                source,
            })
        };
        match (layout, format) {
            (CalibrationLayout::Json, CalibrationFormat::Json) => {
                write(path, self.to_json()?)?;
                return Ok(vec![path.to_owned()]);
            }
            (CalibrationLayout::Json, _) | (_, CalibrationFormat::Json) => {
                let wanted = if layout == CalibrationLayout::Json {
                    ".json"
                } else {
                    ".yml, .yaml or .xml"
                };
                return Err(CameraError::invalid(
                    "layout",
                    format!(
                        "{}: the {layout} layout is written as {wanted}",
                        path.display()
                    ),
                ));
            }
            _ => {}
        }
        self.validate()?;
        let items = layouts::write_items(self, layout)?;
        let render = |items: &[(&'static str, layouts::Item)]| match format {
            CalibrationFormat::OpenCvXml => to_xml(items),
            _ => to_yaml(items),
        };
        let mut files = vec![path.to_owned()];
        if let Some(extrinsics) = &items.extrinsics {
            let e = extrinsics_sibling(path);
            if e == path {
                return Err(CameraError::invalid(
                    "layout",
                    format!(
                        "{}: name the intrinsics file (e.g. intrinsics.yml); the extrinsics \
                         file is written beside it",
                        path.display()
                    ),
                ));
            }
            write(&e, render(extrinsics))?;
            files.push(e);
        }
        write(path, render(&items.main))?;
        Ok(files)
    }

    /// Reads this project's JSON format; `file` names the text in error messages.
    ///
    /// # Errors
    /// [`CameraError::MissingKey`] without a `version`, [`CameraError::UnsupportedVersion`]
    /// for another version, [`CameraError::Json`] (with line and column) for syntax and
    /// schema errors, [`CameraError::BadValue`] for invalid values,
    /// [`CameraError::Implausible`] naming the device and the key when the camera or the
    /// projector makes no physical sense ([`CameraModel::check_physical`]).
    pub fn from_json(text: &str, file: &str) -> Result<Self, CameraError> {
        let json_err = |source| CameraError::Json {
            file: file.to_owned(),
            source,
        };
        let probe: VersionProbe = serde_json::from_str(text).map_err(json_err)?;
        let version = probe.version.ok_or_else(|| CameraError::MissingKey {
            file: file.to_owned(),
            key: "version".into(),
            hint: Some(format!(
                "sl-camera calibration files start with \"version\": {CALIBRATION_FORMAT_VERSION}"
            )),
        })?;
        let found = version.as_u64().ok_or_else(|| CameraError::BadValue {
            file: file.to_owned(),
            line: None,
            key: "version".into(),
            message: format!("expected a positive integer, found {version}"),
        })?;
        if found != u64::from(CALIBRATION_FORMAT_VERSION) {
            return Err(CameraError::UnsupportedVersion {
                file: file.to_owned(),
                found,
                supported: CALIBRATION_FORMAT_VERSION,
            });
        }
        let repr: CalibrationJson = serde_json::from_str(text).map_err(json_err)?;
        let t_cam_proj = match repr.t_cam_proj {
            Some(p) => Some(
                p.to_isometry()
                    .map_err(|e| e.in_file(file, "T_cam_proj", None))?,
            ),
            None => None,
        };
        let turntable = normalized_axis(repr.turntable, file)?;
        let calibration = Self {
            camera: repr.camera,
            projector: repr.projector,
            t_cam_proj,
            turntable,
            projector_response: repr.projector_response,
            rms: repr.rms,
            metadata: repr.metadata,
        };
        calibration
            .validate()
            .map_err(|e| e.in_file(file, "", None))?;
        check_json_models(
            file,
            &[
                ("camera", "camera", Some(&calibration.camera)),
                ("projector", "projector", calibration.projector.as_ref()),
            ],
        )?;
        Ok(calibration)
    }

    /// Writes this project's JSON format (pretty-printed).
    ///
    /// # Errors
    /// The error of [`Calibration::validate`].
    pub fn to_json(&self) -> Result<String, CameraError> {
        self.validate()?;
        let repr = CalibrationJson {
            version: CALIBRATION_FORMAT_VERSION,
            camera: self.camera,
            projector: self.projector,
            t_cam_proj: self.t_cam_proj.as_ref().map(PoseRepr::from_isometry),
            turntable: self.turntable,
            projector_response: self.projector_response.clone(),
            rms: self.rms,
            metadata: self.metadata.clone(),
        };
        let mut text = serde_json::to_string_pretty(&repr).map_err(|source| CameraError::Json {
            file: "(calibration being written)".into(),
            source,
        })?;
        text.push('\n');
        Ok(text)
    }

    /// Reads an OpenCV FileStorage YAML file (see the type docs for the layouts).
    ///
    /// # Errors
    /// [`CameraError::Syntax`] and [`CameraError::BadValue`] with the line,
    /// [`CameraError::MissingKey`].
    pub fn from_opencv_yaml(text: &str, file: &str) -> Result<Self, CameraError> {
        from_document(&parse_yaml(text, file)?, &LoadConfig::default())
    }

    /// Reads an OpenCV FileStorage XML file (see the type docs for the layouts).
    ///
    /// # Errors
    /// As [`Calibration::from_opencv_yaml`].
    pub fn from_opencv_xml(text: &str, file: &str) -> Result<Self, CameraError> {
        from_document(&parse_xml(text, file)?, &LoadConfig::default())
    }

    /// Writes OpenCV FileStorage YAML that `cv::FileStorage` reads.
    ///
    /// # Errors
    /// The error of [`Calibration::validate`].
    pub fn to_opencv_yaml(&self) -> Result<String, CameraError> {
        self.validate()?;
        Ok(to_yaml(
            &layouts::write_items(self, CalibrationLayout::default_for(self))?.main,
        ))
    }

    /// Writes OpenCV FileStorage XML that `cv::FileStorage` reads.
    ///
    /// # Errors
    /// The error of [`Calibration::validate`].
    pub fn to_opencv_xml(&self) -> Result<String, CameraError> {
        self.validate()?;
        Ok(to_xml(
            &layouts::write_items(self, CalibrationLayout::default_for(self))?.main,
        ))
    }

    /// Checks everything a file must satisfy: valid camera and projector models, extrinsics
    /// only with a projector, finite non-negative RMS values, a finite unit turntable
    /// direction, an RFC 3339 creation time.
    ///
    /// # Errors
    /// [`CameraError::InvalidParameter`] naming the dotted key at fault.
    pub fn validate(&self) -> Result<(), CameraError> {
        let prefixed = |e: CameraError, prefix: &str| match e {
            CameraError::InvalidParameter { parameter, message } => {
                CameraError::invalid(format!("{prefix}.{parameter}"), message)
            }
            other => other,
        };
        self.camera.validate().map_err(|e| prefixed(e, "camera"))?;
        if let Some(p) = &self.projector {
            p.validate().map_err(|e| prefixed(e, "projector"))?;
        }
        if let Some(t) = &self.t_cam_proj {
            if self.projector.is_none() {
                return Err(CameraError::invalid(
                    "T_cam_proj",
                    "extrinsics are given without a projector model",
                ));
            }
            let finite = t.translation.vector.iter().all(|v| v.is_finite())
                && t.rotation.coords.iter().all(|v| v.is_finite());
            if !finite {
                return Err(CameraError::invalid("T_cam_proj", "must be finite"));
            }
        }
        if let Some(axis) = &self.turntable {
            let mut check = *axis;
            check.normalize()?;
            let n = axis.direction.norm();
            if n.is_nan() || (n - 1.0).abs() > UNIT_TOLERANCE {
                return Err(CameraError::invalid(
                    "turntable.direction",
                    format!("must be a unit vector, found norm {n} (see TurntableAxis::normalize)"),
                ));
            }
        }
        for (name, v) in [
            ("rms.camera", self.rms.camera),
            ("rms.projector", self.rms.projector),
            ("rms.stereo", self.rms.stereo),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v >= 0.0)
            {
                return Err(CameraError::invalid(
                    name,
                    format!("must be finite and non-negative, found {v}"),
                ));
            }
        }
        if let Some(created) = &self.metadata.created
            && !is_rfc3339(created)
        {
            return Err(CameraError::invalid(
                "metadata.created",
                format!(
                    "expected an RFC 3339 time such as 2024-06-11T10:21:07Z, found `{created}`"
                ),
            ));
        }
        Ok(())
    }
}

/// [`CameraModel::check_physical`] of the models of a JSON file `file`, each given as
/// `(device, JSON key, model)`: the first fault as [`CameraError::Implausible`] naming the
/// device and the key (`camera.intrinsics.fx`).
pub(crate) fn check_json_models(
    file: &str,
    models: &[(&'static str, &str, Option<&CameraModel>)],
) -> Result<(), CameraError> {
    for &(device, key, model) in models {
        if let Some(Err(why)) = model.map(CameraModel::check_physical) {
            return Err(CameraError::Implausible {
                file: file.to_owned(),
                line: None,
                device,
                key: format!("{key}.{}", why.parameter.json_key()),
                message: why.message,
            });
        }
    }
    Ok(())
}

/// Reads a FileStorage document in any layout (one file; OpenCV's stereo sample from its
/// intrinsics file alone).
fn from_document(doc: &Document, options: &LoadConfig) -> Result<Calibration, CameraError> {
    let layout = match options.layout {
        Some(l) => l,
        None => layouts::detect(doc).ok_or_else(|| layouts::unknown_layout(doc))?,
    };
    layouts::read_document(doc, layout, options)
}

pub(crate) fn read_text(path: &Path) -> Result<String, CameraError> {
    std::fs::read_to_string(path).map_err(|source| CameraError::Io {
        path: path.to_owned(),
        source,
    })
}

pub(crate) fn parse_file(path: &Path, format: CalibrationFormat) -> Result<Document, CameraError> {
    let text = read_text(path)?;
    let name = path.display().to_string();
    match format {
        CalibrationFormat::OpenCvXml => parse_xml(&text, &name),
        _ => parse_yaml(&text, &name),
    }
}

/// Whether `s` is an RFC 3339 date-time: `YYYY-MM-DDTHH:MM:SS[.frac](Z|±HH:MM)` (the `T`
/// may be `t` or a space, `Z` may be `z`).
pub(crate) fn is_rfc3339(s: &str) -> bool {
    let b = s.as_bytes();
    let digits = |range: std::ops::Range<usize>| -> Option<u32> {
        let part = b.get(range)?;
        if part.iter().all(u8::is_ascii_digit) {
            std::str::from_utf8(part).ok()?.parse().ok()
        } else {
            None
        }
    };
    let sep = |i: usize, allowed: &[u8]| b.get(i).is_some_and(|c| allowed.contains(c));
    let (Some(_year), Some(month), Some(day), Some(hour), Some(minute), Some(second)) = (
        digits(0..4),
        digits(5..7),
        digits(8..10),
        digits(11..13),
        digits(14..16),
        digits(17..19),
    ) else {
        return false;
    };
    if !(sep(4, b"-") && sep(7, b"-") && sep(10, b"Tt ") && sep(13, b":") && sep(16, b":")) {
        return false;
    }
    if !((1..=12).contains(&month)
        && (1..=31).contains(&day)
        && hour <= 23
        && minute <= 59
        && second <= 60)
    {
        return false;
    }
    let mut i = 19;
    if sep(i, b".") {
        i += 1;
        let start = i;
        while b.get(i).is_some_and(u8::is_ascii_digit) {
            i += 1;
        }
        if i == start {
            return false;
        }
    }
    match b.get(i) {
        Some(b'Z' | b'z') => i + 1 == b.len(),
        Some(b'+' | b'-') => {
            i + 6 == b.len()
                && sep(i + 3, b":")
                && digits(i + 1..i + 3).is_some_and(|h| h <= 23)
                && digits(i + 4..i + 6).is_some_and(|m| m <= 59)
        }
        _ => false,
    }
}

fn fmt_camera(f: &mut fmt::Formatter<'_>, m: &CameraModel, rms: Option<f64>) -> fmt::Result {
    let k = &m.intrinsics;
    writeln!(f, "  image: {} px", m.size)?;
    writeln!(
        f,
        "  fx {:.3}  fy {:.3}  cx {:.3}  cy {:.3}  skew {:.3} (px)",
        k.fx, k.fy, k.cx, k.cy, k.skew
    )?;
    let d = &m.distortion;
    write!(f, "  distortion: {}", d.model())?;
    if d.model() != DistortionModel::None {
        let names = crate::DISTORTION_PARAMETERS;
        let values = d.to_opencv_vec();
        write!(f, ":")?;
        for (name, v) in names.iter().zip(&values) {
            write!(f, " {name} {v}")?;
        }
    }
    writeln!(f)?;
    match m.field_of_view() {
        Some(fov) => write!(
            f,
            "  field of view: {:.1}° x {:.1}°",
            fov.horizontal_deg, fov.vertical_deg
        )?,
        None => write!(
            f,
            "  field of view: not computable (edges outside the valid region)"
        )?,
    }
    let r = d.max_radius();
    if r.is_finite() {
        write!(
            f,
            "; one-to-one up to {:.1}° off-axis",
            r.atan().to_degrees()
        )?;
        if r >= crate::monotonic::RADIUS_CAP {
            write!(f, " (the search limit)")?;
        }
    }
    writeln!(f)?;
    if let Some(rms) = rms {
        writeln!(f, "  RMS reprojection error: {rms:.4} px")?;
    }
    Ok(())
}

impl fmt::Display for Calibration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "Calibration (sl-camera format v{CALIBRATION_FORMAT_VERSION})"
        )?;
        writeln!(f, "Camera:")?;
        fmt_camera(f, &self.camera, self.rms.camera)?;
        match &self.projector {
            Some(p) => {
                writeln!(f, "Projector:")?;
                fmt_camera(f, p, self.rms.projector)?;
            }
            None => writeln!(f, "Projector: none")?,
        }
        match &self.t_cam_proj {
            Some(t) => {
                let axis = t
                    .rotation
                    .axis()
                    .map_or([0.0, 0.0, 1.0], |a| [a.x, a.y, a.z]);
                let tr = t.translation.vector;
                writeln!(f, "Extrinsics T_cam_proj (projector -> camera):")?;
                writeln!(
                    f,
                    "  rotation {:.3}° about ({:.4}, {:.4}, {:.4})",
                    t.rotation.angle().to_degrees(),
                    axis[0],
                    axis[1],
                    axis[2]
                )?;
                writeln!(
                    f,
                    "  translation ({:.3}, {:.3}, {:.3}) mm; baseline {:.3} mm",
                    tr.x,
                    tr.y,
                    tr.z,
                    tr.norm()
                )?;
                if let Some(s) = self.rms.stereo {
                    writeln!(f, "  stereo RMS reprojection error: {s:.4} px")?;
                }
            }
            None => {
                writeln!(f, "Extrinsics: none")?;
                if let Some(s) = self.rms.stereo {
                    writeln!(f, "  stereo RMS reprojection error: {s:.4} px")?;
                }
            }
        }
        match &self.turntable {
            Some(a) => writeln!(
                f,
                "Turntable: axis ({:.5}, {:.5}, {:.5}) through ({:.3}, {:.3}, {:.3}) mm; \
                 platter angle = {} x motor + {}°",
                a.direction.x,
                a.direction.y,
                a.direction.z,
                a.point_mm.x,
                a.point_mm.y,
                a.point_mm.z,
                a.angle_scale,
                a.angle_offset_deg
            )?,
            None => writeln!(f, "Turntable: none")?,
        }
        write!(f, "Metadata: {}", self.metadata.tool_version)?;
        if let Some(c) = &self.metadata.created {
            write!(f, "; created {c}")?;
        }
        writeln!(f)?;
        for line in self.metadata.notes.lines() {
            writeln!(f, "  {line}")?;
        }
        Ok(())
    }
}

/// A JSON file's turntable axis with its direction made unit length; a bad axis is named by
/// its key in `file`.
pub(crate) fn normalized_axis(
    axis: Option<TurntableAxis>,
    file: &str,
) -> Result<Option<TurntableAxis>, CameraError> {
    let Some(mut axis) = axis else {
        return Ok(None);
    };
    axis.normalize().map_err(|e| match e {
        CameraError::InvalidParameter { parameter, message } => CameraError::BadValue {
            file: file.to_owned(),
            line: None,
            key: parameter.replace("turntable", "turntable.direction"),
            message,
        },
        other => other,
    })?;
    Ok(Some(axis))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rfc3339() {
        for ok in [
            "2024-06-11T10:21:07Z",
            "2024-06-11t10:21:07.123456z",
            "2024-06-11 10:21:07+02:00",
            "1999-12-31T23:59:60-08:30",
        ] {
            assert!(is_rfc3339(ok), "{ok}");
        }
        for bad in [
            "",
            "2024-06-11",
            "2024-13-11T10:21:07Z",
            "2024-06-11T10:21:07",
            "2024-06-11T10:21:07.Z",
            "2024-06-11T24:00:00Z",
            "2024-06-11T10:21:07+0200",
            "Tue Jun 11 10:21:07 2024",
            "2024-06-11T10:21:07Zx",
        ] {
            assert!(!is_rfc3339(bad), "{bad}");
        }
    }

    #[test]
    fn format_from_extension() {
        assert_eq!(
            CalibrationFormat::from_path(Path::new("a/B.YML")).unwrap(),
            CalibrationFormat::OpenCvYaml
        );
        assert_eq!(
            CalibrationFormat::from_path(Path::new("c.yaml")).unwrap(),
            CalibrationFormat::OpenCvYaml
        );
        assert_eq!(
            CalibrationFormat::from_path(Path::new("c.xml")).unwrap(),
            CalibrationFormat::OpenCvXml
        );
        assert_eq!(
            CalibrationFormat::from_path(Path::new("c.json")).unwrap(),
            CalibrationFormat::Json
        );
        let e = CalibrationFormat::from_path(Path::new("c.txt")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("c.txt: unknown calibration file extension")
        );
    }
}
