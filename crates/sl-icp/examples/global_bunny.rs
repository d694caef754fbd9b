//! Global registration of the bunny pairs from no pose: every ordered pair of the three shared
//! scans, timed by stage and compared with the reference poses of `bun.conf`. Our side of
//! `benches/peers/global_bunny.py`, which runs this binary in the same run as Open3D.
//!
//! ```sh
//! cargo build --release -p sl-icp --example global_bunny
//! SL_DATA=/work/shared/data target/release/examples/global_bunny [RUNS [SOURCE TARGET]]
//! ```
//! With `SOURCE TARGET` (e.g. `bun045 bun000`) only that pair is run (the peer script
//! interleaves the pairs with Open3D's so that both see the same machine load).
//! Times are medians over `RUNS` (default 11) runs on the global rayon pool (all cores):
//! `describe` is both clouds' voxel grid, normals, orientation, FPFH and descriptor tree
//! ([`GlobalCloud::new`], the two in parallel), then matching, RANSAC and the final ICP
//! ([`register_global_prepared`]'s stages); `total` is all of it, what [`register_global`]
//! costs. Success: the RMS displacement of the source's points against the reference is at
//! most 1 mm (the issue's target; a wrong alignment is off by tens of mm).

use std::time::Instant;

use sl_icp::{
    GlobalCloud, GlobalConfig, IcpError, PoseError, match_features, ransac_pose, register,
};

#[path = "../tests/it/support/bunny.rs"]
mod bunny;

/// Default runs per pair; the median is reported.
const RUNS: usize = 11;

/// Success threshold on the RMS displacement, mm.
const SUCCESS_MM: f64 = 1.0;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() -> Result<(), IcpError> {
    let Some(dir) = bunny::bunny_dir("the global bunny table") else {
        return Ok(());
    };
    let runs = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(RUNS)
        .max(1);
    let names = ["bun000", "bun045", "bun090"];
    let scans: Vec<_> = names.iter().map(|n| bunny::load(&dir, n)).collect();
    let config = GlobalConfig::default();
    println!(
        "sl-icp global registration, threads: {}, runs: {runs}",
        rayon::current_num_threads()
    );
    println!(
        "{:<16} {:>9} {:>8} {:>8} {:>8} {:>9} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7}",
        "pair",
        "describe",
        "match",
        "ransac",
        "icp",
        "total med",
        "rot deg",
        "trans mm",
        "rms mm",
        "success",
        "matches",
        "inliers"
    );
    let position = |name: Option<String>| name.and_then(|n| names.iter().position(|&m| m == n));
    let only = position(std::env::args().nth(2)).zip(position(std::env::args().nth(3)));
    let pairs = [(1, 0), (2, 0), (2, 1), (0, 1), (0, 2), (1, 2)];
    for (s, t) in pairs {
        if only.is_some_and(|o| o != (s, t)) {
            continue;
        }
        let reference = bunny::reference(&scans[t], &scans[s]);
        let (mut describe, mut matching, mut ransac_ms, mut icp, mut total) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut successes = 0;
        let mut last = None;
        for _ in 0..runs {
            let t0 = Instant::now();
            let (a, b) = rayon::join(
                || GlobalCloud::new(&scans[s].cloud, &config, names[s]),
                || GlobalCloud::new(&scans[t].cloud, &config, names[t]),
            );
            let (a, b) = (a?, b?);
            describe.push(ms(t0));
            let t1 = Instant::now();
            let matches = match_features(
                a.features(),
                a.feature_index(),
                b.features(),
                b.feature_index(),
                &config.matching,
            )?;
            matching.push(ms(t1));
            let t2 = Instant::now();
            let found = ransac_pose(
                a.prepared().points(),
                b.prepared().points(),
                &matches,
                &config.ransac,
            )?;
            ransac_ms.push(ms(t2));
            let t3 = Instant::now();
            let refined = match &found {
                Some(r) => Some(register(a.prepared(), b.prepared(), &r.pose, &config.icp)?),
                None => None,
            };
            icp.push(ms(t3));
            total.push(ms(t0));
            let e = refined
                .as_ref()
                .map(|r| PoseError::between(&r.pose, &reference, scans[s].cloud.positions()));
            if e.is_some_and(|e| e.rms_displacement_mm <= SUCCESS_MM) {
                successes += 1;
            }
            last = Some((e, matches.len(), found.map_or(0, |r| r.inliers)));
        }
        let pair = format!("{}->{}", names[s], names[t]);
        let (e, n_matches, inliers) = last.unwrap_or((None, 0, 0));
        let (rot, trans, rms) = e.map_or((f64::NAN, f64::NAN, f64::NAN), |e| {
            (e.rotation_deg, e.translation_mm, e.rms_displacement_mm)
        });
        println!(
            "{:<16} {:>9.1} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>8.3} {:>8.3} {:>8.3} {:>7} {:>7} {:>7}",
            pair,
            median(describe),
            median(matching),
            median(ransac_ms),
            median(icp),
            median(total),
            rot,
            trans,
            rms,
            format!("{successes}/{runs}"),
            n_matches,
            inliers
        );
    }
    Ok(())
}
