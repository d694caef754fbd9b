//! Frames that lie: a capture's frames checked against what the manifest says was projected,
//! before anything is decoded from them.
//!
//! A projector that is late, a camera that drops a frame or one that exposes while the projector
//! updates gives frames that decode without an error into wrong codes. Each of them leaves a mark
//! a frame-by-frame look finds without knowing the geometry:
//!
//! - **Repeats**: the frame is (nearly) the previous one although the two patterns differ — the
//!   projector had not shown the new pattern yet, or the camera delivered a stale frame.
//! - **Mixed**: the top rows show the previous pattern and the bottom rows the new one (or the
//!   other way): the camera exposed while the projector was updating.
//! - **Dark**: the frame is dark where its pattern is bright: with the frame of the complementary
//!   pattern (white and black, a Gray bit and its inverse, phase steps half a period apart) it
//!   adds up to less light than every other such pair — the projector showed nothing (black)
//!   when the camera exposed. A pattern and its complement add up to white whatever the
//!   camera's blur, so the pairs of a capture agree with each other.
//!
//! The yardsticks are the capture's own. The image is cut into horizontal bands; for each band
//! the change between two frames is measured against the change the band shows between other
//! frames per unit of pattern change (the projector's patterns give the latter: the mean
//! absolute difference of consecutive patterns). Bands the projector does not light (no change
//! anywhere) judge nothing. Darkness is judged by pairs of complementary frames against the
//! median pair (of two pairs, the better one); a frame without a complementary partner (a Gray
//! code without inverses, a 3-step phase shift) is not judged for darkness.
//!
//! A frame that lies spoils the decoded codes the band check reads. So, when a complementary
//! pair's light is off (short or over), only that pair's frames are judged by the bands, one liar
//! a pair. Within a pair that is off, the frame still like its predecessor in more bands is the
//! late (all bands) or mixed (a run at the top or bottom) one; otherwise the darker frame where
//! the pair falls short is the dark one. A frame nearly black where the scene is lit, and the
//! frame after it, are not judged against their predecessor: a black frame after a frame dark on
//! the scene is the same picture as a late one, and the dark check names it.

use rayon::prelude::*;

use crate::{CaptureSet, CorrespondenceMap, Frames, Sample};

/// Horizontal bands the image is cut into: a mixed frame is located to a sixteenth of the
/// image.
const BANDS: usize = 16;
/// A band changes "as much as a pattern change" when it changes at least this share of what its
/// own response predicts, and "not at all" below `STILL`.
const STILL: f64 = 0.25;
const MOVING: f64 = 0.5;
/// Two consecutive patterns differ when their mean absolute difference is at least this (in
/// units of full projector light): a 4-step phase shift's neighbours differ by ~0.45, a Gray
/// code's bit planes by ~0.5, two phase frames of one step by 0.
const PATTERNS_DIFFER: f64 = 0.2;
/// A pair of complementary frames holds a dark frame when its light (`pair_light`: 1 for a
/// pair that adds up to white) falls short of the typical pair's by this much: a tenth of the
/// lit image left dark where the pattern was bright.
const DARK_SHORTFALL: f64 = 0.1;
/// A frame is nearly black when its own light (`frame_light`: about the share of the lit scene
/// its pattern lights) is below this.
const BLACK_LIGHT: f64 = 0.1;

/// What is wrong with a frame ([`FrameIssue`]).
#[derive(Debug, Clone, PartialEq)]
pub enum FrameFault {
    /// The frame shows the previous frame's pattern.
    Repeats {
        /// The frame it repeats (the one before).
        previous: usize,
    },
    /// Rows `rows.0..rows.1` show the previous frame's pattern, the other rows this frame's.
    Mixed {
        /// The frame whose pattern the rows still show.
        previous: usize,
        /// First and one-past-last row still showing it.
        rows: (usize, usize),
    },
    /// The frame is dark where its pattern is bright: with the frame of the complementary
    /// pattern it adds up to less light than the capture's other complementary pairs.
    Dark {
        /// The frame of the complementary pattern.
        complement: usize,
        /// The two frames' light together, per lit pixel relative to its range (a pair that
        /// adds up to white: 1).
        light: f64,
        /// The same, typical of the capture's complementary pairs.
        typical: f64,
    },
}

