//! The row-parallel driver shared by every decoder.
//!
//! A decoder is a set of kernels, one per pattern block. The driver splits the camera image
//! into bands of rows, hands each band to rayon, and runs every kernel on the band as one
//! contiguous run of pixels (a band of a row-major frame is one slice), so each frame is read
//! once in long sequential runs and the outputs are written once. Scratch buffers are allocated
//! once per rayon task, never per pixel.

use rayon::prelude::*;

use crate::bits::GrayScratch;
use crate::correspondence::{AxisMap, CorrespondenceMap, InvalidReason};
use crate::gray::GrayKernel;
use crate::hybrid::{HybridKernel, HybridScratch};
use crate::phase_shift::{PhaseKernel, PhaseScratch};
use crate::{Axis, Sample};

/// Where a kernel writes the rows of one band.
pub(crate) struct AxisRows<'a> {
    /// The first kernel of the band writes quality and reason; later ones merge.
    pub(crate) first: bool,
    /// Coordinate along the kernel's axis.
    pub(crate) coord: &'a mut [f32],
    /// Quality (merged by `min`).
    pub(crate) quality: &'a mut [f32],
    /// Invalid reason (merged by priority).
    pub(crate) invalid: &'a mut [InvalidReason],
}

/// The three output slices of one camera row, all of the row's width.
pub(crate) struct RowOut<'r> {
    pub(crate) first: bool,
    pub(crate) coord: &'r mut [f32],
    pub(crate) quality: &'r mut [f32],
    pub(crate) invalid: &'r mut [InvalidReason],
}

/// Writes pixels `0 .. n` of a [`RowOut`] from an expression giving
/// `(coord, quality, reason)` for pixel `i`: the coordinate (NaN unless the reason is valid),
/// the quality (merged by `min` unless this is the band's first kernel) and the reason (merged by
/// priority likewise). A macro rather than a closure so that the body is inlined into both
/// branch-free loops and they vectorise.
macro_rules! fill_out {
    ($out:expr, $n:expr, |$i:ident| $pixel:expr) => {{
        let o: $crate::kernel::RowOut<'_> = $out;
        let n = ($n)
            .min(o.coord.len())
            .min(o.quality.len())
            .min(o.invalid.len());
        let (coord, quality, invalid) =
            (&mut o.coord[..n], &mut o.quality[..n], &mut o.invalid[..n]);
        if o.first {
            for $i in 0..n {
                let (c, q, r): (f32, f32, $crate::InvalidReason) = $pixel;
                coord[$i] = if r == $crate::InvalidReason::Valid {
                    c
                } else {
                    f32::NAN
                };
                quality[$i] = q;
                invalid[$i] = r;
            }
        } else {
            for $i in 0..n {
                let (c, q, r): (f32, f32, $crate::InvalidReason) = $pixel;
                coord[$i] = if r == $crate::InvalidReason::Valid {
                    c
                } else {
                    f32::NAN
                };
                quality[$i] = quality[$i].min(q);
                invalid[$i] = invalid[$i].merge(r);
            }
        }
    }};
}
pub(crate) use fill_out;

impl AxisRows<'_> {
    /// The outputs of the `width` pixels starting at `offset` (empty slices if out of range,
    /// which the callers' loops then skip).
    #[inline]
    pub(crate) fn row(&mut self, offset: usize, width: usize) -> RowOut<'_> {
        let r = offset..offset + width;
        let coord = self.coord.get_mut(r.clone()).unwrap_or_default();
        let quality = self.quality.get_mut(r.clone()).unwrap_or_default();
        let invalid = self.invalid.get_mut(r).unwrap_or_default();
        RowOut {
            first: self.first,
            coord,
            quality,
            invalid,
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
    /// Decodes camera rows `y0 .. y0 + rows` (one contiguous band) into `out`.
    #[inline(always)]
    fn decode_band(&self, y0: usize, rows: usize, out: &mut AxisRows<'_>, scratch: &mut Scratch) {
        match (self, scratch) {
            (Self::Gray(k), Scratch::Gray(s)) => k.decode_band(y0, rows, out, s),
            (Self::Phase(k), Scratch::Phase(s)) => k.decode_band(y0, rows, out, s),
            (Self::Hybrid(k), Scratch::Hybrid(s)) => k.decode_band(y0, rows, out, s),
            // new_scratch pairs each kernel with its own scratch kind.
            _ => {}
        }
    }
}

/// Runs all kernels over the whole image into `map` (sized `width x height`; its previous
/// contents are overwritten).
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
    // Runtime CPU dispatch (AVX2 + FMA where available; feature `simd`): the band loops below,
    // all inlined into the dispatched closure, are then vectorised 8 lanes wide instead of 4
    // (SSE2 baseline).
    #[cfg(feature = "simd")]
    let arch = pulp::Arch::new();
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
                    .map(|k| k.new_scratch(chunk))
                    .collect::<Vec<_>>()
            },
            |scratch, (band, (((col, row), quality), invalid))| {
                let y0 = band * rows_per_task;
                let rows = col.len() / width;
                if !kernels.iter().any(|k| k.axis() == Axis::Column) {
                    col.fill(f32::NAN);
                }
                if !kernels.iter().any(|k| k.axis() == Axis::Row) {
                    row.fill(f32::NAN);
                }
                if kernels.is_empty() {
                    quality.fill(f32::INFINITY);
                    invalid.fill(InvalidReason::Valid);
                }
                for (k, (kernel, s)) in kernels.iter().zip(scratch.iter_mut()).enumerate() {
                    let coord = match kernel.axis() {
                        Axis::Column => &mut *col,
                        Axis::Row => &mut *row,
                    };
                    let mut out = AxisRows {
                        first: k == 0,
                        coord,
                        quality: &mut *quality,
                        invalid: &mut *invalid,
                    };
                    #[cfg(feature = "simd")]
                    arch.dispatch(BandJob {
                        kernel,
                        y0,
                        rows,
                        out: &mut out,
                        scratch: s,
                    });
                    #[cfg(not(feature = "simd"))]
                    kernel.decode_band(y0, rows, &mut out, s);
                }
            },
        );
}

#[cfg(feature = "simd")]
/// One kernel on one band, as a `pulp` operation: `with_simd` is inlined (with everything it
/// calls) into a function compiled for the detected instruction set, so the loops are
/// vectorised for it. A struct rather than a closure because only trait methods marked
/// `#[inline(always)]` are reliably inlined there.
struct BandJob<'k, 'a, 'o, 's, T: Sample> {
    kernel: &'k Kernel<'a, T>,
    y0: usize,
    rows: usize,
    out: &'o mut AxisRows<'a>,
    scratch: &'s mut Scratch,
}

#[cfg(feature = "simd")]
impl<T: Sample> pulp::WithSimd for BandJob<'_, '_, '_, '_, T> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        self.kernel
            .decode_band(self.y0, self.rows, self.out, self.scratch);
    }
}

/// Runs one kernel into a fresh [`AxisMap`].
pub(crate) fn run_axis<T: Sample>(
    kernel: Kernel<'_, T>,
    width: usize,
    height: usize,
    rows_per_task: usize,
) -> AxisMap {
    let axis = kernel.axis();
    let mut map = CorrespondenceMap::new(0, 0);
    map.resize(width, height);
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
