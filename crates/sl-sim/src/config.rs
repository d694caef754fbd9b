//! The rig's configuration: camera and projector models, their poses, the turntable, and how
//! frames are rendered.

use nalgebra::{
    Isometry3, Matrix3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};
use serde::{Deserialize, Serialize};
use sl_camera::{CameraModel, Distortion, ImageSize, Intrinsics, TurntableAxis};

use crate::geometry::Lens;
use crate::{CameraEffects, Illumination, SimError};

/// Distance from the camera to the point where the optical axes cross and the turntable axis
/// stands (mm): the seed design's working distance.
pub const DEFAULT_WORKING_DISTANCE_MM: f64 = 450.0;
/// Projector's offset to the camera's right (mm): with the axes crossing at 450 mm, a
/// triangulation angle of about 24°, where depth resolution and shadowing balance well.
pub const DEFAULT_BASELINE_MM: f64 = 200.0;
/// Downward tilt of the camera and projector (degrees), so that they see the top of objects on
/// the turntable.
pub const DEFAULT_TILT_DEG: f64 = 20.0;
/// Height above the table top (mm) at which the optical axes cross the turntable axis: the
/// middle of a 120 mm object.
pub const DEFAULT_AIM_HEIGHT_MM: f64 = 60.0;

/// How the virtual camera renders frames.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RenderConfig {
    /// Sub-samples per pixel along each axis (anti-aliasing): `s × s` camera rays per pixel.
    /// 2 for objects; use 4 or more for checkerboards, whose corner accuracy depends on
    /// anti-aliased edges.
    pub supersampling: u32,
    /// Ambient light and projector response.
    pub illumination: Illumination,
    /// Global illumination, defocus and the sensor.
    pub effects: CameraEffects,
    /// Seed of every random number the rig draws (noise): the same seed renders the same
    /// frames, whatever the number of threads.
    pub seed: u64,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            supersampling: 2,
            illumination: Illumination::default(),
            effects: CameraEffects::default(),
            seed: 0,
        }
    }
}

/// A second camera of the virtual rig (binocular structured light): its model and its pose in
/// the first camera's frame, `p_cam = t_cam_second · p_second` (mm). The first camera is the
/// left one of a [`sl_camera::BinocularCalibration`], this the right: `t_cam_second` is its
/// `t_left_right`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SecondCamera {
    /// The camera model.
    pub camera: CameraModel,
    /// Its pose in the first camera's frame.
    pub t_cam_second: Isometry3<f64>,
}

/// The virtual rig: camera and projector models, their relative pose, and the turntable.
///
/// The camera frame is the reference. The turntable's `table` frame at platter angle 0 is
/// `t_cam_table`: origin on the axis at the table top, `z` up along the axis. A motor reading
/// `m` (degrees) turns the platter to `θ = angle_scale · m + angle_offset_deg`, right-handedly
/// about the table's `z`: `T_cam_table(θ) = t_cam_table · Rz(θ)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigConfig {
    /// The camera model.
    pub camera: CameraModel,
    /// The projector model (an inverse camera).
    pub projector: CameraModel,
    /// `T_cam_proj`: the projector's pose in the camera frame.
    pub t_cam_proj: Isometry3<f64>,
    /// `T_cam_table` at platter angle 0.
    pub t_cam_table: Isometry3<f64>,
    /// Platter angle (degrees) at motor reading 0.
    pub angle_offset_deg: f64,
    /// Platter degrees per motor degree.
    pub angle_scale: f64,
    /// Rendering options.
    pub render: RenderConfig,
}

/// A rotation whose `z` axis points along `forward` and whose `y` axis is as close as
/// possible to `down`.
fn look_rotation(forward: &Vector3<f64>, down: &Vector3<f64>) -> UnitQuaternion<f64> {
    let z = forward.normalize();
    let x = down.cross(&z).normalize();
    let y = z.cross(&x);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::from_columns(
        &[x, y, z],
    )))
}

