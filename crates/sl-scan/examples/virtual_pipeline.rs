//! Calibrate, scan and mesh on the virtual rig through `sl-scan`'s public API alone: the
//! pipeline `slscan scan` runs, as a Rust program would run it on its own devices (swap
//! `rig.devices()` for `sl_rig::with_devices`).
//!
//! `cargo run -p sl-scan --example virtual_pipeline --release [-- OUT_DIR]` (a quarter of the
//! rig's resolution, 8 views: seconds).

use std::path::PathBuf;
use std::time::Duration;

use sl_codec::BitDepth;
use sl_rig::{CaptureSession, SessionConfig, SessionPlan};
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
    let (s, a) = (&summary, summary.axis_direction_error_deg);
    println!(
        "calibrated from {} poses: RMS camera {:.3}, projector {:.3} px; axis {a:.4}° off",
        s.poses_used, s.rms_camera_px, s.rms_projector_px
    );
    let calib_path = out.join("calibration.json");
    calibration.save(&calib_path)?;
    let calibration = load_scan_calibration(&calib_path)?;

    // 2. Capture a session through the device traits: a full platter turn in 8 views.
    let plan = SessionPlan {
        angles_deg: full_turn_motor_angles(calibration.turntable.as_ref(), 8)?,
        manifest: scan_patterns(rig.config().projector.size, SCAN_PERIOD_PX)
            .manifest(BitDepth::Eight),
        devices: rig.session_devices("virtual turntable"),
        calibration: Some(calib_path),
        exposures: Default::default(),
        colour: false,
    };
    let session_dir = out.join("session");
    let config = SessionConfig {
        display_latency: Duration::ZERO,
        overwrite: true,
        ..SessionConfig::default()
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
