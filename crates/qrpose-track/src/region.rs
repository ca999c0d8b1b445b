//! Where to look for the codes in the next frame: each live track's predicted image
//! quadrilateral and how uncertain it is ([`Tracker::predict_regions`]).
//!
//! The four corners of the marker under the reported branch's pose predicted to the frame's
//! time are projected through the camera (lens distortion included), in the qr order
//! top-left, top-right, bottom-right, bottom-left (`docs/conventions.md`: P3, P2, P1, P4).
//! Their uncertainty is the pose covariance pushed through the ideal projection:
//! Σ_i = J_i·P·J_iᵀ with J_i the 2×6 Jacobian of corner i with respect to (δθ, δc)
//! (`measurement::corner_jacobian`; the lens is left out of J, which changes the scale by
//! the local distortion gradient only). The reported branch's own covariance is used, not
//! the mixture's: both branches of the planar pair project to the same corners.

use crate::measurement::corner_jacobian;
use crate::report::TrackError;
use crate::tracker::Tracker;
use qrpose_core::geometry::{camera::Camera, frames::PixelPoint, marker::CornerOrder};

/// A track's predicted image region.
#[derive(Debug, Clone, PartialEq)]
pub struct PredictedRegion {
    /// The track's id.
    pub track_id: String,
    /// The track's payload.
    pub payload: String,
    /// Predicted corners, px, qr order: top-left, top-right, bottom-right, bottom-left.
    pub corners_px: [PixelPoint; 4],
    /// The largest standard deviation (along any direction) of any predicted corner, px.
    pub corner_sigma_px: f64,
    /// Confident enough to keep the track coasting when a read of this region misses it:
    /// the track is confirmed and `corner_sigma_px` ≤ `confident_corner_sigma_px`.
    pub confident: bool,
}

impl PredictedRegion {
    /// The axis-aligned box (min u, min v, max u, max v), px, around the corners widened by
    /// `sigmas` × `corner_sigma_px` on every side.
    pub fn bounds_px(&self, sigmas: f64) -> [f64; 4] {
        let margin = sigmas * self.corner_sigma_px;
        let us = self.corners_px.map(|p| p.u());
        let vs = self.corners_px.map(|p| p.v());
        let min = |a: [f64; 4]| a.iter().copied().fold(f64::INFINITY, f64::min);
        let max = |a: [f64; 4]| a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        [
            min(us) - margin,
            min(vs) - margin,
            max(us) + margin,
            max(vs) + margin,
        ]
    }

    /// Whether every predicted corner lies inside an image of `width_px` × `height_px`
    /// (pixel centres at integer coordinates, so inside is [-0.5, width − 0.5]). A code
    /// predicted partly outside cannot be read in this frame, by its crop or by a search of
    /// the whole frame.
    pub fn predicted_inside(&self, width_px: f64, height_px: f64) -> bool {
        self.corners_px
            .iter()
            .all(|p| p.inside_image(width_px, height_px))
    }
}

/// The largest eigenvalue of a symmetric 2×2 matrix [[a, b], [b, c]].
fn largest_eigenvalue_2x2(a: f64, b: f64, c: f64) -> f64 {
    let mean = 0.5 * (a + c);
    let half_diff = 0.5 * (a - c);
    mean + (half_diff * half_diff + b * b).sqrt()
}

impl Tracker {
    /// Each live track's predicted region at `t_ms` seen by `camera`, in track order. A
    /// track with a predicted corner at or behind the camera has no region. Nothing
    /// changes in the tracker.
    ///
    /// # Errors
    /// [`TrackError::NonFiniteTime`] when `t_ms` is NaN or infinite.
    pub fn predict_regions(
        &self,
        t_ms: f64,
        camera: &Camera,
    ) -> Result<Vec<PredictedRegion>, TrackError> {
        if !t_ms.is_finite() {
            return Err(TrackError::NonFiniteTime(t_ms));
        }
        let mut out = Vec::new();
        for track in &self.tracks {
            let branches = track.predicted_branches(t_ms, &self.params);
            let f = branches.reported();
            let p = f.pose_covariance();
            let pose = track.marker.pose_centred_at(f.rotation, f.centre_mm);
            let paper = track.marker.object_points();
            let mut corners = [PixelPoint::new(0.0, 0.0); 4];
            let mut sigma_px: f64 = 0.0;
            let mut visible = true;
            for (i, m) in paper.iter().enumerate() {
                let projected = camera.project(&pose.transform(m));
                let jacobian = corner_jacobian(
                    &track.marker,
                    &m.0.coords,
                    &f.rotation,
                    &f.centre_mm,
                    camera,
                );
                let (Some(px), Some(j)) = (projected, jacobian) else {
                    visible = false;
                    break;
                };
                corners[i] = px;
                let s = j * p * j.transpose();
                sigma_px = sigma_px.max(
                    largest_eigenvalue_2x2(s[(0, 0)], s[(0, 1)], s[(1, 1)])
                        .max(0.0)
                        .sqrt(),
                );
            }
            if !visible || !sigma_px.is_finite() {
                continue;
            }
            out.push(PredictedRegion {
                track_id: track.id.clone(),
                payload: track.payload.clone(),
                corners_px: CornerOrder::Qr.from_paper(corners),
                corner_sigma_px: sigma_px,
                confident: track.frames_seen >= self.params.confirm_frames
                    && sigma_px <= self.params.confident_corner_sigma_px,
            });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn region(corners: [(f64, f64); 4]) -> PredictedRegion {
        PredictedRegion {
            track_id: "t1".to_owned(),
            payload: "A".to_owned(),
            corners_px: corners.map(|(u, v)| PixelPoint::new(u, v)),
            corner_sigma_px: 2.0,
            confident: false,
        }
    }

    #[test]
    fn a_region_is_inside_only_when_all_four_corners_are() {
        let inside = region([(10.0, 10.0), (50.0, 10.0), (50.0, 50.0), (10.0, 50.0)]);
        assert!(inside.predicted_inside(640.0, 480.0));
        let left = region([(-20.0, 10.0), (30.0, 10.0), (30.0, 50.0), (-20.0, 50.0)]);
        assert!(!left.predicted_inside(640.0, 480.0));
        let bottom = region([(10.0, 450.0), (50.0, 450.0), (50.0, 480.0), (10.0, 480.0)]);
        assert!(!bottom.predicted_inside(640.0, 480.0));
        assert!(bottom.predicted_inside(640.0, 481.0));
    }
}
