//! End-to-end tests of the virtual rig against closed forms.

// Test helpers (not `#[test]` functions) unwrap too: a failure there is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use approx::assert_relative_eq;
use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use sl_camera::{CameraModel, ImageSize};
use sl_rig::capture_sequence;
use sl_sim::{
    Camera, GreyImage, NO_OBJECT, Projector, ProjectorSampling, RigConfig, Scene, SceneObject,
    SensorConfig, Shape, Texture, Turntable, VirtualRig,
};

/// The default rig with both images scaled down by 4 (same fields of view, same distortion),
/// so that the tests run in a fraction of a second.
fn small_rig() -> RigConfig {
    RigConfig::default().downscaled(4)
}

fn plane_scene(t_cam_plane: Isometry3<f64>) -> Scene {
    Scene::new().with(SceneObject::in_camera(
        "plane",
        Shape::rectangle(2000.0, 2000.0),
        Texture::Uniform(0.5),
        t_cam_plane,
    ))
}

#[test]
fn plane_projector_coordinates_match_the_closed_form() {
    // The full-size default rig (distorted camera and projector), a plane tilted 20° about y.
    let config = RigConfig::default();
    let t_cam_plane = Isometry3::from_parts(
        Translation3::new(10.0, -20.0, 470.0),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.35)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -0.2),
    );
    let rig = VirtualRig::new(
        RigConfig {
            render: sl_sim::RenderConfig {
                supersampling: 1,
                ..config.render
            },
            ..config.clone()
        },
        plane_scene(t_cam_plane),
    )
    .unwrap();
    let view = rig.view(0.0, 0).unwrap();
    let t = &view.truth;
    let n = t_cam_plane.rotation * Vector3::z();
    let p0 = t_cam_plane.translation.vector;
    let t_proj_cam = config.t_cam_proj.inverse();
    let mut checked = 0;
    for y in (0..t.height).step_by(7) {
        for x in (0..t.width).step_by(7) {
            let i = (y * t.width + x) as usize;
            // Closed form: the camera ray (sl-camera's unprojection) meets the plane n·p = n·p0
            // at s = n·p0 / n·d; the projector pixel is sl-camera's projection of that point
            // in the projector frame.
            let d = config
                .camera
                .unproject(&Point2::new(f64::from(x), f64::from(y)))
                .unwrap();
            let s = n.dot(&p0) / n.dot(&d);
            let p = Point3::from(d * s);
            assert_relative_eq!(t.depth_mm[i], p.z, max_relative = 1e-12);
            let q = config.projector.project(&(t_proj_cam * p));
            match q.filter(|q| config.projector.size.contains(q.x, q.y)) {
                Some(q) => {
                    // Both sides are f64 evaluations of the same model through different
                    // intersection formulas: a few ulps of 1000 px, far below 1e-6 px.
                    assert!(t.lit(i), "pixel ({x}, {y}) should be lit");
                    assert!(
                        (t.projector[i] - q).norm() < 1e-6,
                        "pixel ({x}, {y}): {} vs {q}",
                        t.projector[i]
                    );
                    checked += 1;
                }
                None => assert!(!t.lit(i)),
            }
        }
    }
    assert!(checked > 10_000, "only {checked} lit pixels checked");
}

