//! What the poses of a calibration capture cover so far: the corners seen in each cell of the
//! image, the directions the board was tilted in, and a hint for the next pose.
//!
//! Zhang's calibration needs the corners spread over the whole image (the distortion is
//! weakest at the centre, strongest in the corners) and the board tilted about both image
//! axes (a set of boards all parallel to the image leaves the focal length undetermined).

use serde::Serialize;

use crate::pose_quality::BoardGeometry;

/// Columns of the coverage grid over the image.
pub const COVERAGE_COLS: usize = 4;
/// Rows of the coverage grid over the image.
pub const COVERAGE_ROWS: usize = 3;

/// Below this tilt (degrees) a board counts as facing the camera; above it, as tilted in one of
/// four directions. Zhang (2000) finds 10° the least tilt that constrains the focal length.
pub const FLAT_TILT_DEG: f64 = 10.0;

/// The tilt classes a calibration wants, in the order of [`Coverage::tilts`].
pub const TILT_NAMES: [&str; 5] = ["facing", "left", "right", "up", "down"];

/// Coverage of the image and of the tilts by the poses so far.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Coverage {
    /// Corners seen per grid cell, row-major (`COVERAGE_ROWS × COVERAGE_COLS`).
    pub cells: Vec<usize>,
    /// Poses per tilt class, as named by [`TILT_NAMES`].
    pub tilts: [usize; 5],
    /// Poses counted.
    pub poses: usize,
}

/// The tilt class of a board (an index into [`TILT_NAMES`]): the direction the board faces,
/// as seen from the camera.
pub fn tilt_class(geometry: &BoardGeometry) -> usize {
    if geometry.tilt_deg < FLAT_TILT_DEG {
        return 0;
    }
    let f = geometry.facing;
    // The facing normal points back to the camera (z < 0); its x and y say where it turns.
    if f.x.abs() >= f.y.abs() {
        if f.x < 0.0 { 1 } else { 2 }
    } else if f.y < 0.0 {
        3
    } else {
        4
    }
}

impl Coverage {
    /// Coverage of the poses whose corners (px) and geometry are given, in an image of
    /// `width × height` pixels.
    pub fn of<'a>(
        width: u32,
        height: u32,
        poses: impl IntoIterator<Item = (&'a [nalgebra::Point2<f64>], &'a BoardGeometry)>,
    ) -> Self {
        let mut c = Self {
            cells: vec![0; COVERAGE_COLS * COVERAGE_ROWS],
            tilts: [0; 5],
            poses: 0,
        };
        for (corners, geometry) in poses {
            c.poses += 1;
            c.tilts[tilt_class(geometry)] += 1;
            for p in corners {
                if let Some(k) = cell_of(width, height, p) {
                    c.cells[k] += 1;
                }
            }
        }
        c
    }

    /// Fraction of the grid cells holding at least one corner.
    pub fn covered_fraction(&self) -> f64 {
        self.cells.iter().filter(|&&n| n > 0).count() as f64 / self.cells.len() as f64
    }

    /// The coverage drawn in text: the grid with the corners seen per cell (`.` for none) and
    /// the tilt classes with their pose counts.
    pub fn draw(&self) -> String {
        let rule = format!("+{}\n", "-----+".repeat(COVERAGE_COLS));
        let mut s = String::from("image coverage (corners per cell):\n");
        s.push_str(&rule);
        for row in self.cells.chunks(COVERAGE_COLS) {
            s.push('|');
            for &n in row {
                if n == 0 {
                    s.push_str("  .  |");
                } else {
                    s.push_str(&format!("{n:^5}|"));
                }
            }
            s.push('\n');
            s.push_str(&rule);
        }
        s.push_str("tilts:");
        for (name, n) in TILT_NAMES.iter().zip(self.tilts) {
            s.push_str(&format!(" {name} {n}"));
        }
        s.push('\n');
        s
    }

    /// What to do next: a tilt not yet seen first, then an empty part of the image, then
    /// variety until `target` poses are taken.
    pub fn hint(&self, target: usize) -> String {
        if self.poses == 0 {
            return "hold the board facing the camera, about half the image wide".to_owned();
        }
        if let Some(k) = (1..TILT_NAMES.len()).find(|&k| self.tilts[k] == 0) {
            return format!(
                "turn the board to face {} by 20-40 degrees",
                TILT_NAMES.get(k).copied().unwrap_or("")
            );
        }
        if let Some(k) = self.cells.iter().position(|&n| n == 0) {
            return format!(
                "move the board into the {} of the image",
                cell_name(k % COVERAGE_COLS, k / COVERAGE_COLS)
            );
        }
        if self.poses < target {
            return format!(
                "{} more: vary distance and tilt (closer, farther, other corners)",
                target - self.poses
            );
        }
        "enough poses: press q to go on to the turntable".to_owned()
    }
}

