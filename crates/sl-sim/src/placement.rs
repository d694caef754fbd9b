//! An object one turntable placement cannot cover, re-placing it, and its true surface.
//!
//! A turntable scan never sees the underside of what stands on the platter: the camera and the
//! projector look down at it ([`DEFAULT_TILT_DEG`](crate::DEFAULT_TILT_DEG)). The
//! [`Scene::pebble`] has a flat bottom a fifth of its surface wide; [`Scene::replaced`] lays it
//! on its side (as a user does between two placements) and [`Scene::surface_mesh`] gives its
//! true surface in the camera frame, for coverage and distance figures (`sl-metrology`).

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use sl_cloud::TriangleMesh;

use crate::{DEFAULT_ALBEDO, Mount, Scene, SceneObject, Shape, SimError, Texture};

/// Mean radius of [`Scene::pebble`] (mm).
pub const PEBBLE_RADIUS_MM: f64 = 40.0;

/// Depth of the pebble's flat bottom below its centre (mm): a cut at 0.55 radius leaves a
/// bottom about 33 mm across, 15.5 % of the surface, that a single placement never sees.
pub const PEBBLE_CUT_MM: f64 = 22.0;

/// Latitude rings and longitude segments of the pebble's mesh: triangles about 2 mm across
/// (finer than its bumps, coarser than the camera's 0.31 mm pixels so its facets stay a
/// model's, not noise).
const PEBBLE_RINGS: usize = 64;
const PEBBLE_SEGMENTS: usize = 128;

/// The pebble's radius in direction `d` (unit): a sphere with smooth, low bumps that break
/// every symmetry (so that a second placement can be registered onto the first without pose
/// hints), cut flat at `z = -`[`PEBBLE_CUT_MM`].
fn pebble_radius(d: &Vector3<f64>) -> f64 {
    let bumps = 0.10 * (3.0 * d.x + 0.7).sin() * (2.0 * d.y - 0.3).cos()
        + 0.07 * (4.0 * d.z * d.x + 1.1).cos()
        + 0.08 * d.x * d.y
        + 0.06 * (2.5 * d.y + 1.3 * d.z).sin();
    let r = PEBBLE_RADIUS_MM * (1.0 + bumps);
    if d.z < 0.0 {
        r.min(PEBBLE_CUT_MM / -d.z)
    } else {
        r
    }
}

