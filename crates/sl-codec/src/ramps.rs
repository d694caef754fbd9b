//! Stair codes (a Gray code's stripes: one code over several camera pixels) turned into the
//! continuous code a matcher between two cameras needs: along each image row, a run of pixels
//! with exactly the same code between neighbours one stripe lower and one higher is a stripe
//! whose edges are the half-way codes, so the code across it is taken to rise linearly from one
//! edge to the other.

use crate::CorrespondenceMap;

/// Largest code step between neighbouring stripes that is taken for a stripe edge (projector
/// pixels): wider steps are depth jumps or decoding errors, left alone.
const MAX_STEP: f32 = 64.0;

/// Replaces, along every image row of `map.col`, each run of two or more pixels holding
/// exactly the same code `c` — between a neighbour run at `c − s` on one side and `c + s` on the
/// other (`s` the stripe's width in code: 1 for a per-pixel Gray code, the stripe width for a
/// striped one, at most 64) — by a linear ramp from `c − s/2` to `c + s/2` across the run
/// (pixel centres at `(k + ½) / n` of it). Codes that change at every pixel (a phase code's),
/// runs at the border or beside an undecoded pixel, and runs whose two neighbours do not step
/// alike are left as they are. Returns how many pixels changed.
///
/// ```
/// use sl_codec::{CorrespondenceMap, ramp_stair_codes};
/// let mut map = CorrespondenceMap::new(8, 1);
/// map.col.copy_from_slice(&[3.0, 4.0, 4.0, 5.0, 5.0, 5.0, 5.0, 6.0]);
/// assert_eq!(ramp_stair_codes(&mut map), 6);
/// assert_eq!(&map.col[1..3], &[3.75, 4.25]);
/// assert_eq!(&map.col[3..7], &[4.625, 4.875, 5.125, 5.375]);
/// ```
pub fn ramp_stair_codes(map: &mut CorrespondenceMap) -> usize {
    let w = map.width;
    if w == 0 {
        return 0;
    }
    let mut changed = 0;
    for row in map.col.chunks_mut(w) {
        changed += ramp_row(row);
    }
    changed
}

fn ramp_row(row: &mut [f32]) -> usize {
    // The runs of equal whole codes: (start, end exclusive, code).
    let mut runs: Vec<(usize, usize, f32)> = Vec::new();
    let mut x = 0;
    while x < row.len() {
        let c = row[x];
        let start = x;
        // NaN equals NaN here: an undecoded stretch is one run (and the loop always advances).
        let same = |v: f32| v == c || (v.is_nan() && c.is_nan());
        while x < row.len() && same(row[x]) {
            x += 1;
        }
        runs.push((start, x, c));
    }
    let mut changed = 0;
    for k in 1..runs.len().saturating_sub(1) {
        let (prev, (start, end, c), next) = (runs[k - 1], runs[k], runs[k + 1]);
        // A stripe spans several pixels of exactly the same code; a phase code changes at
        // every pixel and is left as it is.
        if end - start < 2 || !(c.is_finite() && prev.2.is_finite() && next.2.is_finite()) {
            continue;
        }
        // The stripe's width in code: the step to both neighbours, the same on each side (1
        // for a per-pixel code, the stripe width for a striped one).
        let step = next.2 - c;
        if !(step != 0.0 && c - prev.2 == step && step.abs() <= MAX_STEP) {
            continue;
        }
        let n = (end - start) as f32;
        for (i, v) in row[start..end].iter_mut().enumerate() {
            *v = c + step * ((i as f32 + 0.5) / n - 0.5);
        }
        changed += end - start;
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stripe pattern seen by a camera: the true code rises by 0.3 per pixel, the decoder
    /// gives the projector pixel it falls in (code `c` covers `[c − ½, c + ½)`, pixel centres
    /// at whole numbers); the ramps follow the truth within a third of a pixel inside the
    /// stripes, where the stairs were off by up to half a pixel everywhere.
    #[test]
    fn ramps_follow_the_true_code_across_stripes() {
        let w = 40;
        let truth: Vec<f32> = (0..w).map(|x| 10.0 + 0.3 * x as f32).collect();
        let mut map = CorrespondenceMap::new(w, 1);
        for (c, t) in map.col.iter_mut().zip(&truth) {
            *c = t.round();
        }
        let before = truth
            .iter()
            .zip(&map.col)
            .map(|(t, c)| (t - c).abs())
            .fold(0.0_f32, f32::max);
        let changed = ramp_stair_codes(&mut map);
        assert!(changed > 30, "{changed}");
        // The first and last stripes have no neighbour on one side and stay as they were.
        let inner: Vec<f32> = truth
            .iter()
            .zip(&map.col)
            .skip(4)
            .take(w - 8)
            .map(|(t, c)| (t - c).abs())
            .collect();
        let worst = inner.iter().copied().fold(0.0_f32, f32::max);
        let mean: f32 = inner.iter().sum::<f32>() / inner.len() as f32;
        assert!(before > 0.45, "{before}");
        assert!(worst < 0.35 && mean < 0.12, "worst {worst}, mean {mean}");
        // Decreasing codes ramp the other way; a phase code is left alone.
        let mut down = CorrespondenceMap::new(6, 1);
        down.col
            .copy_from_slice(&[7.0, 6.0, 6.0, 5.0, 5.2, f32::NAN]);
        ramp_stair_codes(&mut down);
        assert_eq!(&down.col[1..3], &[6.25, 5.75]);
        assert_eq!(down.col[4], 5.2);
    }
}
