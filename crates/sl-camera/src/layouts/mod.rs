//! The calibration file layouts of other systems, and ours: which keys hold what, and which way
//! their extrinsics map. One file per layout; this module holds what they share (detection by
//! keys, camera and pose readers, the extra keys that make every layout round-trip).
//!
//! Every peer layout stores its extrinsics as `p_proj = R · p_cam + T` (the pose
//! `T_proj_cam`, as `cv::stereoCalibrate` and `cv::solvePnP` return it); we store its inverse
//! `T_cam_proj`. Where each layout's convention was read is in `docs/formats.md`.
//!
//! What a layout has no key for (turntable axis, metadata, and for some the image sizes and RMS
//! values) is written under extra keys that OpenCV and the peers' readers ignore and that we
//! read back: `turntable_direction`, `turntable_point_mm`, `turntable_angle_offset_deg`,
//! `turntable_angle_scale`, `tool_version`, `created`, `notes`, `camera_width`,
//! `camera_height`, `projector_width`, `projector_height`, `cam_error`, `proj_error`,
//! `stereo_error`. Translations are taken to be millimetres.

pub(crate) mod binocular;
mod opencv_camera;
mod opencv_stereo;
mod scan3d_capture;
mod slmaster;
mod slstudio;

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

pub(crate) use crate::filestorage::Item;
use crate::filestorage::{Document, MatrixData};
use crate::pose::{isometry_from_rt, isometry_to_rt};
use crate::{
    Calibration, CameraError, CameraModel, Distortion, ImageSize, Intrinsics, Metadata,
    ModelParameter, RmsErrors, TurntableAxis,
};

pub(crate) use opencv_stereo::{extrinsics_sibling, intrinsics_sibling};

/// The layouts of calibration files this crate reads and writes. Which keys each has, and
/// which way its extrinsics map, is in `docs/formats.md`.
///
/// ```
/// use sl_camera::CalibrationLayout;
/// let layout: CalibrationLayout = "scan3d-capture".parse()?;
/// assert_eq!(layout, CalibrationLayout::Scan3dCapture);
/// assert_eq!(layout.to_string(), "scan3d-capture");
/// # Ok::<(), sl_camera::CameraError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CalibrationLayout {
    /// This project's JSON (versioned, lossless).
    Json,
    /// OpenCV's calibration sample (`samples/cpp/calibration.cpp`): `camera_matrix`,
    /// `distortion_coefficients`, `image_width`, `image_height` (a camera alone).
    OpenCvCamera,
    /// SLStudio's `calibration.xml` (`CalibrationData::saveXML`): `Kc kc Kp kp Rp Tp`, errors
    /// and sizes.
    SlStudio,
    /// Moreno & Taubin's scan3d-capture `calibration.yml`: `cam_K cam_kc proj_K proj_kc R T
    /// cam_error proj_error stereo_error` (no image sizes).
    Scan3dCapture,
    /// SLMaster's `caliInfo.yml`: `M1 D1` camera, `S` its size, `M4 D4` projector, `Rlp Tlp`
    /// camera to projector.
    SlMaster,
    /// OpenCV's stereo sample (`samples/cpp/stereo_calib.cpp`): `intrinsics.yml` (`M1 D1 M2
    /// D2`, camera 1 = our camera, camera 2 = our projector) and `extrinsics.yml` (`R T`, and
    /// the rectification `R1 R2 P1 P2 Q` we ignore). No image sizes.
    OpenCvStereo,
}

impl CalibrationLayout {
    /// Every layout, in the order of the docs.
    pub const ALL: [Self; 6] = [
        Self::Json,
        Self::OpenCvCamera,
        Self::SlStudio,
        Self::Scan3dCapture,
        Self::SlMaster,
        Self::OpenCvStereo,
    ];