impl Default for RigConfig {
    /// Close to the seed design: a 1280×720 camera (fx = 1440 px) and a 1920×1080 projector
    /// (fx = 2200 px, same field of view at the working distance), both tilted
    /// [`DEFAULT_TILT_DEG`] down, the projector [`DEFAULT_BASELINE_MM`] to the camera's right
    /// and toed in so that the optical axes cross the turntable axis at
    /// [`DEFAULT_WORKING_DISTANCE_MM`], [`DEFAULT_AIM_HEIGHT_MM`] above the table. Modest
    /// 5-coefficient distortion on both (under 2 px at the image corners).
    fn default() -> Self {
        let tilt = DEFAULT_TILT_DEG.to_radians();
        let (s, c) = tilt.sin_cos();
        // Camera frame is level-then-pitched: world "up" seen from the camera.
        let up = Vector3::new(0.0, -c, -s);
        let aim = Point3::new(0.0, 0.0, DEFAULT_WORKING_DISTANCE_MM);
        let table_origin = aim - up * DEFAULT_AIM_HEIGHT_MM;
        let x_t = Vector3::x();
        let y_t = up.cross(&x_t);
        let r_table = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x_t, y_t, up]));
        let t_cam_table = Isometry3::from_parts(
            Translation3::from(table_origin.coords),
            UnitQuaternion::from_rotation_matrix(&r_table),
        );
        let proj_centre = Point3::new(DEFAULT_BASELINE_MM, 0.0, 0.0);
        let t_cam_proj = Isometry3::from_parts(
            Translation3::from(proj_centre.coords),
            look_rotation(&(aim - proj_centre), &Vector3::y()),
        );
        // Both models are built from literals that satisfy every check of sl-camera; should
        // that ever change, fall back to distortion-free models rather than panic.
        let camera = CameraModel {
            intrinsics: Intrinsics::new(1440.0, 1440.0, 639.5, 359.5),
            distortion: Distortion::from_opencv(&[-0.08, 0.12, 0.0004, -0.0003, 0.0])
                .unwrap_or_default(),
            size: ImageSize::new(1280, 720),
        };
        let projector = CameraModel {
            intrinsics: Intrinsics::new(2200.0, 2200.0, 959.5, 539.5),
            distortion: Distortion::from_opencv(&[0.04, -0.05, 0.0, 0.0, 0.0]).unwrap_or_default(),
            size: ImageSize::new(1920, 1080),
        };
        Self {
            camera,
            projector,
            t_cam_proj,
            t_cam_table,
            angle_offset_deg: 0.0,
            angle_scale: 1.0,
            render: RenderConfig::default(),
        }
    }
}

/// Largest super-sampling factor accepted: 8×8 = 64 rays per pixel already costs ~0.5 GB of
/// cache for a 1280×720 view.
pub const MAX_SUPERSAMPLING: u32 = 8;

impl RigConfig {
    /// The rig with the camera's and the projector's images divided by `d` in each direction
    /// (the same fields of view: focal lengths divided by `d`, pixel centres kept at the
    /// centres of the larger pixels they replace); `d` ≤ 1 leaves it as it is. The quick rigs
    /// of tests and `slscan --downscale`.
    #[must_use]
    pub fn downscaled(mut self, d: u32) -> Self {
        if d > 1 {
            let f = f64::from(d);
            for m in [&mut self.camera, &mut self.projector] {
                let k = m.intrinsics;
                m.intrinsics = Intrinsics::new(
                    k.fx / f,
                    k.fy / f,
                    (k.cx + 0.5) / f - 0.5,
                    (k.cy + 0.5) / f - 0.5,
                );
                m.size = ImageSize::new(m.size.width / d, m.size.height / d);
            }
        }
        self
    }