/// The grid cell (row-major index) of a pixel; `None` outside the image.
fn cell_of(width: u32, height: u32, p: &nalgebra::Point2<f64>) -> Option<usize> {
    let (w, h) = (f64::from(width), f64::from(height));
    let (x, y) = (p.x + 0.5, p.y + 0.5);
    if !(x >= 0.0 && y >= 0.0 && x < w && y < h) {
        return None;
    }
    let i = ((x / w) * COVERAGE_COLS as f64) as usize;
    let j = ((y / h) * COVERAGE_ROWS as f64) as usize;
    Some(j.min(COVERAGE_ROWS - 1) * COVERAGE_COLS + i.min(COVERAGE_COLS - 1))
}

/// "top left", "bottom centre-right", ... of a cell.
fn cell_name(i: usize, j: usize) -> String {
    let v = match j {
        0 => "top",
        j if j + 1 == COVERAGE_ROWS => "bottom",
        _ => "middle",
    };
    let h = match i {
        0 => "left",
        i if i + 1 == COVERAGE_COLS => "right",
        i if 2 * i < COVERAGE_COLS => "centre-left",
        _ => "centre-right",
    };
    format!("{v} {h}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point2, Vector3};

    fn geometry(facing: Vector3<f64>) -> BoardGeometry {
        let facing = facing.normalize();
        BoardGeometry {
            centre_px: Point2::new(0.0, 0.0),
            size_px: 100.0,
            facing,
            tilt_deg: (-facing.z).acos().to_degrees(),
        }
    }

    #[test]
    fn tilt_classes_follow_the_facing_direction() {
        assert_eq!(tilt_class(&geometry(Vector3::new(0.0, 0.0, -1.0))), 0);
        assert_eq!(tilt_class(&geometry(Vector3::new(-0.5, 0.0, -1.0))), 1);
        assert_eq!(tilt_class(&geometry(Vector3::new(0.5, 0.1, -1.0))), 2);
        assert_eq!(tilt_class(&geometry(Vector3::new(0.0, -0.5, -1.0))), 3);
        assert_eq!(tilt_class(&geometry(Vector3::new(0.1, 0.5, -1.0))), 4);
    }

    #[test]
    fn coverage_counts_corners_per_cell_and_hints_at_the_gaps() {
        let corners = [Point2::new(10.0, 10.0), Point2::new(399.0, 10.0)];
        let g = geometry(Vector3::new(0.0, 0.0, -1.0));
        let c = Coverage::of(400, 300, [(&corners[..], &g)]);
        // 400 px wide, 4 columns: x = 10 is column 0, x = 399 column 3; both in row 0.
        assert_eq!(c.cells[0], 1);
        assert_eq!(c.cells[3], 1);
        assert_eq!(c.cells.iter().sum::<usize>(), 2);
        assert_eq!(c.tilts, [1, 0, 0, 0, 0]);
        assert!(c.hint(10).contains("face left"), "{}", c.hint(10));
        let drawn = c.draw();
        assert_eq!(drawn.lines().count(), 1 + 2 * COVERAGE_ROWS + 1 + 1);
        assert!(drawn.contains("facing 1"), "{drawn}");
        assert!(Coverage::of(400, 300, []).hint(10).contains("facing"));
    }

    #[test]
    fn empty_cells_are_named() {
        let g: Vec<BoardGeometry> = [
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(-0.5, 0.0, -1.0),
            Vector3::new(0.5, 0.0, -1.0),
            Vector3::new(0.0, -0.5, -1.0),
            Vector3::new(0.0, 0.5, -1.0),
        ]
        .into_iter()
        .map(geometry)
        .collect();
        let none: [Point2<f64>; 0] = [];
        let c = Coverage::of(400, 300, g.iter().map(|g| (&none[..], g)));
        assert_eq!(c.hint(10), "move the board into the top left of the image");
    }
}
