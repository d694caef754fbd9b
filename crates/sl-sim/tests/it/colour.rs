//! Colour on the virtual rig: colour captures against grey ones and against the albedo, the
//! true colour of the surface, and the virtual camera's colour frames.

#![allow(clippy::unwrap_used)] // test helpers outside #[test] functions

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use sl_rig::{Camera, Projector};
use sl_sim::{
    COLOURED_ALBEDOS, COLOURED_CELL_MM, ColourImage, Finish, GreyImage, Mount, RigConfig, Scene,
    SceneObject, Shape, Texture, VirtualRig, luma_of,
};

/// The default rig at a quarter of its resolution (camera 320x180, projector 480x270).
fn small_config() -> RigConfig {
    let mut c = RigConfig::default().downscaled(4);
    c.render.supersampling = 2;
    c
}

fn white(rig: &VirtualRig) -> GreyImage {
    let p = rig.config().projector.size;
    GreyImage::filled_u8(p.width as usize, p.height as usize, 255).unwrap()
}

fn grey_u8(img: &GreyImage) -> Vec<u8> {
    img.clone().into_u8().data().to_vec()
}

/// Without noise, the luma of a colour frame is the grey frame to within the rounding of the
/// three channels and of the luma (one grey level): the grey albedo of a colour texture is
/// its luma, and everything between the albedo and the quantisation (the projector's light,
/// ambient light, global illumination, lens blur) is linear. With noise, the two agree on
/// average over the object to the standard error of the mean.
#[test]
fn the_luma_of_a_colour_capture_is_the_grey_capture() {
    for noisy in [false, true] {
        let mut config = small_config();
        if !noisy {
            config.render.effects.sensor.photon_noise = false;
            config.render.effects.sensor.read_noise_electrons = 0.0;
        }
        let rig = VirtualRig::new(config, Scene::sphere().finished(Finish::Coloured)).unwrap();
        let view = rig.view(20.0, 0).unwrap();
        let white = white(&rig);
        let grey = grey_u8(&view.capture(&white, 0).unwrap());
        let colour = view.capture_colour(&white, 1).unwrap();
        let luma = grey_u8(&colour.to_grey());
        let on_object: Vec<usize> = (0..grey.len()).filter(|&i| view.truth.visible(i)).collect();
        assert!(on_object.len() > 3000, "{} object pixels", on_object.len());
        // The patches are coloured: the channels of the object's pixels differ by far more
        // than the noise somewhere.
        let spread = on_object
            .iter()
            .map(|&i| {
                let [r, g, b] = colour.data()[i];
                r.max(g).max(b) - r.min(g).min(b)
            })
            .max()
            .unwrap();
        assert!(spread > 60, "channels differ by at most {spread}");
        let diffs: Vec<f64> = on_object
            .iter()
            .map(|&i| f64::from(luma[i]) - f64::from(grey[i]))
            .collect();
        let n = diffs.len() as f64;
        let mean = diffs.iter().sum::<f64>() / n;
        if noisy {
            // Each frame has ~2.6 grey levels of noise at mid-scale (SensorConfig's default),
            // the luma of three independent channels less (weights² sum to 0.45): a
            // difference of < 3.5 levels rms, a standard error of the mean of 3.5/√n (0.06
            // for 3000 pixels); 0.3 is 5 of them.
            let rms = (diffs.iter().map(|d| d * d).sum::<f64>() / n).sqrt();
            eprintln!("noisy: mean luma - grey {mean:.3}, rms {rms:.3} over {n} pixels");
            assert!(mean.abs() < 0.3, "mean difference {mean}");
            assert!(rms < 4.0, "rms difference {rms}");
        } else {
            let worst = diffs.iter().fold(0.0f64, |a, d| a.max(d.abs()));
            eprintln!("noise-free: mean luma - grey {mean:.3}, worst {worst}");
            assert!(worst <= 1.0, "worst difference {worst}");
        }
    }
}

