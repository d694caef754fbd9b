//! The 3-D viewer page in a real browser: headless Chromium (Debian's `chromium` package)
//! loads the page from `file://` and takes a screenshot; the model must be in it, in the
//! colours asked for.
//!
//! Skipped with a note when no Chromium is found (set `SL_CHROMIUM` to its path, or install
//! the `chromium` package).

#![allow(clippy::unwrap_used)] // tests: a panic is a failed test

use std::path::{Path, PathBuf};
use std::process::Command;

use image::RgbImage;
use nalgebra::{Point3, Vector3};
use sl_cloud::PointCloud;
use sl_mesh::{
    PoissonConfig, TriangleMesh, ViewerConfig, ViewerLayer, poisson_reconstruct, viewer_html,
};

/// The page's background, `#1e1e22` (WebGL clear colour 0.118, 0.118, 0.133).
const BACKGROUND: [i32; 3] = [30, 30, 34];

fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("SL_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    [
        "/usr/bin/chromium",
        "/usr/bin/chromium-browser",
        "/usr/bin/google-chrome",
    ]
    .iter()
    .map(PathBuf::from)
    .find(|p| p.is_file())
}

/// A closed mesh of a sphere of radius 10 at the origin (Poisson at depth 5).
fn sphere() -> TriangleMesh {
    let n = 4000;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let (pts, nrm): (Vec<_>, Vec<_>) = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            let v = Vector3::new(r * t.cos(), r * t.sin(), z);
            (Point3::from(v * 10.0), v)
        })
        .unzip();
    let cloud = PointCloud::from_positions(pts).with_normals(nrm).unwrap();
    let cfg = PoissonConfig {
        depth: 5,
        ..PoissonConfig::default()
    };
    poisson_reconstruct(&cloud, &cfg).unwrap().mesh
}

/// The page `html` opened with the address's `query` in headless Chromium, as a screenshot of
/// 800 × 600.
fn screenshot(browser: &Path, html: &str, query: &str) -> RgbImage {
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("view.html");
    std::fs::write(&page, html).unwrap();
    let shot = dir.path().join("shot.png");
    let status = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--enable-unsafe-swiftshader",
            "--use-angle=swiftshader",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--window-size=800,600",
            "--virtual-time-budget=3000",
        ])
        .arg(format!(
            "--user-data-dir={}",
            dir.path().join("profile").display()
        ))
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}{query}", page.display()))
        .output()
        .unwrap();
    assert!(
        shot.is_file(),
        "no screenshot; chromium said: {}",
        String::from_utf8_lossy(&status.stderr)
    );
    image::open(&shot).unwrap().to_rgb8()
}

/// Whether the pixel differs from the background.
fn is_model(p: [i32; 3]) -> bool {
    (0..3).any(|c| (p[c] - BACKGROUND[c]).abs() > 6)
}

#[test]
fn chromium_shows_the_model() {
    let Some(browser) = chromium() else {
        println!(
            "note: no Chromium found (SL_CHROMIUM or /usr/bin/chromium): browser test skipped"
        );
        return;
    };
    // A sphere of radius 10 with an error that grows from −0.2 to +0.2 mm along x.
    let mesh = sphere();
    let errors: Vec<f32> = mesh.vertices.iter().map(|p| (p.x / 50.0) as f32).collect();
    let html = viewer_html(
        &[ViewerLayer::Mesh {
            name: "sphere",
            mesh: &mesh,
            errors_mm: Some(&errors),
            colours: None,
        }],
        &ViewerConfig::default(),
    )
    .unwrap();
    let img = screenshot(&browser, &html, "?colour=error");
    let (w, h) = img.dimensions();
    // The model sits in the middle of the view; the buttons and the legend are in the
    // corners. Count the central pixels that are not background.
    let (mut model, mut total, mut blue, mut red) = (0, 0, 0, 0);
    for y in h / 4..3 * h / 4 {
        for x in w / 4..3 * w / 4 {
            let p = img.get_pixel(x, y).0.map(i32::from);
            total += 1;
            if is_model(p) {
                model += 1;
                if p[2] > p[0] + 40 {
                    blue += 1;
                }
                if p[0] > p[2] + 40 {
                    red += 1;
                }
            }
        }
    }
    // The sphere fills a disc of about a third of the view's height in radius (camera at three
    // bounding radii, 40° field of view): a fifth of the central box at least.
    assert!(
        model * 5 > total,
        "{model} of {total} central pixels show the model"
    );
    // Coloured by error: both ends of the colour map appear (−x blue, +x red).
    assert!(blue > 100 && red > 100, "blue {blue}, red {red}");
}

/// A sphere painted yellow on its −x half and green on its +x half, opened with
/// `?colour=scan` (it has errors too, so the scan colouring is chosen among three): the left of
/// the model shows the yellow, the right the green, each darkened by the shading and nothing
/// else.
#[test]
fn chromium_shows_the_scan_colours() {
    let Some(browser) = chromium() else {
        println!(
            "note: no Chromium found (SL_CHROMIUM or /usr/bin/chromium): browser test skipped"
        );
        return;
    };
    const YELLOW: [u8; 3] = [230, 200, 40];
    const GREEN: [u8; 3] = [40, 200, 90];
    let mesh = sphere();
    let colours: Vec<[u8; 3]> = mesh
        .vertices
        .iter()
        .map(|p| if p.x < 0.0 { YELLOW } else { GREEN })
        .collect();
    let errors: Vec<f32> = mesh.vertices.iter().map(|p| (p.x / 50.0) as f32).collect();
    let html = viewer_html(
        &[ViewerLayer::Mesh {
            name: "sphere",
            mesh: &mesh,
            errors_mm: Some(&errors),
            colours: Some(&colours),
        }],
        &ViewerConfig::default(),
    )
    .unwrap();
    let img = screenshot(&browser, &html, "?colour=scan");
    let (w, h) = img.dimensions();
    // A pixel shows `colour` when it is `s × colour` for a shading factor `s` of the page's
    // range (0.6 to 1 for scan colours; 0.5 to 1.05 allowed), to 12 levels a channel
    // (8-bit rounding, antialiasing inside the surface).
    let shows = |p: [i32; 3], colour: [u8; 3]| {
        let c = colour.map(f64::from);
        let q = p.map(f64::from);
        let s = (0..3).map(|k| q[k] * c[k]).sum::<f64>() / (0..3).map(|k| c[k] * c[k]).sum::<f64>();
        (0.5..=1.05).contains(&s) && (0..3).all(|k| (q[k] - s * c[k]).abs() <= 12.0)
    };
    // Left and right of the model, away from the seam in the middle.
    let (mut left, mut left_yellow, mut right, mut right_green) = (0, 0, 0, 0);
    for y in h / 4..3 * h / 4 {
        for x in w / 4..3 * w / 4 {
            let p = img.get_pixel(x, y).0.map(i32::from);
            if !is_model(p) || x.abs_diff(w / 2) < w / 40 {
                continue;
            }
            if x < w / 2 {
                left += 1;
                left_yellow += usize::from(shows(p, YELLOW));
            } else {
                right += 1;
                right_green += usize::from(shows(p, GREEN));
            }
        }
    }
    assert!(
        left > 5000 && right > 5000,
        "model pixels: left {left}, right {right}"
    );
    // All but the silhouette's antialiased ring and the seam's blend.
    assert!(
        left_yellow * 10 > left * 9 && right_green * 10 > right * 9,
        "yellow {left_yellow} of {left} on the left, green {right_green} of {right} on the right"
    );
}
