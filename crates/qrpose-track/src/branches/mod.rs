//! The planar ambiguity over time: each track keeps up to two hypotheses about which branch
//! of the planar pair is the true pose, each a two-model estimator ([`crate::imm`]) with a
//! log-weight, and reports the heavier.
//!
//! A single frame of a small or distant code often fits two poses about equally well (the
//! planar ambiguity); qrpose-core reports both, with the image's probability p that the
//! alternative is the true one (calibrated: `docs/accuracy.md`). The true pose moves
//! smoothly from frame to frame while the image odds favour it more often than not:
//! evidence accumulates over frames. This is a multiple-hypothesis tracker with a beam of
//! two (Blackman, "Multiple hypothesis tracking for multiple target tracking", IEEE AESM
//! 19(1), 2004; Bar-Shalom, Li and Kirubarajan 2001, §11.6 for the weights), the
//! hypotheses being the branch histories of one code.
//!
//! Per frame, every hypothesis h (a two-model estimator predicted to the frame's time,
//! [`crate::imm`], log-weight l_h) is updated with the frame's corners by the iterated EKF
//! ([`crate::filter`]) from up to three starts: its prediction and each candidate pose of
//! the frame. Starts that reach the same optimum are one; distinct optima are the branches
//! h can take. Children (J the least over the two models, −½(J + ln det S) standing for
//! the log of the models' combined likelihood):
//!
//! ```text
//! each optimum with J ≤ gate:   h updated, l = l_h − ½(J + ln det S)
//! no optimum within the gate:   h predicted only (the frame is clutter to h),
//!                               l = l_h − ½(gate + ln det S)
//!   and, for the heaviest h, a re-opened branch at each candidate k (a fresh filter,
//!   velocity kept):             l = l_h + ln REOPEN_PRIOR − ½(gate + ln det S + e_k),
//!                               e_k = −2 ln P(k | image), P(best) = 1 − p, P(alt) = p
//! ```
//!
//! −½(J + ln det S) is the log predictive likelihood of the corners (Laplace
//! approximation), so the weights are log posteriors up to a common constant, and the
//! image's own preference between the two poses is in J (the better-fitting pose leaves
//! smaller residuals). The gate floor keeps one outlier frame from deciding. The heaviest
//! child is kept; children within `MERGE_D2` of it (squared Mahalanobis over the sum of the
//! covariances) add their weight to it; the next heaviest distinct child is the second
//! hypothesis, dropped if its probability is below `branch_prune_probability`. Re-opening
//! lets frames that see clearly undo a branch chosen when they did not.
//!
//! A candidate of the frame that no updated child reaches (each child's branch being the
//! candidate nearest it in rotation) is re-opened too, from the heaviest updated child c:
//! l = l_c + ln π − ½(e_k − e_c). Two poses a few degrees apart (a small code far away)
//! often lie in one basin of a loose prediction, so the update from either start lands on
//! the same optimum and the other branch would be lost unweighed. π is REOPEN_PRIOR once
//! the track has held two hypotheses (`contested`: one lost on evidence), and 1 before: a
//! branch never weighed starts on the image's odds, as the two candidates of a track's
//! first frame do.
//!
//! A new track starts with one hypothesis per candidate of its first frame, log-weights
//! ln(1 − p) and ln p. The reported pose is the heavier hypothesis, with the mixture's
//! spread about it, Σᵢ wᵢ·(Pᵢ + dᵢdᵢᵀ), dᵢ the pose difference of hypothesis i from the
//! reported one, so an unresolved ambiguity shows in the covariance; but two hypotheses
//! that overlap (their separation, the squared Mahalanobis distance over the sum of their
//! covariances, at most [`REPORT_MERGE_D2`], χ² with 6 degrees of freedom at 95 %) are one
//! uncertain pose, not two: their moment-matched mean is reported, with the spread about it
//! (the minimum-mean-square-error estimate of the mixture; Salmond, "Mixture reduction
//! algorithms for target tracking in clutter", SPIE 1305, 1990; Runnalls, "Kullback-Leibler
//! approach to Gaussian mixture reduction", IEEE TAES 43(3), 2007).