#[test]
fn sphere_depth_matches_ray_sphere_intersection() {
    let config = small_rig();
    let rig = VirtualRig::new(config.clone(), Scene::sphere()).unwrap();
    let angle = 37.0;
    let view = rig.view(angle, 0).unwrap();
    let t = &view.truth;
    // The sphere stands on the table: centre 50 mm up the axis.
    let c = config.t_cam_table_at(angle) * Point3::new(0.0, 0.0, 50.0);
    let r = 50.0;
    let mut hits = 0;
    for y in 0..t.height {
        for x in 0..t.width {
            let i = (y * t.width + x) as usize;
            let d = config
                .camera
                .unproject(&Point2::new(f64::from(x), f64::from(y)))
                .unwrap()
                .normalize();
            // |s d - c|² = r²  →  s = d·c − sqrt((d·c)² − |c|² + r²)
            let b = d.dot(&c.coords);
            let disc = b * b - c.coords.norm_squared() + r * r;
            if disc > 1e-6 {
                let s = b - disc.sqrt();
                // parry solves the same quadratic: agreement to ~1e-12 relative.
                assert_relative_eq!(t.depth_mm[i], s * d.z, max_relative = 1e-9);
                hits += 1;
            } else if disc < -1e-6 {
                assert_eq!(t.object[i], NO_OBJECT);
                assert!(t.depth_mm[i].is_nan());
            }
        }
    }
    // A 50 mm sphere at ~450 mm with fx = 360 px: a disc of radius ~40 px, ~5000 pixels.
    assert!(hits > 4_000, "{hits} hits");
}

#[test]
fn shadows_fall_where_the_projector_cannot_see() {
    // A wall at 500 mm and a 40 mm square occluder 100 mm in front of it, between the wall
    // and the projector (which sits at x = +200). Without the scattered light of the
    // default renders (`CameraEffects::DEFAULT_SCATTER`), which lights shadows by design:
    // here the shadow must hold the ambient light and the sensor's dark level alone.
    let mut config = small_rig();
    config.render.effects.global_illumination = None;
    let wall = Isometry3::translation(0.0, 0.0, 500.0);
    let occluder = Isometry3::translation(40.0, 0.0, 400.0);
    let scene = Scene::new()
        .with(SceneObject::in_camera(
            "wall",
            Shape::rectangle(1000.0, 1000.0),
            Texture::Uniform(0.6),
            wall,
        ))
        .with(SceneObject::in_camera(
            "occluder",
            Shape::rectangle(40.0, 40.0),
            Texture::Uniform(0.6),
            occluder,
        ));
    let rig = VirtualRig::new(config.clone(), scene).unwrap();
    let view = rig.view(0.0, 0).unwrap();
    let t = &view.truth;
    let centre = Point3::from(config.t_cam_proj.translation.vector);
    let (mut shadowed, mut lit) = (0, 0);
    for i in 0..t.object.len() {
        if t.object[i] != 0 {
            continue;
        }
        let p = t.points_cam[i];
        // Closed form: the segment from p to the projector centre crosses z = 400 at
        // s = (500 - 400) / (500 - z_proj); the occluder covers |x - 40| <= 20, |y| <= 20 there.
        let s = (p.z - 400.0) / (p.z - centre.z);
        let q = p + (centre - p) * s;
        let in_shadow = (q.x - 40.0).abs() <= 20.0 && q.y.abs() <= 20.0;
        let q_proj = config
            .projector
            .project(&config.t_cam_proj.inverse_transform_point(&p));
        let in_projector = q_proj.is_some_and(|q| config.projector.size.contains(q.x, q.y));
        // Pixels within 1e-6 mm of the shadow's edge could go either way.
        let edge = ((q.x - 40.0).abs() - 20.0).abs() < 1e-6 || (q.y.abs() - 20.0).abs() < 1e-6;
        if edge || !in_projector {
            continue;
        }
        assert_eq!(t.lit(i), !in_shadow, "pixel {i}");
        if in_shadow { shadowed += 1 } else { lit += 1 }
    }
    assert!(
        shadowed > 100 && lit > 1000,
        "shadowed {shadowed}, lit {lit}"
    );

    // In the rendered frame under full white, the shadow is only as bright as the ambient
    // light: mean over shadow pixels ≈ exposure · full_well · albedo · ambient · g + dark level.
    let white = filled(config.projector.size, 255);
    let frame = view.capture(&white, 0).unwrap();
    let GreyImage::U8(px) = &frame else {
        panic!("8-bit expected")
    };
    let px = px.data();
    let s = config.render.effects.sensor;
    let g = 255.0 / s.full_well_electrons;
    let want = s.exposure * s.full_well_electrons * 0.6 * config.render.illumination.ambient * g
        + s.dark_level_dn;
    let (mut sum, mut n) = (0.0, 0.0);
    for y in 1..t.height - 1 {
        for x in 1..t.width - 1 {
            // Pixels whose 3x3 neighbourhood is all shadow, so that anti-aliasing does not mix in lit samples.
            let all_shadow = (y - 1..=y + 1).all(|yy| {
                (x - 1..=x + 1).all(|xx| {
                    let j = (yy * t.width + xx) as usize;
                    t.object[j] == 0 && !t.lit(j)
                })
            });
            if all_shadow {
                sum += f64::from(px[(y * t.width + x) as usize]);
                n += 1.0;
            }
        }
    }
    assert!(n > 50.0);
    // Noise ≈ 0.5 DN per pixel: the mean of > 50 pixels is within 0.5 DN (with rounding bias).
    assert!(
        (sum / n - want).abs() < 0.5,
        "shadow mean {} vs {want}",
        sum / n
    );
}

