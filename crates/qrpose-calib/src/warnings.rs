//! Warnings: a calibration that was computed but that the views do not constrain well.
//! Each is data ([`Warning`], with a stable snake_case [`Warning::name`]) and each threshold
//! a named constant with its reason.
//!
//! | name | raised when |
//! |---|---|
//! | `too_few_views` | fewer than [`RECOMMENDED_VIEWS`] views were used |
//! | `single_angle` | the largest angle between two views' target normals is below [`MIN_NORMAL_SPREAD_RAD`] |
//! | `corners_not_covered` | a corner cell of a [`COVERAGE_GRID`]² grid holds fewer than [`CORNER_CELL_MIN_POINTS`] used points |
//! | `focal_length_uncertain` | the standard deviation of fx or fy exceeds [`MAX_FOCAL_STD_FRACTION`] of it |
//! | `closed_form_fallback` | Zhang's closed form needed an assumption ([`ClosedFormAssumption`]) |
//! | `not_converged` | the last Levenberg-Marquardt run spent its iteration budget |

use crate::input::ImageSize;
use crate::zhang::ClosedFormAssumption;
use nalgebra::{Rotation3, Vector2, Vector3};

/// Views used below which `too_few_views` is raised: each view adds two constraints on the
/// intrinsics and a spread of positions for the distortion; with fewer, one poor view moves
/// the result and dropping one leaves little redundancy.
pub const RECOMMENDED_VIEWS: usize = 6;

/// Largest angle between two views' target normals below which `single_angle` is raised
/// (15°): planes of one orientation add no constraint on the intrinsics beyond the first
/// (Zhang 2000, Sec. 4), so a single-angle set leaves focal length and distance confounded.
pub const MIN_NORMAL_SPREAD_RAD: f64 = 15.0_f64.to_radians();

/// Cells per side of the coverage grid: its corner cells are the outer quarter of each
/// image axis, where lens distortion is largest and an unseen corner is extrapolated.
pub const COVERAGE_GRID: usize = 4;

/// Used points a corner cell needs to count as covered: a handful of points from one code
/// edge, enough to pin the distortion there.
pub const CORNER_CELL_MIN_POINTS: usize = 10;

/// Largest standard deviation of fx or fy, as a fraction of it (0.5 %): a focal length
/// 0.5 % off puts every code 0.5 % too near or too far.
pub const MAX_FOCAL_STD_FRACTION: f64 = 0.005;

/// A corner of the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ImageCorner {
    /// Small u, small v.
    TopLeft,
    /// Large u, small v.
    TopRight,
    /// Large u, large v.
    BottomRight,
    /// Small u, large v.
    BottomLeft,
}

impl ImageCorner {
    /// Every corner, clockwise from the top left.
    pub const ALL: [Self; 4] = [
        Self::TopLeft,
        Self::TopRight,
        Self::BottomRight,
        Self::BottomLeft,
    ];

    /// The corner's stable name (`top_left`, …).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::TopLeft => "top_left",
            Self::TopRight => "top_right",
            Self::BottomRight => "bottom_right",
            Self::BottomLeft => "bottom_left",
        }
    }
}

/// Something the views leave poorly constrained, or an approximation the solve made.
#[derive(Debug, Clone, PartialEq)]
pub enum Warning {
    /// Fewer than [`RECOMMENDED_VIEWS`] views were used.
    TooFewViews {
        /// Views used.
        used: usize,
        /// Views recommended.
        recommended: usize,
    },
    /// Every view sees the target from about one angle.
    SingleAngle {
        /// Largest angle between two views' target normals, rad.
        normal_spread_rad: f64,
        /// The threshold, rad.
        min_spread_rad: f64,
    },
    /// No points near some corners of the image.
    CornersNotCovered {
        /// The uncovered corners, clockwise from the top left.
        corners: Vec<ImageCorner>,
    },
    /// The focal length's standard deviation is above [`MAX_FOCAL_STD_FRACTION`].
    FocalLengthUncertain {
        /// std(fx) / fx.
        fx_std_fraction: f64,
        /// std(fy) / fy.
        fy_std_fraction: f64,
        /// The threshold.
        max_fraction: f64,
    },
    /// Zhang's closed form was ill-posed for these views and needed an assumption; the
    /// Levenberg-Marquardt then frees every parameter again.
    ClosedFormFallback {
        /// What was assumed.
        assumed: ClosedFormAssumption,
    },
    /// The last Levenberg-Marquardt run stopped on its iteration budget.
    NotConverged {
        /// Iterations of the final fit, over all its robust rounds.
        iterations: usize,
    },
}

