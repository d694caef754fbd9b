//! The measuring stage, where a truth exists (the virtual rig): the truth of the scene and of
//! the flatness plate as `sl-metrology` descriptions, and the scan measured against them
//! (VDI/VDE 2634 part 2: probing size and form, sphere spacing, flatness).

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use sl_cloud::PointCloud;
use sl_metrology::{
    Feature, PlaneNominal, PlaneSpec, Report, SpherePairSpec, SphereSpec, Truth, evaluate,
};
use sl_sim::{
    DEFAULT_ALBEDO, DEFAULT_WORKING_DISTANCE_MM, Mount, Scene, SceneObject, Shape, Texture,
    VirtualRig,
};

use crate::ScanError;

/// Half-width of the selection region of every feature of the scene's truth (mm): points
/// within 2 mm of a true surface — 40 times the 0.05 mm probing target — are measured, so
/// only mis-decoded or mis-merged points are left out.
pub const SELECT_MM: f64 = 2.0;

/// The flat plate of the flatness measurement: 160 × 100 mm.
pub const PLATE_SIZE_MM: (f64, f64) = (160.0, 100.0);

/// Tilt of the plate about the camera's vertical and horizontal axes (degrees): VDI/VDE 2634
/// part 2 measures flatness in several oblique positions; one such position, at the working
/// distance, is measured here.
pub const PLATE_TILT_DEG: (f64, f64) = (25.0, 15.0);

/// The truth of the rig's scene seen at motor angle `motor_deg`, in the camera frame: every
/// sphere with its true centre and radius, and — for the first two spheres — their true centre
/// distance (the dumbbell's sphere spacing). Selection regions of [`SELECT_MM`].
pub fn scene_truth(rig: &VirtualRig, motor_deg: f64) -> Truth {
    let t_cam_table = rig.config().t_cam_table_at(motor_deg);
    let mut truth = Truth::new(format!(
        "virtual rig scene at motor angle {motor_deg} degrees, camera frame (mm)"
    ));
    let mut centres = Vec::new();
    for o in &rig.scene().objects {
        if let Shape::Sphere { radius } = o.shape {
            let pose = match o.mount {
                Mount::Turntable => t_cam_table * o.pose,
                Mount::Camera => o.pose,
            };
            let centre = Point3::from(pose.translation.vector);
            centres.push((o.name.clone(), centre));
            truth = truth.with(Feature::Sphere(SphereSpec {
                name: o.name.clone(),
                radius_mm: radius,
                centre_mm: Some(centre),
                select_mm: SELECT_MM,
            }));
        }
    }
    if let [(n0, c0), (n1, c1), ..] = centres.as_slice() {
        truth = truth.with(Feature::SpherePair(SpherePairSpec {
            name: format!("{n0}-{n1}"),
            spheres: [n0.clone(), n1.clone()],
            centre_distance_mm: (c0 - c1).norm(),
        }));
    }
    truth
}

/// `T_cam_plate` of the flatness plate: centred on the optical axis at the working distance,
/// turned [`PLATE_TILT_DEG`] about the camera's y and x axes.
pub fn plate_pose() -> Isometry3<f64> {
    let (yaw, pitch) = PLATE_TILT_DEG;
    Isometry3::from_parts(
        Translation3::new(0.0, 0.0, DEFAULT_WORKING_DISTANCE_MM),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), yaw.to_radians())
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), pitch.to_radians()),
    )
}

/// The flatness scene: the plate of [`PLATE_SIZE_MM`] at [`plate_pose`], fixed in the camera
/// frame (the turntable does not move it).
pub fn plate_scene() -> Scene {
    let (w, h) = PLATE_SIZE_MM;
    Scene::new().with(SceneObject::in_camera(
        "plate",
        Shape::rectangle(w, h),
        Texture::Uniform(DEFAULT_ALBEDO),
        plate_pose(),
    ))
}

/// The truth of [`plate_scene`]: its plane, in the camera frame.
pub fn plate_truth() -> Truth {
    let pose = plate_pose();
    let normal = pose.rotation * Vector3::z();
    Truth::new("flat plate of the virtual rig, camera frame (mm)").with(Feature::Plane(PlaneSpec {
        name: "plate".to_owned(),
        nominal: Some(PlaneNominal {
            normal,
            offset_mm: normal.dot(&pose.translation.vector),
        }),
        select_mm: SELECT_MM,
    }))
}

/// The figures of a scan measured against its truth.
#[derive(Debug, Clone)]
pub struct Measurements {
    /// The merged cloud measured against the scene's truth (probing and sphere-spacing errors).
    pub accuracy: Report,
    /// The first view alone (before merging) measured against the same truth: the noise and
    /// the grazing points of one view, without registration or averaging.
    pub first_view: Report,
    /// The plate's cloud measured against [`plate_truth`] (flatness), when captured.
    pub flatness: Option<Report>,
}

/// Measures the merged cloud and the first view against `truth`, and the plate's cloud (when
/// given) against [`plate_truth`] (`sl_metrology::evaluate`).
///
/// # Errors
/// [`ScanError::Metrology`] when a feature of the truth cannot be measured (too few points).
pub fn measure_scan(
    merged: &PointCloud,
    first_view: &PointCloud,
    truth: &Truth,
    plate: Option<&PointCloud>,
) -> Result<Measurements, ScanError> {
    Ok(Measurements {
        accuracy: evaluate(merged, truth)?,
        first_view: evaluate(first_view, truth)?,
        flatness: match plate {
            Some(cloud) => Some(evaluate(cloud, &plate_truth())?),
            None => None,
        },
    })
}
