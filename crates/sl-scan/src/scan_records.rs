//! What a scan leaves for its user beside its files: the figures of its `report.json` and the
//! lines a command line prints, for the virtual scan ([`ScanResult`], [`PlacementsResult`])
//! and the scan on devices ([`DeviceScan`]). `slscan scan` prints and writes exactly these; a
//! program that runs the same scans gets the same record.

use std::io::{BufRead, Write};
use std::path::Path;
use std::time::Duration;

use serde::Serialize;

use crate::{
    DeviceScan, RunReport, ScanError, ScanOperator, SessionCapture, StageTime, placement_dir_name,
};
#[cfg(feature = "mesh")]
use crate::{MeshFiles, MeshSummary};
#[cfg(feature = "sim")]
use crate::{PlacementsResult, ScanResult, TRUTH_MESH_FILE};

/// What the virtual single-placement scan measures: its `scene` figure.
#[cfg(feature = "sim")]
const DUMBBELL_SCENE: &str =
    "dumbbell: two spheres r = 25 mm, centres 120 mm apart; then a tilted 160 x 100 mm plate";

/// What the virtual scan of two placements measures: its `scene` figure.
#[cfg(feature = "sim")]
const PEBBLE_SCENE: &str =
    "pebble: a bumpy body about 80 mm across with a flat bottom, standing, then laid on its side";

/// The `accuracy` figure of a scan on devices: a real object has no truth.
const NO_TRUTH: &str = "no truth for a real object: run `slscan report merged.ply --truth …` on a scan of a known sphere or plane";

/// The question the terminal asks before the next placement.
pub const REPLACE_PROMPT: &str = "lay the object on its side and press Enter";

impl RunReport {
    /// Records the figure `name` as the JSON of `value`.
    ///
    /// # Errors
    /// [`ScanError::Stage`] (stage `report`) when `value` has no JSON form (a map with keys
    /// that are not strings; none of this crate's results).
    pub fn figure_of(&mut self, name: &str, value: &impl Serialize) -> Result<(), ScanError> {
        let json = serde_json::to_value(value).map_err(|e| ScanError::Stage {
            stage: "report".into(),
            reason: format!("figure {name}: {e}"),
        })?;
        self.figure(name, json);
        Ok(())
    }
}

/// `watertight` or `NOT watertight`, for the line that names a mesh.
#[must_use]
pub fn watertight_word(closed: bool) -> &'static str {
    if closed {
        "watertight"
    } else {
        "NOT watertight"
    }
}

/// The stage timings, a line each: `  capture        33.76 s`.
#[must_use]
pub fn stage_lines(stages: &[StageTime]) -> Vec<String> {
    stages
        .iter()
        .map(|s| format!("  {:<12} {:>7.2} s", s.name, s.ms / 1e3))
        .collect()
}

#[cfg(feature = "sim")]
impl ScanResult {
    /// Records the scan's figures (`views` asked for) and its stage times in `report`.
    ///
    /// # Errors
    /// Those of [`RunReport::figure_of`].
    pub fn record(&self, report: &mut RunReport, views: usize) -> Result<(), ScanError> {
        report.figure("scene", DUMBBELL_SCENE);
        report.figure("finish", self.finish.name());
        report.figure_of("exposures", &self.exposures)?;
        report.figure("views", views);
        report.figure("views_captured_this_run", self.views_captured);
        report.figure("view_points", self.view_points.clone());
        report.figure("merged_points", self.merged.len());
        report.figure_of("calibration", &self.calibration_summary)?;
        report.figure_of("accuracy", &self.accuracy)?;
        report.figure_of("flatness", &self.flatness)?;
        report.figure_of("plate_phase", &self.plate_phase)?;
        report.figure_of("first_view", &self.first_view)?;
        report.figure_of("mesh", &self.mesh)?;
        report.figure_of("colour", &self.colour)?;
        report.figure_of("merge", &self.merge)?;
        report.figure_of("files", &self.files)?;
        report.add_stages(&self.stages);
        Ok(())
    }