/// The pebble's mesh in its own frame (mm, centre at the origin, `z` up, flat bottom at
/// `z = -`[`PEBBLE_CUT_MM`]): a latitude–longitude grid over the unit sphere, each vertex at
/// the pebble's bumpy radius (star-shaped from the centre, so it never intersects itself), triangles
/// wound counter-clockwise seen from outside.
pub fn pebble_mesh() -> TriangleMesh {
    let (rings, segs) = (PEBBLE_RINGS, PEBBLE_SEGMENTS);
    let vertex = |d: Vector3<f64>| Point3::from(d * pebble_radius(&d));
    let mut vertices = vec![vertex(Vector3::z())];
    for i in 1..rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segs {
            let phi = std::f64::consts::TAU * j as f64 / segs as f64;
            vertices.push(vertex(Vector3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            )));
        }
    }
    vertices.push(vertex(-Vector3::z()));
    let south = (vertices.len() - 1) as u32;
    let at = |i: usize, j: usize| (1 + (i - 1) * segs + j % segs) as u32;
    let mut triangles = Vec::with_capacity(2 * rings * segs);
    for j in 0..segs {
        triangles.push([0, at(1, j), at(1, j + 1)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segs {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
            triangles.push([a, c, d]);
            triangles.push([a, d, b]);
        }
    }
    for j in 0..segs {
        triangles.push([south, at(rings - 1, j + 1), at(rings - 1, j)]);
    }
    TriangleMesh {
        vertices,
        triangles,
    }
}

/// The vertices of a mesh shape in its own frame.
fn mesh_vertices(shape: &Shape) -> Option<&[Point3<f64>]> {
    match shape {
        Shape::Mesh(m) => Some(m.vertices()),
        _ => None,
    }
}

impl Scene {
    /// The pebble ([`pebble_mesh`]) standing on its flat bottom on the turntable, centred on
    /// the axis, with a uniform [`DEFAULT_ALBEDO`]: an object with a top and a bottom, which
    /// one turntable placement cannot cover.
    pub fn pebble() -> Result<Self, SimError> {
        let m = pebble_mesh();
        Self::standing_mesh(
            "pebble",
            &m.vertices,
            m.triangles,
            1.0,
            Vector3::z(),
            Texture::Uniform(DEFAULT_ALBEDO),
        )
    }

    /// The scene with every object on the turntable re-placed as a user re-places an object
    /// between two turntable sessions: turned by `rotation` (in the table frame, e.g. 90°
    /// about `x` to lay it on its side), then moved so that its lowest point rests on the
    /// platter and its bounding box is centred on the axis. Objects fixed to the camera stay.
    ///
    /// # Errors
    /// [`SimError::InvalidScene`] naming an object on the turntable that is not a triangle
    /// mesh (only a mesh's lowest point is computed here).
    pub fn replaced(&self, rotation: UnitQuaternion<f64>) -> Result<Self, SimError> {
        let mut out = self.clone();
        for o in &mut out.objects {
            if o.mount != Mount::Turntable {
                continue;
            }
            let Some(vertices) = mesh_vertices(&o.shape) else {
                return Err(SimError::scene(
                    &o.name,
                    "only triangle-mesh objects can be re-placed on the turntable",
                ));
            };
            let turned = Isometry3::from_parts(Translation3::identity(), rotation) * o.pose;
            let mut lo = Vector3::repeat(f64::INFINITY);
            let mut hi = Vector3::repeat(f64::NEG_INFINITY);
            for v in vertices {
                let p = turned * v;
                lo = lo.inf(&p.coords);
                hi = hi.sup(&p.coords);
            }
            let shift = Vector3::new(-(lo.x + hi.x) / 2.0, -(lo.y + hi.y) / 2.0, -lo.z);
            o.pose = Translation3::from(shift) * turned;
        }
        Ok(out)
    }

    /// [`replaced`](Self::replaced) with a quarter turn about the table's `x` axis: the object
    /// laid on its side, its former bottom facing the camera's side of the platter.
    pub fn laid_on_side(&self) -> Result<Self, SimError> {
        self.replaced(UnitQuaternion::from_axis_angle(
            &Vector3::x_axis(),
            std::f64::consts::FRAC_PI_2,
        ))
    }

    /// The true surface of the scene in the camera frame (mm), with the turntable at
    /// `t_cam_table`: every object's mesh moved by its pose (objects on the turntable through
    /// `t_cam_table`), in one triangle mesh.
    ///
    /// # Errors
    /// [`SimError::InvalidScene`] naming an object that is not a triangle mesh.
    pub fn surface_mesh(&self, t_cam_table: &Isometry3<f64>) -> Result<TriangleMesh, SimError> {
        let mut out = TriangleMesh::default();
        for o in &self.objects {
            let Shape::Mesh(m) = &o.shape else {
                return Err(SimError::scene(
                    &o.name,
                    "only triangle-mesh objects have a surface mesh here",
                ));
            };
            let pose = match o.mount {
                Mount::Turntable => t_cam_table * o.pose,
                Mount::Camera => o.pose,
            };
            let base = u32::try_from(out.vertices.len())
                .map_err(|_| SimError::scene(&o.name, "more than 2^32 vertices"))?;
            out.vertices.extend(m.vertices().iter().map(|v| pose * v));
            out.triangles
                .extend(m.indices().iter().map(|t| t.map(|i| i + base)));
        }
        Ok(out)
    }
}

/// The pebble as a scene object at `T_table_object` (for scenes built by hand).
pub fn pebble_object(t_table_object: Isometry3<f64>) -> Result<SceneObject, SimError> {
    let m = pebble_mesh();
    Ok(SceneObject::on_table(
        "pebble",
        Shape::mesh("pebble", m.vertices, m.triangles)?,
        Texture::Uniform(DEFAULT_ALBEDO),
        t_table_object,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(m: &TriangleMesh) -> f64 {
        m.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.vertices[i as usize]);
                (b - a).cross(&(c - a)).norm() / 2.0
            })
            .sum()
    }

    /// The pebble is closed and wound outward (its signed volume is positive and close to
    /// a cut sphere's), its flat bottom is a fifth of its area or less but well over the 1 %
    /// a two-placement scan may miss.
    #[test]
    fn the_pebble_is_closed_outward_with_a_flat_bottom() {
        let m = pebble_mesh();
        let volume: f64 = m
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.vertices[i as usize].coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum();
        let r = PEBBLE_RADIUS_MM;
        // The sphere of radius r cut at depth h: 4/3 π r³ less the cap of height r − h.
        let cap = r - PEBBLE_CUT_MM;
        let cut_sphere = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3)
            - std::f64::consts::PI * cap * cap * (3.0 * r - cap) / 3.0;
        assert!(
            volume > 0.8 * cut_sphere && volume < 1.2 * cut_sphere,
            "{volume} vs {cut_sphere}"
        );
        let total = area(&m);
        let bottom = area(&TriangleMesh {
            vertices: m.vertices.clone(),
            triangles: m
                .triangles
                .iter()
                .copied()
                .filter(|t| {
                    t.iter()
                        .all(|&i| (m.vertices[i as usize].z + PEBBLE_CUT_MM).abs() < 1e-9)
                })
                .collect(),
        });
        assert!(
            bottom > 0.1 * total && bottom < 0.25 * total,
            "{bottom} of {total}"
        );
    }

    /// Laid on its side, the pebble still rests on the platter, centred on the axis, and its
    /// flat bottom is now vertical (its normal was −z, now ±y of the table).
    #[test]
    fn laid_on_side_rests_on_the_platter() {
        let scene = Scene::pebble().unwrap();
        let side = scene.laid_on_side().unwrap();
        for s in [&scene, &side] {
            let m = s.surface_mesh(&Isometry3::identity()).unwrap();
            let lo = m.vertices.iter().map(|v| v.z).fold(f64::INFINITY, f64::min);
            assert!(lo.abs() < 1e-9, "{lo}");
            let (xl, xh) = m
                .vertices
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| {
                    (a.0.min(v.x), a.1.max(v.x))
                });
            assert!((xl + xh).abs() < 1e-9);
        }
        let pose = side.objects[0].pose * scene.objects[0].pose.inverse();
        let down = pose.rotation * -Vector3::z();
        assert!(
            down.z.abs() < 1e-12 && (down.y.abs() - 1.0).abs() < 1e-12,
            "{down}"
        );
        assert!(Scene::dumbbell().laid_on_side().is_err());
    }
}
