//! Corner error against the virtual rig's truth on the calibration captures of `slscan scan`
//! (the same rig, board, poses, noise keys and turntable angles as
//! `sl_scan::calibrate_virtual`), for several detector settings side by side: the mean error
//! vector (bias) and RMS per pose, by tilt and by image position; with `--procam`, the
//! projector–camera calibration of each setting against the true rig.
//!
//! ```sh
//! cargo run --release -p sl-calib --example rig_corner_truth -- [--procam] [--poses 12] [--seed 0]
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used)] // an example: a failure ends it with the reason

use nalgebra::{Point2, Vector2};
use sl_calib::sl_codec::{BitDepth, CaptureSet, DecodeConfig, Frame, Frames, ImageSize, decode};
use sl_calib::{
    BoardSize, CornerRefiner, DetectorConfig, ProcamConfig, ProcamView, calibrate_procam,
    detect_checkerboard,
};
use sl_sim::{
    BoardTruth, CalibrationCaptures, CalibrationSession, RigConfig, Scene, VirtualRig,
    calibration_sequence,
};

/// The settings compared: the default (the junction fit) and those named in `CONFIGS`
/// (comma-separated; default `saddle`): `saddle` (the saddle points alone), `junction`
/// ([`DetectorConfig::with_junction_fit`]),
/// `jr8`, `jr12`, `jr16` (the junction fit with that largest radius), `jf03` (fraction 0.3).
fn configs() -> Vec<(&'static str, DetectorConfig)> {
    let d = DetectorConfig::default();
    let j = DetectorConfig::with_junction_fit();
    let mut out = vec![("default", d)];
    let names: Vec<String> = std::env::var("CONFIGS")
        .unwrap_or_else(|_| "saddle".to_owned())
        .split(',')
        .map(str::to_owned)
        .collect();
    for n in names {
        let c = match n.as_str() {
            "junction" => j,
            "saddle" => DetectorConfig::with_refiner(CornerRefiner::Saddle),
            "jr12" => DetectorConfig {
                max_junction_radius: 12.0,
                ..j
            },
            "jr8" => DetectorConfig {
                max_junction_radius: 8.0,
                ..j
            },
            "jr16" => DetectorConfig {
                max_junction_radius: 16.0,
                ..j
            },
            "jf03" => DetectorConfig {
                junction_fraction: 0.3,
                ..j
            },
            _ => continue,
        };
        out.push((Box::leak(n.into_boxed_str()), c));
    }
    out
}

#[derive(Default, Clone)]
struct Acc {
    sum: Vector2<f64>,
    sq: f64,
    n: usize,
}

impl Acc {
    fn add(&mut self, e: Vector2<f64>) {
        self.sum += e;
        self.sq += e.norm_squared();
        self.n += 1;
    }
    fn bias(&self) -> Vector2<f64> {
        self.sum / self.n.max(1) as f64
    }
    fn rms(&self) -> f64 {
        (self.sq / self.n.max(1) as f64).sqrt()
    }
}