/// A red plane comes out red: away from its edges every light reaching a pixel (projector,
/// ambient, the global light scattered from the plane itself) is scaled by the channel's
/// albedo, so the channels above the black level stand in the albedo's ratios, 0.8 : 0.2 :
/// 0.1.
#[test]
fn a_red_patch_comes_out_red() {
    let albedo = [0.8, 0.2, 0.1];
    let mut scene = Scene::plane();
    scene.objects[0].texture = Texture::Colour(albedo);
    let config = small_config();
    let dark = config.render.effects.sensor.dark_level_dn;
    let rig = VirtualRig::new(config, scene).unwrap();
    let view = rig.view(0.0, 0).unwrap();
    let colour = view.capture_colour(&white(&rig), 0).unwrap();
    let (w, h) = (colour.width(), colour.height());
    // Pixels whose 9x9 neighbourhood is all plane, lit: away from the edges' blur.
    let inside = |i: usize| {
        let (x, y) = (i % w, i / w);
        x >= 4
            && y >= 4
            && x + 4 < w
            && y + 4 < h
            && (y - 4..=y + 4).all(|yy| (x - 4..=x + 4).all(|xx| view.truth.lit(yy * w + xx)))
    };
    let pixels: Vec<[u8; 3]> = (0..w * h)
        .filter(|&i| inside(i))
        .map(|i| colour.data()[i])
        .collect();
    assert!(pixels.len() > 5000, "{} interior pixels", pixels.len());
    let n = pixels.len() as f64;
    let mean = |c: usize| pixels.iter().map(|p| f64::from(p[c])).sum::<f64>() / n - dark;
    let (r, g, b) = (mean(0), mean(1), mean(2));
    eprintln!("red plane: R {r:.2}, G {g:.2}, B {b:.2} above the black level");
    // The blue mean (~25 levels, ~1.2 of noise per pixel) is known to 1.2/√5000 = 0.02
    // levels: 0.1 % of it. 1 % allows for the noise and the rounding.
    assert!((r / g - 4.0).abs() < 0.04, "R/G {}", r / g);
    assert!((r / b - 8.0).abs() < 0.08, "R/B {}", r / b);
    assert!(r < 250.0 - dark, "red saturates: {r}");
    // Every interior pixel is red.
    assert!(pixels.iter().all(|p| p[0] > p[1] && p[1] > p[2]));
}

/// The true colour is the albedo of the cell the nearest surface point lies in, and its
/// distance the distance to that point: checked on points placed off the centres of known
/// patches of a plane on the turntable (at two table angles), of a sphere's patches, and of
/// a plate fixed to the camera.
#[test]
fn the_true_colour_is_the_albedo_of_the_nearest_patch() {
    let cell = COLOURED_CELL_MM;
    let colours = COLOURED_ALBEDOS.to_vec();
    let texture = Texture::ColourCells {
        cell_mm: cell,
        colours: colours.clone(),
    };
    // Cell (i, j, 0), centred on (i, j, 0) · cell in the plane's frame, has colour
    // (i + j) mod 4.
    let expected = |i: i32, j: i32| colours[(i + j).rem_euclid(4) as usize];
    let mut scene = Scene::plane();
    scene.objects[0].texture = texture.clone();
    let plane_pose = scene.objects[0].pose;
    let plate_pose = Isometry3::from_parts(
        Translation3::new(-200.0, 0.0, 300.0),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.3),
    );
    let scene = scene.with(SceneObject::in_camera(
        "plate",
        Shape::rectangle(60.0, 60.0),
        texture.clone(),
        plate_pose,
    ));
    let rig = VirtualRig::new(RigConfig::default(), scene).unwrap();
    for motor in [0.0, 37.0] {
        let t_cam_plane = rig.config().t_cam_table_at(motor) * plane_pose;
        for (i, j) in [(0, 0), (1, 0), (-2, 3), (3, -2), (-4, -1), (5, 2)] {
            // Near the cell's centre, 4 mm off the plane (−z: the plane faces the camera at
            // angle 0; either side is 4 mm away).
            let local = Point3::new(
                (f64::from(i) + 0.3) * cell,
                (f64::from(j) - 0.2) * cell,
                -4.0,
            );
            let p = t_cam_plane * local;
            let truth = rig.true_colour(motor, &p).unwrap();
            assert_eq!(truth.object, "plane");
            assert!((truth.distance_mm - 4.0).abs() < 1e-9, "{truth:?}");
            assert_eq!(truth.rgb, expected(i, j), "cell ({i}, {j}) at {motor}°");
        }
    }
    // The plate fixed to the camera: the same at any table angle.
    // (−20, 5) is in cell (−1, 0) of 25 mm cells.
    let p = plate_pose * Point3::new(-20.0, 5.0, 2.5);
    for motor in [0.0, 200.0] {
        let truth = rig.true_colour(motor, &p).unwrap();
        assert_eq!(truth.object, "plate");
        assert!((truth.distance_mm - 2.5).abs() < 1e-9);
        assert_eq!(truth.rgb, expected(-1, 0));
    }
    // A sphere of the coloured finish: a point 3 mm outside along a direction projects onto
    // centre + r · direction, whose cell (in the sphere's frame) gives the colour.
    let rig = VirtualRig::new(
        RigConfig::default(),
        Scene::sphere().finished(Finish::Coloured),
    )
    .unwrap();
    let centre = Point3::new(0.0, 0.0, 50.0);
    for (k, d) in [
        Vector3::new(0.3, -0.9, 0.2),
        Vector3::new(-0.5, -0.5, 0.7),
        Vector3::new(0.1, 0.2, -0.95),
    ]
    .iter()
    .enumerate()
    {
        let d = d.normalize();
        let surface = centre + d * 50.0;
        let motor = 60.0 * k as f64;
        let p = rig.config().t_cam_table_at(motor) * (surface + d * 3.0);
        let truth = rig.true_colour(motor, &p).unwrap();
        let cell_of = |v: f64| (v / cell).round() as i64;
        // The texture lives in the sphere's frame, centred on its centre.
        let o = d * 50.0;
        let index = (cell_of(o.x) + cell_of(o.y) + cell_of(o.z)).rem_euclid(4);
        assert!((truth.distance_mm - 3.0).abs() < 1e-6, "{truth:?}");
        assert_eq!(truth.rgb, COLOURED_ALBEDOS[index as usize], "direction {k}");
        assert!(luma_of(&truth.rgb) > 0.4);
    }
    assert!(rig.true_colour(f64::NAN, &centre).is_none());
    assert!(
        rig.true_colour(0.0, &Point3::new(f64::INFINITY, 0.0, 0.0))
            .is_none()
    );
}

