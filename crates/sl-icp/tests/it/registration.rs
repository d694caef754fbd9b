//! Registration on synthetic surfaces whose true motion is known: every metric, every
//! association, trimming, robust kernels, the information matrix, failures, and the law that a
//! rigid motion of both clouds moves the answer with them.

#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: helpers fail loudly

use approx::assert_relative_eq;
use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;
use sl_icp::{
    Association, Icp, IcpConfig, IcpError, Metric, NormalConfig, NormalOrientation, NormalSource,
    PinholeGrid, PointCloud, PoseError, PrepareConfig, PreparedCloud, RobustKernel, Trimming,
    register,
};

/// A smooth terrain 300 mm in front of the camera, bumpy in both directions so that every
/// motion changes the fit: `z = 300 + 6 sin(x/9) cos(y/13) + 0.004 (x - 30)² - 3 cos(y/7)`.
fn height(x: f64, y: f64) -> f64 {
    300.0 + 6.0 * (x / 9.0).sin() * (y / 13.0).cos() + 0.004 * (x - 30.0).powi(2)
        - 3.0 * (y / 7.0).cos()
}

/// Samples of the terrain on `[x0, x0 + w] x [0, 60]` mm with spacing `step`, the grid shifted
/// by `offset` (a different sampling of the same surface), with Gaussian noise along z.
fn terrain(x0: f64, w: f64, step: f64, offset: f64, noise: f64, seed: u64) -> Vec<Point3<f64>> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let n = Normal::new(0.0, noise.max(1e-300)).unwrap();
    let (nx, ny) = ((w / step) as usize, (60.0 / step) as usize);
    let mut pts = Vec::with_capacity(nx * ny);
    for i in 0..nx {
        for j in 0..ny {
            let (x, y) = (x0 + i as f64 * step + offset, j as f64 * step + offset);
            let dz = if noise > 0.0 { n.sample(&mut rng) } else { 0.0 };
            pts.push(Point3::new(x, y, height(x, y) + dz));
        }
    }
    pts
}

/// The motion used by most tests: 2° about a skewed axis and 1.2 mm, about the patch.
fn truth() -> Isometry3<f64> {
    let r = UnitQuaternion::from_scaled_axis(
        Vector3::new(0.3, -0.8, 0.5).normalize() * 2f64.to_radians(),
    );
    let c = Vector3::new(30.0, 30.0, 300.0);
    Isometry3::from_parts(
        Translation3::from(c - r * c + Vector3::new(0.8, -0.6, 0.7)),
        r,
    )
}

fn prepared(points: Vec<Point3<f64>>) -> PreparedCloud {
    PreparedCloud::new(
        &PointCloud::from_positions(points),
        &PrepareConfig::default(),
    )
    .unwrap()
}

/// `T_target_source = truth`: the source is the target's surface moved by `truth^-1`.
fn moved(points: &[Point3<f64>], t: &Isometry3<f64>) -> Vec<Point3<f64>> {
    points.iter().map(|p| t.inverse() * p).collect()
}

fn tight() -> IcpConfig {
    IcpConfig {
        max_iterations: 300,
        rotation_tolerance: 1e-10,
        translation_tolerance: 1e-9,
        relative_error_tolerance: 0.0,
        ..IcpConfig::default()
    }
}

#[test]
fn every_metric_recovers_an_exact_motion() {
    // Identical samples, no noise: the true pose is a zero-residual fixed point, so each
    // metric must land on it to rounding (1e-7 deg, 1e-6 mm: the iterations stop on updates
    // below 1e-10 rad / 1e-9 mm).
    let target_pts = terrain(0.0, 60.0, 0.6, 0.0, 0.0, 1);
    let source_pts = moved(&target_pts, &truth());
    let (target, source) = (prepared(target_pts), prepared(source_pts.clone()));
    for metric in [
        Metric::PointToPoint,
        Metric::PointToPlane,
        Metric::Generalized,
    ] {
        let config = IcpConfig { metric, ..tight() };
        let r = register(&source, &target, &Isometry3::identity(), &config).unwrap();
        let e = PoseError::between(&r.pose, &truth(), &source_pts);
        assert!(
            r.converged,
            "{metric:?} did not converge in {} iterations",
            r.iterations
        );
        assert!(
            e.rotation_deg < 1e-7 && e.rms_displacement_mm < 1e-6,
            "{metric:?}: {e:?}"
        );
        assert_relative_eq!(r.fitness, 1.0);
        assert!(r.rmse < 1e-6);
    }
}

