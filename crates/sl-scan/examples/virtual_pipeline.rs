//! Calibrate, scan and mesh on the virtual rig through `sl-scan`'s public API alone: the
//! pipeline `slscan scan` runs, as a Rust program would run it on its own devices (swap
//! `rig.devices()` for `sl_rig::with_devices`).
//!
//! `cargo run -p sl-scan --example virtual_pipeline --release [-- OUT_DIR]` (a quarter of the
//! rig's resolution, 8 views: seconds).

use std::path::PathBuf;
use std::time::Duration;

use sl_codec::{BitDepth, ImageSize};
use sl_rig::{CaptureSession, SessionConfig, SessionDevices, SessionPlan};
use sl_scan::{
    MeshChainConfig, SCAN_PERIOD_PX, SessionScanConfig, VirtualScanConfig, calibrate_virtual,
    full_turn_motor_angles, load_scan_calibration, mesh_chain, scaled_rig_config, scan_patterns,
    scan_session,
};
use sl_sim::{Scene, VirtualRig};

/// The rig's resolution divided by this: fast, still a closed mesh.
const DOWNSCALE: u32 = 4;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args_os().nth(1).map_or_else(
        || std::env::temp_dir().join("sl-scan-virtual-pipeline"),
        PathBuf::from,
    );
    std::fs::create_dir_all(&out)?;
    let rig = VirtualRig::new(scaled_rig_config(DOWNSCALE), Scene::dumbbell())?;

    // 1. Calibrate camera, projector and turntable from simulated board captures.
    let cfg = VirtualScanConfig {
        resolution_divisor: DOWNSCALE,
        ..VirtualScanConfig::default()
    };
    let (calibration, summary) = calibrate_virtual(&rig, &cfg, |_| {})?;
    println!(
        "calibrated from {} poses: RMS camera {:.3} / projector {:.3} / stereo {:.3} px; axis {:.4}° / {:.3} mm off the truth",
        summary.poses_used,
        summary.rms_camera_px,
        summary.rms_projector_px,
        summary.rms_stereo_px,
        summary.axis_direction_error_deg,
        summary.axis_position_error_mm
    );
    let calib_path = out.join("calibration.json");
    calibration.save(&calib_path)?;
    let calibration = load_scan_calibration(&calib_path)?;

    // 2. Capture a session through the device traits: a full platter turn in 8 views.
    let p = rig.config().projector.size;
    let plan = SessionPlan {
        angles_deg: full_turn_motor_angles(calibration.turntable.as_ref(), 8)?,
        manifest: scan_patterns(ImageSize::new(p.width, p.height), SCAN_PERIOD_PX)
            .manifest(BitDepth::Eight),
        devices: SessionDevices {
            camera: "virtual".into(),
            projector: "virtual".into(),
            turntable: "virtual".into(),
        },
        calibration: Some(calib_path),
    };
    let session_dir = out.join("session");
    let config = SessionConfig {
        display_latency: Duration::ZERO,
        flush_frames: 0,
        overwrite: true,
    };
    let (mut camera, mut projector, mut table) = rig.devices();
    CaptureSession::open(&session_dir, plan, config)?.run(
        &mut camera,
        &mut projector,
        &mut table,
        |_| {},
    )?;

    // 3. Reconstruct and merge the views, then 4. mesh the merged cloud.
    let scan = scan_session(
        &session_dir,
        &calibration,
        &SessionScanConfig::default(),
        |_| {},
    )?;
    let chain = mesh_chain(&scan.merged, &MeshChainConfig::default())?;
    println!(
        "{} merged points; mesh of {} triangles, watertight {}",
        scan.merged.len(),
        chain.mesh.triangles.len(),
        chain.topology.is_watertight()
    );
    Ok(())
}
