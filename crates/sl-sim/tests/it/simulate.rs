//! A simulated turntable scan written to disk, decoded by `sl-codec`, and compared with the
//! ground truth written beside it.

use sl_camera::ImageSize;
use sl_codec::{Axis, CaptureSet, DecodeConfig, GrayCodeSpec, Pattern, PatternSequence, decode};
use sl_sim::{RigConfig, Scene, VirtualRig, simulate_scan};

/// The default rig with both images scaled down by 4 (same fields of view).
fn small_rig() -> RigConfig {
    RigConfig::default().downscaled(4)
}

#[test]
fn simulated_gray_code_scan_decodes_to_the_truth() {
    let mut config = small_rig();
    // A per-pixel Gray code puts ~1.5 projector stripes on a camera pixel here: only a lens
    // sharper than any real one (none) and no scattered light resolve its finest bit
    // everywhere, which is what this test of the files needs. (Real rigs code with wider
    // stripes; see the hybrid codes.)
    config.render.effects.lens_blur_px = 0.0;
    config.render.effects.global_illumination = None;
    // ... and no sensor pedestal: the Gray decoder counts a camera's black level as global
    // light (Lg = 2 Lmin), and at 1.5 stripes a pixel the finest bit's contrast is too small
    // for the weak rules' margin (93.6 % of the pixels decode with the default 5 grey levels).
    config.render.effects.sensor.dark_level_dn = 0.0;
    let p = ImageSize::new(config.projector.size.width, config.projector.size.height);
    let sequence = PatternSequence::new(p)
        .with(Pattern::Gray(GrayCodeSpec::per_pixel(
            Axis::Column,
            p,
            false,
        )))
        .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Row, p, false)));
    let manifest = sequence.manifest(sl_codec::BitDepth::Eight);
    let rig = VirtualRig::new(config, Scene::sphere()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut seen = 0;
    let done = simulate_scan(&rig, &manifest, &[0.0, 90.0], dir.path(), |_| seen += 1).unwrap();
    assert_eq!((done.len(), seen), (2, 2));

    for (k, c) in done.iter().enumerate() {
        for f in [
            "manifest.json",
            "000.png",
            "truth/col.tiff",
            "truth/depth.tiff",
            "truth/view.json",
            "truth/lit.png",
        ] {
            assert!(c.dir.join(f).exists(), "view {k}: {f} missing");
        }
        // Decode what was written, and compare with the view's truth (re-cast: same rig,
        // same angle, so the same truth).
        let capture = CaptureSet::load(&c.dir.join("manifest.json")).unwrap();
        let map = decode(&capture, &DecodeConfig::default()).unwrap();
        let truth = rig.view(c.motor_angle_deg, k as u64).unwrap().truth;
        let (mut good, mut decoded, mut lit) = (0usize, 0usize, 0usize);
        for i in 0..truth.object.len() {
            // Pixels whose 3x3 neighbourhood is fully lit: no shadow or silhouette edge mixes
            // two surfaces into one pixel.
            let (x, y) = (i % truth.width as usize, i / truth.width as usize);
            if x == 0 || y == 0 || x + 1 >= truth.width as usize || y + 1 >= truth.height as usize {
                continue;
            }
            let w = truth.width as usize;
            if ![
                i - w - 1,
                i - w,
                i - w + 1,
                i - 1,
                i,
                i + 1,
                i + w - 1,
                i + w,
                i + w + 1,
            ]
            .iter()
            .all(|&j| truth.lit(j))
            {
                continue;
            }
            lit += 1;
            let (col, row) = (map.col[i], map.row[i]);
            if !(col.is_finite() && row.is_finite()) {
                continue;
            }
            decoded += 1;
            // A Gray code decodes the projector pixel whose square holds the point: within
            // half a pixel of the exact coordinate, plus the pixel's footprint on the projector
            // (the camera pixel covers ~1.5 projector pixels here), so within 1.5 px.
            let t = truth.projector[i];
            if (f64::from(col) - t.x).abs() <= 1.5 && (f64::from(row) - t.y).abs() <= 1.5 {
                good += 1;
            }
        }
        assert!(lit > 3000, "view {k}: {lit} lit pixels");
        assert!(
            decoded as f64 > 0.95 * lit as f64,
            "view {k}: decoded {decoded} of {lit}"
        );
        assert!(
            good as f64 > 0.99 * decoded as f64,
            "view {k}: {good} of {decoded} within 1.5 px"
        );
    }
}