impl Warning {
    /// The warning's stable snake_case name (the module table).
    #[must_use]
    pub const fn name(&self) -> &'static str {
        match self {
            Self::TooFewViews { .. } => "too_few_views",
            Self::SingleAngle { .. } => "single_angle",
            Self::CornersNotCovered { .. } => "corners_not_covered",
            Self::FocalLengthUncertain { .. } => "focal_length_uncertain",
            Self::ClosedFormFallback { .. } => "closed_form_fallback",
            Self::NotConverged { .. } => "not_converged",
        }
    }
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewViews { used, recommended } => write!(
                f,
                "{used} views used; take at least {recommended}, at different tilts and positions"
            ),
            Self::SingleAngle {
                normal_spread_rad,
                min_spread_rad,
            } => write!(
                f,
                "every view sees the code from about one angle (largest difference {:.1}°, below {:.0}°): focal length and distance are confounded; tilt the code differently between photos",
                normal_spread_rad.to_degrees(),
                min_spread_rad.to_degrees()
            ),
            Self::CornersNotCovered { corners } => {
                let names: Vec<&str> = corners.iter().map(|c| c.name()).collect();
                write!(
                    f,
                    "no code seen near the image corners {}: the lens distortion there is extrapolated",
                    names.join(", ")
                )
            }
            Self::FocalLengthUncertain {
                fx_std_fraction,
                fy_std_fraction,
                max_fraction,
            } => write!(
                f,
                "focal length uncertain: std {:.2} % (fx), {:.2} % (fy), above {:.1} %",
                100.0 * fx_std_fraction,
                100.0 * fy_std_fraction,
                100.0 * max_fraction
            ),
            Self::ClosedFormFallback { assumed } => write!(
                f,
                "the views were too similar for Zhang's closed form, which assumed {}",
                assumed.name()
            ),
            Self::NotConverged { iterations } => write!(
                f,
                "the refinement stopped after {iterations} iterations without converging"
            ),
        }
    }
}

/// How many used points fall in each cell of a [`COVERAGE_GRID`]² grid over the image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Coverage {
    /// Cells per side.
    pub grid: usize,
    /// Points per cell, row-major (row 0 at the top, column 0 at the left).
    pub counts: Vec<usize>,
}

impl Coverage {
    /// Counts `pixels_px` (points outside the image are not counted).
    pub(crate) fn of<'a>(
        pixels_px: impl Iterator<Item = &'a Vector2<f64>>,
        image: ImageSize,
    ) -> Self {
        let grid = COVERAGE_GRID;
        let mut counts = vec![0; grid * grid];
        let cell = |x: f64, size: f64| {
            let f = (x + 0.5) / size;
            (0.0..1.0).contains(&f).then(|| {
                // f in [0, 1): the product is in [0, grid).
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let i = (f * grid as f64) as usize;
                i.min(grid - 1)
            })
        };
        for p in pixels_px {
            if let (Some(col), Some(row)) = (cell(p.x, image.width()), cell(p.y, image.height())) {
                counts[row * grid + col] += 1;
            }
        }
        Self { grid, counts }
    }

    /// Points in the cell at `row`, `col`.
    #[must_use]
    pub fn count(&self, row: usize, col: usize) -> usize {
        self.counts.get(row * self.grid + col).copied().unwrap_or(0)
    }

    /// The corners whose cell holds fewer than [`CORNER_CELL_MIN_POINTS`].
    #[must_use]
    pub fn uncovered_corners(&self) -> Vec<ImageCorner> {
        let last = self.grid.saturating_sub(1);
        ImageCorner::ALL
            .into_iter()
            .filter(|corner| {
                let (row, col) = match corner {
                    ImageCorner::TopLeft => (0, 0),
                    ImageCorner::TopRight => (0, last),
                    ImageCorner::BottomRight => (last, last),
                    ImageCorner::BottomLeft => (last, 0),
                };
                self.count(row, col) < CORNER_CELL_MIN_POINTS
            })
            .collect()
    }
}