/// The virtual camera's colour frame is the view's colour capture of what the projector
/// shows, keyed as the view's first frame.
#[test]
fn the_virtual_camera_captures_colour() {
    let rig = VirtualRig::new(small_config(), Scene::cuboid().finished(Finish::Coloured)).unwrap();
    let (mut camera, mut projector, _table) = rig.devices();
    let white = white(&rig);
    projector.show(&white).unwrap();
    let got: ColourImage = camera.capture_colour().unwrap();
    let want = rig.view(0.0, 0).unwrap().capture_colour(&white, 0).unwrap();
    assert_eq!(got, want);
    // A second capture is another frame: other noise.
    assert_ne!(camera.capture_colour().unwrap(), want);
    // The wrong projector size is refused, naming the projector image.
    let view = rig.view(0.0, 0).unwrap();
    let err = view
        .capture_colour(&GreyImage::filled_u8(4, 4, 255).unwrap(), 0)
        .unwrap_err();
    assert!(err.to_string().contains("projector image"), "{err}");
    let _ = Mount::Camera;
}

/// A capture session with the colour option on the virtual devices: each view's
/// `colour.png`, named by its manifest, shows the patches in their colours where the truth
/// says they are (a pixel on a red patch is red, on a green one green), and the grey frames
/// decode as before.
#[test]
fn a_colour_session_on_the_virtual_rig_writes_the_views_colours() {
    use sl_rig::{COLOUR_FILE, CaptureSession, SessionPlan, ViewState};
    let mut config = small_config();
    config.render.supersampling = 1;
    let dark = config.render.effects.sensor.dark_level_dn;
    let rig = VirtualRig::new(config, Scene::cuboid().finished(Finish::Coloured)).unwrap();
    let plan = SessionPlan {
        colour: true,
        ..super::session::plan(&rig, 2)
    };
    let dir = tempfile::tempdir().unwrap();
    let session = CaptureSession::open(dir.path(), plan, super::session::quick(false, 0)).unwrap();
    let (mut camera, mut projector, mut table) = rig.devices();
    session
        .run(&mut camera, &mut projector, &mut table, |_| {})
        .unwrap();
    for (k, motor) in [0.0, 180.0].into_iter().enumerate() {
        assert_eq!(session.view_state(k), ViewState::Complete);
        let view_dir = session.view_dir(k);
        let manifest = sl_codec::Manifest::load(&view_dir.join("manifest.json")).unwrap();
        assert_eq!(manifest.colour.as_deref(), Some(COLOUR_FILE));
        let colour = sl_codec::read_colour_image(&view_dir.join(COLOUR_FILE)).unwrap();
        let truth = rig.view(motor, 0).unwrap().truth;
        let w = colour.width();
        // Pixels whose 5x5 neighbourhood lies on one patch, by the truth.
        let patch_of = |i: usize| -> Option<usize> {
            if !truth.lit(i) {
                return None;
            }
            let rgb = rig.true_colour(motor, &truth.points_cam[i])?.rgb;
            COLOURED_ALBEDOS.iter().position(|c| *c == rgb)
        };
        let (mut red, mut green) = (0, 0);
        for y in 2..colour.height() - 2 {
            for x in 2..w - 2 {
                let i = y * w + x;
                let Some(p) = patch_of(i) else { continue };
                let uniform = (y - 2..=y + 2)
                    .all(|yy| (x - 2..=x + 2).all(|xx| patch_of(yy * w + xx) == Some(p)));
                if !uniform {
                    continue;
                }
                // Above the black level; judged where the patch is well lit (a face seen at a
                // grazing angle is dim and tinted by the global light of its neighbours).
                let [r, g, b] = colour.data()[i].map(|v| f64::from(v) - dark);
                if r.max(g).max(b) < 60.0 {
                    continue;
                }
                // The albedo ratios are 3.4 and 4.25 (red), 2.5 and 2.5 (green); the global
                // light of the other patches lowers them a little.
                match p {
                    0 => {
                        assert!(
                            r > 2.0 * g && r > 2.0 * b,
                            "red patch at ({x}, {y}): {r} {g} {b}"
                        );
                        red += 1;
                    }
                    1 => {
                        assert!(
                            g > 1.7 * r && g > 1.7 * b,
                            "green patch at ({x}, {y}): {r} {g} {b}"
                        );
                        green += 1;
                    }
                    _ => {}
                }
            }
        }
        assert!(
            red > 50 && green > 50,
            "view {k}: {red} red and {green} green pixels"
        );
    }
}
