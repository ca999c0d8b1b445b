//! The camera's path: keyframes ([`super::KeyframeSpec`]) resolved into poses
//! ([`CameraToWorld`]) and interpolated ([`Trajectory::pose_at`]), and the per-frame shake
//! ([`shaken`]).
//!
//! Position, between keyframes i and i + 1 at times t_i < t_{i+1}, with s = (t − t_i) / h,
//! h = t_{i+1} − t_i: `linear` is p_i + s (p_{i+1} − p_i); `smooth` the cubic Hermite curve
//!
//! p(s) = (2s³ − 3s² + 1) p_i + (s³ − 2s² + s) h m_i + (−2s³ + 3s²) p_{i+1} + (s³ − s²) h m_{i+1}
//!
//! with Catmull-Rom tangents m_i = (p_{i+1} − p_{i−1}) / (t_{i+1} − t_{i−1}) (mm/ms), the
//! one-sided difference at the first and last keyframe, and m_i = 0 beside a segment in
//! which the position does not change (so the camera stops there, no overshoot). Rotation:
//! slerp from R_i to R_{i+1} at s (the shorter way round; consecutive keyframes must differ
//! by less than 170°). Outside the keyframes' times the camera stays at the first or last.

use super::SequenceError;
use super::spec::{EulerDeg, Interpolation, KeyframeSpec, Shake, TrajectorySpec};
use nalgebra::{Isometry3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use qrpose_core::geometry::{euler::EulerXyz, frames::MarkerToCamera};
use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};

/// Largest turn between consecutive keyframes, degrees (slerp's way round is ambiguous at
/// 180°).
pub const MAX_KEYFRAME_TURN_DEG: f64 = 170.0;

/// The camera's pose in the world: `p_world = R_wc · p_cam + c`, c the camera centre, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraToWorld(pub Isometry3<f64>);

impl CameraToWorld {
    /// A pose from the camera's rotation into the world and its centre, mm.
    pub fn new(r_wc: UnitQuaternion<f64>, centre_mm: Vector3<f64>) -> Self {
        Self(Isometry3::from_parts(Translation3::from(centre_mm), r_wc))
    }

    /// A camera at `centre_mm` whose optical axis passes through `target_mm`, its image v
    /// axis as close to world +y as that allows, then turned by `roll_deg` about the optical
    /// axis (Rz of the camera frame). `None` when the target is the centre or straight above
    /// or below it.
    pub fn looking_at(
        centre_mm: Vector3<f64>,
        target_mm: Vector3<f64>,
        roll_deg: f64,
    ) -> Option<Self> {
        let z = (target_mm - centre_mm).try_normalize(1e-9)?;
        let x = Vector3::y().cross(&z).try_normalize(1e-9)?;
        let y = z.cross(&x);
        let look = Rotation3::from_basis_unchecked(&[x, y, z]);
        let roll = Rotation3::from_axis_angle(&Vector3::z_axis(), roll_deg.to_radians());
        Some(Self::new(
            UnitQuaternion::from_rotation_matrix(&(look * roll)),
            centre_mm,
        ))
    }

    /// The camera centre in the world, mm.
    pub fn centre_mm(&self) -> Vector3<f64> {
        self.0.translation.vector
    }

    /// R_wc: the camera's axes in the world, as columns.
    pub fn rotation(&self) -> Rotation3<f64> {
        self.0.rotation.to_rotation_matrix()
    }

    /// Where an object placed in the world (`p_world = T · p_object`) sits in this camera's
    /// frame: T_cw · T.
    pub fn object_pose(&self, object_to_world: &Isometry3<f64>) -> MarkerToCamera {
        MarkerToCamera(self.0.inverse() * object_to_world)
    }
}

/// The rotation R = Rx(alpha)·Ry(beta)·Rz(gamma).
pub fn euler_rotation(e: &EulerDeg) -> Rotation3<f64> {
    EulerXyz::from_degrees(e.alpha, e.beta, e.gamma).to_rotation()
}

/// A resolved path: keyframe times, positions, rotations and the position tangents.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    times_ms: Vec<f64>,
    positions_mm: Vec<Vector3<f64>>,
    rotations: Vec<UnitQuaternion<f64>>,
    /// dp/dt at each keyframe, mm/ms (zero for `linear`, which does not use them).
    tangents: Vec<Vector3<f64>>,
    interpolation: Interpolation,
    shake: Shake,
}