#[test]
fn white_frame_radiance_matches_lambert() {
    // A plane facing the camera, gamma 2.2, no noise, 16 bits: every fully lit pixel has
    // DN = exposure · 65535 · albedo · (ambient + power · (black + (1 − black) · v^γ) · cos).
    let mut config = small_rig();
    config.render.illumination.gamma = 2.2;
    // Touching projector pixels: with gaps (the default fill) a uniform image carries the
    // pixel grid's faint screen-door ripple, which this closed form leaves out.
    config.render.illumination.projector_fill = 1.0;
    // The direct image's closed form, pixel by pixel: no lens spread.
    config.render.effects.lens_blur_px = 0.0;
    config.render.effects.sensor = SensorConfig {
        photon_noise: false,
        read_noise_electrons: 0.0,
        bit_depth: sl_sim::BitDepth::Sixteen,
        dark_level_dn: 0.0,
        ..SensorConfig::default()
    };
    // Direct light only: no scatter.
    config.render.effects.global_illumination = None;
    let rig = VirtualRig::new(
        config.clone(),
        plane_scene(Isometry3::translation(0.0, 0.0, 450.0)),
    )
    .unwrap();
    let view = rig.view(0.0, 0).unwrap();
    let t = &view.truth;
    let (w, h) = (config.projector.size.width, config.projector.size.height);
    let v = 128u8;
    let frame = view
        .capture(&filled(sl_camera::ImageSize::new(w, h), v), 0)
        .unwrap();
    let GreyImage::U16(px) = &frame else {
        panic!("16-bit expected")
    };
    let px = px.data();
    let il = config.render.illumination;
    let s = config.render.effects.sensor;
    let centre = Point3::from(config.t_cam_proj.translation.vector);
    let mut checked = 0;
    for y in 2..t.height - 2 {
        for x in 2..t.width - 2 {
            let i = (y * t.width + x) as usize;
            let all_lit = (y - 1..=y + 1)
                .all(|yy| (x - 1..=x + 1).all(|xx| t.lit((yy * t.width + xx) as usize)));
            if !all_lit {
                continue;
            }
            let p = t.points_cam[i];
            let cos = (centre - p).normalize().dot(&-Vector3::z());
            let out =
                il.black_level + (1.0 - il.black_level) * (f64::from(v) / 255.0).powf(il.gamma);
            let radiance = 0.5 * (il.ambient + il.projector_power * out * cos);
            let want = s.exposure * 65535.0 * radiance;
            // The 2x2 sub-samples see cos varying by ~1e-4 across a pixel (a second-order
            // effect on the average) and the radiance is stored as f32: 1 DN + rounding.
            assert!(
                (f64::from(px[i]) - want).abs() <= 1.5,
                "pixel ({x}, {y}): {} vs {want}",
                px[i]
            );
            checked += 1;
        }
    }
    assert!(checked > 1000);
}

