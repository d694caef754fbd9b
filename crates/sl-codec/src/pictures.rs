//! False-colour pictures and map files of a correspondence map: what people look at first when a
//! scan goes wrong.

#[cfg(feature = "image-files")]
use std::path::Path;
use std::path::PathBuf;

use crate::InvalidReason;
#[cfg(feature = "image-files")]
use crate::export::{write_npy_f32, write_png_grey8, write_png_rgb8, write_tiff_f32};
#[cfg(feature = "image-files")]
use crate::{CodecError, CorrespondenceMap, Frame, ImageSize};

/// Colours of the invalid-reason picture, indexed by the reason's byte value: valid pixels
/// dark green, inconsistent code red, low modulation blue, shadow black, saturated white.
pub const INVALID_PALETTE: [[u8; 3]; 5] = [
    [0, 110, 40],
    [230, 20, 20],
    [40, 90, 255],
    [0, 0, 0],
    [255, 255, 255],
];

/// Quantile of the valid qualities mapped to the top of the colour scale, so that a few
/// specular highlights do not squash the picture into the dark end.
#[cfg(feature = "image-files")]
const QUALITY_SCALE_QUANTILE: f64 = 0.99;

/// The "turbo" colour scale (Mikhailov 2019, polynomial fit) at `x` in `[0, 1]`.
pub fn turbo(x: f32) -> [u8; 3] {
    let x = x.clamp(0.0, 1.0);
    let poly = |c: [f32; 6]| c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * (c[4] + x * c[5]))));
    let r = poly([
        0.135_721_38,
        4.615_392_6,
        -42.660_324,
        132.131_08,
        -152.942_4,
        59.286_38,
    ]);
    let g = poly([
        0.091_402_61,
        2.194_188_4,
        4.842_966_6,
        -14.185_033,
        4.277_298_6,
        2.829_566,
    ]);
    let b = poly([
        0.106_673_3,
        12.641_946,
        -60.582_05,
        110.362_77,
        -89.903_11,
        27.348_25,
    ]);
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(r), q(g), q(b)]
}

/// RGB bytes of `values` mapped through [`turbo`] from `lo` to `hi`; NaN is black.
pub fn false_color(values: &[f32], lo: f32, hi: f32) -> Vec<u8> {
    let span = if hi > lo { hi - lo } else { 1.0 };
    values
        .iter()
        .flat_map(|&v| {
            if v.is_finite() {
                turbo((v - lo) / span)
            } else {
                [0, 0, 0]
            }
        })
        .collect()
}

/// RGB bytes of the invalid reasons through [`INVALID_PALETTE`].
pub fn invalid_colors(invalid: &[InvalidReason]) -> Vec<u8> {
    invalid
        .iter()
        .flat_map(|&r| {
            INVALID_PALETTE
                .get(r as usize)
                .copied()
                .unwrap_or([255, 0, 255])
        })
        .collect()
}

/// File format of the float maps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MapFormat {
    /// 32-bit float TIFF (`.tiff`).
    #[default]
    Tiff,
    /// numpy `.npy`.
    Npy,
}

/// Paths written by [`write_outputs`].
#[derive(Clone, Debug, PartialEq, Default)]
pub struct OutputFiles {
    /// Float maps: column, row, quality.
    pub maps: Vec<PathBuf>,
    /// The invalid reasons as an 8-bit label PNG (values as in [`InvalidReason`]).
    pub labels: PathBuf,
    /// False-colour PNGs: column, row, quality, invalid.
    pub pictures: Vec<PathBuf>,
}