/// A frame of a capture that does not show what the manifest says was projected
/// ([`check_frames`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameIssue {
    /// The frame's index in the capture.
    pub frame: usize,
    /// Its name (the file it was read from).
    pub name: String,
    /// What is wrong.
    pub fault: FrameFault,
}

impl std::fmt::Display for FrameIssue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "frame {} ({}): ", self.frame, self.name)?;
        match &self.fault {
            FrameFault::Repeats { previous } => write!(
                f,
                "shows frame {previous}'s pattern although the patterns differ: the projector was late, or the camera delivered a stale frame (capture again with a longer display latency)"
            ),
            FrameFault::Mixed { previous, rows } => write!(
                f,
                "rows {}–{} still show frame {previous}'s pattern: the camera exposed while the projector was updating (capture again with a longer display latency)",
                rows.0,
                rows.1.saturating_sub(1)
            ),
            FrameFault::Dark {
                complement,
                light,
                typical,
            } => write!(
                f,
                "dark where its pattern is bright: with frame {complement} (the complementary pattern) it adds up to {:.0} % of the light the capture's other complementary pairs give ({:.2} against {:.2}): the projector showed nothing, or a pattern dark here, while the camera exposed (capture again with a longer display latency)",
                100.0 * light / typical.max(f64::MIN_POSITIVE),
                light,
                typical
            ),
        }
    }
}

/// Per frame and band: the mean grey level and the mean absolute difference with the previous
/// frame.
struct BandStats {
    mean: Vec<[f64; BANDS]>,
    change: Vec<[f64; BANDS]>,
}

fn band_stats<T: Sample>(frames: &[crate::Frame<T>]) -> BandStats {
    let (w, h) = frames.first().map_or((0, 0), |f| (f.width(), f.height()));
    let band_of = |y: usize| (y * BANDS / h.max(1)).min(BANDS - 1);
    let per_frame: Vec<([f64; BANDS], [f64; BANDS])> = (0..frames.len())
        .into_par_iter()
        .map(|k| {
            let mut mean = [0.0; BANDS];
            let mut change = [0.0; BANDS];
            let mut count = [0usize; BANDS];
            let here = frames[k].data();
            let before = k.checked_sub(1).map(|p| frames[p].data());
            for (y, row) in here.chunks(w.max(1)).enumerate() {
                let b = band_of(y);
                count[b] += row.len();
                mean[b] += row.iter().map(|v| f64::from(v.to_f32())).sum::<f64>();
                if let Some(before) = before {
                    let prev = &before[y * w..(y + 1) * w];
                    change[b] += row
                        .iter()
                        .zip(prev)
                        .map(|(a, p)| f64::from((a.to_f32() - p.to_f32()).abs()))
                        .sum::<f64>();
                }
            }
            for b in 0..BANDS {
                let n = count[b].max(1) as f64;
                mean[b] /= n;
                change[b] /= n;
            }
            (mean, change)
        })
        .collect();
    BandStats {
        mean: per_frame.iter().map(|(m, _)| *m).collect(),
        change: per_frame.iter().map(|(_, c)| *c).collect(),
    }
}

/// Each pixel's darkest and brightest value over the frames: what the projector's light does
/// to it.
fn pixel_bounds<T: Sample>(frames: &[crate::Frame<T>]) -> (Vec<f32>, Vec<f32>) {
    let len = frames.first().map_or(0, |f| f.data().len());
    let mut lo = vec![f32::INFINITY; len];
    let mut hi = vec![f32::NEG_INFINITY; len];
    for f in frames {
        lo.par_iter_mut()
            .zip(hi.par_iter_mut())
            .zip(f.data().par_iter())
            .for_each(|((l, h), v)| {
                let v = v.to_f32();
                *l = l.min(v);
                *h = h.max(v);
            });
    }
    (lo, hi)
}

