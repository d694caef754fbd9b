//! Trimmed ICP (Chetverikov et al. 2002): the squared-distance threshold that keeps the best
//! fraction of the correspondences, fixed or estimated by the overlap criterion of their `TrICP`.

use crate::Trimming;

/// `TrICP`'s λ in the objective `e(ξ) / ξ^(1+λ)`; the paper uses 2 ("λ = 2 gave good results in
/// all our tests").
const TRICP_LAMBDA: f64 = 2.0;

/// The largest squared distance kept, given the squared distances of the current
/// correspondences (`d2`, reordered in place) and the number of source points `n_source`.
/// `f64::INFINITY` keeps everything.
pub(crate) fn threshold(trimming: &Trimming, d2: &mut [f64], n_source: usize) -> f64 {
    if d2.is_empty() {
        return f64::INFINITY;
    }
    match *trimming {
        Trimming::None => f64::INFINITY,
        Trimming::Fixed { overlap } => {
            let keep = ((overlap * n_source as f64).ceil() as usize).max(1);
            if keep >= d2.len() {
                return f64::INFINITY;
            }
            let (_, nth, _) = d2.select_nth_unstable_by(keep - 1, f64::total_cmp);
            *nth
        }
        Trimming::Auto { min_overlap } => {
            d2.sort_unstable_by(f64::total_cmp);
            let n = n_source.max(d2.len()) as f64;
            let first = ((min_overlap * n).ceil() as usize).clamp(1, d2.len());
            let mut sum: f64 = d2.iter().take(first - 1).sum();
            let mut best = (f64::INFINITY, d2.len());
            for (m, v) in d2.iter().enumerate().skip(first - 1) {
                sum += v;
                let kept = (m + 1) as f64;
                let xi = kept / n;
                let psi = (sum / kept) / xi.powf(1.0 + TRICP_LAMBDA);
                if psi <= best.0 {
                    best = (psi, m + 1);
                }
            }
            d2.get(best.1 - 1).copied().unwrap_or(f64::INFINITY)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_keeps_the_closest_fraction() {
        let mut d2: Vec<f64> = (0..100).rev().map(f64::from).collect();
        // 30 % of 100 source points: the 30 smallest, 0..=29.
        assert_eq!(
            threshold(&Trimming::Fixed { overlap: 0.3 }, &mut d2, 100),
            29.0
        );
        // More than available: keep all.
        assert_eq!(
            threshold(&Trimming::Fixed { overlap: 0.9 }, &mut d2[..50], 100),
            f64::INFINITY
        );
        assert_eq!(threshold(&Trimming::None, &mut d2, 100), f64::INFINITY);
        assert_eq!(
            threshold(&Trimming::Fixed { overlap: 0.5 }, &mut [], 10),
            f64::INFINITY
        );
    }

    #[test]
    fn auto_finds_the_true_overlap() {
        // 700 inliers with squared distances ~0.01 and 300 outliers at 25..100: the objective
        // e(ξ)/ξ³ is smallest once all inliers are in and before the first outlier.
        let mut d2: Vec<f64> = (0..700)
            .map(|i| 0.01 * (1.0 + (i % 7) as f64 / 7.0))
            .collect();
        d2.extend((0..300).map(|i| 25.0 + 0.25 * i as f64));
        let t = threshold(&Trimming::Auto { min_overlap: 0.2 }, &mut d2, 1000);
        assert!(t < 0.02, "threshold {t} should keep exactly the inliers");
        assert_eq!(d2.iter().filter(|&&v| v <= t).count(), 700);
    }
}