fn spec_error(field: String, reason: impl Into<String>) -> SequenceError {
    SequenceError::Spec {
        field,
        reason: reason.into(),
    }
}

fn finite3(v: [f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// The pose a keyframe asks for; a refusal names `/trajectory/keyframes/{i}/…`.
fn keyframe_pose(i: usize, k: &KeyframeSpec) -> Result<CameraToWorld, SequenceError> {
    let field = |name: &str| format!("/trajectory/keyframes/{i}/{name}");
    if !finite3(k.position_mm) {
        return Err(spec_error(field("position_mm"), "not a finite point"));
    }
    let centre = Vector3::from(k.position_mm);
    match (k.look_at_mm, k.rotation_euler_xyz_deg) {
        (Some(_), Some(_)) => Err(spec_error(
            field("rotation_euler_xyz_deg"),
            "give look_at_mm or rotation_euler_xyz_deg, not both",
        )),
        (Some(target), None) => {
            if !finite3(target) || !k.roll_deg.is_finite() {
                return Err(spec_error(field("look_at_mm"), "not a finite point"));
            }
            CameraToWorld::looking_at(centre, Vector3::from(target), k.roll_deg).ok_or_else(|| {
                spec_error(
                    field("look_at_mm"),
                    "the target is the camera centre, or straight above or below it",
                )
            })
        }
        (None, euler) => {
            let e = euler.unwrap_or_default();
            if ![e.alpha, e.beta, e.gamma].iter().all(|x| x.is_finite()) {
                return Err(spec_error(field("rotation_euler_xyz_deg"), "not finite"));
            }
            let r = euler_rotation(&e);
            Ok(CameraToWorld::new(
                UnitQuaternion::from_rotation_matrix(&r),
                centre,
            ))
        }
    }
}

/// The Catmull-Rom tangents of `smooth` (see the module doc), mm/ms.
fn tangents(times_ms: &[f64], positions_mm: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let n = times_ms.len();
    let still = |a: usize, b: usize| (positions_mm[b] - positions_mm[a]).norm() < 1e-9;
    (0..n)
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(1), (i + 1).min(n - 1));
            let beside_still = (i > 0 && still(i - 1, i)) || (i + 1 < n && still(i, i + 1));
            if lo == hi || beside_still {
                Vector3::zeros()
            } else {
                (positions_mm[hi] - positions_mm[lo]) / (times_ms[hi] - times_ms[lo])
            }
        })
        .collect()
}