/// The light of two complementary frames `a` and `b` together, per lit pixel (range of at
/// least `lit_range`) relative to its range: `(a + b − 2 lo) / (hi − lo)`, averaged. Blur
/// does not change it (a blurred pattern and its blurred complement still add up to the
/// blurred white), so every complementary pair of a capture gives about the same.
fn pair_light<T: Sample>(
    a: &crate::Frame<T>,
    b: &crate::Frame<T>,
    (lo, hi): (&[f32], &[f32]),
    lit_range: f32,
) -> f64 {
    let (mut n, mut sum) = (0usize, 0.0f64);
    for (((x, y), &l), &h) in a.data().iter().zip(b.data()).zip(lo).zip(hi) {
        let r = h - l;
        if r >= lit_range {
            n += 1;
            sum += f64::from((x.to_f32() + y.to_f32() - 2.0 * l) / r);
        }
    }
    sum / n.max(1) as f64
}

/// The light of frame `a` alone, per lit pixel relative to its range: `(a − lo) / (hi − lo)`,
/// averaged (as [`pair_light`]) over the image and over each band (NaN in a band without a lit
/// pixel): about the share of the lit scene its pattern lights, about 0 for a frame the
/// projector left black. Two frames' lights add up to their pair's light.
fn frame_light<T: Sample>(
    a: &crate::Frame<T>,
    (lo, hi): (&[f32], &[f32]),
    lit_range: f32,
) -> (f64, [f64; BANDS]) {
    let (w, h) = (a.width().max(1), a.height());
    let (mut n, mut sum) = ([0usize; BANDS], [0.0f64; BANDS]);
    for (y, ((row, lo), hi)) in a
        .data()
        .chunks(w)
        .zip(lo.chunks(w))
        .zip(hi.chunks(w))
        .enumerate()
    {
        let b = (y * BANDS / h.max(1)).min(BANDS - 1);
        for ((x, &l), &hh) in row.iter().zip(lo).zip(hi) {
            let r = hh - l;
            if r >= lit_range {
                n[b] += 1;
                sum[b] += f64::from((x.to_f32() - l) / r);
            }
        }
    }
    let total = sum.iter().sum::<f64>() / n.iter().sum::<usize>().max(1) as f64;
    let bands = std::array::from_fn(|b| {
        if n[b] > 0 {
            sum[b] / n[b] as f64
        } else {
            f64::NAN
        }
    });
    (total, bands)
}

/// How much each frame's pattern differs from the previous frame's where the camera sees it:
/// per frame and band, the mean absolute difference of the two patterns over the part of the
/// projector the band's decoded codes span (their 2nd to 98th percentiles; the whole height
/// where the map has no rows). The span, not each pixel's code: a frame that lies moves the
/// codes it decodes to where the lie is consistent, never far out of the span. Two patterns
/// that differ across the projector can be the same on the part the object takes (a coarse
/// Gray bit): that frame is not judged there. A band with codes on less than 1 % of its pixels
/// takes `whole`, the change over the whole projector.
fn local_pattern_change(
    set: &CaptureSet,
    decoded: &CorrespondenceMap,
    whole: &[f64],
) -> Vec<[f64; BANDS]> {
    let sequence = set.manifest.sequence();
    let n = set.frames.len();
    let (w, h) = (decoded.width, decoded.height);
    let (pw, ph) = (
        f64::from(sequence.projector.width),
        f64::from(sequence.projector.height),
    );
    let band_rows = |b: usize| (b * h / BANDS, (b + 1) * h / BANDS);
    let percentile = |mut v: Vec<f32>, lo: f64, hi: f64| -> Option<(f64, f64)> {
        if v.is_empty() {
            return None;
        }
        v.sort_by(f32::total_cmp);
        let at = |q: f64| f64::from(v[((v.len() - 1) as f64 * q) as usize]);
        Some((at(lo), at(hi)))
    };
    let per_band: Vec<Vec<f64>> = (0..BANDS)
        .into_par_iter()
        .map(|b| {
            let (y0, y1) = band_rows(b);
            let span = y0 * w..y1 * w;
            let cols: Vec<f32> = decoded.col[span.clone()]
                .iter()
                .copied()
                .filter(|c| c.is_finite())
                .collect();
            if cols.len() < span.len() / 100 + 1 {
                return whole.to_vec();
            }
            let rows: Vec<f32> = decoded.row[span.clone()]
                .iter()
                .copied()
                .filter(|r| r.is_finite())
                .collect();
            let Some((c0, c1)) = percentile(cols, 0.02, 0.98) else {
                return whole.to_vec();
            };
            let (r0, r1) = percentile(rows, 0.02, 0.98).unwrap_or((-0.5, ph - 0.5));
            const SAMPLES: usize = 1024;
            const R2: (f64, f64) = (0.754_877_666_246_692_7, 0.569_840_290_998_053_3);
            let points: Vec<(f64, f64)> = (0..SAMPLES)
                .map(|i| {
                    let t = i as f64 + 0.5;
                    (
                        (c0 + (t * R2.0).fract() * (c1 - c0)).clamp(-0.5, pw - 0.5),
                        (r0 + (t * R2.1).fract() * (r1 - r0)).clamp(-0.5, ph - 0.5),
                    )
                })
                .collect();
            let values: Vec<Vec<f64>> = (0..n)
                .map(|k| {
                    points
                        .iter()
                        .map(|&(x, y)| sequence.pattern_value(k, x, y).unwrap_or(f64::NAN))
                        .collect()
                })
                .collect();
            consecutive_change(&values)
        })
        .collect();
    (0..n)
        .map(|k| {
            let mut row = [0.0; BANDS];
            for (b, v) in row.iter_mut().enumerate() {
                *v = per_band[b].get(k).copied().unwrap_or(0.0);
            }
            row
        })
        .collect()
}