fn tilt_deg(t: &BoardTruth) -> f64 {
    let n = t.t_cam_board.rotation * nalgebra::Vector3::z();
    let c = t
        .corners_cam
        .iter()
        .map(|p| p.coords)
        .sum::<nalgebra::Vector3<f64>>()
        / t.corners_cam.len() as f64;
    n.dot(&c.normalize())
        .abs()
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let procam = args.iter().any(|a| a == "--procam");
    let count: usize = arg("--poses").map_or(12, |v| v.parse().unwrap());
    let seed: u64 = arg("--seed").map_or(0, |v| v.parse().unwrap());

    let mut config = RigConfig::default();
    config.render.seed = seed;
    // `SUPERSAMPLING=n` renders with n×n samples per pixel instead of the rig's default (2×2,
    // as `slscan scan`): the renderer's point samples put an axis-aligned edge on a grid of
    // 1/n px.
    if let Some(n) = std::env::var("SUPERSAMPLING")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        config.render.supersampling = n;
    }
    // The captures of `sl_scan::calibrate_virtual`: its session, board, patterns and noise keys.
    let session = CalibrationSession::with_poses(count, seed);
    let board = session.board;
    let size = BoardSize::new(board.inner_cols, board.inner_rows);
    let rig = VirtualRig::new(config.clone(), Scene::dumbbell()).unwrap();
    let captures = CalibrationCaptures::new(&rig, &session).unwrap();
    let p = ImageSize::new(config.projector.size.width, config.projector.size.height);
    let sequence = calibration_sequence(p);
    let manifest = sequence.manifest(BitDepth::Eight);
    let cfgs = configs();
    let mut whites = Vec::new();
    let mut truths = Vec::new();
    let mut maps = Vec::new();
    for k in 0..captures.poses().len() {
        let cap = captures.hand_held(k, procam.then_some(&sequence)).unwrap();
        if procam {
            let frames: Vec<Frame<u8>> = cap.frames.into_iter().map(|img| img.into_u8()).collect();
            let set = CaptureSet::from_frames(manifest.clone(), Frames::U8(frames)).unwrap();
            maps.push(decode(&set, &DecodeConfig::default()).unwrap());
        }
        whites.push((format!("pose {k}"), cap.white.into_u8()));
        truths.push(cap.board);
    }
    for (k, &a) in session.turntable_angles_deg.iter().enumerate() {
        let cap = captures.on_table(k, None).unwrap();
        whites.push((format!("table {a:+.0}"), cap.white.into_u8()));
        truths.push(cap.board);
    }

    let (cx, cy) = (config.camera.intrinsics.cx, config.camera.intrinsics.cy);
    println!("per view: tilt, then per setting bias (x, y) / RMS px");
    print!("| view | tilt |");
    for (n, _) in &cfgs {
        print!(" {n} |");
    }
    println!();
    let mut totals = vec![(Acc::default(), Acc::default()); cfgs.len()];
    // By radius from the principal point: < 250, 250-450, > 450 px.
    let mut radial = vec![[Acc::default(), Acc::default(), Acc::default()]; cfgs.len()];
    // Projected onto the radial direction (outward positive): a distortion-shaped bias.
    let mut radial_proj = vec![Acc::default(); cfgs.len()];
    let mut detected: Vec<Vec<Vec<Point2<f64>>>> = vec![Vec::new(); cfgs.len()];
    for ((name, img), t) in whites.iter().zip(&truths) {
        print!("| {name} | {:.0} |", tilt_deg(t));
        for (ci, (_, c)) in cfgs.iter().enumerate() {
            let found = detect_checkerboard(img, size, c, name);
            let Ok(found) = found else {
                print!(" not found |");
                detected[ci].push(Vec::new());
                continue;
            };
            let mut acc = Acc::default();
            for (p, q) in found.corners.iter().zip(&t.corners_px) {
                let q = q.unwrap();
                let e = p - q;
                acc.add(e);
                let table = name.starts_with("table");
                if table {
                    totals[ci].1.add(e);
                } else {
                    totals[ci].0.add(e);
                }
                let r = Vector2::new(q.x - cx, q.y - cy);
                let bin = if r.norm() < 250.0 {
                    0
                } else if r.norm() < 450.0 {
                    1
                } else {
                    2
                };
                radial[ci][bin].add(e);
                radial_proj[ci].add(Vector2::new(e.dot(&r.normalize()), 0.0));
            }
            if std::env::var("WORST").is_ok() {
                let mut errs: Vec<(f64, usize)> = found
                    .corners
                    .iter()
                    .zip(&t.corners_px)
                    .enumerate()
                    .map(|(k, (p, q))| ((p - q.unwrap()).norm(), k))
                    .collect();
                errs.sort_by(|a, b| b.0.total_cmp(&a.0));
                for &(e, k) in errs.iter().take(3) {
                    let q = t.corners_px[k].unwrap();
                    eprint!(
                        " [{k} {e:.3} at {:.0},{:.0} d {:+.3},{:+.3}]",
                        q.x,
                        q.y,
                        found.corners[k].x - q.x,
                        found.corners[k].y - q.y
                    );
                }
            }
            detected[ci].push(found.corners);
            let b = acc.bias();
            print!(" {:+.4} {:+.4} / {:.4} |", b.x, b.y, acc.rms());
        }
        println!();
    }
    println!();
    for (ci, (n, _)) in cfgs.iter().enumerate() {
        let (h, t) = &totals[ci];
        let r = &radial[ci];
        println!(
            "{n}: hand-held bias ({:+.4}, {:+.4}) RMS {:.4}; table bias ({:+.4}, {:+.4}) RMS {:.4}; RMS by radius <250 {:.4} (n {}), 250-450 {:.4} (n {}), >450 {:.4} (n {}); mean radial error {:+.4}",
            h.bias().x,
            h.bias().y,
            h.rms(),
            t.bias().x,
            t.bias().y,
            t.rms(),
            r[0].rms(),
            r[0].n,
            r[1].rms(),
            r[1].n,
            r[2].rms(),
            r[2].n,
            radial_proj[ci].bias().x
        );
    }
    if !procam {
        return;
    }
    println!();
    for (n, c) in &cfgs {
        let views: Vec<ProcamView> = whites
            .iter()
            .zip(&maps)
            .map(|((name, img), map)| ProcamView {
                name: name.clone(),
                lit: img.clone(),
                map: map.clone(),
            })
            .collect();
        let mut pc = ProcamConfig::new(
            size,
            board.square_mm,
            ImageSize::new(config.projector.size.width, config.projector.size.height),
        );
        pc.detector = *c;
        let r = calibrate_procam(&views, &pc).unwrap();
        let rel = |a: f64, b: f64| 100.0 * (a - b) / b;
        let (ec, tc) = (r.camera.camera.intrinsics, config.camera.intrinsics);
        let (ep, tp) = (r.projector.camera.intrinsics, config.projector.intrinsics);
        // Projector corners against the truth.
        let mut pacc = Acc::default();
        for (v, t) in r.views.iter().zip(&truths) {
            for (f, q) in v.projector_corners.fits.iter().zip(&t.corners_projector) {
                if let (Some(f), Some(q)) = (f, q) {
                    pacc.add(f.projector - q);
                }
            }
        }
        // 3-D error of the estimated rig: the true board corners of every hand-held pose seen
        // through the true camera and projector, triangulated (midpoint of the two rays) with
        // the estimated models and T_cam_proj.
        let mut e3 = Acc::default();
        let mut pairs: Vec<(nalgebra::Point3<f64>, nalgebra::Point3<f64>)> = Vec::new();
        let mut depth = Acc::default();
        let (tcam, tproj) = (&config.camera, &config.projector);
        let (ecam, eproj) = (&r.camera.camera, &r.projector.camera);
        for t in truths.iter().take(count) {
            for x in &t.corners_cam {
                let (Some(u), Some(v)) = (
                    tcam.project(x),
                    tproj.project(&config.t_cam_proj.inverse_transform_point(x)),
                ) else {
                    continue;
                };
                let (Some(a), Some(b)) = (ecam.unproject_ray(&u), eproj.unproject_ray(&v)) else {
                    continue;
                };
                let (o1, d1) = (nalgebra::Point3::origin(), a.into_inner());
                let o2 = r.t_cam_proj * nalgebra::Point3::origin();
                let d2 = r.t_cam_proj.rotation * b.into_inner();
                // Closest points of the two lines.
                let w = o1 - o2;
                let (aa, bb, cc, dd, ee) = (
                    d1.dot(&d1),
                    d1.dot(&d2),
                    d2.dot(&d2),
                    d1.dot(&w),
                    d2.dot(&w),
                );
                let den = aa * cc - bb * bb;
                let s1 = (bb * ee - cc * dd) / den;
                let s2 = (aa * ee - bb * dd) / den;
                let p = nalgebra::center(&(o1 + d1 * s1), &(o2 + d2 * s2));
                let err = p - x;
                pairs.push((p, *x));
                e3.add(Vector2::new(err.norm(), 0.0));
                depth.add(Vector2::new(err.z, 0.0));
            }
        }
        println!(
            "{n}: 3-D error of the estimated rig on the hand-held poses' corners: RMS {:.4} mm, mean depth error {:+.4} mm",
            e3.rms(),
            depth.bias().x
        );
        println!(
            "{n}: the same after the best rigid alignment (shape error): RMS {:.4} mm",
            shape_error_mm(&pairs)
        );
        if let Some(p) = r.predicted_error {
            println!(
                "{n}: predicted by the calibration's covariance: shape ±{:.4} mm (2σ), RMS {:.4} mm (camera frame {:.4} mm), depth RMS {:.4} mm, largest {:.4} mm over {} corners at {:.0}–{:.0} mm",
                p.bound_mm,
                p.rms_mm,
                p.absolute_rms_mm,
                p.depth_rms_mm,
                p.max_mm,
                p.points,
                p.depth_range_mm[0],
                p.depth_range_mm[1]
            );
        }
        println!(
            "{n}: RMS {:.4}/{:.4}/{:.4} px; camera fx {:+.4} % fy {:+.4} % cx {:+.3} cy {:+.3}; projector fx {:+.4} % fy {:+.4} % cx {:+.3} cy {:+.3}; baseline error {:.4} mm; projector corners bias ({:+.4}, {:+.4}) RMS {:.4}",
            r.rms_camera,
            r.rms_projector,
            r.rms_stereo,
            rel(ec.fx, tc.fx),
            rel(ec.fy, tc.fy),
            ec.cx - tc.cx,
            ec.cy - tc.cy,
            rel(ep.fx, tp.fx),
            rel(ep.fy, tp.fy),
            ep.cx - tp.cx,
            ep.cy - tp.cy,
            (r.t_cam_proj.translation.vector - config.t_cam_proj.translation.vector).norm(),
            pacc.bias().x,
            pacc.bias().y,
            pacc.rms()
        );
    }
}

/// RMS distance (mm) between the estimated and the true points once the estimated ones are
/// moved by the rigid motion that fits them best (Kabsch): the error of shape.
fn shape_error_mm(pairs: &[(nalgebra::Point3<f64>, nalgebra::Point3<f64>)]) -> f64 {
    let n = pairs.len().max(1) as f64;
    let ca = pairs
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, p| a + p.0.coords)
        / n;
    let cb = pairs
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, p| a + p.1.coords)
        / n;
    let h = pairs.iter().fold(nalgebra::Matrix3::zeros(), |m, (a, b)| {
        m + (a.coords - ca) * (b.coords - cb).transpose()
    });
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = nalgebra::Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    let sq: f64 = pairs
        .iter()
        .map(|(a, b)| (r * (a.coords - ca) + cb - b.coords).norm_squared())
        .sum();
    (sq / n).sqrt()
}
