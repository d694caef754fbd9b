//! Ray casting into a scene placed in the camera frame (parry3d-f64 for the solids and
//! meshes, closed form for rectangles).

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use parry3d_f64::query::{Ray, RayCast};
use parry3d_f64::shape::{Ball, Cuboid, Cylinder};

use crate::footprint::Footprint;
use crate::{Mount, Scene, Shape, Texture};

/// Offset (mm) along the surface normal of a shadow ray's origin, so that the ray does not
/// hit the surface it starts from. Far above f64 rounding at rig distances (~1e-13 mm) and
/// parry's support-map tolerance, far below any feature of a scanned object.
const SHADOW_RAY_OFFSET_MM: f64 = 1e-6;

/// `iso.inverse_transform_vector(v)`: the same operations in the same order as nalgebra
/// 0.34's (`q.conjugate() * v` as `t = 2 (q̄ × v)`, `t w + q̄ × t + v`), hence the same bits,
/// but inlined. Ray casting calls it several times per camera sub-sample, and at
/// `opt-level = 2` LLVM leaves nalgebra's version a call (with parry's, a sixth of a render's
/// samples; inlined, the test binaries that render ran 3–5 % faster).
#[inline(always)]
pub(crate) fn inverse_rotate(iso: &Isometry3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    let q = iso.rotation.quaternion();
    quaternion_rotate(&-q.imag(), q.w, v)
}

/// `iso.transform_vector(v)` (`q * v`), as [`inverse_rotate`] (bit for bit nalgebra's result).
#[inline(always)]
fn rotate(iso: &Isometry3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    let q = iso.rotation.quaternion();
    quaternion_rotate(&q.imag(), q.w, v)
}

/// `v` rotated by the unit quaternion `(a, w)`, as nalgebra computes `q * v`.
#[inline(always)]
fn quaternion_rotate(a: &Vector3<f64>, w: f64, v: &Vector3<f64>) -> Vector3<f64> {
    let t = a.cross(v) * 2.0;
    let c = a.cross(&t);
    t * w + c + v
}

/// `iso.inverse_transform_point(p)`, as [`inverse_rotate`] (bit for bit nalgebra's result).
#[inline(always)]
pub(crate) fn inverse_transform(iso: &Isometry3<f64>, p: &Point3<f64>) -> Point3<f64> {
    Point3::from(inverse_rotate(iso, &(p - iso.translation.vector).coords))
}

/// What a camera ray hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray (mm).
    pub distance: f64,
    /// The point hit, in the camera frame (mm).
    pub point: Point3<f64>,
    /// Unit surface normal at the point, camera frame, turned to face the ray's origin.
    pub normal: Vector3<f64>,
    /// Index of the object in [`Scene::objects`].
    pub object: usize,
    /// Albedo of the surface at the point.
    pub albedo: f64,
}

#[derive(Debug, Clone)]
enum Solid {
    Rectangle {
        x_min: f64,
        y_min: f64,
        x_max: f64,
        y_max: f64,
    },
    Ball(Ball),
    Cuboid(Cuboid),
    Cylinder(Cylinder),
    Mesh(std::sync::Arc<parry3d_f64::shape::TriMesh>),
}

#[derive(Debug, Clone)]
struct Placed {
    solid: Solid,
    /// `T_cam_object` (the object frame, where the texture lives).
    t_cam_object: Isometry3<f64>,
    /// `T_cam_shape`: the frame parry's shape is defined in (differs for cylinders, whose
    /// parry axis is `y`).
    t_cam_shape: Isometry3<f64>,
    texture: Texture,
    gloss: Option<crate::Gloss>,
    /// The camera centre in the object frame: where every camera ray starts.
    camera_in_object: Point3<f64>,
    /// The object's `z` axis in the camera frame (a rectangle's normal).
    z_cam: Vector3<f64>,
}

/// A scene at one turntable pose, placed in the camera frame, ready for ray casting.
#[derive(Debug, Clone)]
pub struct PlacedScene {
    objects: Vec<Placed>,
}