    /// The name used on the command line (`--format`): `json`, `opencv-camera`, `slstudio`,
    /// `scan3d-capture`, `slmaster`, `opencv-stereo`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Json => "json",
            Self::OpenCvCamera => "opencv-camera",
            Self::SlStudio => "slstudio",
            Self::Scan3dCapture => "scan3d-capture",
            Self::SlMaster => "slmaster",
            Self::OpenCvStereo => "opencv-stereo",
        }
    }

    /// What writes files of this layout, for messages (`slscan info` prints it).
    pub fn description(self) -> &'static str {
        match self {
            Self::Json => "structured-light's JSON",
            Self::OpenCvCamera => "OpenCV calibration sample (camera_matrix, ...)",
            Self::SlStudio => "SLStudio calibration.xml (Kc kc Kp kp Rp Tp)",
            Self::Scan3dCapture => {
                "scan3d-capture calibration.yml, Moreno & Taubin (cam_K proj_K R T)"
            }
            Self::SlMaster => "SLMaster caliInfo.yml (M1 D1 S M4 D4 Rlp Tlp)",
            Self::OpenCvStereo => {
                "OpenCV stereo sample intrinsics.yml + extrinsics.yml (M1 D1 M2 D2, R T)"
            }
        }
    }

    /// The layout [`Calibration::save`] writes for a FileStorage file: SLStudio's when the
    /// calibration has a projector, else OpenCV's calibration sample.
    pub fn default_for(calibration: &Calibration) -> Self {
        if calibration.projector.is_some() {
            Self::SlStudio
        } else {
            Self::OpenCvCamera
        }
    }
}

impl fmt::Display for CalibrationLayout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for CalibrationLayout {
    type Err = CameraError;

    /// Parses a [`CalibrationLayout::name`] (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|l| l.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|l| l.name()).collect();
                CameraError::invalid(
                    "layout",
                    format!("unknown layout `{s}`: one of {}", names.join(", ")),
                )
            })
    }
}

/// Options of [`Calibration::load_with`]: what a file may lack.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadConfig {
    /// Read the file as this layout instead of detecting it by its keys.
    pub layout: Option<CalibrationLayout>,
    /// The camera's image size, for layouts that do not store it (scan3d-capture, OpenCV's
    /// stereo sample). A file that stores another size is an error.
    pub camera_size: Option<ImageSize>,
    /// The projector's frame-buffer size, for layouts that do not store it (scan3d-capture,
    /// SLMaster, OpenCV's stereo sample).
    pub projector_size: Option<ImageSize>,
}

/// A calibration read by [`Calibration::load_with`], with the layout it was read as and the
/// files it came from (two for OpenCV's stereo sample).
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedCalibration {
    /// The calibration.
    pub calibration: Calibration,
    /// The layout the file was read as.
    pub layout: CalibrationLayout,
    /// The files read, the one named first.
    pub files: Vec<PathBuf>,
}

/// The layout of a FileStorage document, from its keys.
pub(crate) fn detect(doc: &Document) -> Option<CalibrationLayout> {
    if doc.has("Kc") {
        Some(CalibrationLayout::SlStudio)
    } else if doc.has("cam_K") {
        Some(CalibrationLayout::Scan3dCapture)
    } else if doc.has("M1") && (doc.has("S") || doc.has("M4") || doc.has("Rlp")) {
        Some(CalibrationLayout::SlMaster)
    } else if doc.has("M1") && doc.has("M2") {
        Some(CalibrationLayout::OpenCvStereo)
    } else if doc.has("camera_matrix") {
        Some(CalibrationLayout::OpenCvCamera)
    } else if doc.has("R") && doc.has("T") && !doc.has("M1") {
        // extrinsics.yml of OpenCV's stereo sample, alone.
        Some(CalibrationLayout::OpenCvStereo)
    } else {
        None
    }
}

/// The error for a document whose layout is not recognised.
pub(crate) fn unknown_layout(doc: &Document) -> CameraError {
    doc.missing(
        "camera_matrix",
        Some(
            "no known layout: expected OpenCV's `camera_matrix`, SLStudio's `Kc`, \
             scan3d-capture's `cam_K`, SLMaster's `M1` with `S`/`M4`, or OpenCV's stereo \
             sample's `M1` and `M2`",
        ),
    )
}