#[test]
fn image_and_function_paths_agree_and_devices_match_views() {
    let config = small_rig();
    let rig = VirtualRig::new(config.clone(), Scene::cylinder()).unwrap();
    let (w, h) = (config.projector.size.width, config.projector.size.height);
    // Vertical stripes 8 projector pixels wide.
    let stripes = |x: f64, _y: f64| {
        if (x / 8.0).floor().rem_euclid(2.0) < 0.5 {
            1.0
        } else {
            0.0
        }
    };
    let img = GreyImage::U8(
        sl_codec::Frame::new(
            w as usize,
            h as usize,
            (0..w * h)
                .map(|i| (stripes(f64::from(i % w), 0.0) * 255.0) as u8)
                .collect(),
        )
        .unwrap(),
    );
    let view = rig.view(30.0, 3).unwrap();
    let a = view.capture(&img, 5).unwrap();
    let b = view
        .capture_fn(stripes, ProjectorSampling::Nearest, 5)
        .unwrap();
    assert_eq!(a, b);

    // Through the device traits: turn the table, show the images, capture.
    let (mut cam, mut proj, mut table) = rig.devices();
    assert_eq!(table.rotate_to(30.0).unwrap(), 30.0);
    let black = filled(config.projector.size, 0);
    let frames = capture_sequence(&mut cam, &mut proj, &[black.clone(), img.clone()]).unwrap();
    assert_eq!(frames.len(), 2);
    assert_eq!(
        cam.frame_size(),
        (config.camera.size.width, config.camera.size.height)
    );
    // The devices number views from 0 and frames from 0 within a view.
    let direct = rig
        .view(30.0, 0)
        .unwrap()
        .capture_all(&[black, img])
        .unwrap();
    assert_eq!(frames, direct);
    // A wrong-size image is refused, naming the image.
    let err = proj
        .show(&filled(sl_camera::ImageSize::new(10, 10), 0))
        .unwrap_err();
    assert!(err.to_string().contains("projector image"), "{err}");
}

#[test]
fn camera_model_literals_are_consistent() {
    // The default rig's optical axes cross at the working distance: the camera's principal
    // ray and the projector's meet at (0, 0, 450).
    let c = RigConfig::default();
    let aim = Point3::new(0.0, 0.0, sl_sim::DEFAULT_WORKING_DISTANCE_MM);
    let p_proj = c.t_cam_proj.inverse_transform_point(&aim);
    assert_relative_eq!(p_proj.x, 0.0, epsilon = 1e-9);
    assert_relative_eq!(p_proj.y, 0.0, epsilon = 1e-9);
    // And the turntable axis passes through it.
    let axis = c.turntable_axis();
    let off = (aim - axis.point_mm).cross(&axis.direction).norm();
    assert_relative_eq!(off, 0.0, epsilon = 1e-9);
    let _: &CameraModel = &c.camera;
}

