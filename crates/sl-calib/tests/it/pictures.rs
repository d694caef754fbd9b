//! Pictures of a calibration: the pixels the drawing must colour are coloured, bar heights are
//! proportional to the RMS values, residual arrows point where the residuals do.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use image::Rgb;
use nalgebra::{Point2, Vector2};
use sl_calib::sl_codec::Frame;
use sl_calib::{
    BAR, BoardCorners, BoardSize, FIRST_CORNER, OUTLIER_BAR, PALETTE, PictureConfig, draw_corners,
    error_bars, residual_plot, save_png,
};

fn grid(cols: u32, rows: u32, step: f64, origin: f64) -> BoardCorners {
    BoardCorners {
        size: BoardSize::new(cols, rows),
        corners: (0..rows)
            .flat_map(|r| {
                (0..cols).map(move |c| {
                    Point2::new(origin + f64::from(c) * step, origin + f64::from(r) * step)
                })
            })
            .collect(),
    }
}

#[test]
fn corners_are_drawn_first_in_red_rows_in_palette_order() {
    let img = Frame::filled(320, 240, 128).unwrap();
    let corners = grid(4, 3, 40.0, 60.0);
    let pic = draw_corners(&img, &corners);
    // Corner 0: the red disc.
    assert_eq!(*pic.get_pixel(60, 60), FIRST_CORNER);
    // The last corner: a filled disc in the last row's colour.
    assert_eq!(*pic.get_pixel(180, 140), PALETTE[2]);
    // The segment between corners 1 and 2 of row 0 is drawn in row 0's colour.
    assert_eq!(*pic.get_pixel(120, 60), PALETTE[0]);
    // The segment of row 1 (corners 5 → 6) in row 1's colour.
    assert_eq!(*pic.get_pixel(120, 100), PALETTE[1]);
    // Every other corner is circled: a pixel on its ring is coloured, its centre is not.
    let r = 2; // marker radius at 240 px: max(2, 240/160 rounded) = 2
    for (k, p) in corners.corners.iter().enumerate().skip(1).take(10) {
        let (x, y) = (p.x as u32, p.y as u32);
        let ring = pic.get_pixel(x + r, y);
        assert_ne!(*ring, Rgb([128, 128, 128]), "corner {k} not circled");
    }
    // Far from the board the image is untouched grey.
    assert_eq!(*pic.get_pixel(10, 10), Rgb([128, 128, 128]));
    assert_eq!(*pic.get_pixel(300, 230), Rgb([128, 128, 128]));
}

/// Number of bar-coloured pixels in a column (the bar's height).
fn bar_height(img: &image::RgbImage, x: u32) -> u32 {
    (0..img.height())
        .filter(|&y| {
            let p = *img.get_pixel(x, y);
            p == BAR || p == OUTLIER_BAR
        })
        .count() as u32
}

#[test]
fn bar_heights_are_proportional_to_the_rms() {
    let rms = [0.1, 0.2, 0.05, 0.4, 0.15];
    let chart = error_bars(&rms, 0.18, &PictureConfig::default());
    // The largest bar is 90 % of the 240 px plot: 216 px, so 540 px per px of RMS.
    assert!((chart.px_per_unit - 540.0).abs() < 1e-9);
    for (v, &x) in rms.iter().zip(&chart.bar_centres) {
        // The overall-RMS line may cross a bar and hide one row of it.
        let h = f64::from(bar_height(&chart.image, x));
        let expected = v * chart.px_per_unit;
        assert!(
            (h - expected).abs() <= 1.5,
            "bar {v}: {h} px, expected {expected}"
        );
    }
    // 0.4 is more than twice the median (0.15): drawn as an outlier.
    let x = chart.bar_centres[3];
    assert_eq!(*chart.image.get_pixel(x, chart.baseline_y), OUTLIER_BAR);
    assert_eq!(
        *chart
            .image
            .get_pixel(chart.bar_centres[0], chart.baseline_y),
        BAR
    );
    // Bad values draw nothing instead of failing.
    let chart = error_bars(
        &[f64::NAN, -1.0, 0.3],
        f64::INFINITY,
        &PictureConfig::default(),
    );
    assert_eq!(bar_height(&chart.image, chart.bar_centres[0]), 0);
    assert_eq!(bar_height(&chart.image, chart.bar_centres[1]), 0);
    assert!(bar_height(&chart.image, chart.bar_centres[2]) > 200);
    // Absurd sizes are clamped instead of overflowing.
    let huge = PictureConfig {
        bar_width: u32::MAX,
        bar_chart_height: u32::MAX,
        ..PictureConfig::default()
    };
    let chart = error_bars(&[0.1, 0.2], 0.15, &huge);
    // 2 bars of 256 px with margins of 2 bars; 4096 px of plot with the same margins.
    assert_eq!((chart.image.width(), chart.image.height()), (1664, 5120));
}