#[cfg(feature = "image-files")]
/// Writes `col`, `row` and `quality` as float maps, `invalid.png` (labels), and the
/// false-colour pictures `col_color.png`, `row_color.png`, `quality_color.png` and
/// `invalid_color.png` into `dir` (created if needed).
///
/// Column and row pictures span the projector (`0 .. width - 1`, `0 .. height - 1`) when it is
/// given, else the range of the valid values; quality spans 0 to its 99th percentile.
///
/// # Errors
/// [`CodecError::Io`] / [`CodecError::Image`] naming the file.
pub fn write_outputs(
    map: &CorrespondenceMap,
    dir: &Path,
    format: MapFormat,
    projector: Option<ImageSize>,
) -> Result<OutputFiles, CodecError> {
    std::fs::create_dir_all(dir).map_err(|e| CodecError::io(dir, "create directory", e))?;
    let (w, h) = (map.width, map.height);
    let mut files = OutputFiles::default();
    for (name, values) in [
        ("col", &map.col),
        ("row", &map.row),
        ("quality", &map.quality),
    ] {
        let path = match format {
            MapFormat::Tiff => {
                let p = dir.join(format!("{name}.tiff"));
                write_tiff_f32(&p, w, h, values)?;
                p
            }
            MapFormat::Npy => {
                let p = dir.join(format!("{name}.npy"));
                write_npy_f32(&p, w, h, values)?;
                p
            }
        };
        files.maps.push(path);
    }
    let labels = Frame::new(
        w.max(1),
        h.max(1),
        map.invalid.iter().map(|&r| r as u8).collect(),
    );
    if let Ok(labels) = labels {
        files.labels = dir.join("invalid.png");
        write_png_grey8(&files.labels, &labels)?;
    }
    let range = |v: &[f32], extent: Option<u32>| -> (f32, f32) {
        match extent {
            Some(e) => (0.0, e.saturating_sub(1) as f32),
            None => v
                .iter()
                .filter(|x| x.is_finite())
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &x| {
                    (lo.min(x), hi.max(x))
                }),
        }
    };
    let (c0, c1) = range(&map.col, projector.map(|p| p.width));
    let (r0, r1) = range(&map.row, projector.map(|p| p.height));
    let q1 = quantile(&map.quality, QUALITY_SCALE_QUANTILE);
    let pictures = [
        ("col_color.png", false_color(&map.col, c0, c1)),
        ("row_color.png", false_color(&map.row, r0, r1)),
        ("quality_color.png", false_color(&map.quality, 0.0, q1)),
        ("invalid_color.png", invalid_colors(&map.invalid)),
    ];
    for (name, rgb) in pictures {
        let p = dir.join(name);
        write_png_rgb8(&p, w, h, &rgb)?;
        files.pictures.push(p);
    }
    Ok(files)
}

#[cfg(feature = "image-files")]
/// The `q` quantile of the finite values (1 if there is none).
fn quantile(values: &[f32], q: f64) -> f32 {
    let mut v: Vec<f32> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 1.0;
    }
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    let k = k.min(v.len() - 1);
    let (_, x, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    *x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_scales() {
        // Turbo is dark at both ends, bright in the middle, and ends red; NaN is black.
        let luma =
            |c: [u8; 3]| 0.3 * f32::from(c[0]) + 0.59 * f32::from(c[1]) + 0.11 * f32::from(c[2]);
        let (lo, mid, hi) = (turbo(0.0), turbo(0.5), turbo(1.0));
        assert!(
            luma(lo) < luma(mid) && luma(hi) < luma(mid),
            "{lo:?} {mid:?} {hi:?}"
        );
        assert!(hi[0] > hi[2], "{hi:?}");
        assert_eq!(&false_color(&[f32::NAN], 0.0, 1.0), &[0, 0, 0]);
        assert_eq!(
            invalid_colors(&[InvalidReason::InconsistentCode]),
            vec![230, 20, 20]
        );
        assert_eq!(quantile(&[3.0, 1.0, f32::NAN, 2.0], 1.0), 3.0);
        assert_eq!(quantile(&[3.0, 1.0, 2.0], 0.0), 1.0);
    }

    #[test]
    fn writes_all_files() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = CorrespondenceMap::new(4, 3);
        m.col
            .iter_mut()
            .enumerate()
            .for_each(|(i, c)| *c = i as f32);
        m.invalid[5] = InvalidReason::Shadow;
        let files = write_outputs(&m, dir.path(), MapFormat::Tiff, None).unwrap();
        assert_eq!(files.maps.len(), 3);
        assert_eq!(files.pictures.len(), 4);
        for p in files
            .maps
            .iter()
            .chain(&files.pictures)
            .chain([&files.labels])
        {
            assert!(p.is_file(), "{}", p.display());
        }
        let labels = image::open(&files.labels).unwrap().to_luma8();
        assert_eq!(labels.get_pixel(1, 1).0, [3]);
        let files =
            write_outputs(&m, dir.path(), MapFormat::Npy, Some(ImageSize::new(8, 8))).unwrap();
        assert!(files.maps[0].extension().is_some_and(|e| e == "npy"));
    }
}
