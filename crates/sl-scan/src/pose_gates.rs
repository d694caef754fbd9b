//! The checks a calibration pose passes before it is written: the board found whole, not
//! over-exposed, sharp, and new (far enough from every earlier pose); a refusal says why.

use serde::{Deserialize, Serialize};
use sl_calib::BoardCorners;
use sl_rig::GreyImage;

use crate::BoardGeometry;

/// The checks a pose must pass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseGates {
    /// Largest fraction of the board's pixels at the sensor's top
    /// ([`crate::SATURATION_LEVEL`]): clipped white squares move the corners. Default 0.02.
    pub max_saturated_fraction: f64,
    /// Widest edge (px, [`crate::edge_width_px`]): about 2 for a sharp board, 2.5 σ for a
    /// blur of σ px. Default 5 (σ ≈ 2 px: corner errors grow past a tenth of a pixel).
    pub max_edge_width_px: f64,
    /// A pose is new when its board normal turns at least this much from every earlier pose
    /// (degrees), … Default 10 (Zhang's least useful tilt difference).
    pub min_tilt_change_deg: f64,
    /// … or its centre moves at least this fraction of the image diagonal, … Default 0.1.
    pub min_shift: f64,
    /// … or its apparent size changes by at least this fraction. Default 0.25.
    pub min_size_change: f64,
}

impl Default for PoseGates {
    fn default() -> Self {
        Self {
            max_saturated_fraction: 0.02,
            max_edge_width_px: 5.0,
            min_tilt_change_deg: 10.0,
            min_shift: 0.1,
            min_size_change: 0.25,
        }
    }
}

/// Why a pose was refused (nothing is written for it).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Refusal {
    /// The board is not in the frame, or not all of it.
    BoardNotFound {
        /// The detector's reason.
        reason: String,
    },
    /// Too much of the board is saturated.
    OverExposed {
        /// Fraction of the board's pixels saturated.
        saturated_fraction: f64,
    },
    /// The board's edges are blurred (motion or focus).
    Blurred {
        /// Median edge width (px).
        edge_width_px: f64,
    },
    /// The pose is too close to an earlier one in position, size and tilt.
    TooClose {
        /// Number of the earlier pose (its folder `pose_NNN`).
        pose: usize,
        /// Angle between the two board normals (degrees).
        tilt_change_deg: f64,
        /// Shift of the board centre, as a fraction of the image diagonal.
        shift: f64,
    },
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::BoardNotFound { reason } => write!(f, "board not found: {reason}"),
            Self::OverExposed { saturated_fraction } => write!(
                f,
                "over-exposed: {:.0} % of the board is saturated; lower the camera exposure or \
                 the projector brightness",
                100.0 * saturated_fraction
            ),
            Self::Blurred { edge_width_px } => write!(
                f,
                "blurred: edges {edge_width_px:.1} px wide; hold the board still and check the focus"
            ),
            Self::TooClose {
                pose,
                tilt_change_deg,
                shift,
            } => write!(
                f,
                "too close to pose {pose} (tilt {tilt_change_deg:.0} degrees and {:.0} % of the \
                 image away): move or tilt the board more",
                100.0 * shift
            ),
        }
    }
}

/// What the camera sees now, and whether it makes a pose.
#[derive(Debug, Clone)]
pub struct PoseCheck {
    /// The frame under full white.
    pub white: GreyImage,
    /// The detected corners, when the whole board was found.
    pub corners: Option<BoardCorners>,
    /// Inner corners of the board.
    pub expected_corners: usize,
    /// Where and how tilted the board is (with the camera known so far).
    pub geometry: Option<BoardGeometry>,
    /// Fraction of the board's pixels saturated.
    pub saturated_fraction: f64,
    /// Median width of the board's edges (px).
    pub edge_width_px: Option<f64>,
    /// `Ok` when the pose would be taken, else why not.
    pub verdict: Result<(), Refusal>,
}

impl PoseCheck {
    /// One line for the screen: `board found: 54/54 corners, tilt 23°` and the verdict.
    pub fn summary(&self) -> String {
        let found = self.corners.as_ref().map_or(0, |c| c.corners.len());
        let mut s = if found > 0 {
            format!("board found: {found}/{} corners", self.expected_corners)
        } else {
            format!("board not found: 0/{} corners", self.expected_corners)
        };
        if let Some(g) = &self.geometry {
            s.push_str(&format!(", tilt {:.0} degrees", g.tilt_deg));
        }
        if let Some(w) = self.edge_width_px {
            s.push_str(&format!(", edges {w:.1} px"));
        }
        if found > 0 {
            s.push_str(&format!(
                ", saturated {:.1} %",
                100.0 * self.saturated_fraction
            ));
        }
        match &self.verdict {
            Ok(()) => s.push_str(" - ready"),
            Err(r) => {
                if found > 0 {
                    s.push_str(&format!(" - {r}"));
                } else if let Refusal::BoardNotFound { reason } = r {
                    s.push_str(&format!(" ({reason})"));
                }
            }
        }
        s
    }
}