/// Each frame's pattern change from the previous frame's: the mean absolute difference of
/// their values at the same sample points (`values[k]`, frame `k`'s); 0 for the first frame.
fn consecutive_change(values: &[Vec<f64>]) -> Vec<f64> {
    (0..values.len())
        .map(|k| match k.checked_sub(1) {
            Some(p) => {
                values[k]
                    .iter()
                    .zip(&values[p])
                    .map(|(a, b)| (a - b).abs())
                    .sum::<f64>()
                    / values[k].len().max(1) as f64
            }
            None => 0.0,
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// The pairs of frames whose patterns are each other's complement (`p + q = 1` at points spread
/// over the projector's image: white and black, a Gray bit and its inverse, phase steps half a
/// period apart), each with whether its patterns are binary; and each frame's pattern change
/// from the previous one over the whole projector.
fn complement_pairs(set: &CaptureSet) -> (Vec<(usize, usize, bool)>, Vec<f64>) {
    let sequence = set.manifest.sequence();
    let (pw, ph) = (
        f64::from(sequence.projector.width),
        f64::from(sequence.projector.height),
    );
    // Points of the R2 low-discrepancy sequence over the projector's image: a regular grid
    // would alias with the fringes (a 40 px period sampled every 6.67 px sees 6 phases only).
    const SAMPLES: usize = 8192;
    const R2: (f64, f64) = (0.754_877_666_246_692_7, 0.569_840_290_998_053_3);
    let values = |k: usize| -> Vec<f64> {
        (0..SAMPLES)
            .map(|i| {
                let t = i as f64 + 0.5;
                let x = (t * R2.0).fract() * pw - 0.5;
                let y = (t * R2.1).fract() * ph - 0.5;
                sequence.pattern_value(k, x, y).unwrap_or(f64::NAN)
            })
            .collect()
    };
    let all: Vec<Vec<f64>> = (0..set.frames.len()).map(values).collect();
    let change = consecutive_change(&all);
    let mut paired = vec![false; all.len()];
    let mut pairs = Vec::new();
    for k in 0..all.len() {
        for j in k + 1..all.len() {
            if paired[k] || paired[j] {
                continue;
            }
            let complement = all[k]
                .iter()
                .zip(&all[j])
                .all(|(a, b)| (a + b - 1.0).abs() < 0.02);
            if complement {
                paired[k] = true;
                paired[j] = true;
                // Binary patterns (Gray bits, white and black) and continuous ones (fringes)
                // are judged apart: a projector's gamma makes a fringe and its complement add
                // up to less than white, a stripe and its inverse not.
                let binary = all[k].iter().all(|v| *v <= 1e-9 || *v >= 1.0 - 1e-9);
                pairs.push((k, j, binary));
            }
        }
    }
    (pairs, change)
}

/// The rows a mixed frame still shows the previous frame's pattern on, from each judged band's
/// change `ratio` (to what a pattern change gives): the still bands (below `STILL`) a run at the
/// top or at the bottom, the others changing as a pattern change does (`MOVING` at least).
fn mixed_rows(ratio: &[(usize, f64)], h: usize) -> Option<(usize, usize)> {
    let still: Vec<bool> = ratio.iter().map(|(_, r)| *r < STILL).collect();
    let first_moving = still.iter().position(|s| !s).unwrap_or(still.len());
    let last_still_top = still.iter().take_while(|s| **s).count();
    let top_run = last_still_top > 0 && ratio[first_moving..].iter().all(|(_, r)| *r >= MOVING);
    let bottom_still = still.iter().rev().take_while(|s| **s).count();
    let bottom_run = bottom_still > 0
        && ratio[..ratio.len() - bottom_still]
            .iter()
            .all(|(_, r)| *r >= MOVING);
    let row_of = |b: usize| b * h / BANDS;
    if top_run {
        Some((0, row_of(ratio[last_still_top - 1].0 + 1)))
    } else if bottom_run {
        Some((row_of(ratio[ratio.len() - bottom_still].0), h))
    } else {
        None
    }
}

/// Checks every frame of `set` against what its manifest says was projected (see the module
/// documentation) and returns the frames that do not show it, in frame order. An empty list
/// is a capture whose frames each show their pattern, as far as these checks see; a capture
/// too short to compare frames (fewer than 3) is not judged.
pub fn check_frames(set: &CaptureSet, decoded: &CorrespondenceMap) -> Vec<FrameIssue> {
    let n = set.frames.len();
    if n < 3
        || set.manifest.frame_count() != n
        || decoded.width != set.frames.width()
        || decoded.height != set.frames.height()
    {
        return Vec::new();
    }
    let stats = match &set.frames {
        Frames::U8(f) => band_stats(f),
        Frames::U16(f) => band_stats(f),
    };
    let (pairs, whole) = complement_pairs(set);
    let p_change = local_pattern_change(set, decoded, &whole);
    let h = set.frames.height();

    // Each band's response: grey levels of change per unit of pattern change, over the frame
    // pairs whose patterns differ there (the median: a few bad frames do not move it).
    let response: Vec<f64> = (0..BANDS)
        .map(|b| {
            median(
                (1..n)
                    .filter(|&k| p_change[k][b] >= PATTERNS_DIFFER)
                    .map(|k| stats.change[k][b] / p_change[k][b])
                    .collect(),
            )
            .unwrap_or(0.0)
        })
        .collect();
    let strongest = response.iter().copied().fold(0.0, f64::max);
    // Bands the projector lights: a tenth of the strongest band's response at least.
    let lit: Vec<usize> = (0..BANDS)
        .filter(|&b| strongest > 0.0 && response[b] >= 0.1 * strongest)
        .collect();
    let mut issues = Vec::new();
    let name = |k: usize| set.frame_names.get(k).cloned().unwrap_or(format!("#{k}"));

    // Each pixel's range over the frames; lit: a range of at least a fifth of the bright
    // end's (the 95th percentile).
    let (lo, hi) = match &set.frames {
        Frames::U8(f) => pixel_bounds(f),
        Frames::U16(f) => pixel_bounds(f),
    };
    let mut ranges: Vec<f32> = hi.iter().zip(&lo).step_by(7).map(|(h, l)| h - l).collect();
    ranges.sort_by(f32::total_cmp);
    let bright = ranges.get(ranges.len() * 19 / 20).copied().unwrap_or(0.0);
    let lit_range = (0.2 * bright).max(f32::MIN_POSITIVE);
    // A frame with almost no light of its own where the scene is lit: black, or a pattern
    // dark on the whole scene. Such a frame that looks like its predecessor may be a black
    // frame after a frame dark on the scene as well as a late one; it is left to the dark
    // check, which judges it against its complementary frame.
    let (own_light, own_band): (Vec<f64>, Vec<[f64; BANDS]>) = (0..n)
        .into_par_iter()
        .map(|k| match &set.frames {
            Frames::U8(f) => frame_light(&f[k], (&lo, &hi), lit_range),
            Frames::U16(f) => frame_light(&f[k], (&lo, &hi), lit_range),
        })
        .unzip();
    let nearly_black = |k: usize| own_light[k] < BLACK_LIGHT;

    // The light of each pair of complementary frames together, and the typical pair's.
    let light: Vec<f64> = pairs
        .par_iter()
        .map(|&(k, j, _)| match &set.frames {
            Frames::U8(f) => pair_light(&f[k], &f[j], (&lo, &hi), lit_range),
            Frames::U16(f) => pair_light(&f[k], &f[j], (&lo, &hi), lit_range),
        })
        .collect();
    // The typical pair of each kind (binary, continuous): the median of three or more; of
    // two, the brighter one (a dark frame in one of two pairs would pull their median
    // half-way down to itself); a kind with one pair is not judged.
    let typical_of = |binary: bool| {
        let of_kind: Vec<f64> = pairs
            .iter()
            .zip(&light)
            .filter(|((_, _, b), _)| *b == binary)
            .map(|(_, l)| *l)
            .collect();
        match of_kind.len() {
            0 | 1 => None,
            2 => of_kind.iter().copied().reduce(f64::max),
            _ => median(of_kind),
        }
    };
    // Frames of pairs whose light is off the typical pair's: short (a dark frame) or over (a
    // copy of a bright frame). A frame that lies in such a pair spoils the decoded codes, and
    // with them the spans the band checks judge the other frames on: when a pair is off, only
    // its own frames are judged by the bands.
    let mut in_off_pair = vec![false; n];
    for (&(k, j, binary), &l) in pairs.iter().zip(&light) {
        if typical_of(binary).is_some_and(|t| (l - t).abs() > DARK_SHORTFALL) {
            in_off_pair[k] = true;
            in_off_pair[j] = true;
        }
    }
    let any_off = in_off_pair.iter().any(|s| *s);

    // Repeated and mixed frames.
    let mut band_fault: Vec<Option<FrameFault>> = vec![None; n];
    for k in 1..n {
        // A frame after a nearly black one looks still wherever its own pattern is dark: it
        // is not judged against it (a copy of a nearly black frame is nearly black itself).
        if nearly_black(k) || nearly_black(k - 1) || (any_off && !in_off_pair[k]) {
            continue;
        }
        // The bands where the two patterns differ on what the camera sees.
        let judged: Vec<usize> = lit
            .iter()
            .copied()
            .filter(|&b| p_change[k][b] >= PATTERNS_DIFFER)
            .collect();
        if judged.len() < 2 {
            continue;
        }
        let ratio: Vec<(usize, f64)> = judged
            .iter()
            .map(|&b| (b, stats.change[k][b] / (p_change[k][b] * response[b])))
            .collect();
        let still: Vec<bool> = ratio.iter().map(|(_, r)| *r < STILL).collect();
        let moving = ratio.iter().all(|(_, r)| *r >= STILL);
        if moving {
            continue;
        }
        if still.iter().all(|s| *s) {
            band_fault[k] = Some(FrameFault::Repeats { previous: k - 1 });
            continue;
        }
        if let Some(rows) = mixed_rows(&ratio, h) {
            band_fault[k] = Some(FrameFault::Mixed {
                previous: k - 1,
                rows,
            });
        }
    }
    // One liar a pair: where both frames of a pair that is off were flagged, the copy (every band
    // still) over the mixed frame, of two copies the later one (the spoilt decode can make
    // the partner of a late frame look mixed).
    for &(k, j, _) in &pairs {
        if let (Some(a), Some(b)) = (&band_fault[k], &band_fault[j])
            && in_off_pair[k]
        {
            let repeats = |f: &FrameFault| matches!(f, FrameFault::Repeats { .. });
            let drop = if repeats(a) && !repeats(b) { j } else { k };
            band_fault[drop] = None;
        }
    }
    let mut flagged = vec![false; n];
    for (k, fault) in band_fault.into_iter().enumerate() {
        if let Some(fault) = fault {
            flagged[k] = true;
            issues.push(FrameIssue {
                frame: k,
                name: name(k),
                fault,
            });
        }
    }

    // Pairs whose light is off, not explained by a frame the band check named: the frame that
    // lies in each is named (late, mixed or dark).
    if !lit.is_empty() {
        let mean = |k: usize| lit.iter().map(|&b| stats.mean[k][b]).sum::<f64>() / lit.len() as f64;
        for (&(k, j, binary), &l) in pairs.iter().zip(&light) {
            if let Some(typical) = typical_of(binary) {
                // A repeated or mixed frame explains its pair's shortfall (or excess) too.
                if (l - typical).abs() <= DARK_SHORTFALL || flagged[k] || flagged[j] {
                    continue;
                }
                // Which of the two lies (the decoded codes cannot say: a lying frame moves them
                // to agree with itself). First by likeness to the frame before: each lit band's
                // change from it, per what the projector-wide pattern change predicts (empty
                // where the frame cannot be judged so); the band check passes a late frame over
                // where the two patterns coincide on its bands' codes' span.
                let ratio = |f: usize| -> Vec<(usize, f64)> {
                    if f == 0
                        || nearly_black(f)
                        || nearly_black(f - 1)
                        || whole[f] < PATTERNS_DIFFER
                    {
                        return Vec::new();
                    }
                    lit.iter()
                        .map(|&b| {
                            let expected = whole[f] * response[b].max(f64::MIN_POSITIVE);
                            (b, stats.change[f][b] / expected)
                        })
                        .collect()
                };
                let still_bands = |r: &[(usize, f64)]| r.iter().filter(|(_, v)| *v < STILL).count();
                let (rk, rj) = (ratio(k), ratio(j));
                let (sk, sj) = (still_bands(&rk), still_bands(&rj));
                if sk != sj {
                    // The frame with more bands still like the one before it: late where all
                    // are, mixed where they are a run at the top or the bottom.
                    let (late, r) = if sk > sj { (k, &rk) } else { (j, &rj) };
                    let fault = if still_bands(r) == r.len() {
                        Some(FrameFault::Repeats { previous: late - 1 })
                    } else {
                        mixed_rows(r, h).map(|rows| FrameFault::Mixed {
                            previous: late - 1,
                            rows,
                        })
                    };
                    if let Some(fault) = fault {
                        flagged[late] = true;
                        issues.push(FrameIssue {
                            frame: late,
                            name: name(late),
                            fault,
                        });
                        continue;
                    }
                }
                // A pair over the typical light without a late frame found: not a dark frame.
                if l > typical {
                    continue;
                }
                // The dark frame: the darker one where the pair falls short (the bands whose
                // two lights add up to less than the typical pair's), over the whole lit
                // scene when no band does on its own.
                let short: Vec<usize> = lit
                    .iter()
                    .copied()
                    .filter(|&b| own_band[k][b] + own_band[j][b] < typical - DARK_SHORTFALL)
                    .collect();
                let in_short = |f: usize| short.iter().map(|&b| own_band[f][b]).sum::<f64>();
                // Two frames about as dark there (within 0.02 of the range a band): the later
                // one, which can be a copy of the other (a frame repeats its predecessor).
                let k_darker = if short.is_empty() {
                    mean(k) <= mean(j)
                } else if (in_short(k) - in_short(j)).abs() <= 0.02 * short.len() as f64 {
                    k > j
                } else {
                    in_short(k) < in_short(j)
                };
                let (dark, other) = if k_darker { (k, j) } else { (j, k) };
                issues.push(FrameIssue {
                    frame: dark,
                    name: name(dark),
                    fault: FrameFault::Dark {
                        complement: other,
                        light: l,
                        typical,
                    },
                });
            }
        }
        issues.sort_by_key(|i| i.frame);
    }
    issues
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{
        BitDepth, DecodeConfig, Frame, HybridSpec, ImageSize, Pattern, PatternSequence,
        SyntheticScene, decode,
    };

    /// The checks as a user runs them: after the decode.
    fn check(set: &CaptureSet) -> Vec<FrameIssue> {
        check_frames(set, &decode(set, &DecodeConfig::default()).unwrap())
    }

    /// A capture of the recommended hybrid code (white, black, Gray bits and their inverses,
    /// phase steps) of a synthetic plane, 8-bit, with noise.
    fn capture() -> CaptureSet {
        let projector = ImageSize::new(640, 360);
        let sequence = PatternSequence::new(projector).with(Pattern::Hybrid(
            HybridSpec::complementary(crate::Axis::Column, projector, 4, 640.0 / 16.0),
        ));
        let scene = SyntheticScene {
            ambient: 15.0,
            noise_sigma: 1.5,
            ..SyntheticScene::looking_at(projector, 320, 240)
        };
        let frames: Vec<Frame<u8>> = scene.render(&sequence).unwrap();
        CaptureSet::from_frames(sequence.manifest(BitDepth::Eight), Frames::U8(frames)).unwrap()
    }

    fn frames_mut(set: &mut CaptureSet) -> &mut Vec<Frame<u8>> {
        match &mut set.frames {
            Frames::U8(f) => f,
            Frames::U16(_) => unreachable!("the test capture is 8-bit"),
        }
    }

    /// The frames as rendered pass: no frame is named.
    #[test]
    fn a_clean_capture_has_no_issue() {
        let set = capture();
        assert!(set.frames.len() > 10);
        assert_eq!(check(&set), Vec::new());
    }

    /// A late projector (frame k shows pattern k - 1), a black frame, a frame half of whose rows
    /// still show the previous pattern: each is named, with the rows of the mixed one.
    #[test]
    fn late_black_and_mixed_frames_are_named() {
        let clean = capture();
        let n = clean.frames.len();
        let h = clean.frames.height();
        let w = clean.frames.width();
        // Frames of the Gray part and of the phase part, each after a frame whose pattern differs.
        for k in [4, n - 2] {
            let mut late = clean.clone();
            let f = frames_mut(&mut late);
            f[k] = f[k - 1].clone();
            let issues = check(&late);
            assert_eq!(
                issues
                    .iter()
                    .map(|i| (i.frame, i.fault.clone()))
                    .collect::<Vec<_>>(),
                vec![(k, FrameFault::Repeats { previous: k - 1 })],
                "{issues:?}"
            );
            assert!(
                issues[0]
                    .to_string()
                    .contains(&format!("shows frame {}", k - 1))
            );

            let mut black = clean.clone();
            let f = frames_mut(&mut black);
            f[k] = Frame::new(w, h, vec![15u8; w * h]).unwrap();
            let issues = check(&black);
            assert_eq!(issues.len(), 1, "{issues:?}");
            assert_eq!(issues[0].frame, k);
            assert!(
                matches!(issues[0].fault, FrameFault::Dark { .. }),
                "{issues:?}"
            );

            let mut mixed = clean.clone();
            let f = frames_mut(&mut mixed);
            let split = h * 3 / 8;
            let mut data = f[k].data().to_vec();
            data[..split * w].copy_from_slice(&f[k - 1].data()[..split * w]);
            f[k] = Frame::new(w, h, data).unwrap();
            let issues = check(&mixed);
            assert_eq!(issues.len(), 1, "{issues:?}");
            assert_eq!(issues[0].frame, k);
            match issues[0].fault {
                FrameFault::Mixed { previous, rows } => {
                    assert_eq!(previous, k - 1);
                    // To the band: the split is at 3/8 of the image, 6 bands of 16.
                    assert_eq!(rows, (0, split), "{issues:?}");
                }
                ref other => panic!("{other:?}"),
            }
        }
    }
}