    /// Checks both models, the poses, the turntable and the rendering options.
    pub fn validate(&self) -> Result<(), SimError> {
        self.camera
            .validate()
            .map_err(|e| SimError::param("camera", e.to_string()))?;
        self.projector
            .validate()
            .map_err(|e| SimError::param("projector", e.to_string()))?;
        let pixels = u64::from(self.projector.size.width) * u64::from(self.projector.size.height);
        if pixels >= u64::from(u32::MAX) {
            return Err(SimError::param(
                "projector size",
                format!("{} is too large", self.projector.size),
            ));
        }
        for (name, pose) in [
            ("t_cam_proj", &self.t_cam_proj),
            ("t_cam_table", &self.t_cam_table),
        ] {
            let finite = pose
                .translation
                .vector
                .iter()
                .chain(pose.rotation.coords.iter())
                .all(|v| v.is_finite());
            if !finite {
                return Err(SimError::param(name, "pose is not finite"));
            }
        }
        if !(self.angle_offset_deg.is_finite()
            && self.angle_scale.is_finite()
            && self.angle_scale != 0.0)
        {
            return Err(SimError::param(
                "turntable angle_offset_deg / angle_scale",
                format!(
                    "{} / {} must be finite, the scale non-zero",
                    self.angle_offset_deg, self.angle_scale
                ),
            ));
        }
        let s = self.render.supersampling;
        if s == 0 || s > MAX_SUPERSAMPLING {
            return Err(SimError::param(
                "supersampling",
                format!("{s} is not in 1..={MAX_SUPERSAMPLING}"),
            ));
        }
        self.render.illumination.validate()?;
        self.render.effects.validate()
    }

    /// The platter angle (degrees) for a motor reading (degrees).
    pub fn platter_angle_deg(&self, motor_deg: f64) -> f64 {
        self.angle_scale * motor_deg + self.angle_offset_deg
    }

    /// `T_cam_table` when the motor reads `motor_deg`.
    pub fn t_cam_table_at(&self, motor_deg: f64) -> Isometry3<f64> {
        let angle = self.platter_angle_deg(motor_deg).to_radians();
        self.t_cam_table * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle)
    }

    /// The default second camera of a binocular rig: this camera's twin on the other side of
    /// the projector (its centre at twice the projector's offset from this camera), turned
    /// about its centre to look at the point where this camera's and the projector's optical
    /// axes meet, with a principal point and a distortion of its own (a twin off the same
    /// production line, not a copy).
    pub fn default_second_camera(&self) -> SecondCamera {
        let proj = self.t_cam_proj.translation.vector;
        let centre = Point3::from(2.0 * proj);
        // The point of this camera's axis (the z axis) nearest the projector's axis.
        let d = self.t_cam_proj.rotation * Vector3::z();
        let (b, e) = (d.z, d.dot(&proj));
        let denom = 1.0 - b * b;
        let depth = if denom > 1e-9 {
            (proj.z - b * e) / denom
        } else {
            proj.norm()
        };
        let aim = Point3::new(0.0, 0.0, depth);
        let t_cam_second = Isometry3::from_parts(
            Translation3::from(centre.coords),
            look_rotation(&(aim - centre), &Vector3::y()),
        );
        let mut camera = self.camera;
        let k = camera.intrinsics;
        let size = camera.size;
        camera.intrinsics = Intrinsics::new(
            k.fx * 1.004,
            k.fy * 1.004,
            k.cx - 0.008 * f64::from(size.width),
            k.cy + 0.006 * f64::from(size.height),
        );
        camera.distortion = Distortion::from_opencv(&[-0.06, 0.09, -0.0003, 0.0005, 0.0])
            .unwrap_or(camera.distortion);
        SecondCamera {
            camera,
            t_cam_second,
        }
    }

    /// The same rig seen from `second`: its camera, and the projector and the platter where
    /// they are, in the second camera's frame. Its noise seed is the next one, so that the
    /// two cameras' noise is independent.
    pub fn seen_from(&self, second: &SecondCamera) -> RigConfig {
        let t_second_cam = second.t_cam_second.inverse();
        let mut c = self.clone();
        c.camera = second.camera;
        c.t_cam_proj = t_second_cam * self.t_cam_proj;
        c.t_cam_table = t_second_cam * self.t_cam_table;
        c.render.seed = self.render.seed.wrapping_add(1);
        c
    }

    /// The turntable axis in the camera frame, as the calibration file holds it.
    pub fn turntable_axis(&self) -> TurntableAxis {
        TurntableAxis {
            direction: self.t_cam_table.rotation * Vector3::z(),
            point_mm: Point3::from(self.t_cam_table.translation.vector),
            angle_offset_deg: self.angle_offset_deg,
            angle_scale: self.angle_scale,
        }
    }
}

impl Lens for CameraModel {
    fn size(&self) -> (u32, u32) {
        (self.size.width, self.size.height)
    }
    fn project(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        CameraModel::project(self, p)
    }
}
