//! Mean curvature of a mesh at a vertex from a quadric fitted to the vertices around it (the
//! curvature the fairing continues over a gap).

use nalgebra::{Matrix6, Point3, Vector3, Vector6};

/// A set of vertex ids for the ring walks: foldhash's fixed-seed hasher instead of the
/// standard library's `SipHash`, which took most of the time of a fit's walk (the fairing fits
/// some ten thousand quadrics on the default scan).
pub(crate) type IdSet<T> = std::collections::HashSet<T, foldhash::fast::FixedState>;

/// A map from vertex ids, with the hasher of [`IdSet`].
pub(crate) type IdMap<K, V> = std::collections::HashMap<K, V, foldhash::fast::FixedState>;

/// The quadric of [`fit_quadric`] in the frame (`a`, `b`, `n`) at `p` (the fitted vertex),
/// `c` its coefficients.
pub(crate) struct LocalQuadric {
    p: Point3<f64>,
    a: Vector3<f64>,
    b: Vector3<f64>,
    n: Vector3<f64>,
    c: Vector6<f64>,
    residual: f64,
}

impl LocalQuadric {
    /// The mean curvature at the fitted vertex, `H = (κ1 + κ2) / 2 = −2 c5`: positive where the
    /// surface bends away from its normal (`1/r` on a sphere with outward normals).
    pub(crate) fn mean_curvature(&self) -> Option<f64> {
        let mean = -2.0 * self.c[5];
        mean.is_finite().then_some(mean)
    }

    /// The weighted RMS of the fitted vertices' residuals (their heights above the fitted
    /// surface, to first order): about the surface's own roughness where a quadric describes
    /// it, much more across a crease or a bend it does not follow.
    pub(crate) fn residual(&self) -> f64 {
        self.residual
    }

    /// The point of the fitted surface above or below `q` along the frame's normal, if the
    /// surface reaches it.
    pub(crate) fn project(&self, q: &Point3<f64>) -> Option<Point3<f64>> {
        let d = q - self.p;
        let (x, y) = (d.dot(&self.a), d.dot(&self.b));
        let c = &self.c;
        let g = c[0]
            + c[1] * x
            + c[2] * y
            + c[3] * (x * x - y * y)
            + c[4] * x * y
            + c[5] * (x * x + y * y);
        // c5 z² − z + g = 0, the root nearest g.
        let z = if (c[5] * g).abs() < 1e-12 {
            g
        } else {
            let disc = 1.0 - 4.0 * c[5] * g;
            if disc < 0.0 {
                return None;
            }
            2.0 * g / (1.0 + disc.sqrt())
        };
        let out = self.p + self.a * x + self.b * y + self.n * z;
        out.coords.iter().all(|v| v.is_finite()).then_some(out)
    }
}

