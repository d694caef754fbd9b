//! Multi-frequency hierarchical unwrapping.
//!
//! The coarsest frequency has at most one period across the projector, so its wrapped phase is
//! already an absolute position; each finer frequency, in increasing order, is unwrapped against
//! the position predicted by the previous one. A step is safe while the previous position error
//! times the ratio of the two period counts stays below half a period.

use super::{UnwrapScratch, absolute, stage};

/// The plan: frequency indices in increasing order of period count.
#[derive(Clone, Debug)]
pub(crate) struct Hierarchical {
    order: Vec<usize>,
    periods: Vec<f32>,
}

impl Hierarchical {
    /// `periods` are validated by the spec: at least two, the smallest at most 1.
    pub(crate) fn new(periods: &[f64]) -> Self {
        let mut order: Vec<usize> = (0..periods.len()).collect();
        order.sort_by(|&a, &b| periods[a].total_cmp(&periods[b]));
        Self {
            order,
            periods: periods.iter().map(|&p| p as f32).collect(),
        }
    }

    /// Writes the coarse-to-fine position of each pixel into `s.t`.
    #[inline(always)]
    pub(crate) fn coarse_row(&self, fracs: &[Vec<f32>], s: &mut UnwrapScratch) {
        let mut steps = self
            .order
            .iter()
            .filter_map(|&i| Some((fracs.get(i)?, *self.periods.get(i)?)));
        let Some((f0, p0)) = steps.next() else {
            return;
        };
        for (t, &f) in s.t.iter_mut().zip(f0.iter()) {
            *t = absolute(f, p0);
        }
        for (f, p) in steps {
            stage(&mut s.t, &mut s.resid, f, p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::Unwrap;
    use super::super::tests::check_plan;

    #[test]
    fn recovers_positions_with_noise() {
        // Ratios of 8: a step tolerates 0.5 / 8 = 0.06 cycles of error on the coarser phase.
        check_plan(Unwrap::Hierarchical, &[1.0, 8.0, 64.0], 0.01);
        // Any order in the list, non-integer counts.
        check_plan(Unwrap::Hierarchical, &[37.5, 1.0, 6.0], 0.01);
    }
}