#[test]
fn resampled_noisy_surfaces_register_to_the_noise_level() {
    // The source samples the surface on a grid shifted by 0.3 mm, with 0.02 mm noise on both.
    // Point-to-plane and generalized ICP compare with tangent planes, so the sampling offset
    // matters only through curvature: a tangent plane 0.42 mm (the grid offset) from where
    // the source point lies misses the surface by κ d² / 2 <= 0.14 · 0.42² / 2 = 0.012 mm
    // (κ bounded by the second derivatives of the terrain, 6/81 + 3/49). The 0.02 mm noise
    // averages out over ~10k points. So: within 0.015 mm RMS over the patch, and 0.02°
    // (0.015 mm over the ~40 mm lever arm of the patch).
    let target_pts = terrain(0.0, 60.0, 0.6, 0.0, 0.02, 2);
    let source_pts = moved(&terrain(0.0, 60.0, 0.6, 0.3, 0.02, 3), &truth());
    let (target, source) = (prepared(target_pts), prepared(source_pts.clone()));
    for metric in [Metric::PointToPlane, Metric::Generalized] {
        let config = IcpConfig {
            metric,
            ..IcpConfig::default()
        };
        let r = register(&source, &target, &Isometry3::identity(), &config).unwrap();
        let e = PoseError::between(&r.pose, &truth(), &source_pts);
        assert!(
            r.converged && r.iterations < 20,
            "{metric:?}: {} iterations",
            r.iterations
        );
        assert!(
            e.rotation_deg < 0.02 && e.rms_displacement_mm < 0.015,
            "{metric:?}: {e:?}"
        );
        // Residuals: the noise of two clouds (0.02·√2) plus the sampling offset of a 0.6 mm
        // grid shifted by 0.3 (point-to-point distances ~0.3 mm).
        assert!(r.rmse < 0.45, "{metric:?}: rmse {}", r.rmse);
    }
}

#[test]
fn normal_shooting_converges_to_the_motion() {
    let target_pts = terrain(0.0, 60.0, 0.6, 0.0, 0.0, 4);
    let source_pts = moved(&terrain(0.0, 60.0, 0.6, 0.25, 0.0, 5), &truth());
    let (target, source) = (prepared(target_pts), prepared(source_pts.clone()));
    let config = IcpConfig {
        association: Association::NormalShooting,
        ..IcpConfig::default()
    };
    let r = register(&source, &target, &Isometry3::identity(), &config).unwrap();
    let e = PoseError::between(&r.pose, &truth(), &source_pts);
    assert!(r.converged);
    // Noise-free resampled surfaces: only the curvature bias between samples limits it (see
    // `resampled_noisy_surfaces_register_to_the_noise_level`: <= 0.012 mm).
    assert!(
        e.rotation_deg < 0.02 && e.rms_displacement_mm < 0.015,
        "{e:?}"
    );
}

/// The terrain as an organised cloud seen by a 160 x 120 pinhole camera at the origin: pixel
/// (u, v) sees the terrain point on its ray (found by fixed-point iteration of z = height).
fn organised_terrain(grid: &PinholeGrid, motion: &Isometry3<f64>) -> Vec<Point3<f64>> {
    let mut pts = Vec::with_capacity(grid.width * grid.height);
    for v in 0..grid.height {
        for u in 0..grid.width {
            let dir = Vector3::new(
                (u as f64 - grid.cx) / grid.fx,
                (v as f64 - grid.cy) / grid.fy,
                1.0,
            );
            // The ray in the terrain's frame: x = motion^-1 (z dir).
            let inv = motion.inverse();
            let (o, d) = (inv * Point3::origin(), inv.rotation * dir);
            let mut t = 300.0;
            for _ in 0..100 {
                let p = o + d * t;
                t += (height(p.x, p.y) - p.z) / d.z;
            }
            pts.push(motion * (o + d * t));
        }
    }
    pts
}

