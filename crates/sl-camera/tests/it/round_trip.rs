//! Round trips project ↔ unproject over whole images, and their laws as properties.

// Test helpers outside #[test] functions may unwrap too: a panic is a failed test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{Point2, Point3};
use proptest::prelude::*;
use sl_camera::{CameraModel, Distortion, DistortionModel, ImageSize, Intrinsics};

/// The lenses of the round-trip tests: the strong reference design, a mild webcam, a
/// rational wide-angle lens, a projector with an off-centre principal point and skew, and a
/// pinhole.
fn lenses() -> Vec<(&'static str, CameraModel)> {
    let cam = |k: Intrinsics, d: &[f64], w, h| {
        CameraModel::new(k, Distortion::from_opencv(d).unwrap(), ImageSize::new(w, h)).unwrap()
    };
    vec![
        (
            "reference_strong",
            cam(
                Intrinsics::new(1440.4, 1437.1, 667.8, 354.2),
                &[0.5466, -20.20, -0.02203, 0.008259, 211.1],
                1280,
                720,
            ),
        ),
        (
            "webcam_mild",
            cam(
                Intrinsics::new(905.3, 903.9, 641.2, 362.7),
                &[-0.283, 0.0912, 0.00081, -0.00043, -0.0121],
                1280,
                720,
            ),
        ),
        (
            "rational_wide",
            cam(
                Intrinsics::new(602.1, 601.4, 644.6, 478.3),
                &[2.31, 0.87, 0.00061, -0.00032, 0.029, 2.68, 1.47, 0.19],
                1280,
                960,
            ),
        ),
        (
            "projector_skew",
            cam(
                Intrinsics {
                    fx: 2210.0,
                    fy: 2208.5,
                    cx: 955.0,
                    cy: 1102.0,
                    skew: 4.2,
                },
                &[0.041, -0.162, 0.0006, -0.0011, 0.21],
                1920,
                1080,
            ),
        ),
        (
            "pinhole",
            cam(Intrinsics::new(700.0, 690.0, 399.5, 299.5), &[], 800, 600),
        ),
    ]
}

/// Round-trip target from the task: 1e-9 px. Newton converges to a few ulps of the
/// normalised point, i.e. ~1e-12 px; this bound is three orders looser yet would catch any
/// non-converged or wrong-branch answer.
const ROUND_TRIP_PX: f64 = 1e-9;

/// Every pixel of a decimated grid — every 4th column and row plus the last column and row,
/// so borders and the four corners (at the pixel-centre convention's extreme edges −0.5 and
/// size − 0.5 too) are included — unprojects and projects back to itself.
#[test]
fn dense_grid_round_trip_over_the_whole_image() {
    for (name, cam) in lenses() {
        let (w, h) = (cam.size.width, cam.size.height);
        let mut xs: Vec<f64> = (0..w).step_by(4).map(f64::from).collect();
        xs.extend([f64::from(w - 1), -0.5, f64::from(w) - 0.5]);
        let mut ys: Vec<f64> = (0..h).step_by(4).map(f64::from).collect();
        ys.extend([f64::from(h - 1), -0.5, f64::from(h) - 0.5]);
        let mut worst: f64 = 0.0;
        for &y in &ys {
            for &x in &xs {
                let px = Point2::new(x, y);
                let ray = cam
                    .unproject(&px)
                    .unwrap_or_else(|| panic!("{name}: pixel ({x}, {y}) refused"));
                let back = cam
                    .project(&Point3::from(ray * 700.0))
                    .unwrap_or_else(|| panic!("{name}: ray of ({x}, {y}) does not project"));
                let err = (back - px).norm();
                assert!(
                    err < ROUND_TRIP_PX,
                    "{name}: ({x}, {y}) -> {back:?}, error {err:e}"
                );
                worst = worst.max(err);
            }
        }
        eprintln!(
            "{name}: {} pixels, worst round trip {worst:.2e} px",
            xs.len() * ys.len()
        );
    }
}

/// The ray table holds the same rays as pixel-by-pixel unprojection, for every pixel.
#[test]
fn ray_table_matches_unproject_for_the_reference_lens() {
    let (_, cam) = lenses().remove(0);
    let table = cam.ray_table();
    assert_eq!(table.valid_count(), cam.size.pixel_count());
    for y in (0..cam.size.height).step_by(7) {
        for x in (0..cam.size.width).step_by(3) {
            let a = table.get(x, y).unwrap();
            let b = cam
                .unproject(&Point2::new(f64::from(x), f64::from(y)))
                .unwrap();
            // Same root from two Newton starts: equal to a few ulps.
            assert!((a - b).norm() < 1e-14, "({x}, {y}): {a:?} vs {b:?}");
        }
    }
}

