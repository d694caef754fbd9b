//! The 3-D viewer page in a real browser: headless Chromium (Debian's `chromium` package)
//! loads the page from `file://` and takes a screenshot; the model must be in it.
//!
//! Skipped with a note when no Chromium is found (set `SL_CHROMIUM` to its path, or install
//! the `chromium` package).

use std::path::PathBuf;
use std::process::Command;

use nalgebra::{Point3, Vector3};
use sl_cloud::PointCloud;
use sl_mesh::{PoissonConfig, ViewerConfig, ViewerLayer, poisson_reconstruct, viewer_html};

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

#[test]
fn chromium_shows_the_model() {
    let Some(browser) = chromium() else {
        println!(
            "note: no Chromium found (SL_CHROMIUM or /usr/bin/chromium): browser test skipped"
        );
        return;
    };
    // A sphere of radius 10 with an error that grows from −0.2 to +0.2 mm along x.
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
    let mesh = poisson_reconstruct(&cloud, &cfg).unwrap().mesh;
    let errors: Vec<f32> = mesh.vertices.iter().map(|p| (p.x / 50.0) as f32).collect();
    let html = viewer_html(
        &[ViewerLayer::Mesh {
            name: "sphere",
            mesh: &mesh,
            errors_mm: Some(&errors),
        }],
        &ViewerConfig::default(),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("view.html");
    std::fs::write(&page, html).unwrap();
    let shot = dir.path().join("shot.png");
    let status = Command::new(&browser)
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
        .arg(format!("file://{}?colour=error", page.display()))
        .output()
        .unwrap();
    assert!(
        shot.is_file(),
        "no screenshot; chromium said: {}",
        String::from_utf8_lossy(&status.stderr)
    );
    let img = image::open(&shot).unwrap().to_rgb8();
    let (w, h) = img.dimensions();
    // The model sits in the middle of the view; the buttons and the legend are in the
    // corners. Count the central pixels that are not background.
    let (mut model, mut total, mut blue, mut red) = (0, 0, 0, 0);
    for y in h / 4..3 * h / 4 {
        for x in w / 4..3 * w / 4 {
            let p = img.get_pixel(x, y).0.map(i32::from);
            total += 1;
            if (0..3).any(|c| (p[c] - BACKGROUND[c]).abs() > 6) {
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
