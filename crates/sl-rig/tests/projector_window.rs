//! The projector window on a real X server (Xvfb in CI): show a pattern, take a screenshot of
//! the X display with an independent client (x11rb `GetImage`), compare every pixel of the
//! monitor exactly; then a second pattern.
//!
//! Run with `xvfb-run -a -s "-screen 0 1280x800x24" cargo test -p sl-rig --features window
//! --test projector_window`. Without `DISPLAY` the test says so and skips.
//!
//! One test function: the display's event loop is one per process.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use sl_image::Frame;
use sl_rig::{GreyImage, Projector, ProjectorWindowConfig, list_monitors, run_projector};
use x11rb::connection::Connection;
use x11rb::protocol::xproto::{ConnectionExt as _, ImageFormat, ImageOrder};

/// How long the screenshot may lag the present: the X server handles the window's and the
/// screenshot's connections independently, so the first screenshot may predate the put.
const SETTLE_TIMEOUT: Duration = Duration::from_secs(5);

/// Column `x` of the Gray-code stripe image of bit `bit`: white where the bit of the reflected
/// binary code of `x` is set (written from the definition, not from sl-codec).
fn gray_stripes(w: u32, h: u32, bit: u32) -> GreyImage {
    let row: Vec<u8> = (0..w)
        .map(|x| {
            if ((x ^ (x >> 1)) >> bit) & 1 == 1 {
                255
            } else {
                0
            }
        })
        .collect();
    let pixels = (0..h).flat_map(|_| row.iter().copied()).collect();
    GreyImage::U8(Frame::new(w as usize, h as usize, pixels).unwrap())
}

/// A diagonal ramp over all 256 grey levels, 16-bit (the window shows the high byte).
fn ramp16(w: u32, h: u32) -> GreyImage {
    let pixels = (0..h)
        .flat_map(|y| (0..w).map(move |x| (((x + 3 * y) % 256) as u16) << 8 | 0x7F))
        .collect();
    GreyImage::U16(Frame::new(w as usize, h as usize, pixels).unwrap())
}

/// The grey levels the screen should show: the 8-bit values, or the high byte of 16-bit ones.
fn expected_levels(image: &GreyImage) -> Vec<u8> {
    match image {
        GreyImage::U8(f) => f.data().to_vec(),
        GreyImage::U16(f) => f.data().iter().map(|p| (p >> 8) as u8).collect(),
    }
}

/// A screenshot of the rectangle as (r, g, b) per pixel, from a 24-bit `TrueColor` X screen.
fn screenshot(
    conn: &impl Connection,
    root: u32,
    (x, y): (i32, i32),
    (w, h): (u32, u32),
) -> Result<Vec<[u8; 3]>, String> {
    let reply = conn
        .get_image(
            ImageFormat::Z_PIXMAP,
            root,
            x as i16,
            y as i16,
            w as u16,
            h as u16,
            !0,
        )
        .map_err(|e| e.to_string())?
        .reply()
        .map_err(|e| e.to_string())?;
    let setup = conn.setup();
    let bpp = setup
        .pixmap_formats
        .iter()
        .find(|f| f.depth == reply.depth)
        .map(|f| f.bits_per_pixel)
        .ok_or("no pixmap format for the root depth")?;
    if reply.depth != 24 || bpp != 32 {
        return Err(format!(
            "the X screen has depth {} at {bpp} bits per pixel; start Xvfb with \
             `-screen 0 1280x800x24`",
            reply.depth
        ));
    }
    let lsb = setup.image_byte_order == ImageOrder::LSB_FIRST;
    Ok(reply
        .data
        .chunks_exact(4)
        .map(|p| {
            if lsb {
                [p[2], p[1], p[0]]
            } else {
                [p[1], p[2], p[3]]
            }
        })
        .collect())
}

/// Mismatches between the screen and the expected grey levels: (count, first as text).
fn compare(screen: &[[u8; 3]], expected: &[u8], w: u32) -> (usize, Option<String>) {
    let mut count = 0;
    let mut first = None;
    for (i, (s, &e)) in screen.iter().zip(expected).enumerate() {
        if *s != [e, e, e] {
            count += 1;
            first.get_or_insert_with(|| {
                format!(
                    "pixel ({}, {}): screen {s:?}, expected {e}",
                    i as u32 % w,
                    i as u32 / w
                )
            });
        }
    }
    (count + expected.len().abs_diff(screen.len()), first)
}

#[test]
fn patterns_appear_pixel_for_pixel() {
    if std::env::var_os("DISPLAY").is_none() {
        eprintln!("DISPLAY not set: skipping the projector window test (run it under xvfb-run)");
        return;
    }
    let monitors = list_monitors().unwrap();
    assert!(!monitors.is_empty(), "the display reports no monitor");
    let monitor = monitors[0].clone();
    eprintln!("monitor 0: {monitor:?}");

    let results = run_projector(ProjectorWindowConfig::default(), move |mut projector| {
        let (conn, screen) = x11rb::connect(None).map_err(|e| sl_rig::RigError::Device {
            device: "X screenshot".into(),
            reason: e.to_string(),
        })?;
        let root = conn.setup().roots[screen].root;
        let (w, h) = projector.image_size();
        let position = projector.monitor().position;
        let mut results = Vec::new();
        for (name, pattern) in [
            ("gray code bit 3", gray_stripes(w, h, 3)),
            ("ramp", ramp16(w, h)),
            ("gray code bit 0", gray_stripes(w, h, 0)),
        ] {
            projector.show(&pattern)?;
            let expected = expected_levels(&pattern);
            let start = Instant::now();
            let outcome = loop {
                let outcome = screenshot(&conn, root, position, (w, h))
                    .map(|screen| compare(&screen, &expected, w));
                let settled = matches!(outcome, Ok((0, _)) | Err(_));
                if settled || start.elapsed() > SETTLE_TIMEOUT {
                    break outcome;
                }
                std::thread::sleep(Duration::from_millis(20));
            };
            results.push((name, outcome, start.elapsed()));
        }
        // A wrong size is refused before it reaches the window.
        let refused = projector
            .show(&GreyImage::filled_u8(w as usize + 1, h as usize, 0)?)
            .is_err();
        Ok((projector.image_size(), results, refused))
    })
    .unwrap();

    let ((w, h), results, refused) = results;
    assert_eq!(
        (w, h),
        monitor.size,
        "the window must cover the monitor exactly"
    );
    assert!(refused, "an image of the wrong size must be refused");
    for (name, outcome, elapsed) in results {
        let (mismatches, first) = outcome.unwrap_or_else(|e| panic!("{name}: screenshot: {e}"));
        eprintln!("{name}: {mismatches} mismatched pixels of {w}x{h}, settled in {elapsed:?}");
        assert_eq!(mismatches, 0, "{name}: first mismatch {first:?}");
    }
}