/// The largest angle between two views' target normals (each rotation's third column), rad.
pub(crate) fn normal_spread_rad(rotations: &[Rotation3<f64>]) -> f64 {
    let normals: Vec<Vector3<f64>> = rotations.iter().map(|r| r * Vector3::z()).collect();
    let mut spread: f64 = 0.0;
    for (i, a) in normals.iter().enumerate() {
        for b in &normals[i + 1..] {
            spread = spread.max(a.angle(b));
        }
    }
    spread
}

/// What the warnings are computed from.
pub(crate) struct Evidence<'a> {
    pub used_views: usize,
    pub rotations: &'a [Rotation3<f64>],
    pub coverage: &'a Coverage,
    /// (fx, std fx, fy, std fy), px.
    pub focal: (f64, f64, f64, f64),
    pub assumption: Option<ClosedFormAssumption>,
    pub not_converged_after: Option<usize>,
}

/// Every warning the evidence raises, in the module table's order.
pub(crate) fn warnings(e: &Evidence<'_>) -> Vec<Warning> {
    let mut out = Vec::new();
    if e.used_views < RECOMMENDED_VIEWS {
        out.push(Warning::TooFewViews {
            used: e.used_views,
            recommended: RECOMMENDED_VIEWS,
        });
    }
    let spread = normal_spread_rad(e.rotations);
    if spread < MIN_NORMAL_SPREAD_RAD {
        out.push(Warning::SingleAngle {
            normal_spread_rad: spread,
            min_spread_rad: MIN_NORMAL_SPREAD_RAD,
        });
    }
    let corners = e.coverage.uncovered_corners();
    if !corners.is_empty() {
        out.push(Warning::CornersNotCovered { corners });
    }
    let (fx, fx_std, fy, fy_std) = e.focal;
    let (fx_fraction, fy_fraction) = (fx_std / fx, fy_std / fy);
    // Written so that a NaN or infinite std raises it too.
    if !(fx_fraction <= MAX_FOCAL_STD_FRACTION && fy_fraction <= MAX_FOCAL_STD_FRACTION) {
        out.push(Warning::FocalLengthUncertain {
            fx_std_fraction: fx_fraction,
            fy_std_fraction: fy_fraction,
            max_fraction: MAX_FOCAL_STD_FRACTION,
        });
    }
    if let Some(assumed) = e.assumption {
        out.push(Warning::ClosedFormFallback { assumed });
    }
    if let Some(iterations) = e.not_converged_after {
        out.push(Warning::NotConverged { iterations });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_counts_points_in_their_cells_and_names_the_empty_corners() {
        let image = ImageSize::new(1280, 720);
        let mut points = vec![Vector2::new(-0.5, -0.5); 10];
        points.extend(vec![Vector2::new(1279.4, 719.4); 12]);
        points.push(Vector2::new(1279.6, 100.0)); // outside
        points.push(Vector2::new(640.0, 360.0));
        let c = Coverage::of(points.iter(), image);
        assert_eq!(c.count(0, 0), 10);
        assert_eq!(c.count(3, 3), 12);
        assert_eq!(c.count(2, 2), 1);
        assert_eq!(c.counts.iter().sum::<usize>(), 23);
        assert_eq!(
            c.uncovered_corners(),
            vec![ImageCorner::TopRight, ImageCorner::BottomLeft]
        );
    }

    #[test]
    fn the_normal_spread_is_the_largest_angle_between_two_views() {
        let r = |x: f64, y: f64| Rotation3::from_euler_angles(x, y, 0.7);
        let spread = normal_spread_rad(&[r(0.1, 0.0), r(-0.2, 0.0), r(0.0, 0.05)]);
        assert!((spread - 0.3).abs() < 1e-12, "{spread}");
        assert_eq!(normal_spread_rad(&[r(0.3, 0.2)]), 0.0);
    }
}