    /// What the scan found, a line each: the calibration, the merged cloud (written into
    /// `out`), the poses, the measurements against the truth and the stage times.
    #[must_use]
    pub fn summary(&self, out: &Path, views: usize) -> Vec<String> {
        let c = &self.calibration_summary;
        // In a binocular scan the second device of the calibration is the right camera.
        let (first, second) = match self.pair {
            Some(_) => ("left camera", "right camera"),
            None => ("camera", "projector"),
        };
        let mut lines = vec![format!(
            "calibration: RMS {first} {:.3} px, {second} {:.3} px, stereo {:.3} px; axis {:.4} deg / {:.3} mm off the truth",
            c.rms_camera_px,
            c.rms_projector_px,
            c.rms_stereo_px,
            c.axis_direction_error_deg,
            c.axis_position_error_mm
        )];
        if let Some(p) = &c.predicted_error {
            lines.push(format!("calibration: {}", p.sentence()));
        }
        if !self.exposures.is_single() {
            let times: Vec<String> = self
                .exposures
                .times_ms
                .iter()
                .map(|t| format!("{t:.3}"))
                .collect();
            lines.push(format!(
                "exposures: {} ms, fused per pixel ({}); the {} dumbbell",
                times.join(", "),
                self.exposures.fusion.method.name(),
                self.finish.name()
            ));
        }
        lines.push(format!(
            "{}: {} points merged from {views} views",
            out.join(&self.files.merged).display(),
            self.merged.len(),
        ));
        lines.push(format!("  poses: {}", self.merge.summary));
        lines.extend(
            self.accuracy
                .summary()
                .into_iter()
                .map(|l| format!("  {l}")),
        );
        for s in &self.first_view.spheres {
            lines.push(format!(
                "  first view alone: {} form {:.4} mm ({:.4} mm trimmed), fit RMS {:.4} mm, {} points",
                s.name, s.probing_form_mm, s.probing_form_trimmed_mm, s.fit_rms_mm, s.points
            ));
        }
        if let Some(f) = &self.flatness {
            lines.extend(f.summary().into_iter().map(|l| format!("  {l}")));
        }
        if let Some(p) = &self.plate_phase {
            lines.push(format!(
                "  plate: decoded projector columns against the truth over {} pixels: RMS {:.4} px ({:.4} rad), 99 % within {:.4} px, mean {:+.4} px",
                p.pixels, p.rms_px, p.rms_rad, p.p99_px, p.mean_px
            ));
        }
        if let Some(r) = &self.calibration_summary.response {
            let errors: Vec<String> = r
                .phase_error_rad
                .iter()
                .map(|(n, e)| match e {
                    Some(e) => format!("{n} steps {e:.4} rad"),
                    None => format!("{n} steps: folds the phase"),
                })
                .collect();
            let truth = r
                .truth_difference
                .map(|d| format!(" (within {d:.4} of the true curve)"))
                .unwrap_or_default();
            lines.push(format!(
                "  projector response measured on {} pixels ({}/): equivalent gamma {:.3}{truth}; fringes it is not corrected for would have a phase error of up to {}",
                r.pixels,
                r.ramp.display(),
                r.equivalent_gamma,
                errors.join(", ")
            ));
        }
        if let Some(c) = &self.colour {
            for (what, acc) in [("merged cloud", &c.cloud), ("mesh vertices", &c.mesh)] {
                if let Some(a) = acc {
                    lines.push(format!(
                        "  colour ({} views, {}): {what} against the true albedo over {} points: RMS {:.1} levels ({:.1} %) after gains {:.0}/{:.0}/{:.0}; hue angle median {:.2} deg, 95 % within {:.2} deg",
                        c.views,
                        c.source,
                        a.points,
                        a.rms_levels,
                        100.0 * a.rms_relative,
                        a.gain[0],
                        a.gain[1],
                        a.gain[2],
                        a.angle_median_deg,
                        a.angle_p95_deg
                    ));
                }
            }
        }
        lines.extend(stage_lines(&self.stages));
        lines
    }
}