#[test]
fn board_texture_matches_the_printed_squares() {
    // A board facing the camera at 450 mm, full white, no noise, 16 bits: away from the
    // square edges, each pixel has the closed-form value of its square's albedo.
    let mut config = small_rig();
    config.render.supersampling = 4;
    // Touching projector pixels (no screen-door ripple, as in the test above).
    config.render.illumination.projector_fill = 1.0;
    // The direct image's closed form, pixel by pixel: no lens spread.
    config.render.effects.lens_blur_px = 0.0;
    config.render.effects.sensor = SensorConfig {
        photon_noise: false,
        read_noise_electrons: 0.0,
        bit_depth: sl_sim::BitDepth::Sixteen,
        dark_level_dn: 0.0,
        ..SensorConfig::default()
    };
    // Direct light only: no scatter.
    config.render.effects.global_illumination = None;
    let board = sl_sim::Checkerboard::default();
    let t_cam_board = Isometry3::translation(-80.0, -50.0, 450.0);
    let rig = VirtualRig::new(config.clone(), Scene::plane()).unwrap();
    let cap = sl_sim::capture_board(&rig, &board, &t_cam_board, None, 0).unwrap();
    assert!(cap.frames.is_empty());
    let GreyImage::U16(px) = &cap.white else {
        panic!("16-bit expected")
    };
    let px = px.data();
    let t = &cap.view.truth;
    let il = config.render.illumination;
    let s = config.render.effects.sensor;
    let centre = Point3::from(config.t_cam_proj.translation.vector);
    let (mut dark, mut light) = (0, 0);
    for (i, &value) in px.iter().enumerate() {
        if !t.lit(i) {
            continue;
        }
        let p = t.points_cam[i];
        let b = t_cam_board.inverse_transform_point(&p);
        // One camera pixel is ~1.25 mm here: keep pixels 2 mm from every grid line.
        let off =
            |v: f64| (v / board.square_mm - (v / board.square_mm).round()).abs() * board.square_mm;
        if off(b.x) < 2.0 || off(b.y) < 2.0 {
            continue;
        }
        let albedo = board.albedo_at(b.x, b.y);
        let cos = (centre - p).normalize().dot(&-Vector3::z());
        let want = s.exposure * 65535.0 * albedo * (il.ambient + il.projector_output(1.0) * cos);
        assert!(
            (f64::from(value) - want).abs() <= 2.0,
            "pixel {i}: {value} vs {want}"
        );
        if albedo < 0.5 { dark += 1 } else { light += 1 }
    }
    assert!(dark > 1000 && light > 1000, "dark {dark}, light {light}");
    // The first square (top-left of the grid) is black: the pixel 10 mm up-left of corner 0.
    let c0 = cap.board.corners_px[0].unwrap();
    let q = config
        .camera
        .project(&(t_cam_board * Point3::new(-10.0, -10.0, 0.0)))
        .unwrap();
    assert!(q.x < c0.x && q.y < c0.y);
    let i = (q.y.round() as u32 * t.width + q.x.round() as u32) as usize;
    assert!(f64::from(px[i]) < 0.2 * s.exposure * 65535.0);
}

#[test]
fn frames_do_not_depend_on_the_number_of_threads() {
    let config = small_rig();
    let rig = VirtualRig::new(config.clone(), Scene::dumbbell()).unwrap();
    let img = filled(config.projector.size, 200);
    let many = rig.view(10.0, 1).unwrap().capture(&img, 7).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let one = pool.install(|| rig.view(10.0, 1).unwrap().capture(&img, 7).unwrap());
    assert_eq!(many, one);
}

