//! `slscan reconstruct CAPTURE_DIR --calib FILE --out DIR`: decode a capture set and
//! triangulate it into a point cloud (PLY), depth maps, a shaded preview and `report.json`.

use std::path::{Path, PathBuf};

use sl_codec::Axis;
use sl_scan::{
    CaptureReconstructionConfig, ScanError, reconstruct_binocular_capture, reconstruct_capture,
};
use sl_tri::{BinocularConfig, DEPTH_PNG_SCALE_MM, Method, TriConfig, TriError};

use crate::common::{Report, manifest_file, open_out};
use crate::values;

/// Triangulation method on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum MethodArg {
    /// Camera ray against the projector's (distorted) column surface: columns only.
    RayPlane,
    /// Camera ray against the projector's row surface: rows only.
    RayPlaneRow,
    /// Linear least squares (DLT): columns and rows.
    Linear,
    /// Midpoint of the two rays: columns and rows.
    Midpoint,
    /// Minimal reprojection error (Gauss–Newton): columns and rows.
    Optimal,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::RayPlane => Method::RayPlane { axis: Axis::Column },
            MethodArg::RayPlaneRow => Method::RayPlane { axis: Axis::Row },
            MethodArg::Linear => Method::Linear,
            MethodArg::Midpoint => Method::Midpoint,
            MethodArg::Optimal => Method::Optimal,
        }
    }
}

/// Arguments of `slscan reconstruct`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Capture folder holding `manifest.json` and the frames (the left camera's, with
    /// `--right`).
    pub(crate) capture: PathBuf,
    /// The right camera's capture of the same patterns: binocular reconstruction, the
    /// projector only labelling the surface (`--calib` is then a two-camera calibration).
    #[arg(long)]
    pub(crate) right: Option<PathBuf>,
    /// Calibration file (.json, or OpenCV FileStorage .yml/.yaml/.xml incl. SLStudio's).
    #[arg(long)]
    pub(crate) calib: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Write into `--out` even where that replaces an input (the capture's manifest, the
    /// calibration, the texture).
    #[arg(long)]
    pub(crate) force: bool,
    /// Triangulation method.
    #[arg(long, value_enum, default_value_t = MethodArg::RayPlane)]
    pub(crate) method: MethodArg,
    /// Drop pixels whose decode quality (8-bit grey levels, 0 to 255) is below this.
    #[arg(long, default_value_t = 0.0, value_parser = values::grey_level)]
    pub(crate) min_quality: f32,
    /// Drop points whose reprojection error (px) is above this (> 0; `inf` keeps them all).
    #[arg(long, default_value_t = sl_tri::DEFAULT_MAX_REPROJECTION_PX,
          value_parser = values::positive_or_inf)]
    pub(crate) max_reprojection: f64,
    /// Drop points nearer than this depth (mm, ≥ 0, below `--max-depth`).
    #[arg(long, default_value_t = 1.0, value_parser = values::non_negative)]
    pub(crate) min_depth: f64,
    /// Drop points farther than this depth (mm, > 0; `inf`: no bound).
    #[arg(long, default_value_t = f64::INFINITY, value_parser = values::positive_or_inf)]
    pub(crate) max_depth: f64,
    /// Mixed-pixel filter: largest depth jump to a neighbour, as a fraction of the depth
    /// (> 0; `inf` turns the filter off).
    #[arg(long, default_value_t = sl_tri::DEFAULT_MAX_DEPTH_JUMP,
          value_parser = values::positive_or_inf)]
    pub(crate) max_depth_jump: f64,
    /// Image of the object under full light for the colours (default: the per-pixel maximum
    /// over the capture's frames, which is the fully lit image for complementary patterns).
    #[arg(long)]
    pub(crate) texture: Option<PathBuf>,
    /// Millimetres per unit of the 16-bit depth PNG (> 0). A scale at which a depth of the
    /// cloud would not fit (beyond 65535 units, or below 1) is refused with the range that
    /// holds them all: from the farthest depth / 65535 to the nearest depth.
    #[arg(long, default_value_t = DEPTH_PNG_SCALE_MM, value_parser = values::positive)]
    pub(crate) depth_scale: f64,
}

