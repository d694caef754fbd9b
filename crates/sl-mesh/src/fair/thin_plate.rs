//! The thin plate: `K_ff x_f = −K_fc x_c` with `K = L M⁻¹ L` (the bi-Laplacian of the
//! cotangent operator, Liepa 2003; Botsch & Kobbelt 2004) on the free vertices, the fixed ones
//! entering through the pull of the two rings around them; factored once by sparse Cholesky.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use nalgebra::Vector3;
use sl_cloud::TriangleMesh;

use super::cotangent::Operator;

/// `−K x_C` on the free rows: the pull of the fixed vertices (`K = L M⁻¹ L`).
pub(super) fn fixed_pull(
    op: &Operator,
    mesh: &TriangleMesh,
    free: &[bool],
    active_ids: &[usize],
    free_ids: &[usize],
) -> Vec<Vector3<f64>> {
    let nv = mesh.vertices.len();
    let mut fixed_part: Vec<Vector3<f64>> = vec![Vector3::zeros(); nv];
    for &v in active_ids {
        if !free[v] {
            fixed_part[v] = mesh.vertices[v].coords;
        }
    }
    let mut scratch = vec![Vector3::zeros(); nv];
    let mut out = vec![Vector3::zeros(); nv];
    op.apply(&fixed_part, active_ids, &mut scratch, &mut out);
    free_ids.iter().map(|&v| -out[v]).collect()
}

/// `K_ff`, the thin-plate operator `K = L M⁻¹ L` of an [`Operator`] on the free vertices,
/// factored by sparse Cholesky (faer): the fairing's systems are small but badly conditioned
/// (the bi-Laplacian's condition grows with the fourth power of a gap's width in vertices),
/// which conjugate gradients paid for in thousands of iterations (13 s for the 31,490 free
/// vertices of the Stanford bunny's three scans, and still short of 1e-10); the factor is
/// made once and serves every right-hand side.
pub(super) struct FreeSystem<'a> {
    op: &'a Operator,
    free_ids: &'a [usize],
    active_ids: &'a [usize],
    llt: Llt<usize, f64>,
}

impl<'a> FreeSystem<'a> {
    /// `None` if `K_ff` is not positive definite.
    pub(super) fn new(
        op: &'a Operator,
        free_ids: &'a [usize],
        active_ids: &'a [usize],
    ) -> Option<Self> {
        let mut pos = vec![usize::MAX; op.area.len()];
        for (i, &v) in free_ids.iter().enumerate() {
            pos[v] = i;
        }
        // K = Σ_k L_k·ᵀ L_k· / A_k over the rows k of L (symmetric): each row's free entries
        // pair up.
        let mut triplets = Vec::new();
        let mut row: Vec<(usize, f64)> = Vec::new();
        for &k in active_ids {
            if op.area[k] <= 0.0 {
                continue;
            }
            row.clear();
            if pos[k] != usize::MAX {
                row.push((pos[k], op.diagonal[k]));
            }
            for e in op.start[k]..op.start[k + 1] {
                let j = pos[op.ring[e] as usize];
                if j != usize::MAX {
                    row.push((j, -op.weight[e]));
                }
            }
            for &(i, a) in &row {
                for &(j, b) in &row {
                    triplets.push(Triplet::new(i, j, a * b / op.area[k]));
                }
            }
        }
        let n = free_ids.len();
        let k = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).ok()?;
        let llt = k.sp_cholesky(Side::Lower).ok()?;
        Some(Self {
            op,
            free_ids,
            active_ids,
            llt,
        })
    }

    /// The solution of `K_ff x = b` (three right-hand sides, one per coordinate).
    pub(super) fn solve(&self, b: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let mut m = Mat::<f64>::zeros(b.len(), 3);
        for (i, v) in b.iter().enumerate() {
            for c in 0..3 {
                m[(i, c)] = v[c];
            }
        }
        self.llt.solve_in_place(m.as_mut());
        (0..b.len())
            .map(|i| Vector3::new(m[(i, 0)], m[(i, 1)], m[(i, 2)]))
            .collect()
    }

    /// `|b − K_ff x| / |b|`, with `K` applied through the operator (not the factor).
    pub(super) fn relative_residual(&self, x: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
        let nv = self.op.area.len();
        let mut full = vec![Vector3::zeros(); nv];
        for (i, &v) in self.free_ids.iter().enumerate() {
            full[v] = x[i];
        }
        let mut scratch = vec![Vector3::zeros(); nv];
        let mut out = vec![Vector3::zeros(); nv];
        self.op
            .apply(&full, self.active_ids, &mut scratch, &mut out);
        let (mut r2, mut b2) = (0.0, 0.0);
        for (i, &v) in self.free_ids.iter().enumerate() {
            r2 += (b[i] - out[v]).norm_squared();
            b2 += b[i].norm_squared();
        }
        if b2 > 0.0 {
            (r2 / b2).sqrt()
        } else {
            r2.sqrt()
        }
    }
}