#[test]
fn projective_association_registers_organised_views() {
    let grid = PinholeGrid {
        width: 160,
        height: 120,
        fx: 700.0,
        fy: 700.0,
        cx: 12.0,
        cy: 0.0,
    };
    // Target view: the terrain as is. Source view: the terrain moved by truth^-1, rendered by
    // the same camera, i.e. seen from another viewpoint; T_target_source = truth.
    let target_cloud = PointCloud::from_positions(organised_terrain(&grid, &Isometry3::identity()));
    let source_pts = organised_terrain(&grid, &truth().inverse());
    let config = PrepareConfig::default();
    let target = PreparedCloud::from_organized(&target_cloud, grid, &config).unwrap();
    let source = prepared(source_pts.clone());
    let icp = IcpConfig {
        association: Association::Projective { window: 2 },
        ..IcpConfig::default()
    };
    let r = register(&source, &target, &Isometry3::identity(), &icp).unwrap();
    let e = PoseError::between(&r.pose, &truth(), &source_pts);
    assert!(r.converged, "{r:?}");
    assert!(
        e.rotation_deg < 0.005 && e.rms_displacement_mm < 0.005,
        "{e:?}"
    );
    // The unorganised target refuses projective association.
    let unorganised = prepared(target_cloud.positions().to_vec());
    assert!(matches!(
        Icp::new(&source, &unorganised, &icp),
        Err(IcpError::NotOrganized)
    ));
}

#[test]
fn trimming_ignores_what_only_one_cloud_saw() {
    // The source covers x in [20, 80], the target [0, 60]: a third of the source has no
    // counterpart. Without a distance gate, plain ICP drags the pose toward those points;
    // trimmed ICP keeps the best 60 % (fixed) or estimates the overlap (TrICP's criterion).
    let target_pts = terrain(0.0, 60.0, 0.8, 0.0, 0.0, 6);
    let source_pts = moved(&terrain(20.0, 60.0, 0.8, 0.0, 0.0, 7), &truth());
    let (target, source) = (prepared(target_pts), prepared(source_pts.clone()));
    let run = |metric, trimming| {
        let config = IcpConfig {
            metric,
            trimming,
            max_correspondence_distance: f64::INFINITY,
            ..tight()
        };
        let r = register(&source, &target, &Isometry3::identity(), &config).unwrap();
        (
            PoseError::between(&r.pose, &truth(), &source_pts),
            r.fitness,
        )
    };
    let (plain, _) = run(Metric::PointToPlane, Trimming::None);
    assert!(
        plain.rms_displacement_mm > 0.5,
        "untrimmed should be biased: {plain:?}"
    );
    // The grid step 0.8 divides the 20 mm shift: in the overlap the samples coincide, so the
    // true pose is a zero-residual fixed point and trimming must find it to rounding.
    for (metric, trimming, fitness) in [
        (Metric::PointToPlane, Trimming::Fixed { overlap: 0.6 }, 0.6),
        (
            Metric::PointToPlane,
            Trimming::Auto { min_overlap: 0.3 },
            2.0 / 3.0,
        ),
        (
            Metric::PointToPoint,
            Trimming::Auto { min_overlap: 0.3 },
            2.0 / 3.0,
        ),
    ] {
        let (e, f) = run(metric, trimming);
        assert!(
            e.rotation_deg < 1e-6 && e.rms_displacement_mm < 1e-5,
            "{metric:?} {trimming:?}: {e:?}"
        );
        // Fixed keeps ceil(0.6 N); Auto keeps every zero residual, i.e. the whole overlap
        // (40 of the 60 mm columns), plus at most a column of near-zero ones at its edge.
        assert!(
            (f - fitness).abs() < 0.02,
            "{metric:?} {trimming:?}: fitness {f}"
        );
    }
}