/// Fits `z = c0 + c1 x + c2 y + c3 (x² − y²) + c4 xy + c5 (x² + y² + z²)` by weighted least
/// squares, in the frame of `normal` at vertex `v`, to the vertices within `radius` of it that
/// are reached through the mesh (`ring`) and have a positive `weight`; `None` with fewer than
/// `min_vertices` of them, a singular fit or a zero normal. The fit's residual is
/// [`LocalQuadric::residual`].
///
/// The isotropic term takes `z²` too, which makes the fit exact on a sphere at any radius (a
/// point `d` from a sphere's point has `d·n = −|d|² / 2r`), where a height-field quadric reads
/// a curvature too low once the radius is a fair part of `r`; the linear terms take up an
/// error of the normal. The mean curvature is [`LocalQuadric::mean_curvature`]; the
/// fitted surface can be evaluated elsewhere ([`LocalQuadric::project`]).
pub(crate) fn fit_quadric<'a>(
    positions: &[Point3<f64>],
    ring: &dyn Fn(usize) -> &'a [u32],
    weight: &dyn Fn(usize) -> f64,
    v: usize,
    normal: Vector3<f64>,
    radius: f64,
    min_vertices: usize,
) -> Option<LocalQuadric> {
    let n = normal.try_normalize(0.0)?;
    let p = positions[v];
    let helper = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let a = n.cross(&helper).normalize();
    let b = n.cross(&a);
    let mut normal_matrix = Matrix6::<f64>::zeros();
    let mut rhs = Vector6::<f64>::zeros();
    let (mut count, mut weights, mut squares) = (0usize, 0.0, 0.0);
    let mut seen: IdSet<u32> = IdSet::default();
    seen.insert(v as u32);
    let mut stack = vec![v as u32];
    let r2 = radius * radius;
    while let Some(i) = stack.pop() {
        let d = positions[i as usize] - p;
        let w = weight(i as usize);
        if w > 0.0 {
            let (x, y, z) = (d.dot(&a), d.dot(&b), d.dot(&n));
            let row = Vector6::new(1.0, x, y, x * x - y * y, x * y, d.norm_squared());
            normal_matrix += row * row.transpose() * w;
            rhs += row * (z * w);
            count += 1;
            weights += w;
            squares += w * z * z;
        }
        for &j in ring(i as usize) {
            if (positions[j as usize] - p).norm_squared() <= r2 && seen.insert(j) {
                stack.push(j);
            }
        }
    }
    if count < min_vertices {
        return None;
    }
    let c = normal_matrix.cholesky()?.solve(&rhs);
    // `Σ w (row·c − z)² = Σ w z² − c·rhs` at the least-squares solution.
    let residual = ((squares - c.dot(&rhs)).max(0.0) / weights).sqrt();
    Some(LocalQuadric {
        p,
        a,
        b,
        n,
        c,
        residual,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fan of points on a cylinder of radius 4 around the x axis (vertex at the top, normal
    /// +z) out to 1.5 (the fairing fits over four edges, a fifth of the default scan's
    /// spheres): mean curvature 1/8 within 2 % (the quartic terms of the cylinder); on a
    /// sphere of radius 4, 1/4 to round-off, also out to 3 (three quarters of its radius).
    #[test]
    fn cylinder_and_sphere_are_read_exactly() {
        let r = 4.0;
        let mut cyl = vec![Point3::new(0.0, 0.0, r)];
        let mut sph = vec![Point3::new(0.0, 0.0, r)];
        for i in 0..12 {
            for k in 1..=6 {
                let phi = i as f64 * std::f64::consts::PI / 6.0;
                let rho = 0.5 * k as f64;
                let (x, y) = (rho * phi.cos(), rho * phi.sin());
                cyl.push(Point3::new(x, y, (r * r - y * y).sqrt()));
                sph.push(Point3::new(x, y, (r * r - x * x - y * y).sqrt()));
            }
        }
        let all: Vec<u32> = (0..cyl.len() as u32).collect();
        let ring = |_: usize| all.as_slice();
        let one = |_: usize| 1.0;
        let c = fit_quadric(&cyl, &ring, &one, 0, Vector3::z(), 1.6, 12)
            .and_then(|q| q.mean_curvature())
            .unwrap();
        assert!((c - 0.125).abs() < 0.0025, "{c}");
        let q = fit_quadric(&sph, &ring, &one, 0, Vector3::z(), 3.5, 12).unwrap();
        let s = q.mean_curvature().unwrap();
        assert!((s - 0.25).abs() < 1e-9, "{s}");
        assert!(q.residual() < 1e-9, "{}", q.residual());
        // The fitted sphere, whole: a point off it is put back on it along the frame's
        // normal, also beyond the fitted points (4.5 from the top of a sphere of radius 4
        // fitted out to 3 is past its side: no point; 3.8 is on it).
        let on = q.project(&Point3::new(3.2, 1.0, 5.0)).unwrap();
        assert!((on.coords.norm() - r).abs() < 1e-9, "{on}");
        assert!((on.x - 3.2).abs() < 1e-12 && (on.y - 1.0).abs() < 1e-12 && on.z > 0.0);
        assert!(q.project(&Point3::new(4.5, 0.0, 0.0)).is_none());
        // A roof (two planes meeting at 30° each side of the top) is no quadric: its residual
        // is a fair part of the heights fitted, where a cylinder's is its quartic terms'.
        let roof: Vec<Point3<f64>> = sph
            .iter()
            .map(|p| Point3::new(p.x, p.y, -0.577 * p.x.abs()))
            .collect();
        let roofed = fit_quadric(&roof, &ring, &one, 0, Vector3::z(), 3.5, 12).unwrap();
        let cylinder = fit_quadric(&cyl, &ring, &one, 0, Vector3::z(), 1.6, 12).unwrap();
        eprintln!(
            "residuals: roof {} cylinder {}",
            roofed.residual(),
            cylinder.residual()
        );
        assert!(roofed.residual() > 0.05, "{}", roofed.residual());
        assert!(cylinder.residual() < 1e-3, "{}", cylinder.residual());
        // Too few vertices, or none weighing: no fit.
        assert!(fit_quadric(&sph, &ring, &one, 0, Vector3::z(), 3.5, 1000).is_none());
        assert!(fit_quadric(&sph, &ring, &|_| 0.0, 0, Vector3::z(), 3.5, 6).is_none());
    }
}
