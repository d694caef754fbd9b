//! Ground truth of a view at camera pixel centres.

use nalgebra::{Isometry3, Point2, Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Caster, Lens};

/// Value of [`ViewTruth::object`] for a pixel that sees no object.
pub const NO_OBJECT: u16 = u16::MAX;

/// The pose of one scene object in one view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectPose {
    /// The object's name.
    pub name: String,
    /// `T_cam_object`: the object frame in the camera frame.
    pub t_cam_object: Isometry3<f64>,
}

/// Ground truth of one view, at the centre of every camera pixel (no super-sampling).
///
/// Maps are row-major, `width × height`, pixel `(x, y)` at index `y · width + x`; entries
/// where the map has no value are NaN.
#[derive(Debug, Clone)]
pub struct ViewTruth {
    /// Camera image width (pixels).
    pub width: u32,
    /// Camera image height (pixels).
    pub height: u32,
    /// Motor reading of the turntable (degrees).
    pub motor_angle_deg: f64,
    /// Platter angle (degrees).
    pub platter_angle_deg: f64,
    /// `T_cam_table` in this view.
    pub t_cam_table: Isometry3<f64>,
    /// Pose of every object, in the order of the scene.
    pub objects: Vec<ObjectPose>,
    /// Depth: the `z` of the surface point in the camera frame (mm).
    pub depth_mm: Vec<f64>,
    /// The surface point in the camera frame (mm).
    pub points_cam: Vec<Point3<f64>>,
    /// Unit surface normal in the camera frame, facing the camera.
    pub normals_cam: Vec<Vector3<f64>>,
    /// The exact, continuous projector coordinate (projector pixels) of the light that reaches
    /// the point; NaN where the projector does not light it.
    pub projector: Vec<Point2<f64>>,
    /// Index of the object seen (in the scene's order), or [`NO_OBJECT`].
    pub object: Vec<u16>,
}

impl ViewTruth {
    /// `true` where the camera sees an object.
    pub fn visible(&self, i: usize) -> bool {
        self.object.get(i).is_some_and(|&o| o != NO_OBJECT)
    }

    /// `true` where the camera sees an object that the projector lights: the pixels a decoder
    /// should decode.
    pub fn lit(&self, i: usize) -> bool {
        self.projector.get(i).is_some_and(|p| p.x.is_finite())
    }

    /// Number of pixels where the camera sees a lit object.
    pub fn lit_count(&self) -> usize {
        self.projector.iter().filter(|p| p.x.is_finite()).count()
    }

    /// Number of pixels where the camera sees an object.
    pub fn visible_count(&self) -> usize {
        self.object.iter().filter(|&&o| o != NO_OBJECT).count()
    }
}

/// Depth, point, normal, projector coordinate and object of one pixel.
type PixelTruth = (f64, Point3<f64>, Vector3<f64>, Point2<f64>, u16);

impl<P: Lens> Caster<'_, P> {
    /// Casts one ray through every pixel centre; fills the per-pixel maps of a [`ViewTruth`]
    /// (the caller sets the poses).
    pub(crate) fn truth_maps(&self) -> ViewTruth {
        let (w, h) = (self.rays.width, self.rays.height);
        let nan3 = Point3::new(f64::NAN, f64::NAN, f64::NAN);
        let rows: Vec<Vec<PixelTruth>> = (0..h)
            .into_par_iter()
            .map(|y| {
                (0..w)
                    .map(|x| {
                        let i = y as usize * w as usize + x as usize;
                        let [nx, ny] = self.rays.centre.get(i).copied().unwrap_or([f64::NAN; 2]);
                        let s = self.sample(nx, ny);
                        match s.hit {
                            Some(hit) => (
                                hit.point.z,
                                hit.point,
                                hit.normal,
                                s.proj.unwrap_or(Point2::new(f64::NAN, f64::NAN)),
                                u16::try_from(hit.object).unwrap_or(NO_OBJECT - 1),
                            ),
                            None => (
                                f64::NAN,
                                nan3,
                                nan3.coords,
                                Point2::new(f64::NAN, f64::NAN),
                                NO_OBJECT,
                            ),
                        }
                    })
                    .collect()
            })
            .collect();
        let n = w as usize * h as usize;
        let mut t = ViewTruth {
            width: w,
            height: h,
            motor_angle_deg: 0.0,
            platter_angle_deg: 0.0,
            t_cam_table: Isometry3::identity(),
            objects: Vec::new(),
            depth_mm: Vec::with_capacity(n),
            points_cam: Vec::with_capacity(n),
            normals_cam: Vec::with_capacity(n),
            projector: Vec::with_capacity(n),
            object: Vec::with_capacity(n),
        };
        for (d, p, nrm, q, o) in rows.into_iter().flatten() {
            t.depth_mm.push(d);
            t.points_cam.push(p);
            t.normals_cam.push(nrm);
            t.projector.push(q);
            t.object.push(o);
        }
        t
    }
}

/// The true colour of the scene's surface nearest a point ([`VirtualRig::true_colour`]).
///
/// [`VirtualRig::true_colour`]: crate::VirtualRig::true_colour
#[derive(Debug, Clone, PartialEq)]
pub struct TrueColour {
    /// The RGB albedo there, each channel in `[0, 1]` ([`Texture::albedo_rgb_at`]; a grey
    /// texture's albedo in the three channels).
    ///
    /// [`Texture::albedo_rgb_at`]: crate::Texture::albedo_rgb_at
    pub rgb: [f64; 3],
    /// Distance (mm) from the point asked about to the nearest surface point.
    pub distance_mm: f64,
    /// The name of the object whose surface it is.
    pub object: String,
}