/// A lens whose radial distortion folds inside the image (strong barrel, k1 = −0.6 with a
/// wide field): pixels beyond the fold are refused and everything accepted is exact.
#[test]
fn folding_lens_refuses_instead_of_lying() {
    let cam = CameraModel::new(
        Intrinsics::new(400.0, 400.0, 639.5, 479.5),
        Distortion::from_opencv(&[-0.6, 0.0, 0.0, 0.0, 0.0]).unwrap(),
        ImageSize::new(1280, 960),
    )
    .unwrap();
    // r(1 − 0.6 r²) folds at r² = 1/1.8, distorted radius 0.4969 → 198.8 px from centre.
    let r_max = (1.0_f64 / 1.8).sqrt();
    assert!((cam.distortion.max_radius() - r_max).abs() < 1e-12);
    let rd_max = r_max * (1.0 - 0.6 * r_max * r_max) * 400.0;
    let mut refused = 0;
    let table = cam.ray_table();
    for y in (0..960).step_by(8) {
        for x in (0..1280).step_by(8) {
            let px = Point2::new(f64::from(x), f64::from(y));
            let d = ((px.x - 639.5).powi(2) + (px.y - 479.5).powi(2)).sqrt();
            match cam.unproject(&px) {
                Some(ray) => {
                    let back = cam.project(&Point3::from(ray)).unwrap();
                    assert!((back - px).norm() < ROUND_TRIP_PX);
                    assert!(d < rd_max + 1e-6, "accepted beyond the fold at {d} px");
                }
                None => {
                    refused += 1;
                    assert!(d > rd_max - 1e-6, "refused inside the fold at {d} px");
                }
            }
            assert_eq!(table.get(x, y).is_some(), cam.unproject(&px).is_some());
        }
    }
    assert!(refused > 0);
    // Points beyond the fold do not project either.
    assert!(cam.project(&Point3::new(1.2 * r_max, 0.0, 1.0)).is_none());
}

fn lens_strategy() -> impl Strategy<Value = CameraModel> {
    (0..lenses().len()).prop_map(|i| lenses().swap_remove(i).1)
}

proptest! {
    // No failure persistence: integration tests have no lib.rs next to them to anchor the
    // regression file; a failure prints its minimal case, which is what we need.
    #![proptest_config(ProptestConfig {
        cases: 512,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// unproject(project(p)) has the direction of p, for points whose pixel is on (or near)
    /// the image.
    #[test]
    fn unproject_of_project_is_the_direction(
        cam in lens_strategy(),
        u in -0.1f64..1.1,
        v in -0.1f64..1.1,
        depth in 50.0f64..5000.0,
    ) {
        // Pick the point through a pixel so that it lies in the field of view, then check the
        // law from the 3-D side.
        let px = Point2::new(u * f64::from(cam.size.width), v * f64::from(cam.size.height));
        let ray = cam.unproject(&px);
        prop_assume!(ray.is_some());
        let p = Point3::from(ray.unwrap() * depth);
        let back = cam.unproject(&cam.project(&p).unwrap()).unwrap();
        let dir = p.coords.normalize();
        // Unit directions agree to ~1e-15; 1e-12 leaves room for rounding at large angles.
        prop_assert!((back.normalize() - dir).norm() < 1e-12);
        prop_assert_eq!(back.z, 1.0);
    }

    /// For any lens (coefficients far beyond realistic ones, rational model, tangential terms
    /// up to 0.05), undistortion never returns a wrong preimage: whatever it returns distorts
    /// back to the input, and for a point of the valid region it is that very point (the
    /// valid region is a disc on which the map is one-to-one). Pixels whose preimage is
    /// ambiguous or missing yield `None`, never a guess.
    #[test]
    fn random_lenses_never_return_a_wrong_preimage(
        radial in proptest::array::uniform6(-1.0f64..1.0),
        p1 in -0.05f64..0.05,
        p2 in -0.05f64..0.05,
        fraction in 0.0f64..1.0,
        angle in 0.0f64..std::f64::consts::TAU,
        far_x in -20.0f64..20.0,
        far_y in -20.0f64..20.0,
    ) {
        let [k1, k2, k3, k4, k5, k6] = radial;
        let d = Distortion::new(DistortionModel::Rational, [k1, k2, p1, p2, k3, k4, k5, k6]).unwrap();
        let r = fraction * d.max_radius().min(3.0);
        let p = Point2::new(r * angle.cos(), r * angle.sin());
        prop_assert!(d.is_valid_at(&p));
        if let Some(q) = d.undistort(&d.distort(&p)) {
            // Same point to ~1e-12 (Newton stops at rounding level of the distorted point).
            prop_assert!((q - p).norm() <= 1e-9 * (1.0 + r), "{p:?} came back as {q:?}");
        }
        // Any distorted point, even far outside: an answer must be exact and valid.
        let pd = Point2::new(far_x, far_y);
        if let Some(q) = d.undistort(&pd) {
            prop_assert!(d.is_valid_at(&q));
            prop_assert!((d.distort(&q) - pd).norm() <= 1e-12 * (1.0 + pd.coords.norm()));
        }
    }

    /// project(unproject(px)) == px over the image and a margin around it.
    #[test]
    fn project_of_unproject_is_the_pixel(
        cam in lens_strategy(),
        u in -0.05f64..1.05,
        v in -0.05f64..1.05,
    ) {
        let px = Point2::new(u * f64::from(cam.size.width) - 0.5, v * f64::from(cam.size.height) - 0.5);
        if let Some(ray) = cam.unproject(&px) {
            let back = cam.project(&Point3::from(ray)).unwrap();
            prop_assert!((back - px).norm() < ROUND_TRIP_PX);
        }
    }

    /// Whatever is projected unprojects back exactly (also far outside the image, as long as
    /// projection accepted the point).
    #[test]
    fn accepted_projections_invert(
        cam in lens_strategy(),
        x in -3.0f64..3.0,
        y in -3.0f64..3.0,
    ) {
        let p = Point3::new(x, y, 1.0);
        if let Some(px) = cam.project(&p) {
            let ray = cam.unproject(&px);
            prop_assert!(ray.is_some(), "projection accepted {p:?} but unprojection refused {px:?}");
            let ray = ray.unwrap();
            let scale = px.coords.norm().max(1.0);
            // Far from the image a pixel step is a tiny angle: compare in pixels, relative.
            let back = cam.project(&Point3::from(ray)).unwrap();
            prop_assert!((back - px).norm() <= 1e-9 * scale);
        }
    }
}