impl PlacedScene {
    /// Places `scene` with the turntable frame at `t_cam_table` (objects mounted on the
    /// camera keep their pose).
    pub fn new(scene: &Scene, t_cam_table: &Isometry3<f64>) -> Self {
        let objects = scene
            .objects
            .iter()
            .map(|o| {
                let t_cam_object = match o.mount {
                    Mount::Turntable => t_cam_table * o.pose,
                    Mount::Camera => o.pose,
                };
                let (solid, local) = match &o.shape {
                    Shape::Rectangle {
                        x_min,
                        y_min,
                        x_max,
                        y_max,
                    } => (
                        Solid::Rectangle {
                            x_min: *x_min,
                            y_min: *y_min,
                            x_max: *x_max,
                            y_max: *y_max,
                        },
                        Isometry3::identity(),
                    ),
                    Shape::Sphere { radius } => {
                        (Solid::Ball(Ball::new(*radius)), Isometry3::identity())
                    }
                    Shape::Cuboid { size } => (
                        Solid::Cuboid(Cuboid::new(size / 2.0)),
                        Isometry3::identity(),
                    ),
                    Shape::Cylinder { radius, height } => (
                        Solid::Cylinder(Cylinder::new(height / 2.0, *radius)),
                        // parry's cylinder axis is y; ours is z: rotate y onto z.
                        Isometry3::from_parts(
                            nalgebra::Translation3::identity(),
                            UnitQuaternion::from_axis_angle(
                                &Vector3::x_axis(),
                                std::f64::consts::FRAC_PI_2,
                            ),
                        ),
                    ),
                    Shape::Mesh(m) => (Solid::Mesh(m.clone()), Isometry3::identity()),
                };
                Placed {
                    solid,
                    camera_in_object: inverse_transform(&t_cam_object, &Point3::origin()),
                    z_cam: t_cam_object.rotation * Vector3::z(),
                    t_cam_object,
                    t_cam_shape: t_cam_object * local,
                    texture: o.texture.clone(),
                    gloss: o.gloss,
                }
            })
            .collect();
        Self { objects }
    }

    /// The first surface hit by the ray from `origin` along the unit vector `dir` closer than
    /// `max_distance`, or `None`.
    pub fn cast(&self, origin: &Point3<f64>, dir: &Vector3<f64>, max_distance: f64) -> Option<Hit> {
        let ray = Ray::new(*origin, *dir);
        let mut best: Option<(f64, Vector3<f64>, usize)> = None;
        let mut limit = max_distance;
        for (k, o) in self.objects.iter().enumerate() {
            if let Some((t, n)) = o.cast(&ray, limit) {
                limit = t;
                best = Some((t, n, k));
            }
        }
        let (t, n, k) = best?;
        let o = self.objects.get(k)?;
        let point = ray.point_at(t);
        let normal = if n.dot(dir) > 0.0 { -n } else { n };
        let local = inverse_transform(&o.t_cam_object, &point);
        Some(Hit {
            distance: t,
            point,
            normal,
            object: k,
            albedo: o.texture.albedo_at(&local),
        })
    }

    /// The albedo of `hit`'s surface averaged over the parallelogram centred on the hit point
    /// with edges `edge_x` and `edge_y` (camera frame, mm; a camera sub-sample's footprint on
    /// the tangent plane), instead of the point sample in [`Hit::albedo`].
    pub(crate) fn albedo_over(
        &self,
        hit: &Hit,
        edge_x: &Vector3<f64>,
        edge_y: &Vector3<f64>,
    ) -> f64 {
        let Some(o) = self.objects.get(hit.object) else {
            return hit.albedo;
        };
        if o.texture.is_uniform() {
            return hit.albedo;
        }
        let fp = Footprint {
            centre: inverse_transform(&o.t_cam_object, &hit.point),
            edge_x: inverse_rotate(&o.t_cam_object, edge_x),
            edge_y: inverse_rotate(&o.t_cam_object, edge_y),
        };
        o.texture.albedo_over(&fp)
    }

    /// The specular lobe of object `k`, if it has one.
    pub(crate) fn gloss(&self, k: usize) -> Option<crate::Gloss> {
        self.objects.get(k).and_then(|o| o.gloss)
    }