#[cfg(feature = "sim")]
impl PlacementsResult {
    /// Records the figures of a scan of `placements` placements of `views` views each and its
    /// stage times in `report`.
    ///
    /// # Errors
    /// Those of [`RunReport::figure_of`].
    pub fn record(
        &self,
        report: &mut RunReport,
        placements: usize,
        views: usize,
    ) -> Result<(), ScanError> {
        report.figure("scene", PEBBLE_SCENE);
        report.figure("placements", placements);
        report.figure("views", views);
        report.figure_of("calibration", &self.calibration_summary)?;
        report.figure_of("per_placement", &self.placements)?;
        report.figure("merged_points", self.merged.len());
        report.figure("coverage_spacing_mm", self.spacing_mm);
        report.figure_of("coverage", &self.coverage)?;
        report.figure_of("distance_to_truth", &self.distance)?;
        report.figure_of("mesh", &self.mesh)?;
        report.figure(
            "files",
            serde_json::json!({
                "merged": self.merged_file,
                "previews": self.previews,
                "truth_mesh": TRUTH_MESH_FILE,
                "mesh": self.mesh_files,
            }),
        );
        report.add_stages(&self.stages);
        Ok(())
    }

    /// What the scan found, a line each: each placement, all of them merged (into `out`), the
    /// mesh and the stage times.
    #[must_use]
    pub fn summary(&self, out: &Path) -> Vec<String> {
        let mut lines = Vec::new();
        for p in &self.placements {
            let aligned = p.alignment.as_ref().map_or(String::new(), |a| {
                format!(
                    "; aligned onto placement 1 with no pose hint: fitness {:.3}, RMSE {:.3} mm",
                    a.fitness, a.rmse_mm
                )
            });
            lines.push(format!(
                "placement {}: {} points, covers {:.2} % of the true surface, RMS {:.4} mm to it{aligned}",
                p.placement,
                p.merged_points,
                100.0 * p.coverage.covered_fraction,
                p.distance.rms_mm
            ));
            lines.push(format!("  poses: {}", p.merge.summary));
        }
        lines.push(format!(
            "{}: {} points merged from {} placements: covers {:.2} % of the true surface (within {:.2} mm), RMS {:.4} mm to it ({} points beyond {} mm)",
            out.join(&self.merged_file).display(),
            self.merged.len(),
            self.placements.len(),
            100.0 * self.coverage.covered_fraction,
            self.coverage.distance_mm,
            self.distance.rms_mm,
            self.distance.outliers,
            self.distance.select_mm
        ));
        if let Some(m) = &self.mesh {
            lines.push(format!(
                "  mesh: {} triangles, {}",
                m.triangles,
                watertight_word(m.watertight)
            ));
        }
        lines.extend(stage_lines(&self.stages));
        lines
    }
}

impl DeviceScan {
    /// Records the scan's figures (its calibration file, whether ICP refined the turntable
    /// poses) and stage times in `report`, and the mesh stage's outcome when the feature
    /// `mesh` is on. The mesh's error, if any, is recorded (`mesh_error`) and left in
    /// [`DeviceScan::mesh`] for the caller to report.
    ///
    /// # Errors
    /// Those of [`RunReport::figure_of`].
    pub fn record(
        &self,
        report: &mut RunReport,
        calibration: &Path,
        icp_refinement: bool,
    ) -> Result<(), ScanError> {
        report.add_stages(&self.stages);
        report.figure("rig", "hardware");
        report.figure("cameras", if self.binocular { 2 } else { 1 });
        report.figure("calibration", calibration.display().to_string());
        // Frames the checks named while capturing: captured again, or kept and named.
        let (mut recaptured, mut frame_issues) = (Vec::new(), Vec::new());
        for p in &self.placements {
            for v in &p.capture.summary.views {
                let at = |m: &String| format!("placement {} view {}: {m}", p.placement, v.index);
                recaptured.extend(v.recaptured.iter().map(at));
                frame_issues.extend(v.frame_issues.iter().map(at));
            }
        }
        report.figure("recaptured_frames", recaptured);
        report.figure("frame_issues", frame_issues);
        if let [single] = self.placements.as_slice() {
            let s = &single.scan;
            report.figure("views", s.view_points.len());
            report.figure("motor_angles_deg", s.motor_angles_deg.clone());
            report.figure("platter_angles_deg", s.platter_angles_deg.clone());
            report.figure("view_points", s.view_points.clone());
            report.figure("merged_points", self.merged.len());
            report.figure("icp_refinement", icp_refinement);
            report.figure_of("merge", &s.merge)?;
            report.figure("accuracy", NO_TRUTH);
            report.figure_of("files", &self.files)?;
            report.figure("session", crate::PLACEMENT_SESSION_DIR);
        } else {
            let mut per_placement = Vec::new();
            for p in &self.placements {
                per_placement.push(serde_json::json!({
                    "placement": p.placement,
                    "views": p.scan.view_points.len(),
                    "view_points": p.scan.view_points,
                    "merged_points": p.scan.merged.len(),
                    "merge": p.scan.merge,
                    "merged": p.files.as_ref().map_or_else(
                        || format!("{}/merged.ply", placement_dir_name(p.placement)),
                        |f| f.merged.clone(),
                    ),
                    "alignment": p.alignment,
                }));
            }
            report.figure("placements", self.placements.len());
            report.figure("per_placement", serde_json::Value::Array(per_placement));
            report.figure("merged_points", self.merged.len());
            report.figure_of("files", &self.files)?;
        }
        #[cfg(feature = "mesh")]
        match &self.mesh {
            Some(Ok((mesh, files))) => {
                report.figure_of("mesh", mesh)?;
                report.figure_of("mesh_files", files)?;
            }
            Some(Err(e)) => report.figure("mesh_error", e.to_string()),
            None => {}
        }
        Ok(())
    }