impl Trajectory {
    /// Resolves and checks a path.
    ///
    /// # Errors
    /// [`SequenceError::Spec`] naming the field: no keyframe, a time not finite or not
    /// after the previous one, a point not finite, an orientation that cannot be built, a
    /// turn of [`MAX_KEYFRAME_TURN_DEG`] or more between consecutive keyframes, a negative
    /// or non-finite shake.
    pub fn new(spec: &TrajectorySpec) -> Result<Self, SequenceError> {
        if spec.keyframes.is_empty() {
            return Err(spec_error(
                "/trajectory/keyframes".into(),
                "at least one keyframe",
            ));
        }
        let mut times_ms = Vec::with_capacity(spec.keyframes.len());
        let mut poses = Vec::with_capacity(spec.keyframes.len());
        for (i, k) in spec.keyframes.iter().enumerate() {
            let after_previous = times_ms.last().is_none_or(|&t| k.time_ms > t);
            if !k.time_ms.is_finite() || !after_previous {
                return Err(spec_error(
                    format!("/trajectory/keyframes/{i}/time_ms"),
                    "times must be finite and strictly increasing",
                ));
            }
            let pose = keyframe_pose(i, k)?;
            if let Some(previous) = poses.last().map(|p: &CameraToWorld| p.0.rotation)
                && previous.angle_to(&pose.0.rotation).to_degrees() >= MAX_KEYFRAME_TURN_DEG
            {
                return Err(spec_error(
                    format!("/trajectory/keyframes/{i}"),
                    format!("turns {MAX_KEYFRAME_TURN_DEG}° or more from the previous keyframe"),
                ));
            }
            times_ms.push(k.time_ms);
            poses.push(pose);
        }
        let shake = spec.shake;
        for (name, value) in [
            ("position_mm", shake.position_mm),
            ("rotation_deg", shake.rotation_deg),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(spec_error(
                    format!("/trajectory/shake/{name}"),
                    "must be a finite σ ≥ 0",
                ));
            }
        }
        let positions_mm: Vec<Vector3<f64>> = poses.iter().map(CameraToWorld::centre_mm).collect();
        let tangents = match spec.interpolation {
            Interpolation::Smooth => tangents(&times_ms, &positions_mm),
            Interpolation::Linear => vec![Vector3::zeros(); positions_mm.len()],
        };
        Ok(Self {
            times_ms,
            rotations: poses.iter().map(|p| p.0.rotation).collect(),
            positions_mm,
            tangents,
            interpolation: spec.interpolation,
            shake,
        })
    }

    /// The last keyframe's time, ms.
    pub fn end_ms(&self) -> f64 {
        self.times_ms.last().copied().unwrap_or_default()
    }

    /// The per-frame shake.
    pub fn shake(&self) -> Shake {
        self.shake
    }

    /// The camera's pose at `t_ms` on the path, without shake.
    pub fn pose_at(&self, t_ms: f64) -> CameraToWorld {
        let last = self.times_ms.len() - 1;
        // The segment [i, i + 1] holding t; before the first or after the last keyframe the
        // camera stays there.
        let i = self.times_ms.partition_point(|&t| t <= t_ms);
        if i == 0 || i > last {
            let k = if i == 0 { 0 } else { last };
            return CameraToWorld::new(self.rotations[k], self.positions_mm[k]);
        }
        let (a, b) = (i - 1, i);
        let h = self.times_ms[b] - self.times_ms[a];
        let s = (t_ms - self.times_ms[a]) / h;
        let (pa, pb) = (self.positions_mm[a], self.positions_mm[b]);
        let position = match self.interpolation {
            Interpolation::Linear => pa + (pb - pa) * s,
            Interpolation::Smooth => {
                let (s2, s3) = (s * s, s * s * s);
                pa * (2.0 * s3 - 3.0 * s2 + 1.0)
                    + self.tangents[a] * (h * (s3 - 2.0 * s2 + s))
                    + pb * (-2.0 * s3 + 3.0 * s2)
                    + self.tangents[b] * (h * (s3 - s2))
            }
        };
        // Consecutive rotations differ by less than MAX_KEYFRAME_TURN_DEG, so slerp fails
        // only when they are equal to within its epsilon, and then either is the answer.
        // At a keyframe's own time (s = 0), its rotation exactly.
        let rotation = if s == 0.0 {
            self.rotations[a]
        } else {
            self.rotations[a]
                .try_slerp(&self.rotations[b], s, 1e-9)
                .unwrap_or(self.rotations[a])
        };
        CameraToWorld::new(rotation, position)
    }
}

/// `pose` shaken by a draw from a generator seeded with `seed`: a translation and a rotation vector in the camera
/// frame, each axis Gaussian with the shake's σ (T_wc · δ). No shake, no change.
pub fn shaken(pose: &CameraToWorld, shake: &Shake, seed: u64) -> CameraToWorld {
    if shake.position_mm == 0.0 && shake.rotation_deg == 0.0 {
        return *pose;
    }
    let mut rng = StdRng::seed_from_u64(seed);
    let mut draw3 = |sigma: f64| match Normal::new(0.0, sigma) {
        Ok(n) => Vector3::new(n.sample(&mut rng), n.sample(&mut rng), n.sample(&mut rng)),
        Err(_) => Vector3::zeros(),
    };
    let t = draw3(shake.position_mm);
    let w = draw3(shake.rotation_deg.to_radians());
    let delta = Isometry3::from_parts(
        Translation3::from(t),
        Unit::try_new(w, 1e-15).map_or(UnitQuaternion::identity(), |axis| {
            UnitQuaternion::from_axis_angle(&axis, w.norm())
        }),
    );
    CameraToWorld(pose.0 * delta)
}