/// Column error (projector px) of noise-free 8-step fringes (30 px period) rendered on the
/// default plane by the reduced rig with a projector blur of `blur_px`, decoded by the
/// least-squares phase formula (written out here, independent of sl-codec) and compared with
/// the truth's projector column: RMS and largest error over pixels whose 3×3 neighbourhood
/// sees the lit plane (no mixed pixels at its border).
fn fringe_column_error(blur_px: f64) -> (f64, f64) {
    let mut config = small_rig();
    config.render.illumination.projector_blur_px = blur_px;
    // The projector's blur alone: touching pixels and a sharp camera lens (both also damp
    // the grid's harmonics).
    config.render.illumination.projector_fill = 1.0;
    config.render.effects.lens_blur_px = 0.0;
    config.render.effects.sensor = SensorConfig {
        photon_noise: false,
        read_noise_electrons: 0.0,
        bit_depth: sl_sim::BitDepth::Sixteen,
        dark_level_dn: 0.0,
        ..SensorConfig::default()
    };
    // Direct light only: no scatter.
    config.render.effects.global_illumination = None;
    let rig = VirtualRig::new(config, Scene::plane()).unwrap();
    let view = rig.view(0.0, 0).unwrap();
    let (lambda, steps) = (30.0f64, 8usize);
    let tau = std::f64::consts::TAU;
    let frames: Vec<Vec<f64>> = (0..steps)
        .map(|k| {
            let delta = tau * k as f64 / steps as f64;
            let img = view.capture_fn(
                |x, _| 0.5 + 0.5 * (tau * (x + 0.5) / lambda - delta).cos(),
                ProjectorSampling::Nearest,
                k as u64,
            );
            match img.unwrap() {
                GreyImage::U16(p) => p.into_data().into_iter().map(f64::from).collect(),
                GreyImage::U8(_) => panic!("16-bit frames expected"),
            }
        })
        .collect();
    let t = &view.truth;
    let (w, h) = (t.width as usize, t.height as usize);
    let lit = |x: usize, y: usize| t.lit(y * w + x) && t.object[y * w + x] == 0;
    let (mut sq, mut n, mut worst) = (0.0, 0usize, 0.0f64);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            if !(y - 1..=y + 1).all(|v| (x - 1..=x + 1).all(|u| lit(u, v))) {
                continue;
            }
            let i = y * w + x;
            let (mut s, mut c) = (0.0, 0.0);
            for (k, f) in frames.iter().enumerate() {
                let delta = tau * k as f64 / steps as f64;
                s += f[i] * delta.sin();
                c += f[i] * delta.cos();
            }
            let col = lambda * s.atan2(c) / tau - 0.5;
            let e = (col - t.projector[i].x + lambda / 2.0).rem_euclid(lambda) - lambda / 2.0;
            sq += e * e;
            n += 1;
            worst = worst.max(e.abs());
        }
    }
    assert!(n > 10_000, "{n} interior pixels");
    ((sq / n as f64).sqrt(), worst)
}

#[test]
fn projector_blur_removes_the_pixel_grid_moire() {
    // Hard-edged projector pixels: the fringe is a staircase, and the decoded column follows
    // the pixel grid (measured 0.14 px rms on the full-size rig, error periodic in the
    // fractional projector column). The test asserts it is there, so that the next assertion
    // is known to be able to fail.
    let (hard_rms, hard_max) = fringe_column_error(0.0);
    eprintln!("hard pixels: column error rms {hard_rms:.4} px, max {hard_max:.3} px");
    assert!(hard_rms > 0.05);
    // With the default lens blur the grid's harmonics are damped 100×: the replicas of the
    // render unit test's closed form (5.1e-4 of the fringe) shift the phase by at most
    // 5.1e-4 rad, 0.0024 px of a 30 px period. The patterns are exact functions and the frames
    // 16-bit and noise-free, so little else remains (measured 0.0008 px rms, 0.002 px max).
    // Bounds: 2× and 4× that closed-form peak.
    let (rms, max) = fringe_column_error(sl_sim::Illumination::DEFAULT_PROJECTOR_BLUR_PX);
    eprintln!("blurred pixels: column error rms {rms:.4} px, max {max:.3} px");
    assert!(rms < 0.005, "column error rms {rms} px");
    assert!(max < 0.01, "column error max {max} px");
}

