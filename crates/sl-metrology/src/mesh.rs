//! Metrology of a triangle mesh: the figures of [`evaluate_with`](crate::evaluate_with) over
//! the mesh's vertices or over points spread evenly over its surface.

use sl_cloud::{PointCloud, TriangleMesh};

use crate::{EvaluateConfig, MetrologyError, Report, Truth, evaluate_with};

/// Which points of a mesh are measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MeshSampling {
    /// The vertices, as they are. Fast, and what a per-vertex error map shows; weighs finely
    /// meshed areas more than coarse ones.
    Vertices,
    /// Points spread over the triangles in proportion to area, one per `area_mm2`: every
    /// square millimetre of surface counts the same, and the flat inside of a large triangle is
    /// measured too.
    AreaWeighted {
        /// Surface area each sample stands for (mm²).
        area_mm2: f64,
    },
}

impl Default for MeshSampling {
    /// Area-weighted, one sample per 0.01 mm² (a tenth of a millimetre apart: finer than the
    /// triangles of a depth-9 reconstruction of the scanner's working volume).
    fn default() -> Self {
        Self::AreaWeighted { area_mm2: 0.01 }
    }
}

/// The points of `mesh` that [`evaluate_mesh`] measures.
///
/// # Errors
/// [`MetrologyError::InvalidParameter`] for an area that is not positive and finite, and
/// [`MetrologyError::Cloud`] for a triangle index out of range.
pub fn mesh_samples(
    mesh: &TriangleMesh,
    sampling: MeshSampling,
) -> Result<PointCloud, MetrologyError> {
    let n = mesh.vertices.len();
    if let Some(k) = mesh
        .triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(MetrologyError::InvalidParameter {
            parameter: "mesh",
            reason: format!("triangle {k} has a vertex index out of range ({n} vertices)"),
        });
    }
    Ok(match sampling {
        MeshSampling::Vertices => PointCloud::from_positions(mesh.vertices.clone()),
        MeshSampling::AreaWeighted { area_mm2 } => {
            if !(area_mm2.is_finite() && area_mm2 > 0.0) {
                return Err(MetrologyError::InvalidParameter {
                    parameter: "area_mm2",
                    reason: format!("{area_mm2} is not a positive area"),
                });
            }
            PointCloud::from_positions(sl_cloud::sample_surface(mesh, area_mm2, false))
        }
    })
}

