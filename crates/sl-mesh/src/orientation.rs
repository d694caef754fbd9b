//! A check of the normals' orientation before a reconstruction: screened Poisson takes each
//! normal's sign for the side the object is on, and a cloud whose normals were estimated but
//! never oriented gives a wrong surface (a membrane joining the patches whose normals face in)
//! without any other sign of trouble.

use nalgebra::Point3;
use rayon::prelude::*;
use sl_cloud::{KdIndex, PointCloud};

use crate::MeshError;
use crate::topology::UnionFind;

/// Two neighbours' normals whose angle is below this cosine (120°) disagree in sign: on a
/// smooth surface a flipped neighbour is near 180°, while the two faces of a sharp edge of a
/// correctly oriented surface stay within 90° of each other (a cube's edge) unless the edge is
/// a blade sharper than 60°.
const AGREE_COSINE: f64 = -0.5;

/// How consistently the normals of `cloud` are oriented: the fraction of the points looked at
/// (every `stride`-th with a finite position and a non-zero normal) that lie outside the
/// largest consistently oriented patch of their piece of the cloud. Pieces and patches come
/// from each point's `k` nearest neighbours among those points: neighbours join a piece, and a
/// patch when their normals agree (less than 120° apart).
///
/// Normals that face out of the object, as a merged scan's do, make one patch of every piece:
/// nearly 0 (isolated noisy normals make tiny patches). Normals whose signs were never chosen
/// split into patches that face in and out: PCA normals of the default scan's cloud as Open3D's
/// `estimate_normals` leaves them unoriented give 0.46 (docs/meshing.md), random signs more.
/// Only a surface thinner than the neighbourhood whose edge was not scanned (a sheet seen from
/// both sides) can make an oriented cloud look inconsistent.
///
/// `None` when the cloud has no normals or at most `k` points are looked at.
///
/// ```
/// use nalgebra::{Point3, Vector3};
/// use sl_cloud::PointCloud;
/// use sl_mesh::inconsistent_normal_fraction;
/// let pts: Vec<_> = (0..400).map(|i| Point3::new((i % 20) as f64, (i / 20) as f64, 0.0)).collect();
/// let up = PointCloud::from_positions(pts.clone()).with_normals(vec![Vector3::z(); 400])?;
/// assert_eq!(inconsistent_normal_fraction(&up, 8, 1)?, Some(0.0));
/// // The left half faces down: two patches of 200 points, the smaller outside the largest.
/// let n: Vec<_> = pts.iter().map(|p| if p.x < 10.0 { -Vector3::z() } else { Vector3::z() }).collect();
/// let split = PointCloud::from_positions(pts).with_normals(n)?;
/// assert_eq!(inconsistent_normal_fraction(&split, 8, 1)?, Some(0.5));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`MeshError::InvalidParameter`] when `k` or `stride` is 0.
pub fn inconsistent_normal_fraction(
    cloud: &PointCloud,
    k: usize,
    stride: usize,
) -> Result<Option<f64>, MeshError> {
    if k == 0 {
        return Err(MeshError::invalid("k", k, "needs at least one neighbour"));
    }
    if stride == 0 {
        return Err(MeshError::invalid("stride", stride, "must be at least 1"));
    }
    let Some(normals) = cloud.normals() else {
        return Ok(None);
    };
    let (pts, nrm): (Vec<Point3<f64>>, Vec<_>) = cloud
        .positions()
        .iter()
        .zip(normals)
        .step_by(stride)
        .filter(|(p, n)| {
            p.iter().all(|c| c.is_finite())
                && n.iter().all(|c| c.is_finite())
                && n.norm_squared() > 0.0
        })
        .map(|(p, n)| (*p, n.normalize()))
        .unzip();
    if pts.len() <= k {
        return Ok(None);
    }
    let index = KdIndex::new(&pts)?;
    // Each point's neighbours (k + 1: the point itself is its own nearest), in parallel; the
    // unions after, in order, so the result does not depend on the threads.
    let neighbours: Vec<Vec<u32>> = (0..pts.len())
        .into_par_iter()
        .map_init(Vec::new, |found, i| {
            index.knn_into(&pts[i], k + 1, found);
            found
                .iter()
                .filter(|f| f.index != i)
                .map(|f| f.index as u32)
                .collect()
        })
        .collect();
    let n = pts.len();
    let (mut pieces, mut patches) = (UnionFind::new(n), UnionFind::new(n));
    for (i, near) in neighbours.iter().enumerate() {
        for &j in near {
            pieces.union(i as u32, j);
            if nrm[i].dot(&nrm[j as usize]) > AGREE_COSINE {
                patches.union(i as u32, j);
            }
        }
    }
    let mut patch_size = vec![0usize; n];
    for i in 0..n {
        patch_size[patches.find(i as u32) as usize] += 1;
    }
    // Only a patch's root has a size: each patch counts once, for its piece.
    let mut largest = vec![0usize; n];
    for (root, &size) in patch_size.iter().enumerate() {
        if size > 0 {
            let piece = pieces.find(root as u32) as usize;
            largest[piece] = largest[piece].max(size);
        }
    }
    let consistent: usize = largest.iter().sum();
    Ok(Some((n - consistent) as f64 / n as f64))
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};
    use sl_cloud::PointCloud;

    use super::*;

    /// The test sphere (radius 10 mm, Fibonacci spiral, outward normals): positions and
    /// normals.
    fn sphere(n: usize) -> (Vec<Point3<f64>>, Vec<Vector3<f64>>) {
        let c = crate::test_shapes::sphere_cloud(n, 10.0, Point3::origin());
        let normals = c.normals().map(<[_]>::to_vec).unwrap_or_default();
        (c.positions().to_vec(), normals)
    }

    /// Outward normals: one patch. The upper cap flipped (as unoriented PCA normals flip in
    /// patches): the cap's share. A cube's faces, normals 90° apart across its edges: one
    /// patch. Normals of random sign: most points outside the largest patch.
    #[test]
    fn patches_of_flipped_normals_are_counted() {
        let (p, n) = sphere(4000);
        let out = PointCloud::from_positions(p.clone())
            .with_normals(n.clone())
            .unwrap();
        assert_eq!(inconsistent_normal_fraction(&out, 8, 1).unwrap(), Some(0.0));
        let capped: Vec<_> = p
            .iter()
            .zip(&n)
            .map(|(q, m)| if q.z > 5.0 { -m } else { *m })
            .collect();
        let cap = PointCloud::from_positions(p.clone())
            .with_normals(capped)
            .unwrap();
        let f = inconsistent_normal_fraction(&cap, 8, 1).unwrap().unwrap();
        // The cap above z = 5 of a sphere of radius 10 is a quarter of its area.
        assert!((f - 0.25).abs() < 0.01, "{f}");
        // Every second point looked at: the same answer.
        let f2 = inconsistent_normal_fraction(&cap, 8, 2).unwrap().unwrap();
        assert!((f2 - 0.25).abs() < 0.02, "{f2}");

        let mut cube = (Vec::new(), Vec::new());
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                for a in 0..20 {
                    for b in 0..20 {
                        let (u, v) = (f64::from(a) + 0.5, f64::from(b) + 0.5);
                        let mut q = [0.0; 3];
                        q[axis] = if sign > 0.0 { 20.0 } else { 0.0 };
                        q[(axis + 1) % 3] = u;
                        q[(axis + 2) % 3] = v;
                        let mut m = Vector3::zeros();
                        m[axis] = sign;
                        cube.0.push(Point3::from(q));
                        cube.1.push(m);
                    }
                }
            }
        }
        let cube = PointCloud::from_positions(cube.0)
            .with_normals(cube.1)
            .unwrap();
        assert_eq!(
            inconsistent_normal_fraction(&cube, 8, 1).unwrap(),
            Some(0.0)
        );

        // Random signs (a fixed pseudo-random sequence).
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let random: Vec<_> = n
            .iter()
            .map(|m| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                if state & 1 == 0 { *m } else { -m }
            })
            .collect();
        let random = PointCloud::from_positions(p).with_normals(random).unwrap();
        let f = inconsistent_normal_fraction(&random, 8, 1)
            .unwrap()
            .unwrap();
        assert!(f > 0.3, "{f}");
    }

    #[test]
    fn without_normals_or_points_there_is_no_answer() {
        let (p, _) = sphere(100);
        let bare = PointCloud::from_positions(p.clone());
        assert_eq!(inconsistent_normal_fraction(&bare, 8, 1).unwrap(), None);
        let few = PointCloud::from_positions(p[..5].to_vec())
            .with_normals(vec![Vector3::z(); 5])
            .unwrap();
        assert_eq!(inconsistent_normal_fraction(&few, 8, 1).unwrap(), None);
        let err = inconsistent_normal_fraction(&few, 0, 1).unwrap_err();
        assert!(err.to_string().contains('k'), "{err}");
        let err = inconsistent_normal_fraction(&few, 8, 0).unwrap_err();
        assert!(err.to_string().contains("stride"), "{err}");
    }
}
