//! What `slscan` guarantees about its output folders (docs/outputs.md), through the commands:
//! a failed run leaves the last good outputs as they were, a refused session leaves the files
//! beside it, a second run into a held folder is refused naming the holder, and a run does not
//! replace its inputs or another command's outputs unless `--force`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use sl_scan::OutputFolder;

fn slscan(args: &[&str]) -> anyhow::Result<()> {
    crate::run_cli(args)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Every file below `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    crate::common::files_below(dir)
        .into_iter()
        .map(|f| {
            let bytes = std::fs::read(&f).unwrap();
            (f, bytes)
        })
        .collect()
}

/// No staging folder or lock left in `dir`, and no file written there names a staging folder
/// (the outputs name where they are once in place).
fn assert_clean(dir: &Path) {
    for f in crate::common::files_below(dir) {
        let text = f.to_string_lossy().into_owned();
        assert!(
            !text.contains(".slscan-staging") && !text.ends_with(sl_scan::output_folder::LOCK_FILE),
            "left behind: {text}"
        );
        if f.extension().is_some_and(|e| e == "json" || e == "html") {
            let content = std::fs::read_to_string(&f).unwrap();
            assert!(
                !content.contains(".slscan-staging"),
                "{text} names the staging folder"
            );
        }
    }
}

/// A 64x32 column capture whose frames are the patterns themselves (it decodes everywhere),
/// and the same capture with every frame black (it decodes nowhere).
fn good_and_black_captures(dir: &Path) -> (PathBuf, PathBuf) {
    let good = dir.join("good");
    slscan(&[
        "patterns",
        "--projector",
        "64x32",
        "--axes",
        "columns",
        "--out",
        s(&good),
    ])
    .unwrap();
    let black = dir.join("black");
    std::fs::create_dir_all(&black).unwrap();
    let frame = sl_codec::Frame::filled(64, 32, 0).unwrap();
    for f in crate::common::files_below(&good) {
        let to = black.join(f.file_name().unwrap());
        if f.extension().is_some_and(|e| e == "png") {
            sl_codec::write_png_grey8(&to, &frame).unwrap();
        } else if f.file_name().is_some_and(|n| n == "manifest.json") {
            std::fs::copy(&f, &to).unwrap();
        }
    }
    (good, black)
}

/// `decode GOOD --out D`, then `decode BAD --out D` (no pixel decoded, exit 1): D keeps the
/// good decode byte for byte; the failed run's maps and report are kept apart for the
/// diagnosis, and go once a run succeeds. Before, all nine files of D became the empty decode.
#[test]
fn a_failed_decode_keeps_the_good_one() {
    let tmp = tempfile::tempdir().unwrap();
    let (good, black) = good_and_black_captures(tmp.path());
    let out = tmp.path().join("decoded");
    slscan(&["decode", s(&good), "--out", s(&out)]).unwrap();
    assert_clean(&out);
    let before = snapshot(&out);
    assert!(before.len() >= 5, "{:?}", before.keys());
    let err = slscan(&["decode", s(&black), "--out", s(&out)]).unwrap_err();
    let text = format!("{err:#}");
    let failed = out.join(sl_scan::output_folder::FAILED_RUN_DIR);
    assert!(
        text.contains("no pixel decoded") && text.contains(s(&failed)),
        "{text}"
    );
    assert!(failed.join("report.json").is_file());
    let after: BTreeMap<_, _> = snapshot(&out)
        .into_iter()
        .filter(|(f, _)| !f.starts_with(&failed))
        .collect();
    assert_eq!(after, before, "the good decode was changed");
    slscan(&["decode", s(&good), "--out", s(&out)]).unwrap();
    assert!(
        !failed.exists(),
        "a success clears the failure kept for the diagnosis"
    );
}

/// `capture --downscale 8`, then the same folder with `--downscale 4` (other patterns):
/// refused, and `calibration_true.json` still the one the session was captured with. Before,
/// it was rewritten for the other size before the refusal.
#[test]
fn a_refused_capture_keeps_its_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("session");
    let capture = |downscale: &str| {
        slscan(&[
            "capture",
            "--scene",
            "plane",
            "--views",
            "2",
            "--downscale",
            downscale,
            "--out",
            s(&out),
        ])
    };
    capture("8").unwrap();
    assert_clean(&out);
    let before = snapshot(&out);
    let err = capture("4").unwrap_err();
    assert!(format!("{err:#}").contains("other patterns"), "{err:#}");
    assert_eq!(snapshot(&out), before);
}

/// `scan --out S` where `S/session` holds a session of another plan: refused before the
/// calibration is written. Before, `S/calibration.json` was replaced by the new run's, then
/// the capture refused.
#[test]
fn a_refused_scan_keeps_its_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("scan");
    slscan(&[
        "capture",
        "--scene",
        "plane",
        "--views",
        "2",
        "--downscale",
        "8",
        "--out",
        s(&out.join("session")),
    ])
    .unwrap();
    std::fs::write(
        out.join("calibration.json"),
        "the calibration of the session",
    )
    .unwrap();
    let before = snapshot(&out);
    let err = slscan(&["scan", "--views", "3", "--downscale", "8", "--out", s(&out)]).unwrap_err();
    assert!(format!("{err:#}").contains("session of 2 views"), "{err:#}");
    assert_eq!(snapshot(&out), before);
}

/// `simulate --patterns P` with patterns for another projector: refused, and nothing written
/// into `--out`. Before, `rig.json` and `calibration.json` were written first.
#[test]
fn a_refused_simulation_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let patterns = tmp.path().join("patterns");
    slscan(&[
        "patterns",
        "--projector",
        "64x32",
        "--axes",
        "columns",
        "--out",
        s(&patterns),
    ])
    .unwrap();
    let out = tmp.path().join("sim");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("rig.json"), "an earlier rig").unwrap();
    let before = snapshot(&out);
    let err = slscan(&[
        "simulate",
        "--scene",
        "plane",
        "--patterns",
        s(&patterns),
        "--out",
        s(&out),
    ])
    .unwrap_err();
    assert!(format!("{err:#}").contains("64"), "{err:#}");
    assert_eq!(snapshot(&out), before);
}

/// A folder another run holds: `decode`, `reconstruct`-like staged commands and `capture` are
/// refused naming the holder's process id; the holder's files are untouched. Before, two
/// runs 0.1 s apart both wrote, leaving a cloud of one beside the report of the other.
#[test]
fn a_held_folder_is_refused_naming_its_holder() {
    let tmp = tempfile::tempdir().unwrap();
    let (good, _) = good_and_black_captures(tmp.path());
    let out = tmp.path().join("held");
    let holder = OutputFolder::in_place(&out, "slscan capture (the test)").unwrap();
    let pid = format!("pid {}", std::process::id());
    let err = slscan(&["decode", s(&good), "--out", s(&out)]).unwrap_err();
    assert!(format!("{err:#}").contains(&pid), "{err:#}");
    let err = slscan(&[
        "capture",
        "--scene",
        "plane",
        "--views",
        "2",
        "--downscale",
        "8",
        "--out",
        s(&out),
    ])
    .unwrap_err();
    assert!(format!("{err:#}").contains(&pid), "{err:#}");
    let err = slscan(&[
        "calibrate",
        "capture",
        "--virtual",
        "--auto",
        "--poses",
        "1",
        "--out",
        s(&out),
    ])
    .unwrap_err();
    assert!(format!("{err:#}").contains(&pid), "{err:#}");
    assert!(!out.join("report.json").exists() && !out.join("session.json").exists());
    drop(holder);
    slscan(&["decode", s(&good), "--out", s(&out)]).unwrap();
    assert_clean(&out);
}

/// Outputs that would replace inputs: `mesh D/mesh.ply --out D`, `merge a.ply b.ply --out
/// a.ply` and `report SCAN/merged.ply --out SCAN` are refused (nothing changed) and name
/// `--force`; forced, the mesh is remeshed from the input it replaces. Before, each replaced
/// its input (or the scan's report) without a word.
#[test]
fn inputs_are_not_replaced_without_force() {
    let tmp = tempfile::tempdir().unwrap();
    let (ball, truth) = crate::mesh::tests::ball_files(tmp.path(), |_| true, 2.0);
    let d = tmp.path().join("meshed");
    let mesh = |input: &Path, extra: &[&str]| {
        let mut args = vec!["mesh", s(input), "--out", s(&d), "--depth", "6"];
        args.extend_from_slice(extra);
        slscan(&args)
    };
    mesh(&ball, &[]).unwrap();
    assert_clean(&d);
    let before = snapshot(&d);
    let err = mesh(&d.join("mesh.ply"), &[]).unwrap_err();
    let text = format!("{err:#}");
    assert!(
        text.contains("mesh.ply") && text.contains("--force"),
        "{text}"
    );
    assert_eq!(snapshot(&d), before);
    mesh(&d.join("mesh.ply"), &["--force"]).unwrap();
    assert_clean(&d);

    let a = tmp.path().join("a.ply");
    std::fs::copy(&ball, &a).unwrap();
    let a_bytes = std::fs::read(&a).unwrap();
    let err = slscan(&["merge", s(&a), s(&ball), "--out", s(&a)]).unwrap_err();
    let text = format!("{err:#}");
    assert!(text.contains("a.ply") && text.contains("--force"), "{text}");
    assert_eq!(std::fs::read(&a).unwrap(), a_bytes);

    // A scan's folder: its report holds the calibration and views figures.
    let scan = tmp.path().join("scan");
    let folder = OutputFolder::in_place(&scan, "slscan scan").unwrap();
    std::fs::copy(&ball, scan.join("merged.ply")).unwrap();
    std::fs::write(scan.join("report.json"), "{\"command\": \"scan\"}").unwrap();
    folder.commit().unwrap();
    let before = snapshot(&scan);
    let err = slscan(&[
        "report",
        s(&scan.join("merged.ply")),
        "--truth",
        s(&truth),
        "--out",
        s(&scan),
    ])
    .unwrap_err();
    let text = format!("{err:#}");
    assert!(
        text.contains("slscan scan") && text.contains("--force"),
        "{text}"
    );
    assert_eq!(snapshot(&scan), before);
}
