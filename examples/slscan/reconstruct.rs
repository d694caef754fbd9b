//! `slscan reconstruct CAPTURE_DIR --calib FILE --out DIR`: decode a capture set and
//! triangulate it into a point cloud (PLY), depth maps, a shaded preview and `report.json`.

use std::path::PathBuf;

use sl_codec::Axis;
use sl_scan::{CaptureReconstructionConfig, reconstruct_capture};
use sl_tri::{DEPTH_PNG_SCALE_MM, Method, TriConfig};

use crate::common::{Report, ensure_out_dir};

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
    /// Capture folder holding `manifest.json` and the frames.
    pub(crate) capture: PathBuf,
    /// Calibration file (.json, or OpenCV FileStorage .yml/.yaml/.xml incl. SLStudio's).
    #[arg(long)]
    pub(crate) calib: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Triangulation method.
    #[arg(long, value_enum, default_value_t = MethodArg::RayPlane)]
    pub(crate) method: MethodArg,
    /// Drop pixels whose decode quality (8-bit grey levels) is below this.
    #[arg(long, default_value_t = 0.0)]
    pub(crate) min_quality: f32,
    /// Drop points whose reprojection error (px) is above this.
    #[arg(long, default_value_t = sl_tri::DEFAULT_MAX_REPROJECTION_PX)]
    pub(crate) max_reprojection: f64,
    /// Drop points nearer than this depth (mm).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) min_depth: f64,
    /// Drop points farther than this depth (mm).
    #[arg(long, default_value_t = f64::INFINITY)]
    pub(crate) max_depth: f64,
    /// Mixed-pixel filter: largest depth jump to a neighbour, as a fraction of the depth
    /// (`inf` turns the filter off).
    #[arg(long, default_value_t = sl_tri::DEFAULT_MAX_DEPTH_JUMP)]
    pub(crate) max_depth_jump: f64,
    /// Image of the object under full light for the colours (default: the per-pixel maximum
    /// over the capture's frames, which is the fully lit image for complementary patterns).
    #[arg(long)]
    pub(crate) texture: Option<PathBuf>,
    /// Millimetres per unit of the 16-bit depth PNG.
    #[arg(long, default_value_t = DEPTH_PNG_SCALE_MM)]
    pub(crate) depth_scale: f64,
}

/// Runs `slscan reconstruct`.
pub(crate) fn run(args: &Args) -> anyhow::Result<()> {
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
    let out = ensure_out_dir(&args.out)?;
    let r = reconstruct_capture(&args.capture, &args.calib, &cfg, &out)?;
    r.record(&mut report);
    let path = report.write(&out)?;
    for line in r.summary() {
        outln!("{line}");
    }
    outln!("report: {}", path.display());
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
