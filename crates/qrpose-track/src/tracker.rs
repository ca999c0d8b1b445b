//! The tracker: association of a frame's measurements with tracks, the per-frame cycle,
//! track creation and loss.
//!
//! Per frame at capture time t (ms):
//! 1. every track is predicted to t (dt ≤ 0 taken as 0, see [`crate::track`]);
//! 2. **association**: a (track, measurement) pair is possible when the payloads agree (an
//!    undecoded measurement agrees with any track) and the measurement's centre c_z is
//!    near the track's predicted centre c: d² = (c_z − c)ᵀ(P_c + V_c)⁻¹(c_z − c) at most
//!    `association_gate_chi2`, or, for a decoded measurement of the track's payload,
//!    |c_z − c| at most `association_distance_mm`; an undecoded measurement needs both.
//!    Pairs are taken greedily, decoded ones first, each by increasing d²: two codes
//!    with the same payload each keep their nearest track; tracks and measurements are
//!    few, so greedy is optimal in practice and O(n·m·log(n·m));
//! 3. each associated measurement is fused into its track ([`crate::branches`]); a
//!    decoded one left over starts a track ("t1", "t2", … in order of creation) unless
//!    `max_tracks` are live; an undecoded one left over stays unassigned;
//! 4. tracks not updated are `coasting`, or `lost` (reported once, then dropped).

use crate::measurement::Measurement;
use crate::params::{ParamError, TrackerParams};
use crate::report::{Assignment, FrameUpdate, Outcome, TrackError, TrackReport, TrackStatus};
use crate::track::Track;

/// Tracks of codes over a sequence of frames. Not thread-safe by itself (`&mut self` per
/// frame); one per video stream.
#[derive(Debug, Clone, PartialEq)]
pub struct Tracker {
    pub(crate) params: TrackerParams,
    pub(crate) tracks: Vec<Track>,
    next_id: u64,
}

/// A possible pairing of track `track` with measurement `measurement`.
#[derive(Debug, Clone, Copy)]
struct Pair {
    track: usize,
    measurement: usize,
    undecoded: bool,
    d2: f64,
}

impl Tracker {
    /// A tracker with no tracks.
    ///
    /// # Errors
    /// [`ParamError`] for the first parameter out of range.
    pub fn new(params: TrackerParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(Self {
            params,
            tracks: Vec::new(),
            next_id: 1,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &TrackerParams {
        &self.params
    }

    /// Live tracks.
    pub fn len(&self) -> usize {
        self.tracks.len()
    }

    /// No live track.
    pub fn is_empty(&self) -> bool {
        self.tracks.is_empty()
    }

    /// Every live track at its latest time (status as after the last frame).
    pub fn tracks(&self) -> Vec<TrackReport> {
        self.tracks.iter().map(|t| t.report(&self.params)).collect()
    }

    /// Runs one frame captured at `t_ms` with the codes found in it (module docs).
    ///
    /// # Errors
    /// [`TrackError::NonFiniteTime`] when `t_ms` is NaN or infinite (nothing changes).
    pub fn update(
        &mut self,
        t_ms: f64,
        measurements: &[Measurement],
    ) -> Result<FrameUpdate, TrackError> {
        if !t_ms.is_finite() {
            return Err(TrackError::NonFiniteTime(t_ms));
        }
        for track in &mut self.tracks {
            track.predict_to(t_ms, &self.params);
        }
        let mut assignments: Vec<Assignment> = measurements
            .iter()
            .map(|_| Assignment {
                track_id: None,
                outcome: Outcome::Unassigned,
                picked_alternative: false,
                ambiguity_resolved: false,
                innovation_d2: None,
            })
            .collect();
        let mut updated = vec![false; self.tracks.len()];
        let mut taken = vec![false; measurements.len()];
        for pair in self.pairs(measurements) {
            if updated[pair.track] || taken[pair.measurement] {
                continue;
            }
            updated[pair.track] = true;
            taken[pair.measurement] = true;
            let m = &measurements[pair.measurement];
            let track = &mut self.tracks[pair.track];
            let fused = track.fuse(m, t_ms, &self.params);
            let resolved =
                track.ambiguity_resolved(&self.params) && (m.ambiguous || fused.picked_alternative);
            assignments[pair.measurement] = Assignment {
                track_id: Some(track.id.clone()),
                outcome: fused.outcome,
                picked_alternative: fused.picked_alternative,
                ambiguity_resolved: resolved && fused.outcome == Outcome::Fused,
                innovation_d2: fused.d2,
            };
        }
        for (j, m) in measurements.iter().enumerate() {
            if taken[j] {
                continue;
            }
            let Some(payload) = m.payload.clone() else {
                continue;
            };
            if self.tracks.len() >= self.params.max_tracks {
                assignments[j].outcome = Outcome::TrackLimit;
                continue;
            }
            let id = format!("t{}", self.next_id);
            self.next_id += 1;
            self.tracks
                .push(Track::start(id.clone(), payload, m, t_ms, &self.params));
            updated.push(true);
            assignments[j].track_id = Some(id);
            assignments[j].outcome = Outcome::Created;
        }
        for (track, &was_updated) in self.tracks.iter_mut().zip(&updated) {
            if !was_updated && track.is_lost(t_ms, &self.params) {
                track.status = TrackStatus::Lost;
            }
        }
        let tracks = self.tracks.iter().map(|t| t.report(&self.params)).collect();
        self.tracks.retain(|t| t.status != TrackStatus::Lost);
        Ok(FrameUpdate {
            time_ms: t_ms,
            assignments,
            tracks,
        })
    }

    /// Every possible (track, measurement) pair, best first (module docs).
    fn pairs(&self, measurements: &[Measurement]) -> Vec<Pair> {
        let mut pairs = Vec::new();
        for (i, track) in self.tracks.iter().enumerate() {
            let (c, p_c) = track.centre();
            for (j, m) in measurements.iter().enumerate() {
                let same_payload = match &m.payload {
                    Some(p) if *p != track.payload => continue,
                    Some(_) => true,
                    None => false,
                };
                let diff = m.best.centre_mm - c;
                let s = p_c
                    + m.best.covariance.fixed_view::<3, 3>(3, 3)
                        * self.params.measurement_inflation;
                let Some(chol) = s.cholesky() else {
                    continue;
                };
                let d2 = diff.dot(&chol.solve(&diff));
                let in_gate = d2 <= self.params.association_gate_chi2;
                let near = diff.norm() <= self.params.association_distance_mm;
                let possible = if same_payload {
                    in_gate || near
                } else {
                    in_gate && near
                };
                if possible && d2.is_finite() {
                    pairs.push(Pair {
                        track: i,
                        measurement: j,
                        undecoded: !same_payload,
                        d2,
                    });
                }
            }
        }
        pairs.sort_by(|a, b| a.undecoded.cmp(&b.undecoded).then(a.d2.total_cmp(&b.d2)));
        pairs
    }
}
