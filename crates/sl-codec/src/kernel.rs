//! The row-parallel driver shared by every decoder.
//!
//! A decoder is a set of kernels, one per pattern block. The driver splits the camera image
//! into bands of rows, hands each band to rayon, and in each band runs every kernel one camera
//! row at a time, so the frames' rows are read once, while they are hot, and the outputs are
//! written once. Scratch buffers are allocated once per rayon task, never per pixel.

use rayon::prelude::*;

use crate::correspondence::{AxisMap, CorrespondenceMap, InvalidReason};
use crate::gray::{GrayKernel, GrayScratch};
use crate::hybrid::{HybridKernel, HybridScratch};
use crate::phase_shift::{PhaseKernel, PhaseScratch};
use crate::{Axis, Sample};

/// Where a kernel writes the rows of one band.
pub(crate) struct AxisRows<'a> {
    /// Coordinate along the kernel's axis.
    pub(crate) coord: &'a mut [f32],
    /// Quality (merged by `min`).
    pub(crate) quality: &'a mut [f32],
    /// Invalid reason (merged by priority).
    pub(crate) invalid: &'a mut [InvalidReason],
}

impl AxisRows<'_> {
    /// Writes one pixel's result, merging quality and reason with what earlier kernels wrote.
    #[inline(always)]
    pub(crate) fn put(&mut self, i: usize, coord: f32, quality: f32, reason: InvalidReason) {
        if let Some(c) = self.coord.get_mut(i) {
            *c = if reason.is_valid() { coord } else { f32::NAN };
        }
        if let Some(q) = self.quality.get_mut(i) {
            *q = q.min(quality);
        }
        if let Some(r) = self.invalid.get_mut(i) {
            *r = r.merge(reason);
        }
    }
}

/// A decoder for one block.
pub(crate) enum Kernel<'a, T: Sample> {
    Gray(GrayKernel<'a, T>),
    Phase(PhaseKernel<'a, T>),
    Hybrid(HybridKernel<'a, T>),
}

/// Scratch memory of one kernel for one rayon task.
pub(crate) enum Scratch {
    Gray(GrayScratch),
    Phase(PhaseScratch),
    Hybrid(HybridScratch),
}

impl<T: Sample> Kernel<'_, T> {
    fn axis(&self) -> Axis {
        match self {
            Self::Gray(k) => k.axis(),
            Self::Phase(k) => k.axis(),
            Self::Hybrid(k) => k.axis(),
        }
    }

    fn new_scratch(&self, width: usize) -> Scratch {
        match self {
            Self::Gray(k) => Scratch::Gray(k.new_scratch(width)),
            Self::Phase(k) => Scratch::Phase(k.new_scratch(width)),
            Self::Hybrid(k) => Scratch::Hybrid(k.new_scratch(width)),
        }
    }

    /// Decodes camera row `y` into `out` at offset `offset`.
    fn decode_row(&self, y: usize, offset: usize, out: &mut AxisRows<'_>, scratch: &mut Scratch) {
        match (self, scratch) {
            (Self::Gray(k), Scratch::Gray(s)) => k.decode_row(y, offset, out, s),
            (Self::Phase(k), Scratch::Phase(s)) => k.decode_row(y, offset, out, s),
            (Self::Hybrid(k), Scratch::Hybrid(s)) => k.decode_row(y, offset, out, s),
            // new_scratch pairs each kernel with its own scratch kind.
            _ => {}
        }
    }
}

/// Runs all kernels over the whole image into `map` (which must be reset to `width x height`).
pub(crate) fn run<T: Sample>(
    kernels: &[Kernel<'_, T>],
    map: &mut CorrespondenceMap,
    rows_per_task: usize,
) {
    let width = map.width;
    if width == 0 || map.height == 0 {
        return;
    }
    let chunk = width * rows_per_task.max(1);
    let rows_per_task = rows_per_task.max(1);
    map.col
        .par_chunks_mut(chunk)
        .zip(map.row.par_chunks_mut(chunk))
        .zip(map.quality.par_chunks_mut(chunk))
        .zip(map.invalid.par_chunks_mut(chunk))
        .enumerate()
        .for_each_init(
            || {
                kernels
                    .iter()
                    .map(|k| k.new_scratch(width))
                    .collect::<Vec<_>>()
            },
            |scratch, (band, (((col, row), quality), invalid))| {
                let y0 = band * rows_per_task;
                let rows = col.len() / width;
                for (kernel, s) in kernels.iter().zip(scratch.iter_mut()) {
                    let coord = match kernel.axis() {
                        Axis::Column => &mut *col,
                        Axis::Row => &mut *row,
                    };
                    let mut out = AxisRows {
                        coord,
                        quality: &mut *quality,
                        invalid: &mut *invalid,
                    };
                    for r in 0..rows {
                        kernel.decode_row(y0 + r, r * width, &mut out, s);
                    }
                }
            },
        );
}

/// Runs one kernel into a fresh [`AxisMap`].
pub(crate) fn run_axis<T: Sample>(
    kernel: Kernel<'_, T>,
    width: usize,
    height: usize,
    rows_per_task: usize,
) -> AxisMap {
    let axis = kernel.axis();
    let mut map = CorrespondenceMap::new(width, height);
    run(std::slice::from_ref(&kernel), &mut map, rows_per_task);
    let coord = match axis {
        Axis::Column => map.col,
        Axis::Row => map.row,
    };
    AxisMap {
        width,
        height,
        coord,
        quality: map.quality,
        invalid: map.invalid,
    }
}