#[test]
fn robust_kernels_resist_outliers() {
    // 15 % of the source points are pushed 1.5 mm off the surface (all to the same side, the
    // worst case for least squares), within the 5 mm gate.
    let target_pts = terrain(0.0, 60.0, 0.6, 0.0, 0.0, 8);
    let mut src = terrain(0.0, 60.0, 0.6, 0.0, 0.0, 9);
    let mut rng = Pcg64::seed_from_u64(10);
    for p in &mut src {
        if rng.random::<f64>() < 0.15 {
            p.z += 1.5;
        }
    }
    let source_pts = moved(&src, &truth());
    let (target, source) = (prepared(target_pts), prepared(source_pts.clone()));
    let run = |kernel| {
        let config = IcpConfig {
            kernel,
            ..IcpConfig::default()
        };
        let r = register(&source, &target, &Isometry3::identity(), &config).unwrap();
        PoseError::between(&r.pose, &truth(), &source_pts)
    };
    let l2 = run(RobustKernel::L2);
    let huber = run(RobustKernel::Huber { k: 0.1 });
    let tukey = run(RobustKernel::Tukey { c: 0.5 });
    // L2 shifts the patch by ~15 % of 1.5 mm; Huber by much less; Tukey ignores them (its
    // weight is 0 beyond 0.5 mm), so it is exact to the convergence tolerance.
    assert!(l2.rms_displacement_mm > 0.15, "{l2:?}");
    assert!(
        huber.rms_displacement_mm < 0.5 * l2.rms_displacement_mm,
        "{huber:?} vs {l2:?}"
    );
    assert!(
        tukey.rms_displacement_mm < 0.002 && tukey.rotation_deg < 0.002,
        "{tukey:?}"
    );
}

#[test]
fn information_matrix_is_the_sum_of_point_jacobian_products() {
    // At the true pose every source point lies on its target point (identical samples), so
    // the inliers are all points and the information is Σ G^T G with G = [-[q]x | I].
    let target_pts = terrain(0.0, 30.0, 1.0, 0.0, 0.0, 11);
    let source_pts = moved(&target_pts, &truth());
    let (target, source) = (prepared(target_pts.clone()), prepared(source_pts));
    let mut icp = Icp::new(&source, &target, &IcpConfig::default()).unwrap();
    let ev = icp.evaluate(&truth()).unwrap();
    let mut want = Matrix6::zeros();
    for q in &target_pts {
        let mut g = nalgebra::Matrix3x6::zeros();
        let s = Matrix3::new(0.0, -q.z, q.y, q.z, 0.0, -q.x, -q.y, q.x, 0.0);
        g.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-s));
        g.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        want += g.transpose() * g;
    }
    assert_eq!(ev.inliers, target_pts.len());
    assert_relative_eq!(ev.fitness, 1.0);
    assert!(ev.rmse < 1e-9);
    assert_relative_eq!(ev.information, want, max_relative = 1e-9);
}

#[test]
fn steps_and_flags_report_what_happened() {
    let target_pts = terrain(0.0, 60.0, 0.6, 0.0, 0.0, 12);
    let source_pts = moved(&target_pts, &truth());
    let (target, source) = (prepared(target_pts), prepared(source_pts));
    let one = IcpConfig {
        max_iterations: 1,
        ..IcpConfig::default()
    };
    let r = register(&source, &target, &Isometry3::identity(), &one).unwrap();
    assert_eq!(r.iterations, 1);
    assert!(!r.converged);
    let zero = IcpConfig {
        max_iterations: 0,
        ..IcpConfig::default()
    };
    let r0 = register(&source, &target, &truth(), &zero).unwrap();
    assert_eq!(r0.pose, truth());
    assert!(r0.fitness > 0.999);
    // One step from the identity: the update moves toward the truth.
    let mut icp = Icp::new(&source, &target, &IcpConfig::default()).unwrap();
    let s = icp.step(&Isometry3::identity()).unwrap();
    let before = PoseError::between(&Isometry3::identity(), &truth(), &[]);
    let after = PoseError::between(&s.pose, &truth(), &[]);
    assert!(after.rotation_deg < 0.5 * before.rotation_deg);
    assert_eq!(s.pose, s.update);
}

