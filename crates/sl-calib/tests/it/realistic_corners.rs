//! Corner accuracy on rendered boards that look like real captures (lens blur, vignetting,
//! gamma, sensor noise, perspective, the mean of three phase-shifted fringes), against the
//! renderer's exact truth (issue 15, item 4). The full table against OpenCV is
//! `examples/corner_harness.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test helpers: a failure is the test failing

use crate::support::board_render;

use board_render::{Fringes, RenderSpec, corner_errors, render, rms};
use sl_calib::{BoardSize, DetectorConfig, detect_checkerboard};

/// RMS corner error (px) of the detector with `config` on `spec`.
fn error_of(spec: &RenderSpec, config: &DetectorConfig) -> f64 {
    let board = render(spec);
    let found = detect_checkerboard(
        &board.image,
        BoardSize::new(spec.cols, spec.rows),
        config,
        "render",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    rms(&corner_errors(&found.corners, &board.corners))
}

/// A defocused (σ = 2 px), vignetted, gamma-encoded, noisy board of 30 px squares, tilted.
fn defocused() -> RenderSpec {
    RenderSpec {
        blur_sigma: 2.0,
        vignetting: 0.3,
        gamma: 2.2,
        noise: 2.0,
        rotation_deg: 12.0,
        tilt_x_deg: 18.0,
        tilt_y_deg: -8.0,
        seed: 7,
        ..RenderSpec::new(800, 600, 30.0)
    }
}

#[test]
fn junction_fit_beats_saddle_points_on_a_defocused_board() {
    let spec = defocused();
    let with = error_of(&spec, &DetectorConfig::with_junction_fit());
    let without = error_of(
        &spec,
        &DetectorConfig {
            junction_fraction: 0.0,
            ..DetectorConfig::with_junction_fit()
        },
    );
    eprintln!("defocused: RMS {with:.4} px with the junction fit, {without:.4} px without");
    // Measured 0.013–0.02 px for such boards (see docs/performance.md); OpenCV's cornerSubPix
    // gives 0.03–0.04 px on them. 0.03 px fails if the junction fit regresses to OpenCV's level.
    assert!(with < 0.03, "{with}");
    assert!(with < without, "{with} vs {without}");
}

#[test]
fn board_lit_by_the_mean_of_three_fringes() {
    let spec = RenderSpec {
        fringes: Some(Fringes {
            period_px: 21.0,
            angle_deg: 4.0,
            ripple: 0.04,
        }),
        blur_sigma: 1.5,
        noise: 3.0,
        ..defocused()
    };
    let e = error_of(&spec, &DetectorConfig::with_junction_fit());
    eprintln!("fringe mean: RMS {e:.4} px");
    // Measured ~0.04 px on such images (OpenCV: 0.08 px): the ripple of the fringe mean is
    // the largest error left; 0.06 px fails if the refiner stops absorbing the uneven light.
    assert!(e < 0.06, "{e}");
}

#[test]
fn large_defocused_image_is_found_through_the_pyramid() {
    // σ = 3 px on 50 px squares: at full resolution the ring test misses corners; half
    // resolution finds the grid, the refinement runs at full resolution.
    let spec = RenderSpec {
        blur_sigma: 3.0,
        noise: 4.0,
        ..RenderSpec::new(1000, 760, 50.0)
    };
    let spec = RenderSpec {
        cols: 9,
        rows: 6,
        ..spec
    };
    let e = error_of(&spec, &DetectorConfig::with_junction_fit());
    eprintln!("defocus 3: RMS {e:.4} px");
    assert!(e < 0.06, "{e}");
}

#[test]
fn grid_point_on_an_edge_is_recovered_from_its_neighbours() {
    // The harness's 5 MP board under a fringe mean with 16 % ripple, first image: the
    // detection puts corner 4's grid point 33 px down an edge, where the ripple crosses it;
    // no saddle point there. Without the retry from the neighbours the board is not found
    // (OpenCV finds it).
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(0xC0FFEE + 13);
    let t = 20.0;
    let spec = RenderSpec {
        rotation_deg: rng.random_range(-20.0..20.0),
        tilt_x_deg: rng.random_range(-t..t),
        tilt_y_deg: rng.random_range(-t..t) * 0.5,
        offset: (
            rng.random_range(-0.03..0.03) * 2592.0,
            rng.random_range(-0.03..0.03) * 1944.0,
        ),
        seed: rng.random(),
        fringes: Some(Fringes {
            period_px: 36.0,
            angle_deg: 4.0,
            ripple: 0.16,
        }),
        blur_sigma: 2.0,
        vignetting: 0.4,
        gamma: 2.2,
        noise: 3.0,
        ..RenderSpec::new(2592, 1944, 120.0)
    };
    let e = error_of(&spec, &DetectorConfig::with_junction_fit());
    eprintln!("16 % ripple, 5 MP: RMS {e:.4} px");
    // Measured 0.13 px (OpenCV 0.25 px on the same condition): the ripple's bias dominates.
    assert!(e < 0.2, "{e}");
}
