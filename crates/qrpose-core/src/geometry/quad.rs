//! Four image corners, checked to be a quadrilateral that a square marker can project to.
//!
//! A square seen from its front by a pinhole camera projects to a convex quadrilateral whose
//! corners P1 → P2 → P3 → P4 run clockwise on screen (v down) when listed in paper order.
//! Anything else is refused before a solver sees it: duplicate or collinear corners (no
//! unique pose), a self-intersecting or non-convex outline (corners swapped or misdetected),
//! and a mirrored outline (the corner order is reversed, or the marker would be seen from
//! behind). Tolerances are relative to the quadrilateral's size, so they hold in pixels and
//! in image-plane millimetres alike, and the checks run on the corners divided by their
//! largest coordinate magnitude, so that no finite input overflows or underflows them:
//! corners at 1e200 px form a square like corners at 100 px do, never a "duplicate" because
//! a distance overflowed. (Whether a solver can work at that scale is for the caller to
//! find out from its results.)

use super::frames::PixelPoint;
use super::marker::CornerOrder;
use thiserror::Error;

/// Two corners closer than this fraction of the largest corner distance are duplicates.
pub const DUPLICATE_REL_TOL: f64 = 1e-9;

/// Three corners whose triangle has twice-area below this fraction of the squared largest
/// corner distance are collinear (a square gives 0.5; a square seen 89° off-axis about 0.01).
pub const COLLINEAR_REL_TOL: f64 = 1e-6;

/// Why four corners do not describe a usable quadrilateral. Indices are positions in the
/// caller's list (in the caller's corner order), 0-based.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum QuadError {
    /// A coordinate is NaN or infinite.
    #[error("corner {index} has a coordinate that is not a finite number")]
    NonFinite {
        /// The corner at fault.
        index: usize,
    },
    /// Two corners coincide: four distinct points are needed.
    #[error("corners {first} and {second} coincide")]
    Duplicate {
        /// The first of the pair.
        first: usize,
        /// The second of the pair.
        second: usize,
    },
    /// Three corners lie on one line: the square's projection cannot look like that.
    #[error("corners {indices:?} are collinear")]
    Collinear {
        /// The three corners.
        indices: [usize; 3],
    },
    /// The outline crosses itself: two corners are swapped.
    #[error("the corners form a self-intersecting quadrilateral (are two corners swapped?)")]
    SelfIntersecting,
    /// One corner lies inside the triangle of the other three.
    #[error("the quadrilateral is not convex at corner {index}")]
    NonConvex {
        /// The reflex corner.
        index: usize,
    },
    /// The outline runs the wrong way round: the corner order is reversed (or mirrored),
    /// which a printed marker seen from its front cannot produce.
    #[error(
        "the corners run counter-clockwise on screen: the corner order is reversed or mirrored"
    )]
    Mirrored,
}

/// Four validated image corners, stored in paper order P1..P4.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageQuad {
    paper: [PixelPoint; 4],
    order: CornerOrder,
}

fn cross(o: &PixelPoint, a: &PixelPoint, b: &PixelPoint) -> f64 {
    (a.u() - o.u()) * (b.v() - o.v()) - (a.v() - o.v()) * (b.u() - o.u())
}