    /// The RGB albedo of `hit`'s surface averaged over the parallelogram of
    /// [`PlacedScene::albedo_over`].
    pub(crate) fn albedo_rgb_over(
        &self,
        hit: &Hit,
        edge_x: &Vector3<f64>,
        edge_y: &Vector3<f64>,
    ) -> [f64; 3] {
        let Some(o) = self.objects.get(hit.object) else {
            return [hit.albedo; 3];
        };
        let fp = Footprint {
            centre: inverse_transform(&o.t_cam_object, &hit.point),
            edge_x: inverse_rotate(&o.t_cam_object, edge_x),
            edge_y: inverse_rotate(&o.t_cam_object, edge_y),
        };
        o.texture.albedo_rgb_over(&fp)
    }

    /// The RGB albedo at `hit`'s point.
    pub(crate) fn albedo_rgb_at(&self, hit: &Hit) -> [f64; 3] {
        self.objects.get(hit.object).map_or([hit.albedo; 3], |o| {
            o.texture
                .albedo_rgb_at(&inverse_transform(&o.t_cam_object, &hit.point))
        })
    }

    /// Whether any object has a colour texture ([`Texture::is_colour`]).
    pub(crate) fn has_colour(&self) -> bool {
        self.objects.iter().any(|o| o.texture.is_colour())
    }

    /// The surface point nearest `p` (camera frame, mm) over every object: the object's index,
    /// the point in the object's frame (where its texture lives) and the distance (mm).
    /// `None` for an empty scene.
    pub(crate) fn nearest_surface(&self, p: &Point3<f64>) -> Option<(usize, Point3<f64>, f64)> {
        self.objects
            .iter()
            .enumerate()
            .filter_map(|(k, o)| {
                let local = o.nearest_surface(p)?;
                let d = (o.t_cam_object.transform_point(&local) - p).norm();
                d.is_finite().then_some((k, local, d))
            })
            .min_by(|a, b| a.2.total_cmp(&b.2))
    }

    /// Whether object `k` has a texture that varies over its surface.
    pub(crate) fn is_textured(&self, k: usize) -> bool {
        self.objects.get(k).is_some_and(|o| !o.texture.is_uniform())
    }

    /// `true` when something lies between the surface point `point` (with facing normal
    /// `normal`) and `target` — i.e. `point` is in the shadow of a light at `target`.
    pub fn occluded(
        &self,
        point: &Point3<f64>,
        normal: &Vector3<f64>,
        target: &Point3<f64>,
    ) -> bool {
        let start = point + normal * SHADOW_RAY_OFFSET_MM;
        let d = target - start;
        let dist = d.norm();
        if dist <= 0.0 {
            return false;
        }
        let ray = Ray::new(start, d / dist);
        self.objects.iter().any(|o| o.cast(&ray, dist).is_some())
    }
}

impl Placed {
    /// The point of the object's surface nearest `p` (camera frame, mm), in the object's
    /// frame: by parry's point projection onto the boundary (not the interior: a point inside
    /// a solid projects onto its surface), in closed form for rectangles (exactly on their
    /// `z = 0`, so that a texture's cells are read without rounding across that plane).
    fn nearest_surface(&self, p: &Point3<f64>) -> Option<Point3<f64>> {
        use parry3d_f64::query::PointQuery;
        let on_boundary = |proj: parry3d_f64::query::PointProjection| {
            Some(inverse_transform(&self.t_cam_object, &proj.point))
        };
        match &self.solid {
            Solid::Rectangle {
                x_min,
                y_min,
                x_max,
                y_max,
            } => {
                let local = inverse_transform(&self.t_cam_object, p);
                let q = Point3::new(
                    local.x.clamp(*x_min, *x_max),
                    local.y.clamp(*y_min, *y_max),
                    0.0,
                );
                Some(q)
            }
            Solid::Ball(s) => on_boundary(s.project_point(&self.t_cam_shape, p, false)),
            Solid::Cuboid(s) => on_boundary(s.project_point(&self.t_cam_shape, p, false)),
            Solid::Cylinder(s) => on_boundary(s.project_point(&self.t_cam_shape, p, false)),
            Solid::Mesh(s) => on_boundary(s.project_point(&self.t_cam_shape, p, false)),
        }
    }

