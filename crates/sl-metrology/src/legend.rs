//! The colour scale of a heat map, drawn into the picture: a bar from blue to red with its
//! end and middle values in millimetres, so a saved PNG explains itself.

use sl_cloud::{PreviewImage, colormap};

/// Glyphs of a 3×5 pixel font for the characters a scale needs; each row is 3 bits, the
/// leftmost pixel the highest bit.
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 3, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 2, 2, 2],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        '+' => [0, 2, 7, 2, 0],
        'm' => [0, 0, 7, 7, 5],
        'p' => [0, 7, 5, 7, 4],
        'x' => [0, 5, 2, 5, 0],
        ' ' => [0, 0, 0, 0, 0],
        _ => return None,
    })
}

/// Size of a font pixel in image pixels: 3×5 glyphs become 9×15, readable at 800×600.
const FONT_SCALE: u32 = 3;
/// Width and height of the colour bar, pixels.
const BAR: (u32, u32) = (240, 14);
/// Distance of the legend from the picture's left and bottom edges, pixels.
const INSET: u32 = 12;
/// Colour of the labels (light grey on the dark background of the previews).
const INK: [u8; 3] = [230, 230, 230];

fn put(img: &mut PreviewImage, x: u32, y: u32, c: [u8; 3]) {
    if x < img.width && y < img.height {
        let i = (y as usize * img.width as usize + x as usize) * 3;
        img.rgb[i..i + 3].copy_from_slice(&c);
    }
}

fn text(img: &mut PreviewImage, x: u32, y: u32, s: &str) {
    for (k, c) in s.chars().enumerate() {
        let Some(rows) = glyph(c) else { continue };
        let x0 = x + k as u32 * 4 * FONT_SCALE;
        for (r, bits) in rows.iter().enumerate() {
            for b in 0..3u32 {
                if bits & (4 >> b) != 0 {
                    for dy in 0..FONT_SCALE {
                        for dx in 0..FONT_SCALE {
                            put(
                                img,
                                x0 + b * FONT_SCALE + dx,
                                y + r as u32 * FONT_SCALE + dy,
                                INK,
                            );
                        }
                    }
                }
            }
        }
    }
}

fn text_width(s: &str) -> u32 {
    (s.chars().count() as u32 * 4).saturating_sub(1) * FONT_SCALE
}

/// Draws the colour scale of a heat map of range `range_mm` (blue at `−range_mm`, red at
/// `+range_mm`, as [`heat_map`](crate::heat_map)) into the bottom-left corner of `img`: the
/// bar, and `-0.1`, `0`, `+0.1 mm` under its ends and middle. A picture too small for it is
/// left as it is.
///
/// ```
/// use sl_cloud::PreviewImage;
/// let mut img = PreviewImage { width: 400, height: 300, rgb: vec![0; 400 * 300 * 3], left_out: 0 };
/// sl_metrology::draw_legend(&mut img, 0.1);
/// assert!(img.rgb.iter().any(|&v| v > 0));
/// ```
pub fn draw_legend(img: &mut PreviewImage, range_mm: f32) {
    let Some(y_text) = draw_bar(img) else { return };
    let lo = format!("-{range_mm}");
    let hi = format!("+{range_mm} mm");
    text(img, INSET, y_text, &lo);
    text(img, INSET + BAR.0 / 2 - text_width("0") / 2, y_text, "0");
    text(
        img,
        INSET + BAR.0 - text_width(&format!("+{range_mm}")) / 2,
        y_text,
        &hi,
    );
}

/// Draws the colour scale of a false-colour picture whose [`colormap`] runs from `lo` to `hi`
/// (`unit` after the upper value: `px`, `mm`) into the bottom-left corner of `img`: the bar,
/// and the two ends and the middle under it (rounded to 0.1). A picture too small for it is
/// left as it is.
pub fn draw_scale(img: &mut PreviewImage, lo: f32, hi: f32, unit: &str) {
    let Some(y_text) = draw_bar(img) else { return };
    let label = |v: f32| format!("{v:.1}");
    let (l, m, h) = (label(lo), label(0.5 * (lo + hi)), label(hi));
    text(img, INSET, y_text, &l);
    text(img, INSET + BAR.0 / 2 - text_width(&m) / 2, y_text, &m);
    text(
        img,
        INSET + BAR.0 - text_width(&h) / 2,
        y_text,
        &format!("{h} {unit}"),
    );
}

/// The colour bar in the bottom-left corner of `img`; the height its labels go at, or `None`
/// (nothing drawn) when the picture is too small for the bar and its labels.
fn draw_bar(img: &mut PreviewImage) -> Option<u32> {
    let label_h = 5 * FONT_SCALE;
    let need_h = BAR.1 + 4 + label_h + INSET;
    if img.width < BAR.0 + 2 * INSET + 40 || img.height < need_h + INSET {
        return None;
    }
    let y_bar = img.height - need_h;
    for x in 0..BAR.0 {
        let c = colormap(f64::from(x) / f64::from(BAR.0 - 1));
        for y in 0..BAR.1 {
            put(img, INSET + x, y_bar + y, c);
        }
    }
    Some(y_bar + BAR.1 + 4)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bar's left end is the colour map's blue and its right end its red; labels are drawn
    /// below; a picture too small is untouched.
    #[test]
    fn bar_runs_from_blue_to_red() {
        let mut img = PreviewImage {
            width: 800,
            height: 600,
            rgb: vec![30; 800 * 600 * 3],
            left_out: 0,
        };
        draw_legend(&mut img, 0.1);
        let y = 600 - (BAR.1 + 4 + 5 * FONT_SCALE + INSET) + BAR.1 / 2;
        assert_eq!(img.pixel(INSET, y), Some(colormap(0.0)));
        assert_eq!(img.pixel(INSET + BAR.0 - 1, y), Some(colormap(1.0)));
        let below = (y + BAR.1..600).flat_map(|yy| (0..300).map(move |x| (x, yy)));
        let ink = below
            .filter(|&(x, yy)| img.pixel(x, yy) == Some(INK))
            .count();
        assert!(ink > 50, "{ink} label pixels");
        let mut small = PreviewImage {
            width: 100,
            height: 50,
            rgb: vec![30; 100 * 50 * 3],
            left_out: 0,
        };
        draw_legend(&mut small, 0.1);
        assert!(small.rgb.iter().all(|&v| v == 30));
    }

    /// A scale from 12.5 to 80.0 px: the bar's ends are the colour map's, the labels are drawn.
    #[test]
    fn a_scale_shows_its_range() {
        let mut img = PreviewImage {
            width: 800,
            height: 600,
            rgb: vec![0; 800 * 600 * 3],
            left_out: 0,
        };
        draw_scale(&mut img, 12.5, 80.0, "px");
        let y = 600 - (BAR.1 + 4 + 5 * FONT_SCALE + INSET) + BAR.1 / 2;
        assert_eq!(img.pixel(INSET, y), Some(colormap(0.0)));
        assert_eq!(img.pixel(INSET + BAR.0 - 1, y), Some(colormap(1.0)));
        let ink = (y + BAR.1..600)
            .flat_map(|yy| (0..400).map(move |x| (x, yy)))
            .filter(|&(x, yy)| img.pixel(x, yy) == Some(INK))
            .count();
        // "12.5", "46.2", "80.0 px": 14 glyphs, far more than 100 ink pixels at 3x scale.
        assert!(ink > 100, "{ink} label pixels");
    }
}