/// Reads a one-file document as `layout` (OpenCV's stereo sample: its intrinsics file alone).
pub(crate) fn read_document(
    doc: &Document,
    layout: CalibrationLayout,
    options: &LoadConfig,
) -> Result<Calibration, CameraError> {
    refuse_fisheye(doc)?;
    let calibration = match layout {
        CalibrationLayout::Json => {
            return Err(CameraError::invalid(
                "layout",
                format!("{}: a FileStorage file cannot be read as JSON", doc.file),
            ));
        }
        CalibrationLayout::OpenCvCamera => opencv_camera::read(doc, options)?,
        CalibrationLayout::SlStudio => slstudio::read(doc, options)?,
        CalibrationLayout::Scan3dCapture => scan3d_capture::read(doc, options)?,
        CalibrationLayout::SlMaster => slmaster::read(doc, options)?,
        CalibrationLayout::OpenCvStereo => opencv_stereo::read(doc, None, options)?,
    };
    finish(doc, calibration)
}

/// Reads OpenCV's stereo sample from its two documents.
pub(crate) fn read_stereo_pair(
    intrinsics: &Document,
    extrinsics: Option<&Document>,
    options: &LoadConfig,
) -> Result<Calibration, CameraError> {
    refuse_fisheye(intrinsics)?;
    let calibration = opencv_stereo::read(intrinsics, extrinsics, options)?;
    finish(intrinsics, calibration)
}

fn finish(doc: &Document, calibration: Calibration) -> Result<Calibration, CameraError> {
    calibration
        .validate()
        .map_err(|e| e.in_file(&doc.file, "", None))?;
    Ok(calibration)
}

fn refuse_fisheye(doc: &Document) -> Result<(), CameraError> {
    if let Some(fisheye) = doc.number("fisheye_model")?
        && fisheye != 0.0
    {
        let line = doc.get("fisheye_model").map_or(0, |n| n.line);
        return Err(doc.bad(
            "fisheye_model",
            line,
            "OpenCV's fisheye (Kannala–Brandt) model is not supported; recalibrate with the \
             standard or rational model",
        ));
    }
    Ok(())
}