/// Measures a mesh (mm) against `truth` as [`evaluate_with`] measures a cloud, over the points
/// `sampling` picks. The report's `points` and `signed_distances_mm` are those of the samples
/// (with [`MeshSampling::Vertices`], one per vertex: an error map of the mesh).
///
/// # Errors
/// Those of [`mesh_samples`] and [`evaluate_with`] (a feature with too few samples names the
/// feature).
///
/// ```
/// use nalgebra::Point3;
/// use sl_cloud::TriangleMesh;
/// use sl_metrology::{EvaluateConfig, Feature, MeshSampling, PlaneNominal, PlaneSpec, Truth, evaluate_mesh};
///
/// // A flat square of 20 mm at z = 100 mm, as two triangles.
/// let p = |x: f64, y: f64| Point3::new(x, y, 100.0);
/// let mesh = TriangleMesh {
///     vertices: vec![p(0.0, 0.0), p(20.0, 0.0), p(20.0, 20.0), p(0.0, 20.0)],
///     triangles: vec![[0, 1, 2], [0, 2, 3]],
/// };
/// let truth = Truth::new("a plate").with(Feature::Plane(PlaneSpec {
///     name: "plate".into(),
///     nominal: Some(PlaneNominal { normal: nalgebra::Vector3::z(), offset_mm: 100.0 }),
///     select_mm: 1.0,
/// }));
/// let r = evaluate_mesh(&mesh, &truth, MeshSampling::default(), &EvaluateConfig::default())?;
/// assert_eq!(r.points, 40_000);
/// assert!(r.planes[0].flatness_mm < 1e-9);
/// # Ok::<(), sl_metrology::MetrologyError>(())
/// ```
pub fn evaluate_mesh(
    mesh: &TriangleMesh,
    truth: &Truth,
    sampling: MeshSampling,
    cfg: &EvaluateConfig,
) -> Result<Report, MetrologyError> {
    evaluate_with(&mesh_samples(mesh, sampling)?, truth, cfg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Feature, SphereSpec};
    use nalgebra::{Point3, Vector3};
    use sl_mesh::{PoissonConfig, poisson_reconstruct};

    /// A closed mesh of a sphere of radius 25 at `centre` whose vertices lie exactly on the
    /// sphere (a Poisson mesh with its vertices pushed onto the sphere).
    fn ball(centre: Point3<f64>) -> TriangleMesh {
        let n = 6000;
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let (pts, nrm): (Vec<_>, Vec<_>) = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                let v = Vector3::new(r * t.cos(), r * t.sin(), z);
                (centre + v * 25.0, v)
            })
            .unzip();
        let cloud = PointCloud::from_positions(pts).with_normals(nrm).unwrap();
        let cfg = PoissonConfig {
            depth: 6,
            ..PoissonConfig::default()
        };
        let mut mesh = poisson_reconstruct(&cloud, &cfg).unwrap().mesh;
        for p in &mut mesh.vertices {
            *p = centre + (*p - centre).normalize() * 25.0;
        }
        mesh
    }

    fn truth(centre: Point3<f64>) -> Truth {
        Truth::new("one ball").with(Feature::Sphere(SphereSpec {
            name: "ball".into(),
            radius_mm: 25.0,
            centre_mm: Some(centre),
            select_mm: 2.0,
        }))
    }

    /// Vertices exactly on the sphere measure form and size 0. The triangles between them lie
    /// inside: area-weighted samples find the size too small by about twice the mean depth of
    /// a flat triangle below its circumscribed sphere (sagitta `s²/(8R)` at the centre, `s` the
    /// edge, a third of that on average over the triangle), and never by more than twice the
    /// largest sagitta.
    #[test]
    fn vertices_and_area_samples_of_a_sphere() {
        let centre = Point3::new(10.0, -5.0, 400.0);
        let mesh = ball(centre);
        let t = truth(centre);
        let cfg = EvaluateConfig::default();
        let r = evaluate_mesh(&mesh, &t, MeshSampling::Vertices, &cfg).unwrap();
        assert_eq!(r.points, mesh.vertices.len());
        let s = &r.spheres[0];
        assert!(
            s.probing_form_mm < 1e-9 && s.probing_size_mm.abs() < 1e-9,
            "{s:?}"
        );

        let r = evaluate_mesh(&mesh, &t, MeshSampling::default(), &cfg).unwrap();
        let area = sl_mesh::surface_area(&mesh);
        assert!(
            (r.points as f64 - area / 0.01).abs() <= 1.0,
            "{} samples",
            r.points
        );
        let s = &r.spheres[0];
        let longest = mesh
            .triangles
            .iter()
            .flat_map(|t| {
                let v = t.map(|i| mesh.vertices[i as usize]);
                [
                    (v[1] - v[0]).norm(),
                    (v[2] - v[1]).norm(),
                    (v[0] - v[2]).norm(),
                ]
            })
            .fold(0.0, f64::max);
        let sagitta = longest * longest / (8.0 * 25.0);
        assert!(s.probing_size_mm < 0.0, "{s:?}");
        assert!(
            s.probing_size_mm > -2.0 * sagitta,
            "{s:?}, sagitta {sagitta}"
        );
        assert!(r.rms_to_reference_mm < sagitta, "{}", r.rms_to_reference_mm);
    }

    #[test]
    fn bad_sampling_is_named() {
        let mesh = ball(Point3::origin());
        let e = mesh_samples(&mesh, MeshSampling::AreaWeighted { area_mm2: 0.0 })
            .unwrap_err()
            .to_string();
        assert!(e.contains("area_mm2"), "{e}");
        let broken = TriangleMesh {
            vertices: vec![Point3::origin()],
            triangles: vec![[0, 0, 5]],
        };
        assert!(mesh_samples(&broken, MeshSampling::Vertices).is_err());
        // An empty mesh has no points for the feature: the feature is named.
        let e = evaluate_mesh(
            &TriangleMesh::default(),
            &truth(Point3::origin()),
            MeshSampling::Vertices,
            &EvaluateConfig::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("ball"), "{e}");
    }
}