    /// Distance and unit normal (camera frame, orientation as parry gives it) of the first hit.
    fn cast(&self, ray: &Ray, max: f64) -> Option<(f64, Vector3<f64>)> {
        match &self.solid {
            Solid::Rectangle {
                x_min,
                y_min,
                x_max,
                y_max,
            } => {
                // Camera rays all start at the camera centre (exactly the origin).
                let o = if ray.origin.coords.iter().all(|c| c.to_bits() == 0) {
                    self.camera_in_object
                } else {
                    inverse_transform(&self.t_cam_object, &ray.origin)
                };
                let d = inverse_rotate(&self.t_cam_object, &ray.dir);
                if d.z == 0.0 {
                    return None;
                }
                let t = -o.z / d.z;
                if !(t > 0.0 && t <= max) {
                    return None;
                }
                let x = o.x + t * d.x;
                let y = o.y + t * d.y;
                if x < *x_min || x > *x_max || y < *y_min || y > *y_max {
                    return None;
                }
                Some((t, self.z_cam))
            }
            Solid::Ball(s) => self.cast_shape(s, ray, max),
            Solid::Cuboid(s) => self.cast_shape(s, ray, max),
            Solid::Cylinder(s) => self.cast_shape(s, ray, max),
            Solid::Mesh(s) => self.cast_shape(s.as_ref(), ray, max),
        }
    }

    /// parry's `cast_ray_and_get_normal(&t_cam_shape, ray, max, true)` (the ray into the
    /// shape's frame, cast there, the normal back), with the transforms inlined.
    #[inline(always)]
    fn cast_shape<S: RayCast>(
        &self,
        shape: &S,
        ray: &Ray,
        max: f64,
    ) -> Option<(f64, Vector3<f64>)> {
        let m = &self.t_cam_shape;
        let local = Ray::new(
            inverse_transform(m, &ray.origin),
            inverse_rotate(m, &ray.dir),
        );
        let i = shape.cast_local_ray_and_get_normal(&local, max, true)?;
        hit(Some(parry3d_f64::query::RayIntersection {
            normal: rotate(m, &i.normal),
            ..i
        }))
    }
}