#[test]
fn failures_name_their_cause() {
    let pts = terrain(0.0, 30.0, 1.0, 0.0, 0.0, 13);
    let bare = PreparedCloud::new(
        &PointCloud::from_positions(pts.clone()),
        &PrepareConfig {
            normals: NormalSource::None,
            ..Default::default()
        },
    )
    .unwrap();
    let with_normals = prepared(pts.clone());
    let empty = prepared(Vec::new());
    let c = IcpConfig::default();
    assert!(
        matches!(Icp::new(&empty, &with_normals, &c), Err(IcpError::EmptyCloud { cloud }) if cloud == "source")
    );
    assert!(
        matches!(Icp::new(&with_normals, &empty, &c), Err(IcpError::EmptyCloud { cloud }) if cloud == "target")
    );
    assert!(matches!(
        Icp::new(&with_normals, &bare, &c),
        Err(IcpError::MissingNormals {
            cloud: "target",
            ..
        })
    ));
    let gicp = IcpConfig {
        metric: Metric::Generalized,
        ..c
    };
    assert!(matches!(
        Icp::new(&bare, &with_normals, &gicp),
        Err(IcpError::MissingNormals {
            cloud: "source",
            ..
        })
    ));
    // Clouds 1 m apart: no correspondence within 5 mm.
    let far = Isometry3::translation(1000.0, 0.0, 0.0);
    assert!(matches!(
        register(&with_normals, &with_normals, &far, &c),
        Err(IcpError::TooFewCorrespondences {
            iteration: 0,
            found: 0,
            ..
        })
    ));
    // A plane leaves in-plane motions free.
    let plane: Vec<Point3<f64>> = (0..900)
        .map(|i| Point3::new((i % 30) as f64, (i / 30) as f64, 100.0))
        .collect();
    let plane = prepared(plane);
    assert!(matches!(
        register(&plane, &plane, &Isometry3::translation(0.3, 0.0, 0.0), &c),
        Err(IcpError::Degenerate {
            iteration: 0,
            metric: "point-to-plane"
        })
    ));
    // Bad parameters name the field.
    for (bad, name) in [
        (
            IcpConfig {
                max_correspondence_distance: 0.0,
                ..c
            },
            "max_correspondence_distance",
        ),
        (
            IcpConfig {
                kernel: RobustKernel::Huber { k: -1.0 },
                ..c
            },
            "kernel.k",
        ),
        (
            IcpConfig {
                trimming: Trimming::Fixed { overlap: 1.5 },
                ..c
            },
            "trimming.overlap",
        ),
        (
            IcpConfig {
                gicp_epsilon: 0.0,
                ..c
            },
            "gicp_epsilon",
        ),
    ] {
        match bad.validate() {
            Err(IcpError::InvalidParameter { parameter, .. }) => assert_eq!(parameter, name),
            other => panic!("{name}: {other:?}"),
        }
    }
    let nan = Isometry3::translation(f64::NAN, 0.0, 0.0);
    assert!(register(&with_normals, &with_normals, &nan, &c).is_err());
}