/// Moiré diagnosis: renders the plane under several rig variants, decodes the columns and
/// writes, per decoded object pixel, `x,y,truth_col,decoded_col` to
/// `$SL_MOIRE_OUT/<variant>.csv` (the pictures of docs/triangulation.md come from these).
#[test]
#[ignore = "diagnostic: writes CSV files for the moiré analysis"]
#[allow(clippy::type_complexity)]
fn moire_diagnostics() {
    use sl_codec::{
        Axis, BitDepth, CaptureSet, DecodeConfig, HybridSpec, ImageSize, Pattern, PatternSequence,
        decode,
    };
    use sl_sim::projector_images;
    let Some(out) = std::env::var_os("SL_MOIRE_OUT") else {
        eprintln!("SL_MOIRE_OUT not set: skipping");
        return;
    };
    let out = std::path::PathBuf::from(out);
    std::fs::create_dir_all(&out).unwrap();
    let quiet = |c: &mut RigConfig| {
        c.render.effects.sensor.photon_noise = false;
        c.render.effects.sensor.read_noise_electrons = 0.0;
    };
    let hard = |c: &mut RigConfig| c.render.illumination.projector_blur_px = 0.0;
    type Variant = (&'static str, Box<dyn Fn(&mut RigConfig)>, bool);
    let variants: Vec<Variant> = vec![
        (
            "hard_quiet8",
            Box::new(move |c| {
                hard(c);
                quiet(c)
            }),
            false,
        ),
        (
            "hard_quiet8_ss8",
            Box::new(move |c| {
                hard(c);
                quiet(c);
                c.render.supersampling = 8;
            }),
            false,
        ),
        (
            "hard_quiet8_continuous",
            Box::new(move |c| {
                hard(c);
                quiet(c)
            }),
            true,
        ),
        ("hard_noisy8", Box::new(hard), false),
        ("blur_quiet8", Box::new(quiet), false),
        ("blur_noisy8", Box::new(|_| {}), false),
    ];
    let only = std::env::var("SL_MOIRE_ONLY").unwrap_or_default();
    for (name, tweak, continuous) in variants {
        if !only.is_empty() && !only.split(',').any(|o| o == name) {
            continue;
        }
        let mut config = RigConfig::default();
        tweak(&mut config);
        let rig = VirtualRig::new(config, Scene::plane()).unwrap();
        let projector = ImageSize::new(1920, 1080);
        let sequence = PatternSequence::new(projector).with(Pattern::Hybrid(
            HybridSpec::complementary(Axis::Column, projector, 8, 64.0),
        ));
        let manifest = sequence.manifest(BitDepth::Eight);
        let view = rig.view(0.0, 0).unwrap();
        let frames: Vec<sl_sim::GreyImage> = if continuous {
            (0..sequence.frame_count())
                .map(|k| {
                    view.capture_fn(
                        |x, y| sequence.pattern_value(k, x, y).unwrap_or(0.0),
                        sl_sim::ProjectorSampling::Continuous,
                        k as u64,
                    )
                    .unwrap()
                })
                .collect()
        } else {
            let images = projector_images(&rig, &manifest).unwrap();
            view.capture_all(&images).unwrap()
        };
        let frames = frames
            .into_iter()
            .map(|img| match img {
                GreyImage::U8(f) => f,
                GreyImage::U16(_) => panic!("the variants render 8-bit frames"),
            })
            .collect::<Vec<_>>();
        let capture = CaptureSet::from_frames(manifest, sl_codec::Frames::U8(frames)).unwrap();
        let map = decode(&capture, &DecodeConfig::default()).unwrap();
        let t = &view.truth;
        let mut csv = String::from("x,y,truth_col,decoded_col\n");
        let mut sq = 0.0;
        let mut n = 0usize;
        for i in 0..map.col.len() {
            let c = f64::from(map.col[i]);
            let q = t.projector[i].x;
            if t.object[i] == 0 && c.is_finite() && q.is_finite() {
                let (x, y) = (i % map.width, i / map.width);
                csv.push_str(&format!("{x},{y},{q:.5},{c:.5}\n"));
                sq += (c - q) * (c - q);
                n += 1;
            }
        }
        std::fs::write(out.join(format!("{name}.csv")), csv).unwrap();
        eprintln!(
            "{name}: {n} pixels, column error RMS {:.4} px",
            (sq / n as f64).sqrt()
        );
    }
}

/// A flat 8-bit image of `size`.
fn filled(size: sl_camera::ImageSize, value: u8) -> GreyImage {
    GreyImage::filled_u8(size.width as usize, size.height as usize, value).unwrap()
}

/// A second camera sees the scene where it is: every point it sees, taken into the first
/// camera's frame by its pose, is lit by the projector at the coordinate the second camera's
/// truth gives (the projector and the platter are where they were), and it is not the first
/// camera's view.
#[test]
fn the_second_camera_sees_the_same_scene_from_its_pose() {
    let left = small_rig();
    let second = left.default_second_camera();
    // On the other side of the projector, as far from it as the first camera.
    let p = left.t_cam_proj.translation.vector;
    assert_relative_eq!(
        second.t_cam_second.translation.vector,
        2.0 * p,
        epsilon = 1e-9
    );
    let right = left.seen_from(&second);
    assert_eq!(right.render.seed, left.render.seed + 1);
    let view = VirtualRig::new(right, Scene::sphere())
        .unwrap()
        .view(30.0, 0)
        .unwrap();
    let t = &view.truth;
    assert!(t.lit_count() > 500, "{} lit pixels", t.lit_count());
    let t_proj_cam = left.t_cam_proj.inverse();
    let mut worst = 0.0_f64;
    for i in (0..t.points_cam.len()).filter(|&i| t.lit(i)) {
        let in_left = second.t_cam_second * t.points_cam[i];
        let q = left.projector.project(&(t_proj_cam * in_left)).unwrap();
        worst = worst.max((q - t.projector[i]).norm());
    }
    assert!(worst < 1e-6, "projector coordinates differ by {worst} px");
    // The sphere's centre, on the turntable axis, is seen near the middle of both images.
    let centre = left.t_cam_table_at(30.0) * Point3::new(0.0, 0.0, 50.0);
    for (model, p) in [
        (&left.camera, centre),
        (&second.camera, second.t_cam_second.inverse() * centre),
    ] {
        let px = model.project(&p).unwrap();
        let mid = Point2::new(
            f64::from(model.size.width) / 2.0,
            f64::from(model.size.height) / 2.0,
        );
        assert!(
            (px - mid).norm() < 0.25 * f64::from(model.size.width),
            "{px} is far from the image centre {mid}"
        );
    }
}

/// Both cameras of a binocular rig see what the one projector shows on the one turntable:
/// through the devices, each captures exactly the frame its own rig renders for that angle
/// and that image.
#[test]
fn binocular_devices_share_the_projector_and_the_turntable() {
    let left = small_rig();
    let right = left.seen_from(&left.default_second_camera());
    let left_rig = VirtualRig::new(left.clone(), Scene::sphere()).unwrap();
    let right_rig = VirtualRig::new(right, Scene::sphere()).unwrap();
    let (mut cl, mut cr, mut projector, mut table) =
        left_rig.binocular_devices(&right_rig).unwrap();
    let (w, h) = projector.image_size();
    let (w, h) = (w as usize, h as usize);
    let data = (0..w * h)
        .map(|i| if (i % w / 8) % 2 == 0 { 255 } else { 0 })
        .collect();
    let stripes = GreyImage::U8(sl_codec::Frame::new(w, h, data).unwrap());
    table.rotate_to(40.0).unwrap();
    projector.show(&stripes).unwrap();
    let (fl, fr) = (cl.capture().unwrap(), cr.capture().unwrap());
    for (frame, rig) in [(&fl, &left_rig), (&fr, &right_rig)] {
        let expected = rig.view(40.0, 0).unwrap().capture(&stripes, 0).unwrap();
        assert_eq!(frame, &expected);
    }
    assert_ne!(fl, fr);
    // Another projector size is refused, naming what differs.
    let mut other = left.seen_from(&left.default_second_camera());
    other.projector.size = ImageSize::new(100, 50);
    let err = left_rig
        .binocular_devices(&VirtualRig::new(other, Scene::sphere()).unwrap())
        .unwrap_err();
    assert!(err.to_string().contains("one projector"), "{err}");
}