#[test]
fn residual_arrows_point_along_the_residuals() {
    let corners = vec![
        vec![Point2::new(100.0, 100.0), Point2::new(300.0, 100.0)],
        vec![Point2::new(100.0, 300.0)],
    ];
    let residuals = vec![
        vec![Vector2::new(1.0, 0.0), Vector2::new(0.0, -0.5)],
        vec![Vector2::new(-0.5, 0.5)],
    ];
    let cfg = PictureConfig {
        magnification: Some(60.0),
        ..PictureConfig::default()
    };
    let plot = residual_plot(400, 400, &corners, &residuals, &cfg);
    assert_eq!(plot.magnification, 60.0);
    // Half-way along each arrow (corner + residual × 30) the view's colour is drawn.
    assert_eq!(*plot.image.get_pixel(130, 100), PALETTE[0]);
    assert_eq!(*plot.image.get_pixel(300, 85), PALETTE[0]);
    assert_eq!(*plot.image.get_pixel(85, 315), PALETTE[1]);
    // Where no residual points the plot is white.
    assert_eq!(*plot.image.get_pixel(70, 100), Rgb([255, 255, 255]));
    assert_eq!(*plot.image.get_pixel(300, 130), Rgb([255, 255, 255]));
    // Automatic magnification: the 95th-percentile residual (index 1 of the sorted norms
    // 0.5, 0.71, 1: 0.71 px) to about 6 % of 400 px = 24 px: 34, rounded down to 20.
    let auto = residual_plot(400, 400, &corners, &residuals, &PictureConfig::default());
    assert_eq!(auto.magnification, 20.0);
    // The scale arrow: a round residual at most a fifth of the width (80 px / 20 = 4 px).
    assert_eq!(auto.scale_arrow_px, 2.0);
    assert_eq!(plot.scale_arrow_px, 1.0);
}

#[test]
fn absurd_residuals_are_clipped_not_fatal() {
    let corners = vec![vec![
        Point2::new(100.0, 100.0),
        Point2::new(200.0, 100.0),
        Point2::new(1e12, -1e12),
    ]];
    let residuals = vec![vec![
        Vector2::new(1e9, 0.0),
        Vector2::new(f64::NAN, 1.0),
        Vector2::new(1.0, 1.0),
    ]];
    let cfg = PictureConfig {
        magnification: Some(1e6),
        ..PictureConfig::default()
    };
    let plot = residual_plot(400, 300, &corners, &residuals, &cfg);
    // The first arrow runs to the right edge, clipped; nothing else is drawn on row 200.
    assert_eq!(*plot.image.get_pixel(390, 100), PALETTE[0]);
    assert_eq!(*plot.image.get_pixel(250, 200), Rgb([255, 255, 255]));
    // Corners far outside the image (a broken detection) are drawn as far as they show.
    let img = Frame::filled(100, 80, 128).unwrap();
    let wild = BoardCorners {
        size: BoardSize::new(2, 2),
        corners: vec![
            Point2::new(20.0, 20.0),
            Point2::new(1e12, 20.0),
            Point2::new(f64::NAN, 0.0),
            Point2::new(-1e15, 1e15),
        ],
    };
    let pic = draw_corners(&img, &wild);
    assert_eq!(*pic.get_pixel(20, 20), FIRST_CORNER);
    assert_eq!(*pic.get_pixel(60, 20), PALETTE[0]); // the clipped segment 0 → 1
}

#[test]
fn pictures_are_written_as_png() {
    let dir = tempfile::tempdir().unwrap();
    let chart = error_bars(&[0.1, 0.2], 0.15, &PictureConfig::default());
    let path = dir.path().join("bars.png");
    save_png(&chart.image, &path).unwrap();
    let back = image::open(&path).unwrap().to_rgb8();
    assert_eq!(back, chart.image);
    let err = save_png(&chart.image, dir.path().join("missing/dir/bars.png")).unwrap_err();
    assert!(err.to_string().contains("missing/dir/bars.png"), "{err}");
}

#[test]
fn corners_of_a_real_chessboard_picture() {
    let Ok(dir) = std::env::var("SL_DATA") else {
        eprintln!("SL_DATA not set: skipping the real chessboard picture");
        return;
    };
    let path = std::path::Path::new(&dir).join("chessboard/left01.jpg");
    let img = sl_calib::load_grey(&path).unwrap();
    let found = sl_calib::detect_checkerboard(
        &img,
        BoardSize::new(9, 6),
        &sl_calib::DetectorConfig::default(),
        "left01.jpg",
    )
    .unwrap();
    let pic = draw_corners(&img, &found);
    let first = found.corners[0];
    assert_eq!(
        *pic.get_pixel(first.x.round() as u32, first.y.round() as u32),
        FIRST_CORNER
    );
    // 54 corners, each circled in its row's colour: count pixels of the palette's first
    // colour; row 0 has 9 rings of at least 8 pixels each.
    let row0 = pic.pixels().filter(|p| **p == PALETTE[0]).count();
    assert!(row0 >= 9 * 8, "{row0} pixels of row 0's colour");
}
