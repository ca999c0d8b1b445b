//! The printed QR symbol: its side length, corner labels and model points.
//!
//! Corner labels follow the paper (Figure 1, Eq. 18); docs/conventions.md ties them to the
//! symbol's own corners: P1 bottom-right, P2 top-right (the origin), P3 top-left,
//! P4 bottom-left. Edges follow the paper's Table 1: l1 = P1P2, l2 = P2P3, l3 = P3P4,
//! l4 = P1P4 (sides), l5 = P1P3, l6 = P2P4 (diagonals, √2·l, Eq. 9).

use super::frames::{MarkerPoint, MarkerToCamera};
use nalgebra::{Point3, Rotation3, Vector3};
use std::f64::consts::SQRT_2;
use thiserror::Error;

/// The paper's corner labels, in the paper's order P1..P4.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Corner {
    /// Bottom-right of the symbol.
    P1,
    /// Top-right; the marker-frame origin.
    P2,
    /// Top-left.
    P3,
    /// Bottom-left.
    P4,
}

impl Corner {
    /// All four, in paper order.
    pub const ALL: [Corner; 4] = [Corner::P1, Corner::P2, Corner::P3, Corner::P4];

    /// "P1".."P4".
    pub fn label(self) -> &'static str {
        match self {
            Corner::P1 => "P1",
            Corner::P2 => "P2",
            Corner::P3 => "P3",
            Corner::P4 => "P4",
        }
    }

    /// The symbol's corner this label names: "bottom_right", "top_right", ….
    pub fn qr_corner(self) -> &'static str {
        match self {
            Corner::P1 => "bottom_right",
            Corner::P2 => "top_right",
            Corner::P3 => "top_left",
            Corner::P4 => "bottom_left",
        }
    }
}

/// How a caller lists four corners.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CornerOrder {
    /// Top-left, top-right, bottom-right, bottom-left of the symbol: the order of OpenCV,
    /// zxing and rqrr.
    #[default]
    Qr,
    /// P1, P2, P3, P4 (paper Figure 1).
    Paper,
}

/// For each paper index (P1..P4), its index in the `"qr"` order (TL, TR, BR, BL).
const QR_INDEX_OF_PAPER: [usize; 4] = [2, 1, 0, 3];

impl CornerOrder {
    /// The index, in this order, of paper corner `paper_index` (0 = P1).
    pub fn input_index(self, paper_index: usize) -> usize {
        match self {
            CornerOrder::Qr => QR_INDEX_OF_PAPER[paper_index % 4],
            CornerOrder::Paper => paper_index % 4,
        }
    }

    /// Reorders four items given in this order into paper order P1..P4.
    pub fn to_paper<T: Copy>(self, items: [T; 4]) -> [T; 4] {
        [0, 1, 2, 3].map(|i| items[self.input_index(i)])
    }

    /// Reorders four items in paper order into this order.
    pub fn from_paper<T: Copy>(self, paper: [T; 4]) -> [T; 4] {
        let mut out = paper;
        for (i, item) in paper.into_iter().enumerate() {
            out[self.input_index(i)] = item;
        }
        out
    }
}

/// One of the six lengths of paper Table 1: the corners it joins, by paper index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    /// First corner (0 = P1).
    pub a: usize,
    /// Second corner.
    pub b: usize,
    /// True for the diagonals l5, l6 (length √2·l, Eq. 9).
    pub diagonal: bool,
}

/// l1..l6 of paper Table 1.
pub const EDGES: [Edge; 6] = [
    Edge {
        a: 0,
        b: 1,
        diagonal: false,
    }, // l1 = P1P2
    Edge {
        a: 1,
        b: 2,
        diagonal: false,
    }, // l2 = P2P3
    Edge {
        a: 2,
        b: 3,
        diagonal: false,
    }, // l3 = P3P4
    Edge {
        a: 0,
        b: 3,
        diagonal: false,
    }, // l4 = P1P4
    Edge {
        a: 0,
        b: 2,
        diagonal: true,
    }, // l5 = P1P3
    Edge {
        a: 1,
        b: 3,
        diagonal: true,
    }, // l6 = P2P4
];

/// For each corner P1..P4, the three edges (indices into [`EDGES`]) that meet there
/// (docs/paper-method.md; the paper's Table 2 is garbled in print).
pub const INCIDENT_EDGES: [[usize; 3]; 4] = [
    [0, 3, 4], // P1: l1, l4, l5
    [0, 1, 5], // P2: l1, l2, l6
    [1, 2, 4], // P3: l2, l3, l5
    [2, 3, 5], // P4: l3, l4, l6
];