/// The top-level items of one FileStorage file, in order.
pub(crate) type Items = Vec<(&'static str, Item)>;

/// The FileStorage items of a calibration in a layout: the file's, and for OpenCV's stereo
/// sample the second file's (`extrinsics.yml`).
pub(crate) struct LayoutItems {
    /// The items of the file named.
    pub(crate) main: Items,
    /// The items of the second file, if the layout has one.
    pub(crate) extrinsics: Option<Items>,
}

/// The items of `c` in `layout` (a FileStorage layout).
///
/// # Errors
/// [`CameraError::InvalidParameter`] when the layout cannot hold the calibration (a procam
/// layout without a projector).
pub(crate) fn write_items(
    c: &Calibration,
    layout: CalibrationLayout,
) -> Result<LayoutItems, CameraError> {
    let (mut main, extrinsics) = match layout {
        CalibrationLayout::Json => {
            return Err(CameraError::invalid(
                "layout",
                "JSON is not a FileStorage layout",
            ));
        }
        CalibrationLayout::OpenCvCamera => (opencv_camera::items(c)?, None),
        CalibrationLayout::SlStudio => (slstudio::items(c), None),
        CalibrationLayout::Scan3dCapture => (scan3d_capture::items(c)?, None),
        CalibrationLayout::SlMaster => (slmaster::items(c), None),
        CalibrationLayout::OpenCvStereo => {
            let (i, e) = opencv_stereo::items(c)?;
            (i, Some(e))
        }
    };
    push_extras(c, &mut main);
    Ok(LayoutItems { main, extrinsics })
}

/// The projector a procam-only layout needs.
fn require_projector(
    c: &Calibration,
    layout: CalibrationLayout,
) -> Result<&CameraModel, CameraError> {
    c.projector.as_ref().ok_or_else(|| {
        CameraError::invalid(
            "projector",
            format!(
                "the {} layout holds a camera and a projector; this calibration has no \
                 projector (write it as `opencv-camera` or `json`)",
                layout.name()
            ),
        )
    })
}

// ---- reading helpers ----------------------------------------------------------------------

/// A camera model (of `device`: `camera` or `projector`) from a 3x3 matrix key, a distortion
/// key and a size, checked for physical sense ([`CameraModel::check_physical`]): a fault is
/// [`CameraError::Implausible`] naming the key that holds the parameter at fault.
fn camera_from(
    doc: &Document,
    device: &'static str,
    k_key: &str,
    d_key: &str,
    size: ImageSize,
) -> Result<CameraModel, CameraError> {
    let k = doc.matrix(k_key)?.ok_or_else(|| doc.missing(k_key, None))?;
    let intrinsics = Intrinsics::from_matrix(&matrix3(doc, k_key, &k)?)
        .map_err(|e| doc.bad(k_key, k.line, message_of(e)))?;
    let distortion = match doc.matrix(d_key)? {
        None => return Err(doc.missing(d_key, Some("write an empty matrix for no distortion"))),
        Some(d) => {
            if d.rows != 1 && d.cols != 1 && !d.data.is_empty() {
                return Err(doc.bad(
                    d_key,
                    d.line,
                    format!("expected a vector, found a {}x{} matrix", d.rows, d.cols),
                ));
            }
            Distortion::from_opencv(&d.data).map_err(|e| doc.bad(d_key, d.line, message_of(e)))?
        }
    };
    let model = CameraModel {
        intrinsics,
        distortion,
        size,
    };
    if let Err(why) = model.check_physical() {
        let key = match why.parameter {
            ModelParameter::Intrinsic(_) => k_key,
            ModelParameter::Distortion(_) => d_key,
        };
        return Err(CameraError::Implausible {
            file: doc.file.clone(),
            line: doc.get(key).map(|n| n.line),
            device,
            key: key.to_owned(),
            message: why.message,
        });
    }
    Ok(model)
}

/// An image size stored as two integer keys, if both are there.
fn size_from_keys(
    doc: &Document,
    w_key: &str,
    h_key: &str,
) -> Result<Option<(ImageSize, usize)>, CameraError> {
    match (doc.unsigned(w_key)?, doc.unsigned(h_key)?) {
        (Some(w), Some(h)) => {
            let line = doc.get(w_key).map_or(0, |n| n.line);
            Ok(Some((ImageSize::new(w, h), line)))
        }
        (None, None) => Ok(None),
        (Some(_), None) => Err(doc.missing(h_key, Some(&format!("`{w_key}` is given")))),
        (None, Some(_)) => Err(doc.missing(w_key, Some(&format!("`{h_key}` is given")))),
    }
}

/// The size a file stores (`stored`, with the key and line), else the one of the options;
/// both must agree when both are given, and one is needed.
fn resolve_size(
    doc: &Document,
    stored: Option<(ImageSize, usize)>,
    key: &str,
    option: Option<ImageSize>,
    missing_hint: &str,
) -> Result<ImageSize, CameraError> {
    let size = match (stored, option) {
        (Some((s, line)), Some(o)) if s != o => {
            return Err(doc.bad(
                key,
                line,
                format!(
                    "the file says {}x{}, the options {}x{}",
                    s.width, s.height, o.width, o.height
                ),
            ));
        }
        (Some((s, line)), _) => {
            s.validate()
                .map_err(|e| doc.bad(key, line, message_of(e.into())))?;
            s
        }
        (None, Some(o)) => {
            o.validate()
                .map_err(|e| doc.bad(key, 0, message_of(e.into())))?;
            o
        }
        (None, None) => return Err(doc.missing(key, Some(missing_hint))),
    };
    Ok(size)
}

/// The hint for a size a layout does not store.
fn size_hint(layout: CalibrationLayout, device: &str, option: &str, flag: &str) -> String {
    format!(
        "the {} layout does not store the {device}'s image size: give it \
         (LoadConfig::{option}, or slscan {flag} WxH)",
        layout.name()
    )
}

/// `T_cam_proj` from a layout's `R`, `T` keys, which map camera coordinates into projector
/// coordinates (`p_proj = R · p_cam + T`).
fn t_cam_proj_from(
    doc: &Document,
    r_key: &str,
    t_key: &str,
) -> Result<Option<Isometry3<f64>>, CameraError> {
    match (doc.matrix(r_key)?, doc.matrix(t_key)?) {
        (Some(r), Some(t)) => {
            let rm = matrix3(doc, r_key, &r)?;
            let tv = vector3(doc, t_key, &t)?;
            let t_proj_cam =
                isometry_from_rt(&rm, &tv).map_err(|e| doc.bad(r_key, r.line, message_of(e)))?;
            Ok(Some(t_proj_cam.inverse()))
        }
        (None, None) => Ok(None),
        (Some(_), None) => Err(doc.missing(t_key, Some(&format!("`{r_key}` is given")))),
        (None, Some(_)) => Err(doc.missing(r_key, Some(&format!("`{t_key}` is given")))),
    }
}

/// The RMS values under SLStudio's and scan3d-capture's keys.
fn rms_from(doc: &Document, camera_key: &str) -> Result<RmsErrors, CameraError> {
    Ok(RmsErrors {
        camera: doc.number(camera_key)?,
        projector: doc.number("proj_error")?,
        stereo: doc.number("stereo_error")?,
    })
}

/// The turntable axis and metadata extras, the metadata defaulting to "imported from".
fn extras_from(
    doc: &Document,
    layout: CalibrationLayout,
) -> Result<(Option<TurntableAxis>, Metadata), CameraError> {
    let turntable = turntable_from(doc)?;
    let mut notes = doc.string("notes")?.unwrap_or_default();
    if let Some(time) = doc.string("calibration_time")? {
        if !notes.is_empty() {
            notes.push('\n');
        }
        notes.push_str(&format!("calibration_time: {time}"));
    }
    let metadata = Metadata {
        tool_version: doc.string("tool_version")?.unwrap_or_else(|| {
            format!(
                "imported from OpenCV FileStorage ({} layout)",
                layout.description()
            )
        }),
        created: doc.string("created")?,
        notes,
    };
    Ok((turntable, metadata))
}

fn turntable_from(doc: &Document) -> Result<Option<TurntableAxis>, CameraError> {
    let (Some(dir), Some(point)) = (
        doc.matrix("turntable_direction")?,
        doc.matrix("turntable_point_mm")?,
    ) else {
        if doc.has("turntable_direction") {
            return Err(doc.missing("turntable_point_mm", Some("`turntable_direction` is given")));
        }
        if doc.has("turntable_point_mm") {
            return Err(doc.missing("turntable_direction", Some("`turntable_point_mm` is given")));
        }
        return Ok(None);
    };
    let mut axis = TurntableAxis {
        direction: vector3(doc, "turntable_direction", &dir)?,
        point_mm: Point3::from(vector3(doc, "turntable_point_mm", &point)?),
        angle_offset_deg: doc.number("turntable_angle_offset_deg")?.unwrap_or(0.0),
        angle_scale: doc.number("turntable_angle_scale")?.unwrap_or(1.0),
    };
    axis.normalize()
        .map_err(|e| doc.bad("turntable_direction", dir.line, message_of(e)))?;
    Ok(Some(axis))
}

fn matrix3(doc: &Document, key: &str, m: &MatrixData) -> Result<Matrix3<f64>, CameraError> {
    if m.rows != 3 || m.cols != 3 {
        return Err(doc.bad(
            key,
            m.line,
            format!("expected a 3x3 matrix, found {}x{}", m.rows, m.cols),
        ));
    }
    Ok(Matrix3::from_row_slice(&m.data))
}

fn vector3(doc: &Document, key: &str, m: &MatrixData) -> Result<Vector3<f64>, CameraError> {
    if m.data.len() != 3 || (m.rows != 1 && m.cols != 1) {
        return Err(doc.bad(
            key,
            m.line,
            format!("expected 3 values (3x1), found {}x{}", m.rows, m.cols),
        ));
    }
    Ok(Vector3::from_column_slice(&m.data))
}

/// The message part of an API error, for re-wrapping it with a file and key.
fn message_of(e: CameraError) -> String {
    match e {
        CameraError::InvalidParameter { parameter, message } => format!("{parameter}: {message}"),
        other => other.to_string(),
    }
}

// ---- writing helpers ----------------------------------------------------------------------

/// A camera matrix as a 3x3 FileStorage matrix.
fn k_item(m: &CameraModel) -> Item {
    Item::Matrix {
        rows: 3,
        cols: 3,
        data: m.intrinsics.matrix().transpose().iter().copied().collect(),
    }
}

/// Distortion coefficients as an `n x 1` matrix (`0 x 0` for none).
fn d_item(m: &CameraModel) -> Item {
    let v = m.distortion.to_opencv_vec();
    Item::Matrix {
        rows: v.len(),
        cols: usize::from(!v.is_empty()),
        data: v,
    }
}

fn size_item(v: u32) -> Item {
    Item::Int(i64::from(v))
}

/// `T_proj_cam` (the inverse of `T_cam_proj`) as a 3x3 `R` and a 3x1 `T`.
fn rt_items(
    t_cam_proj: &Isometry3<f64>,
    r_key: &'static str,
    t_key: &'static str,
) -> [(&'static str, Item); 2] {
    let (r, t) = isometry_to_rt(&t_cam_proj.inverse());
    [
        (
            r_key,
            Item::Matrix {
                rows: 3,
                cols: 3,
                data: r.transpose().iter().copied().collect(),
            },
        ),
        (
            t_key,
            Item::Matrix {
                rows: 3,
                cols: 1,
                data: t.iter().copied().collect(),
            },
        ),
    ]
}

/// The RMS values that are known, under SLStudio's keys (`camera_key` for the camera's).
fn push_rms(c: &Calibration, camera_key: &'static str, items: &mut Vec<(&'static str, Item)>) {
    for (key, value) in [
        (camera_key, c.rms.camera),
        ("proj_error", c.rms.projector),
        ("stereo_error", c.rms.stereo),
    ] {
        if let Some(v) = value {
            items.push((key, Item::Real(v)));
        }
    }
}

/// The image size of a camera or projector under the extra keys `{prefix}_width`/`_height`.
fn push_size_extra(
    size: ImageSize,
    keys: (&'static str, &'static str),
    items: &mut Vec<(&'static str, Item)>,
) {
    items.push((keys.0, size_item(size.width)));
    items.push((keys.1, size_item(size.height)));
}

/// Extra keys for the camera's and projector's sizes, where a layout has none.
const CAMERA_SIZE_KEYS: (&str, &str) = ("camera_width", "camera_height");
/// See [`CAMERA_SIZE_KEYS`].
const PROJECTOR_SIZE_KEYS: (&str, &str) = ("projector_width", "projector_height");

/// Turntable and metadata, which no layout has.
fn push_extras(c: &Calibration, items: &mut Vec<(&'static str, Item)>) {
    if let Some(axis) = &c.turntable {
        let v3 = |v: [f64; 3]| Item::Matrix {
            rows: 3,
            cols: 1,
            data: v.to_vec(),
        };
        items.push((
            "turntable_direction",
            v3([axis.direction.x, axis.direction.y, axis.direction.z]),
        ));
        items.push((
            "turntable_point_mm",
            v3([axis.point_mm.x, axis.point_mm.y, axis.point_mm.z]),
        ));
        items.push((
            "turntable_angle_offset_deg",
            Item::Real(axis.angle_offset_deg),
        ));
        items.push(("turntable_angle_scale", Item::Real(axis.angle_scale)));
    }
    items.push(("tool_version", Item::Str(c.metadata.tool_version.clone())));
    if let Some(created) = &c.metadata.created {
        items.push(("created", Item::Str(created.clone())));
    }
    if !c.metadata.notes.is_empty() {
        items.push(("notes", Item::Str(c.metadata.notes.clone())));
    }
}