/// True when segments ab and cd cross at a point interior to both.
fn segments_cross(a: &PixelPoint, b: &PixelPoint, c: &PixelPoint, d: &PixelPoint) -> bool {
    let d1 = cross(a, b, c);
    let d2 = cross(a, b, d);
    let d3 = cross(c, d, a);
    let d4 = cross(c, d, b);
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

/// `paper` divided by its largest coordinate magnitude (so every coordinate is in
/// [−1, 1]), or `None` when every coordinate is zero. Distances between the results are at
/// most 2√2 and twice-areas at most 8: nothing overflows, and relative tolerances mean the
/// same at any scale.
fn normalised(paper: &[PixelPoint; 4]) -> Option<[PixelPoint; 4]> {
    let largest = paper
        .iter()
        .flat_map(|p| [p.u().abs(), p.v().abs()])
        .fold(0.0, f64::max);
    (largest > 0.0).then(|| paper.map(|p| PixelPoint::new(p.u() / largest, p.v() / largest)))
}

impl ImageQuad {
    /// Validates four corners listed in `order`.
    ///
    /// # Errors
    /// The first [`QuadError`] found, checked in the order the variants are declared.
    pub fn try_new(corners: [PixelPoint; 4], order: CornerOrder) -> Result<Self, QuadError> {
        let paper = order.to_paper(corners);
        let input = |paper_index: usize| order.input_index(paper_index);
        for (i, p) in paper.iter().enumerate() {
            if !(p.u().is_finite() && p.v().is_finite()) {
                return Err(QuadError::NonFinite { index: input(i) });
            }
        }
        let pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
        let Some(unit) = normalised(&paper) else {
            let (first, second) = (input(0).min(input(1)), input(0).max(input(1)));
            return Err(QuadError::Duplicate { first, second });
        };
        let dist = |a: usize, b: usize| (unit[a].0 - unit[b].0).norm();
        let scale = pairs.iter().map(|&(a, b)| dist(a, b)).fold(0.0, f64::max);
        for &(a, b) in &pairs {
            if dist(a, b) <= DUPLICATE_REL_TOL * scale {
                let (first, second) = (input(a).min(input(b)), input(a).max(input(b)));
                return Err(QuadError::Duplicate { first, second });
            }
        }
        for skip in 0..4 {
            let [a, b, c] = match skip {
                0 => [1, 2, 3],
                1 => [0, 2, 3],
                2 => [0, 1, 3],
                _ => [0, 1, 2],
            };
            if cross(&unit[a], &unit[b], &unit[c]).abs() <= COLLINEAR_REL_TOL * scale * scale {
                let mut indices = [input(a), input(b), input(c)];
                indices.sort_unstable();
                return Err(QuadError::Collinear { indices });
            }
        }
        if segments_cross(&unit[0], &unit[1], &unit[2], &unit[3])
            || segments_cross(&unit[1], &unit[2], &unit[3], &unit[0])
        {
            return Err(QuadError::SelfIntersecting);
        }
        // Turn at each corner of the cycle P1 → P2 → P3 → P4: negative = clockwise on screen.
        let turns: [f64; 4] =
            [0, 1, 2, 3].map(|i| cross(&unit[(i + 3) % 4], &unit[i], &unit[(i + 1) % 4]));
        let clockwise = turns.iter().filter(|t| **t < 0.0).count();
        match clockwise {
            4 => Ok(Self { paper, order }),
            0 => Err(QuadError::Mirrored),
            _ => {
                let majority_negative = clockwise >= 2;
                let reflex = turns
                    .iter()
                    .position(|t| (*t < 0.0) != majority_negative)
                    .unwrap_or(0);
                Err(QuadError::NonConvex {
                    index: input(reflex),
                })
            }
        }
    }

    /// The corners in paper order P1..P4.
    pub fn paper_order(&self) -> &[PixelPoint; 4] {
        &self.paper
    }

    /// The order the caller listed the corners in (to name a corner back to them).
    pub fn order(&self) -> CornerOrder {
        self.order
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn qr(points: [(f64, f64); 4]) -> Result<ImageQuad, QuadError> {
        ImageQuad::try_new(points.map(|(u, v)| PixelPoint::new(u, v)), CornerOrder::Qr)
    }

    const SQUARE: [(f64, f64); 4] = [
        (100.0, 100.0),
        (200.0, 100.0),
        (200.0, 200.0),
        (100.0, 200.0),
    ];

    #[test]
    fn accepts_a_square_in_either_order() {
        assert!(qr(SQUARE).is_ok());
        let paper =
            [SQUARE[2], SQUARE[1], SQUARE[0], SQUARE[3]].map(|(u, v)| PixelPoint::new(u, v));
        let quad = ImageQuad::try_new(paper, CornerOrder::Paper).expect("valid square");
        assert_eq!(
            quad.paper_order()[2],
            PixelPoint::new(100.0, 100.0),
            "P3 is top-left"
        );
    }

    #[test]
    fn rejects_non_finite_corners() {
        let mut c = SQUARE;
        c[3].1 = f64::NAN;
        assert_eq!(qr(c), Err(QuadError::NonFinite { index: 3 }));
    }

    #[test]
    fn rejects_duplicate_corners() {
        let mut c = SQUARE;
        c[2] = c[0];
        assert_eq!(
            qr(c),
            Err(QuadError::Duplicate {
                first: 0,
                second: 2
            })
        );
    }

    #[test]
    fn rejects_collinear_corners() {
        let c = [
            (100.0, 100.0),
            (150.0, 100.0),
            (200.0, 100.0),
            (100.0, 200.0),
        ];
        assert_eq!(qr(c), Err(QuadError::Collinear { indices: [0, 1, 2] }));
    }

    #[test]
    fn rejects_self_intersecting_corners() {
        let c = [SQUARE[0], SQUARE[2], SQUARE[1], SQUARE[3]];
        assert_eq!(qr(c), Err(QuadError::SelfIntersecting));
    }

    #[test]
    fn rejects_non_convex_corners() {
        let mut c = SQUARE;
        c[2] = (130.0, 130.0);
        assert_eq!(qr(c), Err(QuadError::NonConvex { index: 2 }));
    }

    #[test]
    fn validation_is_the_same_at_any_finite_scale() {
        // A square, a collinear triple and a duplicate, from 1e-300 to 1e300: distances at
        // 1e200 overflow and at 1e-200 underflow unless the corners are normalised first.
        let collinear = [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (0.0, 1.0)];
        let mut duplicate = SQUARE;
        duplicate[3] = duplicate[1];
        for exponent in [-300, -200, -150, -10, 0, 10, 150, 200, 300, 305] {
            let s = 10f64.powi(exponent);
            let scaled = |c: [(f64, f64); 4]| c.map(|(u, v)| (u * s, v * s));
            assert!(qr(scaled(SQUARE)).is_ok(), "square at 1e{exponent}");
            let negative = scaled(SQUARE).map(|(u, v)| (u - 2.0 * s * 100.0, v));
            assert!(qr(negative).is_ok(), "shifted square at 1e{exponent}");
            assert_eq!(
                qr(scaled(collinear)),
                Err(QuadError::Collinear { indices: [0, 1, 2] }),
                "1e{exponent}"
            );
            assert_eq!(
                qr(scaled(duplicate)),
                Err(QuadError::Duplicate {
                    first: 1,
                    second: 3
                }),
                "1e{exponent}"
            );
        }
        // Huge but finite corners: an overflow must not report "corners 1 and 2 coincide".
        let huge = [(0.0, 0.0), (1e200, 0.0), (1e200, 1e200), (0.0, 1e200)];
        assert!(qr(huge).is_ok());
        let largest = [
            (-f64::MAX, -f64::MAX),
            (f64::MAX, -f64::MAX),
            (f64::MAX, f64::MAX),
            (-f64::MAX, f64::MAX),
        ];
        assert!(qr(largest).is_ok());
        assert_eq!(
            qr([(0.0, 0.0); 4]),
            Err(QuadError::Duplicate {
                first: 1,
                second: 2
            }),
            "paper corners P1 and P2, as before"
        );
    }

    #[test]
    fn rejects_mirrored_corner_order() {
        let c = [SQUARE[0], SQUARE[3], SQUARE[2], SQUARE[1]];
        assert_eq!(qr(c), Err(QuadError::Mirrored));
    }
}