/// Why a marker was refused.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum MarkerError {
    /// The side length is zero, negative or not finite: there is no scale to recover.
    #[error("marker size must be a positive number of millimetres, got {size_mm}")]
    InvalidSize {
        /// The value given, mm.
        size_mm: f64,
    },
}

/// A square marker of side `size_mm`: the QR symbol from the outer edge of one finder
/// pattern to the outer edge of the other, quiet zone excluded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    size_mm: f64,
}

impl Marker {
    /// A marker of the given side length.
    ///
    /// # Errors
    /// [`MarkerError::InvalidSize`] unless `size_mm` is finite and positive.
    pub fn try_new(size_mm: f64) -> Result<Self, MarkerError> {
        if size_mm.is_finite() && size_mm > 0.0 {
            Ok(Self { size_mm })
        } else {
            Err(MarkerError::InvalidSize { size_mm })
        }
    }

    /// Side length l, mm.
    pub fn size_mm(&self) -> f64 {
        self.size_mm
    }

    /// The known length of an edge, mm: l for sides (Eq. 8), √2·l for diagonals (Eq. 9).
    pub fn edge_length_mm(&self, edge: &Edge) -> f64 {
        if edge.diagonal {
            SQRT_2 * self.size_mm
        } else {
            self.size_mm
        }
    }

    /// Model corners P1..P4 in the marker frame (paper Eq. 18).
    pub fn object_points(&self) -> [MarkerPoint; 4] {
        let l = self.size_mm;
        [
            MarkerPoint(Point3::new(0.0, l, 0.0)),
            MarkerPoint(Point3::new(0.0, 0.0, 0.0)),
            MarkerPoint(Point3::new(-l, 0.0, 0.0)),
            MarkerPoint(Point3::new(-l, l, 0.0)),
        ]
    }

    /// The marker centre in the marker frame, (−l/2, l/2, 0).
    pub fn centre(&self) -> MarkerPoint {
        MarkerPoint(Point3::new(-self.size_mm / 2.0, self.size_mm / 2.0, 0.0))
    }

    /// The pose that turns this marker by `r_cm` and puts its centre at `centre_mm` in the
    /// camera frame (the translation is then that of P2, the marker frame's origin).
    #[must_use]
    pub fn pose_centred_at(&self, r_cm: Rotation3<f64>, centre_mm: Vector3<f64>) -> MarkerToCamera {
        MarkerToCamera::new(r_cm, centre_mm - r_cm * self.centre().0.coords)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_centred_at_puts_the_centre_there() {
        let marker = Marker::try_new(40.0).expect("valid size");
        let r = Rotation3::from_euler_angles(0.3, -0.2, 1.1);
        let centre = Vector3::new(12.0, -7.0, 400.0);
        let pose = marker.pose_centred_at(r, centre);
        let seen = pose.transform(&marker.centre()).0.coords;
        assert!((seen - centre).norm() < 1e-12, "{seen}");
        assert!(pose.rotation().angle_to(&r) < 1e-12);
    }

    #[test]
    fn qr_order_maps_to_paper_labels() {
        let qr = ["top_left", "top_right", "bottom_right", "bottom_left"];
        let paper = CornerOrder::Qr.to_paper(qr);
        for (corner, name) in Corner::ALL.iter().zip(paper) {
            assert_eq!(corner.qr_corner(), name, "{}", corner.label());
        }
        assert_eq!(CornerOrder::Qr.from_paper(paper), qr);
        assert_eq!(CornerOrder::Paper.to_paper(qr), qr);
    }

    #[test]
    fn model_edges_have_the_lengths_of_table_1() {
        let marker = Marker::try_new(50.0).expect("valid size");
        let p = marker.object_points();
        for (j, edge) in EDGES.iter().enumerate() {
            let d = (p[edge.a].0 - p[edge.b].0).norm();
            assert!(
                (d - marker.edge_length_mm(edge)).abs() < 1e-12,
                "l{}",
                j + 1
            );
        }
        for (i, incident) in INCIDENT_EDGES.iter().enumerate() {
            for &j in incident {
                assert!(
                    EDGES[j].a == i || EDGES[j].b == i,
                    "edge l{} does not touch P{}",
                    j + 1,
                    i + 1
                );
            }
        }
    }

    #[test]
    fn rejects_non_positive_and_non_finite_sizes() {
        for size_mm in [0.0, -50.0, f64::NAN, f64::INFINITY] {
            assert!(Marker::try_new(size_mm).is_err(), "size {size_mm}");
        }
    }
}