use crate::filter::{Eskf, ProcessNoise};
use crate::imm::{Imm, ImmPosterior, MANOEUVRING, MODES};
use crate::measurement::{Measurement, PoseCandidate};
use crate::params::TrackerParams;
use nalgebra::{Matrix6, SMatrix, Vector3};

/// Two children whose poses differ by at most this squared Mahalanobis distance (over the
/// sum of their covariances, 6 dof) are one hypothesis: merged.
const MERGE_D2: f64 = 1.0;

/// Prior probability, given to a re-opened branch, that the track's branch history is wrong.
pub(crate) const REOPEN_PRIOR: f64 = 1e-3;

/// Two hypotheses whose poses are at most this squared Mahalanobis distance apart (over the
/// sum of their covariances; χ² with 6 degrees of freedom at 95 %) are reported as their
/// moment-matched mean (module docs).
pub(crate) const REPORT_MERGE_D2: f64 = 12.592;

/// One branch hypothesis.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Hypothesis {
    pub imm: Imm,
    /// The combined estimate of `imm`.
    pub estimate: Eskf,
    /// Unnormalised log-weight (the heaviest is kept at 0).
    pub log_weight: f64,
}

impl Hypothesis {
    fn new(imm: Imm, log_weight: f64) -> Self {
        Self {
            estimate: imm.combined(),
            imm,
            log_weight,
        }
    }
}

/// What fusing one measurement did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Fused {
    /// The reported hypothesis (after the update) fused the measurement.
    pub any: bool,
    /// The reported hypothesis took the frame's alternative pose, not its best fit.
    pub picked_alternative: bool,
    /// J of the reported hypothesis's update (squared Mahalanobis, 8 dof).
    pub d2: Option<f64>,
}

/// The hypotheses of one track (one or two).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Branches {
    hyps: Vec<Hypothesis>,
    /// The track has held two hypotheses at once (module docs: the re-open prior).
    contested: bool,
}

fn start_imm(pose: &PoseCandidate, velocity: Vector3<f64>, params: &TrackerParams) -> Imm {
    Imm::new(Eskf::from_pose(
        pose,
        params.measurement_inflation,
        velocity,
        params.initial_velocity_sigma_mm_s,
        params.initial_angular_velocity_sigma_rad_s,
    ))
}

/// A candidate next hypothesis.
#[derive(Debug, Clone)]
struct Child {
    hyp: Hypothesis,
    /// It fused this frame (an update, or a re-opened branch started from it).
    fused: bool,
    /// J of its update (the least one when it only predicted); `None` when re-opened.
    cost: Option<f64>,
}

impl Child {
    /// A branch re-opened at `pose`: a fresh filter with `velocity_mm_s`, counted as fused.
    fn reopened(
        pose: &PoseCandidate,
        velocity_mm_s: Vector3<f64>,
        log_weight: f64,
        params: &TrackerParams,
    ) -> Self {
        Self {
            hyp: Hypothesis::new(start_imm(pose, velocity_mm_s, params), log_weight),
            fused: true,
            cost: None,
        }
    }
}

impl Branches {
    /// Hypotheses from a first measurement.
    pub fn start(m: &Measurement, params: &TrackerParams) -> Self {
        let mut hyps: Vec<Hypothesis> = m
            .candidates()
            .into_iter()
            .map(|(pose, e)| Hypothesis::new(start_imm(&pose, Vector3::zeros(), params), -0.5 * e))
            .collect();
        hyps.retain(|h| h.log_weight.exp() >= params.branch_prune_probability);
        if hyps.is_empty() {
            hyps.push(Hypothesis::new(
                start_imm(&m.best, Vector3::zeros(), params),
                0.0,
            ));
        }
        let contested = hyps.len() > 1;
        let mut b = Self { hyps, contested };
        b.normalise();
        b
    }