/// The checks of `slscan reconstruct` that need two values.
pub(crate) fn check(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.min_depth < args.max_depth,
        "--min-depth {} must be below --max-depth {}",
        args.min_depth,
        args.max_depth
    );
    Ok(())
}

/// Runs `slscan reconstruct`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
    check(args)?;
    if let Some(right) = &args.right {
        return run_binocular(args, right);
    }
    let mut report = Report::new("reconstruct");
    let cfg = CaptureReconstructionConfig {
        tri: TriConfig {
            method: Method::from(args.method),
            min_quality: args.min_quality,
            min_depth_mm: args.min_depth,
            max_depth_mm: args.max_depth,
            max_reprojection_px: args.max_reprojection,
            max_depth_jump: args.max_depth_jump,
            ..TriConfig::default()
        },
        texture: args.texture.clone(),
        depth_png_scale_mm: args.depth_scale,
    };
    let manifest = manifest_file(&args.capture);
    let mut read = vec![manifest.as_path(), args.calib.as_path()];
    read.extend(args.texture.as_deref());
    let folder = open_out(&args.out, "reconstruct", &read, &[], args.force)?;
    let mut r = reconstruct_capture(&args.capture, &args.calib, &cfg, folder.path()).map_err(
        |e| match e {
            ScanError::Tri(TriError::InvalidParameter {
                parameter: "scale_mm",
                message,
            }) => anyhow::anyhow!("--depth-scale {message}"),
            ScanError::Session { path, reason } => {
                // Name the options behind the statuses that took the pixels.
                let options: Vec<String> = [
                    ("low_quality", format!("--min-quality {}", args.min_quality)),
                    (
                        "out_of_depth_range",
                        format!(
                            "--min-depth {}, --max-depth {}",
                            args.min_depth, args.max_depth
                        ),
                    ),
                    (
                        "reprojection",
                        format!("--max-reprojection {}", args.max_reprojection),
                    ),
                    (
                        "mixed_pixel",
                        format!("--max-depth-jump {}", args.max_depth_jump),
                    ),
                ]
                .into_iter()
                .filter(|(status, _)| reason.contains(status))
                .map(|(status, option)| format!("{status}: {option}"))
                .collect();
                if options.is_empty() {
                    ScanError::Session { path, reason }.into()
                } else {
                    anyhow::anyhow!("{}: {reason} ({})", path.display(), options.join("; "))
                }
            }
            other => other.into(),
        },
    )?;
    r.cloud = folder.final_path(&r.cloud);
    r.record(&mut report);
    report.write(folder.path())?;
    let out = folder.dir().to_path_buf();
    folder.commit()?;
    for line in r.summary() {
        outln!("{line}");
    }
    outln!("report: {}", out.join("report.json").display());
    Ok(())
}

