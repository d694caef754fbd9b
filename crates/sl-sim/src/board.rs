//! The printed checkerboard used for calibration.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::footprint::Footprint;

/// Albedo of the black squares of a printed board (matte black ink reflects a few percent).
pub const BOARD_DARK_ALBEDO: f64 = 0.05;
/// Albedo of the white squares and margin of a printed board (matte paper).
pub const BOARD_LIGHT_ALBEDO: f64 = 0.9;

/// A printed checkerboard: a square grid of black and white squares on a white board.
///
/// Board frame (see `docs/conventions.md`): origin at the first inner corner, `x` along the
/// first row of inner corners, `y` along the columns, `z` into the board; the printed side is
/// the `z = 0` plane seen from `z < 0`. Inner corner `(i, j)` (column `i`, row `j`) is at
/// `(i · square_mm, j · square_mm, 0)`. The square whose top-left corner is at
/// `(-square_mm, -square_mm)` is black, as on OpenCV's boards.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Checkerboard {
    /// Number of inner corners along `x` (a row).
    pub inner_cols: u32,
    /// Number of inner corners along `y` (a column).
    pub inner_rows: u32,
    /// Side of one square in millimetres.
    pub square_mm: f64,
    /// White margin around the outer squares, in squares.
    pub margin_squares: f64,
    /// Albedo of the black squares.
    pub dark_albedo: f64,
    /// Albedo of the white squares and the margin.
    pub light_albedo: f64,
}

impl Default for Checkerboard {
    /// 9x6 inner corners of 20 mm (a 200 × 140 mm grid, 240 × 180 mm board with its margin):
    /// it fills about half of the default camera's view at the working distance.
    fn default() -> Self {
        Self {
            inner_cols: 9,
            inner_rows: 6,
            square_mm: 20.0,
            margin_squares: 1.0,
            dark_albedo: BOARD_DARK_ALBEDO,
            light_albedo: BOARD_LIGHT_ALBEDO,
        }
    }
}

impl Checkerboard {
    /// Checks the parameters: at least 2×2 inner corners, a positive finite square size, a
    /// non-negative margin, albedos in `[0, 1]`.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.inner_cols < 2 || self.inner_rows < 2 {
            return Err(SimError::param(
                "board inner corners",
                format!(
                    "{}x{}: at least 2x2 inner corners are needed",
                    self.inner_cols, self.inner_rows
                ),
            ));
        }
        if !(self.square_mm.is_finite() && self.square_mm > 0.0) {
            return Err(SimError::param(
                "board square_mm",
                format!("{} is not a positive size", self.square_mm),
            ));
        }
        if !(self.margin_squares.is_finite() && self.margin_squares >= 0.0) {
            return Err(SimError::param(
                "board margin_squares",
                format!("{} is not a non-negative number", self.margin_squares),
            ));
        }
        for (name, a) in [
            ("dark_albedo", self.dark_albedo),
            ("light_albedo", self.light_albedo),
        ] {
            if !(0.0..=1.0).contains(&a) {
                return Err(SimError::param(
                    format!("board {name}"),
                    format!("{a} is not in [0, 1]"),
                ));
            }
        }
        Ok(())
    }

    /// The 3-D inner corners in the board frame (mm), row by row: corner `(i, j)` at index
    /// `j · inner_cols + i`.
    pub fn corners(&self) -> Vec<Point3<f64>> {
        let mut out = Vec::with_capacity(self.inner_cols as usize * self.inner_rows as usize);
        for j in 0..self.inner_rows {
            for i in 0..self.inner_cols {
                out.push(Point3::new(
                    f64::from(i) * self.square_mm,
                    f64::from(j) * self.square_mm,
                    0.0,
                ));
            }
        }
        out
    }

    /// The board's outline in the board frame: `(x_min, y_min, x_max, y_max)` in mm, the
    /// squares plus the margin.
    pub fn extent(&self) -> (f64, f64, f64, f64) {
        let s = self.square_mm;
        let border = s * (1.0 + self.margin_squares);
        (
            -border,
            -border,
            f64::from(self.inner_cols - 1) * s + border,
            f64::from(self.inner_rows - 1) * s + border,
        )
    }

    /// The albedo printed at `(x, y)` in the board frame (mm); the margin and anything outside
    /// the squares is white.
    pub fn albedo_at(&self, x: f64, y: f64) -> f64 {
        let s = self.square_mm;
        let i = (x / s).floor();
        let j = (y / s).floor();
        // Squares run from index -1 to inner_cols - 1 (inner_cols + 1 squares per row).
        let inside = i >= -1.0
            && j >= -1.0
            && i <= f64::from(self.inner_cols) - 1.0
            && j <= f64::from(self.inner_rows) - 1.0;
        if !inside {
            return self.light_albedo;
        }
        // i + j even (the top-left square is (-1, -1)) is black.
        if (i + j).rem_euclid(2.0) < 0.5 {
            self.dark_albedo
        } else {
            self.light_albedo
        }
    }
}

impl Checkerboard {
    /// The albedo averaged over a camera sub-sample's footprint on the board (board frame, mm):
    /// the printed area is the box `[−s, cols·s) × [−s, rows·s)` (`s` the square), its dark
    /// squares those where the square waves of `x` and `y` agree; each factor is averaged
    /// exactly over the footprint's spread along its axis (see [`crate::footprint`]).
    pub(crate) fn albedo_over(&self, fp: &Footprint) -> f64 {
        let s = self.square_mm;
        let (u, v) = (fp.axis(0), fp.axis(1));
        let bu = (-s, f64::from(self.inner_cols) * s);
        let bv = (-s, f64::from(self.inner_rows) * s);
        // Dark share: E[B_u B_v (1 + S_u S_v) / 2], the footprint's axes taken as independent.
        let boxes = u.mean_box(bu.0, bu.1) * v.mean_box(bv.0, bv.1);
        let waves = u.mean_square_wave(s, Some(bu)) * v.mean_square_wave(s, Some(bv));
        let dark = (0.5 * (boxes + waves)).clamp(0.0, 1.0);
        self.light_albedo + (self.dark_albedo - self.light_albedo) * dark
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corner_layout_and_colours() {
        let b = Checkerboard::default();
        let c = b.corners();
        assert_eq!(c.len(), 54);
        assert_eq!(c[10], Point3::new(20.0, 20.0, 0.0));
        // Top-left square black, its right neighbour white, margin white.
        assert_eq!(b.albedo_at(-10.0, -10.0), BOARD_DARK_ALBEDO);
        assert_eq!(b.albedo_at(10.0, -10.0), BOARD_LIGHT_ALBEDO);
        assert_eq!(b.albedo_at(10.0, 10.0), BOARD_DARK_ALBEDO);
        assert_eq!(b.albedo_at(-30.0, -30.0), BOARD_LIGHT_ALBEDO);
        // Last square (8, 5): 8 + 5 odd -> white.
        assert_eq!(b.albedo_at(170.0, 110.0), BOARD_LIGHT_ALBEDO);
        assert_eq!(b.extent(), (-40.0, -40.0, 200.0, 140.0));
    }

    #[test]
    fn rejects_bad_boards() {
        let b = Checkerboard {
            inner_cols: 1,
            ..Checkerboard::default()
        };
        assert!(b.validate().is_err());
        let b = Checkerboard {
            square_mm: -1.0,
            ..Checkerboard::default()
        };
        assert!(b.validate().is_err());
    }
}