/// A random rigid motion: any rotation, translation up to 2 m.
fn motion() -> impl Strategy<Value = Isometry3<f64>> {
    (
        (
            -1.0..1.0f64,
            -1.0..1.0f64,
            -1.0..1.0f64,
            0.0..std::f64::consts::PI,
        ),
        (-2000.0..2000.0f64, -2000.0..2000.0f64, -2000.0..2000.0f64),
    )
        .prop_filter("axis", |((x, y, z, _), _)| x * x + y * y + z * z > 1e-3)
        .prop_map(|((x, y, z, a), (tx, ty, tz))| {
            Isometry3::from_parts(
                Translation3::new(tx, ty, tz),
                UnitQuaternion::from_scaled_axis(Vector3::new(x, y, z).normalize() * a),
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// Moving both clouds by G moves the answer with them:
    /// register(G S, G T, G T0 G^-1) = G T* G^-1, for every metric.
    #[test]
    fn a_rigid_motion_of_both_clouds_leaves_the_answer_unchanged(g in motion(), metric in 0usize..3) {
        let metric = [Metric::PointToPoint, Metric::PointToPlane, Metric::Generalized][metric];
        let target_pts = terrain(0.0, 40.0, 0.8, 0.0, 0.02, 20);
        let source_pts = moved(&terrain(0.0, 40.0, 0.8, 0.35, 0.02, 21), &truth());
        // Unoriented normals: the sign convention "toward the origin" is not motion-invariant
        // (and none of the metrics depends on the sign).
        let prep = PrepareConfig {
            normals: NormalSource::Estimate(NormalConfig { k: 12, orientation: NormalOrientation::Unoriented }),
            ..Default::default()
        };
        let cloud = |p: Vec<Point3<f64>>| PreparedCloud::new(&PointCloud::from_positions(p), &prep).unwrap();
        let config = IcpConfig { metric, max_iterations: 500, ..tight() };
        let a = register(&cloud(source_pts.clone()), &cloud(target_pts.clone()), &Isometry3::identity(), &config).unwrap();
        let gs: Vec<_> = source_pts.iter().map(|p| g * p).collect();
        let gt: Vec<_> = target_pts.iter().map(|p| g * p).collect();
        let b = register(&cloud(gs), &cloud(gt), &(g * Isometry3::identity() * g.inverse()), &config).unwrap();
        let mapped = g * a.pose * g.inverse();
        let e = PoseError::between(&b.pose, &mapped, &target_pts.iter().map(|p| g * p).collect::<Vec<_>>());
        // Both runs stop within 1e-10 rad / 1e-9 mm of the same fixed point; coordinates up to
        // 2.3 m carry ~5e-13 mm rounding per operation. 1e-6 mm leaves room for both.
        prop_assert!(e.rms_displacement_mm < 1e-6 && e.rotation_deg < 1e-7, "{:?} {:?}", metric, e);
        prop_assert_eq!(a.inliers, b.inliers);
        prop_assert!((a.rmse - b.rmse).abs() < 1e-6);
    }
}

#[test]
fn the_answer_is_the_same_bits_on_any_number_of_threads() {
    // ~10k points: several of the fold's fixed blocks (2048 points), which rayon hands to
    // one, two or four threads as they come. The sums are grouped by block, not by how the
    // work was split, so the registration (pose, residual, information) is the same to the
    // last bit; with rayon's `fold`/`reduce` it differed in the last digits between these
    // pools.
    let target = prepared(terrain(0.0, 60.0, 0.6, 0.0, 0.02, 2));
    let source = prepared(moved(&terrain(0.0, 60.0, 0.6, 0.3, 0.02, 3), &truth()));
    assert!(source.len() > 4 * 2048, "{} points", source.len());
    for metric in [
        Metric::PointToPoint,
        Metric::PointToPlane,
        Metric::Generalized,
    ] {
        let config = IcpConfig {
            metric,
            ..IcpConfig::default()
        };
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let r = pool
                .install(|| register(&source, &target, &Isometry3::identity(), &config))
                .unwrap();
            (
                r.pose.to_homogeneous(),
                r.rmse,
                r.inliers,
                r.iterations,
                r.information,
            )
        };
        let one = on(1);
        for threads in [2, 4] {
            assert_eq!(on(threads), one, "{metric:?} on {threads} threads");
        }
    }
}
