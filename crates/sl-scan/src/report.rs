//! The report stage: the merged cloud as PLY, shaded previews, error heat maps and the
//! one-page summary (`index.html`; `report.json` is written by the caller, `slscan`).

use std::path::Path;
#[cfg(feature = "sim")]
use std::path::PathBuf;

use serde::Serialize;
use sl_cloud::{PlyFormat, PointCloud, PreviewColoring, PreviewConfig, render_preview, write_ply};
use sl_codec::write_png_rgb8;
use sl_metrology::{DEFAULT_HEAT_MAP_RANGE_MM, Report, heat_map};

#[cfg(feature = "sim")]
use crate::ScanResult;
use crate::error::io;
use crate::{ScanError, ScanProgress};

/// Viewpoints of the previews: azimuth and elevation (degrees).
const PREVIEWS: [(f64, f64); 4] = [(0.0, 20.0), (90.0, 20.0), (180.0, 20.0), (0.0, 80.0)];

/// Files written by [`write_scan_cloud`], relative to the output folder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SessionScanFiles {
    /// The merged cloud.
    pub merged: String,
    /// Shaded previews from several viewpoints.
    pub previews: Vec<String>,
}

/// Writes the merged cloud (`merged.ply`) and shaded previews (`preview_*.png`) into `out`
/// (created when missing), reporting each preview as progress of the stage `report`.
///
/// # Errors
/// [`ScanError::Io`] naming the folder; the PLY's and the pictures' errors.
pub fn write_scan_cloud(
    out: &Path,
    merged: &PointCloud,
    mut progress: impl FnMut(ScanProgress<'_>),
) -> Result<SessionScanFiles, ScanError> {
    std::fs::create_dir_all(out).map_err(io(out))?;
    let merged_name = "merged.ply".to_owned();
    write_ply(&out.join(&merged_name), merged, PlyFormat::default())?;
    let mut previews = Vec::with_capacity(PREVIEWS.len());
    for (k, &(az, el)) in PREVIEWS.iter().enumerate() {
        let name = format!("preview_{k}.png");
        write_preview(&out.join(&name), merged, PreviewColoring::Grey, az, el)?;
        previews.push(name);
        progress(ScanProgress {
            stage: "report",
            done: k + 1,
            total: PREVIEWS.len(),
        });
    }
    Ok(SessionScanFiles {
        merged: merged_name,
        previews,
    })
}

/// Writes the heat map of `report` over `cloud` to `path`.
pub fn write_heat_map(path: &Path, cloud: &PointCloud, report: &Report) -> Result<(), ScanError> {
    let view = PreviewConfig {
        azimuth_deg: 0.0,
        elevation_deg: 20.0,
        ..PreviewConfig::default()
    };
    let mut img = heat_map(
        cloud,
        &report.signed_distances_mm,
        DEFAULT_HEAT_MAP_RANGE_MM,
        &view,
    )?;
    sl_metrology::draw_legend(&mut img, DEFAULT_HEAT_MAP_RANGE_MM);
    write_png_rgb8(path, img.width as usize, img.height as usize, &img.rgb)?;
    Ok(())
}

fn write_preview(
    path: &Path,
    cloud: &PointCloud,
    coloring: PreviewColoring<'_>,
    azimuth_deg: f64,
    elevation_deg: f64,
) -> Result<(), ScanError> {
    let cfg = PreviewConfig {
        azimuth_deg,
        elevation_deg,
        ..PreviewConfig::default()
    };
    let img = render_preview(cloud, coloring, &cfg)?;
    write_png_rgb8(path, img.width as usize, img.height as usize, &img.rgb)?;
    Ok(())
}

#[cfg(feature = "sim")]
/// Writes `index.html`: a one-page summary linking the pictures and figures of a scan.
pub fn write_summary_html(out: &Path, result: &ScanResult) -> Result<PathBuf, ScanError> {
    let a = &result.accuracy;
    let c = &result.calibration_summary;
    let mut rows = String::new();
    for s in &a.spheres {
        rows.push_str(&format!(
            "<tr><td>{}</td><td>{}</td><td>{:.4}</td><td>{:+.4}</td><td>{:.4}</td><td>{:.4}</td></tr>\n",
            s.name,
            s.points,
            s.radius_mm,
            s.probing_size_mm,
            s.probing_form_mm,
            s.probing_form_trimmed_mm
        ));
    }
    let spacing: String = a
        .sphere_pairs
        .iter()
        .map(|p| {
            format!(
                "Sphere-spacing error ({}) {:+.4} mm. ",
                p.name, p.sphere_spacing_mm
            )
        })
        .collect();
    let flatness: String = match (&result.flatness, &result.files.plate_heat_map) {
        (Some(f), Some(heat)) => f
            .planes
            .iter()
            .map(|p| {
                format!(
                    "<h2>Flatness (tilted plate)</h2>\n<p>{} points; flatness {:.4} mm, {:.4} mm with 0.3 % left out; RMS to the fitted plane {:.4} mm. Cloud <a href=\"plate.ply\">plate.ply</a>, truth <a href=\"plate_truth.json\">plate_truth.json</a>.</p>\n<p><a href=\"{heat}\"><img src=\"{heat}\" width=\"480\"></a></p>\n",
                    p.points, p.flatness_mm, p.flatness_trimmed_mm, p.fit_rms_mm
                )
            })
            .collect(),
        _ => String::new(),
    };
    let mesh = match (&result.mesh, &result.files.mesh) {
        (Some(m), Some(f)) => {
            let acc = |r: &Option<sl_metrology::Report>| {
                r.as_ref().map_or("not measured".to_owned(), |r| {
                    format!("{:.4} mm", r.rms_to_reference_mm)
                })
            };
            format!(
                "<h2>Mesh and 3-D view</h2>\n<p>Screened Poisson surface of the merged cloud (depth {depth}, cells of {cell:.3} mm): <a href=\"{ply}\">{ply}</a>, <a href=\"{stl}\">{stl}</a>; {v} vertices, {t} triangles{simplified}, watertight {wt}, manifold {mf}. RMS distance to the true surface: {rv} at its vertices, {ra} over its area.</p>\n<p><iframe src=\"{view}\" width=\"960\" height=\"540\" style=\"border:0\"></iframe><br>Drag to rotate, wheel to zoom; the buttons switch the mesh and the cloud and colour them by their signed error (blue −{range} mm, red +{range} mm). <a href=\"{view}\">Open the 3-D view alone</a>; <a href=\"{pre}\">still picture</a>.</p>\n",
                depth = m.depth,
                cell = m.cell_size_mm,
                ply = f.ply,
                stl = f.stl,
                v = m.vertices,
                t = m.triangles,
                simplified = if m.simplify_ms.is_some() {
                    format!(" (simplified from {} vertices)", m.vertices_extracted)
                } else {
                    String::new()
                },
                wt = m.watertight,
                mf = m.manifold,
                rv = acc(&m.accuracy_vertices),
                ra = acc(&m.accuracy_area),
                view = f.view3d,
                pre = f.preview,
                range = DEFAULT_HEAT_MAP_RANGE_MM,
            )
        }
        _ => String::new(),
    };
    let stages: String = result
        .stages
        .iter()
        .map(|s| format!("<tr><td>{}</td><td>{:.2} s</td></tr>", s.name, s.ms / 1e3))
        .collect();
    let imgs: String = result
        .files
        .previews
        .iter()
        .map(|p| format!("<a href=\"{p}\"><img src=\"{p}\" width=\"320\"></a>\n"))
        .collect();
    let html = format!(
        r#"<!doctype html>
<html><head><meta charset="utf-8"><title>slscan scan</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}}td,th{{padding:2px 10px;text-align:right}}</style>
</head><body>
<h1>Virtual-rig scan: dumbbell on the turntable</h1>
<p>{views} views, {points} merged points: <a href="{merged}">{merged}</a>; calibration <a href="{calib}">{calib}</a>; figures <a href="report.json">report.json</a>; frames in <a href="{session}/">{session}/</a>.</p>
{imgs}
<h2>Accuracy against the truth</h2>
<p>Measured by sl-metrology against <a href="{truth}">{truth}</a> (<code>slscan report {merged} --truth {truth}</code> gives the same figures). RMS distance to the true surface {rms:.4} mm in the estimated camera frame (largest {max:.3} mm; {outliers} points farther than 2 mm from every sphere are left out). {spacing}</p>
<table><tr><th>sphere</th><th>points</th><th>radius (mm)</th><th>probing size (mm)</th><th>probing form (mm)</th><th>form, 0.3 % trimmed (mm)</th></tr>
{rows}</table>
<p>Probing form: range of the radial residuals of the least-squares sphere over all its points, and with the 0.3 % farthest left out as VDI/VDE 2634 part 2 allows.</p>
<p><a href="{heat}"><img src="{heat}" width="480"></a><br>Signed distance to the true surface, blue −{range} mm to red +{range} mm.</p>
{mesh}{flatness}<h2>Calibration (estimated from simulated board captures)</h2>
<p>RMS {first} {rc:.3} px, {second} {rp:.3} px, stereo {rs:.3} px, turntable {rt:.3} px; {first} fx error {fxc:+.4} %, {second} fx error {fxp:+.4} %, baseline error {base:.3} mm; axis direction error {ad:.4}°, position error {ap:.3} mm.</p>
<h2>Stages</h2>
<table>{stages}</table>
</body></html>
"#,
        views = result.view_points.len(),
        first = if result.pair.is_some() {
            "left camera"
        } else {
            "camera"
        },
        second = if result.pair.is_some() {
            "right camera"
        } else {
            "projector"
        },
        points = result.merged.len(),
        merged = result.files.merged,
        calib = result.files.calibration,
        session = result.files.session,
        truth = result.files.truth,
        rms = a.rms_to_reference_mm,
        max = a.max_to_reference_mm,
        outliers = a.points - a.assigned_points,
        heat = result.files.heat_map,
        range = DEFAULT_HEAT_MAP_RANGE_MM,
        rc = c.rms_camera_px,
        rp = c.rms_projector_px,
        rs = c.rms_stereo_px,
        rt = c.rms_turntable_px,
        fxc = c.camera_fx_error_percent,
        fxp = c.projector_fx_error_percent,
        base = c.baseline_error_mm,
        ad = c.axis_direction_error_deg,
        ap = c.axis_position_error_mm,
    );
    let path = out.join("index.html");
    std::fs::write(&path, html).map_err(io(&path))?;
    Ok(path)
}