/// `slscan reconstruct LEFT --right RIGHT --calib PAIR`: two cameras triangulate.
fn run_binocular(args: &Args, right: &Path) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.texture.is_none() && args.method == MethodArg::RayPlane,
        "--texture and --method are for a camera and a projector; with --right the two \
         cameras triangulate"
    );
    let mut report = Report::new("reconstruct");
    let cfg = BinocularConfig {
        min_depth_mm: args.min_depth,
        max_depth_mm: args.max_depth,
        max_depth_jump: args.max_depth_jump,
        ..BinocularConfig::default()
    };
    let (left_manifest, right_manifest) = (manifest_file(&args.capture), manifest_file(right));
    let read = [
        left_manifest.as_path(),
        right_manifest.as_path(),
        args.calib.as_path(),
    ];
    let folder = open_out(&args.out, "reconstruct", &read, &[], args.force)?;
    let r = reconstruct_binocular_capture(&args.capture, right, &args.calib, &cfg, folder.path())?;
    report.add_stages(&r.stages);
    report.figure("method", "binocular");
    report.figure("width", r.width);
    report.figure("height", r.height);
    report.figure("points", r.points);
    report.figure("decoded_fraction_left", r.decoded_fraction.0);
    report.figure("decoded_fraction_right", r.decoded_fraction.1);
    let c = r.counts;
    report.figure(
        "pixels",
        serde_json::json!({
            "decoded": c.decoded, "unmatched": c.unmatched, "ambiguous": c.ambiguous,
            "inconsistent": c.inconsistent, "out_of_depth_range": c.out_of_depth_range,
            "mixed_pixels": c.mixed_pixels, "isolated": c.isolated, "valid": c.valid,
        }),
    );
    report.figure(
        "disparity_range_px",
        vec![r.disparity_range_px.0, r.disparity_range_px.1],
    );
    report.figure("disparity_roughness_px", r.roughness_px);
    if let Some((min, max)) = r.bbox_mm {
        report.figure("bbox_min_mm", min.to_vec());
        report.figure("bbox_max_mm", max.to_vec());
    }
    report.write(folder.path())?;
    let out = folder.dir().to_path_buf();
    folder.commit()?;
    outln!(
        "{}: {} points from two cameras ({:.1} % of the {}x{} rectified pixels; decoded {:.1} % \
         left, {:.1} % right; {} occluded or unmatched, {} inconsistent)",
        out.join("cloud.ply").display(),
        r.points,
        100.0 * r.points as f64 / (r.width * r.height).max(1) as f64,
        r.width,
        r.height,
        100.0 * r.decoded_fraction.0,
        100.0 * r.decoded_fraction.1,
        c.unmatched,
        c.inconsistent
    );
    outln!(
        "disparity: {} (scale {:.1}..{:.1} px, roughness {:.3} px); report: {}",
        out.join("disparity.png").display(),
        r.disparity_range_px.0,
        r.disparity_range_px.1,
        r.roughness_px,
        out.join("report.json").display()
    );
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    //! `slscan reconstruct` on a column-only capture (what most real systems record) that the
    //! virtual rig renders at a quarter of its resolution (320x180 camera, 480x270 projector),
    //! with the rig's own calibration.

    use std::path::{Path, PathBuf};

    use sl_codec::{Axis, BitDepth, HybridSpec, ImageSize, Pattern, PatternSequence};
    use sl_scan::scaled_rig_config;
    use sl_sim::{Scene, VirtualRig, simulate_scan};

    /// Quarter resolution, as the other command tests.
    const DOWNSCALE: u32 = 4;

    fn slscan(args: &[&str]) -> anyhow::Result<()> {
        crate::run_cli(args)
    }

    /// Renders one view of the plane with the recommended hybrid code on the columns only;
    /// returns the capture folder and the calibration file.
    pub(crate) fn column_only_capture(dir: &Path) -> (PathBuf, PathBuf) {
        let rig = VirtualRig::new(scaled_rig_config(DOWNSCALE), Scene::plane()).unwrap();
        let p = rig.config().projector.size;
        let p = ImageSize::new(p.width, p.height);
        let manifest = PatternSequence::new(p)
            .with(Pattern::Hybrid(HybridSpec::recommended(Axis::Column, p)))
            .manifest(BitDepth::Eight);
        simulate_scan(&rig, &manifest, &[0.0], dir, |_| {}).unwrap();
        let calib = dir.join("calibration.json");
        rig.config().calibration().save(&calib).unwrap();
        (dir.join("view_000"), calib)
    }

    fn report(out: &Path) -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
    }

    /// Ray–plane, linear and optimal all triangulate the column-only capture, to the same
    /// points (linear and optimal meet the same exact column surface); midpoint is refused
    /// naming the missing rows; a run that keeps no point is an error naming the capture and
    /// what took the pixels, not an empty cloud with exit 0.
    #[test]
    fn column_only_capture_reconstructs_or_fails_loudly() {
        let tmp = tempfile::tempdir().unwrap();
        let (capture, calib) = column_only_capture(tmp.path());
        let (capture, calib) = (capture.to_str().unwrap(), calib.to_str().unwrap());
        let run = |method: &str, extra: &[&str]| {
            let out = tmp.path().join(format!("out_{method}"));
            let mut args = vec![
                "reconstruct",
                capture,
                "--calib",
                calib,
                "--out",
                out.to_str().unwrap(),
                "--method",
                method,
            ];
            args.extend_from_slice(extra);
            slscan(&args).map(|()| out)
        };
        let reference = run("ray-plane", &[]).unwrap();
        let points = report(&reference)["figures"]["points"].as_u64().unwrap();
        // The plane fills most of the 320x180 view.
        assert!(points > 20_000, "{points} points");
        let cloud = |out: &Path| sl_cloud::read_ply(&out.join("cloud.ply")).unwrap();
        let ref_cloud = cloud(&reference);
        for method in ["linear", "optimal"] {
            let out = run(method, &[]).unwrap();
            let r = report(&out);
            assert_eq!(r["figures"]["points"].as_u64().unwrap(), points, "{method}");
            let c = cloud(&out);
            let worst = c
                .positions()
                .iter()
                .zip(ref_cloud.positions())
                .map(|(a, b)| (a - b).norm())
                .fold(0.0f64, f64::max);
            // PLY stores f32: ~3e-5 mm at 450 mm.
            assert!(worst < 1e-3, "{method}: {worst} mm from ray-plane");
        }

        let err = run("midpoint", &[]).unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("projector rows"), "{text}");
        assert!(text.contains(capture), "{text}");

        let err = run("linear", &["--min-depth", "5000", "--max-depth", "6000"]).unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("no point triangulated"), "{text}");
        assert!(text.contains(capture), "{text}");
        assert!(text.contains("out_of_depth_range"), "{text}");
    }

    /// The rig of the left camera (the virtual rig at a quarter of its resolution).
    fn left_config() -> sl_sim::RigConfig {
        scaled_rig_config(DOWNSCALE)
    }

    /// The centre of `Scene::sphere()` (radius 50 mm) in the left camera's frame.
    fn sphere_centre() -> nalgebra::Point3<f64> {
        left_config().t_cam_table_at(0.0) * nalgebra::Point3::new(0.0, 0.0, 50.0)
    }

    /// The same rig seen from the right camera of `pair`: the projector and the platter
    /// where they are, in the right camera's frame.
    fn right_config(pair: &sl_camera::BinocularCalibration) -> sl_sim::RigConfig {
        let left = left_config();
        let t_right_left = pair.t_left_right.inverse();
        let mut right = left.clone();
        right.camera = pair.right;
        right.t_cam_proj = t_right_left * left.t_cam_proj;
        right.t_cam_table = t_right_left * left.t_cam_table;
        right
    }

    /// The virtual rig with a second camera 160 mm to the right of the first, toed in towards
    /// the platter, rendering the sphere (radius 50 mm) under the same patterns: the left and
    /// the right capture and their two-camera calibration.
    fn binocular_captures(dir: &Path) -> (PathBuf, PathBuf, PathBuf, nalgebra::Point3<f64>) {
        binocular_captures_of(dir, |p| {
            [Axis::Column, Axis::Row]
                .into_iter()
                .map(|axis| Pattern::Hybrid(HybridSpec::recommended(axis, p)))
                .collect()
        })
    }

    /// [`binocular_captures`] with the patterns `patterns` gives for the projector's size.
    fn binocular_captures_of(
        dir: &Path,
        patterns: impl Fn(ImageSize) -> Vec<Pattern>,
    ) -> (PathBuf, PathBuf, PathBuf, nalgebra::Point3<f64>) {
        use nalgebra::{Isometry3, Translation3, UnitQuaternion};
        let left = left_config();
        let centre = sphere_centre();
        // Turned about y so that it looks at the sphere's centre, as the left camera does.
        let toe = (160.0 / centre.z).atan();
        let t_left_right = Isometry3::from_parts(
            Translation3::new(160.0, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, -toe, 0.0),
        );
        let right = right_config(&sl_camera::BinocularCalibration::new(
            left.camera,
            left.camera,
            t_left_right,
        ));
        let p = left.projector.size;
        let p = ImageSize::new(p.width, p.height);
        let mut sequence = PatternSequence::new(p);
        for pattern in patterns(p) {
            sequence = sequence.with(pattern);
        }
        let manifest = sequence.manifest(BitDepth::Eight);
        let mut views = Vec::new();
        for (name, config) in [("left", &left), ("right", &right)] {
            let rig = VirtualRig::new(config.clone(), Scene::sphere()).unwrap();
            let d = dir.join(name);
            simulate_scan(&rig, &manifest, &[0.0], &d, |_| {}).unwrap();
            views.push(d.join("view_000"));
        }
        let pair = sl_camera::BinocularCalibration::new(left.camera, right.camera, t_left_right);
        let calib = dir.join("pair.json");
        pair.save(&calib).unwrap();
        (views.remove(0), views.remove(0), calib, centre)
    }

    /// Two cameras of the virtual rig reconstruct the sphere they rendered: its fitted radius
    /// and centre are the scene's (50 mm), from points of both cameras' view only; a right
    /// capture of another size than the calibration's camera is named.
    #[test]
    fn two_cameras_reconstruct_the_rendered_sphere() {
        let tmp = tempfile::tempdir().unwrap();
        let (left, right, calib, centre) = binocular_captures(tmp.path());
        let out = tmp.path().join("out");
        slscan(&[
            "reconstruct",
            left.to_str().unwrap(),
            "--right",
            right.to_str().unwrap(),
            "--calib",
            calib.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .unwrap();
        let r = report(&out);
        assert_eq!(r["figures"]["method"], "binocular");
        let cloud = sl_cloud::read_ply(&out.join("cloud.ply")).unwrap();
        assert!(out.join("disparity.png").is_file());
        let near: Vec<_> = cloud
            .positions()
            .iter()
            .filter(|p| ((*p - centre).norm() - 50.0).abs() < 3.0)
            .copied()
            .collect();
        // A quarter-resolution view (320x180): the sphere covers a few thousand pixels.
        assert!(
            near.len() > 2000,
            "{} sphere points of {}",
            near.len(),
            cloud.len()
        );
        let fit = sl_tri::fit_sphere(&near).unwrap();
        // Measured: radius +0.154 mm, centre 0.18 mm off, fit RMS 0.114 mm (the monocular
        // reconstruction of the left capture: −0.007 mm, 0.08 mm, 0.081 mm). At a quarter of
        // the resolution a disparity error of 0.04 px is 0.15 mm here; with the renderer's exact
        // projector coordinates instead of the decoded ones the same matching gives +0.017 mm
        // (below): what is left is the decoding, not the geometry.
        assert!((fit.radius - 50.0).abs() < 0.25, "radius {}", fit.radius);
        assert!(
            (fit.centre - centre).norm() < 0.3,
            "centre {} vs {centre}",
            fit.centre
        );
        assert!(fit.rms < 0.15, "fit RMS {}", fit.rms);

        // The renderer's exact projector coordinates, matched by the same library call.
        let pair = sl_camera::BinocularCalibration::load(&calib).unwrap();
        let maps: Vec<sl_codec::CorrespondenceMap> = [left_config(), right_config(&pair)]
            .into_iter()
            .map(|c| {
                let view = VirtualRig::new(c, Scene::sphere())
                    .unwrap()
                    .view(0.0, 0)
                    .unwrap();
                let t = &view.truth;
                let mut m = sl_codec::CorrespondenceMap::new(t.width as usize, t.height as usize);
                for (i, p) in t.projector.iter().enumerate() {
                    m.col[i] = p.x as f32;
                    m.row[i] = p.y as f32;
                }
                m
            })
            .collect();
        let b = sl_tri::Binocular::new(&pair.left, &pair.right, &pair.t_left_right).unwrap();
        let exact = b
            .reconstruct(&maps[0], &maps[1], &sl_tri::BinocularConfig::default())
            .unwrap();
        let near: Vec<_> = exact
            .cloud
            .positions()
            .iter()
            .filter(|p| ((*p - centre).norm() - 50.0).abs() < 3.0)
            .copied()
            .collect();
        let fit = sl_tri::fit_sphere(&near).unwrap();
        assert!(
            (fit.radius - 50.0).abs() < 0.03,
            "exact codes: radius {}",
            fit.radius
        );
        assert!(
            (fit.centre - centre).norm() < 0.05,
            "exact codes: centre {}",
            fit.centre
        );
        assert!(fit.rms < 0.02, "exact codes: fit RMS {}", fit.rms);
    }

    /// The matching needs only that both cameras decode the same code: a Gray code on both
    /// axes (stripes of 4 projector pixels, which the quarter-resolution cameras resolve; its
    /// stair codes made ramps, `sl_codec::ramp_stair_codes`) and a three-frequency phase
    /// shift on the columns alone reconstruct the sphere. Measured (printed): Gray 3,211
    /// sphere points, radius 49.74 mm, fit RMS 0.82 mm — a stripe is 3 mm on the sphere here,
    /// and a ramp only guesses where in it a pixel is; phase 4,371 points, radius 50.49 mm,
    /// fit RMS 0.14 mm (the hybrid code: +0.15 mm, 0.11 mm). One seed, quarter resolution.
    #[test]
    fn two_cameras_reconstruct_with_other_codecs() {
        use structured_light::codec::{GrayCodeSpec, PhaseShiftSpec, Unwrap};
        type Patterns = fn(ImageSize) -> Vec<Pattern>;
        let codecs: [(&str, Patterns); 2] = [
            ("gray", |p| {
                [Axis::Column, Axis::Row]
                    .into_iter()
                    .filter_map(|axis| GrayCodeSpec::striped(axis, p, 4, true).ok())
                    .map(Pattern::Gray)
                    .collect()
            }),
            ("phase", |p| {
                let periods = PhaseShiftSpec::heterodyne_periods(f64::from(p.width), 12.0);
                vec![Pattern::Phase(PhaseShiftSpec::new(
                    Axis::Column,
                    p,
                    8,
                    periods,
                    Unwrap::Heterodyne,
                ))]
            }),
        ];
        for (name, patterns) in codecs {
            let tmp = tempfile::tempdir().unwrap();
            let (left, right, calib, centre) = binocular_captures_of(tmp.path(), patterns);
            let out = tmp.path().join("out");
            slscan(&[
                "reconstruct",
                left.to_str().unwrap(),
                "--right",
                right.to_str().unwrap(),
                "--calib",
                calib.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ])
            .unwrap();
            let cloud = sl_cloud::read_ply(&out.join("cloud.ply")).unwrap();
            let near: Vec<_> = cloud
                .positions()
                .iter()
                .filter(|p| ((*p - centre).norm() - 50.0).abs() < 3.0)
                .copied()
                .collect();
            let fit = sl_tri::fit_sphere(&near).unwrap();
            eprintln!(
                "{name}: {} sphere points, radius {:.3} mm, fit RMS {:.3} mm",
                near.len(),
                fit.radius,
                fit.rms
            );
            let (radius_bound, rms_bound) = if name == "gray" {
                (0.5, 1.2)
            } else {
                (0.6, 0.2)
            };
            assert!(near.len() > 1000, "{name}: {} sphere points", near.len());
            assert!(
                (fit.radius - 50.0).abs() < radius_bound,
                "{name}: radius {}",
                fit.radius
            );
            assert!(fit.rms < rms_bound, "{name}: fit RMS {}", fit.rms);
        }
    }

    /// A depth scale at which the cloud's depths do not fit the 16-bit depth PNG is refused
    /// naming `--depth-scale`, its value and the range that works for this cloud (before, 1e-6
    /// wrote an all-zero `depth.png` with exit 0); a scale that is no number is refused when
    /// parsed.
    #[test]
    fn a_depth_scale_the_depths_do_not_fit_is_refused_with_the_working_range() {
        let tmp = tempfile::tempdir().unwrap();
        let (capture, calib) = column_only_capture(tmp.path());
        let (capture, calib) = (capture.to_str().unwrap(), calib.to_str().unwrap());
        for (scale, at_parse) in [
            ("0.000001", false),
            ("1000", false),
            ("0", true),
            ("-0.02", true),
            ("NaN", true),
            ("inf", true),
        ] {
            let out = tmp.path().join("out");
            let arg = format!("--depth-scale={scale}");
            let err = slscan(&[
                "reconstruct",
                capture,
                "--calib",
                calib,
                "--out",
                out.to_str().unwrap(),
                &arg,
            ])
            .unwrap_err();
            let text = format!("{err:#}");
            assert!(text.contains("--depth-scale"), "{scale}: {text}");
            if at_parse {
                assert!(err.downcast_ref::<clap::Error>().is_some(), "{text}");
            } else {
                // The plane lies at about 450 mm: the range runs from ~0.007 to ~400 mm.
                assert!(
                    text.starts_with(&format!("--depth-scale {scale}")),
                    "{text}"
                );
                assert!(text.contains("mm per unit"), "{text}");
            }
            assert!(!out.join("depth.png").exists(), "{scale}");
            assert!(!out.join("cloud.ply").exists(), "{scale}");
        }
    }

    /// A calibration that makes no physical sense is refused where it is read, by `slscan
    /// info` and `slscan reconstruct`, naming the file, the device and the key as the file
    /// spells it: in our JSON (`camera.intrinsics.fx`) and in SLStudio's XML (`Kc`, `kp`).
    /// fx = 1e308 px puts the 320 px wide image into 2e-303° (a lens sees between 0.1° and
    /// 179°); k1 = 1e6 makes the distortion scale the corner's radius by ~64 (a lens's by at
    /// most 10). Until issue 30 both were read, `info` printed them and `reconstruct` wrote a
    /// cloud of a few points with exit 0. The rig's own calibration still reads.
    #[test]
    fn calibrations_without_physical_sense_are_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let (capture, calib) = column_only_capture(tmp.path());
        let good = sl_camera::Calibration::load(&calib).unwrap();
        slscan(&["info", calib.to_str().unwrap()]).unwrap();
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&calib).unwrap()).unwrap();
        let mut files = Vec::new();
        for (device, part, key, value) in [
            ("camera", "intrinsics", "fx", 1e308),
            ("camera", "distortion", "k1", 1e6),
            ("projector", "intrinsics", "fy", 1e308),
            ("projector", "distortion", "k1", 1e6),
        ] {
            let mut bad = json.clone();
            bad[device][part][key] = value.into();
            let path = tmp.path().join(format!("bad_{device}_{key}.json"));
            std::fs::write(&path, serde_json::to_string_pretty(&bad).unwrap()).unwrap();
            files.push((path, device, format!("`{device}.{part}.{key}`"), key));
        }
        // SLStudio's layout: the camera's matrix `Kc`, the projector's distortion `kp`.
        let mut c = good.clone();
        c.camera.intrinsics.fx = 1e308;
        let path = tmp.path().join("bad_fx.xml");
        c.save(&path).unwrap();
        files.push((path, "camera", "`Kc`".to_owned(), "fx"));
        let mut c = good.clone();
        let p = c.projector.as_mut().unwrap();
        p.distortion = sl_camera::Distortion::from_opencv(&[1e6, 0.0, 0.0, 0.0, 0.0]).unwrap();
        let path = tmp.path().join("bad_k1.xml");
        c.save(&path).unwrap();
        files.push((path, "projector", "`kp`".to_owned(), "k1"));
        for (path, device, key, parameter) in &files {
            let name = path.file_name().unwrap().to_str().unwrap();
            let out = tmp.path().join(format!("out_{name}"));
            for argv in [
                vec!["info", path.to_str().unwrap()],
                vec![
                    "reconstruct",
                    capture.to_str().unwrap(),
                    "--calib",
                    path.to_str().unwrap(),
                    "--out",
                    out.to_str().unwrap(),
                ],
            ] {
                let err = format!("{:#}", slscan(&argv).unwrap_err());
                for part in [name, device, key.as_str(), parameter] {
                    assert!(err.contains(part), "{argv:?}: no {part} in {err}");
                }
            }
            assert!(!out.join("cloud.ply").exists(), "{name}");
        }
    }
}