fn hit(i: Option<parry3d_f64::query::RayIntersection>) -> Option<(f64, Vector3<f64>)> {
    let i = i?;
    // A ray starting inside a solid reports a zero distance and a zero normal: not a surface.
    if i.time_of_impact <= 0.0 {
        return None;
    }
    let n = i.normal.try_normalize(0.0)?;
    Some((i.time_of_impact, n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{SceneObject, Texture};
    use approx::assert_relative_eq;

    fn sphere_scene(c: Vector3<f64>, r: f64) -> PlacedScene {
        let scene = Scene::new().with(SceneObject::in_camera(
            "s",
            Shape::Sphere { radius: r },
            Texture::Uniform(0.5),
            Isometry3::translation(c.x, c.y, c.z),
        ));
        PlacedScene::new(&scene, &Isometry3::identity())
    }

    /// The inlined transforms give nalgebra's results bit for bit (renders must not change
    /// with them): over rotations about many axes and points from millimetres to metres.
    #[test]
    fn inlined_transforms_are_nalgebras_bit_for_bit() {
        let bits = |v: &Vector3<f64>| v.map(f64::to_bits);
        for i in 0..500u32 {
            let f = f64::from(i);
            let axis = Vector3::new((f * 0.37).sin(), (f * 1.13).cos(), (f * 0.71).sin() + 0.1);
            let iso = Isometry3::from_parts(
                nalgebra::Translation3::new(f * 3.1 - 700.0, -f * 0.7, 450.0 + f.sqrt()),
                UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), f * 0.013),
            );
            let p = Point3::new(
                (f * 2.3).cos() * 1e3,
                f * 0.01 - 2.0,
                (f * 0.5).sin() * 1e-3,
            );
            assert_eq!(
                bits(&inverse_transform(&iso, &p).coords),
                bits(&iso.inverse_transform_point(&p).coords)
            );
            assert_eq!(
                bits(&inverse_rotate(&iso, &p.coords)),
                bits(&iso.inverse_transform_vector(&p.coords))
            );
            assert_eq!(
                bits(&rotate(&iso, &p.coords)),
                bits(&iso.transform_vector(&p.coords))
            );
        }
    }

    #[test]
    fn sphere_hit_matches_quadratic() {
        let c = Vector3::new(10.0, -5.0, 400.0);
        let r = 50.0;
        let s = sphere_scene(c, r);
        let dir = Vector3::new(0.05, -0.02, 1.0).normalize();
        let h = s.cast(&Point3::origin(), &dir, 1e6).unwrap();
        // |t d - c|^2 = r^2  ->  t = d.c - sqrt((d.c)^2 - |c|^2 + r^2)
        let b = dir.dot(&c);
        let t = b - (b * b - c.norm_squared() + r * r).sqrt();
        // parry solves the same quadratic in f64: agreement to a few ulps of 400 mm.
        assert_relative_eq!(h.distance, t, max_relative = 1e-12);
        assert_relative_eq!(h.normal, (h.point.coords - c) / r, epsilon = 1e-9);
        assert!(
            s.cast(&Point3::origin(), &Vector3::new(1.0, 0.0, 0.0), 1e6)
                .is_none()
        );
    }

    #[test]
    fn rectangle_and_shadow() {
        // A wall at z = 500 and a small occluding square at z = 300 facing the camera.
        let scene = Scene::new()
            .with(SceneObject::in_camera(
                "wall",
                Shape::rectangle(1000.0, 1000.0),
                Texture::Uniform(0.5),
                Isometry3::translation(0.0, 0.0, 500.0),
            ))
            .with(SceneObject::in_camera(
                "occluder",
                Shape::rectangle(20.0, 20.0),
                Texture::Uniform(0.5),
                Isometry3::translation(100.0, 0.0, 300.0),
            ));
        let s = PlacedScene::new(&scene, &Isometry3::identity());
        let h = s.cast(&Point3::origin(), &Vector3::z(), 1e6).unwrap();
        assert_eq!(h.object, 0);
        assert_relative_eq!(h.distance, 500.0);
        assert_relative_eq!(h.normal, -Vector3::z());
        // A light at (250, 0, 0): the line from (0,0,500) to it crosses z = 300 at x = 100.
        assert!(s.occluded(&h.point, &h.normal, &Point3::new(250.0, 0.0, 0.0)));
        assert!(!s.occluded(&h.point, &h.normal, &Point3::new(-250.0, 0.0, 0.0)));
    }

    #[test]
    fn cylinder_axis_is_z() {
        let scene = Scene::new().with(SceneObject::in_camera(
            "c",
            Shape::Cylinder {
                radius: 30.0,
                height: 100.0,
            },
            Texture::Uniform(0.5),
            Isometry3::translation(0.0, 0.0, 400.0),
        ));
        let s = PlacedScene::new(&scene, &Isometry3::identity());
        // The axis is the camera's z here: along the optical axis, the cap at z = 400 - 50.
        let h = s.cast(&Point3::origin(), &Vector3::z(), 1e6).unwrap();
        // parry casts rays on cylinders with its support-map (GJK) solver: ~1e-9 mm.
        assert_relative_eq!(h.distance, 350.0, epsilon = 1e-6);
        assert_relative_eq!(h.normal, -Vector3::z(), epsilon = 1e-6);
        // From the side (100 mm off the axis, in the middle), the wall at radius 30.
        let h = s
            .cast(&Point3::new(0.0, 100.0, 420.0), &-Vector3::y(), 1e6)
            .unwrap();
        assert_relative_eq!(h.distance, 70.0, epsilon = 1e-6);
        assert_relative_eq!(h.normal, Vector3::y(), epsilon = 1e-6);
        // Beyond the far cap (z = 450), nothing.
        assert!(
            s.cast(&Point3::new(0.0, 100.0, 455.0), &-Vector3::y(), 1e6)
                .is_none()
        );
    }
}