    /// Predicts every hypothesis `dt_s` ahead.
    pub fn predict(&mut self, dt_s: f64, noises: &[ProcessNoise; MODES], hold_s: f64) {
        for h in &mut self.hyps {
            h.imm.predict(dt_s, noises, hold_s);
            h.estimate = h.imm.combined();
        }
    }

    /// A copy predicted `dt_s` ahead.
    pub fn predicted(&self, dt_s: f64, noises: &[ProcessNoise; MODES], hold_s: f64) -> Self {
        let mut b = self.clone();
        b.predict(dt_s, noises, hold_s);
        b
    }

    /// The index of the heaviest hypothesis.
    fn reported_index(&self) -> usize {
        let mut best = 0;
        for (i, h) in self.hyps.iter().enumerate() {
            if h.log_weight > self.hyps[best].log_weight {
                best = i;
            }
        }
        best
    }

    /// The reported (heaviest) hypothesis's combined estimate.
    pub fn reported(&self) -> &Eskf {
        &self.hyps[self.reported_index()].estimate
    }

    /// The normalised probability of the reported hypothesis.
    pub fn reported_probability(&self) -> f64 {
        self.probabilities()[self.reported_index()]
    }

    /// The probability of the manoeuvring model in the reported hypothesis.
    pub fn manoeuvre_probability(&self) -> f64 {
        self.hyps[self.reported_index()].imm.probs[MANOEUVRING]
    }

    fn probabilities(&self) -> Vec<f64> {
        let w: Vec<f64> = self.hyps.iter().map(|h| h.log_weight.exp()).collect();
        let total: f64 = w.iter().sum();
        w.iter().map(|x| x / total).collect()
    }

    /// Keeps the heaviest log-weight at 0.
    fn normalise(&mut self) {
        let max = self
            .hyps
            .iter()
            .map(|h| h.log_weight)
            .fold(f64::NEG_INFINITY, f64::max);
        for h in &mut self.hyps {
            h.log_weight -= max;
        }
    }

    /// The pose to report and its covariance (module docs): the moment-matched mean of two
    /// hypotheses within [`REPORT_MERGE_D2`] of each other and their spread about it; else
    /// the heaviest hypothesis and [`Self::mixture_pose_covariance`].
    pub fn reported_pose(&self) -> (Eskf, Matrix6<f64>) {
        let reported = self.reported();
        let overlap = match self.hyps.as_slice() {
            [a, b] => separation(&a.estimate, &b.estimate) <= REPORT_MERGE_D2,
            _ => false,
        };
        if !overlap {
            return (reported.clone(), self.mixture_pose_covariance());
        }
        let weights = self.probabilities();
        let mean_d: SMatrix<f64, 12, 1> = self
            .hyps
            .iter()
            .zip(&weights)
            .map(|(h, w)| h.estimate.minus(reported) * *w)
            .sum();
        let mean = reported.plus(&mean_d);
        let mut p = Matrix6::zeros();
        for (h, w) in self.hyps.iter().zip(&weights) {
            let d = h.estimate.pose_difference(&mean);
            p += (h.estimate.pose_covariance() + d * d.transpose()) * *w;
        }
        (mean, p)
    }

    /// Σᵢ wᵢ·(Pᵢ + dᵢdᵢᵀ) about the reported hypothesis (module docs).
    pub fn mixture_pose_covariance(&self) -> Matrix6<f64> {
        let reported = self.reported();
        let mut p = Matrix6::zeros();
        for (h, w) in self.hyps.iter().zip(self.probabilities()) {
            let d = h.estimate.pose_difference(reported);
            p += (h.estimate.pose_covariance() + d * d.transpose()) * w;
        }
        p
    }