    /// What the scan found, a line each: the poses or the placements' alignments, the merged
    /// cloud (written into `out`, with `calibration`), the mesh and the stage times.
    #[must_use]
    pub fn summary(&self, out: &Path, calibration: &Path) -> Vec<String> {
        let mut lines = Vec::new();
        let merged = out.join(&self.files.merged);
        if let [single] = self.placements.as_slice() {
            lines.push(format!("poses: {}", single.scan.merge.summary));
            lines.push(format!(
                "{}: {} points merged from {} views{} (calibration {})",
                merged.display(),
                self.merged.len(),
                single.scan.view_points.len(),
                if self.binocular {
                    " of two cameras"
                } else {
                    ""
                },
                calibration.display()
            ));
            #[cfg(feature = "mesh")]
            if let Some((mesh, files)) = self.meshed() {
                lines.push(format!(
                    "{}: {} triangles, {}",
                    out.join(&files.ply).display(),
                    mesh.triangles,
                    watertight_word(mesh.watertight)
                ));
            }
            lines.extend(stage_lines(&self.stages));
        } else {
            for a in self.placements.iter().filter_map(|p| p.alignment.as_ref()) {
                lines.push(format!(
                    "placement {} aligned onto placement 1 with no pose hint: fitness {:.3}, RMSE {:.3} mm",
                    a.placement, a.fitness, a.rmse_mm
                ));
            }
            lines.push(format!(
                "{}: {} points merged from {} placements (calibration {})",
                merged.display(),
                self.merged.len(),
                self.placements.len(),
                calibration.display()
            ));
        }
        lines
    }

    /// The mesh and its files when the mesh stage ran and succeeded.
    #[cfg(feature = "mesh")]
    #[must_use]
    pub fn meshed(&self) -> Option<(&MeshSummary, &MeshFiles)> {
        match &self.mesh {
            Some(Ok((mesh, files))) => Some((mesh, files)),
            _ => None,
        }
    }
}

/// The [`ScanOperator`] of a terminal: each placement's session is announced on `output`; before
/// the next placement the user is asked to lay the object on its side and press Enter on
/// `input` — or, with a wait, told so and given that many seconds (for scripts).
#[derive(Debug)]
pub struct TerminalOperator<I, O> {
    input: I,
    output: O,
    wait_s: Option<f64>,
}

impl<I: BufRead, O: Write> TerminalOperator<I, O> {
    /// An operator reading answers from `input` and writing to `output`, or waiting `wait_s`
    /// seconds instead of asking.
    pub fn new(input: I, output: O, wait_s: Option<f64>) -> Self {
        Self {
            input,
            output,
            wait_s,
        }
    }
}