    /// Whether every hypothesis is finite.
    pub fn is_finite(&self) -> bool {
        self.hyps
            .iter()
            .all(|h| h.imm.is_finite() && h.estimate.is_finite() && h.log_weight.is_finite())
    }

    /// The distinct optima of hypothesis `h` updated from its prediction and from each
    /// candidate pose.
    fn optima(
        h: &Hypothesis,
        m: &Measurement,
        params: &TrackerParams,
    ) -> Vec<(ImmPosterior, Eskf)> {
        let mut own: Vec<(ImmPosterior, Eskf)> = Vec::new();
        let starts = std::iter::once(None).chain(m.candidates().into_iter().map(Some));
        for candidate in starts {
            // A candidate within reach of an optimum already found lies in its basin: the
            // update from it would land there again.
            if let Some((c, _)) = &candidate
                && own.iter().any(|(_, e)| near(e, c))
            {
                continue;
            }
            let start = candidate.map(|(c, _)| (c.rotation, c.centre_mm));
            let Some(post) = h.imm.update(
                &m.corners,
                &m.marker,
                params.measurement_inflation,
                start.as_ref().map(|(r, c)| (r, c)),
            ) else {
                continue;
            };
            let estimate = post.imm.combined();
            match own
                .iter_mut()
                .find(|(_, e)| separation(e, &estimate) <= MERGE_D2)
            {
                Some((o, _)) if o.log_likelihood >= post.log_likelihood => {}
                Some(o) => *o = (post, estimate),
                None => own.push((post, estimate)),
            }
        }
        own
    }

    /// Fuses one measurement (module docs).
    pub fn fuse(&mut self, m: &Measurement, params: &TrackerParams) -> Fused {
        let gate = params.gate_chi2;
        let heaviest = self.reported_index();
        let mut children: Vec<Child> = Vec::new();
        for (i, h) in self.hyps.iter().enumerate() {
            let own = Self::optima(h, m, params);
            let least = own
                .iter()
                .map(|(o, _)| o.cost)
                .fold(f64::INFINITY, f64::min);
            for (post, estimate) in own.into_iter().filter(|(o, _)| o.cost <= gate) {
                children.push(Child {
                    cost: Some(post.cost),
                    hyp: Hypothesis {
                        imm: post.imm,
                        estimate,
                        log_weight: h.log_weight + post.log_likelihood,
                    },
                    fused: true,
                });
            }
            if least <= gate {
                continue;
            }
            // Clutter to h: the floor −½(gate + ln det S), ln det S that of its prediction.
            let ln_det =
                h.estimate
                    .predicted_ln_det_s(&m.corners, &m.marker, params.measurement_inflation);
            children.push(Child {
                hyp: Hypothesis {
                    log_weight: h.log_weight - 0.5 * (gate + ln_det),
                    ..h.clone()
                },
                fused: false,
                cost: least.is_finite().then_some(least),
            });
            if i == heaviest {
                for (pose, e) in m.candidates() {
                    children.push(Child::reopened(
                        &pose,
                        h.estimate.velocity_mm_s,
                        h.log_weight + REOPEN_PRIOR.ln() - 0.5 * (gate + ln_det + e),
                        params,
                    ));
                }
            }
        }
        Self::reopen_unreached(&mut children, m, params, self.contested);
        let first = self.select(children, params);
        let picked_alternative =
            first.fused && m.nearer_candidate(&first.hyp.estimate.rotation) == 1;
        Fused {
            any: first.fused,
            picked_alternative,
            d2: first.cost,
        }
    }