impl<I: BufRead, O: Write> ScanOperator for TerminalOperator<I, O> {
    fn replace(&mut self, next: usize, total: usize) -> Result<(), ScanError> {
        let failed = |reason: String| ScanError::Stage {
            stage: "placements".into(),
            reason,
        };
        // What the terminal shows is a courtesy: a closed output does not stop the scan.
        match self.wait_s {
            Some(s) => {
                let wait = Duration::try_from_secs_f64(s).map_err(|_| {
                    failed(format!("--placement-wait {s}: not a number of seconds"))
                })?;
                let _ = writeln!(
                    self.output,
                    "placement {next} of {total}: lay the object on its side; scanning again in {s} s (--placement-wait)"
                );
                let _ = self.output.flush();
                std::thread::sleep(wait);
            }
            None => {
                let _ = write!(
                    self.output,
                    "placement {next} of {total}: {REPLACE_PROMPT} "
                );
                let _ = self.output.flush();
                let mut line = String::new();
                let read = self
                    .input
                    .read_line(&mut line)
                    .map_err(|e| failed(format!("reading the answer from stdin: {e}")))?;
                if read == 0 {
                    return Err(failed(format!(
                        "stdin closed before placement {next} was confirmed: press Enter in a terminal, or pass --placement-wait SECONDS"
                    )));
                }
            }
        }
        Ok(())
    }

    fn capturing(&mut self, placement: usize, total: usize, dir: &Path) -> Result<(), ScanError> {
        if total > 1 {
            let _ = writeln!(
                self.output,
                "placement {placement}: capturing {}",
                dir.display()
            );
        }
        Ok(())
    }

    fn captured(&mut self, placement: usize, capture: &SessionCapture) -> Result<(), ScanError> {
        let path = capture.write_report().map_err(|e| ScanError::Stage {
            stage: "capture".into(),
            reason: format!("placement {placement}: {e}"),
        })?;
        for line in capture.summary(&path) {
            let _ = writeln!(self.output, "{line}");
        }
        Ok(())
    }
}

impl SessionCapture {
    /// Writes the session's `report.json` into its folder (`command` `capture`: the views
    /// captured and kept, the latency when measured, the stage times) and returns its path.
    ///
    /// # Errors
    /// [`RunReport::write`]'s, naming the file.
    pub fn write_report(&self) -> Result<std::path::PathBuf, ScanError> {
        let mut report = RunReport::new("capture");
        report.started_before(self.stages.iter().map(|s| s.ms).sum());
        if let Some(latency) = &self.latency {
            report.figure_of("latency", latency)?;
        }
        report.add_stages(&self.stages);
        let summary = &self.summary;
        report.figure("views", summary.views.len());
        report.figure("captured", summary.captured);
        report.figure("kept_from_earlier_run", summary.skipped);
        report.figure_of("views_detail", &summary.views)?;
        report.write(&self.session)
    }

    /// What the capture did, a line each: the latency when measured, the views captured and
    /// kept (with the `report` written by [`SessionCapture::write_report`]).
    #[must_use]
    pub fn summary(&self, report: &Path) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(latency) = &self.latency {
            lines.push(format!(
                "latency: {} frame(s) to flush, {:.1} ms from show to a frame that shows it",
                latency.frames, latency.ms
            ));
        }
        lines.push(format!(
            "{}: {} views captured, {} kept from an earlier run (report: {})",
            self.session.display(),
            self.summary.captured,
            self.summary.skipped,
            report.display()
        ));
        lines
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    /// Between two placements the user is asked to lay the object on its side and press
    /// Enter; a closed stdin names the non-interactive option; a wait reads nothing.
    #[test]
    fn the_replace_prompt_waits_for_enter_or_the_given_time() {
        let mut out = Vec::new();
        TerminalOperator::new("\n".as_bytes(), &mut out, None)
            .replace(2, 2)
            .unwrap();
        let said = String::from_utf8(out).unwrap();
        assert!(
            said.contains(REPLACE_PROMPT) && said.contains("placement 2 of 2"),
            "{said}"
        );
        let e = TerminalOperator::new("".as_bytes(), Vec::new(), None)
            .replace(2, 2)
            .unwrap_err();
        assert!(e.to_string().contains("--placement-wait"), "{e}");
        let mut input = "not read\n".as_bytes();
        TerminalOperator::new(&mut input, Vec::new(), Some(0.0))
            .replace(2, 2)
            .unwrap();
        assert_eq!(input, b"not read\n");
        let e = TerminalOperator::new(&mut input, Vec::new(), Some(-1.0))
            .replace(2, 2)
            .unwrap_err();
        assert!(e.to_string().contains("--placement-wait -1"), "{e}");
    }

    #[test]
    fn stage_lines_align_names_and_seconds() {
        let lines = stage_lines(&[StageTime {
            name: "capture".into(),
            ms: 33_760.0,
        }]);
        assert_eq!(lines, ["  capture        33.76 s"]);
    }
}