    /// Re-opens each candidate of the frame on whose branch no updated child lies (module
    /// docs), from the heaviest updated child c: l = l_c + ln π − ½(e_k − e_c), π =
    /// [`REOPEN_PRIOR`] when the track is `contested`, else 1. Nothing when no child was
    /// updated (the candidates were re-opened already) or the frame has one candidate.
    fn reopen_unreached(
        children: &mut Vec<Child>,
        m: &Measurement,
        params: &TrackerParams,
        contested: bool,
    ) {
        let candidates = m.candidates();
        if candidates.len() < 2 {
            return;
        }
        let reached: Vec<usize> = children
            .iter()
            .filter(|c| c.fused)
            .map(|c| m.nearer_candidate(&c.hyp.estimate.rotation))
            .collect();
        let Some(best) = children
            .iter()
            .filter(|c| c.fused && c.cost.is_some())
            .max_by(|a, b| a.hyp.log_weight.total_cmp(&b.hyp.log_weight))
        else {
            return;
        };
        let e_best = candidates[m.nearer_candidate(&best.hyp.estimate.rotation)].1;
        let (log_weight, velocity) = (best.hyp.log_weight, best.hyp.estimate.velocity_mm_s);
        let prior = if contested { REOPEN_PRIOR } else { 1.0 };
        for (k, (pose, e)) in candidates.iter().enumerate() {
            if !reached.contains(&k) {
                children.push(Child::reopened(
                    pose,
                    velocity,
                    log_weight + prior.ln() - 0.5 * (e - e_best),
                    params,
                ));
            }
        }
    }

    /// Keeps the heaviest child and the heaviest distinct one (module docs); returns the
    /// heaviest's record.
    fn select(&mut self, mut children: Vec<Child>, params: &TrackerParams) -> Child {
        children.sort_by(|a, b| b.hyp.log_weight.total_cmp(&a.hyp.log_weight));
        let mut rest = children.into_iter();
        let Some(mut first) = rest.next() else {
            // No hypothesis had a child: cannot happen (each has at least one).
            return Child {
                hyp: self.hyps[0].clone(),
                fused: false,
                cost: None,
            };
        };
        let mut second: Option<Child> = None;
        for c in rest {
            if separation(&first.hyp.estimate, &c.hyp.estimate) <= MERGE_D2 {
                first.hyp.log_weight = log_add(first.hyp.log_weight, c.hyp.log_weight);
            } else {
                second = Some(c);
                break;
            }
        }
        self.hyps = vec![first.hyp.clone()];
        if let Some(c) = second {
            let p = 1.0 / (1.0 + (first.hyp.log_weight - c.hyp.log_weight).exp());
            if p >= params.branch_prune_probability {
                self.hyps.push(c.hyp);
            }
        }
        self.normalise();
        self.contested |= self.hyps.len() > 1;
        first
    }
}

/// ln(eᵃ + eᵇ).
fn log_add(a: f64, b: f64) -> f64 {
    let (hi, lo) = if a >= b { (a, b) } else { (b, a) };
    hi + (lo - hi).exp().ln_1p()
}

/// A candidate pose at most this squared Mahalanobis distance (6 dof, over the sum of
/// its covariance and the optimum's) from an update's optimum lies in its basin.
const SAME_BASIN_D2: f64 = 16.0;

/// Whether candidate `c` is within [`SAME_BASIN_D2`] of the estimate `e`.
fn near(e: &Eskf, c: &PoseCandidate) -> bool {
    let mut d = nalgebra::Vector6::zeros();
    d.fixed_rows_mut::<3>(0)
        .copy_from(&crate::so3::log(&(c.rotation * e.rotation.inverse())));
    d.fixed_rows_mut::<3>(3)
        .copy_from(&(c.centre_mm - e.centre_mm));
    let s = e.pose_covariance() + c.covariance;
    s.cholesky()
        .is_some_and(|ch| d.dot(&ch.solve(&d)) <= SAME_BASIN_D2)
}

/// dᵀ(P_a + P_b)⁻¹d between the poses of two filters.
fn separation(a: &Eskf, b: &Eskf) -> f64 {
    let d = a.pose_difference(b);
    let s = a.pose_covariance() + b.pose_covariance();
    s.cholesky().map_or(f64::INFINITY, |c| d.dot(&c.solve(&d)))
}

#[cfg(test)]
mod tests;
